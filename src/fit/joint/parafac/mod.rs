//! Non-negative PARAFAC (CP) of a stack of EEMs with missing cells:
//! `X[s, ex, em] ≈ Σ_k A[s,k]·Ex[k,ex]·Em[k,em]`, every factor ≥ 0.
//!
//! Start (closed form, one start): the leading singular vectors of the excitation and
//! emission unfoldings (missing cells read as 0; a sequentially truncated HOSVD, so the
//! long emission mode never needs its own large Gram matrix), each made non-negative as
//! NNDSVD does (the larger of its positive and negative parts), scores 1.
//!
//! Iterations: alternating exact row-wise non-negative least squares by hierarchical ALS
//! (HALS: coordinate descent on each row's K×K normal equations). Cells missing in every
//! sample (scatter bands, unrecorded corners) are weighted out of the normal equations;
//! cells missing in some samples only are imputed from the current model before each
//! sweep (expectation maximisation), which keeps every mode's Gram matrix shared by the
//! samples and each sweep at two passes over the data. After each sweep the factors are
//! extrapolated along their last step (Bro's line search, step √iteration) and the
//! extrapolation kept when it lowers the loss over the measured cells. The whole scheme
//! is deterministic: the passes over the data run on the samples in parallel, their
//! partial sums added in sample order.

pub mod image;
mod start;

use rayon::prelude::*;

use crate::error::{Error, Result};
use image::Image;
use start::start;

/// Coordinate-descent sweeps per mode update (the normal equations are cheap to revisit;
/// more sweeps bring each update closer to the exact non-negative least-squares solution).
const INNER_SWEEPS: usize = 3;
/// Floor added to the non-negative start so that no loading starts exactly at zero (HALS
/// cannot leave zero when its gradient points below).
const START_FLOOR: f64 = 1e-3;

/// A stack of matrices on one grid: `values[(s·n_ex + ex)·n_em + em]`, NaN = missing.
#[derive(Debug, Clone, PartialEq)]
pub struct Tensor {
    /// Number of samples.
    pub samples: usize,
    /// Excitation wavelengths per sample.
    pub n_ex: usize,
    /// Emission wavelengths per sample.
    pub n_em: usize,
    /// Cells, sample-major, then excitation, then emission; NaN where not measured.
    pub values: Vec<f64>,
}

impl Tensor {
    /// Index of cell (`s`, `ex`, `em`).
    pub fn index(&self, s: usize, ex: usize, em: usize) -> usize {
        (s * self.n_ex + ex) * self.n_em + em
    }

    /// The samples listed in `keep`, in that order.
    pub fn subset(&self, keep: &[usize]) -> Tensor {
        let per = self.n_ex * self.n_em;
        let mut values = Vec::with_capacity(keep.len() * per);
        for &s in keep {
            values.extend_from_slice(&self.values[s * per..(s + 1) * per]);
        }
        Tensor {
            samples: keep.len(),
            n_ex: self.n_ex,
            n_em: self.n_em,
            values,
        }
    }
}

/// Non-negative CP factors: `scores[s·K + k]`, `excitation[k·n_ex + ex]`,
/// `emission[k·n_em + em]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Factors {
    /// Components.
    pub k: usize,
    /// Sample scores (they carry the scale).
    pub scores: Vec<f64>,
    /// Excitation (absorption) loadings, max 1 each.
    pub excitation: Vec<f64>,
    /// Emission loadings, ∫ dλ = 1 each (with the emission weights given to [`fit`]).
    pub emission: Vec<f64>,
}

impl Factors {
    /// Model value at cell (`s`, `ex`, `em`).
    pub fn model(&self, t: &Tensor, s: usize, ex: usize, em: usize) -> f64 {
        (0..self.k)
            .map(|k| {
                self.scores[s * self.k + k]
                    * self.excitation[k * t.n_ex + ex]
                    * self.emission[k * t.n_em + em]
            })
            .sum()
    }

