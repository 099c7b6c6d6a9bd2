//! `fluorite class`: the randomized class sweep is deterministic, complete and consistent,
//! its ΔE2000 against the truth agrees with one recomputed here from the colour functions,
//! and the command writes the report and the CSV.

use crate::common;

use std::process::Command;

use fluorite::colour::{Light, delta_e2000, material_xyz, xyz_to_lab};
use fluorite::evaluate::class::{
    self, ClassConfig, ClassSweep, DEFAULT_FIT, GRID_FIT, METHODS, SEARCH, SEARCH_NOISE,
};
use fluorite::fit::{FitOutcome, fit};

const SMALL: ClassConfig = ClassConfig {
    cases: 8,
    seed: class::DEFAULT_SEED,
    truth_bands: fluorite::parametric::BandDomain::Wavelength,
    band_axis: fluorite::fit::BandAxisChoice::Both,
};

/// The sweep with every wall time zeroed: what must not depend on the run. The fitted
/// materials go through their JSON, which leaves their reports' wall times out.
fn without_times(mut sweep: ClassSweep) -> ClassSweep {
    for case in &mut sweep.cases {
        for result in &mut case.results {
            result.ms = 0.0;
            if let Some(material) = result.material.as_mut() {
                **material = serde_json::from_str(&material.to_json()).unwrap();
            }
        }
    }
    sweep
}

#[test]
fn small_sweep_is_deterministic_complete_and_adds_up() {
    let first = without_times(class::run(&SMALL).unwrap());
    let second = without_times(class::run(&SMALL).unwrap());
    assert_eq!(first, second);
    assert_eq!(first.cases.len(), SMALL.cases);
    for case in &first.cases {
        let methods: Vec<&str> = case.results.iter().map(|r| r.method.as_str()).collect();
        assert_eq!(methods, METHODS, "{}", case.name);
        // The default fit keeps the grid fit where one fluorophore does (it is the grid
        // fit then), else it is a parametric model with its own figures.
        let of = |method: &str| case.results.iter().find(|r| r.method == method).unwrap();
        let (grid, default) = (of(GRID_FIT), of(DEFAULT_FIT));
        if default.model == "tabulated" {
            assert_eq!(default.delta_e_truth, grid.delta_e_truth, "{}", case.name);
            assert_eq!(default.fluorophores, grid.fluorophores, "{}", case.name);
        } else {
            assert!(default.model.starts_with("gaussian:"), "{}", case.name);
        }
        assert!((1..=2).contains(&case.true_fluorophores), "{}", case.name);
        // Its twin without fluorophores stays a plain reflector, fitted and close to the truth.
        assert_eq!(case.dye_free.fluorophores, 0, "{}", case.name);
        assert!(case.dye_free.error.is_none(), "{}", case.name);
        assert!(
            case.dye_free.delta_e_truth < 1.0,
            "{}: {:?}",
            case.name,
            case.dye_free
        );
    }
    let summaries = class::summarise(&first);
    assert_eq!(summaries.len(), METHODS.len());
    let one_dye = first
        .cases
        .iter()
        .filter(|c| c.true_fluorophores == 1)
        .count();
    for s in &summaries {
        assert_eq!(s.cases, SMALL.cases, "{}", s.method);
        for split in [&s.truth, &s.measurement] {
            assert_eq!(split.all.n + s.errors, s.cases, "{}", s.method);
            assert_eq!(split.one.n + split.two.n, split.all.n, "{}", s.method);
            assert!(split.one.n <= one_dye);
            assert!(split.all.within_1 <= split.all.within_2);
            assert!(split.all.median <= split.all.p90 && split.all.p90 <= split.all.max);
        }
        assert!(s.fluorophores_right <= s.cases - s.errors);
        assert_eq!(
            s.bound_met.is_some(),
            [SEARCH, SEARCH_NOISE].contains(&s.method.as_str()),
            "{}",
            s.method
        );
        assert!(s.bound_met.unwrap_or(0) <= s.cases);
    }
}

