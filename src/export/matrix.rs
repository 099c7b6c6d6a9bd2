//! The model's reradiation matrix on any grid (model.md §2), as a wide CSV or BFC-450
//! file that `fluorite fit` reads back.

use crate::error::Result;
use crate::formats::{RowsAre, write_bfc, write_wide_csv};
use crate::material::{Material, YieldForm};
use crate::measurement::{Measurement, Units};
use crate::model::predict;

use super::{VERSION, one_line};

/// The grids a matrix export uses by default: excitation at the absorption and
/// reflectance samples, emission at the emission and reflectance samples (for a fitted
/// material, the measurement's grids).
pub fn default_grids(material: &Material) -> (Vec<f64>, Vec<f64>) {
    let merge = |mut all: Vec<f64>| {
        all.sort_by(f64::total_cmp);
        all.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        all
    };
    let mut ex = material.reflectance.wavelength_nm.clone();
    let mut em = ex.clone();
    for f in &material.fluorophores {
        ex.extend(&f.absorption.wavelength_nm);
        em.extend(&f.emission.wavelength_nm);
    }
    (merge(ex), merge(em))
}

/// The matrix `material` predicts on the grids, with the diagonal d = (1 − Σc·a)·r where
/// both grids share a wavelength. The grids are checked (positive, strictly increasing).
pub fn matrix(
    material: &Material,
    excitation_nm: &[f64],
    emission_nm: &[f64],
    units: Units,
) -> Result<Measurement> {
    crate::spectrum::check_grid(excitation_nm, "excitation grid")?;
    crate::spectrum::check_grid(emission_nm, "emission grid")?;
    if excitation_nm.is_empty() || emission_nm.is_empty() {
        return Err(crate::Error::invalid(
            "grid",
            "is empty; give at least one excitation and one emission wavelength",
        ));
    }
    let m = predict(
        material,
        &material.name,
        excitation_nm,
        emission_nm,
        units,
        true,
    );
    m.validate()?;
    Ok(m)
}

fn quantity(material: &Material, units: Units) -> String {
    let components = material.fluorophores.len();
    let (sum, k) = if components > 1 {
        ("Σ", format!(" summed over the {components} fluorophores"))
    } else {
        ("", String::new())
    };
    // The photon form's row factor is c·Φ·(λi/λ̄e)·a(λi): write the energy yield Q(λi).
    let row = if any_photon(material) {
        "c·Q(λi)·a(λi)"
    } else {
        "k·a(λi)"
    };
    match units {
        Units::PerBin => format!(
            "bispectral radiance factor per emission bin (dimensionless; off the diagonal {sum}{row}·e(λo)·Δλo with trapezoid bin widths Δλo{k})"
        ),
        Units::PerNm => format!(
            "bispectral radiance factor density per nm of emission (1/nm; off the diagonal {sum}{row}·e(λo){k}); read back with `fluorite fit --per-nm`"
        ),
    }
}

fn any_photon(material: &Material) -> bool {
    material
        .fluorophores
        .iter()
        .any(|f| f.yield_form == YieldForm::Photon)
}

/// One line per photon-form fluorophore: its Φ, λ̄e and energy yield (the matrix holds
/// the energy yield Q(λi) = Φ·λi/λ̄e, which grows with λi).
fn photon_lines(material: &Material, prefix: &str) -> String {
    let n = material.fluorophores.len();
    material
        .fluorophores
        .iter()
        .enumerate()
        .filter(|(_, f)| f.yield_form == YieldForm::Photon)
        .map(|(i, f)| {
            let which = if n > 1 {
                format!("fluorophore {i}")
            } else {
                "the fluorophore".to_string()
            };
            format!(
                "{prefix}yield: {which} has a constant photon yield Φ = {} (yield_form photon): its energy yield is Q(λi) = Φ·λi/λ̄e with λ̄e = {} nm, c = {}\n",
                f.quantum_yield,
                f.emission_mean_nm(),
                f.concentration
            )
        })
        .collect()
}

/// The diagonal's formula: `(1 − c·a)·r`, or `(1 − Σc·a)·r` for several fluorophores.
fn diagonal_formula(material: &Material, times: &str, minus: &str) -> String {
    if material.fluorophores.len() > 1 {
        format!("(1 {minus} Σc{times}a){times}r")
    } else {
        format!("(1 {minus} c{times}a){times}r")
    }
}

/// The wide CSV export of `m`, the [`matrix`] `material` predicts (rows = excitation),
/// with a `#` header fluorite's reader skips.
pub(super) fn wide(material: &Material, m: &Measurement) -> String {
    let units = m.units;
    let mut out = format!(
        "# fluorite {VERSION} export of material \"{}\": model reradiation matrix (Jung et al. 2018)\n",
        one_line(&material.name)
    );
    out.push_str(&format!("# quantity: {}\n", quantity(material, units)));
    out.push_str(&photon_lines(material, "# "));
    out.push_str(&format!(
        "# diagonal (λo = λi): reflectance factor d = {} (dimensionless) plus the fluorescence emitted at the same wavelength\n",
        diagonal_formula(material, "·", "−")
    ));
    out.push_str("# rows: excitation wavelength λi (nm); columns: emission wavelength λo (nm)\n");
    out.push_str(&super::spectra::forms_header(material, "# "));
    out.push_str(&write_wide_csv(m, RowsAre::Excitation));
    out
}

/// The BFC-450 export of `m`, the [`matrix`] `material` predicts (rows = emission, CRLF),
/// its metadata lines stating the quantity.
pub(super) fn bfc(material: &Material, m: &Measurement) -> Result<String> {
    let units = m.units;
    let text = write_bfc(m)?;
    // The BFC-450 header has six free metadata lines (`;<none>`); fill them with what the
    // file holds.
    let info = [
        format!(";fluorite {VERSION} model reradiation matrix"),
        format!(
            ";quantity: {}",
            match units {
                Units::PerBin => "radiance factor per emission bin (dimensionless)",
                Units::PerNm => "radiance factor density per nm of emission (1/nm)",
            }
        ),
        format!(
            ";diagonal: reflectance factor d = {}",
            diagonal_formula(material, "*", "-")
        ),
        ";rows: emission nm; columns: excitation nm".to_string(),
        // BFC metadata is plain ASCII; the photon form shares this line (six are free).
        match (material.fluorophores.len(), any_photon(material)) {
            (0 | 1, false) => String::new(),
            (n, false) => format!(";fluorescence summed over {n} fluorophores"),
            (0 | 1, true) => {
                ";photon-form yield: energy yield Q(li) = Phi*li/mean emission wavelength".into()
            }
            (n, true) => format!(
                ";fluorescence summed over {n} fluorophores; photon-form ones: Q(li) = Phi*li/mean emission"
            ),
        },
        match &material.forms {
            Some(f) => format!(
                ";spectra from the continuous forms of model {}",
                one_line(&f.model)
            ),
            None => String::new(),
        },
    ];
    let mut info = info.into_iter().filter(|line| !line.is_empty());
    let mut out = String::with_capacity(text.len() + 512);
    for line in text.split_inclusive("\r\n") {
        if line == ";<none>\r\n"
            && let Some(i) = info.next()
        {
            out.push_str(&i.replace(['\r', '\n'], " "));
            out.push_str("\r\n");
        } else {
            out.push_str(line);
        }
    }
    Ok(out)
}
