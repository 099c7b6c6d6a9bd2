//! The layout's rules, read from the source: no import circle between modules (the
//! top-level ones, or the files and folders of one module folder), no source file over
//! 800 lines, and one place that builds an argmin executor.
//! They keep the one-way flow read → fit → material → check/export/plot/render from
//! eroding one convenient import at a time.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

fn src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

/// Every `.rs` file below `dir`, sorted.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut pending = vec![dir.to_path_buf()];
    while let Some(d) = pending.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                pending.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// The module a file is (`["fit", "search"]` for `src/fit/search/mod.rs`, `["cli", "fit"]`
/// for the binary's `src/cli/fit.rs`, empty for the crate roots `lib.rs` and `main.rs`).
fn module_path(file: &Path) -> Vec<String> {
    let relative = file.strip_prefix(src()).unwrap();
    let mut path: Vec<String> = relative
        .components()
        .map(|c| {
            c.as_os_str()
                .to_string_lossy()
                .trim_end_matches(".rs")
                .to_string()
        })
        .collect();
    if matches!(
        path.last().map(String::as_str),
        Some("mod") | Some("lib") | Some("main")
    ) {
        path.pop();
    }
    path
}

/// The code of a file without its test module and without comment lines (doc links
/// name modules without importing them).
fn code(file: &Path) -> String {
    code_of(&std::fs::read_to_string(file).unwrap())
}