/// The grid fit's ΔE2000 against the truth of one case, recomputed from the drawn spec
/// with the colour functions (largest over the four standard lights), refitting with the
/// grid method's options (`--model tabulated`).
#[test]
fn delta_e_against_the_truth_matches_a_recomputation() {
    let config = ClassConfig {
        cases: 3,
        seed: 11,
        ..ClassConfig::default()
    };
    let sweep = class::run(&config).unwrap();
    let specs = class::draw(&config).unwrap().specs;
    for (case, spec) in sweep.cases.iter().zip(&specs) {
        let (m, truth) = spec.generate().unwrap();
        assert_eq!(case.true_fluorophores, truth.fluorophores.len());
        let FitOutcome::Material(fitted) = fit(&m, &class::grid_options()).unwrap() else {
            panic!("{}: expected a material", case.name);
        };
        let expected = Light::standard()
            .iter()
            .map(|light| {
                let (fit_xyz, white) = material_xyz(&fitted, light);
                let (true_xyz, _) = material_xyz(&truth, light);
                delta_e2000(xyz_to_lab(fit_xyz, white), xyz_to_lab(true_xyz, white))
            })
            .fold(0.0, f64::max);
        let grid = &case.results[0];
        assert_eq!(grid.method, GRID_FIT);
        assert!(
            (grid.delta_e_truth - expected).abs() <= 1e-9 * expected.max(1.0),
            "{}: {} vs {expected}",
            case.name,
            grid.delta_e_truth
        );
    }
}

/// The measured colour's own distance from the truth needs no fit: nil for a noiseless
/// matrix without crosstalk or missing cells, growing with the noise; and no fit within
/// d of the measured colour comes closer to the truth than its distance − d (ΔE2000 as a
/// distance), which makes it a floor for any bound judged against the measurement.
#[test]
fn measured_colour_distance_is_nil_without_noise_and_floors_every_fit() {
    let specs = class::draw(&SMALL).unwrap().specs;
    for spec in &specs {
        let clean = fluorite::synth::SynthSpec {
            noise_sigma: 0.0,
            crosstalk: 0.0,
            missing_fraction: 0.0,
            ..spec.clone()
        };
        let (m, truth) = clean.generate().unwrap();
        let nil = class::measured_colour_delta_e(&m, &truth);
        assert!(nil < 1e-9, "{}: {nil}", spec.name);
        let noisy = |sigma: f64| {
            let (m, truth) = fluorite::synth::SynthSpec {
                noise_sigma: sigma,
                ..clean.clone()
            }
            .generate()
            .unwrap();
            class::measured_colour_delta_e(&m, &truth)
        };
        let (low, high) = (noisy(1e-4), noisy(3e-3));
        assert!(low > 0.0 && low < high, "{}: {low} vs {high}", spec.name);
    }
    let sweep = class::run(&SMALL).unwrap();
    for case in &sweep.cases {
        for r in &case.results {
            assert!(
                r.delta_e_truth >= case.measured_colour_truth - r.delta_e_measurement - 0.05,
                "{} {}: truth {} < measured colour {} − measurement {}",
                case.name,
                r.method,
                r.delta_e_truth,
                case.measured_colour_truth,
                r.delta_e_measurement
            );
        }
    }
}

#[test]
fn command_writes_report_and_csv() {
    let dir = common::temp_dir("class");
    let (report, csv) = (dir.join("class.md"), dir.join("class.csv"));
    common::succeed(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(["class", "--cases", "3", "--seed", "0x2A", "-q", "--report"])
            .arg(&report)
            .arg("--csv")
            .arg(&csv),
    );
    let text = std::fs::read_to_string(&report).unwrap();
    assert!(text.starts_with("# Accuracy on a randomized class of materials"));
    assert!(
        text.contains("`fluorite class --cases 3 --seed 0x2A`"),
        "{text}"
    );
    let table = std::fs::read_to_string(&csv).unwrap();
    let mut lines = table.lines();
    assert_eq!(lines.next(), Some(class::CSV_HEADER));
    assert_eq!(lines.count(), METHODS.len() * 3);

    let (_, message) = common::refused(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(["class", "--cases", "0", "--report"])
            .arg(dir.join("none.md")),
    );
    assert!(message.contains("--cases"), "{message}");
    assert!(!dir.join("none.md").exists());
}

