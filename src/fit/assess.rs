//! How well a fitted material matches its measurement, and what to warn about.

use std::collections::BTreeMap;

use crate::colour::{Light, PatchColorimeter, delta_e2000, xyz_to_lab};
use crate::material::Material;
use crate::measurement::{CellKind, Measurement};
use crate::model::predict;

use super::data::{Cell, FitData};

/// Accuracy figures of a fit.
#[derive(Debug, Clone, Default)]
pub struct Accuracy {
    /// ‖M − F‖/‖M‖ over the Stokes-side cells outside the guard band.
    pub rel_residual_fluorescence: f64,
    /// RMSE of the diagonal.
    pub rmse_diagonal: f64,
    /// RMS residual over all fitted off-diagonal cells.
    pub rms_off_diagonal: f64,
    /// ΔE2000 per light.
    pub delta_e2000: BTreeMap<String, f64>,
}

/// Residual figures and ΔE2000 for `material` against measurement `m`.
pub fn accuracy(
    material: &Material,
    m: &Measurement,
    data: &FitData,
    lights: &[Light],
) -> Accuracy {
    let fitted = predict(
        material,
        &m.name,
        &m.excitation_nm,
        &m.emission_nm,
        m.units,
        m.has_diagonal,
    );
    let rel = |cells: &[Cell]| {
        let (mut num, mut den) = (0.0, 0.0);
        for c in cells {
            num += (c.value - fitted.get(c.row, c.column)).powi(2);
            den += c.value * c.value;
        }
        if den > 0.0 { (num / den).sqrt() } else { 0.0 }
    };
    let rms = |cells: &[Cell]| {
        if cells.is_empty() {
            return 0.0;
        }
        let s: f64 = cells
            .iter()
            .map(|c| (c.value - fitted.get(c.row, c.column)).powi(2))
            .sum();
        (s / cells.len() as f64).sqrt()
    };
    let mut delta_e = BTreeMap::new();
    if m.has_diagonal && !m.arbitrary_scale {
        let fitted_per_bin = fitted.to_per_bin();
        let measured = measured_patch(m, &fitted_per_bin, data.guard_nm);
        for light in lights {
            let pc = PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm);
            let lab_m = xyz_to_lab(pc.xyz(&measured), pc.white);
            let lab_f = xyz_to_lab(pc.xyz(&fitted_per_bin), pc.white);
            delta_e.insert(light.name.clone(), delta_e2000(lab_m, lab_f));
        }
    }
    Accuracy {
        rel_residual_fluorescence: rel(&data.stokes),
        rmse_diagonal: rms(&data.diagonal),
        rms_off_diagonal: rms(&data.off_diagonal),
        delta_e2000: delta_e,
    }
}

/// The measured patch the colour is judged on, per bin: every measured cell outside the
/// guard band. Guard cells hold instrument crosstalk (neither reflectance nor
/// fluorescence) mixed with the fluorescence right next to the diagonal, and missing
/// cells hold nothing: both are taken from `fitted_per_bin`, so neither side is judged
/// on what the data cannot tell.
pub fn measured_patch(m: &Measurement, fitted_per_bin: &Measurement, guard_nm: f64) -> Measurement {
    let mut measured = m.to_per_bin();
    for i in 0..m.n_excitation() {
        for j in 0..m.n_emission() {
            if matches!(
                m.cell_kind(i, j, guard_nm),
                CellKind::Missing | CellKind::Guard
            ) {
                *measured.get_mut(i, j) = fitted_per_bin.get(i, j);
            }
        }
    }
    measured
}

/// Wavelength ranges (`"300–350 nm"`) of the flagged samples of `grid`.
pub fn ranges(grid: &[f64], flagged: &[bool]) -> String {
    let mut out = Vec::new();
    let mut i = 0;
    while i < grid.len() {
        if flagged[i] {
            let start = i;
            while i + 1 < grid.len() && flagged[i + 1] {
                i += 1;
            }
            out.push(if start == i {
                format!("{} nm", grid[i])
            } else {
                format!("{}–{} nm", grid[start], grid[i])
            });
        }
        i += 1;
    }
    out.join(", ")
}

/// Excitation samples whose absorption the data barely constrain: less than `threshold`
/// of the emission (squared, as it enters least squares) falls in that row's fitted cells.
pub fn unobservable_absorption(
    data: &FitData,
    emission_columns: &[f64],
    threshold: f64,
) -> Vec<bool> {
    let total: f64 = emission_columns.iter().map(|v| v * v).sum();
    let mut seen = vec![0.0; data.n_excitation()];
    for c in &data.off_diagonal {
        seen[c.row] += emission_columns[c.column].powi(2);
    }
    seen.iter()
        .map(|s| total > 0.0 && *s < threshold * total)
        .collect()
}
