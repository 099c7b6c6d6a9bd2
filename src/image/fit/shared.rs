//! The fluorophores every pixel shares: a K-component non-negative PARAFAC of the pixels ×
//! excitation × emission tensor of reradiation cells (model.md §8), fitted in the
//! compressed coordinates of the scratch file.
//!
//! Each pixel's reradiation x_p ≈ Σ_k s_pk·B_k with B_k[(i, o)] = β_k(i)·ε_k(o) on the
//! layout's cells (β max 1, Σ_o ε = 1: ε is the emission per bin). With x_p ≈ Q·y_p:
//! - the scores s_p = NNLS(BᵀB, (QᵀB)ᵀ·y_p), exact per pixel;
//! - the sums Sᵀ·S and Sᵀ·X ≈ (Sᵀ·Y)·Qᵀ give β and ε by hierarchical ALS on their rows,
//!   with the layout's mask (only λo > λi exists) in the row Gram matrices.
//!
//! One iteration reads every record once (a pass of [`super::records`]); the start comes from the joint fit's
//! non-negative PARAFAC on a regular grid of pixels rebuilt from their coordinates.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::fit::joint::parafac;

use super::nnls;
use super::scratch::Scratch;

/// Coordinate-descent sweeps of each factor update.
const INNER_SWEEPS: usize = 3;
/// Ridge of the row updates, relative to the best-determined row: an excitation row
/// whose emission lies almost wholly outside its cells (λo > λi only) tells nothing of
/// β there, and without a ridge its noise, divided by a vanishing Gram entry, would set
/// the absorption's maximum.
const RIDGE: f64 = 1e-4;

/// How the layout's reradiation cells map onto excitation and emission indices.
#[derive(Debug, Clone)]
pub struct Cells {
    /// Per reradiation cell: its excitation index (into the excitation wavelengths).
    pub excitation: Vec<usize>,
    /// Per reradiation cell: its emission index (into the emission wavelengths).
    pub emission: Vec<usize>,
    /// Excitation wavelengths (nm).
    pub excitation_nm: Vec<f64>,
    /// Emission wavelengths (nm).
    pub emission_nm: Vec<f64>,
}

impl Cells {
    /// Number of reradiation cells.
    pub fn len(&self) -> usize {
        self.excitation.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.excitation.is_empty()
    }
}

/// Shared spectra of K fluorophores and how their fit went.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Shared {
    /// Components.
    pub k: usize,
    /// β_k(i), K × excitation, max 1 each.
    pub excitation: Vec<f64>,
    /// ε_k(o), K × emission, Σ = 1 each (per bin).
    pub emission: Vec<f64>,
    /// Σ over unmasked pixels of the squared residual of the reradiation cells
    /// (compressed estimate).
    pub loss: f64,
    /// Σ over unmasked pixels of their reradiation energy.
    pub energy: f64,
    /// Iterations over all pixels.
    pub iterations: usize,
    /// Whether the relative loss change fell below the tolerance.
    pub converged: bool,
    /// Largest score of each component over the pixels.
    pub max_scores: Vec<f64>,
}

impl Shared {
    /// B_k over the reradiation cells.
    pub fn cell_vector(&self, cells: &Cells, k: usize) -> Vec<f64> {
        let (ni, no) = (cells.excitation_nm.len(), cells.emission_nm.len());
        (0..cells.len())
            .map(|j| {
                self.excitation[k * ni + cells.excitation[j]]
                    * self.emission[k * no + cells.emission[j]]
            })
            .collect()
    }
}

/// What every pass needs: the projection of the components on the basis and their Gram.
pub struct Projected {
    /// K.
    pub k: usize,
    /// G = QᵀB, rank × K row-major.
    pub g: Vec<f64>,
    /// H = BᵀB, K × K.
    pub h: Vec<f64>,
}

