//! What OBJ and MTL files written by other tools hold that tobj does not
//! check, or does not read as this renderer needs: faces cut short (tobj
//! takes a two-index face for a line and drops it), indices out of range
//! and numbers that do not parse (tobj's errors name no line), and texture
//! statements with options (`map_Kd -s 2 2 -bm 1 tex.png`), whose options
//! tobj would take as part of the file name.

use std::path::Path;

use anyhow::{bail, ensure, Result};

/// Checks every `v`, `vt`, `vn` and `f` line of an OBJ file, so that what
/// is broken is an error naming the file and line before tobj reads it.
pub fn check_obj(path: &Path, text: &str) -> Result<()> {
    // Elements declared so far: faces may only refer back (OBJ indices
    // count from 1, negative ones from the end).
    let mut counts = [0usize; 3];
    for (i, line) in text.lines().enumerate() {
        let at = || format!("{}:{}", path.display(), i + 1);
        let mut words = line.split_whitespace();
        let (kind, min, max) = match words.next() {
            Some("v") => (0, 3, 7),
            Some("vt") => (1, 1, 3),
            Some("vn") => (2, 3, 3),
            Some("f") => {
                face(&at, words, counts)?;
                continue;
            }
            _ => continue,
        };
        let mut n = 0;
        for w in words {
            n += 1;
            let ok = w.parse::<f32>().is_ok_and(f32::is_finite);
            ensure!(ok, "{}: `{w}` is not a finite number", at());
        }
        ensure!(
            (min..=max).contains(&n),
            "{}: `{}` with {n} numbers (expected {min} to {max})",
            at(),
            line.trim()
        );
        counts[kind] += 1;
    }
    Ok(())
}

/// One `f` line: at least three corners, each `v`, `v/vt`, `v//vn` or
/// `v/vt/vn` with indices that name elements declared above.
fn face<'a>(
    at: &dyn Fn() -> String,
    words: impl Iterator<Item = &'a str>,
    counts: [usize; 3],
) -> Result<()> {
    const NAMES: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let mut corners = 0;
    for w in words {
        corners += 1;
        let parts: Vec<&str> = w.split('/').collect();
        ensure!(
            !parts[0].is_empty() && parts.len() <= 3,
            "{}: face corner `{w}` is not v, v/vt, v//vn or v/vt/vn",
            at()
        );
        for (k, p) in parts.iter().enumerate() {
            if p.is_empty() {
                continue;
            }
            let Ok(index) = p.parse::<i64>() else {
                bail!("{}: face corner `{w}`: `{p}` is not an index", at());
            };
            let n = counts[k] as i64;
            let resolved = if index < 0 { n + index + 1 } else { index };
            ensure!(
                index != 0 && (1..=n).contains(&resolved),
                "{}: face corner `{w}` names {} {index}, but {n} are declared above it",
                at(),
                NAMES[k]
            );
        }
    }
    ensure!(
        corners >= 3,
        "{}: a face with {corners} corner(s); a face needs at least 3 (is the line cut short?)",
        at()
    );
    Ok(())
}

/// Texture statements whose options are taken out.
const TEXTURE_STATEMENTS: [&str; 4] = ["bump", "disp", "decal", "refl"];

/// Options that change where a texture lands on the surface; they are
/// ignored (the texture is mapped as if they were absent), so a warning
/// says so.
const PLACEMENT_OPTIONS: [&str; 3] = ["-o", "-s", "-t"];

