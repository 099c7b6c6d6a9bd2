//! Committed outputs stay put when regenerated: the synth command in
//! `scripts/regenerate.sh` rewrites `data/` byte for byte, and fitting a shipped example
//! twice writes byte-identical material JSON (no wall-clock time in it).

use crate::common;

use std::path::Path;
use std::process::Command;

use common::repository;

fn fluorite() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_fluorite"));
    command.current_dir(repository());
    command
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// The arguments of the `fluorite synth` line of scripts/regenerate.sh (after
/// `$fluorite`), so that the test runs exactly the documented command.
fn regenerate_synth_arguments() -> Vec<String> {
    let script = std::fs::read_to_string(repository().join("scripts/regenerate.sh")).unwrap();
    let line = script
        .lines()
        .find(|l| l.trim_start().starts_with("$fluorite synth"))
        .expect("scripts/regenerate.sh has a `$fluorite synth` line");
    line.split_whitespace().skip(1).map(String::from).collect()
}

#[test]
fn the_documented_synth_command_reproduces_data_byte_for_byte() {
    let arguments = regenerate_synth_arguments();
    assert!(
        arguments.iter().any(|a| a == "data/"),
        "the synth line writes data/: {arguments:?}"
    );
    let out = common::temp_dir("synth");
    let arguments: Vec<String> = arguments
        .into_iter()
        .map(|a| {
            if a == "data/" {
                format!("{}/", out.display())
            } else {
                a
            }
        })
        .collect();
    common::succeed(fluorite().args(&arguments));
    let shipped = repository().join("data");
    assert_eq!(files_in(&out), files_in(&shipped), "the same files");
    for name in files_in(&shipped) {
        let made = std::fs::read(out.join(&name)).unwrap();
        let committed = std::fs::read(shipped.join(&name)).unwrap();
        assert!(
            made == committed,
            "{name}: `fluorite {}` writes different bytes than data/{name}",
            arguments.join(" ")
        );
    }
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn fitting_a_shipped_example_twice_writes_identical_json_without_timings() {
    let first = common::temp_dir("fit-first");
    let second = common::temp_dir("fit-second");
    for out in [&first, &second] {
        common::succeed(
            fluorite()
                .args(["fit", "data/red-pigment.csv", "-q", "-o"])
                .arg(out),
        );
    }
    let a = std::fs::read(first.join("red-pigment.json")).unwrap();
    let b = std::fs::read(second.join("red-pigment.json")).unwrap();
    assert!(
        a == b,
        "two fits of data/red-pigment.csv wrote different JSON"
    );
    let text = String::from_utf8(a).unwrap();
    assert!(
        !text.contains("\"seconds\""),
        "a wall-clock time is written"
    );
    // The timing is still read from older files that hold one.
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    value["fit"]["seconds"] = serde_json::json!(0.25);
    let material: fluorite::Material = serde_json::from_value(value).unwrap();
    assert_eq!(material.fit.unwrap().seconds, 0.25);
    for dir in [first, second] {
        std::fs::remove_dir_all(dir).unwrap();
    }
}