    /// Model row (all emission cells) of sample `s` at excitation `ex`, into `row`.
    fn model_row(&self, t: &Tensor, s: usize, ex: usize, row: &mut [f64]) {
        row.fill(0.0);
        for k in 0..self.k {
            let c = self.scores[s * self.k + k] * self.excitation[k * t.n_ex + ex];
            if c != 0.0 {
                let e = &self.emission[k * t.n_em..(k + 1) * t.n_em];
                for (r, e) in row.iter_mut().zip(e) {
                    *r += c * e;
                }
            }
        }
    }

    /// Scales each excitation loading to max 1 and each emission loading to unit
    /// integral (weights `em_weights`), moving the scale into the scores.
    fn normalise(&mut self, n_ex: usize, n_em: usize, em_weights: &[f64]) {
        let samples = self.scores.len() / self.k.max(1);
        for k in 0..self.k {
            let ex = &mut self.excitation[k * n_ex..(k + 1) * n_ex];
            let peak = ex.iter().cloned().fold(0.0, f64::max);
            let em = &mut self.emission[k * n_em..(k + 1) * n_em];
            let area = crate::numeric::dot(em, em_weights);
            if peak > 0.0 && area > 0.0 {
                ex.iter_mut().for_each(|v| *v /= peak);
                em.iter_mut().for_each(|v| *v /= area);
                for s in 0..samples {
                    self.scores[s * self.k + k] *= peak * area;
                }
            }
        }
    }
}

/// How to fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ParafacOptions {
    /// Components K (1 to [`MAX_COMPONENTS`]).
    pub components: usize,
    /// Sweep limit.
    pub max_iterations: usize,
    /// Converged when a sweep lowers the loss by less than this fraction.
    pub tolerance: f64,
}

/// Largest number of components (drEEM and staRdom users rarely go past 7).
pub const MAX_COMPONENTS: usize = 10;
/// Default relative loss change at which the iterations stop.
pub const DEFAULT_TOLERANCE: f64 = 1e-6;
/// Default sweep limit.
pub const DEFAULT_MAX_ITERATIONS: usize = 2000;

impl Default for ParafacOptions {
    fn default() -> Self {
        ParafacOptions {
            components: 4,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            tolerance: DEFAULT_TOLERANCE,
        }
    }
}

/// A fitted CP model and how the iterations went.
#[derive(Debug, Clone, PartialEq)]
pub struct Parafac {
    /// The factors, normalised (max excitation 1, ∫ emission 1).
    pub factors: Factors,
    /// Sum of squared residuals over the measured cells.
    pub loss: f64,
    /// Sweeps run.
    pub iterations: usize,
    /// Whether the loss change fell below the tolerance within the sweep limit.
    pub converged: bool,
    /// Sweeps whose extrapolation was kept.
    pub extrapolations: usize,
    /// Components restarted from the residual after they had died (all scores or a
    /// loading at zero, from which HALS cannot leave).
    pub reseeded: usize,
    /// With the second-order image fitted ([`fit_with_image`]): G at the image's nodes
    /// ([`Image::nodes_nm`]). The factors' emission is then the effective one,
    /// `e(λo) + G(λo)·e(λo/2)`; [`Image::first_order`] gives e.
    pub image_gain: Option<Vec<f64>>,
}

/// Rounds of (fit G to the effective emission, refit the factors with G held) after the
/// fit without the image.
const IMAGE_ROUNDS: usize = 4;

/// The working state: data with the sample-specific gaps filled, and the common mask.
struct Work<'a> {
    t: &'a Tensor,
    /// Cells with the gaps of some samples imputed, 0 where every sample misses them.
    filled: Vec<f64>,
    /// `present[ex·n_em + em]`: measured in at least one sample (1) or in none (0).
    present: Vec<f64>,
    /// Cells imputed from the model (missing in their sample, measured in another).
    imputed: Vec<(usize, usize, usize)>,
    /// Σ X² over the measured cells.
    measured_square: f64,
    /// The cells with 0 where not measured, and 1 (measured) or 0 per cell: the loss
    /// without a branch per cell.
    data: Vec<f64>,
    weight: Vec<f64>,
}

/// Fits `options.components` non-negative components to `t`. `em_weights` are the
/// emission integration weights (bin widths) of the ∫e = 1 normalisation.
pub fn fit(t: &Tensor, em_weights: &[f64], options: &ParafacOptions) -> Result<Parafac> {
    fit_with_image(t, em_weights, options, None)
}

