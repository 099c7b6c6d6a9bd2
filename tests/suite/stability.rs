//! The evaluation harness: a small version of the stability sweep, one test
//! per failure mode showing that `fit` flags it, and the benchmark table's structure and
//! accuracy numbers (never its times).

use crate::common;

use fluorite::evaluate::stability::{
    self, Config, DELTA_E_TOLERANCE, RECOVERY_TOLERANCE, Sweep, case_data, material_delta_e,
};
use fluorite::evaluate::{Method, SEARCH_BOUND, bench};
use fluorite::fit::{FitOptions, FitOutcome, Solver, fit};
use fluorite::formats::{ReadOptions, read};
use fluorite::synth::{MEASURED_NOISE_SIGMA, SynthSpec};

/// The grid fit's options (the default fit would escalate on crosstalk's colour miss and
/// report the search's model instead).
fn grid_options() -> FitOptions {
    FitOptions {
        model: fluorite::fit::ModelChoice::Tabulated,
        max_iterations: 500,
        ..FitOptions::default()
    }
}

/// Warnings (and convergence) of the default fit of one sweep case.
fn warnings_of(sweep: Sweep, value: f64, seed: usize, solver: Solver) -> (Vec<String>, bool) {
    let (m, _, start) = case_data(sweep, value, seed).unwrap();
    let options = FitOptions {
        solver,
        start,
        max_iterations: if solver == Solver::NelderMead {
            2000
        } else {
            500
        },
        // The grid fit's own checks are under test (the default fit would escalate on
        // crosstalk's colour miss and report the search's model instead).
        model: fluorite::fit::ModelChoice::Tabulated,
        ..FitOptions::default()
    };
    let outcome = fit(&m, &options).unwrap();
    let report = outcome.report();
    (report.warnings.clone(), report.converged)
}

fn any_contains(warnings: &[String], needle: &str) -> bool {
    warnings.iter().any(|w| w.contains(needle))
}

#[test]
fn small_sweep_succeeds_at_the_bfc_noise_level_and_flags_wide_crosstalk() {
    let config = Config {
        seeds: 3,
        sweeps: vec![Sweep::Noise, Sweep::Crosstalk],
        methods: vec![Method::new(Solver::Init), Method::new(Solver::Lbfgs)],
    };
    let runs = stability::run(&config).unwrap();
    assert_eq!(runs.len(), (7 + 5) * 2 * 3);
    let summaries = stability::summarise(&runs);
    assert_eq!(summaries.len(), (7 + 5) * 2);

    // Closed form + L-BFGS at the BFC-450 noise level: every preset recovered.
    let at_bfc = summaries
        .iter()
        .find(|s| s.sweep == Sweep::Noise && s.value == 6e-4 && s.method == "lbfgs")
        .unwrap();
    assert_eq!(MEASURED_NOISE_SIGMA, 6e-4);
    assert_eq!(at_bfc.success_rate, 1.0);
    // The colour term trades shape for colour: the median shape error at this noise is
    // about 0.06 (0.015 for the closed form alone) while ΔE2000 against the truth falls
    // from about 0.6 to 0.2 (`fluorite stability`, noise table).
    assert!(at_bfc.median_recovery_error < RECOVERY_TOLERANCE);
    assert!(at_bfc.median_delta_e < DELTA_E_TOLERANCE);
    assert_eq!(at_bfc.flagged_rate, 0.0, "no false alarm at the BFC level");

    // Crosstalk at the presets' level (0.1 % of the diagonal, what most real files show):
    // L-BFGS recovers every preset. At 8 % (twice what POLGREE and TEXTYELL show) every
    // failure is flagged.
    let typical = summaries
        .iter()
        .find(|s| s.sweep == Sweep::Crosstalk && s.value == 0.001 && s.method == "lbfgs")
        .unwrap();
    assert_eq!(typical.success_rate, 1.0, "{typical:?}");
    for s in summaries
        .iter()
        .filter(|s| s.sweep == Sweep::Crosstalk && s.value >= 0.08 && s.success_rate < 1.0)
    {
        assert_eq!(s.flagged_failures, 1.0, "{s:?}");
    }
    // At the largest noise the fit falls back to a plain reflector, flagged.
    let loudest = summaries
        .iter()
        .find(|s| s.sweep == Sweep::Noise && s.value == 0.2 && s.method == "lbfgs")
        .unwrap();
    assert_eq!(loudest.success_rate, 0.0);
    assert_eq!(loudest.flagged_failures, 1.0);

    // Table structure: one CSV line per summary; the report has a table per sweep and
    // names where each method breaks.
    let csv = stability::to_csv(&summaries);
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], stability::CSV_HEADER);
    assert_eq!(lines.len(), summaries.len() + 1);
    let columns = stability::CSV_HEADER.split(',').count();
    assert!(lines.iter().all(|l| l.split(',').count() == columns));
    let report = stability::report(&config, &summaries, "test");
    assert!(report.contains("## noise σ\n"));
    assert!(report.contains("## crosstalk (fraction of the diagonal)\n"));
}

