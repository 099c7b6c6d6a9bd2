//! How well a fitted material matches its measurement, and what to warn about.

use std::collections::BTreeMap;

use crate::colour::{Lab, Light, PatchColorimeter, Xyz, delta_e2000};
use crate::material::{FitReport, Material};
use crate::measurement::Measurement;
use crate::model::predict_like;

use super::colour_term::ColourTerm;
use super::data::{Cell, FitData};
use super::init::{noise_rank_one_energy, rank_one};

/// Residual RMS above this many noise σ is flagged (single fits and series alike).
pub const RESIDUAL_NOISE_FACTOR: f64 = 3.0;

/// The words of the grid fit's warning that its residual exceeds [`RESIDUAL_NOISE_FACTOR`]
/// × the noise (the default fit escalates on it).
pub const STRUCTURE_WARNING: &str =
    "the matrix holds structure one fluorophore with a constant yield does not explain";

/// `--yield auto` takes the photon form only when its objective is lower than the energy
/// form's by more than this fraction (plus ½σ²): forms that fit equally keep the paper's.
const YIELD_FORM_MARGIN: f64 = 1e-3;

/// Whether the photon form's objective `photon_cost` (½·RSS) beats the energy form's
/// `energy_cost` clearly enough to take it, at noise level `sigma`: by more than 0.1 % of
/// the energy form's objective plus ½σ².
pub fn photon_form_fits_better(energy_cost: f64, photon_cost: f64, sigma: f64) -> bool {
    photon_cost < energy_cost - (YIELD_FORM_MARGIN * energy_cost + 0.5 * sigma * sigma)
}

/// How many times the reference colour's noise (RMS ΔE76 over noise draws) a colour
/// difference may reach and still be the noise's doing. Three: noise alone passes it in
/// well under 1 % of draws per light (the stability sweep's dye-free matrices, four
/// lights each, went past twice the RMS in one of six).
pub const NOISE_COVERAGE: f64 = 3.0;

/// χ² (three degrees of freedom) of a colour difference under one light beyond which the
/// cells' noise does not explain it ([`colour_noise_chi2`]): noise alone passes it in 1
/// of 10⁵ draws per light. A ΔE within [`NOISE_COVERAGE`] × the noise's RMS is noise's
/// doing only where this holds too: the RMS is one number, while the noise spreads
/// unevenly over the colour's three channels. On class draws the grid fit of a one-dye
/// truth passes it under every light 98 % of the time, of a two-dye truth 25 %
/// (`cargo run --release --example grid_fit_tests`).
pub const NOISE_CHI2_LIMIT: f64 = 25.9;

/// Per light, the RMS ΔE76 that cell noise of level `sigma` alone gives the measured
/// patch colour `reference` (XYZ per light) on the grids of `data`.
pub fn colour_noise(data: &FitData, lights: &[Light], reference: &[Xyz], sigma: f64) -> Vec<f64> {
    ColourTerm::new(data, lights, reference, 0.0, sigma).noise_delta_e
}

/// Per light, the RMS ΔE2000 that cell noise of level `sigma` alone gives the measured
/// patch colour of `m` (the patch [`accuracy`] judges `material` against), on the grids
/// of `data`: the noise's Lab covariance Σ (channel by channel, as [`colour_noise`]
/// propagates it) through ΔE2000's local metric G at that colour, √trace(G·Σ). The noise
/// does not spread evenly over L*, a* and b* (the cells' noise moves chroma, which
/// ΔE2000 weighs less, more than lightness): taking it as even overstated green-dye's
/// under A by 1.65× against noise draws (`tests/suite/colour_noise.rs`).
pub fn colour_noise_delta_e2000(
    m: &Measurement,
    material: &Material,
    data: &FitData,
    lights: &[Light],
    sigma: f64,
) -> Vec<f64> {
    let reference = patch_xyz(m, material, lights);
    let term = ColourTerm::new(data, lights, &reference, 0.0, sigma);
    noise_delta_e2000(m, lights, &reference, &term.noise_covariance)
}