/// [`code`] of a file's text.
fn code_of(text: &str) -> String {
    let text = match text.find("#[cfg(test)]") {
        Some(i) => &text[..i],
        None => text,
    };
    text.lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

fn is_identifier_char(c: char) -> bool {
    c.is_alphanumeric() || c == '_'
}

/// The paths spelled from the start of `rest` (`a::b::{c, d::e}` gives `a::b::c` and
/// `a::b::d::e`), as segments; groups are expanded at any depth, `self` in a group is the
/// group's prefix.
fn paths_at(rest: &str) -> Vec<Vec<String>> {
    let rest = rest.trim_start();
    if let Some(group) = rest.strip_prefix('{') {
        let mut depth = 0;
        let mut items = Vec::new();
        let mut item_start = 0;
        for (i, c) in group.char_indices() {
            match c {
                '{' => depth += 1,
                '}' if depth == 0 => {
                    items.push(&group[item_start..i]);
                    break;
                }
                '}' => depth -= 1,
                ',' if depth == 0 => {
                    items.push(&group[item_start..i]);
                    item_start = i + 1;
                }
                _ => {}
            }
        }
        return items
            .into_iter()
            .flat_map(|item| match item.trim() {
                "self" | "" => vec![Vec::new()],
                item => paths_at(item),
            })
            .collect();
    }
    let identifier: String = rest
        .chars()
        .take_while(|&c| is_identifier_char(c))
        .collect();
    if identifier.is_empty() {
        return vec![Vec::new()];
    }
    match rest[identifier.len()..].strip_prefix("::") {
        Some(more) => paths_at(more)
            .into_iter()
            .map(|tail| std::iter::once(identifier.clone()).chain(tail).collect())
            .collect(),
        None => vec![vec![identifier]],
    }
}

/// The absolute paths that the code of the module `module` names through `crate::`,
/// `super::` (at any depth) and `self::`, as segments from the crate root.
fn references(code: &str, module: &[String]) -> BTreeSet<Vec<String>> {
    let mut found = BTreeSet::new();
    for (i, _) in code.match_indices(['c', 's']) {
        let before = code[..i].chars().next_back();
        if before.is_some_and(|c| is_identifier_char(c) || c == ':' || c == '$') {
            continue;
        }
        let rest = &code[i..];
        if !["crate::", "super::", "self::"]
            .iter()
            .any(|start| rest.starts_with(start))
        {
            continue;
        }
        for path in paths_at(rest) {
            let mut segments = path.into_iter().peekable();
            let mut absolute: Vec<String> = match segments.peek().map(String::as_str) {
                Some("crate") => Vec::new(),
                Some("self") => module.to_vec(),
                _ => {
                    let mut base = module.to_vec();
                    while segments.peek().is_some_and(|s| s == "super") {
                        base.pop();
                        segments.next();
                    }
                    base.extend(segments);
                    found.insert(base);
                    continue;
                }
            };
            segments.next();
            absolute.extend(segments);
            found.insert(absolute);
        }
    }
    found
}

/// The imports between sibling modules, as (importer, imported) module paths with the same
/// parent: a file of `fit/search` naming `crate::fit::joint::…` gives (fit::search,
/// fit::joint); one naming `crate::material` gives (fit, material). A module naming its
/// own children or its parents' items gives none.
fn import_edges() -> BTreeSet<(Vec<String>, Vec<String>)> {
    let files = rust_files(&src());
    let modules: BTreeSet<Vec<String>> = files.iter().map(|f| module_path(f)).collect();
    let mut edges = BTreeSet::new();
    for file in &files {
        let module = module_path(file);
        for reference in references(&code(file), &module) {
            // The module named: the longest known module the path starts with (the rest
            // are items).
            let Some(target) = (0..=reference.len())
                .rev()
                .map(|n| reference[..n].to_vec())
                .find(|p| modules.contains(p))
            else {
                continue;
            };
            let shared = module
                .iter()
                .zip(&target)
                .take_while(|(a, b)| a == b)
                .count();
            if shared < module.len() && shared < target.len() {
                edges.insert((module[..=shared].to_vec(), target[..=shared].to_vec()));
            }
        }
    }
    edges
}

/// Every import circle among `edges`, each once, as `a -> b -> a`.
fn circles(edges: &BTreeSet<(Vec<String>, Vec<String>)>) -> Vec<String> {
    let mut imports: BTreeMap<&Vec<String>, BTreeSet<&Vec<String>>> = BTreeMap::new();
    for (from, to) in edges {
        imports.entry(from).or_default().insert(to);
    }
    let name = |m: &Vec<String>| m.join("::");
    let mut found: BTreeMap<BTreeSet<&Vec<String>>, String> = BTreeMap::new();
    for &start in imports.keys() {
        let mut stack: Vec<Vec<&Vec<String>>> = vec![vec![start]];
        let mut seen = BTreeSet::new();
        while let Some(path) = stack.pop() {
            let last = *path.last().unwrap();
            for &next in imports.get(last).into_iter().flatten() {
                if next == start {
                    let members: BTreeSet<_> = path.iter().copied().collect();
                    let text = path
                        .iter()
                        .map(|m| name(m))
                        .collect::<Vec<_>>()
                        .join(" -> ");
                    found
                        .entry(members)
                        .or_insert_with(|| format!("{text} -> {}", name(start)));
                } else if seen.insert(next) {
                    let mut longer = path.clone();
                    longer.push(next);
                    stack.push(longer);
                }
            }
        }
    }
    found.into_values().collect()
}

fn module(path: &str) -> Vec<String> {
    path.split("::").map(String::from).collect()
}

#[test]
fn no_import_circle_between_modules() {
    let edges: BTreeSet<_> = import_edges()
        .into_iter()
        .filter(|(from, _)| from.len() == 1)
        .collect();
    assert!(
        edges.len() > 10 && edges.contains(&(module("fit"), module("material"))),
        "the scan found too little: {edges:?}"
    );
    let found = circles(&edges);
    assert!(found.is_empty(), "import circles: {found:#?}");
}

#[test]
fn no_import_circle_between_the_files_of_one_module_folder() {
    let edges: BTreeSet<_> = import_edges()
        .into_iter()
        .filter(|(from, _)| from.len() > 1)
        .collect();
    assert!(
        edges.contains(&(module("cli::fit"), module("cli::printer")))
            && edges.contains(&(module("cli::fit"), module("cli::joint")))
            && edges.contains(&(module("cli::check"), module("cli::printer"))),
        "the scan found too little: {edges:?}"
    );
    let found = circles(&edges);
    assert!(found.is_empty(), "import circles: {found:#?}");
}

#[test]
fn no_source_file_over_800_lines() {
    let long: Vec<String> = rust_files(&src())
        .into_iter()
        .filter_map(|f| {
            let lines = std::fs::read_to_string(&f).unwrap().lines().count();
            (lines > 800).then(|| format!("{} ({lines} lines)", f.display()))
        })
        .collect();
    assert!(long.is_empty(), "split by concern: {long:?}");
}

#[test]
fn one_place_builds_an_argmin_executor() {
    let builders: Vec<PathBuf> = rust_files(&src())
        .into_iter()
        .filter(|f| code(f).contains("Executor::new"))
        .collect();
    assert_eq!(builders, vec![src().join("optimise.rs")]);
}

#[test]
fn the_reference_reader_reads_paths_not_comments() {
    // The reader on made-up code in module `x::y`: grouped, nested, inline and relative
    // paths count; doc links, test modules and other crates' paths do not.
    let here = module("x::y");
    let found = references(
        &code_of(
            "//! see [`crate::d`]\nuse crate::{b::Thing, e::{f, g::h}};\nfn f() { crate::c::g() }\n\
             use super::z::w;\nuse super::super::top;\nuse fluorite::crate_like;\n\
             #[cfg(test)]\nmod tests { use crate::t; }",
        ),
        &here,
    );
    let expected: BTreeSet<Vec<String>> = ["b::Thing", "e::f", "e::g::h", "c::g", "x::z::w", "top"]
        .iter()
        .map(|p| module(p))
        .collect();
    assert_eq!(found, expected);
}

#[test]
fn the_circle_finder_finds_sibling_circles() {
    let edge = |a: &str, b: &str| (module(a), module(b));
    let edges: BTreeSet<_> = [
        edge("m::a", "m::b"),
        edge("m::b", "m::c"),
        edge("m::c", "m::a"),
        edge("m::c", "m::d"),
    ]
    .into_iter()
    .collect();
    assert_eq!(circles(&edges), ["m::a -> m::b -> m::c -> m::a"]);
    let without: BTreeSet<_> = edges
        .into_iter()
        .filter(|e| e != &edge("m::c", "m::a"))
        .collect();
    assert!(circles(&without).is_empty());
}
