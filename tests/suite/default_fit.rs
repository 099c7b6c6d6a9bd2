//! The default fit (`--model as-needed`): one fluorophore where it explains the matrix,
//! the smallest model meeting ΔE2000 ≤ 1 under d65, a and f11 where it does not. Colour
//! is recomputed here from the written material and the measured matrix, not read from
//! the fit's own report.

use std::path::{Path, PathBuf};
use std::process::Command;

use fluorite::Material;
use fluorite::colour::Light;
use fluorite::evaluate::stability::material_delta_e;
use fluorite::fit::{FitOptions, FitOutcome, ModelChoice, fit};
use fluorite::formats::read;
use fluorite::measurement::Measurement;
use fluorite::synth::{Band, SynthComponent, SynthSpec};

use crate::common;

/// The lights and bound the default fit promises.
const LIGHTS: [&str; 3] = ["d65", "a", "f11"];
const BOUND: f64 = 1.0;

fn lights() -> Vec<Light> {
    LIGHTS.iter().map(|n| Light::builtin(n).unwrap()).collect()
}

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data")
        .join(name)
}

fn material(outcome: FitOutcome) -> Material {
    match outcome {
        FitOutcome::Material(m) => *m,
        FitOutcome::Shapes(_) => panic!("expected a material"),
    }
}

/// The default fit of class draw `case` of `seed`, which must escalate for a reason naming
/// `reason` and end with two fluorophores: its largest ΔE2000 against the truth under the
/// standard lights.
fn escalated_to_two_fluorophores(seed: u64, case: &str, reason: &str) -> f64 {
    let (m, truth) = common::class_case(seed, case).generate().unwrap();
    let material = material(fit(&m, &FitOptions::default()).unwrap());
    let report = material.fit.as_ref().unwrap();
    let escalation = report.escalation.as_ref().unwrap();
    assert!(escalation.escalated, "{}", escalation.reason);
    assert!(escalation.reason.contains(reason), "{}", escalation.reason);
    assert_eq!(material.fluorophores.len(), 2, "{}", report.model);
    material_delta_e(&material, &truth, &Light::standard())
}

/// The one-fluorophore grid fit (`--model tabulated`), which the default fit starts from.
fn grid_fit(m: &Measurement) -> Material {
    material(
        fit(
            m,
            &FitOptions {
                model: ModelChoice::Tabulated,
                ..FitOptions::default()
            },
        )
        .unwrap(),
    )
}

fn assert_within_bound(what: &str, material: &Material, m: &Measurement) {
    for (light, de) in common::delta_e_to_matrix(material, m, &LIGHTS) {
        assert!(
            de <= BOUND,
            "{what}: ΔE2000 {de:.3} under {light} against the matrix ({})",
            material
                .fit
                .as_ref()
                .map(|f| f.model.as_str())
                .unwrap_or("")
        );
    }
}

