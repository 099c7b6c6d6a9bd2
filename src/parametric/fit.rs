//! Least-squares fits of forms to sampled spectra.
//!
//! [`fit_bands`] fits a sum of Gaussian bands to a sampled absorption or emission curve;
//! [`fit_sigmoid_polynomial`] fits a sigmoid of a Legendre series to a reflectance. Both
//! start deterministically (greedy band placement, or a linear fit of the logit) and
//! refine with a small Levenberg–Marquardt solver on the analytic Jacobian: the fits also
//! seed the matrix fit, whose whole model search has a budget of tens of milliseconds.

use std::ops::RangeInclusive;

pub use super::sigmoid_fit::{SigmoidFit, fit_sigmoid_polynomial};
use super::{BandDomain, BandTerms, GaussianBands, PARAMS_PER_BAND, check_samples};
use crate::error::{Error, Result};

use super::lm::{LeastSquares, SEED_STOPPING, STOPPING, levenberg_marquardt};

/// The band domain fits use unless told otherwise: wavenumber, because real dyes need
/// fewer bands in it.
///
/// Measured on the excitation and emission curves of fluorescein (0.1 M NaOH), rhodamine
/// 6G (ethanol) and quinine sulfate (0.5 M H₂SO₄), each over its measured range, as the
/// fewest bands whose RMS error is at most 1 % of the peak: 23 bands for the six curves
/// in wavenumber against 26 in wavelength (16 against 18 at 2 %). Emission decides it
/// (2, 3, 3 bands in wavenumber against 3, 4, 4), consistent with electronic bands being
/// broadened in energy; excitation needs the same counts in both (3, 6, 6). Reproduce with
/// `fluorite bands ../shared/data/spectra/*.csv` (`--tolerance 0.02` for 2 %); the test
/// `dye_spectra_need_the_measured_band_counts` in `tests/suite/parametric.rs` holds the counts.
pub const DEFAULT_BAND_DOMAIN: BandDomain = BandDomain::Wavenumber;

/// A sum of Gaussian bands fitted to samples, with how well it fits.
#[derive(Debug, Clone, PartialEq)]
pub struct BandFit {
    /// The bands, sorted by centre wavelength, at the scale of the data; their support is
    /// [first, last] sample wavelength.
    pub bands: GaussianBands,
    /// Root mean square of fit − data over the samples (the data's unit).
    pub rms: f64,
    /// `rms` divided by the data's peak (largest value).
    pub rel_rms: f64,
    /// The largest |fit − data| over the samples, divided by the data's peak.
    pub max_rel_error: f64,
}

/// Fits exactly `n_bands` Gaussian bands in `domain` to `values` sampled at `nm`
/// (strictly increasing wavelengths), by least squares on the samples.
///
/// The values may have any positive scale, negative noise and zero tails; the bands'
/// support is [first, last] of `nm`. The start is deterministic: bands are added one at a
/// time at the largest remaining residual (width from its half maximum, heights by
/// non-negative least squares), each addition refined by Levenberg–Marquardt over all
/// bands. Fails when the samples are unusable (empty, mismatched, unsorted, non-finite),
/// when there are fewer than three samples per band, or when no value is positive.
pub fn fit_bands(
    nm: &[f64],
    values: &[f64],
    domain: BandDomain,
    n_bands: usize,
) -> Result<BandFit> {
    // Grown without polishing the smaller counts, which only a search needs.
    BandGrowth::new(nm, values, domain).fit(n_bands)
}

/// Fits 1, 2, … up to `max_bands` bands (as [`fit_bands`] does) and stops at the first
/// fit whose [`BandFit::rel_rms`] is at most `tolerance_rel_rms` (positive; see
/// [`check_band_search`]).
///
/// Returns every fit tried, in order of band count; the last is the chosen one. When no
/// count meets the tolerance the last is the `max_bands` fit, so check its `rel_rms`.
/// Each fit starts from the previous one, so the whole search costs about as much as the
/// last fit alone; `fit_bands(…, n)` returns the same bands as the n-th fit here.
pub fn fit_bands_to_tolerance(
    nm: &[f64],
    values: &[f64],
    domain: BandDomain,
    max_bands: usize,
    tolerance_rel_rms: f64,
) -> Result<Vec<BandFit>> {
    check_band_search(max_bands, tolerance_rel_rms)?;
    grow_bands(nm, values, domain, max_bands, "max_bands", |fit| {
        fit.rel_rms <= tolerance_rel_rms
    })
}