/// `--case` fits only the named cases, the same as in the whole sweep; `--dump` writes
/// files from which each is refitted: the measurement reads back as drawn, the truth is
/// the synthesiser's, and `fluorite fit NAME.csv` gives the dumped default fit again.
#[test]
fn named_cases_are_the_sweeps_and_their_dump_refits() {
    let dir = common::temp_dir("class-dump");
    let config = ClassConfig { cases: 6, ..SMALL };
    let names = ["case004".to_string(), "case001".to_string()];
    let named = without_times(class::run_named(&config, &names).unwrap());
    let whole = without_times(class::run(&config).unwrap());
    let picked: Vec<&str> = named.cases.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(picked, ["case001", "case004"], "in the draw's order");
    for case in &named.cases {
        assert_eq!(Some(case), whole.cases.iter().find(|c| c.name == case.name));
    }

    let dump = dir.join("dump");
    let report = dir.join("one.md");
    common::succeed(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args([
                "class", "--cases", "6", "--case", "case004", "-q", "--report",
            ])
            .arg(&report)
            .arg("--dump")
            .arg(&dump),
    );
    assert!(
        std::fs::read_to_string(&report)
            .unwrap()
            .contains("--case case004`")
    );
    let spec = class::draw(&config).unwrap().specs.remove(4);
    let (m, truth) = spec.generate().unwrap();
    let read = fluorite::formats::read(&dump.join("case004.csv"), &Default::default()).unwrap();
    assert_eq!(read.values.len(), m.values.len());
    for (a, b) in read.values.iter().zip(&m.values) {
        assert!(a == b || (a.is_nan() && b.is_nan()), "{a} against {b}");
    }
    let dumped_truth = std::fs::read_to_string(dump.join("case004.truth.json")).unwrap();
    assert_eq!(dumped_truth, truth.to_json());
    let dumped_spec: fluorite::synth::SynthSpec =
        serde_json::from_str(&std::fs::read_to_string(dump.join("case004.synth.json")).unwrap())
            .unwrap();
    assert_eq!(dumped_spec, spec);
    for method in METHODS {
        assert!(
            dump.join(format!("case004.{method}.json")).exists(),
            "{method}"
        );
    }
    let refit = dir.join("refit.json");
    common::succeed(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .arg("fit")
            .arg(dump.join("case004.csv"))
            .arg("--output")
            .arg(&refit),
    );
    // The source names the file read, and the dump's fit read none.
    let without_source = |path: &std::path::Path| {
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        v["fit"]["source"] = serde_json::Value::Null;
        v["fit"]["source_sha256"] = serde_json::Value::Null;
        v
    };
    assert_eq!(
        without_source(&refit),
        without_source(&dump.join("case004.default.json"))
    );

    let (_, message) = common::refused(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(["class", "--cases", "6", "--case", "case006", "--report"])
            .arg(dir.join("none.md")),
    );
    assert!(
        message.contains("--case") && message.contains("case006"),
        "{message}"
    );
}

/// `--truth-bands wavenumber` draws from the same random numbers with every band Gaussian
/// in wavenumber (the same centre, and at its centre the same width), and `--band-axis`
/// runs the searches on one axis: checked against the closed form of such a band, and
/// against the model names the fits report.
#[test]
fn the_class_draws_bands_gaussian_in_wavenumber_and_searches_on_one_axis() {
    let wavelength = ClassConfig {
        cases: 4,
        seed: 5,
        ..ClassConfig::default()
    };
    let wavenumber = ClassConfig {
        truth_bands: fluorite::parametric::BandDomain::Wavenumber,
        band_axis: fluorite::fit::BandAxisChoice::Wavelength,
        ..wavelength
    };
    let spec = class::draw(&wavenumber).unwrap().specs.remove(0);
    let same_draw = class::draw(&wavelength).unwrap().specs.remove(0);
    assert_eq!(spec.emission, same_draw.emission);
    // The first component's emission e(λ) ∝ Σ w·exp(−½((1/λ − 1/c)·c²/σ)²), ∫e = 1 on
    // the emission grid (bin widths of the measurement's grid).
    let (m, truth) = spec.generate().unwrap();
    let closed_form = |l: f64| -> f64 {
        spec.emission
            .iter()
            .map(|b| {
                let z = (1.0 / l - 1.0 / b.centre_nm) * b.centre_nm * b.centre_nm / b.width_nm;
                b.weight * (-0.5 * z * z).exp()
            })
            .sum()
    };
    let e = &truth.fluorophores[0].emission;
    let grid = &m.emission_nm;
    let widths = fluorite::spectrum::bin_widths(grid);
    let area: f64 = grid
        .iter()
        .zip(&widths)
        .map(|(&l, w)| closed_form(l) * w)
        .sum();
    for (&l, v) in e.wavelength_nm.iter().zip(&e.value) {
        let expected = closed_form(l) / area;
        assert!(
            (v - expected).abs() <= 1e-9 * expected.abs().max(1e-3),
            "{l} nm: {v} against {expected}"
        );
    }
    // Its forms say the axis, and the searches ran on wavelength alone.
    let forms = spec.truth_with_forms().unwrap().forms.unwrap();
    let json = serde_json::to_string(&forms).unwrap();
    assert!(json.contains("\"wavenumber\""), "{json}");
    let sweep = class::run(&ClassConfig {
        cases: 2,
        ..wavenumber
    })
    .unwrap();
    for case in &sweep.cases {
        for result in &case.results {
            if result.model.starts_with("gaussian:") {
                assert!(result.model.contains("@wavelength"), "{}", result.model);
            }
        }
    }
    let report = class::to_markdown(&sweep, "fluorite class");
    assert!(report.contains("Gaussian bands in wavenumber"), "{report}");
    assert!(report.contains("`--band-axis wavelength`"), "{report}");
}
