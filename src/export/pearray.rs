//! PearRay: the model as PearRay 95f065ad renders it, in a `.prc` file to include, and the
//! spectra as a CSV.
//!
//! PearRay's `fluorescent` material (`src/plugins/main/materials/fluorescent_diffuse.cpp`)
//! holds Jung et al. 2018 on paper but does not render it as it stands (docs/renderers.md):
//! its wavelength-preserving term is weighted by `nonFlourescency()`, which is 0 on the
//! diagonal, and its re-emission comes out scaled by 1/(Σ400 e · span) (the emission
//! normalised by a sum over 400 bins, the excitation pdf per unit of the normalised range).
//! The export therefore writes what renders the model in the `direct` integrator with
//! `:nee false` (BSDF sampling only; with light sampling the two strategies disagree in
//! scale): PearRay's `add` of
//!   - a `diffuse` of the model's diagonal d(λ) = (1 − Σ c·a)·r, and
//!   - a `fluorescent` with `albedo` 0 (so only c·Q·a(λi)·e(λo) is left) and `scale` the
//!     inverse of that factor, computed from the CSV as PearRay reads it,
//!
//! each doubled, because `add` (`add.cpp`, `sample()`) draws one of its two materials with
//! probability 1/2 and does not divide its weight by 1/2. The emission is floored at 1e-12
//! per nm so that the material never falls back to its broken non-fluorescent lobe (it
//! does where e(λo) = 0). A photon-form fluorophore (Q(λi) = Φ·λi/λ̄e) is written exactly
//! as `aefactor` 1, `absorption` X/max X and `concentration` max X with X = c·Φ·(λi/λ̄e)·a.
//! With several fluorophores the one re-emitting the most under the first light is kept;
//! d keeps every fluorophore's absorption; the others' re-emission is dropped (the `.prc`
//! says how much).
//!
//! The CSV follows what PearRay's readers accept: `src/base/container/CSV.cpp` has no
//! comment lines (a header row of names, then numbers parsed by `std::stof`), and the
//! `spd` node (`src/plugins/main/node/SPDFileNode.cpp`) places the rows on an
//! equidistant grid from the first two wavelengths, so the CSV has one row per nm.

use crate::colour::Light;
use crate::material::{Material, YieldForm};

use super::baked::strongest_fluorophore;
use super::spectra::{number, union_grid};
use super::{VERSION, one_line};

/// How this export was checked, for its header (docs/renderers.md).
const PEARRAY_RENDERED: &str = "\
; RENDERED in PearRay 95f065ad (scripts/verify-renderers.sh, docs/renderers.md): a furnace sphere of this\n\
; material matches the exact colour of the model within ΔE2000 1 under D65, A, F11 and the UV light, with\n\
; (integrator :type 'direct' :nee false) and PearRay built with -DPR_USE_CIE_1931. Both matter:\n\
; - :nee false. With light sampling (the default) PearRay's `fluorescent` material comes out at the scale\n\
;   of its light-wavelength pdf, which differs from the BSDF one this file compensates; the colour is wrong.\n\
; - PearRay's film uses the CIE 2006 2° observer (src/core/spectral/CIE.h) unless built with\n\
;   -DPR_USE_CIE_1931; with it, saturated colours differ from CIE 1931 by several ΔE2000 (a plain\n\
;   `diffuse` too), and it repeats its 390 nm value below 390 nm when the scene's spectral_domain starts lower.\n\
; Why an `add` and a `scale`: PearRay's `fluorescent` weights its non-fluorescent term by\n\
; nonFlourescency() = |λ - λ'| (0 on the diagonal) and scales its re-emission by 1/(Σ400 e · span); `add`\n\
; samples each of its two materials with probability 1/2 without dividing by it (so both are doubled).\n";

/// The emission's floor in the CSV (1/nm): far below any colour, above 0 so that PearRay's
/// `fluorescent` never selects its non-fluorescent lobe (`pdfSelectFluorescent` is 0/0 → 0
/// where e(λo) = 0 and the albedo is 0).
const EMISSION_FLOOR: f64 = 1e-12;