/// Crosstalk next to the diagonal (the synthesiser's: +f one step below, −f one step
/// above) is measured in the rows without fluorescence and the report says so. At the
/// real files' level (POLGREE and TEXTYELL: about 4 %) it is taken out of the cells; at
/// twice that the fit without it may miss its own cells' colour by more than the fit of
/// the cells as measured, and then those are fitted, with the note why and the warning
/// of a residual next to the diagonal. At the
/// smallest real level (0.1 %) no cell shows it above the noise: nothing is reported.
#[test]
fn fit_removes_crosstalk_next_to_the_diagonal_and_says_so() {
    for seed in 0..3 {
        for fraction in [0.04, 0.08] {
            let (m, _, _) = case_data(Sweep::Crosstalk, fraction, seed).unwrap();
            let outcome = fit(&m, &grid_options()).unwrap();
            let report = outcome.report();
            let found = report.crosstalk.as_ref().expect("crosstalk reported");
            for (got, error) in [
                (found.below, found.below_error),
                (-found.above, found.above_error),
            ] {
                assert!(
                    (got - fraction).abs() <= 4.0 * error + 0.02 * fraction,
                    "seed {seed}: {got} against {fraction} (± {error})"
                );
            }
            assert!(found.removed || fraction > 0.04, "seed {seed}: {found:?}");
            assert_eq!(found.note.is_empty(), found.removed, "{found:?}");
            if !found.removed {
                assert!(any_contains(&report.warnings, "residual concentrated"));
            }
        }
        let (m, _, _) = case_data(Sweep::Crosstalk, 0.001, seed).unwrap();
        let outcome = fit(&m, &grid_options()).unwrap();
        assert_eq!(outcome.report().crosstalk, None);
        assert!(!any_contains(
            &outcome.report().warnings,
            "residual concentrated"
        ));
    }
}

#[test]
fn fit_flags_weak_fluorescence() {
    for seed in 0..3 {
        let (w, _) = warnings_of(Sweep::Strength, 0.1, seed, Solver::Lbfgs);
        assert!(any_contains(&w, "weak fluorescence"), "{w:?}");
    }
    // No dye at all: noise alone must not be fitted as fluorescence, in any seed.
    for seed in 0..6 {
        let (w, _) = warnings_of(Sweep::Strength, 0.0, seed, Solver::Lbfgs);
        assert!(any_contains(&w, "no fluorescent signal"), "{w:?}");
    }
}

