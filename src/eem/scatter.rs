//! Rayleigh and water-Raman scatter in solution EEMs: where the lines lie, how wide they
//! are, and masking them.
//!
//! Lines (emission wavelength for excitation λi): first-order Rayleigh λo = λi,
//! second-order Rayleigh λo = 2λi, first-order water Raman λo = 1/(1/λi − ν̃) with the
//! O–H stretch shift ν̃ ≈ 3400 cm⁻¹, and its second order at twice that. As in staRdom's
//! `eem_rem_scat` (eemR's `eem_remove_scattering`) and drEEM's `smootheem`, each line is
//! masked in a band from `below` nm under it to `above` nm over it. Unless set, a band's
//! widths are measured on the data: in every excitation row where the line stands out
//! (its peak at least twice the fluorescence beside it), the distances from the line to
//! the half-maximum on each side; the median over rows, times
//! [`HALF_MAX_TO_EDGE`], is the band edge. Without such rows the instrument bandwidth
//! decides (the band's edge where the excitation and emission slit functions, triangles
//! of that full width at half maximum, stop overlapping: twice the bandwidth), else
//! [`DEFAULT_HALF_WIDTH_NM`] (eemR's and staRdom's default width).
//!
//! A measured width is then held to what the lines' physics allows ([`bound`]): the
//! first-order Rayleigh line is the instrument's own profile (the excitation slit function
//! convolved with the emission one), and the other lines are that profile widened.
//! Water's Raman line is the same profile convolved with the O–H stretch band
//! ([`WATER_RAMAN_FWHM_CM`] wide), so it is at least as wide as first-order Rayleigh and at
//! most that plus the band's own edge; a wider "Raman line" is fluorescence peaking near
//! it (phenylalanine at 255 nm excitation emits at 282 nm, on the 279 nm Raman line), and
//! masking it would cut that fluorescence out. Second-order lines pass the excitation
//! band at twice its width (λo = 2λi) through the same emission slit, so they are taken
//! at least twice as wide as first-order Rayleigh, and second-order Raman at most twice
//! first-order Raman's bound.

use serde::{Deserialize, Serialize};

use crate::measurement::Measurement;

/// Raman shift of liquid water's O–H stretch band (cm⁻¹).
pub const WATER_RAMAN_SHIFT_CM: f64 = 3400.0;
/// Band half-width when nothing else decides (nm): eemR's and staRdom's default.
pub const DEFAULT_HALF_WIDTH_NM: f64 = 10.0;
/// Band edge in units of the measured half-width at half maximum: 2.5 HWHM puts a
/// Gaussian line at 1.3 % of its peak and a triangular one at zero.
pub const HALF_MAX_TO_EDGE: f64 = 2.5;
/// Rows in which a line must stand out before its width counts as measured.
pub const MIN_ROWS_MEASURED: usize = 3;
/// Full width at half maximum of liquid water's O–H stretch Raman band (cm⁻¹; the band
/// spans about 3000–3700 cm⁻¹, Walrafen): what widens the Raman line beyond the
/// instrument's profile.
pub const WATER_RAMAN_FWHM_CM: f64 = 400.0;

/// The four scatter lines of a water sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ScatterLine {
    /// λo = λi.
    Rayleigh1,
    /// λo = 1/(1/λi − ν̃).
    Raman1,
    /// λo = 2λi.
    Rayleigh2,
    /// λo = 2/(1/λi − ν̃).
    Raman2,
}

impl ScatterLine {
    /// All four, first order first (staRdom orders its widths raman1, raman2, rayleigh1,
    /// rayleigh2; options here name the line instead).
    pub const ALL: [ScatterLine; 4] = [
        ScatterLine::Rayleigh1,
        ScatterLine::Raman1,
        ScatterLine::Rayleigh2,
        ScatterLine::Raman2,
    ];

    /// The line's name as options and reports spell it.
    pub fn name(self) -> &'static str {
        match self {
            ScatterLine::Rayleigh1 => "rayleigh1",
            ScatterLine::Raman1 => "raman1",
            ScatterLine::Rayleigh2 => "rayleigh2",
            ScatterLine::Raman2 => "raman2",
        }
    }

    /// Emission wavelength (nm) of the line for excitation `ex_nm`, with the Raman shift
    /// `shift_cm` (cm⁻¹); `None` where the Raman line does not exist (shift ≥ wavenumber).
    pub fn centre_nm(self, ex_nm: f64, shift_cm: f64) -> Option<f64> {
        let raman = || {
            let wavenumber = 1e7 / ex_nm - shift_cm; // cm⁻¹
            (wavenumber > 0.0).then(|| 1e7 / wavenumber)
        };
        match self {
            ScatterLine::Rayleigh1 => Some(ex_nm),
            ScatterLine::Rayleigh2 => Some(2.0 * ex_nm),
            ScatterLine::Raman1 => raman(),
            ScatterLine::Raman2 => raman().map(|l| 2.0 * l),
        }
    }
}

