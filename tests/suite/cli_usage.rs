//! The command line's first hour: usage errors as clap renders them (what is missing,
//! suggestions, possible values, the subcommand's usage) with exit code 2, help texts that
//! name their guide page, the hint when a pinned yield breaks photon conservation, and
//! `plot` finding the matrix a material was fitted to.

use crate::common;

use std::path::Path;
use std::process::{Command, Output};

fn fluorite(args: &[&str]) -> Output {
    run_in(args, Path::new(env!("CARGO_MANIFEST_DIR")))
}

use crate::common::{run_in, stderr};

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Runs a command line clap must refuse: exit code 2, nothing on stdout, stderr holding
/// each of `needles`, `usage` (the subcommand's usage line where clap gives one) and the
/// pointers to `--help` and the guide page `page`.
fn assert_usage_error(args: &[&str], usage: &str, page: &str, needles: &[&str]) {
    let o = fluorite(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(o.stdout.is_empty(), "{args:?}: {}", stdout(&o));
    for needle in needles
        .iter()
        .chain(&[usage, "For more information, try '--help'"])
    {
        assert!(err.contains(needle), "{args:?}: no {needle:?} in\n{err}");
    }
    assert!(
        err.trim_end().ends_with(&format!("More: {page}")),
        "{args:?}: the guide page {page} should close\n{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn fit_without_input_names_the_missing_argument() {
    assert_usage_error(
        &["fit"],
        "Usage: fluorite fit",
        "docs/fitting.md",
        &[
            "the following required arguments were not provided",
            "<INPUTS>...",
        ],
    );
}

#[test]
fn a_mistyped_flag_gets_the_flag_it_resembles() {
    assert_usage_error(
        &["fit", "data/green-dye.csv", "--plto"],
        "Usage: fluorite fit",
        "docs/fitting.md",
        &[
            "unexpected argument '--plto'",
            "similar argument exists: '--plot'",
        ],
    );
}

#[test]
fn a_bad_value_lists_the_possible_values() {
    assert_usage_error(
        &["fit", "data/green-dye.csv", "--solver", "newton"],
        // clap gives no usage line for a bad value: the value's list is the help.
        "error: invalid value",
        "docs/fitting.md",
        &[
            "invalid value 'newton' for '--solver <SOLVER>'",
            "[possible values: ",
            "lbfgs",
            "gauss-newton",
        ],
    );
}

#[test]
fn export_without_its_output_names_it() {
    assert_usage_error(
        &["export", "fits/green-dye.json", "--to", "mitsuba"],
        "Usage: fluorite export",
        "docs/export.md",
        &[
            "the following required arguments were not provided",
            "--out <OUT>",
        ],
    );
}

#[test]
fn an_unknown_subcommand_points_at_the_index() {
    assert_usage_error(
        &["fitt", "data/green-dye.csv"],
        "Usage: fluorite",
        "docs/README.md",
        &[
            "unrecognized subcommand 'fitt'",
            "similar subcommand exists: 'fit'",
        ],
    );
}

#[test]
fn help_and_version_succeed() {
    for args in [
        &["--help"][..],
        &["--version"],
        &["fit", "--help"],
        &["help"],
    ] {
        let o = fluorite(args);
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        assert!(!o.stdout.is_empty() && o.stderr.is_empty(), "{args:?}");
    }
    let version = stdout(&fluorite(&["--version"]));
    assert_eq!(
        version.trim(),
        format!("fluorite {}", env!("CARGO_PKG_VERSION"))
    );
}

/// The guide's pages (docs-pages.md); each help names one of them.
const GUIDE: [&str; 13] = [
    "docs/README.md",
    "docs/fitting.md",
    "docs/images.md",
    "docs/eem.md",
    "docs/series.md",
    "docs/export.md",
    "docs/render.md",
    "docs/material.md",
    "docs/formats.md",
    "docs/how-it-works.md",
    "docs/results.md",
    "docs/troubleshooting.md",
    "docs/plots.md",
];

/// The `docs/….md` paths `text` names.
fn pages_named(text: &str) -> Vec<String> {
    let pattern = regex::Regex::new(r"docs/[a-z-]+\.md|docs/README\.md").unwrap();
    pattern
        .find_iter(text)
        .map(|m| m.as_str().to_string())
        .collect()
}

/// Asserts that `page` is one of the guide's, and a file in the repository once the guide
/// has landed there.
fn assert_guide_page(page: &str, what: &str) {
    assert!(
        GUIDE.contains(&page),
        "{what} names {page}, not a guide page"
    );
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    if root.join("docs/README.md").exists() {
        assert!(
            root.join(page).exists(),
            "{what} names {page}, which is missing"
        );
    }
}

#[test]
fn every_help_ends_with_its_guide_page() {
    let top = stdout(&fluorite(&["--help"]));
    assert!(top.trim_end().ends_with("More: docs/README.md"), "{top}");
    // The subcommands as the top-level help lists them, so a new one cannot go unpaged.
    let listed: Vec<&str> = top
        .split("Commands:")
        .nth(1)
        .expect("the help lists the subcommands")
        .lines()
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .collect();
    let expected = [
        ("fit", "docs/fitting.md"),
        ("fit-image", "docs/images.md"),
        ("image-diff", "docs/images.md"),
        ("synth", "docs/formats.md"),
        ("render", "docs/render.md"),
        ("plot", "docs/plots.md"),
        ("check", "docs/material.md"),
        ("export", "docs/export.md"),
        ("import-spectra", "docs/export.md"),
        ("bench", "docs/results.md"),
        ("stability", "docs/results.md"),
        ("class", "docs/results.md"),
        ("bands", "docs/fitting.md"),
    ];
    assert_eq!(
        listed,
        expected.iter().map(|(name, _)| *name).collect::<Vec<_>>()
    );
    for (name, page) in expected {
        for flag in ["--help", "-h"] {
            let o = fluorite(&[name, flag]);
            let help = stdout(&o);
            assert_eq!(o.status.code(), Some(0), "{name} {flag}");
            assert!(
                help.contains(&format!("More: {page}")),
                "{name} {flag} should name {page}:\n{help}"
            );
            for named in pages_named(&help) {
                assert_guide_page(&named, &format!("{name} {flag}"));
            }
        }
    }
}

#[test]
fn fit_help_describes_the_input_layouts() {
    let help = stdout(&fluorite(&["fit", "--help"]));
    for layout in [
        "wide CSV",
        "corner cell",
        "Rows are excitation by default",
        "--rows",
        "long CSV",
        "excitation_nm, emission_nm, value",
        "BFC-450",
        "WebFluor",
        "OpenEXR",
        "raw EEMs",
        "docs/formats.md",
        "docs/eem.md",
        "docs/series.md",
    ] {
        assert!(
            help.contains(layout),
            "fit --help lacks {layout:?}:\n{help}"
        );
    }
}

#[test]
fn a_pinned_yield_beyond_the_photon_limit_suggests_the_photon_form() {
    let dir = common::temp_dir("yield");
    let out = dir.join("green-dye.json");
    let out_arg = out.to_str().unwrap();
    // green-dye absorbs down to 300 nm and emits around 531 nm: photons allow an energy
    // yield Q of at most 300/531 ≈ 0.565, so 0.92 must be a photon yield Φ.
    let pinned = [
        "fit",
        "data/green-dye.csv",
        "--model",
        "tabulated",
        "--quantum-yield",
        "0.92",
        "-o",
        out_arg,
    ];
    let (code, message) = common::refused(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(pinned)
            .current_dir(env!("CARGO_MANIFEST_DIR")),
    );
    assert_eq!(code, Some(2), "{message}");
    for needle in [
        "fluorite: error: --quantum-yield: 0.92 breaks photon conservation",
        "pass --yield photon to pin Φ instead of Q",
    ] {
        assert!(message.contains(needle), "no {needle:?} in {message}");
    }
    assert!(!out.exists(), "a refused fit writes nothing");
    // The advice works: pinned as a photon yield, the fit runs and keeps Φ = 0.92.
    let followed: Vec<&str> = pinned
        .iter()
        .copied()
        .chain(["--yield", "photon"])
        .collect();
    common::succeed(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(&followed)
            .current_dir(env!("CARGO_MANIFEST_DIR")),
    );
    let material = fluorite::Material::load(&out).unwrap();
    assert_eq!(material.fluorophores.len(), 1);
    let gauge = &material.fit.as_ref().unwrap().gauge;
    assert!(gauge.contains("Φ = 0.92"), "{gauge}");
}

/// A temporary folder holding a copy of `data/green-dye.csv` fitted there (so the
/// material records the relative path `green-dye.csv`); returns the folder.
fn fitted_copy(tag: &str) -> common::TempDir {
    let dir = common::temp_dir(tag);
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/green-dye.csv");
    std::fs::copy(&data, dir.join("green-dye.csv")).unwrap();
    common::succeed(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args([
                "fit",
                "green-dye.csv",
                "--model",
                "tabulated",
                "-q",
                "-o",
                "green-dye.json",
            ])
            .current_dir(&dir),
    );
    dir
}

fn sha256_of(path: &Path) -> String {
    use sha2::{Digest, Sha256};
    Sha256::digest(std::fs::read(path).unwrap())
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn plot_finds_the_recorded_source_and_refuses_a_changed_one() {
    let dir = fitted_copy("plot-source");
    let source = dir.join("green-dye.csv");
    let recorded = sha256_of(&source);
    let material = fluorite::Material::load(&dir.join("green-dye.json")).unwrap();
    let fit = material.fit.as_ref().unwrap();
    assert_eq!(
        (fit.source.as_str(), fit.source_sha256.as_str()),
        ("green-dye.csv", recorded.as_str())
    );

    // Unchanged: the figures that need the matrix are drawn, and stderr says from where.
    let o = run_in(&["plot", "green-dye.json"], &dir);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("plotting against green-dye.csv, the material's recorded source"),
        "{err}"
    );
    assert!(!err.contains("needs the measured matrix"), "{err}");
    let residuals = dir.join("green-dye-residuals.png");
    assert!(residuals.exists(), "{}", stdout(&o));
    let colour = dir.join("green-dye-colour.png");
    assert!(colour.exists(), "{}", stdout(&o));

    // Edited after the fit: a one-line error naming both digests and --data.
    let text = std::fs::read_to_string(&source).unwrap();
    std::fs::write(&source, text.replacen("0.", "0.5", 40)).unwrap();
    let edited = sha256_of(&source);
    assert_ne!(edited, recorded);
    std::fs::remove_file(&residuals).unwrap();
    let (code, message) = common::refused(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(["plot", "green-dye.json"])
            .current_dir(&dir),
    );
    assert_eq!(code, Some(2));
    for needle in [
        "has changed since the fit",
        &format!("SHA-256 now {edited}"),
        &format!("recorded {recorded}"),
        "--data FILE",
    ] {
        assert!(message.contains(needle), "no {needle:?} in {message}");
    }
    assert!(!residuals.exists(), "a refused plot writes nothing");

    // Gone: the figures that need it are skipped, and the note names the recorded path.
    std::fs::remove_file(&source).unwrap();
    let o = run_in(&["plot", "green-dye.json"], &dir);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("the recorded source green-dye.csv is not there"),
        "{err}"
    );
    assert!(
        err.contains("residual map: needs the measured matrix (--data FILE)"),
        "{err}"
    );
    assert!(!residuals.exists());
}
