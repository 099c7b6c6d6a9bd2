//! `--noise-aware-bound`: the search holds each light to max(bound, 3 × its measured
//! colour's noise RMS) and weighs its colour term by that noise. Judged against the
//! truth the synthetic matrices were made from: on noisy matrices it ends nearer the
//! truth than the literal search, and where every colour is precise it changes nothing.

use std::process::Command;

use fluorite::Material;
use fluorite::colour::Light;
use fluorite::evaluate::stability::material_delta_e;
use fluorite::fit::{BandAxisChoice, FitOptions, FitOutcome, ModelChoice, fit};
use fluorite::synth::SynthSpec;

use crate::common;

fn search(bound: f64, noise_aware_bound: bool) -> FitOptions {
    FitOptions {
        model: ModelChoice::Auto,
        max_delta_e: Some(bound),
        noise_aware_bound,
        ..FitOptions::default()
    }
}

/// The grid fit (`--model tabulated`), which every search starts from.
fn grid_fit() -> FitOptions {
    FitOptions {
        model: ModelChoice::Tabulated,
        ..FitOptions::default()
    }
}

fn material(outcome: FitOutcome) -> Material {
    match outcome {
        FitOutcome::Material(m) => *m,
        FitOutcome::Shapes(_) => panic!("expected a material"),
    }
}

fn median(mut values: Vec<f64>) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    0.5 * (values[(n - 1) / 2] + values[n / 2])
}

/// The red pigment at σ 2.5·10⁻³ (four times the BFC-450 files' noise), twelve draws:
/// its UV colour is measured only to about 6 ΔE2000 (RMS), and the literal search meets
/// or chases ΔE2000 ≤ 1 there by fitting that noise. Against the truth (the material the
/// matrix was made from, never the fit's own report) the noise-aware search ends nearer
/// in median and in mean (3.29 → 0.88, 3.71 → 1.88 with the matrix test; 2.60 and 3.42
/// without it; `-- --nocapture` prints every draw), and every light it judged against a
/// widened bound is listed with its ΔE2000 and noise. Not in every draw: at seed 10 it goes
/// from 0.79 to 7.57, where no candidate meets the capped bounds and the fallback keeps a
/// two-component one.
#[test]
fn on_noisy_matrices_the_noise_aware_search_ends_nearer_the_truth() {
    let bound = 1.0;
    let lights = Light::standard();
    let (mut literal, mut aware) = (Vec::new(), Vec::new());
    let mut widened = 0;
    for seed in 1..=12 {
        let mut spec = SynthSpec::preset("red-pigment").unwrap();
        spec.noise_sigma = 2.5e-3;
        spec.seed = seed;
        let (m, truth) = spec.generate().unwrap();
        let plain = material(fit(&m, &search(bound, false)).unwrap());
        let noisy = material(fit(&m, &search(bound, true)).unwrap());
        literal.push(material_delta_e(&plain, &truth, &lights));
        aware.push(material_delta_e(&noisy, &truth, &lights));
        noisy.validate().unwrap();
        let report = noisy.fit.as_ref().unwrap();
        let search = report.model_search.as_ref().unwrap();
        assert!(
            search.rule.contains("--noise-aware-bound"),
            "{}",
            search.rule
        );
        if !search.met {
            continue;
        }
        // Met: every light within the bound, or listed with a ΔE2000 within 3 × its noise.
        for (light, de) in &report.delta_e2000 {
            match search.misses_within_noise.get(light) {
                Some([listed, noise]) => {
                    assert_eq!(listed, de, "seed {seed}, {light}");
                    assert!(*de > bound && *de <= 3.0 * noise, "seed {seed}, {light}");
                    widened += 1;
                }
                None => assert!(*de <= bound, "seed {seed}, {light}: {de:.2} unlisted"),
            }
        }
    }
    assert!(widened > 0, "no draw was judged against a widened bound");
    let (literal_median, aware_median) = (median(literal.clone()), median(aware.clone()));
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    println!(
        "ΔE2000 from the truth, literal {literal:.2?} (median {literal_median:.2}, mean {:.2}), noise-aware {aware:.2?} (median {aware_median:.2}, mean {:.2})",
        mean(&literal),
        mean(&aware)
    );
    assert!(
        aware_median < literal_median && mean(&aware) < mean(&literal),
        "ΔE2000 from the truth, literal {literal:.2?} (median {literal_median:.2}), noise-aware {aware:.2?} (median {aware_median:.2})"
    );
}

