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
//! (`ArRSSpectrum2D.c`), so 10 nm steps are the default. The model's full matrix is
//! written, every fluorophore summed, anti-Stokes cells included (ART zeroes the cells with
//! excitation at or above emission but keeps the diagonal, `rss2d_strip_noncrosstalk_data`
//! in `ArCrosstalk500.c`, so it renders only the Stokes part of the model).
//!
//! RENDERED in ART 99c65c0 (docs/renderers.md, `scripts/verify-renderers.sh` with `ART`): a
//! furnace of each material of `fits/measured/` under D65, A, F11 and the UV-rich light,
//! rendered with `-s46e` (ART's default 8 bands of 40 nm over 380-700 nm cost up to 4
//! ΔE2000 on plain saturated reflectances), matches the exact colour of the model without
//! its anti-Stokes re-emission at these 10 nm cells within ΔE2000 1; against the full model
//! the dropped anti-Stokes part costs up to about 1.5.

use crate::error::{Error, Result};
use crate::material::Material;
use crate::measurement::Units;

use super::matrix::{default_grids, matrix};
use super::spectra::number;
use super::{VERSION, one_line};

/// The step ART's interpolation assumes (nm).
const ART_STEP_NM: f64 = 10.0;

/// What the archive has been checked against, in its description (the archive holds no
/// comments): the furnace renders of docs/renderers.md.
const ART_CHECKED: &str = "RENDERED in ART 99c65c0 (render with artist -s46e: the default 8 bands of 40 nm shift saturated colours by up to 4 CIEDE2000): in a furnace under D65, A, F11 and a UV-rich light, the six one-fluorophore materials of fluorite's fits/measured come out within 1 CIEDE2000 of the model's exact colour without anti-Stokes re-emission, which ART does not render (it zeroes the cells with excitation at or above emission, keeping the diagonal); that part costs up to about 1.5 CIEDE2000 against the full model (docs/renderers.md).";

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
) -> Result<(String, String)> {
    let (default_ex, default_em) = default_grids(material);
    let ex = excitation_nm.map_or_else(|| tens(&default_ex), <[f64]>::to_vec);
    let em = emission_nm.map_or_else(|| tens(&default_em), <[f64]>::to_vec);
    let (ex_start, ex_step) = regular(&ex, "excitation")?;
    let (em_start, em_step) = regular(&em, "emission")?;
    let m = matrix(material, &ex, &em, Units::PerBin)?;
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
Description           :  fluorite model of {name}: bispectral radiance factor per emission bin (trapezoid widths: {em_step} nm, half at the two ends), dimensionless; series = emission wavelengths, values within a series = excitation wavelengths; every cell of the model, the anti-Stokes ones included.{step_note} {ART_CHECKED}\n\
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
    Ok((format!("{stem}.ark"), text))
}
