//! Every quantity a file or an option sets has a range the physics allows: a typo ends in
//! an error naming the place and the range, never in a run that does not end. Commands run
//! the built binary under a watchdog (a hang fails the test instead of stalling the suite;
//! the bound is generous, this is no timing assert).

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// Far above what any of these commands needs; only a hang reaches it.
const WATCHDOG: Duration = Duration::from_secs(120);

use crate::common::fluorite;

/// Runs `command`, killing it at the watchdog; panics if it had to.
fn run_bounded(command: &mut Command) -> Output {
    let mut child = command
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    let start = Instant::now();
    loop {
        if child.try_wait().expect("waits").is_some() {
            return child.wait_with_output().expect("output");
        }
        if start.elapsed() > WATCHDOG {
            let _ = child.kill();
            panic!("{command:?} was still running after {WATCHDOG:?}: a hang");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs a command that must be refused with exit 2 and one line on stderr; returns it.
fn refused(command: &mut Command) -> String {
    let out = run_bounded(command);
    let stderr = String::from_utf8_lossy(&out.stderr).trim().to_string();
    assert_eq!(out.status.code(), Some(2), "{command:?}: {stderr}");
    assert_eq!(stderr.lines().count(), 1, "{command:?}: {stderr}");
    stderr
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_wavelength_typo_in_a_wide_csv_names_the_cell_and_the_range() {
    let dir = common::temp_dir("wide");
    for (typo, shown) in [
        ("1e12", "1e12 nm"),
        ("1e300", "1e300 nm"),
        (
            "123456789012345678901234567890123456789012",
            "1.2345678901234568e41 nm",
        ),
    ] {
        let path = write(
            &dir,
            "huge.csv",
            &format!("ex\\em,300,310\n300,0.9,0.01\n{typo},0.01,0.9\n"),
        );
        let message = refused(
            fluorite()
                .arg("fit")
                .arg(&path)
                .arg("-o")
                .arg(dir.join("out.json")),
        );
        // The row wavelength is line 3, column 1.
        assert!(message.contains("huge.csv:3:1"), "{message}");
        assert!(message.contains(shown), "{message}");
        assert!(message.contains("100–100,000 nm"), "{message}");
        assert!(!dir.join("out.json").exists(), "nothing is written");
    }
    // A column wavelength of the header: line 1, column 3.
    let path = write(
        &dir,
        "header.csv",
        "ex\\em,300,3e9\n300,0.9,0.01\n310,0.01,0.9\n",
    );
    let message = refused(fluorite().arg("fit").arg(&path));
    assert!(message.contains("header.csv:1:3"), "{message}");
    assert!(message.contains("100–100,000 nm"), "{message}");
}

#[test]
fn a_garbled_row_of_a_real_file_is_refused_at_its_line() {
    let Some(source) = common::measured("postit_pink.csv") else {
        return;
    };
    let text = std::fs::read_to_string(source).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // The last row that starts with a number: garble its wavelength into 42 digits.
    let last = lines
        .iter()
        .rposition(|l| {
            l.split(',')
                .next()
                .is_some_and(|c| c.trim().parse::<f64>().is_ok())
        })
        .expect("a data row");
    let mut mutated: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    let rest = mutated[last].split_once(',').unwrap().1.to_string();
    mutated[last] = format!("{},{rest}", "9".repeat(42));
    let dir = common::temp_dir("postit");
    let path = write(&dir, "garbled.csv", &(mutated.join("\n") + "\n"));
    let message = refused(fluorite().arg("fit").arg(&path));
    assert!(
        message.contains(&format!("garbled.csv:{}:1", last + 1)),
        "{message}"
    );
    assert!(message.contains("100–100,000 nm"), "{message}");
}

#[test]
fn a_long_table_and_a_bfc_grid_line_meet_the_same_range() {
    let dir = common::temp_dir("long-bfc");
    let long = write(
        &dir,
        "long.csv",
        "excitation,emission,value\n300,300,0.9\n300,310,0.01\n310,310,0.9\n310,1e15,0.01\n",
    );
    let message = refused(fluorite().arg("fit").arg(&long).args(["--format", "long"]));
    assert!(message.contains("long.csv:5:2"), "{message}");
    assert!(message.contains("100–100,000 nm"), "{message}");

    let Some(source) = common::measured("CIBA12.BFC") else {
        return;
    };
    let text = std::fs::read_to_string(source).unwrap();
    let lines: Vec<String> = text.lines().map(str::to_string).collect();
    let header = lines
        .iter()
        .position(|l| l.trim().eq_ignore_ascii_case("BFC-450 Matrix File"))
        .unwrap();
    let grid = (header + 1..lines.len())
        .find(|&k| !lines[k].trim().is_empty() && !lines[k].trim_start().starts_with(';'))
        .unwrap();
    let mut fields: Vec<String> = lines[grid].split_whitespace().map(str::to_string).collect();
    fields[1] = "1e12".into(); // em_end
    let mut mutated = lines.clone();
    mutated[grid] = fields.join(" ");
    let path = write(&dir, "grid.BFC", &(mutated.join("\n") + "\n"));
    let message = refused(fluorite().arg("fit").arg(&path));
    assert!(
        message.contains(&format!("grid.BFC:{}:2", grid + 1)),
        "{message}"
    );
    assert!(message.contains("em_end"), "{message}");
    assert!(message.contains("100–100,000 nm"), "{message}");
}

#[test]
fn a_wide_range_inside_the_limits_ends_with_a_fit() {
    // 300 nm and 99,000 nm: allowed, but the work a fit builds from the range (fine grids,
    // colour integrals) is bounded by the limits, not by the span.
    let dir = common::temp_dir("wide-range");
    let path = write(
        &dir,
        "wide.csv",
        "ex\\em,300,99000\n300,0.9,0.01\n99000,0.001,0.9\n",
    );
    let out = run_bounded(
        fluorite()
            .arg("fit")
            .arg(&path)
            .arg("-o")
            .arg(dir.join("wide.json")),
    );
    let code = out.status.code();
    assert!(
        code == Some(0) || code == Some(2),
        "exit {code:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let search = run_bounded(
        fluorite()
            .arg("fit")
            .arg(&path)
            .args(["--model", "auto", "-o"])
            .arg(dir.join("wide-auto.json")),
    );
    let code = search.status.code();
    assert!(code == Some(0) || code == Some(2), "exit {code:?}");
}

#[test]
fn options_beyond_their_ranges_are_refused_naming_the_option() {
    let message = refused(fluorite().args([
        "fit",
        "data/red-pigment.csv",
        "--max-iterations",
        "1000000000",
    ]));
    assert!(message.contains("--max-iterations"), "{message}");
    assert!(message.contains("1000000"), "{message}");

    let dir = common::temp_dir("render");
    let message = refused(
        fluorite()
            .args([
                "render",
                "fits/red-pigment.json",
                "--spp",
                "16384",
                "--size",
                "16384x16384",
                "-o",
            ])
            .arg(dir.join("r.png")),
    );
    assert!(message.contains("--spp"), "{message}");
    assert!(message.contains("camera paths"), "{message}");
}

#[test]
fn a_material_or_light_with_a_wavelength_typo_is_refused() {
    let dir = common::temp_dir("material");
    let text = std::fs::read_to_string("fits/red-pigment.json").unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let grid = json["reflectance"]["wavelength_nm"]
        .as_array_mut()
        .expect("the material's reflectance grid");
    let last = grid.len() - 1;
    grid[last] = serde_json::json!(1e12);
    let path = write(&dir, "typo.json", &serde_json::to_string(&json).unwrap());
    // check reports it as a broken law (exit 1), naming the sample and the range.
    let out = run_bounded(fluorite().arg("check").arg(&path));
    let report = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{report}");
    assert!(
        report.contains("reflectance.wavelength_nm[") && report.contains("100–100,000 nm"),
        "{report}"
    );
    let message = refused(
        fluorite()
            .arg("render")
            .arg(&path)
            .args(["--size", "8x8", "--spp", "1", "-o"])
            .arg(dir.join("r.png")),
    );
    assert!(message.contains("100–100,000 nm"), "{message}");

    let light = write(
        &dir,
        "light.csv",
        "wavelength_nm,power\n400,1\n500,1\n6e13,1\n",
    );
    let message = refused(
        fluorite()
            .args(["fit", "data/red-pigment.csv", "--lights"])
            .arg(format!("d65,{}", light.display()))
            .arg("-o")
            .arg(dir.join("x.json")),
    );
    assert!(message.contains("light.csv:4:1"), "{message}");
    assert!(message.contains("100–100,000 nm"), "{message}");
}

#[test]
fn ctrl_c_ends_a_long_run_with_nothing_half_written() {
    let dir = common::temp_dir("interrupt");
    // A class sweep of 100,000 cases runs for hours: it is certainly running when the
    // interrupt comes.
    let mut child = fluorite()
        .args(["class", "--cases", "100000", "--report"])
        .arg(dir.join("class.md"))
        .arg("--csv")
        .arg(dir.join("class.csv"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary starts");
    std::thread::sleep(Duration::from_millis(1500));
    let status = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(status.success());
    let start = Instant::now();
    while child.try_wait().expect("waits").is_none() {
        assert!(
            start.elapsed() < WATCHDOG,
            "the run did not end after Ctrl-C"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().expect("output");
    assert_eq!(out.status.code(), Some(130));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("interrupted"), "{stderr}");
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    assert!(left.is_empty(), "files left behind: {left:?}");
}