/// Where every light's colour is measured to better than a fifth of the bound (the green
/// dye at σ 10⁻⁴), neither the bounds nor the colour weights move: every light is held to
/// the bound as given and no miss is excused by noise. The noise-aware search meets it with
/// the literal search's bands (on a tabulated reflectance: no polynomial fits a diagonal
/// known to 10⁻⁴), then tests that candidate against the matrix: its residual exceeds the
/// grid model's by far more than noise (its bands, pulled onto the measured colour, miss
/// the matrix), the grid fit meets the bound too, and the grid fit is kept. Against the
/// truth it is the nearer (0.05 against 0.20 ΔE2000).
#[test]
fn where_every_colour_is_precise_only_the_matrix_test_moves_the_noise_aware_search() {
    let mut spec = SynthSpec::preset("green-dye").unwrap();
    spec.noise_sigma = 1e-4;
    let (m, truth) = spec.generate().unwrap();
    let plain = material(fit(&m, &search(1.0, false)).unwrap());
    let aware = material(fit(&m, &search(1.0, true)).unwrap());
    let report = aware.fit.as_ref().unwrap();
    assert!(
        report.delta_e2000_noise.values().all(|n| *n <= 0.2),
        "not a precise case: {:?}",
        report.delta_e2000_noise
    );
    let search = report.model_search.as_ref().unwrap();
    for light in Light::standard() {
        assert!(
            search.rule.contains(&format!("{} ≤ 1.00", light.name)),
            "{}",
            search.rule
        );
    }
    assert!(search.met && search.misses_within_noise.is_empty());
    let plain_model = &plain.fit.as_ref().unwrap().model;
    assert_ne!(plain_model, "tabulated");
    assert_eq!(report.model, "tabulated");
    let why = search.matrix_test.as_deref().expect("matrix_test says why");
    // The literal search's bands, on the tabulated reflectance.
    let bands = plain_model.split('+').next().unwrap();
    assert!(
        why.starts_with(&format!("kept the grid fit: {bands}+rt met the bound")),
        "{why}"
    );
    assert!(report.delta_e2000.values().all(|de| *de <= 1.0));
    let lights = Light::standard();
    let (near, far) = (
        material_delta_e(&aware, &truth, &lights),
        material_delta_e(&plain, &truth, &lights),
    );
    assert!(
        near < far,
        "grid fit {near:.2}, candidate {far:.2} from the truth"
    );
}