/// The MTL text with the options of its texture statements taken out, so
/// that only the file name follows `map_Kd` and its kin, and a warning for
/// every option ignored that changes how the texture looks.
pub fn strip_texture_options(path: &Path, text: &str) -> (String, Vec<String>) {
    let mut out = String::with_capacity(text.len());
    let mut warnings = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace().peekable();
        let keyword = words.next().unwrap_or("");
        let is_texture = keyword.starts_with("map_") || TEXTURE_STATEMENTS.contains(&keyword);
        if !is_texture || !line.contains(" -") {
            out.push_str(line);
            out.push('\n');
            continue;
        }
        let mut ignored = Vec::new();
        while let Some(option) = words.next_if(|w| w.starts_with('-') && w.len() > 1) {
            let arguments = match option {
                "-mm" => 2,
                "-o" | "-s" | "-t" => 3,
                _ => usize::MAX,
            };
            // Fixed-count options take up to that many numbers or switches;
            // unknown ones (`-c on`) take what looks like an argument.
            let mut taken = 0;
            while taken < arguments && words.next_if(|w| is_option_argument(w, option)).is_some() {
                taken += 1;
            }
            if PLACEMENT_OPTIONS.contains(&option) {
                ignored.push(option);
            }
        }
        let file: Vec<&str> = words.collect();
        if !ignored.is_empty() {
            warnings.push(format!(
                "{}:{}: texture option(s) {} ignored: the texture is placed without them",
                path.display(),
                i + 1,
                ignored.join(" ")
            ));
        }
        out.push_str(keyword);
        out.push(' ');
        out.push_str(&file.join(" "));
        out.push('\n');
    }
    (out, warnings)
}

fn is_option_argument(word: &str, option: &str) -> bool {
    let switch = matches!(word, "on" | "off");
    let channel = option == "-imfchan" && matches!(word, "r" | "g" | "b" | "m" | "l" | "z");
    let kind = option == "-type";
    switch || channel || kind || word.parse::<f32>().is_ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(text: &str) -> Result<()> {
        check_obj(Path::new("m.obj"), text)
    }

    #[test]
    fn broken_lines_are_errors_naming_the_line() {
        let v = "v 0 0 0\nv 1 0 0\nv 1 1 0\n";
        check(&format!("{v}f 1 2 3\nf -3 -2 -1\nvt 0 0\nf 1/1 2/1 3/1\n")).unwrap();
        for (text, needle) in [
            (format!("{v}f 1 2\n"), "m.obj:4: a face with 2 corner(s)"),
            (
                format!("{v}f 1 2 4\n"),
                "m.obj:4: face corner `4` names vertex 4, but 3",
            ),
            (format!("{v}f 1 2 1000000000\n"), "vertex 1000000000"),
            (format!("{v}f 1 2 0\n"), "vertex 0"),
            (format!("{v}f 1 2 -4\n"), "vertex -4"),
            (format!("{v}f 1/2 2 3\n"), "texture coordinate 2, but 0"),
            (format!("{v}f 1 2 x\n"), "`x` is not an index"),
            ("v 0 0\n".to_string(), "m.obj:1: `v 0 0` with 2 numbers"),
            (
                "v 0 nan 0\n".to_string(),
                "m.obj:1: `nan` is not a finite number",
            ),
            ("v 0 0 0\nvn 0 0 1e50\n".to_string(), "m.obj:2: `1e50`"),
        ] {
            let e = check(&text).unwrap_err().to_string();
            assert!(e.contains(needle), "`{needle}` not in: {e}");
        }
    }

    #[test]
    fn texture_options_are_taken_out() {
        let mtl = "newmtl a\nKd 0.5 0.5 0.5\nmap_Kd -c on -texres 512 -bm 0.5 wood grain.png\n\
                   map_Ks -s 2 2 1 -o 0.5 0.5 spec.png\nbump -imfchan l b.png\nmap_Kd plain.png\n";
        let (text, warnings) = strip_texture_options(Path::new("a.mtl"), mtl);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[2], "map_Kd wood grain.png");
        assert_eq!(lines[3], "map_Ks spec.png");
        assert_eq!(lines[4], "bump b.png");
        assert_eq!(lines[5], "map_Kd plain.png");
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("a.mtl:4") && warnings[0].contains("-s -o"));
    }
}
