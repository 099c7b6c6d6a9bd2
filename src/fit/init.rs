//! The closed-form start: a masked non-negative rank-1 factorisation of the off-diagonal
//! cells (alternating least squares, each half-step an exact non-negative least-squares
//! solve), then the diagonal minus the fluorescent term.

use super::data::{Cell, FitData};

/// A rank-1 factorisation M ≈ u·vᵀ of the off-diagonal cells.
#[derive(Debug, Clone)]
pub struct RankOne {
    /// Per excitation row: k·a(λi) up to the scale carried by `column`.
    pub row: Vec<f64>,
    /// Per emission column: e(λo)·Δλo (per-bin) or e(λo) (per-nm), up to scale.
    pub column: Vec<f64>,
    /// Alternating sweeps performed.
    pub sweeps: usize,
    /// Whether successive sweeps stopped changing (relative 1e-13).
    pub converged: bool,
    /// ½ Σ (M − u·v)² over the off-diagonal cells, per sweep.
    pub cost_history: Vec<f64>,
}

impl RankOne {
    /// The energy of `data`'s off-diagonal cells this fit explains: Σ M² − Σ (M − u·v)²
    /// (`data` the cells it was fitted to; all of it before the first sweep).
    pub fn explained(&self, data: &FitData) -> f64 {
        let total: f64 = data.off_diagonal.iter().map(|c| c.value * c.value).sum();
        total - 2.0 * self.cost_history.last().copied().unwrap_or(0.5 * total)
    }
}

/// What a rank-1 fit explains of pure noise of level `sigma` on an `rows` × `columns`
/// grid: about σ²(√m + √n)², the top singular value of the noise matrix squared. The unit
/// in which the grid fit asks whether a matrix holds fluorescence, and the model search
/// whether a grid model's residual holds a second fluorophore.
pub fn noise_rank_one_energy(sigma: f64, rows: usize, columns: usize) -> f64 {
    sigma * sigma * ((rows as f64).sqrt() + (columns as f64).sqrt()).powi(2)
}

/// Sweep limit of the rank-1 start. Fluorescent surfaces converge in about ten sweeps;
/// pure noise (σ₁ ≈ σ₂) converges slowly, and the significance test needs only the
/// explained energy, which is near its limit long before.
pub const MAX_SWEEPS: usize = 200;

/// Masked non-negative rank-1 fit by alternating least squares. With exact rank-1 data
/// it recovers the factors to machine precision in a few sweeps; with noise it converges
/// linearly at the rate (σ₂/σ₁)², fast for fluorescent surfaces whose matrix is nearly
/// rank 1.
pub fn rank_one(data: &FitData, max_sweeps: usize) -> RankOne {
    let (n_ex, n_em) = (data.n_excitation(), data.n_emission());
    // Start from the positive column mass: the emission profile the data show.
    let mut column = vec![0.0; n_em];
    for c in &data.off_diagonal {
        column[c.column] += c.value.max(0.0);
    }
    let mut row = vec![0.0; n_ex];
    let mut history = Vec::new();
    let mut converged = false;
    let mut sweeps = 0;
    for sweep in 0..max_sweeps {
        sweeps = sweep + 1;
        row = fit_factor(&data.off_diagonal, None, &column, n_ex, by_row);
        let new = fit_factor(&data.off_diagonal, None, &row, n_em, by_column);
        let change: f64 = new.iter().zip(&column).map(|(a, b)| (a - b).powi(2)).sum();
        let norm: f64 = new.iter().map(|x| x * x).sum();
        column = new;
        let cost: f64 = data
            .off_diagonal
            .iter()
            .map(|c| 0.5 * (c.value - row[c.row] * column[c.column]).powi(2))
            .sum();
        history.push(cost);
        if norm == 0.0 {
            break;
        }
        // Rescale so both factors carry equal norm: keeps the sweeps well conditioned.
        let row_norm = row.iter().map(|x| x * x).sum::<f64>().sqrt();
        let column_norm = norm.sqrt();
        if row_norm > 0.0 {
            let s = (row_norm / column_norm).sqrt();
            row.iter_mut().for_each(|x| *x /= s);
            column.iter_mut().for_each(|x| *x *= s);
        }
        if change <= 1e-26 * norm {
            converged = true;
            break;
        }
    }
    RankOne {
        row,
        column,
        sweeps,
        converged,
        cost_history: history,
    }
}