/// Per light, the squared Mahalanobis distance of the colour difference `reference −
/// model` (patch XYZ per light) under the covariance that cell noise of level `sigma`
/// gives `reference` on the grids of `data`. A colour is linear in the cells, so where the
/// difference is that noise alone this is χ² with three degrees of freedom however large
/// the noise, where a ΔE against its RMS is not: Lab bends at dark colours, and the
/// noise spreads unevenly over the three channels. ∞ where the noise is nil and the
/// colours differ, 0 where they do not.
pub fn colour_noise_chi2(
    data: &FitData,
    lights: &[Light],
    reference: &[Xyz],
    model: &[Xyz],
    sigma: f64,
) -> Vec<f64> {
    let term = ColourTerm::new(data, lights, reference, 0.0, sigma);
    lights
        .iter()
        .zip(reference.iter().zip(model))
        .zip(&term.noise_covariance)
        .map(|((light, (r, f)), covariance)| {
            // The covariance is of ΔLab, the Jacobian's image of ΔXYZ's: the distance is
            // the same in either space, so ΔXYZ goes through the same Jacobian.
            let white =
                PatchColorimeter::cached(light, &data.excitation_nm, &data.emission_nm).white;
            let j = crate::colour::lab_jacobian(*r, white);
            let d =
                nalgebra::Vector3::from_fn(|a, _| (0..3).map(|x| j[a][x] * (r[x] - f[x])).sum());
            if d.iter().all(|v| *v == 0.0) {
                return 0.0;
            }
            let c = nalgebra::Matrix3::from_fn(|a, b| covariance[a][b]);
            match c.cholesky() {
                Some(chol) => d.dot(&chol.solve(&d)),
                None => f64::INFINITY,
            }
        })
        .collect()
}

/// The cells `data` fitted, as a patch: `m` less the crosstalk next to the diagonal where
/// the fit took it out (that shift of the measured colour is the instrument's, which no
/// material shows), its missing cells filled from `predicted`.
pub(super) fn fitted_cells_patch(
    m: &Measurement,
    data: &FitData,
    predicted: &Measurement,
) -> Measurement {
    match data.crosstalk.as_ref().filter(|c| c.removed) {
        Some(found) => measured_patch(&super::crosstalk::remove(m, found), predicted),
        None => measured_patch(m, predicted),
    }
}

/// Per light, [`colour_noise_chi2`] of the difference between the measured patch (cells
/// the file does not hold filled from `material`) and `material`'s own patch: how far
/// beyond the cells' noise the fit misses the measured colour, in the χ² of three degrees
/// of freedom noise alone follows.
pub fn misfit_colour_chi2(
    m: &Measurement,
    material: &Material,
    data: &FitData,
    lights: &[Light],
    sigma: f64,
) -> Vec<f64> {
    let predicted = crate::model::predict_like(material, m).to_per_bin();
    let cells = fitted_cells_patch(m, data, &predicted);
    let reference: Vec<Xyz> = lights
        .iter()
        .map(|l| PatchColorimeter::cached(l, &m.excitation_nm, &m.emission_nm).xyz(&cells))
        .collect();
    let model: Vec<Xyz> = lights
        .iter()
        .map(|l| PatchColorimeter::cached(l, &m.excitation_nm, &m.emission_nm).xyz(&predicted))
        .collect();
    colour_noise_chi2(data, lights, &reference, &model, sigma)
}

/// [`colour_noise_delta_e2000`] from the patch colours `reference` (XYZ per light) and
/// the noise's Lab covariance per light ([`ColourTerm`]'s), for a caller that has them.
pub(super) fn noise_delta_e2000(
    m: &Measurement,
    lights: &[Light],
    reference: &[Xyz],
    covariance: &[[[f64; 3]; 3]],
) -> Vec<f64> {
    lights
        .iter()
        .zip(reference)
        .zip(covariance)
        .map(|((light, xyz), cov)| {
            let white = PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm).white;
            let metric = delta_e2000_metric(crate::colour::xyz_to_lab(*xyz, white));
            let trace: f64 = (0..3)
                .flat_map(|a| (0..3).map(move |b| (a, b)))
                .map(|(a, b)| metric[a][b] * cov[b][a])
                .sum();
            trace.max(0.0).sqrt()
        })
        .collect()
}