/// The matrix test on the red pigment at σ 10⁻³ (a noise the BFC-450 files reach), twelve
/// draws. The literal search keeps a Gaussian model that meets ΔE2000 ≤ 1 through its
/// colour term; the noise-aware search keeps the grid fit wherever the matrix tells the
/// candidate from the grid model and the grid fit meets every bound too. Against the
/// truth it ends nearer in median and in every draw where it kept the grid fit; it never
/// keeps a grid fit that misses a bound, and the literal search never applies the test.
/// All on wavenumber bands alone; on both axes (the default) the search's wavelength
/// bands, the truth's shape, pass the test and end nearer the truth still (median).
#[test]
fn the_matrix_test_keeps_the_grid_fit_when_a_candidate_met_the_bound_through_its_colour() {
    let lights = Light::standard();
    let (mut literal, mut aware, mut kept) = (Vec::new(), Vec::new(), 0);
    let mut both_axes = Vec::new();
    // On wavenumber alone, the bands' shape the preset's truth (Gaussian in wavelength)
    // does not take: the candidates follow the colour only through the pull.
    let on_wavenumber = |noise_aware: bool| FitOptions {
        band_axis: BandAxisChoice::Wavenumber,
        ..search(1.0, noise_aware)
    };
    for seed in 1..=12 {
        let mut spec = SynthSpec::preset("red-pigment").unwrap();
        spec.noise_sigma = 1e-3;
        spec.seed = seed;
        let (m, truth) = spec.generate().unwrap();
        let plain = material(fit(&m, &on_wavenumber(false)).unwrap());
        let noisy = material(fit(&m, &on_wavenumber(true)).unwrap());
        let both = material(fit(&m, &search(1.0, true)).unwrap());
        both_axes.push(material_delta_e(&both, &truth, &lights));
        noisy.validate().unwrap();
        assert!(
            plain
                .fit
                .as_ref()
                .unwrap()
                .model_search
                .as_ref()
                .unwrap()
                .matrix_test
                .is_none(),
            "seed {seed}: the literal search applied the matrix test"
        );
        let (l, a) = (
            material_delta_e(&plain, &truth, &lights),
            material_delta_e(&noisy, &truth, &lights),
        );
        let report = noisy.fit.as_ref().unwrap();
        let search = report.model_search.as_ref().unwrap();
        if let Some(why) = search
            .matrix_test
            .as_ref()
            .filter(|w| w.starts_with("kept the grid fit"))
        {
            kept += 1;
            assert_eq!(report.model, "tabulated", "seed {seed}");
            assert!(search.met, "seed {seed}");
            assert!(why.contains("σ²"), "seed {seed}: {why}");
            for (light, de) in &report.delta_e2000 {
                let widened = search.misses_within_noise.get(light).map(|[_, n]| 3.0 * n);
                assert!(
                    *de <= widened.unwrap_or(1.0).max(1.0),
                    "seed {seed}, {light}: {de:.2}"
                );
            }
            assert!(
                a <= l,
                "seed {seed}: grid fit {a:.2}, candidate {l:.2} from the truth"
            );
        }
        literal.push(l);
        aware.push(a);
    }
    println!(
        "ΔE2000 from the truth, literal {literal:.2?}, noise-aware {aware:.2?}, on both axes {both_axes:.2?}"
    );
    assert!(kept >= 6, "the grid fit was kept on {kept} of 12 draws");
    assert!(
        median(aware.clone()) < median(literal.clone()),
        "literal {literal:.2?}, noise-aware {aware:.2?}"
    );
    // On both axes the search finds bands of the truth's shape, which the matrix passes:
    // nearer the truth again.
    assert!(
        median(both_axes.clone()) < median(aware.clone()),
        "noise-aware {aware:.2?}, on both axes {both_axes:.2?}"
    );
}

/// The flag belongs to the bound: without --max-delta-e the command is refused with a
/// usage error naming both; with it the printed rule says how each light was judged.
#[test]
fn the_cli_takes_the_flag_with_a_bound_only() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/green-dye.csv");
    let out = Command::new(env!("CARGO_BIN_EXE_fluorite"))
        .args(["fit", "--noise-aware-bound"])
        .arg(&data)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--max-delta-e"), "{stderr}");
    let dir = tempfile::tempdir().unwrap();
    let out = common::succeed(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(["fit", "--max-delta-e", "1", "--noise-aware-bound", "-o"])
            .arg(dir.path().join("g.json"))
            .arg(&data),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("3 × the measured colour's noise RMS") && stdout.contains("d65 ≤ 1.00"),
        "{stdout}"
    );
}

/// The library refuses the flag without a bound too (the CLI and Python refuse it before
/// calling it): a caller who set it must not believe the noise was allowed for, on the
/// default fit or any model.
#[test]
fn the_library_refuses_the_flag_without_a_bound() {
    let (m, _) = SynthSpec::preset("green-dye").unwrap().generate().unwrap();
    for model in [
        ModelChoice::AsNeeded,
        ModelChoice::Tabulated,
        ModelChoice::Auto,
    ] {
        let options = FitOptions {
            model,
            noise_aware_bound: true,
            ..FitOptions::default()
        };
        let error = fit(&m, &options).expect_err("refused").to_string();
        assert!(
            error.contains("--noise-aware-bound") && error.contains("--max-delta-e"),
            "{model:?}: {error}"
        );
    }
}

