//! Crosstalk next to the diagonal: estimated from the rows that hold no fluorescence, and
//! removed before a fit.
//!
//! A slight wavelength offset between the two monochromators, or a bandpass wider than the
//! step, moves a share of each reflected sample into the cells one step off the diagonal
//! (model.md §5: POLGREE +4.2 %/−4.3 %, TEXTYELL +4.7 %/−3.4 % of the diagonal, one step
//! below / above). It is the instrument's, not the material's: a fit that keeps it reads it
//! as fluorescence of a small Stokes shift (above the diagonal) and bends a(λ) and e(λ)
//! towards it. In rows without fluorescence those cells hold only the crosstalk and noise,
//! so there it is measured: one fraction of the diagonal per side, by least squares. Where
//! it is significant it is subtracted from every row's neighbours and its net energy given
//! back to the diagonal (the reflectance it came from).

use crate::colour::{Light, PatchColorimeter, delta_e2000};
use crate::material::CrosstalkCorrection;
use crate::measurement::{CellKind, Measurement, Units};

/// A row counts as free of fluorescence when its cells beyond the first step off the
/// diagonal have an RMS within this many noise σ.
const QUIET_ROW_RMS_FACTOR: f64 = 2.0;
/// A fraction is removed only when it is at least this many standard errors from zero…
const SIGNIFICANCE_FACTOR: f64 = 3.0;
/// …and its largest cell (the fraction times the largest diagonal) at least this many
/// noise σ: crosstalk no single cell shows above the noise is left as measured (the
/// cells are data, model.md §5; CIBA12's and HERPICER's 0.1–0.2 % stay).
const VISIBLE_FACTOR: f64 = 3.0;
/// Fewest quiet rows with both the diagonal and the neighbour measured for an estimate.
const MIN_QUIET_ROWS: usize = 3;

/// The neighbours of a diagonal cell: (row, diagonal column, below column, above column),
/// a neighbour where the cell one step off the diagonal is measured
/// ([`CellKind::Guard`] for a guard of `step`: the classification the fit's cells use).
fn neighbours(m: &Measurement, step: f64) -> Vec<(usize, usize, Option<usize>, Option<usize>)> {
    let near = |i: usize, j: usize| m.cell_kind(i, j, step) == CellKind::Guard;
    m.diagonal()
        .into_iter()
        .map(|(i, j)| {
            let below = j.checked_sub(1).filter(|&b| near(i, b));
            let above = Some(j + 1).filter(|&a| a < m.n_emission() && near(i, a));
            (i, j, below, above)
        })
        .collect()
}

/// Estimates the crosstalk of `m` (noise level `noise_sigma` in the file's units), with
/// what it is worth in the measured colour under `lights`. `None` where there is nothing
/// to remove: without a diagonal, on an arbitrary scale, with fewer than
/// three rows free of fluorescence to measure it in, or when neither side is
/// significant and visible above the noise.
pub fn estimate(
    m: &Measurement,
    noise_sigma: f64,
    lights: &[Light],
) -> Option<CrosstalkCorrection> {
    if !m.has_diagonal || m.arbitrary_scale || !(noise_sigma.is_finite() && noise_sigma > 0.0) {
        return None;
    }
    let step = m.default_guard_nm();
    let rows = neighbours(m, step);
    let quiet = |i: usize| {
        let (mut sum, mut n) = (0.0, 0usize);
        for j in 0..m.n_emission() {
            if matches!(
                m.cell_kind(i, j, step),
                CellKind::Stokes | CellKind::AntiStokes
            ) {
                let v = m.get(i, j);
                sum += v * v;
                n += 1;
            }
        }
        n >= MIN_QUIET_ROWS && (sum / n as f64).sqrt() <= QUIET_ROW_RMS_FACTOR * noise_sigma
    };
    let mut sums = [(0.0, 0.0); 2];
    let mut quiet_rows = 0;
    for &(i, j, below, above) in &rows {
        let d = m.get(i, j);
        if !d.is_finite() || !quiet(i) {
            continue;
        }
        let mut used = false;
        for (side, column) in [below, above].into_iter().enumerate() {
            if let Some(v) = column.map(|c| m.get(i, c)).filter(|v| v.is_finite()) {
                sums[side].0 += v * d;
                sums[side].1 += d * d;
                used = true;
            }
        }
        quiet_rows += used as usize;
    }
    if quiet_rows < MIN_QUIET_ROWS {
        return None;
    }
    let largest_diagonal = rows
        .iter()
        .map(|&(i, j, _, _)| m.get(i, j))
        .filter(|d| d.is_finite())
        .fold(0.0, f64::max);
    let fraction = |(vd, dd): (f64, f64)| {
        if dd <= 0.0 {
            return (0.0, f64::INFINITY);
        }
        let error = noise_sigma / dd.sqrt();
        let f = vd / dd;
        let kept = f.abs() >= SIGNIFICANCE_FACTOR * error
            && f.abs() * largest_diagonal >= VISIBLE_FACTOR * noise_sigma;
        (if kept { f } else { 0.0 }, error)
    };
    let (below, below_error) = fraction(sums[0]);
    let (above, above_error) = fraction(sums[1]);
    if below == 0.0 && above == 0.0 {
        return None;
    }
    let mut correction = CrosstalkCorrection {
        below,
        above,
        below_error,
        above_error,
        quiet_rows,
        removed: true,
        ..CrosstalkCorrection::default()
    };
    let (raw, clean) = (m.to_per_bin(), remove(m, &correction).to_per_bin());
    correction.delta_e2000 = lights
        .iter()
        .map(|light| {
            let pc = PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm);
            (
                light.name.clone(),
                delta_e2000(pc.lab(&raw), pc.lab(&clean)),
            )
        })
        .collect();
    Some(correction)
}

