//! The committed fits in `fits/` are what the code makes now, and the tables beside them
//! say what their materials hold. `scripts/regenerate.sh` rewrites the material JSON on
//! every run but the tables (`--table`, with times) only with `--timings`; a change of
//! the fit could leave a table naming a model its JSON no longer holds, and README and
//! docs/results.md quote those tables.

use crate::common;

use std::path::{Path, PathBuf};

use common::repository;

/// What a table row or a material JSON says of one fit: the model (empty for a plain
/// reflector), its parameter count and ΔE2000 under D65, A, F11 and UV to two decimals,
/// as the table prints them.
#[derive(Debug, PartialEq)]
struct Summary {
    model: String,
    parameters: String,
    delta_e: [String; 4],
}

/// The header of the table `fluorite fit --table` prints after a fit that chose a model.
const MODEL_TABLE_HEADER: &str =
    "| material | model chosen | parameters | ΔE D65 | ΔE A | ΔE F11 | ΔE UV |";

/// The rows of the `--table` Markdown table in `text`: material name → summary.
fn table_rows(text: &str) -> Vec<(String, Summary)> {
    let headers = text.lines().filter(|l| l.starts_with("| material")).count();
    assert!(
        headers == 1 && text.lines().any(|l| l.starts_with(MODEL_TABLE_HEADER)),
        "one table of the chosen models, headed {MODEL_TABLE_HEADER}…"
    );
    text.lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| material"))
        .map(|line| {
            let cells: Vec<&str> = line.split('|').map(str::trim).collect();
            // "", name, model, parameters, ΔE D65, A, F11, UV, bound, laws, candidates, ms, "".
            assert_eq!(cells.len(), 13, "an unexpected table row: {line}");
            (
                cells[1].to_string(),
                Summary {
                    model: cells[2].to_string(),
                    parameters: cells[3].to_string(),
                    delta_e: [4, 5, 6, 7].map(|i| cells[i].to_string()),
                },
            )
        })
        .collect()
}

/// The summary of the material JSON at `path`; `what` says which material it is meant to
/// be, for the message when it is missing.
fn material_summary(path: &Path, what: &str) -> Summary {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e} ({what})", path.display()));
    let value: serde_json::Value = serde_json::from_str(&text).unwrap();
    let fit = &value["fit"];
    // Only a plain reflector (no fluorophore) goes without a model and its parameter count.
    let plain = value["fluorophores"]
        .as_array()
        .is_some_and(|f| f.is_empty());
    assert!(
        plain || (fit["model"].is_string() && fit["parameter_count"].is_u64()),
        "{}: a fluorescent material without its model or parameter count",
        path.display()
    );
    let delta_e = |light: &str| {
        let de = fit["delta_e2000"][light]
            .as_f64()
            .unwrap_or_else(|| panic!("{}: no ΔE2000 under {light}", path.display()));
        format!("{de:.2}")
    };
    Summary {
        model: fit["model"].as_str().unwrap_or("").to_string(),
        parameters: fit["parameter_count"].as_u64().unwrap_or(0).to_string(),
        delta_e: ["d65", "a", "f11", "uv"].map(delta_e),
    }
}

#[test]
fn every_committed_table_row_is_what_the_material_beside_it_holds() {
    let tables = [
        ("fits/data-table.txt", "fits"),
        ("fits/models/data-table.txt", "fits/models"),
        ("fits/measured/table.txt", "fits/measured"),
        ("fits/models/measured/table.txt", "fits/models/measured"),
    ];
    for (table, folder) in tables {
        let text = std::fs::read_to_string(repository().join(table)).unwrap();
        let rows = table_rows(&text);
        assert!(rows.len() >= 4, "{table}: {} rows", rows.len());
        for (name, row) in rows {
            let json = repository().join(folder).join(format!("{name}.json"));
            assert_eq!(
                row,
                material_summary(&json, "the material of a table row"),
                "{table}'s row of {name} against {folder}/{name}.json: run scripts/regenerate.sh --timings"
            );
        }
    }
}