/// The iterations' bookkeeping.
#[derive(Default)]
struct Progress {
    iterations: usize,
    converged: bool,
    extrapolations: usize,
    reseeded: usize,
}

/// [`fit`], and with `image` the grating's second-order image of the emission as well:
/// every component's emission is seen as `e(λo) + G(λo)·e(λo/2)` with one non-negative
/// G shared by all ([`image`]). The fit first runs without the image; then, per round,
/// G is fitted to the effective emission ([`Image::fit_gain`]) and the factors refitted
/// with G held, the emission updated as first-order emission ≥ 0 ([`Image::update_rows`]).
/// Without an image (or with G = 0) this is [`fit`].
pub fn fit_with_image(
    t: &Tensor,
    em_weights: &[f64],
    options: &ParafacOptions,
    image: Option<&Image>,
) -> Result<Parafac> {
    let k = options.components;
    if k == 0 || k > MAX_COMPONENTS {
        return Err(Error::invalid(
            "--components",
            format!("{k}: give 1 to {MAX_COMPONENTS} components"),
        ));
    }
    if options.max_iterations == 0 || options.max_iterations as u64 > crate::limits::MAX_ITERATIONS
    {
        return Err(Error::invalid(
            "--max-iterations",
            format!(
                "is {}; give a count from 1 to {}",
                options.max_iterations,
                crate::limits::MAX_ITERATIONS
            ),
        ));
    }
    if t.samples == 0 || t.n_ex == 0 || t.n_em == 0 {
        return Err(Error::invalid(
            "joint fit",
            "no cells to fit: give at least one sample with excitation and emission wavelengths",
        ));
    }
    if t.values.len() != t.samples * t.n_ex * t.n_em || em_weights.len() != t.n_em {
        return Err(Error::invalid(
            "joint fit",
            "the tensor's cells or emission weights do not match its dimensions",
        ));
    }
    if image.is_some_and(|i| i.len() != t.n_em) {
        return Err(Error::invalid(
            "joint fit",
            "the second-order image was built for another emission grid",
        ));
    }
    let work = Work::new(t);
    let mut factors = start(&work, k);
    factors.normalise(t.n_ex, t.n_em, em_weights);
    let mut work = work;
    work.impute(&factors);
    let mut progress = Progress::default();
    let mut loss = iterate(
        &mut work,
        &mut factors,
        em_weights,
        options,
        None,
        &mut progress,
    );
    let mut image_gain = None;
    if let Some(image) = image {
        let mut gain = vec![0.0; t.n_em];
        let mut g = vec![0.0; image.nodes_nm().len()];
        for _ in 0..IMAGE_ROUNDS {
            let rows = transpose(&factors.emission, k, t.n_em);
            let weights = work.emission_weights(&factors);
            let next = image.fit_gain(&rows, k, &weights, &gain);
            let change = next
                .iter()
                .zip(&g)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            let scale = next.iter().cloned().fold(0.0, f64::max);
            g = next;
            gain = image.gain(&g);
            project(&mut factors, image, &gain, t, em_weights);
            work.impute(&factors);
            let mut round = Progress::default();
            loss = iterate(
                &mut work,
                &mut factors,
                em_weights,
                options,
                Some((image, &gain)),
                &mut round,
            );
            progress.iterations += round.iterations;
            progress.extrapolations += round.extrapolations;
            progress.reseeded += round.reseeded;
            progress.converged = round.converged;
            if change <= 1e-3 * scale.max(1e-12) {
                break;
            }
        }
        image_gain = Some(g);
    }
    let _ = loss;
    Ok(Parafac {
        // Exact, free of the cancellation in the sweeps' running figure.
        loss: work.loss(&factors),
        factors,
        iterations: progress.iterations,
        converged: progress.converged,
        extrapolations: progress.extrapolations,
        reseeded: progress.reseeded,
        image_gain,
    })
}

/// Makes every component's effective emission one the image allows (first-order emission
/// ≥ 0 under `gain`), then normalises.
fn project(f: &mut Factors, image: &Image, gain: &[f64], t: &Tensor, em_weights: &[f64]) {
    let n = t.n_em;
    for c in 0..f.k {
        let e = image.first_order(&f.emission[c * n..(c + 1) * n], gain);
        f.emission[c * n..(c + 1) * n].copy_from_slice(&image.effective(&e, gain));
    }
    f.normalise(t.n_ex, n, em_weights);
}