impl Projected {
    /// For the components of `shared` and the `basis` (m × rank).
    pub fn new(shared: &Shared, cells: &Cells, basis: &[f64], rank: usize) -> Projected {
        let k = shared.k;
        let vectors: Vec<Vec<f64>> = (0..k).map(|c| shared.cell_vector(cells, c)).collect();
        let mut g = vec![0.0; rank * k];
        for (c, b) in vectors.iter().enumerate() {
            for (j, &v) in b.iter().enumerate() {
                if v != 0.0 {
                    for a in 0..rank {
                        g[a * k + c] += basis[j * rank + a] * v;
                    }
                }
            }
        }
        let mut h = vec![0.0; k * k];
        for a in 0..k {
            for b in a..k {
                let d = crate::numeric::dot(&vectors[a], &vectors[b]);
                h[a * k + b] = d;
                h[b * k + a] = d;
            }
        }
        Projected { k, g, h }
    }

    /// The scores of a pixel with coordinates `y`.
    pub fn scores(&self, y: &[f32]) -> [f64; nnls::MAX_UNKNOWNS] {
        let k = self.k;
        let mut rhs = [0.0; nnls::MAX_UNKNOWNS];
        for (a, &v) in y.iter().enumerate() {
            let v = f64::from(v);
            for c in 0..k {
                rhs[c] += self.g[a * k + c] * v;
            }
        }
        nnls::solve(&self.h, &rhs[..k])
    }
}

/// Sums over the pixels of one iteration of the shared fit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sums {
    /// Sᵀ·S, K × K.
    pub sts: Vec<f64>,
    /// Sᵀ·Y, K × rank.
    pub sty: Vec<f64>,
    /// Σ squared residual (compressed estimate).
    pub loss: f64,
    /// Σ energy.
    pub energy: f64,
    /// Largest score per component.
    pub max_scores: Vec<f64>,
}

impl Sums {
    /// Nothing summed yet.
    pub fn zero(k: usize, rank: usize) -> Sums {
        Sums {
            sts: vec![0.0; k * k],
            sty: vec![0.0; k * rank],
            loss: 0.0,
            energy: 0.0,
            max_scores: vec![0.0; k],
        }
    }

    /// Adds another chunk's sums.
    pub fn add(&mut self, o: &Sums) {
        for (a, b) in self.sts.iter_mut().zip(&o.sts) {
            *a += b;
        }
        for (a, b) in self.sty.iter_mut().zip(&o.sty) {
            *a += b;
        }
        self.loss += o.loss;
        self.energy += o.energy;
        for (a, b) in self.max_scores.iter_mut().zip(&o.max_scores) {
            *a = a.max(*b);
        }
    }
}

/// Updates β and ε from Sᵀ·S and Sᵀ·X (K × m) by row-wise coordinate descent.
fn update_factors(shared: &mut Shared, cells: &Cells, sts: &[f64], stx: &[f64]) {
    let k = shared.k;
    let (ni, no) = (cells.excitation_nm.len(), cells.emission_nm.len());
    // Cells by excitation row and by emission column.
    let mut rows: Vec<Vec<usize>> = vec![Vec::new(); ni];
    let mut columns: Vec<Vec<usize>> = vec![Vec::new(); no];
    for j in 0..cells.len() {
        rows[cells.excitation[j]].push(j);
        columns[cells.emission[j]].push(j);
    }
    let excitation = Mode {
        groups: &rows,
        own: &cells.excitation,
        other: &cells.emission,
    };
    let emission = Mode {
        groups: &columns,
        own: &cells.emission,
        other: &cells.excitation,
    };
    // The ridges are set once per update, from the factors it starts with.
    let ridge_rows = excitation.ridge(&shared.emission, no, sts, k);
    let ridge_columns = emission.ridge(&shared.excitation, ni, sts, k);
    for _ in 0..INNER_SWEEPS {
        excitation.sweep(
            &mut shared.excitation,
            ni,
            &shared.emission,
            no,
            sts,
            stx,
            &ridge_rows,
            k,
        );
        emission.sweep(
            &mut shared.emission,
            no,
            &shared.excitation,
            ni,
            sts,
            stx,
            &ridge_columns,
            k,
        );
    }
    normalise(shared, ni, no);
}

/// One factor's view of the cells: the cells of each of its entries (an excitation row
/// or an emission column), and each cell's index in this factor and in the other.
struct Mode<'a> {
    groups: &'a [Vec<usize>],
    own: &'a [usize],
    other: &'a [usize],
}