/// Refuses a band search [`fit_bands_to_tolerance`] cannot run: no band allowed
/// (`max_bands` 0) or a tolerance that is not a positive fraction of the peak (0 asks for
/// an exact fit, which no count reaches in floating point; to get every count up to
/// `max_bands`, give a tolerance far below the data's noise). Errors name the parameters
/// `max_bands` and `tolerance_rel_rms`.
pub fn check_band_search(max_bands: usize, tolerance_rel_rms: f64) -> Result<()> {
    if max_bands == 0 {
        return Err(Error::invalid("max_bands", "is 0; allow at least one band"));
    }
    if !(tolerance_rel_rms.is_finite() && tolerance_rel_rms > 0.0) {
        return Err(Error::invalid(
            "tolerance_rel_rms",
            format!("is {tolerance_rel_rms}; give a positive fraction of the peak, such as 0.01"),
        ));
    }
    Ok(())
}

/// The indices from the first to the last positive value (`None` when none is positive):
/// the measured range of a curve stored with zeros outside it.
pub fn positive_range(values: &[f64]) -> Option<RangeInclusive<usize>> {
    let first = values.iter().position(|&v| v > 0.0)?;
    let last = values.iter().rposition(|&v| v > 0.0)?;
    Some(first..=last)
}

/// Adds bands one at a time up to `max_bands`, refining after each addition, and returns
/// every fit until `done` accepts one. `bands_parameter` names `max_bands` in errors.
fn grow_bands(
    nm: &[f64],
    values: &[f64],
    domain: BandDomain,
    max_bands: usize,
    bands_parameter: &str,
    mut done: impl FnMut(&BandFit) -> bool,
) -> Result<Vec<BandFit>> {
    let problem = band_problem(nm, values, domain, max_bands, bands_parameter)?;
    let mut params = Vec::with_capacity(max_bands * PARAMS_PER_BAND);
    let mut fits = Vec::new();
    for _ in 0..max_bands {
        params = add_band(&problem, &params)?;
        let fit = polish(&problem, &params)?;
        let accepted = done(&fit);
        fits.push(fit);
        if accepted {
            break;
        }
    }
    Ok(fits)
}

/// The band problem of `values` on `nm`, once the samples are checked for `max_bands`
/// bands (`bands_parameter` names that count in errors).
fn band_problem(
    nm: &[f64],
    values: &[f64],
    domain: BandDomain,
    max_bands: usize,
    bands_parameter: &str,
) -> Result<BandProblem> {
    let min_samples = max_bands.saturating_mul(PARAMS_PER_BAND);
    if nm.len() == values.len() && nm.len() < min_samples {
        return Err(Error::invalid(
            bands_parameter,
            format!(
                "is {max_bands}, which needs at least {min_samples} samples (three per band), but there are {}; fit fewer bands or give more samples",
                nm.len()
            ),
        ));
    }
    check_samples(nm, values, min_samples)?;
    let peak = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if peak <= 0.0 {
        return Err(Error::invalid(
            "values",
            format!(
                "peak at {peak}; a band fit needs at least one positive value (is this the right column?)"
            ),
        ));
    }
    BandProblem::new(nm, values, domain, peak)
}

/// The seed of one more band: each candidate placed beside the loosely converged bands
/// `params` and refined with them; the best wins (the first on ties, so the result is
/// deterministic).
fn add_band(problem: &BandProblem, params: &[f64]) -> Result<Vec<f64>> {
    let mut best: Option<(f64, Vec<f64>)> = None;
    for band in problem.candidate_bands(params, CANDIDATES) {
        let mut trial = params.to_vec();
        trial.extend_from_slice(&band);
        problem.set_heights(&mut trial);
        problem.project(&mut trial);
        let cost = levenberg_marquardt(problem, &mut trial, SEED_STOPPING);
        if best.as_ref().is_none_or(|(c, _)| cost < *c) {
            best = Some((cost, trial));
        }
    }
    best.map(|(_, seed)| seed)
        .ok_or_else(|| Error::Fit("no starting band could be placed".into()))
}

/// The fit polished from `seed`. The next count grows from the loosely converged seed,
/// not from this, so `fit_bands(…, n)` equals the n-th fit of any search.
fn polish(problem: &BandProblem, seed: &[f64]) -> Result<BandFit> {
    let mut polished = seed.to_vec();
    levenberg_marquardt(problem, &mut polished, STOPPING);
    problem.result(&polished)
}

