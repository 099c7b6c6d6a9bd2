//! The joint fit of a surface concentration series (issue 16, part 5) against synthetic
//! truth: a concentration series of a preset (`SynthSpec::concentration_series`, what
//! `fluorite synth --concentrations` writes) with known c per file, Q, a, e and r.

use fluorite::fit::series::{SeriesFit, SeriesOptions, fit_concentration_series};
use fluorite::fit::{FitOptions, FitOutcome, YieldChoice, fit};
use fluorite::material::{Material, YieldForm};
use fluorite::measurement::Measurement;
use fluorite::synth::SynthSpec;

/// Concentrations inside (0, 1): at c = 1 (every photon at the absorption peak absorbed)
/// the estimate sits on its bound, where no standard error applies.
const CONCENTRATIONS: [f64; 3] = [0.2, 0.5, 0.9];

/// The series of `preset` in yield form `form` with noise σ `noise`, without crosstalk
/// (the model has none), seed `seed`.
fn series(
    preset: &str,
    form: YieldForm,
    noise: f64,
    seed: u64,
    concentrations: &[f64],
) -> (Vec<Measurement>, Vec<Material>) {
    let mut spec = SynthSpec::preset(preset).unwrap();
    spec.yield_form = form;
    spec.noise_sigma = noise;
    spec.crosstalk = 0.0;
    spec.seed = seed;
    spec.concentration_series(concentrations)
        .unwrap()
        .into_iter()
        .map(|(_, m, truth)| (m, truth))
        .unzip()
}

/// `spec`'s series at [`CONCENTRATIONS`], as written (its noise, crosstalk and missing
/// cells).
fn measured_series(spec: &SynthSpec) -> (Vec<Measurement>, Vec<Material>) {
    spec.concentration_series(&CONCENTRATIONS)
        .unwrap()
        .into_iter()
        .map(|(_, m, t)| (m, t))
        .unzip()
}

fn options(form: YieldForm) -> SeriesOptions {
    SeriesOptions {
        yield_choice: match form {
            YieldForm::Energy => YieldChoice::Energy,
            YieldForm::Photon => YieldChoice::Photon,
        },
        ..SeriesOptions::default()
    }
}

/// Asserts every c_j within `relative` of its truth.
fn assert_concentrations(fit: &SeriesFit, truths: &[Material], relative: f64) {
    for (f, t) in fit.files.iter().zip(truths) {
        let c = t.fluorophores[0].concentration;
        assert!(
            (f.concentration - c).abs() <= relative * c,
            "{}: c {} against {c}",
            f.name,
            f.concentration
        );
    }
}

/// Asserts the yield and every c_j within 3 propagated errors of the truth and returns
/// the normalised errors (estimate − truth)/σ̂, yield first.
fn within_three_errors(fit: &SeriesFit, truths: &[Material]) -> Vec<f64> {
    let q = truths[0].fluorophores[0].quantum_yield;
    let mut z = vec![(fit.quantum_yield - q) / fit.quantum_yield_std_error];
    for (f, t) in fit.files.iter().zip(truths) {
        z.push((f.concentration - t.fluorophores[0].concentration) / f.concentration_std_error);
    }
    assert!(
        z.iter().all(|z| z.abs() <= 3.0),
        "normalised errors {z:?} (yield first)"
    );
    z
}

fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn print(fit: &SeriesFit, truths: &[Material]) {
    let q = truths[0].fluorophores[0].quantum_yield;
    println!(
        "Q {:.6} ± {:.2e} (truth {q:.6}), σ noise {:.2e} residual {:.2e}, {} iterations, {:.3} s",
        fit.quantum_yield,
        fit.quantum_yield_std_error,
        fit.noise_sigma,
        fit.residual_sigma,
        fit.iterations,
        fit.seconds
    );
    for (f, t) in fit.files.iter().zip(truths) {
        println!(
            "  {}: c {:.6} ± {:.2e} (truth {:.6}), ΔE2000 d65 {:.3}",
            f.name,
            f.concentration,
            f.concentration_std_error,
            t.fluorophores[0].concentration,
            f.delta_e2000.get("d65").copied().unwrap_or(f64::NAN)
        );
    }
    for w in &fit.warnings {
        println!("  warning: {w}");
    }
}