/// One line for the summary: what was found and what the fit did with it.
pub fn describe(c: &CrosstalkCorrection) -> String {
    let worth = c
        .delta_e2000
        .iter()
        .map(|(l, de)| format!("{l} {de:.2}"))
        .collect::<Vec<_>>()
        .join(", ");
    let found = format!(
        "{:+.2} % of the diagonal one step below it, {:+.2} % one step above (± {:.2} / {:.2} %, from {} rows without fluorescence; worth ΔE2000 {worth} in the measured colour)",
        100.0 * c.below,
        100.0 * c.above,
        100.0 * c.below_error,
        100.0 * c.above_error,
        c.quiet_rows
    );
    if c.removed {
        format!(
            "crosstalk removed before fitting: {found}; its net energy went back to the reflectance"
        )
    } else {
        format!("crosstalk kept as measured: {found}; {}", c.note)
    }
}

/// `m` with `crosstalk` taken out of the cells next to the diagonal and its net energy
/// given back to the diagonal cell of the same row.
pub fn remove(m: &Measurement, crosstalk: &CrosstalkCorrection) -> Measurement {
    let mut out = m.clone();
    let widths = m.emission_bin_widths();
    // Energy per cell: values are per bin, or per nm (× the bin width).
    let weight = |j: usize| match m.units {
        Units::PerBin => 1.0,
        Units::PerNm => widths[j],
    };
    for (i, j, below, above) in neighbours(m, m.default_guard_nm()) {
        let d = m.get(i, j);
        if !d.is_finite() {
            continue;
        }
        let mut returned = 0.0;
        for (column, fraction) in [(below, crosstalk.below), (above, crosstalk.above)] {
            if let Some(c) = column.filter(|_| fraction != 0.0) {
                let moved = fraction * d;
                let v = out.get_mut(i, c);
                // Energy goes back only where it was taken out (a missing neighbour gave none).
                if v.is_finite() {
                    *v -= moved;
                    returned += moved * weight(c);
                }
            }
        }
        *out.get_mut(i, j) += returned;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::SynthSpec;

    #[test]
    fn the_synthesisers_crosstalk_is_found_and_removed() {
        for (preset, fraction) in [("red-pigment", 0.03), ("brightener", 0.01)] {
            let mut spec = SynthSpec::preset(preset).unwrap();
            spec.crosstalk = fraction;
            spec.noise_sigma = 5e-4;
            let (m, _) = spec.generate().unwrap();
            let c = estimate(&m, spec.noise_sigma, &Light::standard()).expect("visible crosstalk");
            // The synthesiser puts +f below and −f above the diagonal.
            for (got, error) in [(c.below, c.below_error), (-c.above, c.above_error)] {
                assert!(
                    (got - fraction).abs() <= 4.0 * error + 0.02 * fraction,
                    "{preset}: {got} against {fraction} (± {error})"
                );
            }
            let mut clean = spec.clone();
            clean.crosstalk = 0.0;
            let (without, _) = clean.generate().unwrap();
            let removed = remove(&m, &c);
            // Every neighbour of a measured diagonal cell is as without crosstalk, to the
            // estimate's error times the diagonal (rows without a diagonal cell, such as
            // 370 nm on a grid whose emission starts at 380 nm, have nothing to scale).
            for (i, j, below, above) in neighbours(&m, m.default_guard_nm()) {
                let d = m.get(i, j);
                for column in [below, above].into_iter().flatten() {
                    let (got, want) = (removed.get(i, column), without.get(i, column));
                    if d.is_finite() && got.is_finite() {
                        let allowed = 4.0 * (c.below_error + c.above_error + 0.02 * fraction) * d;
                        assert!(
                            (got - want).abs() <= allowed + 1e-12,
                            "{preset} ({i}, {column}): {got} against {want}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn no_crosstalk_is_found_where_there_is_none() {
        let mut spec = SynthSpec::preset("red-pigment").unwrap();
        spec.crosstalk = 0.0;
        let (m, _) = spec.generate().unwrap();
        assert_eq!(estimate(&m, spec.noise_sigma, &Light::standard()), None);
    }
}