/// PearRay's factor on the re-emission, inverted: with BSDF sampling its `fluorescent`
/// divides e by Σ e(start + span·i/400) over 400 bins (`buildEmissionDistribution`) and
/// draws λi with a pdf per unit of the normalised range (`Distribution1D::continuousPdf`),
/// so c·Q·a·e comes out multiplied by 1/(span·Σ). `written` holds the emission as written
/// on `grid` (PearRay interpolates it linearly, `EquidistantSpectrum::lookup`).
fn pearray_emission_scale(grid: &[f64], written: &[f64]) -> f64 {
    let (start, end) = (grid[0], grid[grid.len() - 1]);
    let span = end - start;
    let step = grid[1] - grid[0];
    let sum: f64 = (0..400)
        .map(|i| {
            let x = (span * i as f64 / 400.0) / step;
            let j = (x.floor() as usize).min(written.len() - 2);
            let t = x - j as f64;
            written[j] * (1.0 - t) + written[j + 1] * t
        })
        .sum();
    span * sum
}

/// The whole-nanometre grid the CSV holds: the material's samples and 300–830 nm.
fn csv_grid(material: &Material) -> Vec<f64> {
    let samples = union_grid(material);
    let first = samples.first().map_or(300.0, |l| l.floor().min(300.0));
    let last = samples.last().map_or(830.0, |l| l.ceil().max(830.0));
    (0..=(last - first) as usize)
        .map(|i| first + i as f64)
        .collect()
}

