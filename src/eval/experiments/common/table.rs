//! Tables of results as Markdown (for reading) and CSV (for other tools).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{ensure, Context, Result};

/// A table of text cells; every row has one cell per header.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Table {
    pub headers: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl Table {
    pub fn new<S: Into<String>>(headers: impl IntoIterator<Item = S>) -> Self {
        Self {
            headers: headers.into_iter().map(Into::into).collect(),
            rows: Vec::new(),
        }
    }

    /// Appends a row; its length must match the headers (a mismatch is a
    /// bug in the caller, caught here rather than as a shifted column).
    pub fn push<S: Into<String>>(&mut self, row: impl IntoIterator<Item = S>) -> Result<()> {
        let row: Vec<String> = row.into_iter().map(Into::into).collect();
        ensure!(
            row.len() == self.headers.len(),
            "table row has {} cells for {} columns ({:?})",
            row.len(),
            self.headers.len(),
            self.headers
        );
        self.rows.push(row);
        Ok(())
    }

    /// GitHub-flavoured Markdown; numbers are right-aligned by the caller's
    /// formatting, `|` in cells is escaped.
    pub fn to_markdown(&self) -> String {
        let cell = |s: &str| s.replace('|', "\\|").replace('\n', " ");
        let mut out = String::new();
        let line = |out: &mut String, cells: &[String]| {
            out.push('|');
            for c in cells {
                let _ = write!(out, " {} |", cell(c));
            }
            out.push('\n');
        };
        line(&mut out, &self.headers);
        out.push('|');
        for _ in &self.headers {
            out.push_str(" --- |");
        }
        out.push('\n');
        for r in &self.rows {
            line(&mut out, r);
        }
        out
    }

    /// RFC 4180 CSV: fields with commas, quotes or line breaks are quoted.
    pub fn to_csv(&self) -> String {
        let field = |s: &str| {
            if s.contains([',', '"', '\n', '\r']) {
                format!("\"{}\"", s.replace('"', "\"\""))
            } else {
                s.to_string()
            }
        };
        let mut out = String::new();
        for r in std::iter::once(&self.headers).chain(&self.rows) {
            let cells: Vec<String> = r.iter().map(|c| field(c)).collect();
            out.push_str(&cells.join(","));
            out.push('\n');
        }
        out
    }

    pub fn write_csv(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        std::fs::write(path, self.to_csv()).with_context(|| format!("writing {}", path.display()))
    }
}

/// The row of a table of published figures (the paper's) for quality `q`.
pub fn for_quality<T>(rows: &[T], q: f32, quality: impl Fn(&T) -> f32) -> Option<&T> {
    rows.iter().find(|r| (quality(r) - q).abs() < 1e-6)
}

/// A number with `digits` significant digits, without exponent where it
/// stays readable: table cells of very different magnitudes (seconds,
/// errors) line up without a per-column format.
pub fn sig(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return x.to_string();
    }
    if x == 0.0 {
        return "0".to_string();
    }
    let mag = x.abs().log10().floor() as i32;
    if !(-4..=6).contains(&mag) {
        return format!("{:.*e}", digits.saturating_sub(1), x);
    }
    let decimals = (digits as i32 - 1 - mag).max(0) as usize;
    format!("{x:.decimals$}")
}

/// The mean of `xs`; NaN when there are none.
pub fn mean(xs: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = xs.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

/// A short list of times: all of them when few, else the ends and count.
pub fn times_list(times: &[f32]) -> String {
    let all: Vec<String> = times
        .iter()
        .map(|t| {
            format!("{t:.4}")
                .trim_end_matches('0')
                .trim_end_matches('.')
                .to_string()
        })
        .collect();
    if all.len() <= 6 {
        all.join(", ")
    } else {
        format!(
            "{}, {}, ..., {} ({} times)",
            all[0],
            all[1],
            all[all.len() - 1],
            all.len()
        )
    }
}

/// A number for a table, or a dash where there is none.
pub fn cell(x: Option<f64>, digits: usize) -> String {
    x.map_or("—".to_string(), |x| sig(x, digits))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_has_header_rule_and_rows() {
        let mut t = Table::new(["q", "note"]);
        t.push(["0.3", "a|b"]).unwrap();
        let md = t.to_markdown();
        let lines: Vec<&str> = md.lines().collect();
        assert_eq!(lines, ["| q | note |", "| --- | --- |", "| 0.3 | a\\|b |"]);
    }

    #[test]
    fn rows_must_fit_the_headers() {
        let mut t = Table::new(["a", "b"]);
        assert!(t.push(["1"]).is_err());
        assert!(t.rows.is_empty());
    }

    #[test]
    fn csv_quotes_what_needs_quoting() {
        let mut t = Table::new(["a", "b"]);
        t.push(["x,y", "say \"hi\""]).unwrap();
        assert_eq!(t.to_csv(), "a,b\n\"x,y\",\"say \"\"hi\"\"\"\n");
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(0.14712, 3), "0.147");
        assert_eq!(sig(123.456, 3), "123");
        assert_eq!(sig(1.5, 3), "1.50");
        assert_eq!(sig(0.0, 3), "0");
        assert_eq!(sig(-0.0123, 2), "-0.012");
        assert_eq!(sig(1.0e-7, 2), "1.0e-7");
        assert_eq!(sig(f64::NAN, 2), "NaN");
    }
}
