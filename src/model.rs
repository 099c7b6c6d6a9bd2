//! The model on a measurement grid (model.md §2): what matrix a material predicts.

use crate::material::Material;
use crate::measurement::{Measurement, Units};
use crate::spectrum::{bin_widths, find_wavelength};

/// The reradiation matrix `material` predicts on the given grids:
/// M[λi, λo] = [λi = λo]·d(λi) + Σ c·Q(λi)·a(λi)·e(λo)·Δλo (per bin) or without Δλo (per
/// nm), with Q(λi) = Q (energy form) or Φ·λi/λ̄e (photon form).
/// `with_diagonal` adds d on the cells where both grids share a wavelength.
pub fn predict(
    material: &Material,
    name: &str,
    excitation_nm: &[f64],
    emission_nm: &[f64],
    units: Units,
    with_diagonal: bool,
) -> Measurement {
    let widths = match units {
        Units::PerBin => bin_widths(emission_nm),
        Units::PerNm => vec![1.0; emission_nm.len()],
    };
    let fluorescence = material.fluorescence_on_grid(excitation_nm, emission_nm);
    let values: Vec<f64> = fluorescence
        .chunks_exact(emission_nm.len().max(1))
        .flat_map(|row| row.iter().zip(&widths).map(|(f, w)| f * w))
        .collect();
    let mut m = Measurement {
        name: name.to_string(),
        source: None,
        source_sha256: None,
        excitation_nm: excitation_nm.to_vec(),
        emission_nm: emission_nm.to_vec(),
        values,
        units,
        has_diagonal: with_diagonal,
        arbitrary_scale: false,
        notes: Vec::new(),
    };
    if with_diagonal {
        for (j, &lo) in emission_nm.iter().enumerate() {
            if let Some(i) = find_wavelength(excitation_nm, lo) {
                *m.get_mut(i, j) += material.diagonal(lo);
            }
        }
    }
    m
}

/// The matrix `material` predicts on `m`'s grids, in `m`'s units, with a diagonal where
/// `m` has one: the model side of every comparison with a measurement.
pub fn predict_like(material: &Material, m: &Measurement) -> Measurement {
    predict(
        material,
        &m.name,
        &m.excitation_nm,
        &m.emission_nm,
        m.units,
        m.has_diagonal,
    )
}