/// The ALS sweeps until converged or `options.max_iterations` in all (counted in
/// `progress`); returns the last loss.
fn iterate(
    work: &mut Work<'_>,
    factors: &mut Factors,
    em_weights: &[f64],
    options: &ParafacOptions,
    image: Option<(&Image, &[f64])>,
    progress: &mut Progress,
) -> f64 {
    let t = work.t;
    let mut loss = work.loss(factors);
    let mut previous = factors.clone();
    let mut sweeps = 0;
    while sweeps < options.max_iterations {
        sweeps += 1;
        progress.iterations += 1;
        let mut new_loss = work.sweep(factors, image);
        let dead = work.reseed_dead(factors);
        if dead > 0 {
            progress.reseeded += dead;
            if let Some((image, gain)) = image {
                project(factors, image, gain, t, em_weights);
            }
            new_loss = work.loss(factors);
        }
        factors.normalise(t.n_ex, t.n_em, em_weights);
        if sweeps > 1 {
            let step = (sweeps as f64).sqrt();
            let mut trial = extrapolate(factors, &previous, step, t, em_weights);
            if let Some((image, gain)) = image {
                project(&mut trial, image, gain, t, em_weights);
            }
            let trial_loss = work.loss(&trial);
            if trial_loss < new_loss {
                previous = std::mem::replace(factors, trial);
                new_loss = trial_loss;
                progress.extrapolations += 1;
            } else {
                previous = factors.clone();
            }
        } else {
            previous = factors.clone();
        }
        work.impute(factors);
        let change = (loss - new_loss).abs() / loss.max(f64::MIN_POSITIVE);
        loss = new_loss;
        if change < options.tolerance || loss == 0.0 {
            progress.converged = true;
            break;
        }
    }
    loss
}

/// `f + step·(f − previous)`, clipped at 0 and normalised.
fn extrapolate(
    f: &Factors,
    previous: &Factors,
    step: f64,
    t: &Tensor,
    em_weights: &[f64],
) -> Factors {
    let go = |now: &[f64], before: &[f64]| -> Vec<f64> {
        now.iter()
            .zip(before)
            .map(|(n, b)| (n + step * (n - b)).max(0.0))
            .collect()
    };
    let mut trial = Factors {
        k: f.k,
        scores: go(&f.scores, &previous.scores),
        excitation: go(&f.excitation, &previous.excitation),
        emission: go(&f.emission, &previous.emission),
    };
    trial.normalise(t.n_ex, t.n_em, em_weights);
    trial
}

/// A HALS right-hand side by rows of one mode: out[row·k + c] = Σ_other term(row, other, c),
/// summed over `other` in order.
fn mode_rhs(
    rows: usize,
    others: usize,
    k: usize,
    term: impl Fn(usize, usize, usize) -> f64,
) -> Vec<f64> {
    let mut out = vec![0.0; rows * k];
    for row in 0..rows {
        for c in 0..k {
            out[row * k + c] = (0..others).map(|other| term(row, other, c)).sum();
        }
    }
    out
}

/// One HALS pass over the rows of a factor: `rows[r·K + k]` (row-major) with per-row
/// Gram `gram(r)` (K×K, row-major) and right-hand side `rhs[r·K + k]`.
fn hals_rows(rows: &mut [f64], k: usize, rhs: &[f64], gram: impl Fn(usize) -> Vec<f64>) {
    for r in 0..rows.len() / k {
        let g = gram(r);
        let row = &mut rows[r * k..(r + 1) * k];
        for _ in 0..INNER_SWEEPS {
            for c in 0..k {
                let diagonal = g[c * k + c];
                if diagonal <= 0.0 {
                    continue;
                }
                let predicted: f64 = (0..k).map(|l| g[c * k + l] * row[l]).sum();
                row[c] = (row[c] + (rhs[r * k + c] - predicted) / diagonal).max(0.0);
            }
        }
    }
}