/// Exact data: c per file, Q and every spectrum to 1e-6 (relative) in both yield forms.
#[test]
fn noise_free_series_recovers_the_truth_in_both_yield_forms() {
    for (preset, form) in [
        ("green-dye", YieldForm::Energy),
        ("green-dye", YieldForm::Photon),
        ("red-pigment", YieldForm::Energy),
        ("brightener", YieldForm::Photon),
    ] {
        let (measurements, truths) = series(preset, form, 0.0, 1, &CONCENTRATIONS);
        let fit = fit_concentration_series(&measurements, &options(form)).unwrap();
        println!("{preset} {form:?}");
        print(&fit, &truths);
        let truth = &truths[0].fluorophores[0];
        assert_eq!(fit.yield_form, form);
        assert!(
            (fit.quantum_yield - truth.quantum_yield).abs() <= 1e-6 * truth.quantum_yield,
            "{preset} {form:?}: yield {} against {}",
            fit.quantum_yield,
            truth.quantum_yield
        );
        assert_concentrations(&fit, &truths, 1e-6);
        assert!(largest_difference(&fit.absorption.value, &truth.absorption.value) <= 1e-6);
        let e_peak = truth.emission.max();
        assert!(largest_difference(&fit.emission.value, &truth.emission.value) <= 1e-6 * e_peak);
        let r_truth: Vec<f64> = fit
            .reflectance
            .wavelength_nm
            .iter()
            .map(|&l| truths[0].reflectance.eval_clamped(l))
            .collect();
        assert!(largest_difference(&fit.reflectance.value, &r_truth) <= 1e-6);
        assert!(fit.converged, "{preset} {form:?}: {:?}", fit.warnings);
    }
}

/// Noise of the size the real BFC-450 files show: every c and Q within 3 propagated
/// standard errors of the truth, errors small against the values, and over eight noise
/// draws the normalised errors (estimate − truth)/σ̂ have an RMS near 1, so the
/// propagated errors are neither too small nor too large.
#[test]
fn noisy_series_recovers_c_and_q_within_their_propagated_errors() {
    let sigma = fluorite::synth::MEASURED_NOISE_SIGMA;
    for form in [YieldForm::Energy, YieldForm::Photon] {
        let mut z = Vec::new();
        for seed in 1..=8 {
            let (measurements, truths) =
                series("green-dye", form, sigma, 100 * seed, &CONCENTRATIONS);
            let fit = fit_concentration_series(&measurements, &options(form)).unwrap();
            if seed == 1 {
                println!("green-dye {form:?}, noise σ = {sigma}");
                print(&fit, &truths);
            }
            let q = truths[0].fluorophores[0].quantum_yield;
            let dq = fit.quantum_yield_std_error;
            assert!(dq > 0.0 && dq < 0.05 * q, "{form:?} seed {seed}: σ(Q) {dq}");
            for f in &fit.files {
                let dc = f.concentration_std_error;
                assert!(
                    dc > 0.0 && dc < 0.05 * f.concentration,
                    "{form:?} seed {seed}: σ(c) {dc}"
                );
            }
            z.extend(within_three_errors(&fit, &truths));
            // Noise σ estimated as the single fits estimate it, close to the truth.
            assert!(
                (fit.noise_sigma / sigma - 1.0).abs() < 0.2,
                "{}",
                fit.noise_sigma
            );
        }
        let rms = (z.iter().map(|x| x * x).sum::<f64>() / z.len() as f64).sqrt();
        println!(
            "{form:?}: RMS of (estimate − truth)/σ̂ over {} values: {rms:.2}",
            z.len()
        );
        assert!((0.4..=1.8).contains(&rms), "{form:?}: RMS z {rms}");
    }
}

