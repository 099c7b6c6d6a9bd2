//! Whether a component's emission sits on a scatter line: the share of its emission
//! (∫e dλ = 1) that lies inside the scatter bands at its own excitation maximum.
//!
//! A component that holds leaked scatter carries emission where the scatter lines stand
//! at the excitation it absorbs most: first-order Rayleigh (λo = λi) or second-order
//! Rayleigh (λo = 2λi), the lines thousands of times brighter than the fluorescence.
//! Fluorescence lies on the Stokes side, clear of them; more than
//! [`MAX_RAYLEIGH_SHARE`] of a component's emission inside a Rayleigh band says it sits
//! on a scatter line. Water's Raman lines (λo = 1/(1/λi − ν̃) and twice that) lie in the
//! Stokes region where fluorescence belongs (phenylalanine at 255 nm excitation emits on
//! the 279 nm Raman line), and they are faint: their share is reported, not judged.
//!
//! The bands are the set's: per line, the widest band any sample was masked with
//! ([`set_bands`]).

use serde::{Deserialize, Serialize};

use crate::eem::scatter::{MaskedBand, ScatterLine, WATER_RAMAN_SHIFT_CM};
use crate::spectrum::bin_widths;

use super::JointComponent;

/// Share of a component's emission inside the Rayleigh bands at its excitation maximum
/// above which it is said to sit on a scatter line.
pub const MAX_RAYLEIGH_SHARE: f64 = 0.02;

/// One band at a component's excitation maximum and its share of the emission.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LineShare {
    /// The line.
    pub line: ScatterLine,
    /// The band's emission range at the excitation maximum (nm).
    pub from_nm: f64,
    /// Its upper end (nm).
    pub to_nm: f64,
    /// Share of ∫e dλ inside the band (0–1; 0 when the band lies off the grid).
    pub share: f64,
}

/// How much of a component's emission lies inside the scatter bands at its excitation
/// maximum.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScatterOverlap {
    /// The excitation maximum (nm) the bands are placed for.
    pub excitation_nm: f64,
    /// Every line's band and share, in [`ScatterLine::ALL`] order.
    pub lines: Vec<LineShare>,
    /// Share inside the first- and second-order Rayleigh bands together (a cell in both
    /// counts once).
    pub rayleigh_share: f64,
    /// Share inside the two Raman bands together.
    pub raman_share: f64,
    /// Whether `rayleigh_share` exceeds [`MAX_RAYLEIGH_SHARE`].
    pub on_scatter_line: bool,
}

/// The set's band per line: the widest below and the widest above any sample was masked
/// with (a line no sample masked is left out). `reports` holds each sample's bands.
pub fn set_bands<'a>(reports: impl IntoIterator<Item = &'a [MaskedBand]>) -> Vec<MaskedBand> {
    let mut out: Vec<MaskedBand> = Vec::new();
    for bands in reports {
        for band in bands {
            match out.iter_mut().find(|b| b.line == band.line) {
                Some(b) => {
                    b.below_nm = b.below_nm.max(band.below_nm);
                    b.above_nm = b.above_nm.max(band.above_nm);
                }
                None => out.push(band.clone()),
            }
        }
    }
    out.sort_by_key(|b| ScatterLine::ALL.iter().position(|l| *l == b.line));
    out
}