/// Transposes a K × n block (`[k·n + i]`) into n × K (`[i·K + k]`) and back.
fn transpose(m: &[f64], rows: usize, columns: usize) -> Vec<f64> {
    let mut out = vec![0.0; m.len()];
    for r in 0..rows {
        for c in 0..columns {
            out[c * rows + r] = m[r * columns + c];
        }
    }
    out
}

impl<'a> Work<'a> {
    fn new(t: &'a Tensor) -> Self {
        let per = t.n_ex * t.n_em;
        let mut present = vec![0.0; per];
        for s in 0..t.samples {
            for (c, p) in present.iter_mut().enumerate() {
                if t.values[s * per + c].is_finite() {
                    *p = 1.0;
                }
            }
        }
        let mut imputed = Vec::new();
        let mut filled = t.values.clone();
        for s in 0..t.samples {
            for c in 0..per {
                let v = &mut filled[s * per + c];
                if !v.is_finite() {
                    *v = 0.0;
                    if present[c] > 0.0 {
                        imputed.push((s, c / t.n_em, c % t.n_em));
                    }
                }
            }
        }
        let measured_square = t
            .values
            .iter()
            .filter(|v| v.is_finite())
            .map(|v| v * v)
            .sum();
        Work {
            t,
            filled,
            present,
            imputed,
            measured_square,
            data: t
                .values
                .iter()
                .map(|v| if v.is_finite() { *v } else { 0.0 })
                .collect(),
            weight: t
                .values
                .iter()
                .map(|v| if v.is_finite() { 1.0 } else { 0.0 })
                .collect(),
        }
    }

    /// Fills the sample-specific gaps with the model.
    fn impute(&mut self, f: &Factors) {
        for &(s, ex, em) in &self.imputed {
            let i = self.t.index(s, ex, em);
            self.filled[i] = f.model(self.t, s, ex, em);
        }
    }

    /// Restarts every dead component (a factor column all zero: HALS never moves it
    /// again) as the rank-1 sums of the positive residual, scaled by least squares: the
    /// signal the other components leave unexplained. Returns how many were restarted.
    fn reseed_dead(&self, f: &mut Factors) -> usize {
        let t = self.t;
        let (k, n_ex, n_em) = (f.k, t.n_ex, t.n_em);
        let dead: Vec<usize> = (0..k)
            .filter(|&c| {
                (0..t.samples).all(|s| f.scores[s * k + c] <= 0.0)
                    || f.excitation[c * n_ex..(c + 1) * n_ex]
                        .iter()
                        .all(|&x| x <= 0.0)
                    || f.emission[c * n_em..(c + 1) * n_em]
                        .iter()
                        .all(|&x| x <= 0.0)
            })
            .collect();
        for &c in &dead {
            let mut residual = vec![0.0; t.values.len()];
            let mut row = vec![0.0; n_em];
            for s in 0..t.samples {
                for ex in 0..n_ex {
                    f.model_row(t, s, ex, &mut row);
                    let start = t.index(s, ex, 0);
                    for em in 0..n_em {
                        let v = t.values[start + em];
                        if v.is_finite() {
                            residual[start + em] = (v - row[em]).max(0.0);
                        }
                    }
                }
            }
            let (mut a, mut x, mut e) = (vec![0.0; t.samples], vec![0.0; n_ex], vec![0.0; n_em]);
            for s in 0..t.samples {
                for ex in 0..n_ex {
                    for em in 0..n_em {
                        let r = residual[t.index(s, ex, em)];
                        a[s] += r;
                        x[ex] += r;
                        e[em] += r;
                    }
                }
            }
            let (mut cross, mut square) = (0.0, 0.0);
            for s in 0..t.samples {
                for ex in 0..n_ex {
                    for em in 0..n_em {
                        if t.values[t.index(s, ex, em)].is_finite() {
                            let m = a[s] * x[ex] * e[em];
                            cross += residual[t.index(s, ex, em)] * m;
                            square += m * m;
                        }
                    }
                }
            }
            if cross <= 0.0 || square <= 0.0 {
                continue;
            }
            for (s, a) in a.iter().enumerate() {
                f.scores[s * k + c] = a * cross / square;
            }
            f.excitation[c * n_ex..(c + 1) * n_ex].copy_from_slice(&x);
            f.emission[c * n_em..(c + 1) * n_em].copy_from_slice(&e);
        }
        dead.len()
    }

