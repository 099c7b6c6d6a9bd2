//! The grid fit's starting spectra: the rank-1 estimate projected onto the feasible set,
//! or the flat start of [`Start::Flat`].

use super::*;

/// The start: grid spectra projected onto the feasible set (κ ≤ 1), and the κ the
/// unconstrained rank-1 estimate would need.
pub(super) struct StartEstimate {
    pub(super) spectra: GridSpectra,
    pub(super) kappa_unbounded: f64,
}

/// Grid spectra from the rank-1 start, projected onto the feasible set (κ ≤ 1). The
/// rank-1 row is s·a_i·x_i: in the photon form a_i ∝ row_i/λ_i.
pub(super) fn start_spectra(objective: &Objective<'_>, start: &init::RankOne) -> StartEstimate {
    let row: Vec<f64> = start
        .row
        .iter()
        .enumerate()
        .map(|(i, u)| u / objective.row_factor(i))
        .collect();
    let peak = row.iter().cloned().fold(0.0, f64::max);
    let absorption: Vec<f64> = row
        .iter()
        .map(|u| if peak > 0.0 { u / peak } else { 0.0 })
        .collect();
    let normaliser: f64 = start
        .column
        .iter()
        .zip(&objective.data.emission_weight)
        .map(|(v, w)| v * w)
        .sum();
    let emission: Vec<f64> = start
        .column
        .iter()
        .map(|v| {
            if normaliser > 0.0 {
                v / normaliser
            } else {
                0.0
            }
        })
        .collect();
    let mut sp = GridSpectra {
        kappa: 0.0,
        absorption,
        emission,
    };
    let d = objective.derived(&sp);
    // F = u·v = peak·normaliser · a·x·(v/normaliser) = s·a·x·v with s = κ/(κ/s) and S = 1.
    let kappa = peak * normaliser * d.kappa_per_scale;
    // Start strictly inside: with κ = sin²t the bound κ = 1 is a stationary point
    // (dκ/dt = 0), where a start exactly on it would stay although the optimum lies inside.
    sp.kappa = kappa.min(START_KAPPA_CAP);
    StartEstimate {
        spectra: sp,
        kappa_unbounded: kappa,
    }
}

/// The flat start of [`Start::Flat`]: a = ½, e at the mean level of the estimate's
/// emission, κ as estimated (so only the spectral shapes are withheld).
pub(super) fn flat_start(estimate: &GridSpectra) -> GridSpectra {
    let n = estimate.emission.len().max(1) as f64;
    let level = estimate.emission.iter().sum::<f64>() / n;
    GridSpectra {
        kappa: estimate.kappa,
        absorption: vec![0.5; estimate.absorption.len()],
        emission: vec![level; estimate.emission.len()],
    }
}