/// ΔE2000's local metric at `lab`: G with ΔE2000(lab, lab + d)² ≈ dᵀ·G·d for small d,
/// by central differences (polarisation for the off-diagonal entries).
pub(crate) fn delta_e2000_metric(lab: Lab) -> [[f64; 3]; 3] {
    const STEP: f64 = 1e-3;
    let squared = |d: [f64; 3]| {
        let moved = [lab[0] + d[0], lab[1] + d[1], lab[2] + d[2]];
        delta_e2000(lab, moved).powi(2)
    };
    let even = |d: [f64; 3]| 0.5 * (squared(d) + squared(d.map(|x| -x)));
    let unit = |a: usize| {
        let mut d = [0.0; 3];
        d[a] = STEP;
        d
    };
    std::array::from_fn(|a| {
        std::array::from_fn(|b| {
            let (ua, ub) = (unit(a), unit(b));
            if a == b {
                even(ua) / (STEP * STEP)
            } else {
                let plus = even([ua[0] + ub[0], ua[1] + ub[1], ua[2] + ub[2]]);
                let minus = even([ua[0] - ub[0], ua[1] - ub[1], ua[2] - ub[2]]);
                (plus - minus) / (4.0 * STEP * STEP)
            }
        })
    })
}

/// The measured patch's XYZ per light, as the accuracy report sees it.
fn patch_xyz(m: &Measurement, material: &Material, lights: &[Light]) -> Vec<crate::colour::Xyz> {
    // The model only fills cells the file does not hold: a full file needs no prediction.
    let measured = if m.values.iter().all(|v| v.is_finite()) {
        m.to_per_bin()
    } else {
        measured_patch(m, &crate::model::predict_like(material, m).to_per_bin())
    };
    lights
        .iter()
        .map(|l| PatchColorimeter::cached(l, &m.excitation_nm, &m.emission_nm).xyz(&measured))
        .collect()
}

/// Per light, the ΔE2000 a fit must stay within: `bound`, or the difference the
/// reference's noise explains ([`NOISE_COVERAGE`] × `noise`) where that is larger. A
/// colour difference the measurement's own noise explains is no evidence of a model
/// missing something, and fitting it means fitting noise.
pub fn noise_aware_bounds(bound: f64, lights: &[Light], noise: &[f64]) -> BTreeMap<String, f64> {
    lights
        .iter()
        .zip(noise)
        .map(|(light, n)| (light.name.clone(), bound.max(NOISE_COVERAGE * n)))
        .collect()
}

/// Σ over `lights` of max(0, ΔE2000 − bound): by how much `delta_e2000` exceeds the
/// bounds in total, each light held to its bound in `bounds` or to `default_bound`. A
/// light without a finite ΔE2000 exceeds by ∞. The default fit's fallback and the
/// search's closest fit when none meets the bound both keep the fit of least total.
pub fn total_excess<'a>(
    delta_e2000: &BTreeMap<String, f64>,
    lights: impl IntoIterator<Item = &'a str>,
    bounds: &BTreeMap<String, f64>,
    default_bound: f64,
) -> f64 {
    lights
        .into_iter()
        .map(|l| match delta_e2000.get(l) {
            Some(de) if de.is_finite() => {
                (de - bounds.get(l).copied().unwrap_or(default_bound)).max(0.0)
            }
            _ => f64::INFINITY,
        })
        .sum()
}

/// The largest ΔE2000 over the lights (0 for none).
pub fn worst(delta_e: &BTreeMap<String, f64>) -> f64 {
    delta_e.values().cloned().fold(0.0, f64::max)
}

