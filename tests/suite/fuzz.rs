//! Fuzzing (issue 21): 5,000 deterministic mutants of every format's example files
//! (shipped `data/*.csv`, `../shared/data` BFC-450, wide CSV, WebFluor, staRdom, Dorrit,
//! absorbance and spectra files, material JSON, and a bispectral EXR, a long CSV and a
//! BFC-450 file fluorite writes) go through the library: read → prepare → fit, or load →
//! check → render at 8×8. Each must end with Ok or a one-line error, within a time
//! budget, without a panic and without holding more than 1 GiB at once.
//! `cargo run --release --example fuzz` runs the same mutator for a long campaign
//! (scripts/fuzz-campaign.sh).

#[path = "fuzz/harness/mod.rs"]
mod harness;

use std::sync::Arc;
use std::time::Duration;

use harness::corpus::Kind;
use harness::run::{Campaign, Ending, Harness, campaign, summary};

/// Mutants the suite runs.
const MUTANTS: u64 = 5_000;

/// A mutant's budget in the dev profile: release mutants take at most a few hundred ms
/// (see scripts/fuzz-campaign.sh); this allows for opt-level 1 and a loaded machine while
/// still turning a hang into a named failure.
const DEV_BUDGET: Duration = Duration::from_secs(30);

fn workers() -> usize {
    std::thread::available_parallelism().map_or(2, |n| n.get().max(2))
}