/// One matrix cannot separate c from Q: the single fit reports c at its gauge (the
/// smallest feasible c) with an interval that holds every c from the gauge to the truth
/// and beyond, and the series fit refuses one file and files of one concentration.
#[test]
fn one_matrix_cannot_separate_c_from_q() {
    let (measurements, truths) = series("green-dye", YieldForm::Energy, 0.0, 1, &CONCENTRATIONS);
    let truth = truths[1].fluorophores[0].concentration;
    let FitOutcome::Material(single) = fit(&measurements[1], &FitOptions::default()).unwrap()
    else {
        panic!("a surface matrix gives a material");
    };
    let f = &single.fluorophores[0];
    let [lo, hi] = f.concentration_range.unwrap();
    println!(
        "single fit of c = {truth}: c = {:.4}, feasible {lo:.4}–{hi:.4}",
        f.concentration
    );
    assert!(
        (f.concentration - lo).abs() <= 1e-9,
        "the gauge is the smallest c"
    );
    assert!(
        lo < truth && truth < hi,
        "the truth is one of many feasible c"
    );
    assert!(hi - lo > 0.1, "the feasible interval is wide");
    assert!(
        (f.concentration - truth).abs() > 0.05 * truth,
        "the gauge is not the truth"
    );
    let one = fit_concentration_series(&measurements[1..2], &options(YieldForm::Energy));
    let message = one.unwrap_err().to_string();
    assert!(message.contains("at least two"), "{message}");
    let same = series("green-dye", YieldForm::Energy, 0.0, 1, &[0.5, 0.5]).0;
    let message = fit_concentration_series(&same, &options(YieldForm::Energy))
        .unwrap_err()
        .to_string();
    assert!(message.contains("cannot be separated"), "{message}");
}

/// The per-file material reproduces its file: exact data give ΔE2000 ≈ 0 under every light.
#[test]
fn per_file_materials_match_their_files() {
    let (measurements, _) = series("red-pigment", YieldForm::Energy, 0.0, 1, &[0.3, 0.9]);
    let fit = fit_concentration_series(&measurements, &options(YieldForm::Energy)).unwrap();
    for (j, f) in fit.files.iter().enumerate() {
        let material = fit.material_for(j);
        material.validate().unwrap();
        assert_eq!(material.fluorophores[0].concentration, f.concentration);
        for (light, de) in &f.delta_e2000 {
            assert!(*de < 1e-4, "{} {light}: ΔE2000 {de}", f.name);
        }
    }
}