/// Where a band's widths came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum WidthSource {
    /// Given by the user.
    Option,
    /// Measured on the data (half maxima of the line).
    Measured,
    /// From the instrument bandwidth the user gave.
    Bandwidth,
    /// The eemR/staRdom default.
    Default,
    /// Measured (or too faint to measure), then held within the bounds the first-order
    /// Rayleigh line and the lines' physics set (see [`bound`]).
    Bounded,
}

/// One masked band and what it took away.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MaskedBand {
    /// The line.
    pub line: ScatterLine,
    /// Masked from this many nm below the line…
    pub below_nm: f64,
    /// …to this many nm above it.
    pub above_nm: f64,
    /// Where the widths came from.
    pub source: WidthSource,
    /// Excitation rows in which the line stood out (those that measured the width).
    pub rows_measured: usize,
    /// Measured cells set to missing by this band (cells of an earlier band not counted).
    pub cells: usize,
    /// Their share of the sum of |value| over all measured cells before masking.
    pub signal_share: f64,
}

impl MaskedBand {
    /// Whether emission `em_nm` under excitation `ex_nm` lies in this band, with the
    /// Raman shift `shift_cm` (cm⁻¹).
    pub fn contains(&self, ex_nm: f64, em_nm: f64, shift_cm: f64) -> bool {
        self.line
            .centre_nm(ex_nm, shift_cm)
            .is_some_and(|c| em_nm >= c - self.below_nm - 1e-9 && em_nm <= c + self.above_nm + 1e-9)
    }
}

/// How to mask: a width per line (`None`: measured, else bandwidth, else default).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScatterOptions {
    /// Half-width (nm, both sides) per line, in [`ScatterLine::ALL`] order; `None` = auto.
    pub half_width_nm: [Option<f64>; 4],
    /// The instrument's spectral bandwidth (slit bandpass, nm), if known.
    pub bandwidth_nm: Option<f64>,
    /// Raman shift (cm⁻¹); `None` = [`WATER_RAMAN_SHIFT_CM`].
    pub raman_shift_cm: Option<f64>,
}

/// Measures a line's half-maximum distances below and above it (nm), as medians over
/// the rows where it stands out; `None` with fewer than [`MIN_ROWS_MEASURED`] rows. The
/// second value is the number of rows that measured it.
pub fn measure_width(
    m: &Measurement,
    line: ScatterLine,
    shift_cm: f64,
) -> (Option<(f64, f64)>, usize) {
    let em = &m.emission_nm;
    let step = median_step(em).max(1e-9);
    let window = (6.0 * step).max(40.0);
    let near = (1.5 * step).max(6.0);
    let (mut below, mut above) = (Vec::new(), Vec::new());
    for (i, &ex) in m.excitation_nm.iter().enumerate() {
        let Some(c) = line.centre_nm(ex, shift_cm) else {
            continue;
        };
        if c - window < em[0] || c + window > em[em.len() - 1] {
            continue;
        }
        let cells: Vec<(f64, f64)> = (0..em.len())
            .filter(|&j| (em[j] - c).abs() <= window)
            .map(|j| (em[j], m.get(i, j)))
            .filter(|(_, v)| v.is_finite())
            .collect();
        // Peak close to the line.
        let Some(&(peak_nm, peak)) = cells
            .iter()
            .filter(|(l, _)| (l - c).abs() <= near)
            .max_by(|a, b| a.1.total_cmp(&b.1))
        else {
            continue;
        };
        // The fluorescence beside the line: the lower of the two flanks' medians.
        let flank = |side: f64| {
            let mut v: Vec<f64> = cells
                .iter()
                .filter(|(l, _)| side * (l - c) > window / 2.0)
                .map(|(_, v)| *v)
                .collect();
            v.sort_by(f64::total_cmp);
            (!v.is_empty()).then(|| v[v.len() / 2])
        };
        let background = match (flank(-1.0), flank(1.0)) {
            (Some(a), Some(b)) => a.min(b),
            (Some(a), None) | (None, Some(a)) => a,
            (None, None) => continue,
        };
        if peak <= 0.0 || peak < 2.0 * background.max(0.0) {
            continue;
        }
        let half = background + 0.5 * (peak - background);
        // Walk out from the peak until the values fall below half maximum.
        let crossing = |dir: f64| -> Option<f64> {
            let mut side: Vec<&(f64, f64)> = cells
                .iter()
                .filter(|(l, _)| dir * (l - peak_nm) >= 0.0)
                .collect();
            side.sort_by(|a, b| (dir * a.0).total_cmp(&(dir * b.0)));
            let mut last = (peak_nm, peak);
            for &&(l, v) in side.iter().skip(1) {
                if v < half {
                    let t = (last.1 - half) / (last.1 - v);
                    return Some(last.0 + t * (l - last.0));
                }
                last = (l, v);
            }
            None
        };
        if let (Some(lo), Some(hi)) = (crossing(-1.0), crossing(1.0)) {
            below.push((c - lo).max(0.0));
            above.push((hi - c).max(0.0));
        }
    }
    let rows = below.len();
    if rows < MIN_ROWS_MEASURED {
        return (None, rows);
    }
    (
        Some((
            crate::numeric::median(&below),
            crate::numeric::median(&above),
        )),
        rows,
    )
}