/// Band fits of one sampled curve at several band counts, sharing their growth: the
/// seeds of 1, 2, … bands are kept, so the fit of n bands after that of m < n adds n − m
/// bands instead of growing all n again (a model search asks for the same spectra with
/// 1, 2 and 3 bands). [`fit_bands`] is one growth's fit.
pub struct BandGrowth {
    nm: Vec<f64>,
    values: Vec<f64>,
    domain: BandDomain,
    /// The problem, once built (it depends on the samples alone).
    problem: Option<BandProblem>,
    /// The seed of 1, 2, … bands, as far as grown.
    seeds: Vec<Vec<f64>>,
}

impl BandGrowth {
    /// The growth of `values` sampled at `nm` on `domain`, no band placed yet.
    pub fn new(nm: &[f64], values: &[f64], domain: BandDomain) -> Self {
        BandGrowth {
            nm: nm.to_vec(),
            values: values.to_vec(),
            domain,
            problem: None,
            seeds: Vec::new(),
        }
    }

    /// `n_bands` bands: the n-th fit of [`fit_bands_to_tolerance`]'s growth, each seed
    /// grown once however many counts are asked for.
    pub fn fit(&mut self, n_bands: usize) -> Result<BandFit> {
        if n_bands == 0 {
            return Err(Error::invalid(
                "n_bands",
                "is 0; a band fit needs at least one band",
            ));
        }
        // Checked for this count every time: the sample count an error names depends on it.
        let checked = band_problem(&self.nm, &self.values, self.domain, n_bands, "n_bands")?;
        let problem = self.problem.get_or_insert(checked);
        while self.seeds.len() < n_bands {
            let last = self.seeds.last().map(Vec::as_slice).unwrap_or(&[]);
            let seed = add_band(problem, last)?;
            self.seeds.push(seed);
        }
        polish(problem, &self.seeds[n_bands - 1])
    }
}

/// Residual peaks tried as the start of each added band. One: on the three dye files of
/// `fluorite bands`, trying the 2, 3 or 5 largest peaks changed no band count at the
/// 1 % tolerance but one (fluorescein excitation in wavelength, 6 → 5) and cost 2–5×
/// the time, which the matrix fit's budget cannot spare.
const CANDIDATES: usize = 1;

/// A band fit in solver coordinates, on data divided by its peak.
struct BandProblem {
    domain: BandDomain,
    support_nm: [f64; 2],
    peak: f64,
    /// Solver coordinate of each sample.
    u: Vec<f64>,
    /// Values divided by the peak.
    y: Vec<f64>,
    /// Bounds of (ln height, centre, ln width) that keep the solver in a sensible range.
    lower: [f64; PARAMS_PER_BAND],
    upper: [f64; PARAMS_PER_BAND],
}

/// √(8 ln 2): the full width at half maximum of a Gaussian in standard deviations.
const FWHM_PER_SIGMA: f64 = 2.354_820_045_030_949;

impl BandProblem {
    fn new(nm: &[f64], values: &[f64], domain: BandDomain, peak: f64) -> Result<Self> {
        let u: Vec<f64> = nm.iter().map(|&l| domain.coordinate(l)).collect();
        let y: Vec<f64> = values.iter().map(|v| v / peak).collect();
        let (lo, hi) = u
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        let span = hi - lo;
        let finest = u
            .windows(2)
            .map(|w| (w[1] - w[0]).abs())
            .fold(f64::INFINITY, f64::min);
        let usable = y.iter().all(|v| v.is_finite())
            && span.is_finite()
            && finest.is_finite()
            && finest > 0.0
            && lo.is_finite();
        if !usable {
            return Err(Error::invalid(
                "nm/values",
                "span too many orders of magnitude for a band fit; give wavelengths in nm and values on a common scale",
            ));
        }
        Ok(BandProblem {
            domain,
            support_nm: [nm[0], nm[nm.len() - 1]],
            peak,
            u,
            y,
            // Heights from a millionth to a thousand times the peak; centres within one
            // span of the samples but at a positive coordinate (a positive wavelength);
            // widths from half the finest sample spacing (narrower bands fall between
            // samples) to four spans (a nearly flat baseline).
            lower: [
                (1e-6f64).ln(),
                (lo - span).max(0.5 * lo),
                (0.5 * finest).ln(),
            ],
            upper: [(1e3f64).ln(), hi + span, (4.0 * span).ln()],
        })
    }

