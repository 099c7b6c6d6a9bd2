//! The layout's rules, read from the source: no import circle between the library's
//! modules, no source file over 800 lines, and one place that builds an argmin executor.
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

/// The top-level module a file belongs to (`fit` for `src/fit/search/mod.rs`), or None
/// for the crate roots and the binary's `cli`.
fn top_module(file: &Path) -> Option<String> {
    let relative = file.strip_prefix(src()).unwrap();
    let first = relative.components().next()?.as_os_str().to_string_lossy();
    let name = first.trim_end_matches(".rs").to_string();
    (!matches!(name.as_str(), "lib" | "main" | "cli")).then_some(name)
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

/// The top-level modules named after `crate::` in `code`, including inside
/// `use crate::{a, b::c}` groups.
fn crate_references(code: &str) -> BTreeSet<String> {
    let mut found = BTreeSet::new();
    let identifier = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_alphanumeric() || *c == '_')
            .collect()
    };
    for (i, _) in code.match_indices("crate::") {
        let rest = &code[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let inner = &group[..group.find('}').unwrap_or(group.len())];
            for item in inner.split(',') {
                found.insert(identifier(item.trim()));
            }
        } else {
            found.insert(identifier(rest));
        }
    }
    // Items re-exported at the crate root (`crate::Material`) are types, not modules.
    found.retain(|m| m.chars().next().is_some_and(|c| c.is_ascii_lowercase()));
    found
}

#[test]
fn no_import_circle_between_modules() {
    let mut imports: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for file in rust_files(&src()) {
        let Some(module) = top_module(&file) else {
            continue;
        };
        let targets = crate_references(&code(&file));
        let entry = imports.entry(module.clone()).or_default();
        entry.extend(targets.into_iter().filter(|t| *t != module));
    }
    assert!(
        imports.len() > 10 && imports["fit"].contains("material"),
        "the scan found too little: {imports:?}"
    );
    // A circle exists when some module reaches itself; report the first path found.
    for start in imports.keys() {
        let mut stack: Vec<Vec<String>> = vec![vec![start.clone()]];
        let mut seen = BTreeSet::new();
        while let Some(path) = stack.pop() {
            let last = path.last().unwrap();
            for next in imports.get(last).into_iter().flatten() {
                if next == start {
                    panic!("import circle: {} -> {start}", path.join(" -> "));
                }
                if seen.insert(next.clone()) {
                    let mut longer = path.clone();
                    longer.push(next.clone());
                    stack.push(longer);
                }
            }
        }
    }
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
    // The reader on made-up code: grouped and inline paths count, doc links, test modules
    // and root re-exports do not.
    let a = crate_references("use crate::{b::Thing, error::Result};\nfn f() { crate::c::g() }");
    assert_eq!(
        a,
        ["b", "c", "error"]
            .iter()
            .map(|s| s.to_string())
            .collect::<BTreeSet<_>>()
    );
    let skipped = crate_references(&code_of(
        "//! see [`crate::d`]\nuse crate::Material;\n#[cfg(test)]\nmod tests { use crate::e; }",
    ));
    assert!(skipped.is_empty(), "{skipped:?}");
}