/// Where what the grid model leaves holds a second fluorophore, the matrix test does not
/// fall back on the grid fit, nor keep a one-component candidate: the search goes on among
/// two-component models. case013 of the default seed (`fluorite class`): two dyes at σ
/// 2.2·10⁻⁴; the grid fit (one component) lies 0.90 from the truth, the literal search
/// keeps gaussian:1x1+r7 0.53 from it; the noise-aware search's one-component candidate
/// meets the bound, but what the grid model leaves holds a rank-1 component of 303 ×
/// σ²(√m + √n)², and it keeps gaussian:2x1+rt after it, 0.38 from the truth.
///
/// (Until session 24 the cases were case035 and 0xBEEF's case081, then case042: since
/// the search removes the crosstalk its grid fit kept and tries every two-component start
/// where the grid model misses, those reach two components without the test. Until
/// session 32, case090 and 0xBEEF's case009: since the noise-aware search takes the
/// reflectance tabulated where no polynomial fits the diagonal within its noise, their
/// one-component candidates miss the bound and the search reaches two components without
/// the test, 0.44 and 0.74 from the truth.)
#[test]
fn where_the_grid_model_leaves_a_second_fluorophore_the_search_goes_on_to_two_components() {
    use fluorite::evaluate::class::DEFAULT_SEED;
    let lights = Light::standard();
    let (seed, case) = (DEFAULT_SEED, "case013");
    let spec = common::class_case(seed, case);
    assert_eq!(spec.components.len(), 1, "{case} is a two-dye draw");
    let (m, truth) = spec.generate().unwrap();
    let grid = material(fit(&m, &grid_fit()).unwrap());
    let plain = material(fit(&m, &search(1.0, false)).unwrap());
    let aware = material(fit(&m, &search(1.0, true)).unwrap());
    aware.validate().unwrap();
    let report = aware.fit.as_ref().unwrap();
    let search = report.model_search.as_ref().unwrap();
    let why = search
        .matrix_test
        .as_deref()
        .expect("the matrix test spoke");
    assert!(why.contains("so the search went on"), "{case}: {why}");
    assert!(search.met, "{case}");
    assert_eq!(aware.fluorophores.len(), 2, "{case}: {}", report.model);
    let (g, p, a) = (
        material_delta_e(&grid, &truth, &lights),
        material_delta_e(&plain, &truth, &lights),
        material_delta_e(&aware, &truth, &lights),
    );
    assert!(
        a < 1.0 && a < g && a < p,
        "{case} from the truth: grid fit {g:.2}, literal search {p:.2}, noise-aware {a:.2}"
    );
}

/// Two dyes on a 5 nm grid (`fluorite class --seed 165 --case case085`) whose grid fit
/// (one fluorophore) misses the measured colour by ΔE2000 24.7 under uv, far beyond its
/// noise, so the search skips one-component models. Its two-component models used to
/// start from that grid fit alone and all ended about 25 from the measured colour and 27
/// from the truth, where the literal search, starting from its 1x1 parent, ends within
/// 0.4. The smallest one-component model is now fitted as their start (never chosen).
#[test]
fn two_component_models_start_from_a_one_component_parent_even_where_it_is_not_a_candidate() {
    let (m, truth) = common::class_case(165, "case085").generate().unwrap();
    let material = material(fit(&m, &search(1.0, true)).unwrap());
    let report = material.fit.as_ref().unwrap();
    let search_report = report.model_search.as_ref().unwrap();
    assert_eq!(material.fluorophores.len(), 2, "{}", report.model);
    assert!(
        search_report
            .skipped
            .as_deref()
            .is_some_and(|s| s.contains("fitted only as a start")),
        "{:?}",
        search_report.skipped
    );
    assert!(!report.model.starts_with("gaussian:1x"), "{}", report.model);
    let against_truth = material_delta_e(&material, &truth, &Light::standard());
    assert!(against_truth < 1.0, "{against_truth}");
}