/// Decides each line's band on `m` (widths set, measured, from the bandwidth or the
/// default); the cell counts are filled in by [`apply`]. Measure on the raw sample,
/// before a blank subtraction removes most of the scatter it would measure.
pub fn plan(m: &Measurement, options: &ScatterOptions) -> Vec<MaskedBand> {
    let shift = options.raman_shift_cm.unwrap_or(WATER_RAMAN_SHIFT_CM);
    let step = median_step(&m.emission_nm);
    let mut bands = Vec::new();
    for (k, line) in ScatterLine::ALL.into_iter().enumerate() {
        let (measured, rows) = measure_width(m, line, shift);
        let (mut below, mut above, source) = if let Some(w) = options.half_width_nm[k] {
            (w, w, WidthSource::Option)
        } else if let Some((lo, hi)) = measured {
            // A line whose peak sits off its predicted position measures one side near
            // zero; scatter profiles are near symmetric, so neither side is taken below
            // half the other.
            let (lo, hi) = (lo.max(0.5 * hi), hi.max(0.5 * lo));
            (
                HALF_MAX_TO_EDGE * lo,
                HALF_MAX_TO_EDGE * hi,
                WidthSource::Measured,
            )
        } else if let Some(b) = options.bandwidth_nm {
            let order = if matches!(line, ScatterLine::Rayleigh2 | ScatterLine::Raman2) {
                2.0
            } else {
                1.0
            };
            (2.0 * b * order, 2.0 * b * order, WidthSource::Bandwidth)
        } else {
            (
                DEFAULT_HALF_WIDTH_NM,
                DEFAULT_HALF_WIDTH_NM,
                WidthSource::Default,
            )
        };
        if source != WidthSource::Option {
            // Never narrower than the emission grid can resolve.
            below = below.max(step);
            above = above.max(step);
        }
        bands.push(MaskedBand {
            line,
            below_nm: below,
            above_nm: above,
            source,
            rows_measured: rows,
            cells: 0,
            signal_share: 0.0,
        });
    }
    bound(&mut bands, raman_edge_nm(m, shift));
    bands
}

/// The edge (nm, [`HALF_MAX_TO_EDGE`] half-widths) that water's Raman band adds to the
/// instrument's profile on the first-order Raman line of `m`'s longest excitation (the
/// band is constant in wavenumber, so it is widest in nm there): λ²·Γ/2 with Γ =
/// [`WATER_RAMAN_FWHM_CM`]. The line is taken no farther out than the emission grid.
pub fn raman_edge_nm(m: &Measurement, shift_cm: f64) -> f64 {
    let last_em = m.emission_nm.last().copied().unwrap_or(0.0);
    let longest = m
        .excitation_nm
        .iter()
        .filter_map(|&ex| ScatterLine::Raman1.centre_nm(ex, shift_cm))
        .map(|l| l.min(last_em))
        .fold(0.0, f64::max);
    HALF_MAX_TO_EDGE * longest * longest * 1e-7 * WATER_RAMAN_FWHM_CM / 2.0
}