/// The light under which `delta_e2000` exceeds its bound in `bounds` the most (by ratio),
/// with its ΔE2000; None when every light is within its bound.
pub fn worst_excess(
    delta_e2000: &BTreeMap<String, f64>,
    bounds: &BTreeMap<String, f64>,
) -> Option<(String, f64)> {
    delta_e2000
        .iter()
        .filter_map(|(light, de)| {
            let bound = bounds.get(light)?;
            (*de > *bound || !de.is_finite()).then_some((light, *de, *de / bound))
        })
        .max_by(|a, b| a.2.total_cmp(&b.2))
        .map(|(light, de, _)| (light.clone(), de))
}

/// Accuracy figures of a fit.
#[derive(Debug, Clone, Default)]
pub struct Accuracy {
    /// ‖M − F‖/‖M‖ over the Stokes-side cells the fit uses.
    pub rel_residual_fluorescence: f64,
    /// RMSE of the diagonal.
    pub rmse_diagonal: f64,
    /// RMS residual over all fitted off-diagonal cells.
    pub rms_off_diagonal: f64,
    /// ΔE2000 per light.
    pub delta_e2000: BTreeMap<String, f64>,
    /// What of the colour reference was filled from the model (missing cells).
    pub filled: FilledReference,
}

impl Accuracy {
    /// Records the residuals, the ΔE2000 and the filled share of the colour reference in
    /// a fit report.
    pub fn record_in(&self, fit: &mut FitReport) {
        fit.rel_residual_fluorescence = self.rel_residual_fluorescence;
        fit.rmse_diagonal = self.rmse_diagonal;
        fit.delta_e2000 = self.delta_e2000.clone();
        fit.reference_filled_cells = self.filled.cells;
        fit.reference_filled_share = self.filled.light_share;
        fit.reference_filled_delta_e2000 = self.filled.delta_e2000.clone();
    }

    /// Whether the off-diagonal residual exceeds [`RESIDUAL_NOISE_FACTOR`] × `noise_sigma`:
    /// structure the model does not explain. The noise estimate of exact (synthetic) data
    /// is rounding error, so a residual below 1e-9 of `m`'s largest value never counts.
    pub fn leaves_structure(&self, noise_sigma: f64, m: &Measurement) -> bool {
        let signal_floor = 1e-9
            * m.values
                .iter()
                .filter(|v| v.is_finite())
                .fold(0.0f64, |a, v| a.max(v.abs()));
        self.rms_off_diagonal > (RESIDUAL_NOISE_FACTOR * noise_sigma).max(signal_floor)
    }

    /// [`unconfirmed_fill_warning`] for this fit of `m` at noise level `noise_sigma`.
    pub fn unconfirmed_fill(
        &self,
        noise_sigma: f64,
        m: &Measurement,
        bound: f64,
    ) -> Option<String> {
        unconfirmed_fill_warning(&self.filled, self.leaves_structure(noise_sigma, m), bound)
    }
}

/// CIELAB of `material`'s patch under each light: predicted on `m`'s grids (per bin, with
/// a diagonal where `m` has one) and seen by the cached colorimeters of those grids.
pub fn predicted_labs(material: &Material, m: &Measurement, lights: &[Light]) -> Vec<Lab> {
    let per_bin = crate::model::predict(
        material,
        &m.name,
        &m.excitation_nm,
        &m.emission_nm,
        crate::measurement::Units::PerBin,
        m.has_diagonal,
    );
    lights
        .iter()
        .map(|light| PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm))
        .map(|pc| pc.lab(&per_bin))
        .collect()
}

/// Residual figures and ΔE2000 for `material` against measurement `m`.
pub fn accuracy(
    material: &Material,
    m: &Measurement,
    data: &FitData,
    lights: &[Light],
) -> Accuracy {
    let fitted = predict_like(material, m);
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
    let mut filled = FilledReference::default();
    if m.has_diagonal && !m.arbitrary_scale {
        let fitted_per_bin = fitted.to_per_bin();
        filled = filled_reference(m, &fitted_per_bin, lights);
        let measured = measured_patch(m, &fitted_per_bin);
        for light in lights {
            let pc = PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm);
            let (lab_m, lab_f) = (pc.lab(&measured), pc.lab(&fitted_per_bin));
            delta_e.insert(light.name.clone(), delta_e2000(lab_m, lab_f));
        }
    }
    Accuracy {
        rel_residual_fluorescence: rel(&data.stokes),
        rmse_diagonal: rms(&data.diagonal),
        rms_off_diagonal: rms(&data.off_diagonal),
        delta_e2000: delta_e,
        filled,
    }
}