    /// Up to `count` starting bands (ln height, centre, ln width) for the residual of
    /// `params`, one per distinct residual peak, largest first: each sits at the peak,
    /// as high as the residual there and as wide as its half maximum. The samples within
    /// a candidate's half maximum are not searched again, so candidates are distinct peaks
    /// rather than noise on one.
    fn candidate_bands(&self, params: &[f64], count: usize) -> Vec<[f64; PARAMS_PER_BAND]> {
        let (terms, mut scratch) = (BandTerms::new(params), vec![0.0; params.len()]);
        let residual: Vec<f64> = self
            .u
            .iter()
            .zip(&self.y)
            .map(|(&u, &y)| y - terms.value_gradient(u, &mut scratch))
            .collect();
        let mut searched = vec![false; residual.len()];
        let mut candidates = Vec::with_capacity(count);
        while candidates.len() < count {
            let Some(k) = (0..residual.len())
                .filter(|&i| !searched[i])
                .max_by(|&a, &b| residual[a].total_cmp(&residual[b]).then(b.cmp(&a)))
            else {
                break;
            };
            // A later candidate must be a real peak; the first is taken even when the
            // fit is already exact everywhere (the caller asked for that many bands).
            if !candidates.is_empty() && residual[k] <= 0.0 {
                break;
            }
            let half = 0.5 * residual[k];
            // The half-maximum crossing walking by `step` from k: its coordinate offset
            // and the last sample above half, or None when the samples end first.
            let crossing = |step: isize| -> (Option<f64>, usize) {
                let mut i = k;
                loop {
                    let Some(j) = i.checked_add_signed(step).filter(|&j| j < residual.len()) else {
                        return (None, i);
                    };
                    if residual[j] <= half {
                        let t = (residual[i] - half) / (residual[i] - residual[j]);
                        let at = self.u[i] + t * (self.u[j] - self.u[i]);
                        return (Some((at - self.u[k]).abs()), i);
                    }
                    i = j;
                }
            };
            let ((left, first), (right, last)) = (crossing(-1), crossing(1));
            searched[first..=last].fill(true);
            let fwhm = match (left, right) {
                (Some(a), Some(b)) => a + b,
                (Some(a), None) | (None, Some(a)) => 2.0 * a,
                // Above half everywhere: a band as wide as the samples' span.
                (None, None) => self.upper[2].exp() / 4.0,
            };
            let ln_width = (fwhm / FWHM_PER_SIGMA)
                .ln()
                .clamp(self.lower[2], self.upper[2]);
            candidates.push([residual[k].max(1e-3).ln(), self.u[k], ln_width]);
        }
        candidates
    }

    /// Replaces the heights by the non-negative least-squares heights for the current
    /// centres and widths: coordinate descent on the normal equations, which is cheap for
    /// the handful of bands a spectrum has; the refinement that follows polishes what 100
    /// sweeps leave.
    fn set_heights(&self, params: &mut [f64]) {
        let n = params.len() / PARAMS_PER_BAND;
        let shape = |b: usize, u: f64| {
            let p = &params[b * PARAMS_PER_BAND..(b + 1) * PARAMS_PER_BAND];
            let z = (u - p[1]) / p[2].exp();
            (-0.5 * z * z).exp()
        };
        let mut gram = vec![0.0; n * n];
        let mut rhs = vec![0.0; n];
        let mut row = vec![0.0; n];
        for (&u, &y) in self.u.iter().zip(&self.y) {
            for (b, r) in row.iter_mut().enumerate() {
                *r = shape(b, u);
            }
            for a in 0..n {
                rhs[a] += row[a] * y;
                for b in 0..n {
                    gram[a * n + b] += row[a] * row[b];
                }
            }
        }
        let mut heights: Vec<f64> = (0..n).map(|b| params[b * PARAMS_PER_BAND].exp()).collect();
        for _ in 0..100 {
            let mut change: f64 = 0.0;
            for a in 0..n {
                let diagonal = gram[a * n + a];
                if diagonal <= 0.0 {
                    continue;
                }
                let fitted: f64 = (0..n).map(|b| gram[a * n + b] * heights[b]).sum();
                let next = (heights[a] + (rhs[a] - fitted) / diagonal).max(0.0);
                change = change.max((next - heights[a]).abs());
                heights[a] = next;
            }
            if change <= 1e-12 {
                break;
            }
        }
        for (b, h) in heights.iter().enumerate() {
            // The floor keeps ln height finite; the refinement can still drop the band.
            params[b * PARAMS_PER_BAND] = h.max(1e-6).ln();
        }
    }