/// Holds measured widths within physics, once first-order Rayleigh (the instrument's
/// profile) is measured; widths set or from `--bandwidth` are left alone. Per side, with
/// R1 the first-order Rayleigh edge and `raman_edge` the Raman band's own
/// ([`raman_edge_nm`]): first-order Raman within [R1, R1 + raman_edge], second-order
/// Rayleigh at least 2·R1, second-order Raman within [2·R1, 2·(R1 + raman_edge)]. A line
/// too faint to measure (its band defaulted) takes the upper bound (second-order
/// Rayleigh: 2·R1). A band that moved says [`WidthSource::Bounded`].
pub fn bound(bands: &mut [MaskedBand], raman_edge: f64) {
    let Some(first) = bands
        .iter()
        .find(|b| b.line == ScatterLine::Rayleigh1 && b.source == WidthSource::Measured)
    else {
        return;
    };
    let (r_below, r_above) = (first.below_nm, first.above_nm);
    for band in bands
        .iter_mut()
        .filter(|b| matches!(b.source, WidthSource::Measured | WidthSource::Default))
    {
        let (order, upper) = match band.line {
            ScatterLine::Rayleigh1 => continue,
            ScatterLine::Raman1 => (1.0, Some(raman_edge)),
            ScatterLine::Rayleigh2 => (2.0, None),
            ScatterLine::Raman2 => (2.0, Some(raman_edge)),
        };
        let clamp = |w: f64, r: f64| {
            let lo = order * r;
            let hi = upper.map_or(f64::INFINITY, |e| order * (r + e));
            w.clamp(lo, hi)
        };
        // A line too faint to measure gets the widest band its physics allows (the
        // default width knows nothing of the instrument).
        let (below, above) = if band.source == WidthSource::Default {
            let widest = |r: f64| order * (r + upper.unwrap_or(0.0));
            (widest(r_below), widest(r_above))
        } else {
            (clamp(band.below_nm, r_below), clamp(band.above_nm, r_above))
        };
        if below != band.below_nm || above != band.above_nm {
            band.below_nm = below;
            band.above_nm = above;
            band.source = WidthSource::Bounded;
        }
    }
}

/// Sets the cells of `bands` to missing in `m` and counts what each took away.
pub fn apply(m: &mut Measurement, bands: &mut [MaskedBand], raman_shift_cm: Option<f64>) {
    let shift = raman_shift_cm.unwrap_or(WATER_RAMAN_SHIFT_CM);
    let total: f64 = m
        .values
        .iter()
        .filter(|v| v.is_finite())
        .map(|v| v.abs())
        .sum();
    for band in bands.iter_mut() {
        let (mut cells, mut removed) = (0, 0.0);
        for i in 0..m.n_excitation() {
            for j in 0..m.n_emission() {
                if band.contains(m.excitation_nm[i], m.emission_nm[j], shift) {
                    let v = m.get_mut(i, j);
                    if v.is_finite() {
                        removed += v.abs();
                        cells += 1;
                        *v = f64::NAN;
                    }
                }
            }
        }
        band.cells = cells;
        band.signal_share = if total > 0.0 { removed / total } else { 0.0 };
    }
}

/// Plans the bands on `m` and masks them (see [`plan`] and [`apply`]).
pub fn mask(m: &mut Measurement, options: &ScatterOptions) -> Vec<MaskedBand> {
    let mut bands = plan(m, options);
    apply(m, &mut bands, options.raman_shift_cm);
    bands
}

pub use crate::numeric::median_step;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::Units;

    #[test]
    fn line_positions() {
        // Water Raman for 350 nm excitation lies near 397 nm (Lakowicz: 397–398 nm).
        let r = ScatterLine::Raman1.centre_nm(350.0, 3400.0).unwrap();
        assert!((r - 397.2).abs() < 0.5, "{r}");
        assert_eq!(ScatterLine::Rayleigh2.centre_nm(300.0, 3400.0), Some(600.0));
        assert!(ScatterLine::Raman1.centre_nm(5000.0, 3400.0).is_none());
    }

    /// A synthetic EEM with Gaussian Rayleigh lines of known width on a flat floor: the
    /// measured half-maximum distances come back.
    #[test]
    fn measured_width_of_a_known_line() {
        let ex: Vec<f64> = (0..20).map(|i| 250.0 + 5.0 * i as f64).collect();
        let em: Vec<f64> = (0..200).map(|i| 200.0 + 2.0 * i as f64).collect();
        let sigma: f64 = 4.0; // HWHM = 1.1774·σ = 4.71 nm
        let mut values = Vec::new();
        for &x in &ex {
            for &l in &em {
                values.push(10.0 + 1000.0 * (-(l - x).powi(2) / (2.0 * sigma * sigma)).exp());
            }
        }
        let mut m = Measurement::new("g", ex, em, values, Units::PerBin).unwrap();
        let (w, rows) = measure_width(&m, ScatterLine::Rayleigh1, 3400.0);
        let (lo, hi) = w.unwrap();
        assert!(rows >= 10);
        let hwhm = 1.1774 * sigma;
        assert!(
            (lo - hwhm).abs() < 0.5 && (hi - hwhm).abs() < 0.5,
            "{lo} {hi}"
        );
        let bands = mask(&mut m, &ScatterOptions::default());
        assert_eq!(bands[0].source, WidthSource::Measured);
        // Nothing above 2 % of the line is left within 3σ of it.
        for i in 0..m.n_excitation() {
            for j in 0..m.n_emission() {
                let d = (m.emission_nm[j] - m.excitation_nm[i]).abs();
                if d < 3.0 * sigma {
                    assert!(m.get(i, j).is_nan(), "cell {i},{j} left");
                }
            }
        }
    }
}
