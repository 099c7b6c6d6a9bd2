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

/// A row counts as free of fluorescence when the nearest [`QUIET_WINDOW`] cells beyond its
/// neighbours on each side of the diagonal each have an RMS within this many noise σ.
/// Each side on its own, and near the diagonal: one RMS over every cell beyond one step
/// let a row's noise cells dilute a tail of a few σ (a synthetic dye absorbing to 780 nm,
/// without crosstalk, then had +0.2 % "found" on each side); the Stokes side alone passed
/// rows whose below neighbour holds anti-Stokes fluorescence (which the model, and so the
/// synthesiser, writes wherever absorption and emission overlap: blue and red emitters
/// then had up to +0.3 % "found" below), and a whole side's RMS diluted that too.
const QUIET_ROW_RMS_FACTOR: f64 = 2.0;
/// Cells beyond a neighbour judged on each side (fewer where the row has fewer). Four
/// cells of noise alone pass with probability 0.997 (χ²₄ ≤ 16).
const QUIET_WINDOW: usize = 4;
/// A fraction is removed only when it is at least this many standard errors from zero…
const SIGNIFICANCE_FACTOR: f64 = 3.0;
/// …and its largest cell (the fraction times the largest diagonal) at least this many
/// noise σ: crosstalk no single cell shows above the noise is left as measured (the
/// cells are data, model.md §5; CIBA12's and HERPICER's 0.1–0.2 % stay).
const VISIBLE_FACTOR: f64 = 3.0;
/// Fewest quiet rows with both the diagonal and the neighbour measured for a side's
/// estimate (a side with fewer is not estimated).
const MIN_QUIET_ROWS: usize = 3;

/// The measured neighbours of each diagonal cell: (row, diagonal column, below column,
/// above column), the emission columns j ∓ 1 ([`Measurement::diagonal_neighbours`], as
/// the synthesiser writes crosstalk) where measured.
fn neighbours(m: &Measurement) -> Vec<(usize, usize, Option<usize>, Option<usize>)> {
    let measured = |i: usize, c: Option<usize>| c.filter(|&c| m.get(i, c).is_finite());
    m.diagonal_neighbours()
        .into_iter()
        .map(|(i, j, below, above)| (i, j, measured(i, below), measured(i, above)))
        .collect()
}

/// Whether row `i`, whose diagonal cell is in column `j`, holds no fluorescence above
/// `noise_sigma` near the diagonal ([`QUIET_ROW_RMS_FACTOR`]). "Beyond the neighbour" is
/// [`Measurement::cell_kind`]'s Stokes and anti-Stokes for a guard of the emission grid's
/// local spacing on that side, so the neighbour is the column next to the diagonal cell on
/// any pair of grids.
fn quiet(m: &Measurement, i: usize, j: usize, noise_sigma: f64) -> bool {
    let l = &m.emission_nm;
    // The emission grid's spacing above and below the diagonal cell (0 at its ends, where
    // that side has no cells).
    let above = l.get(j + 1).map_or(0.0, |a| a - l[j]);
    let below = j.checked_sub(1).map_or(0.0, |b| l[j] - l[b]);
    // Σ v² and count of the nearest QUIET_WINDOW cells on each side.
    let mut sides = [(0.0, 0usize); 2];
    let stokes = (j + 1..l.len()).map(|c| (c, CellKind::Stokes, 0, above));
    let anti_stokes = (0..j).rev().map(|c| (c, CellKind::AntiStokes, 1, below));
    for (c, kind, side, guard) in stokes.chain(anti_stokes) {
        if sides[side].1 < QUIET_WINDOW && m.cell_kind(i, c, guard) == kind {
            let v = m.get(i, c);
            sides[side].0 += v * v;
            sides[side].1 += 1;
        }
    }
    let within = |(sum, n): (f64, usize)| {
        n == 0 || (sum / n as f64).sqrt() <= QUIET_ROW_RMS_FACTOR * noise_sigma
    };
    // Each side is judged on the cells it has, up to QUIET_WINDOW. Rows at the grid's red
    // end have one or two Stokes cells, or none (then the anti-Stokes side judges alone):
    // POLGREE's 740–770 nm rows carry its crosstalk above (−4 to −7 %), and requiring
    // four Stokes cells there halved that side's estimate and moved its fit under A from
    // 0.47 to 0.55.
    sides[0].1 + sides[1].1 > 0 && within(sides[0]) && within(sides[1])
}

