//! Scripted input (`rangewalk view --input FILE`): what is held at each
//! frame, so that a walk through the window can be replayed exactly, by
//! tests and for recordings.
//!
//! One step a line, `<frames> [key ...] [drag <dx>,<dy>]`: the keys are
//! held (and the mouse dragged by `dx, dy` pixels each frame) for that many
//! frames; a line with a count alone waits. `#` starts a comment.

use std::path::Path;

use anyhow::{bail, ensure, Context, Result};

use super::walker::{Input, Key};

/// The input of every frame, in order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Script {
    pub frames: Vec<Input>,
}

impl Script {
    pub fn read(path: &Path) -> Result<Script> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading the input script {}", path.display()))?;
        Script::parse(&text).with_context(|| format!("input script {}", path.display()))
    }

    pub fn parse(text: &str) -> Result<Script> {
        let mut frames = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let (count, input) = parse_step(line).with_context(|| format!("line {}", n + 1))?;
            frames.extend(std::iter::repeat_n(input, count));
        }
        Ok(Script { frames })
    }
}

fn parse_step(line: &str) -> Result<(usize, Input)> {
    let mut words = line.split_whitespace();
    let first = words.next().expect("the line is not empty");
    let count: usize = first
        .parse()
        .with_context(|| format!("`{first}` is not a number of frames"))?;
    ensure!(count > 0, "a step lasts at least 1 frame, not 0");
    let mut input = Input::default();
    while let Some(w) = words.next() {
        if w == "drag" {
            let Some(by) = words.next() else {
                bail!("`drag` needs `<dx>,<dy>` (pixels)");
            };
            let parsed = by
                .split_once(',')
                .and_then(|(x, y)| Some((x.parse::<f32>().ok()?, y.parse::<f32>().ok()?)))
                .filter(|(x, y)| x.is_finite() && y.is_finite());
            let Some(drag) = parsed else {
                bail!("`drag {by}`: give `<dx>,<dy>` in pixels, e.g. `drag 40,0`");
            };
            input.drag = drag;
        } else {
            input.keys.insert(Key::parse(w)?);
        }
    }
    Ok((count, input))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_expand_to_frames() {
        let s = Script::parse("# walk right\n2 d shift\n\n1\n1 drag -4,2.5 left # turn\n").unwrap();
        assert_eq!(s.frames.len(), 4);
        assert_eq!(
            s.frames[0].keys.iter().copied().collect::<Vec<_>>(),
            [Key::D, Key::Shift]
        );
        assert_eq!(s.frames[1], s.frames[0]);
        assert_eq!(s.frames[2], Input::default());
        assert_eq!(s.frames[3].drag, (-4.0, 2.5));
        assert!(s.frames[3].keys.contains(&Key::Left));
    }

    #[test]
    fn bad_lines_are_named() {
        let e = format!("{:#}", Script::parse("1 w\nx w\n").unwrap_err());
        assert!(e.contains("line 2") && e.contains("`x`"), "{e}");
        let e = format!("{:#}", Script::parse("3 jump").unwrap_err());
        assert!(e.contains("line 1") && e.contains("`jump`"), "{e}");
        let e = format!("{:#}", Script::parse("1 drag 3").unwrap_err());
        assert!(e.contains("drag 3"), "{e}");
        let e = format!("{:#}", Script::parse("0 w").unwrap_err());
        assert!(e.contains("at least 1"), "{e}");
    }
}