/// The weakest dye of the sweep (c = 0.03) is under the noise cell by cell, but where a
/// plain reflector misses its colour by more than the measured colour's noise explains, it
/// is fitted as fluorescent: its colour against the truth (not the noisy measurement) is
/// then within ΔE2000 1.25 under every light, where a plain reflector is up to 5 off. (The
/// seeds that stay plain reflectors are up to 1.2 from the truth: there the noise of the
/// measured colour is larger than what the fluorescence adds.)
#[test]
fn weak_fluorescence_that_shows_in_colour_is_fitted() {
    use fluorite::colour::{Light, delta_e2000, material_xyz, xyz_to_lab};
    let against_truth = |material: &fluorite::Material, truth: &fluorite::Material| {
        Light::standard()
            .iter()
            .map(|light| {
                let (fitted, white) = material_xyz(material, light);
                let (true_xyz, true_white) = material_xyz(truth, light);
                delta_e2000(xyz_to_lab(fitted, white), xyz_to_lab(true_xyz, true_white))
            })
            .fold(0.0, f64::max)
    };
    let (mut worst_fit, mut worst_plain) = (0.0f64, 0.0f64);
    for seed in 0..6 {
        let (m, truth, start) = case_data(Sweep::Strength, 0.03, seed).unwrap();
        let options = FitOptions {
            start,
            ..FitOptions::default()
        };
        let FitOutcome::Material(material) = fit(&m, &options).unwrap() else {
            panic!("a material");
        };
        let mut plain = (*material).clone();
        plain.fluorophores.clear();
        // What a plain reflector keeps of the truth: its diagonal d = (1 − c·a)·r.
        plain.reflectance.wavelength_nm = truth.reflectance.wavelength_nm.clone();
        plain.reflectance.value = truth
            .reflectance
            .wavelength_nm
            .iter()
            .map(|&nm| truth.diagonal(nm))
            .collect();
        eprintln!(
            "seed {seed}: {} fluorophore(s), ΔE2000 to the truth {:.2}; its plain reflector {:.2}",
            material.fluorophores.len(),
            against_truth(&material, &truth),
            against_truth(&plain, &truth)
        );
        worst_fit = worst_fit.max(against_truth(&material, &truth));
        worst_plain = worst_plain.max(against_truth(&plain, &truth));
    }
    eprintln!(
        "worst ΔE2000 against the truth: fitted {worst_fit:.2}, plain reflector {worst_plain:.2}"
    );
    assert!(worst_fit <= 1.25, "{worst_fit}");
    assert!(worst_plain > 2.0, "{worst_plain}");
}

/// A weak dye (c = 0.12, absorbing at 393 nm, emitting at 485 nm) at σ 2.1·10⁻³
/// (`fluorite class --seed 54 --case case124`): a rank-1 fit of its cells explains less
/// than noise would, but a plain reflector misses its measured colour under D65 and uv
/// by χ² 54 and 53 over the colour's three channels, which noise alone passes in fewer
/// than 1 of 10⁹ draws. Judged by ΔE2000 against three times the colour's RMS ΔE76, as
/// until 2026-12-05, it stayed a plain reflector 5.15 from its truth; the grid fit now
/// fits it as fluorescent, within 2. Its one fluorophore meets the colour only within its
/// noise, so the default fit takes the noise-aware search's gaussian:1x1+r6 of lower BIC,
/// 1.53 from the truth where the grid fit is 1.25 (a case the change of session 31 moved
/// further; docs/results.md).
#[test]
fn a_weak_dye_below_the_cell_noise_is_fitted_where_its_colour_shows() {
    use fluorite::colour::Light;
    let (m, truth) = common::class_case(54, "case124").generate().unwrap();
    let grid_options = FitOptions {
        model: fluorite::fit::ModelChoice::Tabulated,
        ..FitOptions::default()
    };
    let FitOutcome::Material(default) = fit(&m, &FitOptions::default()).unwrap() else {
        panic!("a material");
    };
    assert_eq!(default.fluorophores.len(), 1);
    let default_truth = material_delta_e(&default, &truth, &Light::standard());
    assert!(default_truth < 2.0, "the default fit: {default_truth}");
    let FitOutcome::Material(material) = fit(&m, &grid_options).unwrap() else {
        panic!("a material");
    };
    let warnings = &material.fit.as_ref().unwrap().warnings;
    assert_eq!(material.fluorophores.len(), 1, "{warnings:?}");
    assert!(
        any_contains(warnings, "fitted as fluorescent"),
        "{warnings:?}"
    );
    let against_truth = material_delta_e(&material, &truth, &Light::standard());
    assert!(against_truth < 2.0, "{against_truth}");
}

