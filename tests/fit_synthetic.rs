//! Fits of synthetic matrices with known ground truth.

use fluorite::fit::{FitOptions, FitOutcome, Solver, fit};
use fluorite::material::Material;
use fluorite::synth::SynthSpec;

fn fitted(outcome: FitOutcome) -> Material {
    match outcome {
        FitOutcome::Material(m) => *m,
        FitOutcome::Shapes(_) => panic!("expected a material"),
    }
}

/// Largest relative error of `got` against `truth`, over samples where the truth is at
/// least `floor` of its peak (elsewhere the data barely determine the value).
fn max_rel_error(got: &[f64], truth: &[f64], floor: f64) -> f64 {
    let peak = truth.iter().cloned().fold(0.0, f64::max);
    got.iter()
        .zip(truth)
        .filter(|(_, t)| **t >= floor * peak)
        .map(|(g, t)| ((g - t) / t).abs())
        .fold(0.0, f64::max)
}

#[test]
fn noise_free_recovery_is_exact() {
    for preset in ["green-dye", "red-pigment", "brightener"] {
        for solver in [Solver::Init, Solver::Lbfgs, Solver::GaussNewton] {
            let mut spec = SynthSpec::preset(preset).unwrap();
            spec.noise_sigma = 0.0;
            spec.crosstalk = 0.05;
            let (m, truth) = spec.generate().unwrap();
            let options = FitOptions {
                solver,
                ..FitOptions::default()
            };
            let material = fitted(fit(&m, &options).unwrap());
            let (f, t) = (&material.fluorophores[0], &truth.fluorophores[0]);
            let ea = max_rel_error(&f.absorption.value, &t.absorption.value, 1e-3);
            let ee = max_rel_error(&f.emission.value, &t.emission.value, 1e-3);
            let ek = (f.k() - t.k()).abs() / t.k();
            let d_fit: Vec<f64> = truth
                .reflectance
                .wavelength_nm
                .iter()
                .map(|&l| material.diagonal(l))
                .collect();
            let d_true: Vec<f64> = truth
                .reflectance
                .wavelength_nm
                .iter()
                .map(|&l| truth.diagonal(l))
                .collect();
            let ed = max_rel_error(&d_fit, &d_true, 0.0);
            let report = material.fit.as_ref().unwrap();
            println!(
                "{preset} {solver:?}: a {ea:.2e} e {ee:.2e} k {ek:.2e} d {ed:.2e} iters {} conv {} warn {:?} dE {:?}",
                report.iterations, report.converged, report.warnings, report.delta_e2000
            );
            assert!(
                ea < 1e-6 && ee < 1e-6 && ek < 1e-6 && ed < 1e-6,
                "{preset} {solver:?}"
            );
        }
    }
}