/// Two dyes at σ 2.3·10⁻³ (`fluorite class --seed 23 --case case014`): the grid model
/// (one fluorophore) misses uv by ΔE2000 5.54, within the 6.45 that 3 × the measured
/// colour's noise RMS allows, and was kept, 6.22 from the truth. The miss lies along
/// channels the noise hardly moves (χ² 30.6 over the colour's three channels, beyond
/// the 25.9 noise alone passes in 1 of 10⁵ draws): the search now starts at two
/// components and ends within 1 of the truth.
#[test]
fn a_grid_miss_within_the_noise_rms_but_beyond_its_chi_square_is_not_noise() {
    let (m, truth) = common::class_case(23, "case014").generate().unwrap();
    let material = material(fit(&m, &search(1.0, true)).unwrap());
    let report = material.fit.as_ref().unwrap();
    let skipped = report
        .model_search
        .as_ref()
        .and_then(|s| s.skipped.clone())
        .unwrap_or_default();
    assert!(skipped.contains("at χ²"), "{skipped}");
    assert_eq!(material.fluorophores.len(), 2, "{}", report.model);
    let against_truth = material_delta_e(&material, &truth, &Light::standard());
    assert!(against_truth < 1.0, "{against_truth}");
}

/// One dye with crosstalk 0.044 next to the diagonal (`fluorite class --seed 7 --case
/// case017`). The grid model misses the measured colour under f11 by 1.18, beyond the
/// 1.00 its noise explains, only because the measured colour holds the monochromator
/// offset the grid fit took out of the cells (it comes within 1 of the cells it fitted,
/// and within 0.1 of the truth). Read as a light one fluorophore cannot meet, that miss
/// sent the search to two components that fit the offset (0.49 from the truth). The
/// search now ends with one fluorophore, within 0.3 of the truth.
#[test]
fn a_grid_miss_the_crosstalk_explains_keeps_the_search_at_one_fluorophore() {
    let (m, truth) = common::class_case(7, "case017").generate().unwrap();
    let searched = material(fit(&m, &search(1.0, true)).unwrap());
    let report = searched.fit.as_ref().unwrap();
    assert_eq!(searched.fluorophores.len(), 1, "{}", report.model);
    let against_truth = material_delta_e(&searched, &truth, &Light::standard());
    assert!(against_truth < 0.3, "{}: {against_truth}", report.model);
}

/// A narrow UV-excited emitter at σ 2.3·10⁻³ (`fluorite class --seed 30 --case case074`):
/// the grid fit leaves only noise, in its cells' residual and in its miss of every
/// light's measured colour (χ² within the noise's mean + 3 SD), and the colour under uv
/// is known only to several ΔE2000. Pulled onto that colour, gaussian:1x1+r5 ended 3.81
/// from the truth (uv); the pull now scales with the share of what the grid fit leaves
/// beyond the noise, 0 here, so the matrix sets its bands: within 1 of the truth.
#[test]
fn where_the_grid_model_leaves_only_noise_the_colour_pull_gives_way_to_the_matrix() {
    let (m, truth) = common::class_case(30, "case074").generate().unwrap();
    let searched = material(fit(&m, &search(1.0, true)).unwrap());
    let report = searched.fit.as_ref().unwrap();
    let rule = &report.model_search.as_ref().unwrap().rule;
    assert!(
        rule.contains("in the cells or that colour: d65 0.00, a 0.00, f11 0.00, uv 0.00"),
        "{rule}"
    );
    assert_eq!(searched.fluorophores.len(), 1, "{}", report.model);
    let against_truth = material_delta_e(&searched, &truth, &Light::standard());
    assert!(against_truth < 1.0, "{}: {against_truth}", report.model);
}

