//! Whether a fit of the cells less their crosstalk ([`super::crosstalk`]) still holds
//! the colour of the cells it fitted: where it misses by far more than their noise
//! explains, removing the crosstalk may have tipped the fit to another optimum, and the
//! grid fit (`tabulated`) compares it with the fit of the cells as measured. And where
//! such a fit comes within the bound of the cells it fitted while missing the measured
//! colour, the rest of that miss is the crosstalk's ([`crosstalk_explained`]): the default
//! fit does not escalate for it, nor does the noise-aware search take it for a light one
//! fluorophore cannot meet.

use std::collections::BTreeMap;

use crate::colour::Light;
use crate::material::{CrosstalkCorrection, Material};
use crate::measurement::{Measurement, Units};
use crate::model::predict;

use super::assess;
use super::crosstalk::remove;
use super::data::FitData;

/// The lights under which `cleaned`, fitted to the cells of `m` less `found`, misses
/// those cells' colour by more than `bound`, or 3 × what the colour's own noise (cells'
/// σ `sigma`) explains if larger (the default fit's noise-aware bound: a miss of that
/// size is no sign of another optimum), with its ΔE2000. The cells' patch has its
/// missing cells filled from the fit, as the report's reference has.
pub(super) fn own_colour_misses(
    m: &Measurement,
    cleaned: &Material,
    found: &CrosstalkCorrection,
    lights: &[Light],
    sigma: f64,
    guard_nm: f64,
    bound: f64,
) -> Vec<(String, f64)> {
    let data = FitData::with_crosstalk(m, guard_nm, Some(found));
    let noise = assess::colour_noise_delta_e2000(m, cleaned, &data, lights, sigma);
    let bounds = assess::noise_aware_bounds(bound, lights, &noise);
    own_colour_delta_e(m, cleaned, found, lights)
        .into_iter()
        .filter(|(light, de)| *de > bounds.get(light).copied().unwrap_or(bound))
        .collect()
}

/// The lights among `lights` under which `material`, a fit of the cells of `m` less the
/// crosstalk next to the diagonal it removed (its report's `crosstalk`), comes within
/// `bound` of the colour of those cells, with that ΔE2000: where it misses the measured
/// colour there, the rest of the miss is the crosstalk's, a monochromator offset that
/// moves the measured colour as no material does. Empty where the fit kept the cells as
/// measured (or has no report).
pub(super) fn crosstalk_explained(
    m: &Measurement,
    material: &Material,
    lights: &[Light],
    bound: f64,
) -> BTreeMap<String, f64> {
    let removed = material
        .fit
        .as_ref()
        .and_then(|f| f.crosstalk.as_ref())
        .filter(|c| c.removed);
    let Some(found) = removed.filter(|_| !lights.is_empty()) else {
        return BTreeMap::new();
    };
    own_colour_delta_e(m, material, found, lights)
        .into_iter()
        .filter(|(_, de)| *de <= bound)
        .collect()
}

/// Per light, ΔE2000 between `material`'s patch and the colour of the cells of `m` less
/// `found` (its missing cells filled from the material, as the report's reference has):
/// how far the material is from the cells it was fitted to.
pub(super) fn own_colour_delta_e(
    m: &Measurement,
    material: &Material,
    found: &CrosstalkCorrection,
    lights: &[Light],
) -> BTreeMap<String, f64> {
    let predicted = predict(
        material,
        &m.name,
        &m.excitation_nm,
        &m.emission_nm,
        Units::PerBin,
        true,
    );
    let cells = assess::measured_patch(&remove(m, found), &predicted);
    assess::patch_delta_e2000(m, &cells, &predicted, lights)
}