/// Per light, ΔE2000 between `material`'s patch and the measured cells of `m` with the
/// cells the file does not hold filled from `filler` instead of from `material` itself
/// (as [`accuracy`] fills them). Where `material` leaves structure in the measured cells,
/// its own fill is no evidence of its colour ([`unconfirmed_fill_warning`]); a model that
/// explains those cells (the lowest BIC) predicts the rest better, and judged against
/// the same fill, two fits compare on one reference.
pub fn delta_e2000_filled_from(
    material: &Material,
    filler: &Material,
    m: &Measurement,
    lights: &[Light],
) -> BTreeMap<String, f64> {
    let own = predict_like(material, m).to_per_bin();
    let reference = measured_patch(m, &predict_like(filler, m).to_per_bin());
    patch_delta_e2000(m, &reference, &own, lights)
}

/// Per light, ΔE2000 between the patches of the per-bin cells `reference` and `model`
/// on the grids of `m`.
pub fn patch_delta_e2000(
    m: &Measurement,
    reference: &Measurement,
    model: &Measurement,
    lights: &[Light],
) -> BTreeMap<String, f64> {
    lights
        .iter()
        .map(|light| {
            let pc = PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm);
            (
                light.name.clone(),
                delta_e2000(pc.lab(reference), pc.lab(model)),
            )
        })
        .collect()
}

/// The measured patch the colour is judged on, per bin: the measurement as measured
/// (model.md §7). Every measured cell counts, the cells next to the diagonal included;
/// only cells the file does not hold (missing) are taken from `fitted_per_bin`. A
/// reference that borrowed any measured cell from the fit would let the fit grade itself.
pub fn measured_patch(m: &Measurement, fitted_per_bin: &Measurement) -> Measurement {
    m.to_per_bin().filled_from(fitted_per_bin)
}

/// XYZ of the measured patch under each light, as the accuracy report sees it
/// ([`measured_patch`]: every measured cell, missing ones from the tabulated fit,
/// whose matrix on `m`'s grids is `grid_predicted`).
pub fn measured_xyz(m: &Measurement, grid_predicted: &Measurement, lights: &[Light]) -> Vec<Xyz> {
    let measured = measured_patch(m, &grid_predicted.to_per_bin());
    lights
        .iter()
        .map(|light| {
            PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm).xyz(&measured)
        })
        .collect()
}

/// How much of the colour reference was not measured: the cells filled from the model,
/// the largest share, over `lights`, of the reference patch's light they carry, and what
/// they are worth in colour.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FilledReference {
    /// Cells the file does not hold.
    pub cells: usize,
    /// Largest share over the lights of the patch's luminance (Y) those cells carry.
    pub light_share: f64,
    /// Per light, ΔE2000 between the reference patch and the same patch with those cells
    /// at zero: how far the model's guess in cells no one measured moves the colour.
    pub delta_e2000: BTreeMap<String, f64>,
}

/// [`FilledReference`] of the patch [`measured_patch`] builds from `m` and
/// `fitted_per_bin`.
pub fn filled_reference(
    m: &Measurement,
    fitted_per_bin: &Measurement,
    lights: &[Light],
) -> FilledReference {
    let missing: Vec<bool> = m.values.iter().map(|v| !v.is_finite()).collect();
    let cells = missing.iter().filter(|&&x| x).count();
    if cells == 0 {
        return FilledReference::default();
    }
    let reference = measured_patch(m, fitted_per_bin);
    let mut filled_only = reference.clone();
    let mut measured_only = reference.clone();
    for ((f, o), &is_missing) in filled_only
        .values
        .iter_mut()
        .zip(measured_only.values.iter_mut())
        .zip(&missing)
    {
        if is_missing {
            *o = 0.0;
        } else {
            *f = 0.0;
        }
    }
    let mut light_share = 0.0f64;
    let mut delta_e = BTreeMap::new();
    for light in lights {
        let pc = PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm);
        let total = pc.xyz(&reference)[1];
        let filled = pc.xyz(&filled_only)[1];
        if total.abs() > 0.0 {
            light_share = light_share.max((filled / total).abs());
        }
        delta_e.insert(
            light.name.clone(),
            delta_e2000(pc.lab(&reference), pc.lab(&measured_only)),
        );
    }
    FilledReference {
        cells,
        light_share,
        delta_e2000: delta_e,
    }
}