    /// The diagonal of each emission row's Gram matrix, `[em·K + c]`: how much the cells
    /// of row em weigh on component c's emission.
    fn emission_weights(&self, f: &Factors) -> Vec<f64> {
        let t = self.t;
        let (k, n_ex, n_em) = (f.k, t.n_ex, t.n_em);
        let ata = scores_gram(f, t.samples);
        let mut out = vec![0.0; n_em * k];
        for ex in 0..n_ex {
            for em in 0..n_em {
                if self.present[ex * n_em + em] > 0.0 {
                    for c in 0..k {
                        out[em * k + c] += ata[c * k + c] * f.excitation[c * n_ex + ex].powi(2);
                    }
                }
            }
        }
        out
    }

    /// Sum of squared residuals over the measured cells.
    fn loss(&self, f: &Factors) -> f64 {
        let t = self.t;
        let per_sample: Vec<f64> = (0..t.samples)
            .into_par_iter()
            .map(|s| {
                let mut row = vec![0.0; t.n_em];
                let mut total = 0.0;
                for ex in 0..t.n_ex {
                    f.model_row(t, s, ex, &mut row);
                    let start = t.index(s, ex, 0);
                    let cells = start..start + t.n_em;
                    for ((v, w), m) in self.data[cells.clone()]
                        .iter()
                        .zip(&self.weight[cells])
                        .zip(&row)
                    {
                        total += w * (v - m) * (v - m);
                    }
                }
                total
            })
            .collect();
        per_sample.iter().sum()
    }