/// Estimates the crosstalk of `m` (noise level `noise_sigma` in the file's units), with
/// what it is worth in the measured colour under `lights`. `None` where there is nothing
/// to remove: without a diagonal, on an arbitrary scale, or when neither side is
/// significant and visible above the noise (a side measured in fewer than three rows free
/// of fluorescence counts as neither).
pub fn estimate(
    m: &Measurement,
    noise_sigma: f64,
    lights: &[Light],
) -> Option<CrosstalkCorrection> {
    if !m.has_diagonal || m.arbitrary_scale || !(noise_sigma.is_finite() && noise_sigma > 0.0) {
        return None;
    }
    let rows = neighbours(m);
    // Per nm, a column whose bin is not the grid's typical one (the trapezoid's half bins
    // at the grid's ends) holds the crosstalk's energy over another width: it would bias
    // one fraction per nm (by 7 % on a 10 nm grid once the red-end rows count as quiet).
    let widths = m.emission_bin_widths();
    let typical = crate::numeric::median_step(&m.emission_nm);
    let usable =
        |c: usize| m.units != Units::PerNm || (widths[c] - typical).abs() <= 0.01 * typical;
    // Per side: Σ v·d, Σ d² and the rows that gave them.
    let mut sums = [(0.0, 0.0, 0usize); 2];
    let mut quiet_rows = 0;
    for &(i, j, below, above) in &rows {
        let d = m.get(i, j);
        if !d.is_finite() || !quiet(m, i, j, noise_sigma) {
            continue;
        }
        let mut used = false;
        for (side, column) in [below, above].into_iter().enumerate() {
            if let Some(v) = column
                .filter(|&c| usable(c))
                .map(|c| m.get(i, c))
                .filter(|v| v.is_finite())
            {
                sums[side].0 += v * d;
                sums[side].1 += d * d;
                sums[side].2 += 1;
                used = true;
            }
        }
        quiet_rows += used as usize;
    }
    let largest_diagonal = rows
        .iter()
        .map(|&(i, j, _, _)| m.get(i, j))
        .filter(|d| d.is_finite())
        .fold(0.0, f64::max);
    // A side measured in too few quiet rows is not estimated: 0 ± 0.
    let fraction = |(vd, dd, n): (f64, f64, usize)| {
        if n < MIN_QUIET_ROWS || dd <= 0.0 {
            return (0.0, 0.0);
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
        units: m.units,
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

/// One line for the summary: what was found and what the fit did with it, in the file's
/// units (% of the diagonal, or % of the diagonal per nm for per-nm files).
pub fn describe(c: &CrosstalkCorrection) -> String {
    let worth = c
        .delta_e2000
        .iter()
        .map(|(l, de)| format!("{l} {de:.2}"))
        .collect::<Vec<_>>()
        .join(", ");
    // A side measured in too few quiet rows has fraction and error 0.
    // Per-nm cells are densities: their fraction of the (unitless) diagonal is per nm.
    let (per, digits) = match c.units {
        Units::PerBin => ("", 2),
        Units::PerNm => (" per nm", 3),
    };
    let side = |f: f64, error: f64, where_: &str| {
        if error > 0.0 {
            format!(
                "{:+.digits$} % of the diagonal{per} one step {where_} it (± {:.digits$} %{per})",
                100.0 * f,
                100.0 * error
            )
        } else {
            format!("not measured one step {where_} it (too few rows without fluorescence)")
        }
    };
    let found = format!(
        "{}, {} (from {} rows without fluorescence; worth ΔE2000 {worth} in the measured colour)",
        side(c.below, c.below_error, "below"),
        side(c.above, c.above_error, "above"),
        c.quiet_rows
    );
    if c.removed {
        let note = if c.note.is_empty() {
            String::new()
        } else {
            format!("; {}", c.note)
        };
        format!(
            "crosstalk removed before fitting: {found}; its net energy went back to the reflectance{note}"
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
    // A neighbour column the grid lacks (at its ends) counts with the typical bin.
    let typical = match m.units {
        Units::PerBin => 1.0,
        Units::PerNm => crate::numeric::median_step(&m.emission_nm),
    };
    for (i, j, below, above) in m.diagonal_neighbours() {
        let d = m.get(i, j);
        if !d.is_finite() {
            continue;
        }
        // The diagonal gets back the crosstalk's net, (below + above)·d, whether or not
        // its neighbours were measured: what the offset took from the reflected sample
        // does not depend on which cells the file holds. Giving back only what measured
        // neighbours gave put a whole side's f·d on the diagonal of every row with one
        // neighbour missing or off the grid (class case055, 1.5 % of cells missing:
        // 0.03 → 0.57 ΔE2000 from the truth).
        let mut returned = 0.0;
        for (column, fraction) in [(below, crosstalk.below), (above, crosstalk.above)] {
            if fraction == 0.0 {
                continue;
            }
            let moved = fraction * d;
            match column {
                Some(c) => {
                    let v = out.get_mut(i, c);
                    if v.is_finite() {
                        *v -= moved;
                    }
                    returned += moved * weight(c);
                }
                None => returned += moved * typical,
            }
        }
        *out.get_mut(i, j) += returned;
    }
    out
}

/// The crosstalk next to the diagonal as the search takes it: removed from the cells
/// wherever the grid fit found it. It is the instrument's offset, measured on rows
/// without fluorescence (to ±0.01–0.06 % of the diagonal on `fluorite class`); where the
/// grid fit kept the cells as measured, it did so because without the crosstalk its one
/// fluorophore moved to another emitter of two sharing the matrix, which the search's
/// models have the components for. The search starts from that grid fit but fits the
/// cleaned cells: on `fluorite class` the two-dye cases whose grid fit kept it were
/// fitted to the offset (seed 33 case126: 6.25 → 0.24 ΔE2000 from the truth), and the
/// default fit's p90 against the truth fell on 9 of 15 seeds and rose on 3 (docs/results.md).
pub(super) fn as_the_search_takes_it(
    grid: Option<&CrosstalkCorrection>,
) -> Option<CrosstalkCorrection> {
    grid.map(|c| {
        if c.removed {
            c.clone()
        } else {
            CrosstalkCorrection {
                removed: true,
                note: format!(
                    "the model search removed it; the grid fit it started from kept it ({})",
                    c.note
                ),
                ..c.clone()
            }
        }
    })
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
            // estimate's error times the diagonal.
            for (i, j, below, above) in neighbours(&m) {
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

    /// A dye absorbing up to the grid's end (680 ± 50 nm) and emitting at 740 nm, without
    /// crosstalk: in its red rows the Stokes tail stands a few σ above the noise, which
    /// the rows' anti-Stokes noise cells diluted below 2 σ RMS; those rows then passed as
    /// quiet and their fluorescent neighbours read as crosstalk (+0.21 % / +0.17 %).
    #[test]
    fn a_weak_stokes_tail_is_not_read_as_crosstalk() {
        use crate::synth::Band;
        let band = |centre_nm, width_nm| Band {
            centre_nm,
            width_nm,
            weight: 1.0,
        };
        let mut spec = SynthSpec::preset("green-dye").unwrap();
        spec.absorption = vec![band(680.0, 50.0)];
        spec.emission = vec![band(740.0, 15.0)];
        spec.concentration = 0.1;
        spec.reflectance_edge_nm = 450.0;
        spec.crosstalk = 0.0;
        spec.noise_sigma = 3e-4;
        for seed in 1..6 {
            spec.seed = seed;
            let (m, truth) = spec.generate().unwrap();
            // The premise, from the truth: in some row the Stokes cells beyond one step
            // hold fluorescence of 2.5 σ RMS (noise-free) where the row's cells beyond one
            // step on both sides hold less than 1.7 σ, so that with noise of σ their RMS
            // stays within the old rule's 2 σ (row 740 nm: 4.0 σ against 1.6 σ).
            let clean = crate::model::predict_like(&truth, &m);
            let rms = |i: usize, stokes_only: bool| {
                let l = m.excitation_nm[i];
                let cells: Vec<f64> = (0..m.n_emission())
                    .filter(|&j| {
                        let offset = m.emission_nm[j] - l;
                        offset > 10.0 + 1e-6 || (!stokes_only && offset < -10.0 - 1e-6)
                    })
                    .map(|j| clean.get(i, j))
                    .collect();
                (cells.iter().map(|v| v * v).sum::<f64>() / cells.len().max(1) as f64).sqrt()
            };
            let sigma = spec.noise_sigma;
            assert!(
                (0..m.n_excitation())
                    .any(|i| rms(i, true) > 2.5 * sigma && rms(i, false) < 1.7 * sigma),
                "no row with a weak Stokes tail"
            );
            assert_eq!(estimate(&m, sigma, &Light::standard()), None, "seed {seed}");
        }
    }

    /// Grids whose steps differ (5 nm excitation and 10 nm emission, and the reverse), and
    /// an emission grid whose step changes (10 nm, then 20 nm above 600 nm): the crosstalk
    /// the synthesiser writes next to each diagonal cell is found within 4 standard errors
    /// and taken out of exactly those cells. (The uneven grid carries the brightener: the
    /// red pigment's row at 600 nm holds fluorescence in its 20 nm neighbour above, 4 % of
    /// the crosstalk, that the four cells beyond it do not show above 2 σ.)
    #[test]
    fn crosstalk_is_found_on_grids_of_different_steps() {
        use crate::spectrum::uniform_grid;
        let fraction = 0.03;
        let mut uneven = uniform_grid(380.0, 600.0, 10.0);
        uneven.extend(uniform_grid(620.0, 780.0, 20.0));
        let (ten, five) = (
            uniform_grid(300.0, 780.0, 10.0),
            uniform_grid(300.0, 780.0, 5.0),
        );
        for (preset, excitation, emission) in [
            (
                "red-pigment",
                five.clone(),
                uniform_grid(380.0, 780.0, 10.0),
            ),
            ("red-pigment", ten.clone(), uniform_grid(380.0, 780.0, 5.0)),
            ("brightener", ten, uneven),
        ] {
            let mut spec = SynthSpec::preset(preset).unwrap();
            spec.excitation_nm = excitation;
            spec.emission_nm = emission;
            spec.crosstalk = fraction;
            spec.noise_sigma = 5e-4;
            let (m, truth) = spec.generate().unwrap();
            let grid = format!("{preset}, {} × {} cells", m.n_excitation(), m.n_emission());
            let c = estimate(&m, spec.noise_sigma, &Light::standard()).expect("visible crosstalk");
            for (got, error) in [(c.below, c.below_error), (-c.above, c.above_error)] {
                assert!(
                    error > 0.0 && (got - fraction).abs() <= 4.0 * error,
                    "{grid}: {got} against {fraction} (± {error})"
                );
            }
            let mut clean = spec.clone();
            clean.crosstalk = 0.0;
            let (without, _) = clean.generate().unwrap();
            let removed = remove(&m, &c);
            let allowed = 4.0 * (c.below_error + c.above_error);
            // The fraction is applied to the measured diagonal cell: its noise and the
            // fluorescence it holds beside the reflectance (which the synthesiser's
            // crosstalk leaves alone), times the fraction, move the cells too.
            for (i, j) in m.diagonal() {
                let d = m.get(i, j);
                let fluorescence = without.get(i, j) - truth.diagonal(m.excitation_nm[i]);
                let noise = fraction * (4.0 * spec.noise_sigma + fluorescence.abs());
                for column in 0..m.n_emission() {
                    let (got, want) = (removed.get(i, column), without.get(i, column));
                    if column != j {
                        assert!(
                            (got - want).abs() <= allowed * d + noise,
                            "{grid} ({i}, {column}): {got} against {want}"
                        );
                    }
                }
            }
        }
    }

    /// A per-nm file (the synthesiser's per-bin matrix with its off-diagonal cells divided
    /// by the 10 nm bin): the crosstalk is a tenth of the written fraction per nm, and the
    /// summary says so.
    #[test]
    fn per_nm_crosstalk_is_per_nm_and_says_so() {
        let fraction = 0.03;
        let mut spec = SynthSpec::preset("red-pigment").unwrap();
        spec.crosstalk = fraction;
        spec.noise_sigma = 5e-4;
        let (per_bin, _) = spec.generate().unwrap();
        let mut m = per_bin.clone();
        m.units = Units::PerNm;
        let diagonal = m.diagonal();
        let widths = m.emission_bin_widths();
        for i in 0..m.n_excitation() {
            for (j, w) in widths.iter().enumerate() {
                if !diagonal.contains(&(i, j)) {
                    *m.get_mut(i, j) /= w;
                }
            }
        }
        // The noise is per bin as written, so per nm a tenth of it.
        let c = estimate(&m, spec.noise_sigma / 10.0, &Light::standard()).expect("found");
        let want = fraction / 10.0;
        for (got, error) in [(c.below, c.below_error), (-c.above, c.above_error)] {
            assert!(
                (got - want).abs() <= 4.0 * error + 0.02 * want,
                "{got} against {want} (± {error})"
            );
        }
        let line = describe(&c);
        assert!(
            line.contains("% of the diagonal per nm one step below it"),
            "{line}"
        );
        assert!(
            line.contains(&format!("{:+.3} % of", 100.0 * c.below)),
            "{line}"
        );
        // Per bin the same crosstalk is the written fraction, without "per nm".
        let c = estimate(&per_bin, spec.noise_sigma, &Light::standard()).expect("found");
        let line = describe(&c);
        assert!(
            line.contains("% of the diagonal one step below it") && !line.contains("per nm"),
            "{line}"
        );
    }

    #[test]
    fn no_crosstalk_is_found_where_there_is_none() {
        let mut spec = SynthSpec::preset("red-pigment").unwrap();
        spec.crosstalk = 0.0;
        let (m, _) = spec.generate().unwrap();
        assert_eq!(estimate(&m, spec.noise_sigma, &Light::standard()), None);
    }
}