/// The warning for a fit whose colour rests on filled cells it cannot vouch for: the
/// cells the file does not hold are worth more than `bound` ΔE2000 under some light, and
/// the residual on the measured cells leaves structure (`leaves_structure`), so the model
/// that fills them is known not to be the matrix's. A model that explains the measured
/// cells to their noise predicts the rest from the same spectra (one fluorophore's
/// a(λi)·e(λo) round-trips the spectral EXR layout within ΔE2000 0.25); one that does not
/// may put any colour there (HERPICER's two fluorophores through that layout, refitted
/// with one: ΔE2000 ≤ 0.3 on the measured cells, 5.9 off in full under D65). None when
/// the fill is worth less or the model explains the measured cells.
pub fn unconfirmed_fill_warning(
    filled: &FilledReference,
    leaves_structure: bool,
    bound: f64,
) -> Option<String> {
    let worth: BTreeMap<String, f64> = filled
        .delta_e2000
        .iter()
        .filter(|(_, de)| **de > bound)
        .map(|(l, de)| (l.clone(), *de))
        .collect();
    if !leaves_structure || worth.is_empty() {
        return None;
    }
    let listed: Vec<String> = worth.iter().map(|(l, de)| format!("{l} {de:.2}")).collect();
    Some(format!(
        "{UNCONFIRMED_FILL_WARNING}: the {} cells the file does not hold are worth ΔE2000 {} (the patch with and without them) and are filled from a model whose residual leaves structure above {RESIDUAL_NOISE_FACTOR} × the noise, so the colour in full may be off by that much although the ΔE2000 against the measured cells is small; measure those cells (a file or layout that holds them), or treat the material's colour as uncertain by that much",
        filled.cells,
        listed.join(", ")
    ))
}

/// The energy of the non-negative rank-1 component of what the grid model leaves, in units
/// of σ²(√m + √n)², above which it counts as a second fluorophore
/// (the noise-aware search then looks on among two-component models; the default fit
/// does not excuse a miss by the noise). The grid fit asks the matrix the same question before it
/// fits any fluorescence (pure noise explains at most 0.86 there). Measured on `fluorite
/// class` (five seeds, every case the test judged): at most 6.4 on 522 of 524 one-dye
/// truths (91 and 135 on two whose grid fit ends 0.59 and 0.32 from the truth), above 5 on
/// 151 of 188 two-dye truths (a weak second dye leaves nothing). At 5 against the mean
/// squared residual at 3 σ² it was taking before: 0xBEEF p90 1.67 → 1.53, max 4.95 →
/// 4.79, seed 12 p90 1.46 → 1.42, the default seed's max 2.70 → 2.78; 3 and 8 within 0.1.
/// Over every grid fit of seeds default, 7, 11, 12 and 0xBEEF: above 5 on 4 of 547 one-dye truths, 161
/// of 201 two-dye truths (`cargo run --release --example grid_fit_tests`).
pub const SECOND_FLUOROPHORE_ENERGY: f64 = 5.0;

/// Sweeps of the rank-1 fit of the grid model's residual: 30 gave the class the same
/// figures as the grid fit's 200 (default seed and 0xBEEF), the search 0.7 ms sooner.
const RANK_ONE_SWEEPS: usize = 30;

