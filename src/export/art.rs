//! ART (BUG-Association/ART): a bispectral entry of an ART measurement archive (`.ark`),
//! laid out like `ART_Resources/SpectralData/FluorescentPostIt.ark` and read by
//! `Source/ClassLibraries/Parser/ArfMeasurementArchive.m`.
//!
//! The archive's fields come in a fixed order with fixed labels (the parser `scanf`s
//! them), and "no comments or other, unspecified text can be inserted": the quantity and
//! units are stated in the archive content line and the entry's description. The
//! sample data `{{…}, {…}}` hold one series per emission ("reflectance") wavelength, each
//! with one value per excitation ("illumination") wavelength: ART's `ARRSS2D_SAMPLE(s,
//! i, j)` reads `array[j·stride + i]`, i the excitation and j the emission index. The
//! whole array sits on one line, as the parser skips only spaces between series. Grids
//! are regular (start and increment); ART's interpolation divides offsets by 10 nm
//! (`ArRSSpectrum2D.c`), so 10 nm steps are the default. The model's matrix is written,
//! every fluorophore summed, with its anti-Stokes part folded into the diagonal: ART zeroes
//! the cells with excitation at or above emission but keeps the diagonal
//! (`rss2d_strip_noncrosstalk_data` in `ArCrosstalk500.c`), so it renders only Stokes
//! shifts, and dropping the model's anti-Stokes re-emission (light absorbed at λi, emitted
//! at λo < λi where absorption and emission overlap) cost up to ΔE2000 1.5. Folded, that
//! light is emitted at λo as if the light at λo had been reflected: exact under an
//! equal-energy light, off under others by how much the light differs between λi and λo
//! ([`fold_anti_stokes`]).
//!
//! RENDERED in ART 99c65c0 (docs/renderers.md, `scripts/verify-renderers.sh` with `ART`): a
//! furnace of each material of `fits/measured/` under D65, A, F11 and the UV-rich light,
//! rendered with `-s46e` (ART's default 8 bands of 40 nm over 380-700 nm cost up to 4
//! ΔE2000 on plain saturated reflectances); the figures against the model's exact colour
//! are in docs/renderers.md.

use crate::error::{Error, Result};
use crate::material::Material;
use crate::measurement::Units;

use crate::measurement::Measurement;

use super::matrix::{default_grids, matrix};
use super::spectra::number;
use super::{VERSION, one_line};

/// The step ART's interpolation assumes (nm).
const ART_STEP_NM: f64 = 10.0;

/// What the archive has been checked against, in its description (the archive holds no
/// comments): the furnace renders of docs/renderers.md.
const ART_CHECKED: &str = "RENDERED in ART 99c65c0 (render with artist -s46e: the default 8 bands of 40 nm shift saturated colours by up to 4 CIEDE2000) in a furnace under D65, A, F11 and a UV-rich light: the six materials of fluorite's fits/measured come out within 0.91 CIEDE2000 of the model's exact colour (the fold below costs up to 0.73), except one under UV (1.03), from ART's 10 nm spectral buckets (docs/renderers.md). ART renders Stokes shifts only (it zeroes the cells with excitation at or above emission, keeping the diagonal), so the model's anti-Stokes re-emission is folded into the diagonal of its emission wavelength and those cells are written as 0: exact under an equal-energy light.";

/// What [`fold_anti_stokes`] moved, for the export's notes.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct Fold {
    /// The anti-Stokes share of the off-diagonal energy under an equal-energy light.
    pub share: f64,
    /// The part of that share not folded, because the diagonal's excitation would have
    /// re-emitted more than it received.
    pub clamped: f64,
}