/// One dye on a reflectance with a sharp edge (a sigmoid 10 nm wide at 589 nm) at σ
/// 1.7·10⁻³ (`fluorite class --seed 66 --case case051`). The lowest polynomial degree
/// that keeps the grid fit's colour, 11, misses the diagonal by far more than its noise,
/// so every candidate on it failed the matrix test against the grid model and the search
/// kept the grid fit, 4.41 from the truth (its free emission samples hold the noise; uv).
/// The noise-aware search now takes the reflectance tabulated where no degree fits the
/// diagonal within its noise: gaussian:1x1+rt, 1.71 from the truth.
#[test]
fn a_reflectance_form_the_diagonal_noise_rejects_gives_way_to_the_tabulated_one() {
    let (m, truth) = common::class_case(66, "case051").generate().unwrap();
    let grid = material(fit(&m, &grid_fit()).unwrap());
    let grid_against_truth = material_delta_e(&grid, &truth, &Light::standard());
    let searched = material(fit(&m, &search(1.0, true)).unwrap());
    let report = searched.fit.as_ref().unwrap();
    assert!(report.model.ends_with("+rt"), "{}", report.model);
    assert_eq!(searched.fluorophores.len(), 1, "{}", report.model);
    let against_truth = material_delta_e(&searched, &truth, &Light::standard());
    assert!(
        against_truth < 2.0 && against_truth < grid_against_truth - 1.0,
        "{}: {against_truth} (grid fit {grid_against_truth})",
        report.model
    );
}

/// One dye with a second absorption band at 3–7 % of its peak in the UV LED's rows, at σ
/// 2.8·10⁻³ (the default seed's case049 of `fluorite class`). The grid model's free
/// samples there are each within 2σ of zero and pruned as noise, and the first candidate,
/// gaussian:1x1+rt, misses the matrix (it has no second band), so the search kept the grid
/// fit, 2.70 from the truth under uv. It now goes on among the one-component models,
/// fitted to the matrix alone, and keeps the one of lowest BIC where that is below the
/// grid model's: gaussian:1x2/1+rt, within 1 of the truth. The default fit, which kept its
/// grid fit within the measured colour's noise, takes that model for its lower BIC.
#[test]
fn where_the_matrix_test_keeps_the_grid_fit_a_one_component_model_of_lower_bic_replaces_it() {
    let (m, truth) = common::class_case(0xC1A5_5EE9_2026_1130, "case049")
        .generate()
        .unwrap();
    let lights = Light::standard();
    let grid = material(fit(&m, &grid_fit()).unwrap());
    let grid_against_truth = material_delta_e(&grid, &truth, &lights);
    let searched = material(fit(&m, &search(1.0, true)).unwrap());
    let report = searched.fit.as_ref().unwrap();
    let why = report
        .model_search
        .as_ref()
        .and_then(|s| s.matrix_test.clone())
        .unwrap_or_default();
    assert_eq!(searched.fluorophores.len(), 1, "{}", report.model);
    assert!(report.model.starts_with("gaussian:1x2"), "{}", report.model);
    assert!(
        why.starts_with(&format!("kept {}", report.model))
            && why.contains("fitted to the matrix alone")
            && why.contains("the grid fit was kept at first: gaussian:1x1+rt met the bound"),
        "{why}"
    );
    let bic = |r: &fluorite::material::FitReport| r.bic.unwrap();
    assert!(bic(report) < bic(grid.fit.as_ref().unwrap()));
    let against_truth = material_delta_e(&searched, &truth, &lights);
    assert!(
        against_truth < 1.2 && against_truth < grid_against_truth - 1.0,
        "{}: {against_truth:.2} (grid fit {grid_against_truth:.2})",
        report.model
    );
    let default = material(fit(&m, &FitOptions::default()).unwrap());
    assert_eq!(default.fit.as_ref().unwrap().model, report.model);
}