    /// The fit for `params`, at the data's scale.
    fn result(&self, params: &[f64]) -> Result<BandFit> {
        if params.iter().any(|p| !p.is_finite()) {
            return Err(Error::Fit(
                "the band fit diverged (non-finite parameters); check that the values are a spectrum sampled in nm"
                    .into(),
            ));
        }
        let (terms, mut scratch) = (BandTerms::new(params), vec![0.0; params.len()]);
        let (mut sum_sq, mut max_abs) = (0.0f64, 0.0f64);
        for (&u, &y) in self.u.iter().zip(&self.y) {
            let r = terms.value_gradient(u, &mut scratch) - y;
            sum_sq += r * r;
            max_abs = max_abs.max(r.abs());
        }
        let rel_rms = (sum_sq / self.u.len() as f64).sqrt();
        let mut bands = GaussianBands::from_params(self.domain, self.support_nm, params);
        bands.scale(self.peak);
        let finite = |v: f64| v.is_finite() && v > 0.0;
        let usable = bands
            .bands
            .iter()
            .all(|b| finite(b.centre_nm) && finite(b.width) && b.height.is_finite())
            && rel_rms.is_finite()
            && max_abs.is_finite();
        if !usable {
            return Err(Error::Fit(
                "the fitted bands do not fit in floating point; give wavelengths in nm and values on a moderate scale"
                    .into(),
            ));
        }
        bands
            .bands
            .sort_by(|a, b| a.centre_nm.total_cmp(&b.centre_nm));
        Ok(BandFit {
            bands,
            rms: rel_rms * self.peak,
            rel_rms,
            max_rel_error: max_abs,
        })
    }
}

impl LeastSquares for BandProblem {
    fn residual_count(&self) -> usize {
        self.u.len()
    }

    /// The same values and derivatives as [`BandTerms::value_gradient`], band by band so that
    /// each sample costs one exponential per band.
    fn evaluate(&self, params: &[f64], residuals: &mut [f64], mut jacobian: Option<&mut [f64]>) {
        let m = self.u.len();
        for (r, &y) in residuals.iter_mut().zip(&self.y) {
            *r = -y;
        }
        for (b, p) in params.chunks_exact(PARAMS_PER_BAND).enumerate() {
            let (height, centre, inverse_width) = (p[0].exp(), p[1], (-p[2]).exp());
            let band = |u: f64| {
                let z = (u - centre) * inverse_width;
                (z, height * (-0.5 * z * z).exp())
            };
            let Some(jacobian) = jacobian.as_deref_mut() else {
                for (&u, r) in self.u.iter().zip(residuals.iter_mut()) {
                    *r += band(u).1;
                }
                continue;
            };
            let columns = &mut jacobian[b * PARAMS_PER_BAND * m..(b + 1) * PARAMS_PER_BAND * m];
            let (by_height, rest) = columns.split_at_mut(m);
            let (by_centre, by_width) = rest.split_at_mut(m);
            for (i, (&u, r)) in self.u.iter().zip(residuals.iter_mut()).enumerate() {
                let (z, v) = band(u);
                *r += v;
                by_height[i] = v;
                by_centre[i] = v * z * inverse_width;
                by_width[i] = v * z * z;
            }
        }
    }