impl Mode<'_> {
    /// Per component: [`RIDGE`] × the largest Gram diagonal over the entries × Sᵀ·S.
    fn ridge(&self, other: &[f64], n_other: usize, sts: &[f64], k: usize) -> Vec<f64> {
        (0..k)
            .map(|a| {
                self.groups
                    .iter()
                    .map(|g| {
                        g.iter()
                            .map(|&j| other[a * n_other + self.other[j]].powi(2))
                            .sum::<f64>()
                    })
                    .fold(0.0, f64::max)
                    * RIDGE
                    * sts[a * k + a]
            })
            .collect()
    }

    /// One coordinate-descent sweep over the entries of `factor` (K × n), the other
    /// factor held.
    #[allow(clippy::too_many_arguments)]
    fn sweep(
        &self,
        factor: &mut [f64],
        n: usize,
        other: &[f64],
        n_other: usize,
        sts: &[f64],
        stx: &[f64],
        ridge: &[f64],
        k: usize,
    ) {
        let m = self.own.len();
        for (e, group) in self.groups.iter().enumerate() {
            let mut gram = vec![0.0; k * k];
            let mut rhs = vec![0.0; k];
            for &j in group {
                let o = self.other[j];
                for a in 0..k {
                    let va = other[a * n_other + o];
                    rhs[a] += stx[a * m + j] * va;
                    for b in 0..k {
                        gram[a * k + b] += va * other[b * n_other + o];
                    }
                }
            }
            for a in 0..k {
                let diagonal = sts[a * k + a] * gram[a * k + a] + ridge[a];
                if diagonal <= 0.0 {
                    continue;
                }
                let others: f64 = (0..k)
                    .filter(|&b| b != a)
                    .map(|b| sts[a * k + b] * gram[a * k + b] * factor[b * n + e])
                    .sum();
                factor[a * n + e] = ((rhs[a] - others) / diagonal).max(0.0);
            }
        }
    }
}

/// β max 1, Σ ε = 1 (the scale goes to the scores, which the next pass recomputes).
fn normalise(shared: &mut Shared, ni: usize, no: usize) {
    for a in 0..shared.k {
        let ex = &mut shared.excitation[a * ni..(a + 1) * ni];
        let peak = ex.iter().cloned().fold(0.0, f64::max);
        if peak > 0.0 {
            ex.iter_mut().for_each(|v| *v /= peak);
        }
        let em = &mut shared.emission[a * no..(a + 1) * no];
        let sum: f64 = em.iter().sum();
        if sum > 0.0 {
            em.iter_mut().for_each(|v| *v /= sum);
        }
    }
}

/// The pixels the successive projection algorithm picks (Araújo et al. 2001; the
/// endmember search of hyperspectral unmixing): each the unmasked pixel farthest from the
/// span of those picked before, in the compressed coordinates. With non-negative mixtures
/// these are the purest pixels of each fluorophore, wherever they lie in the image.
///
/// `farthest(directions)` is a pass over the records: the unmasked pixel farthest from the
/// span of `directions` (its squared distance and index), none if every pixel is masked.
pub fn extreme_pixels(
    scratch: &Scratch,
    count: usize,
    mut farthest: impl FnMut(&[Vec<f64>]) -> Result<Option<(f64, usize)>>,
) -> Result<Vec<usize>> {
    let rank = scratch.layout.rank;
    let mut picked: Vec<usize> = Vec::new();
    // Orthonormal directions of the picked pixels' coordinates.
    let mut directions: Vec<Vec<f64>> = Vec::new();
    for _ in 0..count.min(rank) {
        let Some(winner) = farthest(&directions)? else {
            break;
        };
        if winner.0 <= 0.0 {
            break;
        }
        let record = scratch.read(winner.1, 1)?;
        let mut v: Vec<f64> = record[scratch.layout.y()]
            .iter()
            .map(|&x| f64::from(x))
            .collect();
        for d in &directions {
            let dot: f64 = d.iter().zip(&v).map(|(a, b)| a * b).sum();
            for (x, a) in v.iter_mut().zip(d) {
                *x -= dot * a;
            }
        }
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm <= 0.0 {
            break;
        }
        v.iter_mut().for_each(|x| *x /= norm);
        directions.push(v);
        picked.push(winner.1);
    }
    Ok(picked)
}

/// Extreme pixels the start of every K is fitted on (with a regular grid).
pub const START_EXTREMES: usize = 16;