    /// One ALS sweep: scores, excitation, emission (this order reuses the emission
    /// projection for the first two). Returns the loss over the measured cells.
    fn sweep(&self, f: &mut Factors, image: Option<(&Image, &[f64])>) -> f64 {
        let t = self.t;
        let (k, n_ex, n_em, samples) = (f.k, t.n_ex, t.n_em, t.samples);
        let x = &self.filled;
        // p[(s·n_ex + ex)·K + c] = Σ_em X[s,ex,em]·Em[c,em].
        let mut p = vec![0.0; samples * n_ex * k];
        p.par_chunks_mut(n_ex * k).enumerate().for_each(|(s, ps)| {
            for ex in 0..n_ex {
                let row = &x[t.index(s, ex, 0)..t.index(s, ex, 0) + n_em];
                for c in 0..k {
                    ps[ex * k + c] =
                        crate::numeric::dot(row, &f.emission[c * n_em..(c + 1) * n_em]);
                }
            }
        });
        // h[ex] = Σ_em present·Em Emᵀ (K×K).
        let mut h = vec![0.0; n_ex * k * k];
        for ex in 0..n_ex {
            let mask = &self.present[ex * n_em..(ex + 1) * n_em];
            for a in 0..k {
                let ea = &f.emission[a * n_em..(a + 1) * n_em];
                for b in a..k {
                    let eb = &f.emission[b * n_em..(b + 1) * n_em];
                    let v: f64 = mask
                        .iter()
                        .zip(ea.iter().zip(eb))
                        .map(|(m, (x, y))| m * x * y)
                        .sum();
                    h[ex * k * k + a * k + b] = v;
                    h[ex * k * k + b * k + a] = v;
                }
            }
        }
        // Scores: one Gram for all samples.
        let mut gram_a = vec![0.0; k * k];
        for ex in 0..n_ex {
            for a in 0..k {
                for b in 0..k {
                    gram_a[a * k + b] += h[ex * k * k + a * k + b]
                        * f.excitation[a * n_ex + ex]
                        * f.excitation[b * n_ex + ex];
                }
            }
        }
        let rhs = mode_rhs(samples, n_ex, k, |s, ex, c| {
            f.excitation[c * n_ex + ex] * p[(s * n_ex + ex) * k + c]
        });
        hals_rows(&mut f.scores, k, &rhs, |_| gram_a.clone());
        let ata = scores_gram(f, samples);
        // Excitation: Gram (AᵀA) ⊙ h[ex] per row.
        let rhs = mode_rhs(n_ex, samples, k, |ex, s, c| {
            f.scores[s * k + c] * p[(s * n_ex + ex) * k + c]
        });
        let mut rows = transpose(&f.excitation, k, n_ex);
        hals_rows(&mut rows, k, &rhs, |ex| {
            (0..k * k).map(|i| ata[i] * h[ex * k * k + i]).collect()
        });
        f.excitation = transpose(&rows, n_ex, k);
        // Emission: RHS[c, em] = Σ_s,ex A[s,c]·Ex[c,ex]·X[s,ex,em]; Gram (AᵀA) ⊙
        // Σ_ex present·Ex Exᵀ per emission row.
        // Per-sample partial sums, added in sample order: the same result on any number
        // of threads.
        let partials: Vec<Vec<f64>> = (0..samples)
            .into_par_iter()
            .map(|s| {
                let mut part = vec![0.0; k * n_em];
                for ex in 0..n_ex {
                    let row = &x[t.index(s, ex, 0)..t.index(s, ex, 0) + n_em];
                    for c in 0..k {
                        let w = f.scores[s * k + c] * f.excitation[c * n_ex + ex];
                        if w != 0.0 {
                            for (o, r) in part[c * n_em..(c + 1) * n_em].iter_mut().zip(row) {
                                *o += w * r;
                            }
                        }
                    }
                }
                part
            })
            .collect();
        let mut rhs_t = vec![0.0; k * n_em];
        for part in &partials {
            for (o, v) in rhs_t.iter_mut().zip(part) {
                *o += v;
            }
        }
        let rhs = transpose(&rhs_t, k, n_em);
        let mut outer = vec![0.0; n_ex * k * k];
        for ex in 0..n_ex {
            for a in 0..k {
                for b in 0..k {
                    outer[ex * k * k + a * k + b] =
                        ata[a * k + b] * f.excitation[a * n_ex + ex] * f.excitation[b * n_ex + ex];
                }
            }
        }
        let mut grams = vec![0.0; n_em * k * k];
        for (em, g) in grams.chunks_mut(k * k).enumerate() {
            for ex in 0..n_ex {
                if self.present[ex * n_em + em] > 0.0 {
                    for (o, v) in g.iter_mut().zip(&outer[ex * k * k..(ex + 1) * k * k]) {
                        *o += v;
                    }
                }
            }
        }
        let mut rows = transpose(&f.emission, k, n_em);
        match image {
            Some((image, gain)) => {
                image.update_rows(&mut rows, k, &rhs, &grams, gain, INNER_SWEEPS)
            }
            None => hals_rows(&mut rows, k, &rhs, |em| {
                grams[em * k * k..(em + 1) * k * k].to_vec()
            }),
        }
        // The loss over the cells the model is fitted to, without another pass over the
        // data: Σ X² − 2⟨X, M⟩ + ‖M‖², with ⟨X, M⟩ from the emission right-hand side
        // and ‖M‖² from the emission Gram matrices.
        let cross: f64 = rhs.iter().zip(&rows).map(|(r, e)| r * e).sum();
        let model_square: f64 = rows
            .chunks(k)
            .zip(grams.chunks(k * k))
            .map(|(e, g)| {
                (0..k)
                    .map(|a| e[a] * (0..k).map(|b| g[a * k + b] * e[b]).sum::<f64>())
                    .sum::<f64>()
            })
            .sum();
        f.emission = transpose(&rows, n_em, k);
        let mut filled_loss = self.measured_square - 2.0 * cross + model_square;
        // The imputed cells are not data: take their share out.
        for &(s, ex, em) in &self.imputed {
            let v = self.filled[t.index(s, ex, em)];
            filled_loss += v * v - (v - f.model(t, s, ex, em)).powi(2);
        }
        filled_loss.max(0.0)
    }
}

/// AᵀA of the scores (K×K, row-major).
fn scores_gram(f: &Factors, samples: usize) -> Vec<f64> {
    let k = f.k;
    let mut g = vec![0.0; k * k];
    for s in 0..samples {
        let row = &f.scores[s * k..(s + 1) * k];
        for a in 0..k {
            for b in 0..k {
                g[a * k + b] += row[a] * row[b];
            }
        }
    }
    g
}

#[cfg(test)]
mod tests;
