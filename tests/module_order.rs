//! The library's modules depend on each other one way, in the order of the
//! pipeline (DESIGN.md): a module names only modules below it. A new module
//! must be given its place here, and an arrow pointing up fails.

use std::fs;
use std::path::{Path, PathBuf};

/// Lowest first; modules on one line are independent of each other.
const LAYERS: &[&[&str]] = &[
    &[
        "rng", "checksum", "ray", "alloc", "output", "progress", "quality",
    ],
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

/// A library file's module path: `src/a/b.rs` and `src/a/b/mod.rs` are
/// `a::b`.
fn module_path(src: &Path, file: &Path) -> Vec<String> {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut path: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().to_string())
        .collect();
    if path.last().is_some_and(|l| l == "mod") {
        path.pop();
    }
    path
}

/// The paths `text` names through `super::` or `crate::`, resolved against
/// `own` (the naming file's module path): each as the identifiers that
/// follow, one path per element of a `{...}` group. Comments and the test
/// module at the end of a file (whose `super` is the file) are left out.
fn paths_named(own: &[String], text: &str) -> Vec<Vec<String>> {
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    // `a::b::c` at the start of `s`, as identifiers.
    let chain = |s: &str| -> Vec<String> {
        let mut out = Vec::new();
        let mut rest = s.trim_start();
        loop {
            let id = ident(rest);
            if id.is_empty() {
                break;
            }
            rest = &rest[id.len()..];
            out.push(id);
            match rest.strip_prefix("::") {
                Some(r) if !r.starts_with('{') => rest = r,
                _ => break,
            }
        }
        out
    };
    let mut found = Vec::new();
    for line in text.lines() {
        if line.trim_start().starts_with("#[cfg(test)]") {
            break;
        }
        let code = line.split("//").next().unwrap_or("");
        let mut at = 0;
        while let Some(i) = code[at..].find(['s', 'c']).map(|i| at + i) {
            at = i + 1;
            if i > 0 && code[..i].ends_with(|c: char| c.is_ascii_alphanumeric() || c == '_') {
                continue;
            }
            let mut rest = &code[i..];
            let mut base: Vec<String> = own.to_vec();
            if let Some(r) = rest.strip_prefix("crate::") {
                base.clear();
                rest = r;
            } else if rest.starts_with("super::") {
                while let Some(r) = rest.strip_prefix("super::") {
                    base.pop();
                    rest = r;
                }
            } else {
                continue;
            }
            let heads = chain(rest);
            let taken = heads.iter().map(|h| h.len() + 2).sum::<usize>();
            let after = rest.get(taken..).unwrap_or("");
            if heads.is_empty() && !rest.starts_with('{') {
                // `prefix::*`: the module itself.
                found.push(base);
            } else if heads.is_empty() || after.starts_with('{') {
                // `prefix::{a, b::c}` or `prefix::a::{...}`: one path per element.
                let prefix: Vec<String> = base.iter().cloned().chain(heads).collect();
                let group = rest[rest.find('{').unwrap_or(0) + 1..]
                    .split('}')
                    .next()
                    .unwrap_or("");
                for element in group.split(',') {
                    let tail = chain(element);
                    found.push(prefix.iter().cloned().chain(tail).collect());
                }
            } else {
                found.push(base.into_iter().chain(heads).collect());
            }
        }
    }
    found
}