/// The start: the joint fit's non-negative PARAFAC on a few pixels (the `extremes` of
/// [`extreme_pixels`] and a regular grid, `pixels` in all), rebuilt from their coordinates (x ≈ Q·y, which also
/// removes most of their noise).
#[allow(clippy::too_many_arguments)]
pub fn start(
    scratch: &Scratch,
    cells: &Cells,
    basis: &[f64],
    extremes: &[usize],
    width: usize,
    height: usize,
    k: usize,
    pixels: usize,
) -> Result<Shared> {
    let rank = scratch.layout.rank;
    let (ni, no) = (cells.excitation_nm.len(), cells.emission_nm.len());
    let mut chosen = extremes.to_vec();
    let grid = pixels.saturating_sub(chosen.len()).max(1);
    let stride = ((width * height) as f64 / grid as f64)
        .sqrt()
        .ceil()
        .max(1.0) as usize;
    for y in (stride / 2..height).step_by(stride) {
        for x in (stride / 2..width).step_by(stride) {
            if !chosen.contains(&(y * width + x)) {
                chosen.push(y * width + x);
            }
        }
    }
    let mut values = Vec::new();
    let mut samples = 0;
    for &p in &chosen {
        let record = scratch.read(p, 1)?;
        if record[0] != 0.0 {
            continue;
        }
        let coordinates = &record[scratch.layout.y()];
        let mut matrix = vec![f64::NAN; ni * no];
        for j in 0..cells.len() {
            let v: f64 = (0..rank)
                .map(|a| basis[j * rank + a] * f64::from(coordinates[a]))
                .sum();
            matrix[cells.excitation[j] * no + cells.emission[j]] = v;
        }
        values.extend(matrix);
        samples += 1;
    }
    if samples == 0 {
        return Err(Error::invalid(
            "image",
            "every pixel is masked (each holds a non-finite cell): nothing to fit",
        ));
    }
    let tensor = parafac::Tensor {
        samples,
        n_ex: ni,
        n_em: no,
        values,
    };
    let fitted = parafac::fit(
        &tensor,
        &vec![1.0; no],
        &parafac::ParafacOptions {
            components: k,
            max_iterations: 300,
            tolerance: 1e-7,
        },
    )?;
    let mut shared = Shared {
        k,
        excitation: fitted.factors.excitation,
        emission: fitted.factors.emission,
        loss: f64::INFINITY,
        energy: 0.0,
        iterations: 0,
        converged: false,
        max_scores: vec![0.0; k],
    };
    normalise(&mut shared, ni, no);
    Ok(shared)
}

/// Refines `shared` on every pixel until the loss changes by less than `tolerance`
/// (relative) or `max_iterations` passes; `scores(shared)` is a pass over the records
/// (the sums of every unmasked pixel's scores); `progress` gets each iteration.
#[allow(clippy::too_many_arguments)]
pub fn refine(
    cells: &Cells,
    basis: &[f64],
    rank: usize,
    mut shared: Shared,
    max_iterations: usize,
    tolerance: f64,
    mut scores: impl FnMut(&Shared) -> Result<Sums>,
    mut progress: impl FnMut(usize),
) -> Result<Shared> {
    let k = shared.k;
    let m = cells.len();
    let mut previous = f64::INFINITY;
    for iteration in 1..=max_iterations {
        crate::files::check_interrupted(std::path::Path::new("image fit"))?;
        let sums = scores(&shared)?;
        shared.loss = sums.loss.max(0.0);
        shared.energy = sums.energy;
        shared.max_scores = sums.max_scores.clone();
        shared.iterations = iteration;
        progress(iteration);
        let change = (previous - sums.loss).abs() / sums.energy.max(f64::MIN_POSITIVE);
        if change < tolerance {
            shared.converged = true;
            break;
        }
        previous = sums.loss;
        if iteration == max_iterations {
            break;
        }
        // Sᵀ·X ≈ (Sᵀ·Y)·Qᵀ.
        let mut stx = vec![0.0; k * m];
        for a in 0..k {
            for j in 0..m {
                stx[a * m + j] = (0..rank)
                    .map(|t| sums.sty[a * rank + t] * basis[j * rank + t])
                    .sum();
            }
        }
        update_factors(&mut shared, cells, &sums.sts, &stx);
    }
    Ok(shared)
}