/// `fluorite fit` with no model option on every shipped example: the written material
/// meets the bound against its matrix; the one-fluorophore examples keep the grid fit
/// without a search (the fast path) or, where it meets a light only within the measured
/// colour's noise, take a one-component model of lower BIC that lies nearer the truth;
/// two-dyes escalates to two fluorophores and says so.
#[test]
fn every_shipped_example_meets_the_bound_by_default() {
    let dir = common::temp_dir("default-fit-examples");
    let examples = common::files_in(&data(""), &["csv"]);
    assert!(examples.len() >= 5, "{examples:?}");
    for input in examples {
        let stem = input.file_stem().unwrap().to_string_lossy().into_owned();
        let out = dir.join(format!("{stem}.json"));
        let output = common::succeed(Command::new(env!("CARGO_BIN_EXE_fluorite")).args([
            "fit",
            input.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]));
        let stdout = String::from_utf8_lossy(&output.stdout);
        let m = read(&input, &Default::default()).unwrap();
        let written = Material::load(&out).unwrap();
        assert_within_bound(&stem, &written, &m);
        let report = written.fit.as_ref().unwrap();
        let truth = Material::load(&data(&format!("{stem}.truth.json"))).unwrap();
        if truth.fluorophores.len() > 1 {
            let escalation = report.escalation.as_ref().expect("the choice is reported");
            assert!(escalation.escalated, "{stem}: {escalation:?}");
            assert_eq!(written.fluorophores.len(), truth.fluorophores.len());
            assert!(report.model.starts_with("gaussian:2x"), "{}", report.model);
            // Why: the grid fit's figures, which miss the bound.
            let grid_worst = escalation
                .grid_delta_e2000
                .values()
                .fold(0.0f64, |a, b| a.max(*b));
            assert!(grid_worst > BOUND, "{escalation:?}");
            assert!(
                stdout.contains("escalated beyond one fluorophore"),
                "{stdout}"
            );
            assert!(stdout.contains(&report.model), "{stdout}");
        } else {
            assert_eq!(
                written.fluorophores.len(),
                truth.fluorophores.len(),
                "{stem}"
            );
            if truth.fluorophores.is_empty() {
                assert!(report.model_search.is_none(), "{stem}: a search ran");
            } else if report.model_search.is_none() {
                assert_eq!(report.model, "tabulated", "{stem}");
                let escalation = report.escalation.as_ref().expect("the choice is reported");
                assert!(!escalation.escalated, "{stem}: {escalation:?}");
                assert!(stdout.contains("one fluorophore explains"), "{stdout}");
            } else {
                // The grid fit met a light only within the measured colour's noise, and the
                // search found a one-component model of lower BIC (red-pigment: Gaussian in
                // wavelength, as its truth): fewer parameters average the noise, so it must
                // lie nearer the truth than the grid fit.
                let escalation = report.escalation.as_ref().expect("the choice is reported");
                assert!(
                    escalation
                        .reason
                        .contains("of lower BIC than the grid model"),
                    "{stem}: {escalation:?}"
                );
                let grid = crate::common::grid_fit(&m);
                let lights = Light::standard();
                let (searched, gridded) = (
                    material_delta_e(&written, &truth, &lights),
                    material_delta_e(&grid, &truth, &lights),
                );
                println!(
                    "{stem}: {} {searched:.3}, grid fit {gridded:.3} from the truth",
                    report.model
                );
                assert!(searched < gridded, "{stem}: {searched} against {gridded}");
            }
        }
    }
}

/// Two-dye matrices other than the shipped one: different dyes, concentrations, noise
/// and seeds. The default fit escalates. Where a model meets every judged light (d65, a,
/// f11 and uv: the grids start at 300 nm), it meets the bound against the matrix and
/// comes within ΔE2000 1 of the generating material under d65, a and f11. Where none does
/// (red-pigment+440nm: the search's closest misses f11 by 0.40), the report says so, and
/// in its worst light the kept model is closer to the truth than the search under d65, a
/// and f11 alone, which ignores uv (there 11.9 from the truth).
#[test]
fn two_dye_matrices_escalate_to_two_fluorophores() {
    let band = |centre_nm: f64, width_nm: f64, weight: f64| Band {
        centre_nm,
        width_nm,
        weight,
    };
    // (first dye from a preset, second dye's absorption and emission, its c, noise, seed)
    let cases = [
        ("green-dye", (420.0, 20.0), (470.0, 18.0), 0.5, 0.0006, 3),
        ("red-pigment", (440.0, 18.0), (490.0, 16.0), 0.8, 0.0003, 5),
        ("brightener", (580.0, 20.0), (640.0, 20.0), 0.6, 0.001, 11),
    ];
    for (preset, absorption, emission, concentration, noise, seed) in cases {
        let mut spec = SynthSpec::preset(preset).unwrap();
        spec.components = vec![SynthComponent {
            absorption: vec![band(absorption.0, absorption.1, 1.0)],
            emission: vec![band(emission.0, emission.1, 1.0)],
            concentration,
            yield_fraction_of_limit: 0.8,
            yield_form: fluorite::YieldForm::Energy,
        }];
        spec.noise_sigma = noise;
        spec.seed = seed;
        spec.name = format!("{preset}+{}nm", absorption.0);
        let (m, truth) = spec.generate().unwrap();
        let fitted = material(fit(&m, &FitOptions::default()).unwrap());
        let report = fitted.fit.as_ref().unwrap();
        let escalation = report.escalation.as_ref().unwrap();
        assert!(escalation.escalated, "{}: {escalation:?}", spec.name);
        let met = report.model_search.as_ref().is_some_and(|s| s.met);
        if met {
            assert_within_bound(&spec.name, &fitted, &m);
            let to_truth = material_delta_e(&fitted, &truth, &lights());
            assert!(
                to_truth <= BOUND,
                "{}: ΔE2000 {to_truth:.3} to the truth ({})",
                spec.name,
                report.model
            );
        } else {
            assert!(
                escalation.reason.contains("exceeds the bounds least"),
                "{}: {escalation:?}",
                spec.name
            );
            let daylight = material(
                fit(
                    &m,
                    &FitOptions {
                        model: ModelChoice::Auto,
                        max_delta_e: Some(BOUND),
                        lights: lights(),
                        ..FitOptions::default()
                    },
                )
                .unwrap(),
            );
            let every = [lights(), vec![Light::builtin("uv").unwrap()]].concat();
            let (kept, alone) = (
                material_delta_e(&fitted, &truth, &every),
                material_delta_e(&daylight, &truth, &every),
            );
            assert!(
                kept < alone,
                "{}: worst ΔE2000 to the truth {kept:.2} ({}) against {alone:.2} ({}) for the search under d65, a, f11 alone",
                spec.name,
                report.model,
                daylight
                    .fit
                    .as_ref()
                    .map(|f| f.model.as_str())
                    .unwrap_or("")
            );
        }
    }
}