/// What the grid model (its matrix `predicted`) leaves in the off-diagonal cells of `data`
/// more than one emission step from their excitation wavelength (where the crosstalk next
/// to the diagonal sits, up to 350 σ² per cell on one-dye truths, whatever the
/// fluorophores): the energy of its best non-negative rank-1 component in units of
/// σ²(√m + √n)², m × n the matrix. A second fluorophore shows there as a positive excitation × emission
/// product the single component could not take.
pub fn second_fluorophore_energy(
    predicted: &Measurement,
    m: &Measurement,
    data: &FitData,
    sigma: f64,
) -> f64 {
    let em = &m.emission_nm;
    let step = |j: usize| {
        let below = j.checked_sub(1).map(|b| em[j] - em[b]);
        let above = em.get(j + 1).map(|a| a - em[j]);
        below.into_iter().chain(above).fold(0.0f64, f64::max)
    };
    let mut left = data.clone();
    left.off_diagonal = data
        .off_diagonal
        .iter()
        .filter(|c| (em[c.column] - m.excitation_nm[c.row]).abs() > step(c.column) + 1e-6)
        .map(|c| Cell {
            value: c.value - predicted.get(c.row, c.column),
            ..*c
        })
        .filter(|c| c.value.is_finite())
        .collect();
    let explained = rank_one(&left, RANK_ONE_SWEEPS).explained(&left);
    explained.max(0.0) / noise_rank_one_energy(sigma, m.n_excitation(), m.n_emission()).max(1e-300)
}

/// The words that open [`unconfirmed_fill_warning`]'s warning.
pub const UNCONFIRMED_FILL_WARNING: &str = "colour unconfirmed in cells no one measured";

/// Whether `report` carries [`unconfirmed_fill_warning`]'s warning: its fit's colour
/// rests on cells it filled itself, from a model that leaves structure in the others.
pub fn colour_unconfirmed(report: &FitReport) -> bool {
    report
        .warnings
        .iter()
        .any(|w| w.starts_with(UNCONFIRMED_FILL_WARNING))
}

/// Bayesian information criterion of a fit of `data` with `parameters` parameters whose
/// matrix residual (off-diagonal and diagonal cells) sums to `rss`: BIC = RSS/σ² + p·ln n,
/// n the cells fitted, σ the noise level (floored at 1e-12, so noise-free data rank by
/// RSS); lower is better among fits of the same data. The grid fit and every search
/// candidate are ranked by this one recipe.
pub fn bic(rss: f64, sigma: f64, parameters: usize, data: &FitData) -> f64 {
    let residuals = data.off_diagonal.len() + data.diagonal.len();
    let sigma = sigma.max(1e-12);
    rss / (sigma * sigma) + parameters as f64 * (residuals.max(1) as f64).ln()
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

#[cfg(test)]
mod tests {
    use super::*;

    fn filled(worth: &[(&str, f64)]) -> FilledReference {
        FilledReference {
            cells: 120,
            light_share: 0.05,
            delta_e2000: worth.iter().map(|(l, v)| (l.to_string(), *v)).collect(),
        }
    }

    /// Cells worth more than the bound warn only when the model leaves structure, and the
    /// warning names every light past the bound with its worth.
    #[test]
    fn unconfirmed_fill_needs_both_worth_and_structure() {
        let worth = filled(&[("d65", 5.02), ("a", 11.81), ("uv", 0.4)]);
        assert!(unconfirmed_fill_warning(&worth, false, 1.0).is_none());
        assert!(unconfirmed_fill_warning(&filled(&[("d65", 0.9)]), true, 1.0).is_none());
        let w = unconfirmed_fill_warning(&worth, true, 1.0).unwrap();
        assert!(w.starts_with(UNCONFIRMED_FILL_WARNING), "{w}");
        assert!(
            w.contains("a 11.81") && w.contains("d65 5.02") && !w.contains("uv"),
            "{w}"
        );
        assert!(w.contains("120 cells"), "{w}");
        // A looser bound (--max-delta-e 6) leaves only A.
        let w = unconfirmed_fill_warning(&worth, true, 6.0).unwrap();
        assert!(w.contains("a 11.81") && !w.contains("d65"), "{w}");
    }
}