    fn bounds(&self, j: usize) -> (f64, f64) {
        let k = j % PARAMS_PER_BAND;
        (self.lower[k], self.upper[k])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parametric::GaussianBand;

    fn grid(lo: f64, hi: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
            .collect()
    }

    fn assert_same_bands(found: &GaussianBands, truth: &GaussianBands, tolerance: f64) {
        assert_eq!(found.bands.len(), truth.bands.len(), "{found:?}");
        for (f, t) in found.bands.iter().zip(&truth.bands) {
            for (a, b) in [
                (f.centre_nm, t.centre_nm),
                (f.width, t.width),
                (f.height, t.height),
            ] {
                assert!(
                    (a - b).abs() <= tolerance * b.abs(),
                    "found {found:?}\nexpected {truth:?}"
                );
            }
        }
    }

    #[test]
    fn recovers_two_bands_in_both_domains() {
        let nm = grid(380.0, 720.0, 50);
        for domain in [BandDomain::Wavenumber, BandDomain::Wavelength] {
            let width = |nm_width: f64, at: f64| match domain {
                BandDomain::Wavelength => nm_width,
                // Wavenumber width of a band nm_width wide at `at` nm.
                BandDomain::Wavenumber => 1e7 * nm_width / (at * at),
            };
            let truth = GaussianBands {
                domain,
                support_nm: [380.0, 720.0],
                bands: vec![
                    GaussianBand {
                        centre_nm: 470.0,
                        width: width(25.0, 470.0),
                        height: 3.0,
                    },
                    GaussianBand {
                        centre_nm: 560.0,
                        width: width(40.0, 560.0),
                        height: 1.7,
                    },
                ],
            };
            let values: Vec<f64> = nm.iter().map(|&l| truth.eval(l)).collect();
            let fit = fit_bands(&nm, &values, domain, 2).unwrap();
            assert_same_bands(&fit.bands, &truth, 1e-8);
            assert!(fit.rel_rms < 1e-10, "{}", fit.rel_rms);
        }
    }

    #[test]
    fn a_growth_gives_each_count_what_growing_every_count_gives_bit_for_bit() {
        // A noisy three-band curve (the growth's seeds matter only where fits are not
        // exact), asked for out of order and twice, then a count it has too few samples
        // for, and a curve with no positive value.
        let nm = grid(380.0, 720.0, 31);
        let values: Vec<f64> = nm
            .iter()
            .enumerate()
            .map(|(i, &l)| {
                let band = |c: f64, w: f64, h: f64| h * (-0.5 * ((l - c) / w).powi(2)).exp();
                band(450.0, 20.0, 1.0)
                    + band(520.0, 35.0, 0.6)
                    + band(610.0, 25.0, 0.3)
                    + 0.01 * ((i * 7919 % 13) as f64 / 13.0 - 0.5)
            })
            .collect();
        let bits = |fit: &BandFit| -> Vec<u64> {
            fit.bands
                .params()
                .iter()
                .chain([&fit.rms])
                .map(|x| x.to_bits())
                .collect()
        };
        for domain in [BandDomain::Wavenumber, BandDomain::Wavelength] {
            // The reference grows and polishes every count in one pass (no count reaches
            // the tolerance on this noise), the path fit_bands took before the growth.
            let every = fit_bands_to_tolerance(&nm, &values, domain, 4, 1e-12).unwrap();
            assert_eq!(every.len(), 4);
            let mut growth = BandGrowth::new(&nm, &values, domain);
            for n in [3, 1, 2, 3, 4] {
                let grown = growth.fit(n).unwrap();
                assert_eq!(bits(&grown), bits(&every[n - 1]), "{domain:?}, {n} bands");
                let alone = fit_bands(&nm, &values, domain, n).unwrap();
                assert_eq!(bits(&alone), bits(&every[n - 1]), "{domain:?}, {n} bands");
            }
            let too_many = growth.fit(11).unwrap_err().to_string();
            assert!(
                too_many.contains("n_bands") && too_many.contains("at least 33 samples"),
                "{too_many}"
            );
            assert!(growth.fit(0).is_err());
        }
        let flat = vec![0.0; nm.len()];
        let none = BandGrowth::new(&nm, &flat, BandDomain::Wavenumber)
            .fit(1)
            .unwrap_err();
        assert!(none.to_string().contains("peak at 0"), "{none}");
    }

    #[test]
    fn recovers_overlapping_and_three_bands() {
        let nm = grid(300.0, 700.0, 81);
        let cases = [
            // A shoulder: the second band sits within the first's half width.
            vec![(450.0, 1500.0, 1.0), (490.0, 1200.0, 0.5)],
            vec![
                (350.0, 2500.0, 0.4),
                (480.0, 1100.0, 1.0),
                (600.0, 900.0, 0.3),
            ],
            // The largest band peaks outside the samples.
            vec![(290.0, 3000.0, 2.0), (520.0, 1000.0, 0.6)],
        ];
        for case in cases {
            let truth = GaussianBands {
                domain: BandDomain::Wavenumber,
                support_nm: [300.0, 700.0],
                bands: case
                    .iter()
                    .map(|&(centre_nm, width, height)| GaussianBand {
                        centre_nm,
                        width,
                        height,
                    })
                    .collect(),
            };
            let values: Vec<f64> = nm.iter().map(|&l| truth.eval(l)).collect();
            let fit = fit_bands(&nm, &values, BandDomain::Wavenumber, case.len()).unwrap();
            assert_same_bands(&fit.bands, &truth, 1e-8);
        }
    }
}