/// `run` reads the files `fluorite synth --concentrations` writes (wide CSV) and fits
/// them; a file on other grids is refused with its name.
#[test]
fn run_reads_a_written_series() {
    let dir = std::env::temp_dir().join(format!("fluorite-series-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (measurements, truths) = series("green-dye", YieldForm::Energy, 0.0, 1, &[0.3, 0.8]);
    let mut paths = Vec::new();
    for m in &measurements {
        let path = dir.join(format!("{}.csv", m.name));
        let csv = fluorite::formats::write_wide_csv(m, fluorite::formats::RowsAre::Excitation);
        fluorite::files::write_atomic(&path, csv.as_bytes()).unwrap();
        paths.push(path);
    }
    let fit = fluorite::fit::series::run(&paths, &SeriesOptions::default()).unwrap();
    assert_eq!(fit.files[0].name, "green-dye-c0.3");
    assert_concentrations(&fit, &truths, 1e-4);
    for f in &fit.files {
        assert!(f.source.ends_with(&format!("{}.csv", f.name)));
    }
    // Written: the series and one material per file, which load back.
    let written = fit.write(&dir.join("fits"), "series").unwrap();
    assert_eq!(written.len(), 3);
    let loaded = Material::load(&written[2]).unwrap();
    assert_eq!(
        loaded.fluorophores[0].concentration,
        fit.files[1].concentration
    );
    let series_json: SeriesFit =
        serde_json::from_str(&std::fs::read_to_string(&written[0]).unwrap()).unwrap();
    assert_eq!(series_json, fit);
    let mut other = measurements[1].clone();
    other.emission_nm.iter_mut().for_each(|l| *l += 1.0);
    other.name = "shifted".into();
    let message = fit_concentration_series(
        &[measurements[0].clone(), other],
        &options(YieldForm::Energy),
    )
    .unwrap_err()
    .to_string();
    assert!(
        message.contains("shifted") && message.contains("grids"),
        "{message}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// The presets as `fluorite synth` writes them (crosstalk 0.001 next to the diagonal,
/// which the model does not hold) with 5 % of the off-diagonal cells missing: c and Q
/// still within 3 propagated errors.
#[test]
fn series_with_crosstalk_and_missing_cells() {
    for preset in ["green-dye", "red-pigment", "brightener"] {
        let mut spec = SynthSpec::preset(preset).unwrap();
        spec.missing_fraction = 0.05;
        let (measurements, truths) = measured_series(&spec);
        let fit = fit_concentration_series(&measurements, &options(YieldForm::Energy)).unwrap();
        println!("{preset}, crosstalk {}, 5 % missing", spec.crosstalk);
        print(&fit, &truths);
        within_three_errors(&fit, &truths);
    }
}

/// POLGREE's and TEXTYELL's level of crosstalk (4 % of the diagonal, + below, − above),
/// with 5 % of the cells missing: every file's crosstalk is found and taken out before the
/// joint fit, as a single fit does, and c and Q stay within 3 propagated errors.
#[test]
fn series_with_instrument_crosstalk_removes_it_per_file() {
    let fraction = 0.04;
    for preset in ["green-dye", "red-pigment"] {
        let mut spec = SynthSpec::preset(preset).unwrap();
        spec.crosstalk = fraction;
        spec.missing_fraction = 0.05;
        let (measurements, truths) = measured_series(&spec);
        let fit = fit_concentration_series(&measurements, &options(YieldForm::Energy)).unwrap();
        println!("{preset}, crosstalk {fraction}, 5 % missing");
        print(&fit, &truths);
        for file in &fit.files {
            let found = file
                .crosstalk
                .as_ref()
                .unwrap_or_else(|| panic!("{preset} {}: crosstalk found", file.name));
            for (got, error) in [
                (found.below, found.below_error),
                (-found.above, found.above_error),
            ] {
                assert!(
                    (got - fraction).abs() <= 4.0 * error + 0.05 * fraction,
                    "{preset} {}: {got} against {fraction} (± {error})",
                    file.name
                );
            }
        }
        within_three_errors(&fit, &truths);
    }
}

/// What spread of concentrations a user needs: the propagated error of Q (and of c at
/// 0.5) for two files ever further apart, and for more files, on green-dye with the
/// measured noise. Wider spreads separate c from Q better; every estimate stays within
/// 3 propagated errors of the truth.
#[test]
fn wider_spread_separates_c_from_q_better() {
    let sigma = fluorite::synth::MEASURED_NOISE_SIGMA;
    let designs: [&[f64]; 6] = [
        &[0.45, 0.55],
        &[0.3, 0.7],
        &[0.1, 0.9],
        &[0.1, 0.5, 0.9],
        &[0.1, 0.3, 0.5, 0.7, 0.9],
        &[0.05, 0.1, 0.2],
    ];
    let mut two_file_errors = Vec::new();
    println!("| concentrations | Q (truth) | σ(Q) | σ(c)/c, median |");
    for design in designs {
        let (measurements, truths) = series("green-dye", YieldForm::Energy, sigma, 7, design);
        let fit = fit_concentration_series(&measurements, &options(YieldForm::Energy)).unwrap();
        let q = truths[0].fluorophores[0].quantum_yield;
        let mut relative: Vec<f64> = fit
            .files
            .iter()
            .map(|f| f.concentration_std_error / f.concentration)
            .collect();
        relative.sort_by(f64::total_cmp);
        println!(
            "| {design:?} | {:.4} ({q:.4}) | {:.4} | {:.2} % |",
            fit.quantum_yield,
            fit.quantum_yield_std_error,
            100.0 * relative[relative.len() / 2]
        );
        within_three_errors(&fit, &truths);
        if design.len() == 2 {
            two_file_errors.push(fit.quantum_yield_std_error);
        }
    }
    assert!(
        two_file_errors.windows(2).all(|w| w[1] < w[0]),
        "{two_file_errors:?}"
    );
}

/// A series tells the yield forms apart where the diagonal covers the absorption band
/// (the diagonal sees a, the fluorescence a·Q(λ)): the default `Auto` takes the truth's
/// form at the measured noise, and says why. (The brightener absorbs mostly below the
/// diagonal's 380 nm: there an energy-form truth fits both forms within the noise, and
/// the paper's form is kept by a margin of the noise's size only, so it is left out.)
#[test]
fn auto_takes_the_yield_form_of_the_truth() {
    let sigma = fluorite::synth::MEASURED_NOISE_SIGMA;
    for (preset, form) in [
        ("green-dye", YieldForm::Energy),
        ("green-dye", YieldForm::Photon),
        ("red-pigment", YieldForm::Energy),
        ("red-pigment", YieldForm::Photon),
        ("brightener", YieldForm::Photon),
    ] {
        let (measurements, truths) = series(preset, form, sigma, 3, &CONCENTRATIONS);
        let fit = fit_concentration_series(&measurements, &SeriesOptions::default()).unwrap();
        println!("{preset} {form:?}: {}", fit.yield_choice);
        assert_eq!(fit.yield_form, form, "{preset}: {}", fit.yield_choice);
        within_three_errors(&fit, &truths);
    }
}