/// Every seed goes through its path unmutated without an error: the mutants start from
/// files the library accepts, so a refusal is the mutation's doing.
#[test]
fn every_seed_is_accepted_unmutated() {
    let harness = Harness::new();
    for note in &harness.skipped {
        crate::common::skipped(note);
    }
    let kinds = [
        Kind::Matrix,
        Kind::Material,
        Kind::Spectra,
        Kind::Absorbance,
    ];
    for kind in kinds {
        let n = harness.seeds.iter().filter(|s| s.kind == kind).count();
        let expected_without_shared = matches!(kind, Kind::Spectra | Kind::Absorbance);
        assert!(
            n > 0 || (expected_without_shared && !harness.skipped.is_empty()),
            "no {kind:?} seed"
        );
    }
    let scratch = std::env::temp_dir().join(format!("fluorite-fuzz-seeds-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).unwrap();
    for seed in &harness.seeds {
        assert_eq!(
            harness.run(seed, &seed.bytes, &scratch),
            Ending::Accepted,
            "{} unmutated",
            seed.origin
        );
    }
    let _ = std::fs::remove_dir_all(&scratch);
}

/// The campaign in miniature: 5,000 mutants, none panics, hangs, runs over its
/// budget, passes the allocation bound or answers with a multi-line error. Most mutants
/// must be refused and some accepted, or the mutator is not reaching both paths.
#[test]
fn five_thousand_mutants_end_in_ok_or_a_one_line_error() {
    let harness = Arc::new(Harness::new());
    let failures_dir =
        std::env::temp_dir().join(format!("fluorite-fuzz-failures-{}", std::process::id()));
    let report = campaign(
        &harness,
        &Campaign {
            seed: 21,
            first: 0,
            count: MUTANTS,
            workers: workers(),
            budget: DEV_BUDGET,
            failures_dir: failures_dir.clone(),
            max_failures: 20,
            progress_every: 1000,
        },
    );
    let text = summary(&report);
    eprintln!("{text}");
    assert!(report.failures.is_empty(), "{text}");
    assert_eq!(report.mutants, MUTANTS, "{text}");
    assert_eq!(report.accepted + report.refused, MUTANTS);
    assert!(
        report.accepted >= MUTANTS / 20 && report.refused >= MUTANTS / 20,
        "the mutants should reach both outcomes: {text}"
    );
    let _ = std::fs::remove_dir_all(&failures_dir);
}

/// Found by this harness (seed 21, mutants 180 and 540): a BFC-450 cell of −1e308 made the
/// fit's sums of squares infinite and L-BFGS's line search loop forever. Such a cell is
/// now refused on reading, naming the cell; one just inside the bound still fits.
#[test]
fn a_cell_whose_square_overflows_is_refused_not_fitted_forever() {
    let Some(path) = harness::corpus::shared_data().map(|d| d.join("measured/HERPICER.BFC")) else {
        crate::common::skipped("../shared/data is absent");
        return;
    };
    let text = std::fs::read_to_string(&path).unwrap();
    // Line 16 is the emission row at 410 nm; its fourth field is excitation 320 nm.
    let with_cell = |value: &str| {
        let mut lines: Vec<String> = text.split('\n').map(str::to_string).collect();
        let mut fields: Vec<&str> = lines[15].split('\t').collect();
        assert_eq!(fields[0], "410");
        fields[3] = value;
        lines[15] = fields.join("\t");
        lines.join("\n").into_bytes()
    };
    let options = fluorite::formats::ReadOptions::default();
    let e = fluorite::formats::read_bytes(&with_cell("-1e308"), &path, &options)
        .and_then(|m| m.validate())
        .expect_err("a cell of -1e308 is refused");
    let message = e.to_string();
    assert!(
        message.contains("HERPICER") && message.contains("410 nm") && message.contains("1e100"),
        "{message}"
    );
    let m = fluorite::formats::read_bytes(&with_cell("-1e99"), &path, &options).unwrap();
    let options = fluorite::fit::FitOptions {
        max_iterations: harness::run::FIT_ITERATIONS,
        ..Default::default()
    };
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || tx.send(fluorite::fit::fit(&m, &options).is_ok()));
    let ended = rx.recv_timeout(DEV_BUDGET);
    assert!(ended.is_ok(), "a cell of -1e99 still hangs the fit");
}

/// Found by this harness (seed 21, mutant 4553): a 42-digit absorbance reached the
/// inner-filter correction, whose factor 10^(A/2) made the sample's cells infinite, and
/// the error named the sample instead of the absorbance file. The absorbance file is now
/// refused, by name.
#[test]
fn an_absurd_absorbance_is_refused_naming_its_file() {
    let harness = Harness::new();
    if harness.seeds.iter().all(|s| s.kind != Kind::Absorbance) {
        crate::common::skipped("no absorbance seed (../shared/data is absent)");
        return;
    }
    let (which, mutant) = harness.mutant(21, 4553);
    let seed = &harness.seeds[which];
    assert_eq!(seed.kind, Kind::Absorbance, "{}", seed.origin);
    let scratch = std::env::temp_dir().join(format!("fluorite-fuzz-abs-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).unwrap();
    let ending = harness.run(seed, &mutant.bytes, &scratch);
    let _ = std::fs::remove_dir_all(&scratch);
    match ending {
        Ending::Refused(message) => assert!(
            message.contains(&seed.file_name) && message.contains("absorbance at"),
            "{message}"
        ),
        Ending::Accepted => panic!("{}: {:?} accepted", seed.origin, mutant.edits),
        Ending::Invalid(law) => {
            panic!("{}: {:?} fitted, breaking {law}", seed.origin, mutant.edits)
        }
    }
}

/// Seed 20261204's mutant 8322 cuts the shipped `plain.csv` to its 300–350 nm rows: no
/// fluorescence and no wavelength shared by the two grids, so no reflectance either. The
/// fit returned a plain reflector of no sample (which `check` rejects) and the campaign
/// counted it as a refusal; it is refused now, saying why, and a material that breaks its
/// own laws ends a campaign as a failure.
#[test]
fn a_dye_free_matrix_cut_below_the_emission_grid_is_refused() {
    let harness = Harness::new();
    let (which, mutant) = harness.mutant(20261204, 8322);
    let seed = &harness.seeds[which];
    if seed.file_name != "plain.csv" {
        crate::common::skipped("the corpus differs without ../shared/data: another seed file");
        return;
    }
    let scratch = std::env::temp_dir().join(format!("fluorite-fuzz-plain-{}", std::process::id()));
    std::fs::create_dir_all(&scratch).unwrap();
    let ending = harness.run(seed, &mutant.bytes, &scratch);
    let _ = std::fs::remove_dir_all(&scratch);
    match ending {
        Ending::Refused(message) => assert!(
            message.contains("measured at no wavelength") && message.contains("300–350 nm"),
            "{message}"
        ),
        other => panic!("{:?}: {other:?}", mutant.edits),
    }
}