/// The share of `component`'s emission inside each of `bands` at its excitation maximum,
/// with the Raman shift `raman_shift_cm` (`None`: water's).
pub fn overlap(
    component: &JointComponent,
    bands: &[MaskedBand],
    raman_shift_cm: Option<f64>,
) -> ScatterOverlap {
    let shift = raman_shift_cm.unwrap_or(WATER_RAMAN_SHIFT_CM);
    let ex = component.peak_excitation_nm;
    let em = &component.emission.wavelength_nm;
    let e = &component.emission.value;
    let w = bin_widths(em);
    let total: f64 = e.iter().zip(&w).map(|(v, w)| v.max(0.0) * w).sum();
    let share_where = |inside: &dyn Fn(f64) -> bool| -> f64 {
        if total <= 0.0 {
            return 0.0;
        }
        e.iter()
            .zip(&w)
            .zip(em)
            .filter(|(_, l)| inside(**l))
            .map(|((v, w), _)| v.max(0.0) * w)
            .sum::<f64>()
            / total
    };
    let lines: Vec<LineShare> = bands
        .iter()
        .filter_map(|b| {
            let c = b.line.centre_nm(ex, shift)?;
            Some(LineShare {
                line: b.line,
                from_nm: c - b.below_nm,
                to_nm: c + b.above_nm,
                share: share_where(&|l| b.contains(ex, l, shift)),
            })
        })
        .collect();
    let in_any = |kinds: &[ScatterLine]| {
        share_where(&|l| {
            bands
                .iter()
                .filter(|b| kinds.contains(&b.line))
                .any(|b| b.contains(ex, l, shift))
        })
    };
    let rayleigh_share = in_any(&[ScatterLine::Rayleigh1, ScatterLine::Rayleigh2]);
    let raman_share = in_any(&[ScatterLine::Raman1, ScatterLine::Raman2]);
    ScatterOverlap {
        excitation_nm: ex,
        lines,
        rayleigh_share,
        raman_share,
        on_scatter_line: rayleigh_share > MAX_RAYLEIGH_SHARE,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eem::scatter::WidthSource;
    use crate::spectrum::Spectrum;

    fn band(line: ScatterLine, below: f64, above: f64) -> MaskedBand {
        MaskedBand {
            line,
            below_nm: below,
            above_nm: above,
            source: WidthSource::Option,
            rows_measured: 0,
            cells: 0,
            signal_share: 0.0,
        }
    }

    fn component(ex: f64, emission: impl Fn(f64) -> f64) -> JointComponent {
        let em: Vec<f64> = (0..=400).map(|i| 250.0 + i as f64).collect();
        let value: Vec<f64> = em.iter().map(|&l| emission(l)).collect();
        JointComponent {
            absorption: Spectrum {
                wavelength_nm: vec![ex],
                value: vec![1.0],
            },
            emission: Spectrum {
                wavelength_nm: em,
                value,
            },
            peak_excitation_nm: ex,
            peak_emission_nm: 0.0,
            share: 1.0,
            scatter: None,
            image_share: None,
        }
    }

    /// A flat emission over 250–650 nm (401 cells of 1 nm, the ends half-bins): a band of
    /// known width holds its width over 400 of it.
    #[test]
    fn shares_of_a_flat_emission_are_band_widths() {
        let c = component(280.0, |_| 1.0);
        let bands = vec![
            band(ScatterLine::Rayleigh1, 10.0, 10.0),
            band(ScatterLine::Rayleigh2, 20.0, 20.0),
        ];
        let o = overlap(&c, &bands, None);
        // 270–290: 21 full cells over a total of 400 nm.
        assert!((o.lines[0].share - 21.0 / 400.0).abs() < 1e-9, "{:?}", o);
        assert!((o.lines[1].share - 41.0 / 400.0).abs() < 1e-9, "{:?}", o);
        assert!((o.rayleigh_share - 62.0 / 400.0).abs() < 1e-9);
        assert!(o.on_scatter_line);
        assert_eq!((o.lines[1].from_nm, o.lines[1].to_nm), (540.0, 580.0));
    }

    /// Emission far on the Stokes side of both Rayleigh lines holds none of them.
    #[test]
    fn stokes_emission_is_off_the_lines() {
        let c = component(280.0, |l| (-(l - 360.0).powi(2) / 200.0).exp());
        let bands = set_bands([
            &[band(ScatterLine::Rayleigh1, 5.0, 10.0)][..],
            &[band(ScatterLine::Rayleigh1, 8.0, 6.0)][..],
        ]);
        assert_eq!((bands[0].below_nm, bands[0].above_nm), (8.0, 10.0));
        let o = overlap(&c, &bands, None);
        assert!(o.rayleigh_share < 1e-9 && !o.on_scatter_line, "{o:?}");
    }
}
