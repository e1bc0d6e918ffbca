//! What OBJ and MTL files written by other tools hold that tobj does not
//! check, or does not read as this renderer needs: faces cut short (tobj
//! takes a two-index face for a line and drops it), indices out of range
//! and numbers that do not parse (tobj's errors name no line), colours
//! with other than three numbers (tobj panics on `Kd 1 1`, and refuses the
//! `Kd 0.5` the format allows), and texture statements with options
//! (`map_Kd -s 2 2 -bm 1 tex.png`), whose options tobj would take as part
//! of the file name.

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

/// Colour statements, which tobj reads as exactly three numbers.
const COLOUR_STATEMENTS: [&str; 5] = ["Ka", "Kd", "Ks", "Ke", "Tf"];

/// Statements tobj reads as one number.
const NUMBER_STATEMENTS: [&str; 4] = ["Ns", "Ni", "d", "Tr"];

/// The MTL text as tobj can read it: colours given as one number (`Kd
/// 0.5`, grey) written out as three, and the options of texture statements
/// taken out, so that only the file name follows `map_Kd` and its kin; a
/// warning for every option ignored that changes how the texture looks.
/// A colour or number that does not parse is an error naming the line.
pub fn prepare_mtl(path: &Path, text: &str) -> Result<(String, Vec<String>)> {
    let mut out = String::with_capacity(text.len());
    let mut warnings = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace().peekable();
        let keyword = words.next().unwrap_or("");
        let at = || format!("{}:{}", path.display(), i + 1);
        if COLOUR_STATEMENTS.contains(&keyword) || NUMBER_STATEMENTS.contains(&keyword) {
            let values: Vec<&str> = words.collect();
            let numbers = values.iter().all(|w| w.parse::<f32>().is_ok());
            let colour = COLOUR_STATEMENTS.contains(&keyword);
            match (colour, values.len()) {
                _ if !numbers
                    && colour
                    && matches!(values.first(), Some(&("xyz" | "spectral"))) =>
                {
                    bail!(
                        "{}: `{}`: CIE XYZ and spectral colours are not supported; give `{keyword} r g b`",
                        at(),
                        line.trim()
                    )
                }
                _ if !numbers => bail!("{}: `{}`: not a number", at(), line.trim()),
                (true, 1) => out.push_str(&format!("{keyword} {0} {0} {0}\n", values[0])),
                (true, 3) | (false, 1) => {
                    out.push_str(line);
                    out.push('\n');
                }
                (true, n) => bail!(
                    "{}: `{}` with {n} numbers (expected 1 or 3)",
                    at(),
                    line.trim()
                ),
                (false, n) => bail!("{}: `{}` with {n} numbers (expected 1)", at(), line.trim()),
            }
            continue;
        }
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
    Ok((out, warnings))
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
        let (text, warnings) = prepare_mtl(Path::new("a.mtl"), mtl).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[2], "map_Kd wood grain.png");
        assert_eq!(lines[3], "map_Ks spec.png");
        assert_eq!(lines[4], "bump b.png");
        assert_eq!(lines[5], "map_Kd plain.png");
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(warnings[0].contains("a.mtl:4") && warnings[0].contains("-s -o"));
    }

    /// `Kd 1 1` once panicked inside tobj (found by fuzzing).
    #[test]
    fn colours_are_one_or_three_numbers() {
        let prepare = |text: &str| prepare_mtl(Path::new("a.mtl"), text);
        let (text, _) = prepare("newmtl a\nKd 0.5\nKs 0.1 0.2 0.3\nNs 10\n").unwrap();
        assert_eq!(text, "newmtl a\nKd 0.5 0.5 0.5\nKs 0.1 0.2 0.3\nNs 10\n");
        for (text, needle) in [
            ("newmtl a\nKd 101 1\n", "a.mtl:2: `Kd 101 1` with 2 numbers"),
            ("Ke\n", "a.mtl:1: `Ke` with 0 numbers"),
            ("Kd 1 1 1 1\n", "with 4 numbers"),
            ("Kd xyz 0.1 0.2 0.3\n", "CIE XYZ"),
            (
                "Kd 0.5 red 0.5\n",
                "a.mtl:1: `Kd 0.5 red 0.5`: not a number",
            ),
            ("Ns\n", "`Ns` with 0 numbers (expected 1)"),
            ("d 0.5 0.5\n", "expected 1"),
        ] {
            let e = prepare(text).unwrap_err().to_string();
            assert!(e.contains(needle), "`{needle}` not in: {e}");
        }
    }
}