/// Moves every anti-Stokes cell (excitation above emission) of `m` onto the diagonal cell
/// of its emission wavelength, scaled by the excitation step over the emission step (what
/// keeps the emission under an equal-energy light), and zeroes it. An emission wavelength
/// without a diagonal cell keeps its anti-Stokes cells (ART drops them). A diagonal
/// excitation's albedo (its column's sum) is not raised above 1 by the fold: the surplus
/// is dropped and reported in [`Fold::clamped`].
pub(super) fn fold_anti_stokes(m: &mut Measurement, ex_step: f64, em_step: f64) -> Fold {
    let (ex, em) = (m.excitation_nm.clone(), m.emission_nm.clone());
    let scale = ex_step / em_step;
    let (mut off_diagonal, mut anti, mut clamped) = (0.0, 0.0, 0.0);
    for (i, &li) in ex.iter().enumerate() {
        for (j, &lo) in em.iter().enumerate() {
            let v = m.get(i, j);
            if (li - lo).abs() > 1e-9 && v.is_finite() {
                off_diagonal += v;
            }
        }
    }
    for (d, j) in m.diagonal() {
        let lo = em[j];
        let mut moved = 0.0;
        for (i, &li) in ex.iter().enumerate() {
            if li > lo + 1e-9 {
                let cell = m.get_mut(i, j);
                if cell.is_finite() {
                    moved += *cell;
                    anti += *cell;
                }
                *cell = 0.0;
            }
        }
        let albedo: f64 = (0..em.len())
            .map(|k| m.get(d, k))
            .filter(|v| v.is_finite())
            .sum();
        let room = (1.0 - albedo).max(0.0);
        let folded = (moved * scale).min(room);
        clamped += moved - folded / scale;
        *m.get_mut(d, j) += folded;
    }
    if off_diagonal > 0.0 {
        Fold {
            share: anti / off_diagonal,
            clamped: clamped / off_diagonal,
        }
    } else {
        Fold::default()
    }
}

/// A regular grid's start and step, or an error naming `what` and the fix.
fn regular(grid: &[f64], what: &str) -> Result<(f64, f64)> {
    let (Some(&start), Some(&second)) = (grid.first(), grid.get(1)) else {
        return Err(Error::invalid(
            "--grid",
            format!("the {what} grid needs at least two wavelengths for ART"),
        ));
    };
    let step = second - start;
    for (i, &l) in grid.iter().enumerate() {
        if (l - (start + step * i as f64)).abs() > 1e-6 * step.max(1.0) {
            return Err(Error::invalid(
                "--grid",
                format!(
                    "ART archives hold regular grids; the {what} grid is not (at {l} nm); give start:end:step, e.g. 300:780:10"
                ),
            ));
        }
    }
    Ok((start, step))
}

/// The default grid: 10 nm steps over the material's samples, ends rounded outwards to
/// whole tens of nm.
fn tens(grid: &[f64]) -> Vec<f64> {
    let first = (grid.first().copied().unwrap_or(380.0) / ART_STEP_NM).floor();
    let last = (grid.last().copied().unwrap_or(780.0) / ART_STEP_NM).ceil();
    (0..=(last - first).max(1.0) as usize)
        .map(|i| (first + i as f64) * ART_STEP_NM)
        .collect()
}

