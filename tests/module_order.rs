//! The library's modules depend on each other one way, in the order of the
//! pipeline (DESIGN.md): a module names only modules below it. A new module
//! must be given its place here, and an arrow pointing up fails.

use std::fs;
use std::path::{Path, PathBuf};

/// Lowest first; modules on one line are independent of each other.
const LAYERS: &[&[&str]] = &[
    &["rng", "checksum", "ray", "alloc", "output", "progress"],
    &["camera"],
    &["image"],
    &["scene"],
    &["bsdf", "embree", "export"],
    &["accel"],
    &["radiosity"],
    &["render"],
    &["plan"],
    &["bake"],
    &["synth"],
    &["eval"],
    &["capi", "viewer"],
];

fn layer(module: &str) -> Option<usize> {
    LAYERS.iter().position(|l| l.contains(&module))
}

fn sources(path: &Path, out: &mut Vec<PathBuf>) {
    if path.is_dir() {
        for e in fs::read_dir(path).unwrap() {
            sources(&e.unwrap().path(), out);
        }
    } else if path.extension().is_some_and(|e| e == "rs") {
        out.push(path.to_path_buf());
    }
}

/// The modules `text` names as `crate::<module>`, comments left out.
fn named(text: &str) -> Vec<String> {
    let mut found = Vec::new();
    for line in text.lines() {
        let code = line.split("//").next().unwrap_or("");
        for (i, _) in code.match_indices("crate::") {
            let name: String = code[i + 7..]
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                found.push(name);
            }
        }
    }
    found
}

fn library_modules(src: &Path) -> Vec<(String, Vec<PathBuf>)> {
    let mut modules = Vec::new();
    for e in fs::read_dir(src).unwrap() {
        let path = e.unwrap().path();
        let stem = path.file_stem().unwrap().to_string_lossy().to_string();
        // The binary's own files are not the library's.
        if ["lib", "main", "cli"].contains(&stem.as_str()) {
            continue;
        }
        let mut files = Vec::new();
        sources(&path, &mut files);
        if !files.is_empty() {
            modules.push((stem, files));
        }
    }
    modules.sort();
    modules
}

#[test]
fn every_module_names_only_modules_below_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let modules = library_modules(&src);
    assert!(modules.len() >= 15, "found only {modules:?}");
    let mut upward = Vec::new();
    for (module, files) in &modules {
        let own = layer(module)
            .unwrap_or_else(|| panic!("module `{module}` has no place in LAYERS: give it one"));
        for file in files {
            for other in named(&fs::read_to_string(file).unwrap()) {
                if &other == module {
                    continue;
                }
                let theirs = layer(&other).unwrap_or_else(|| {
                    panic!(
                        "{} names `crate::{other}`, which has no place in LAYERS",
                        file.display()
                    )
                });
                if theirs >= own {
                    upward.push(format!("{} names crate::{other}", file.display()));
                }
            }
        }
    }
    assert!(
        upward.is_empty(),
        "arrows against the pipeline's order:\n{}",
        upward.join("\n")
    );
}

#[test]
fn the_library_knows_nothing_of_the_command_line_parser() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut found = Vec::new();
    for (_, files) in library_modules(&src) {
        for file in files {
            let text = fs::read_to_string(&file).unwrap();
            if text
                .lines()
                .any(|l| l.split("//").next().unwrap_or("").contains("clap::"))
            {
                found.push(file.display().to_string());
            }
        }
    }
    assert!(found.is_empty(), "clap in the library: {found:?}");
}

/// The checks above would pass on nothing: show that they see an arrow
/// pointing up where there is one.
#[test]
fn an_upward_arrow_is_seen() {
    let text =
        "use crate::synth::Fill; // crate::eval in a comment\nlet x = crate::rng::Pcg32::new(1);";
    assert_eq!(named(text), ["synth", "rng"]);
    assert!(layer("synth").unwrap() > layer("render").unwrap());
}