/// `--model tabulated` is the old default: one fluorophore on two-dyes, with its residual
/// (the second dye is not modelled), its colour miss and the warning, and no search.
#[test]
fn model_tabulated_keeps_one_fluorophore() {
    let m = read(&data("two-dyes.csv"), &Default::default()).unwrap();
    let options = FitOptions {
        model: ModelChoice::Tabulated,
        ..FitOptions::default()
    };
    let one = material(fit(&m, &options).unwrap());
    let report = one.fit.as_ref().unwrap();
    assert_eq!(one.fluorophores.len(), 1);
    assert_eq!(report.model, "tabulated");
    assert!(report.model_search.is_none() && report.escalation.is_none());
    assert!(report.rel_residual_fluorescence > 0.3, "{report:?}");
    let worst = common::delta_e_to_matrix(&one, &m, &LIGHTS)
        .into_iter()
        .fold(0.0f64, |a, (_, de)| a.max(de));
    assert!(
        worst > 2.0,
        "one fluorophore misses the second dye's colour"
    );
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains(fluorite::fit::assess::STRUCTURE_WARNING)),
        "{:?}",
        report.warnings
    );
}

/// On a matrix one fluorophore explains, the default fit is the tabulated fit: the same
/// spectra and figures, plus the report of the choice.
#[test]
fn the_fast_path_is_the_tabulated_fit() {
    let m = read(&data("green-dye.csv"), &Default::default()).unwrap();
    let default = material(fit(&m, &FitOptions::default()).unwrap());
    let tabulated = grid_fit(&m);
    assert_eq!(default.fluorophores, tabulated.fluorophores);
    assert_eq!(default.reflectance, tabulated.reflectance);
    let (d, t) = (default.fit.unwrap(), tabulated.fit.unwrap());
    assert_eq!(d.delta_e2000, t.delta_e2000);
    assert_eq!(d.warnings, t.warnings);
    assert!(!d.escalation.unwrap().escalated);
}

/// Raw EEMs and pins keep one fluorophore: a pinned yield on two-dyes keeps the grid fit
/// and warns what the matrix would need.
#[test]
fn a_pinned_yield_keeps_one_fluorophore_and_says_so() {
    let m = read(&data("two-dyes.csv"), &Default::default()).unwrap();
    let options = FitOptions {
        quantum_yield: Some(0.5),
        ..FitOptions::default()
    };
    let pinned = material(fit(&m, &options).unwrap());
    let report = pinned.fit.as_ref().unwrap();
    assert_eq!(pinned.fluorophores.len(), 1);
    assert!(!report.escalation.as_ref().unwrap().escalated);
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("kept one fluorophore because --quantum-yield")),
        "{:?}",
        report.warnings
    );
}

/// The six real surfaces (skipped when ../shared is absent): the default fit meets the
/// bound against each matrix under d65, a and f11, and is within 2 under uv (their grid
/// reaches the 365 nm LED's rows, so uv is judged too). Four keep the grid fit (ΔE2000 ≤
/// 0.65 under d65, a and f11), TEXTYELL included, whose residual shows structure: the
/// search's smallest model meeting the bound would explain less of that matrix. HERPICER
/// escalates: its grid fit misses uv by 4.46 (a second, UV-excited blue emitter); so
/// does postit_pink, whose grid fit misses uv by 1.32, within 3 × its measured colour's
/// noise RMS but along channels the noise hardly moves (χ² 64 over three channels).
#[test]
fn measured_surfaces_meet_the_bound_by_default() {
    let Some(files) = common::measured_files() else {
        crate::common::skipped("../shared/data/measured is absent");
        return;
    };
    for path in files {
        let m = read(&path, &Default::default()).unwrap();
        let fitted = material(fit(&m, &FitOptions::default()).unwrap());
        assert_within_bound(&m.name, &fitted, &m);
        let report = fitted.fit.as_ref().unwrap();
        let uv = report.delta_e2000["uv"];
        assert!(uv <= 2.0, "{}: ΔE2000 {uv:.2} under uv", m.name);
        let escalated = report.escalation.as_ref().unwrap().escalated;
        assert_eq!(
            escalated,
            ["HERPICER", "postit_pink"].contains(&m.name.as_str()),
            "{}",
            m.name
        );
        if !escalated {
            assert_eq!(report.model, "tabulated", "{}", m.name);
        }
    }
}

