//! `fluorite fit` and `fluorite synth` from the command line: outputs, exit codes, and
//! bad input (one-line message, non-zero exit, no output file).

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{run_in as fluorite, stderr};

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = walk(dir);
    v.sort();
    v
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                out.extend(walk(&p));
            } else {
                out.push(p);
            }
        }
    }
    out
}

/// Asserts a failed run: exit code 2, one line on stderr naming `needle`, no new files.
fn assert_fails_cleanly(dir: &Path, args: &[&str], needles: &[&str]) {
    let before = files_in(dir);
    let o = fluorite(args, dir);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(
        err.trim_end().lines().count(),
        1,
        "one line expected: {err}"
    );
    assert!(
        !err.contains("panicked") && !err.contains("backtrace"),
        "{err}"
    );
    for n in needles {
        assert!(
            err.contains(n),
            "{args:?}: message should name {n:?}: {err}"
        );
    }
    assert_eq!(files_in(dir), before, "{args:?} left files behind");
}

#[test]
fn synth_then_fit_writes_materials_and_summaries() {
    let dir = tempfile::tempdir().unwrap();
    let o = fluorite(
        &["synth", "--out", "data", "--preset", "green-dye,plain"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("data/green-dye.csv").is_file());
    assert!(dir.path().join("data/green-dye.truth.json").is_file());
    let o = fluorite(
        &["fit", "data/green-dye.csv", "data/plain.csv", "-o", "out/"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("k = c·Q")
            && stdout.contains("ΔE2000")
            && stdout.contains("plain reflector"),
        "{stdout}"
    );
    let text = std::fs::read_to_string(dir.path().join("out/green-dye.json")).unwrap();
    let material: fluorite::Material = serde_json::from_str(&text).unwrap();
    material.validate().unwrap();
    let fit = material.fit.unwrap();
    assert_eq!(fit.solver, "lbfgs");
    assert!(fit.source.ends_with("green-dye.csv"));
    assert_eq!(fit.source_sha256.len(), 64);
    for light in ["d65", "a", "f11", "uv"] {
        assert!(fit.delta_e2000.contains_key(light));
    }
    // The summary says what the colour is judged against and that every cell was fitted.
    assert!(stdout.contains("every measured cell fitted"), "{stdout}");
    assert!(
        stdout.contains("against every cell as measured"),
        "{stdout}"
    );
    assert!(stdout.contains("yield form: energy form"), "{stdout}");
    // With missing cells the summary and the material say how many were filled.
    let o = fluorite(
        &[
            "synth",
            "--out",
            "gaps",
            "--preset",
            "green-dye",
            "--missing",
            "0.05",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = fluorite(
        &["fit", "gaps/green-dye.csv", "-o", "gaps/fit.json"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    let text = std::fs::read_to_string(dir.path().join("gaps/fit.json")).unwrap();
    let gaps: fluorite::Material = serde_json::from_str(&text).unwrap();
    let filled = gaps.fit.as_ref().unwrap().reference_filled_cells;
    let m = fluorite::formats::read(
        &dir.path().join("gaps/green-dye.csv"),
        &fluorite::formats::ReadOptions::default(),
    )
    .unwrap();
    let missing = m.values.iter().filter(|v| !v.is_finite()).count();
    assert!(missing > 0);
    assert_eq!(filled, missing);
    assert!(
        stdout.contains(&format!("{missing} missing cells filled from the model")),
        "{stdout}"
    );
    // Default output: fits/<stem>.json; --strict exits 1 on the plain reflector's warning.
    let o = fluorite(&["fit", "data/plain.csv", "--strict", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(dir.path().join("fits/plain.json").is_file());
}

#[test]
fn pinned_yield_that_breaks_photon_conservation_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    assert!(
        fluorite(
            &["synth", "--out", "d", "--preset", "red-pigment"],
            dir.path()
        )
        .status
        .success()
    );
    assert_fails_cleanly(
        dir.path(),
        &[
            "fit",
            "d/red-pigment.csv",
            "--quantum-yield",
            "0.99",
            "-o",
            "m.json",
        ],
        &["--quantum-yield", "photon"],
    );
    assert_fails_cleanly(
        dir.path(),
        &["fit", "d/red-pigment.csv", "--quantum-yield", "1.5"],
        &["--quantum-yield", "(0, 1]"],
    );
}

#[test]
fn bad_input_files_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cases: [(&str, &str, &[&str]); 8] = [
        ("empty.csv", "", &["empty.csv", "empty"]),
        (
            "ragged.csv",
            "ex\\em,400,410,420\n300,0.1,0.2,0.3\n310,0.1,0.2\n",
            &["ragged.csv:3", "ragged"],
        ),
        (
            "text.csv",
            "ex\\em,400,410\n300,0.1,abc\n",
            &["text.csv:2:3", "abc"],
        ),
        (
            "dup.csv",
            "ex\\em,400,400\n300,0.1,0.2\n",
            &["dup.csv:1", "400"],
        ),
        (
            "unsorted.csv",
            "ex\\em,400,410\n310,0.1,0.2\n300,0.1,0.2\n",
            &["unsorted.csv:3", "300"],
        ),
        (
            "negative.csv",
            "ex\\em,-400,410\n300,0.1,0.2\n",
            &["negative.csv:1", "-400"],
        ),
        (
            "nocell.csv",
            "ex\\em,400,410\n300,NaN,NA\n310,,NaN\n",
            &["nocell.csv", "no"],
        ),
        (
            "inf.csv",
            "ex\\em,400,410\n300,0.1,inf\n",
            &["inf.csv:2:3", "infinit"],
        ),
    ];
    for (name, content, needles) in cases {
        std::fs::write(d.join(name), content).unwrap();
        assert_fails_cleanly(d, &["fit", name, "-o", "out.json"], needles);
        std::fs::remove_file(d.join(name)).unwrap();
    }
    std::fs::write(d.join("t.bfc"), "VEC_01\t1\r\nBFC-450 Matrix File\r\n;x\r\n380\t390\t10\t2\t380\t10\r\nr:c:\t380\t390\r\n380\t0.5\t0.01\r\n").unwrap();
    assert_fails_cleanly(
        d,
        &["fit", "t.bfc", "-o", "out.json"],
        &["t.bfc", "truncated"],
    );
    std::fs::remove_file(d.join("t.bfc")).unwrap();
    assert_fails_cleanly(d, &["fit", "missing.csv"], &["missing.csv"]);
}

#[test]
fn bad_options_fail_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(
        fluorite(
            &["synth", "--out", "in", "--preset", "green-dye,red-pigment"],
            d
        )
        .status
        .success()
    );
    assert_fails_cleanly(
        d,
        &["fit", "in/green-dye.csv", "--guard=-5", "-o", "x.json"],
        &["--guard"],
    );
    assert_fails_cleanly(
        d,
        &[
            "fit",
            "in/green-dye.csv",
            "--lights",
            "d65,nolight",
            "-o",
            "x.json",
        ],
        &["nolight"],
    );
    assert_fails_cleanly(
        d,
        &[
            "fit",
            "in/green-dye.csv",
            "in/red-pigment.csv",
            "-o",
            "one.json",
        ],
        &["folder"],
    );
    assert_fails_cleanly(
        d,
        &["synth", "--out", "s", "--preset", "nonsense"],
        &["nonsense", "green-dye"],
    );
}

/// `fit -q --plot --render` writes the figures and the preview but prints nothing.
#[test]
fn quiet_fit_with_plot_and_render_prints_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let o = fluorite(
        &["synth", "--out", "data", "--preset", "green-dye"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = fluorite(
        &[
            "fit",
            "data/green-dye.csv",
            "-o",
            "out/green-dye.json",
            "--plot",
            "--render",
            "-q",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    for file in ["green-dye.json", "green-dye.png", "green-dye-residuals.png"] {
        assert!(dir.path().join("out").join(file).is_file(), "{file}");
    }
}

/// Flags of single fits are refused by `--joint`, naming the flag, rather than ignored.
#[test]
fn joint_fit_refuses_single_fit_flags() {
    let dir = tempfile::tempdir().unwrap();
    let o = fluorite(
        &[
            "synth",
            "--out",
            "s",
            "--preset",
            "green-dye",
            "--concentrations",
            "0.3,0.8",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for flag in [&["--plot"][..], &["--quantum-yield", "0.5"], &["--strict"]] {
        let mut args = vec![
            "fit",
            "s/green-dye-c0.3.csv",
            "s/green-dye-c0.8.csv",
            "--joint",
        ];
        args.extend_from_slice(flag);
        let (_, message) = common::refused(
            Command::new(env!("CARGO_BIN_EXE_fluorite"))
                .args(&args)
                .current_dir(dir.path()),
        );
        assert!(
            message.contains(flag[0]) && message.contains("single fits"),
            "{message}"
        );
    }
}