/// Where noise leaves the fitted colour more than 1.5 ΔE2000 from the truth, the fit says
/// that noise limits its colour. At σ = 2·10⁻³ and 3·10⁻³ the shapes are still within
/// 10 %, but some seeds' colours are 2–3 off (seed 1); the pruning of unsupported samples
/// brings others back (seed 2 at 2·10⁻³: 2.76 → 0.13), and those need no warning.
#[test]
fn fit_flags_noise_limited_colour() {
    use fluorite::colour::Light;
    let mut exercised = 0;
    for sigma in [2e-3, 3e-3] {
        for seed in 0..4 {
            let (m, truth, start) = case_data(Sweep::Noise, sigma, seed).unwrap();
            let options = FitOptions {
                start,
                model: fluorite::fit::ModelChoice::Tabulated,
                ..FitOptions::default()
            };
            let FitOutcome::Material(material) = fit(&m, &options).unwrap() else {
                panic!("a material");
            };
            let off = stability::material_delta_e(&material, &truth, &Light::standard());
            let warnings = &material.fit.as_ref().unwrap().warnings;
            if off > 1.5 {
                exercised += 1;
                assert!(
                    any_contains(warnings, "noise limits the colour"),
                    "σ {sigma} seed {seed}: {off:.2} from the truth, unflagged: {warnings:?}"
                );
            }
        }
    }
    assert!(exercised > 0, "no case left the colour 1.5 from the truth");
}

#[test]
fn fit_flags_undersampled_absorption() {
    for seed in 0..3 {
        let (w, _) = warnings_of(Sweep::ExcitationStep, 40.0, seed, Solver::Lbfgs);
        assert!(
            any_contains(&w, "absorption band resolved by only"),
            "{w:?}"
        );
    }
}

#[test]
fn fit_flags_many_missing_cells() {
    for seed in 0..3 {
        let (w, _) = warnings_of(Sweep::Missing, 0.8, seed, Solver::Lbfgs);
        assert!(
            any_contains(&w, "absorption is barely constrained"),
            "{w:?}"
        );
    }
}

#[test]
fn fit_flags_a_poor_start_that_nelder_mead_cannot_leave() {
    let (w, converged) = warnings_of(Sweep::PoorStart, 6e-4, 0, Solver::NelderMead);
    assert!(!converged);
    assert!(any_contains(&w, "stuck in a local minimum"), "{w:?}");
    // L-BFGS finds its way from the same flat start without a warning.
    let (w, converged) = warnings_of(Sweep::PoorStart, 6e-4, 0, Solver::Lbfgs);
    assert!(converged);
    assert!(w.is_empty(), "{w:?}");
}

#[test]
fn bench_table_holds_each_method_with_the_fits_own_accuracy() {
    let mut spec = SynthSpec::preset("green-dye").unwrap();
    spec.noise_sigma = 0.0;
    spec.crosstalk = 0.0;
    let (m, _) = spec.generate().unwrap();
    let methods = vec![
        Method::new(Solver::Init),
        Method::new(Solver::Lbfgs),
        Method::tightened(Solver::Lbfgs),
    ];
    let rows = bench::run(std::slice::from_ref(&m), &methods, 2).unwrap();
    assert_eq!(rows.len(), 3);
    for (row, method) in rows.iter().zip(&methods) {
        assert_eq!(row.method, method.name);
        assert_eq!(row.runs, 2);
        assert!(row.min_ms <= row.median_ms && row.median_ms <= row.max_ms);
        // Noise-free data without crosstalk: exact recovery.
        assert!(row.max_delta_e < 1e-3, "{row:?}");
        assert!(row.rel_residual < 1e-6, "{row:?}");
        let own = fit(&m, &method.options()).unwrap();
        let own_de = own
            .report()
            .delta_e2000
            .values()
            .cloned()
            .fold(0.0, f64::max);
        assert!((own_de - row.max_delta_e).abs() < 1e-12);
    }
    assert!(rows.iter().any(|r| r.pareto));
    let csv = bench::to_csv(&rows);
    assert_eq!(csv.lines().next().unwrap(), bench::CSV_HEADER);
    assert_eq!(csv.lines().count(), 4);
    assert!(bench::run(&[m], &methods, 0).is_err());
}