/// Two dyes whose second shows in cells the file does not hold (`fluorite class --seed 30
/// --case case033`: 114 missing cells worth ΔE2000 15.2 under uv): one fluorophore meets
/// the bound against the measured cells only with those cells filled from itself, while
/// its residual leaves structure 4.9 × the noise. Kept, as until 2026-12-05, it was 16.55
/// from the truth; the default escalates on it and ends with two fluorophores more than
/// ten times nearer the truth (1.02: what the unmeasured cells hold is any model's guess).
#[test]
fn a_colour_that_rests_on_self_filled_cells_escalates() {
    let against_truth =
        escalated_to_two_fluorophores(30, "case033", "cells the file does not hold");
    let (m, truth) = common::class_case(30, "case033").generate().unwrap();
    let one = FitOptions {
        model: ModelChoice::Tabulated,
        ..FitOptions::default()
    };
    let kept = material(fit(&m, &one).unwrap());
    let one_against_truth = material_delta_e(&kept, &truth, &Light::standard());
    assert!(
        against_truth < 0.1 * one_against_truth,
        "{against_truth} against one fluorophore's {one_against_truth}"
    );
}

/// Two dyes at σ 2.6·10⁻³ (`fluorite class --seed 46 --case case148`): one fluorophore
/// misses d65 by ΔE2000 1.13, within 3 × the measured colour's noise RMS, and was kept,
/// 7.80 from the truth. That miss lies along channels the noise hardly moves (χ² 30.7 over
/// the colour's three channels): the default escalates and ends with two fluorophores
/// within 3 of the truth (the measured colour itself lies 2.42 from it). It was 1.62;
/// since session 31 the search's pull on its noisy colours is weighed by what the grid
/// fit leaves beyond the noise, and it ends 2.56 (docs/results.md lists it among the
/// cases that moved further).
#[test]
fn a_miss_within_the_noise_rms_but_beyond_its_chi_square_escalates() {
    let against_truth = escalated_to_two_fluorophores(46, "case148", "but not its χ²");
    assert!(against_truth < 3.0, "{against_truth}");
}

/// Two dyes at σ 2.6·10⁻³ (`fluorite class --seed 198 --case case059`): one fluorophore
/// misses uv by ΔE2000 14.87, within 3 × the measured colour's noise RMS and its χ², and
/// was kept, 19.80 from the truth. What it leaves away from the diagonal holds a rank-1
/// component of 5.2 × σ²(√m + √n)², beyond the 5 noise reaches: a second fluorophore, so
/// the miss is no noise. The default escalates (to the noise-aware search: 3.62 from the
/// truth; the literal search ended 4.65) and ends with two fluorophores within the floor
/// the measured colour sets (4.34 from the truth, plus the search's bound of 1).
#[test]
fn a_miss_within_the_noise_escalates_where_the_residual_holds_a_second_fluorophore() {
    let against_truth = escalated_to_two_fluorophores(198, "case059", "a second fluorophore");
    assert!(against_truth < 4.34 + 1.0, "{against_truth}");
}

/// Two dyes at σ 2.5·10⁻³ (`fluorite class --case case011`, the default seed): f11's miss
/// lies within the measured colour's noise while the residual holds a second fluorophore.
/// Escalated to the search held to ΔE2000 1, the default chased the noisy colour (1.11
/// from it) and ended 4.37 from the truth, beyond the measured colour itself (4.06 from
/// it). The search it escalates to now holds each light to its noise, with the matrix
/// test: two fluorophores, nearer the truth than the measured colour is.
#[test]
fn a_noise_excused_miss_escalates_to_the_noise_aware_search() {
    let against_truth = escalated_to_two_fluorophores(
        fluorite::evaluate::class::DEFAULT_SEED,
        "case011",
        "noise-aware search",
    );
    assert!(against_truth < 4.06, "{against_truth}");
}