/// Fits `inputs` into a fresh folder with `arguments` and compares each material with the
/// committed one in `committed` (model, parameters, ΔE2000 to two decimals).
fn refit_matches_committed(inputs: &[PathBuf], arguments: &[&str], committed: &Path, tag: &str) {
    let out = common::temp_dir(tag);
    common::succeed(
        common::fluorite()
            .current_dir(repository())
            .arg("fit")
            .args(inputs)
            .args(arguments)
            .args(["-q", "-o"])
            .arg(&out),
    );
    assert!(!inputs.is_empty(), "{tag}: nothing to fit");
    for input in inputs {
        let stem = input.file_stem().unwrap().to_string_lossy();
        let name = format!("{stem}.json");
        assert_eq!(
            material_summary(&out.join(&name), "the fit just made"),
            material_summary(&committed.join(&name), "the committed fit"),
            "{name}: the fit `fluorite fit {} {}` makes now against the committed {}: run scripts/regenerate.sh",
            input.display(),
            arguments.join(" "),
            committed.join(&name).display()
        );
    }
}

#[test]
fn the_committed_fits_of_the_shipped_examples_are_what_the_code_makes() {
    let examples: Vec<PathBuf> = [
        "brightener",
        "green-dye",
        "plain",
        "red-pigment",
        "two-dyes",
    ]
    .iter()
    .map(|name| PathBuf::from(format!("data/{name}.csv")))
    .collect();
    refit_matches_committed(&examples, &[], &repository().join("fits"), "committed-data");
    // scripts/regenerate.sh's model search: every example but the plain reflector.
    let searched: Vec<PathBuf> = examples
        .iter()
        .filter(|p| !p.ends_with("plain.csv"))
        .cloned()
        .collect();
    refit_matches_committed(
        &searched,
        &["--max-delta-e", "1"],
        &repository().join("fits/models"),
        "committed-models",
    );
}

#[test]
fn the_committed_fits_of_the_shared_surfaces_are_what_the_code_makes() {
    // Skips, saying so, where ../shared is absent.
    let Some(files) = common::measured_files() else {
        return;
    };
    refit_matches_committed(
        &files,
        &[],
        &repository().join("fits/measured"),
        "committed-measured",
    );
    refit_matches_committed(
        &files,
        &["--max-delta-e", "1"],
        &repository().join("fits/models/measured"),
        "committed-models-measured",
    );
}

/// `fits/class.csv`'s rows of `names`, each without its time (the last column).
fn class_rows_without_times(csv: &str, names: &[&str]) -> Vec<String> {
    csv.lines()
        .filter(|line| names.iter().any(|n| line.starts_with(&format!("{n},"))))
        .map(|line| {
            line.rsplit_once(',')
                .map_or(line, |(rest, _)| rest)
                .to_string()
        })
        .collect()
}

#[test]
fn the_committed_class_sweep_is_what_the_code_makes() {
    // README and docs/results.md quote fits/class.md, written with fits/class.csv. By ΔE2000
    // to the truth on the default seed: case085 the grid fit's worst (two dyes, one
    // fitted), case113 the search's, case062 the noise-aware search's and the default's,
    // case127 a one-dye case the noise-aware search pulls (the search's sixth worst), and
    // case000 the first of the draw.
    let names = ["case000", "case062", "case085", "case113", "case127"];
    let out = common::temp_dir("committed-class");
    let csv = out.join("class.csv");
    common::succeed(
        common::fluorite()
            .current_dir(repository())
            .args(["class", "-q", "--case", &names.join(","), "--report"])
            .arg(out.join("class.md"))
            .arg("--csv")
            .arg(&csv),
    );
    let made = std::fs::read_to_string(&csv).unwrap();
    let committed = std::fs::read_to_string(repository().join("fits/class.csv")).unwrap();
    let made_rows = class_rows_without_times(&made, &names);
    assert_eq!(made_rows.len(), 4 * names.len(), "{made}");
    assert_eq!(
        made_rows,
        class_rows_without_times(&committed, &names),
        "`fluorite class --case {}` against fits/class.csv: run scripts/regenerate.sh --timings",
        names.join(",")
    );
}
