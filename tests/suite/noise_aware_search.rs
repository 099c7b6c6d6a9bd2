//! `--noise-aware-bound`: the search holds each light to max(bound, 3 × its measured
//! colour's noise RMS) and weighs its colour term by that noise. Judged against the
//! truth the synthetic matrices were made from: on noisy matrices it ends nearer the
//! truth than the literal search, and where every colour is precise it changes nothing.

use std::process::Command;

use fluorite::Material;
use fluorite::colour::Light;
use fluorite::evaluate::stability::material_delta_e;
use fluorite::fit::{FitOptions, FitOutcome, ModelChoice, fit};
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
/// in median and in mean (3.29 → 2.60, 3.71 → 3.42; `-- --nocapture` prints every draw),
/// and every light it judged against a widened bound is listed with its ΔE2000 and noise.
/// Not in every draw: at seed 5 it goes from 1.17 (the literal search kept the grid fit)
/// to 7.23, because bounds widened to uv ≤ 17.7 and a ≤ 8.9 accept a two-component model
/// whose reflectance misses the diagonal by 5 σ; at seed 10 from 0.79 to 7.57, where no
/// candidate meets the capped bounds and the fallback keeps a two-component one.
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
/// dye at σ 10⁻⁴), neither the bounds nor the colour weights move: the same material.
#[test]
fn where_every_colour_is_precise_the_noise_aware_search_changes_nothing() {
    let mut spec = SynthSpec::preset("green-dye").unwrap();
    spec.noise_sigma = 1e-4;
    let (m, _) = spec.generate().unwrap();
    let plain = material(fit(&m, &search(1.0, false)).unwrap());
    let aware = material(fit(&m, &search(1.0, true)).unwrap());
    let report = aware.fit.as_ref().unwrap();
    assert!(
        report.delta_e2000_noise.values().all(|n| *n <= 0.2),
        "not a precise case: {:?}",
        report.delta_e2000_noise
    );
    assert_eq!(report.model, plain.fit.as_ref().unwrap().model);
    assert_eq!(report.delta_e2000, plain.fit.as_ref().unwrap().delta_e2000);
    assert_eq!(aware.fluorophores, plain.fluorophores);
    assert!(
        report
            .model_search
            .as_ref()
            .unwrap()
            .misses_within_noise
            .is_empty()
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