/// Two dyes, 112 missing cells worth up to ΔE2000 11.2 (`fluorite class --seed 22 --case
/// case111`), where no model meets the bound: every two-component candidate misses f11 by
/// 0.35–0.40, the grid fit by 0.24, but only with those cells filled from itself. Judged
/// each against its own fill, the grid fit was the closest and was kept, 6.85 from the
/// truth. Judged against the cells filled from the lowest-BIC candidate, it is not: the
/// search and the default end with two fluorophores within 1.5 of the truth.
#[test]
fn the_closest_fit_is_judged_on_a_fill_that_explains_the_cells() {
    let (m, truth) = common::class_case(22, "case111").generate().unwrap();
    let search = FitOptions {
        model: ModelChoice::Auto,
        max_delta_e: Some(1.0),
        ..FitOptions::default()
    };
    for (what, options) in [("search", search), ("default", FitOptions::default())] {
        let material = material(fit(&m, &options).unwrap());
        let report = material.fit.as_ref().unwrap();
        assert_eq!(material.fluorophores.len(), 2, "{what}: {}", report.model);
        let against_truth = material_delta_e(&material, &truth, &Light::standard());
        assert!(against_truth < 1.5, "{what}: {against_truth}");
    }
}

/// One dye with crosstalk 0.044 next to the diagonal (`fluorite class --seed 7 --case
/// case017`: a monochromator offset moving 4.4 % of each diagonal cell one step down).
/// The grid fit takes that crosstalk out and comes within 0.1 of the truth, but the
/// measured colour, offset included, lies 1.2 from the truth under f11, beyond its noise:
/// held to it, the default escalated to two fluorophores that fit the offset (0.49 from
/// the truth). The miss is the instrument's: the default keeps the one fluorophore and
/// says so, as it does for the same draw measured without the offset.
#[test]
fn a_miss_the_crosstalk_explains_keeps_one_fluorophore() {
    let spec = common::class_case(7, "case017");
    let mut without_offset = spec.clone();
    without_offset.crosstalk = 0.0;
    for (what, spec) in [("with crosstalk", spec), ("without", without_offset)] {
        let (m, truth) = spec.generate().unwrap();
        let material = material(fit(&m, &FitOptions::default()).unwrap());
        let report = material.fit.as_ref().unwrap();
        let escalation = report.escalation.as_ref().unwrap();
        assert!(!escalation.escalated, "{what}: {}", escalation.reason);
        assert_eq!(material.fluorophores.len(), 1, "{what}: {}", report.model);
        let against_truth = material_delta_e(&material, &truth, &Light::standard());
        assert!(against_truth < 0.3, "{what}: {against_truth}");
        if what == "with crosstalk" {
            assert!(
                report.delta_e2000["f11"] > 1.0 && escalation.reason.contains("crosstalk"),
                "{what}: {:?}, {}",
                report.delta_e2000,
                escalation.reason
            );
        }
    }
}

/// One dye at σ 3·10⁻³ on a 5 nm grid (`fluorite class --case case127`, the default
/// seed): the grid fit misses the measured colour under d65, a and uv by 1.1–1.5, within
/// what its noise explains, so it used to be kept, 2.93 from the truth: its 258 free
/// samples fit the noise. The noise-aware search's first model, gaussian:1x1+rt, has the
/// lower BIC on the same cells and now replaces it, nearer the truth (1.33).
#[test]
fn a_grid_fit_kept_only_within_its_noise_gives_way_to_a_model_of_lower_bic() {
    let (m, truth) = common::class_case(fluorite::evaluate::class::DEFAULT_SEED, "case127")
        .generate()
        .unwrap();
    let grid = grid_fit(&m);
    let default = material(fit(&m, &FitOptions::default()).unwrap());
    let report = default.fit.as_ref().unwrap();
    let escalation = report.escalation.as_ref().unwrap();
    assert!(escalation.escalated, "{}", escalation.reason);
    assert!(
        escalation.reason.contains("only within its noise")
            && escalation.reason.contains("lower BIC"),
        "{}",
        escalation.reason
    );
    assert_eq!(default.fluorophores.len(), 1, "{}", report.model);
    assert!(report.bic.unwrap() < grid.fit.as_ref().unwrap().bic.unwrap());
    let standard = Light::standard();
    let (grid_truth, default_truth) = (
        material_delta_e(&grid, &truth, &standard),
        material_delta_e(&default, &truth, &standard),
    );
    assert!(grid_truth > 2.5, "the grid fit: {grid_truth}");
    assert!(default_truth < 2.0, "{}: {default_truth}", report.model);
}