/// A masked non-negative factorisation M ≈ Σk row_k·column_kᵀ of the off-diagonal cells.
#[derive(Debug, Clone)]
pub struct Factors {
    /// Per component, per excitation row.
    pub rows: Vec<Vec<f64>>,
    /// Per component, per emission column.
    pub columns: Vec<Vec<f64>>,
}

/// Refines starting factors by hierarchical alternating least squares on the off-diagonal
/// cells: each half-step solves one component's row (or column) exactly with the others
/// fixed, clamped at zero. Several fluorophores excited in different bands separate
/// because each row's emission is the mix the data show there.
pub fn masked_nmf(data: &FitData, start: Factors, sweeps: usize) -> Factors {
    let Factors {
        mut rows,
        mut columns,
    } = start;
    let k_count = rows.len();
    let mut residual: Vec<f64> = data
        .off_diagonal
        .iter()
        .map(|c| {
            c.value
                - (0..k_count)
                    .map(|k| rows[k][c.row] * columns[k][c.column])
                    .sum::<f64>()
        })
        .collect();
    for _ in 0..sweeps {
        for k in 0..k_count {
            refit_component(data, &mut residual, &mut rows[k], &columns[k], by_row);
            refit_component(data, &mut residual, &mut columns[k], &rows[k], by_column);
        }
    }
    Factors { rows, columns }
}

/// A cell's (row, column): for the half-step that fits the rows.
pub(super) fn by_row(c: &Cell) -> (usize, usize) {
    (c.row, c.column)
}

/// A cell's (column, row): for the half-step that fits the columns.
pub(super) fn by_column(c: &Cell) -> (usize, usize) {
    (c.column, c.row)
}

/// The exact non-negative least-squares solution num/den of one factor entry, 0 where no
/// cell constrains it.
fn nonnegative_quotient(num: f64, den: f64) -> f64 {
    if den > 0.0 { (num / den).max(0.0) } else { 0.0 }
}

/// One half-step of alternating least squares on `cells`: the non-negative factor along
/// `at(cell).0` (length `n`) that best fits the cells given the other factor `other`
/// (along `at(cell).1`), each cell weighted by `weights` (all 1 when None).
pub(super) fn fit_factor(
    cells: &[Cell],
    weights: Option<&[f64]>,
    other: &[f64],
    n: usize,
    at: impl Fn(&Cell) -> (usize, usize),
) -> Vec<f64> {
    let (mut num, mut den) = (vec![0.0; n], vec![0.0; n]);
    for (k, c) in cells.iter().enumerate() {
        let (i, j) = at(c);
        let w = weights.map_or(1.0, |w| w[k]);
        num[i] += w * c.value * other[j];
        den[i] += w * other[j] * other[j];
    }
    num.iter()
        .zip(&den)
        .map(|(&n, &d)| nonnegative_quotient(n, d))
        .collect()
}

/// One half-step of [`masked_nmf`]: component factor `this` (along `at(cell).0`) refitted
/// given its partner `other`, against the `residual` of the other components, which is
/// kept current.
fn refit_component(
    data: &FitData,
    residual: &mut [f64],
    this: &mut [f64],
    other: &[f64],
    at: impl Fn(&Cell) -> (usize, usize),
) {
    let (mut num, mut den) = (vec![0.0; this.len()], vec![0.0; this.len()]);
    for (c, r) in data.off_diagonal.iter().zip(residual.iter()) {
        let (i, j) = at(c);
        let v = other[j];
        num[i] += (r + this[i] * v) * v;
        den[i] += v * v;
    }
    let old = this.to_vec();
    for (x, (&n, &d)) in this.iter_mut().zip(num.iter().zip(&den)) {
        *x = nonnegative_quotient(n, d);
    }
    for (c, r) in data.off_diagonal.iter().zip(residual.iter_mut()) {
        let (i, j) = at(c);
        *r -= (this[i] - old[i]) * other[j];
    }
}