/// ART: `NAME.ark` on the given grids (default: 10 nm over the material's samples), in
/// radiance factor per emission bin.
pub(super) fn art(
    material: &Material,
    stem: &str,
    excitation_nm: Option<&[f64]>,
    emission_nm: Option<&[f64]>,
) -> Result<(String, String, Fold)> {
    let (default_ex, default_em) = default_grids(material);
    let ex = excitation_nm.map_or_else(|| tens(&default_ex), <[f64]>::to_vec);
    let em = emission_nm.map_or_else(|| tens(&default_em), <[f64]>::to_vec);
    let (ex_start, ex_step) = regular(&ex, "excitation")?;
    let (em_start, em_step) = regular(&em, "emission")?;
    let mut m = matrix(material, &ex, &em, Units::PerBin)?;
    let fold = fold_anti_stokes(&mut m, ex_step, em_step);
    let name = one_line(&material.name);
    let n = material.fluorophores.len();
    let step_note = if ex_step != ART_STEP_NM || em_step != ART_STEP_NM {
        " ART's interpolation assumes 10 nm steps; these grids differ, so use them only with code that reads the steps."
    } else {
        ""
    };
    let series: Vec<String> = (0..em.len())
        .map(|j| {
            let row: Vec<String> = (0..ex.len()).map(|i| number(m.get(i, j))).collect();
            format!("{{{}}}", row.join(", "))
        })
        .collect();
    let summed = if n > 1 {
        format!(", {n} fluorophores summed")
    } else {
        String::new()
    };
    let text = format!(
        "ART measurement archive version 1.1\n\
\n\
Archive content: fluorite {VERSION} export of material \"{name}\": the reradiation matrix of the diffuse fluorescent BBRRDF (Jung et al. 2018) fitted to it, as a bispectral radiance factor per emission bin (dimensionless): diagonal d = (1 - c*a)*r plus fluorescence c*Q(excitation)*a(excitation)*e(emission)*bin width{summed}.\n\
\n\
\n\
Entry ID:   {stem}\n\
---------------------------------------------------------------------------\n\
Description           :  fluorite model of {name}: bispectral radiance factor per emission bin (trapezoid widths: {em_step} nm, half at the two ends), dimensionless; series = emission wavelengths, values within a series = excitation wavelengths; the model's anti-Stokes re-emission (excitation above emission) folded into the diagonal of its emission wavelength, those cells 0.{step_note} {ART_CHECKED}\n\
Type                  :  reflectance spectrum\n\
Fluorescence data     :  yes\n\
Measurement device    :  fluorite {VERSION} (a model, not a measurement)\n\
Measured by           :  fluorite export\n\
Measurement date      :  \n\
\n\
Sampling information\n\
--------------------\n\
Type                  :  regular\n\
Reflectance start     :  {em_start} nm\n\
Reflectance increment :  {em_step} nm\n\
Illumination start    :  {ex_start} nm\n\
Illumination increment:  {ex_step} nm\n\
Maximum sample value  :  1.0\n\
\n\
ASCII sample data\n\
-----------------\n\
{{{}}}\n",
        series.join(", ")
    );
    Ok((format!("{stem}.ark"), text, fold))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 3 × 3 on a shared 10 nm grid: rows excitation, columns emission.
    fn matrix3(values: [[f64; 3]; 3]) -> Measurement {
        let grid = vec![400.0, 410.0, 420.0];
        let flat = values.iter().flatten().copied().collect();
        Measurement::new("fold", grid.clone(), grid, flat, Units::PerBin).unwrap()
    }

    /// The anti-Stokes cells move onto the diagonal of their emission wavelength, so every
    /// emission column keeps its sum (the emission under an equal-energy light).
    #[test]
    fn fold_keeps_each_emission_under_equal_energy() {
        let before = [[0.5, 0.1, 0.05], [0.02, 0.4, 0.1], [0.01, 0.03, 0.3]];
        let mut m = matrix3(before);
        let fold = fold_anti_stokes(&mut m, 10.0, 10.0);
        for j in 0..3 {
            let was: f64 = before.iter().map(|row| row[j]).sum();
            let now: f64 = (0..3).map(|i| m.get(i, j)).sum();
            assert!((was - now).abs() < 1e-15, "emission {j}: {was} → {now}");
            assert!((j + 1..3).all(|i| m.get(i, j) == 0.0), "emission {j}");
        }
        assert!((m.get(0, 0) - 0.53).abs() < 1e-15 && (m.get(1, 1) - 0.43).abs() < 1e-15);
        let off = 0.1 + 0.05 + 0.02 + 0.1 + 0.01 + 0.03;
        assert!((fold.share - 0.06 / off).abs() < 1e-12 && fold.clamped == 0.0);
    }

    /// A fold that would make an excitation re-emit more than it receives stops at 1 and
    /// says how much it dropped.
    #[test]
    fn fold_never_raises_an_albedo_above_one() {
        let mut m = matrix3([[0.9, 0.05, 0.0], [0.2, 0.5, 0.0], [0.0, 0.0, 0.5]]);
        let fold = fold_anti_stokes(&mut m, 10.0, 10.0);
        assert!((m.get(0, 0) + m.get(0, 1) + m.get(0, 2) - 1.0).abs() < 1e-15);
        assert!((fold.share - 0.2 / 0.25).abs() < 1e-12);
        assert!((fold.clamped - 0.15 / 0.25).abs() < 1e-12, "{fold:?}");
    }
}