#[test]
fn bench_on_a_real_matrix_reports_the_fitted_accuracy() {
    let Some(path) = common::measured("HERPICER.BFC") else {
        return;
    };
    let m = read(&path, &ReadOptions::default()).unwrap();
    let rows = bench::run(
        std::slice::from_ref(&m),
        &[
            Method::new(Solver::Init),
            Method::new(Solver::Lbfgs),
            Method::search(SEARCH_BOUND),
        ],
        1,
    )
    .unwrap();
    // The parametric search meets the bound the one-fluorophore grid fits miss (UV).
    let search = rows.iter().find(|r| r.method == "search").unwrap();
    assert!(search.max_delta_e <= SEARCH_BOUND, "{search:?}");
    // On a matrix without a calibrated scale the search does not apply: no row.
    let mut uncalibrated = m.clone();
    uncalibrated.arbitrary_scale = true;
    let rows_uncalibrated = bench::run(
        &[uncalibrated],
        &[Method::new(Solver::Lbfgs), Method::search(SEARCH_BOUND)],
        1,
    )
    .unwrap();
    assert_eq!(rows_uncalibrated.len(), 1);
    assert_eq!(rows_uncalibrated[0].method, "lbfgs");
    let rows: Vec<_> = rows.into_iter().filter(|r| r.method != "search").collect();
    for r in &rows {
        // The rank-1 model leaves 8–50 % of the fluorescence of real files unexplained
        // (data README); HERPICER's colour is off mostly under the UV light.
        assert!((0.08..0.2).contains(&r.rel_residual), "{r:?}");
        assert!((1.0..8.0).contains(&r.max_delta_e), "{r:?}");
    }
    // Refinement (with the colour term) ends no worse in colour than the closed-form
    // estimate; it may trade some of the cells' residual for it.
    assert!(
        rows[1].max_delta_e <= rows[0].max_delta_e + 1e-9,
        "{rows:?}"
    );
}

#[test]
fn recovery_compares_the_row_factor_whatever_the_yield_form() {
    // A photon-form truth (row factor c·Φ·(λ/λ̄e)·a) and an energy-form "fit" whose
    // absorption is λ·a rescaled to peak 1 with k = c·Φ·max(λ·a)/λ̄e: the same matrix,
    // so the recovery error is zero; read as k·a against k·a it would not be.
    let mut truth = SynthSpec::preset("green-dye").unwrap().truth().unwrap();
    let t = &mut truth.fluorophores[0];
    t.yield_form = fluorite::YieldForm::Photon;
    t.quantum_yield = 0.8;
    let t = truth.fluorophores[0].clone();
    let e = &t.emission;
    let w = fluorite::spectrum::bin_widths(&e.wavelength_nm);
    let mean = (0..e.len())
        .map(|i| w[i] * e.value[i] * e.wavelength_nm[i])
        .sum::<f64>()
        / (0..e.len()).map(|i| w[i] * e.value[i]).sum::<f64>();
    let la: Vec<f64> = t
        .absorption
        .wavelength_nm
        .iter()
        .zip(&t.absorption.value)
        .map(|(l, a)| l * a)
        .collect();
    let peak = la.iter().cloned().fold(0.0, f64::max);
    let mut fitted = truth.clone();
    let f = &mut fitted.fluorophores[0];
    f.yield_form = fluorite::YieldForm::Energy;
    f.absorption.value = la.iter().map(|v| v / peak).collect();
    f.concentration = 1.0;
    f.quantum_yield = t.concentration * 0.8 * peak / mean;
    assert!(f.quantum_yield < 1.0);
    let error = stability::recovery_error(&fitted, &truth);
    assert!(error < 1e-12, "{error}");
    // The same truth read in the energy form differs by the factor λ/λ̄e.
    let mut energy_truth = truth.clone();
    energy_truth.fluorophores[0].yield_form = fluorite::YieldForm::Energy;
    assert!(stability::recovery_error(&fitted, &energy_truth) > 0.05);
}