/// PearRay: `NAME.prc` (the material) and `NAME_pearray.csv` (its spectra).
pub(super) fn pearray(material: &Material, stem: &str, lights: &[Light]) -> Vec<(String, String)> {
    let name = one_line(&material.name);
    let grid = csv_grid(material);
    let csv_name = format!("{stem}_pearray.csv");
    let kept = lights
        .first()
        .and_then(|light| strongest_fluorophore(material, light).map(|k| (k, light)));
    // (absorption, emission) per row, and the scalars, for the kept fluorophore.
    let (absorption, emission, concentration, aefactor, about): (
        Vec<f64>,
        Vec<f64>,
        f64,
        f64,
        String,
    ) = match kept {
        None => (
            vec![0.0; grid.len()],
            vec![0.0; grid.len()],
            0.0,
            0.0,
            "; The material has no fluorophore: PearRay's plain `diffuse` material (lambert.cpp) with the reflectance.\n"
                .into(),
        ),
        Some(((index, share), light)) => {
            let f = &material.fluorophores[index];
            let emission = grid
                .iter()
                .map(|&l| f.emission.eval_zero_outside(l))
                .collect();
            let n = material.fluorophores.len();
            let mut about = if n > 1 {
                format!(
                    "; This material has {n} fluorophores; PearRay's material holds one. Kept: fluorophore {index},\n\
; which re-emits {:.1} % of the fluorescent energy under light \"{}\". The others' absorption stays in\n\
; d (their light is absorbed, not re-emitted).\n",
                    100.0 * share,
                    one_line(&light.name)
                )
            } else {
                String::new()
            };
            match f.yield_form {
                YieldForm::Energy => (
                    grid.iter()
                        .map(|&l| f.absorption.eval_zero_outside(l))
                        .collect(),
                    emission,
                    f.concentration,
                    f.quantum_yield,
                    about,
                ),
                YieldForm::Photon => {
                    let mean = f.emission_mean_nm();
                    let x: Vec<f64> = grid
                        .iter()
                        .map(|&l| f.reradiated_with_mean(l, mean))
                        .collect();
                    let peak = x.iter().copied().fold(0.0, f64::max);
                    about.push_str(&format!(
                            "; The fluorophore has a constant PHOTON yield Φ = {} (energy yield Q(λi) = Φ·λi/λ̄e, λ̄e = {} nm),\n\
; which a constant aefactor cannot hold: written as aefactor 1, concentration max X and absorption\n\
; X/max X with X = c·Φ·(λi/λ̄e)·a (exact).\n",
                            number(f.quantum_yield),
                            number(mean)
                        ));
                    let absorption = x
                        .iter()
                        .map(|v| if peak > 0.0 { v / peak } else { 0.0 })
                        .collect();
                    (absorption, emission, peak, 1.0, about)
                }
            }
        }
    };
    // Column 3: the plain `diffuse`'s reflectance r, or for the `add` the diagonal d
    // doubled (add.cpp draws each material with probability 1/2 and does not divide by it).
    let (reflectance_name, reflectance_factor) = if kept.is_some() {
        ("reflectance_x2", 2.0)
    } else {
        ("albedo", 1.0)
    };
    // The emission floored so that PearRay's `fluorescent` always picks its fluorescent lobe
    // (its non-fluorescent lobe, chosen where e(λo) = 0, returns the wrong term).
    let emission: Vec<f64> = if kept.is_some() {
        emission.iter().map(|&e| e.max(EMISSION_FLOOR)).collect()
    } else {
        emission
    };
    let mut csv = format!("wavelength,absorption,emission,{reflectance_name}\n");
    let mut written: Vec<f64> = Vec::with_capacity(grid.len());
    for (i, &l) in grid.iter().enumerate() {
        let reflectance = reflectance_factor * material.diagonal(l);
        let e = number(emission[i]);
        written.push(e.parse().unwrap_or(0.0));
        csv.push_str(&format!(
            "{},{},{},{}\n",
            number(l),
            number(absorption[i]),
            e,
            number(reflectance)
        ));
    }
    let block = if kept.is_some() {
        let scale = 2.0 * pearray_emission_scale(&grid, &written);
        format!(
            "(material\n\t:name '{stem}_reflectance'\n\t:type 'diffuse'\n\t:albedo (spd '{csv_name}' 3)\n)\n\
(material\n\t:name '{stem}_fluorescence'\n\t:type 'fluorescent'\n\t:absorption (spd '{csv_name}' 1)\n\t:emission (spd '{csv_name}' 2)\n\t:albedo 0\n\t:aefactor {}\n\t:concentration {}\n\t:scale {}\n)\n\
(material\n\t:name '{stem}'\n\t:type 'add'\n\t:material1 '{stem}_reflectance'\n\t:material2 '{stem}_fluorescence'\n)\n",
            aefactor as f32, concentration as f32, scale as f32
        )
    } else {
        format!(
            "(material\n\t:name '{stem}'\n\t:type 'diffuse'\n\t:albedo (spd '{csv_name}' 3)\n)\n"
        )
    };
    let about_file = if kept.is_some() {
        format!(
            "; fluorite {VERSION} export of material \"{name}\" for PearRay: the diffuse fluorescent BBRRDF of\n\
; Jung et al. 2018, f = [δ(λi - λo)·d(λi) + c·Q·a(λi)·e(λo)] / π, as material '{stem}' (an `add` of\n\
; '{stem}_reflectance', a `diffuse` of 2·d, and '{stem}_fluorescence', a `fluorescent` with albedo 0).\n\
; Include it inside a (scene ...) with (include \"{stem}.prc\"); keep {csv_name} beside this file.\n\
; {csv_name}: one row per nm (PearRay's spd node needs equidistant rows), no comment lines (its CSV\n\
; reader has none); columns: 0 wavelength (nm), 1 absorption a (dimensionless, max 1), 2 emission e\n\
; (1/nm, integral 1, floored at {EMISSION_FLOOR:e}), 3 twice the diagonal reflectance d = (1 - c·a)·r.\n\
; aefactor is the energy quantum yield Q, concentration c; scale = 2·span·Σ e(start + span·i/400), i < 400\n\
; (span = the CSV's wavelength range), the inverse of the factor PearRay applies, doubled. Valid under every light.\n"
        )
    } else {
        format!(
            "; fluorite {VERSION} export of material \"{name}\" for PearRay (no fluorophore).\n\
; Include it inside a (scene ...) with (include \"{stem}.prc\"); keep {csv_name} beside this file.\n\
; {csv_name}: columns 0 wavelength (nm), 3 reflectance r (one row per nm, no comment lines).\n"
        )
    };
    let checked = if kept.is_some() { PEARRAY_RENDERED } else { "" };
    let prc = format!("{about_file}{checked}{about}{block}");
    vec![(format!("{stem}.prc"), prc), (csv_name, csv)]
}