/// Within a module, files name each other one way too: no circle of files
/// (a module's `mod.rs`, which declares its files, is left out of it).
#[test]
fn no_circle_of_files_within_a_module() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    for (_, fs_) in library_modules(&src) {
        files.extend(fs_);
    }
    let paths: Vec<Vec<String>> = files.iter().map(|f| module_path(&src, f)).collect();
    let is_ancestor = |a: &[String], b: &[String]| b.len() > a.len() && b.starts_with(a);
    // The file a named path is in: its longest prefix that is a file's module.
    let file_of = |named: &[String]| {
        (1..=named.len())
            .rev()
            .find_map(|n| paths.iter().position(|p| p[..] == named[..n]))
    };
    let mut edges = vec![Vec::new(); files.len()];
    for (i, file) in files.iter().enumerate() {
        for named in paths_named(&paths[i], &fs::read_to_string(file).unwrap()) {
            let Some(j) = file_of(&named) else { continue };
            let (a, b) = (&paths[i], &paths[j]);
            if i != j && a[0] == b[0] && !is_ancestor(a, b) && !is_ancestor(b, a) {
                edges[i].push(j);
            }
        }
    }
    let names: Vec<String> = circles(&edges)
        .iter()
        .map(|c| {
            let c: Vec<String> = c.iter().map(|&i| paths[i].join("::")).collect();
            c.join(" <-> ")
        })
        .collect();
    assert!(
        names == KNOWN_CIRCLES,
        "files that name each other:\n{}\n(known: {KNOWN_CIRCLES:?}; remove a circle from there once it is gone)",
        names.join("\n")
    );
}

/// Circles that are being taken apart where their module is worked on
/// (issue 50): the check fails on any other, and on one of these once it
/// is gone and still listed.
const KNOWN_CIRCLES: &[&str] = &["radiosity::solver::linear <-> radiosity::solver::links"];

/// The strongly connected groups of more than one node (Tarjan).
fn circles(edges: &[Vec<usize>]) -> Vec<Vec<usize>> {
    struct Walk<'a> {
        edges: &'a [Vec<usize>],
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        stack: Vec<usize>,
        on_stack: Vec<bool>,
        next: usize,
        found: Vec<Vec<usize>>,
    }
    impl Walk<'_> {
        fn visit(&mut self, v: usize) {
            self.index[v] = Some(self.next);
            self.low[v] = self.next;
            self.next += 1;
            self.stack.push(v);
            self.on_stack[v] = true;
            for &w in &self.edges[v] {
                match self.index[w] {
                    None => {
                        self.visit(w);
                        self.low[v] = self.low[v].min(self.low[w]);
                    }
                    Some(iw) if self.on_stack[w] => self.low[v] = self.low[v].min(iw),
                    Some(_) => {}
                }
            }
            if Some(self.low[v]) == self.index[v] {
                let mut group = Vec::new();
                loop {
                    let w = self.stack.pop().unwrap();
                    self.on_stack[w] = false;
                    group.push(w);
                    if w == v {
                        break;
                    }
                }
                if group.len() > 1 {
                    group.sort();
                    self.found.push(group);
                }
            }
        }
    }
    let n = edges.len();
    let mut walk = Walk {
        edges,
        index: vec![None; n],
        low: vec![0; n],
        stack: Vec::new(),
        on_stack: vec![false; n],
        next: 0,
        found: Vec::new(),
    };
    for v in 0..n {
        if walk.index[v].is_none() {
            walk.visit(v);
        }
    }
    walk.found
}

/// The file-level check sees `super::` and `crate::` paths, grouped
/// imports included, and a circle where there is one.
#[test]
fn a_circle_of_files_is_seen() {
    let own = |p: &str| p.split("::").map(String::from).collect::<Vec<_>>();
    let text = "use super::links::{Link, Transfer};\nuse super::{hierarchy::Node, pruned};\nlet x = crate::radiosity::Quality::new(0.5); // super::gone\n";
    assert_eq!(
        paths_named(&own("radiosity::solver::linear"), text),
        [
            own("radiosity::solver::links::Link"),
            own("radiosity::solver::links::Transfer"),
            own("radiosity::solver::hierarchy::Node"),
            own("radiosity::solver::pruned"),
            own("radiosity::Quality::new"),
        ]
    );
    assert_eq!(
        circles(&[vec![1], vec![2], vec![0], vec![]]),
        [vec![0, 1, 2]]
    );
    assert!(circles(&[vec![1], vec![2], vec![]]).is_empty());
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
