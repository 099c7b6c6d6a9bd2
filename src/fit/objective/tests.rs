//! The objective's cost, gradient and residuals checked against finite differences and
//! each other.

use super::*;
use crate::colour::{Light, Xyz};
use crate::measurement::{Measurement, Units};

/// A small noisy-looking matrix with a diagonal, for derivative checks.
fn data() -> FitData {
    let excitation_nm: Vec<f64> = (0..9).map(|i| 360.0 + 20.0 * i as f64).collect();
    let emission_nm: Vec<f64> = (0..8).map(|i| 380.0 + 20.0 * i as f64).collect();
    let mut values = Vec::new();
    for (i, &li) in excitation_nm.iter().enumerate() {
        for (j, &lo) in emission_nm.iter().enumerate() {
            let a = (-(li - 420.0f64).powi(2) / 800.0).exp();
            let e = (-(lo - 500.0f64).powi(2) / 1500.0).exp();
            let wobble = 0.003 * ((i * 7 + j * 3) % 5) as f64 - 0.006;
            let diag = if (li - lo).abs() < 1e-9 {
                0.5 + 0.001 * j as f64
            } else {
                0.0
            };
            values.push(0.08 * a * e + wobble + diag);
        }
    }
    let m = Measurement {
        name: "t".into(),
        source: None,
        source_sha256: None,
        excitation_nm,
        emission_nm,
        values,
        units: Units::PerBin,
        has_diagonal: true,
        arbitrary_scale: false,
        notes: Vec::new(),
    };
    FitData::new(&m, 0.0)
}

fn spectra(data: &FitData, kappa: f64) -> GridSpectra {
    GridSpectra {
        kappa,
        absorption: data
            .excitation_nm
            .iter()
            .map(|l| 0.05 + 0.9 * (-(l - 430.0f64).powi(2) / 900.0).exp())
            .collect(),
        emission: data
            .emission_nm
            .iter()
            .map(|l| 0.01 + 0.2 * (-(l - 510.0f64).powi(2) / 1200.0).exp())
            .collect(),
    }
}

/// The analytic gradient against central differences, both forms, with and without
/// the colour term, with κ large enough that diagonal cells hit their cap.
#[test]
fn gradient_matches_central_differences() {
    let data = data();
    let lights = Light::standard();
    let reference: Vec<Xyz> = lights.iter().map(|_| [40.0, 45.0, 30.0]).collect();
    for (form, noise) in [
        (YieldForm::Energy, 0.0),
        (YieldForm::Photon, 0.0),
        (YieldForm::Energy, 0.002),
        (YieldForm::Photon, 0.002),
    ] {
        for colour in [false, true] {
            for kappa in [0.3, 0.99] {
                let objective = Objective::new(&data, form).with_colour(
                    colour.then(|| ColourTerm::new(&data, &lights, &reference, 0.01, noise)),
                );
                let sp = spectra(&data, kappa);
                let (cost, gk, ga, gv) = objective.cost_gradient(&sp);
                // The residual vector gives the same cost.
                let r = objective.residuals(&sp);
                let half: f64 = 0.5 * r.iter().map(|x| x * x).sum::<f64>();
                assert!(
                    (half - cost).abs() <= 1e-12 * cost.max(1e-12),
                    "{form:?} {colour}"
                );
                let jac = objective.jacobian(&sp);
                let h = 1e-6;
                let cost_at = |sp: &GridSpectra| objective.cost_gradient(sp).0;
                let mut analytic = vec![gk];
                analytic.extend(&ga);
                analytic.extend(&gv);
                for k in 0..analytic.len() {
                    let bump = |delta: f64| {
                        let mut s = sp.clone();
                        if k == 0 {
                            s.kappa += delta;
                        } else if k <= s.absorption.len() {
                            s.absorption[k - 1] += delta;
                        } else {
                            s.emission[k - 1 - data.n_excitation()] += delta;
                        }
                        s
                    };
                    let numeric = (cost_at(&bump(h)) - cost_at(&bump(-h))) / (2.0 * h);
                    let scale = analytic[k].abs().max(numeric.abs()).max(1e-6);
                    assert!(
                        (analytic[k] - numeric).abs() <= 1e-4 * scale,
                        "{form:?} colour {colour} κ {kappa} parameter {k}: analytic {} numeric {numeric}",
                        analytic[k]
                    );
                    // Jᵀr is the gradient too.
                    let jtr: f64 = (0..r.len()).map(|row| jac[(row, k)] * r[row]).sum::<f64>();
                    assert!(
                        (jtr - analytic[k]).abs() <= 1e-6 * scale.max(1e-3),
                        "{form:?} colour {colour} κ {kappa} parameter {k}: Jᵀr {jtr} gradient {}",
                        analytic[k]
                    );
                }
            }
        }
    }
}
