//! The closed-form start: a masked non-negative rank-1 factorisation of the off-diagonal
//! cells (alternating least squares, each half-step an exact non-negative least-squares
//! solve), then the diagonal minus the fluorescent term.

use super::data::{Cell, FitData};
use super::dense_nmf::{DenseCells, WeightedRankOne, nonnegative_quotient};

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
    match DenseCells::new(data).filter(|cells| cells.takes(&start.rows, &start.columns)) {
        Some(cells) => {
            let Factors {
                mut rows,
                mut columns,
            } = start;
            cells.sweep(&mut rows, &mut columns, sweeps);
            Factors { rows, columns }
        }
        None => sparse_masked_nmf(data, start, sweeps),
    }
}

/// Non-negative rank-1 fit of the off-diagonal cells with per-cell `weights` (one per
/// cell, in the list's order): alternating weighted least squares, rows then columns,
/// started from the weighted positive column mass. Over the dense layout where that gives
/// the cell walk's bits (the walk was 3 % of a noise-aware search).
pub(super) fn weighted_rank_one(
    data: &FitData,
    weights: &[f64],
    sweeps: usize,
) -> (Vec<f64>, Vec<f64>) {
    let column = positive_column_mass(data, weights);
    DenseCells::new(data)
        .as_ref()
        .and_then(|cells| WeightedRankOne::new(cells, data, weights))
        .and_then(|fit| fit.sweep(column, sweeps))
        .unwrap_or_else(|| weighted_rank_one_by_cells(data, weights, sweeps))
}

/// The start of [`weighted_rank_one`]: Σ_i w·max(v, 0) per column.
fn positive_column_mass(data: &FitData, weights: &[f64]) -> Vec<f64> {
    let mut column = vec![0.0; data.n_emission()];
    for (c, w) in data.off_diagonal.iter().zip(weights) {
        column[c.column] += w * c.value.max(0.0);
    }
    column
}

/// [`weighted_rank_one`] walking the cell list: the reference the dense sweep equals bit
/// for bit, and the path for cells it cannot take.
fn weighted_rank_one_by_cells(
    data: &FitData,
    weights: &[f64],
    sweeps: usize,
) -> (Vec<f64>, Vec<f64>) {
    let (n_ex, n_em) = (data.n_excitation(), data.n_emission());
    let mut column = positive_column_mass(data, weights);
    let mut row = vec![0.0; n_ex];
    for _ in 0..sweeps {
        row = fit_factor(&data.off_diagonal, Some(weights), &column, n_ex, by_row);
        column = fit_factor(&data.off_diagonal, Some(weights), &row, n_em, by_column);
    }
    (row, column)
}

/// [`masked_nmf`] over the cell list as it is ordered: the reference the dense sweep
/// ([`super::dense_nmf`]) equals bit for bit on row-major cells, and the path for any
/// other order.
fn sparse_masked_nmf(data: &FitData, start: Factors, sweeps: usize) -> Factors {
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
    let (num, den) = accumulate(cells, n, &at, |k, c, _, j| {
        let w = weights.map_or(1.0, |w| w[k]);
        (w * c.value * other[j], w * other[j] * other[j])
    });
    num.iter()
        .zip(&den)
        .map(|(&n, &d)| nonnegative_quotient(n, d))
        .collect()
}

/// Σ of `term(k, cell k, i, j)`'s two parts over `cells` into `n` sums each, cell k adding
/// to entry i where (i, j) = `at(cell)`, in cell order. A run of cells with the same i (a
/// row's cells, for the half-step that fits the rows) is summed in registers: the same
/// additions in the same order, without each waiting on the last one's store (the
/// factorisations' half-steps were 8 % of a noise-aware search).
#[inline(always)]
fn accumulate(
    cells: &[Cell],
    n: usize,
    at: &impl Fn(&Cell) -> (usize, usize),
    term: impl Fn(usize, &Cell, usize, usize) -> (f64, f64),
) -> (Vec<f64>, Vec<f64>) {
    let (mut num, mut den) = (vec![0.0; n], vec![0.0; n]);
    let mut run: Option<(usize, f64, f64)> = None;
    for (k, c) in cells.iter().enumerate() {
        let (i, j) = at(c);
        let (a, b) = term(k, c, i, j);
        run = match run {
            Some((at_i, x, y)) if at_i == i => Some((i, x + a, y + b)),
            other => {
                if let Some((done, x, y)) = other {
                    num[done] = x;
                    den[done] = y;
                }
                Some((i, num[i] + a, den[i] + b))
            }
        };
    }
    if let Some((done, x, y)) = run {
        num[done] = x;
        den[done] = y;
    }
    (num, den)
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
    let (num, den) = accumulate(&data.off_diagonal, this.len(), &at, |k, _, i, j| {
        let v = other[j];
        ((residual[k] + this[i] * v) * v, v * v)
    });
    let old = this.to_vec();
    for (x, (&n, &d)) in this.iter_mut().zip(num.iter().zip(&den)) {
        *x = nonnegative_quotient(n, d);
    }
    for (c, r) in data.off_diagonal.iter().zip(residual.iter_mut()) {
        let (i, j) = at(c);
        *r -= (this[i] - old[i]) * other[j];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::numeric::SplitMix64;

    /// Two components on a 13 × 11 grid with a fifth of the cells missing (whole stretches
    /// of some rows, as a guard band leaves them), rows not a multiple of four.
    fn two_dyes_with_holes() -> (FitData, Factors) {
        let (n_ex, n_em) = (13, 11);
        let mut random = SplitMix64::new(7);
        let mut data = FitData {
            excitation_nm: (0..n_ex).map(|i| 300.0 + 10.0 * i as f64).collect(),
            emission_nm: (0..n_em).map(|j| 400.0 + 10.0 * j as f64).collect(),
            off_diagonal: Vec::new(),
            diagonal: Vec::new(),
            diagonal_positions: Vec::new(),
            guard: Vec::new(),
            stokes: Vec::new(),
            anti_stokes: Vec::new(),
            emission_bin_widths: vec![10.0; n_em],
            emission_weight: vec![1.0; n_em],
            guard_nm: 0.0,
            crosstalk: None,
        };
        for row in 0..n_ex {
            for column in 0..n_em {
                if random.uniform() < 0.2 || (row == 5 && column < 6) {
                    continue;
                }
                let a = [
                    (-((row as f64 - 3.0) / 2.5).powi(2)).exp(),
                    (-((row as f64 - 9.0) / 2.0).powi(2)).exp(),
                ];
                let e = [
                    (-((column as f64 - 4.0) / 2.0).powi(2)).exp(),
                    (-((column as f64 - 8.0) / 1.5).powi(2)).exp(),
                ];
                let value = 0.7 * a[0] * e[0] + 0.4 * a[1] * e[1] + 0.01 * (random.uniform() - 0.5);
                data.off_diagonal.push(Cell { row, column, value });
            }
        }
        let start = Factors {
            rows: vec![
                vec![0.5; n_ex],
                (0..n_ex).map(|i| 0.1 + 0.05 * i as f64).collect(),
            ],
            columns: vec![
                vec![0.3; n_em],
                (0..n_em).map(|j| 0.2 + 0.02 * j as f64).collect(),
            ],
        };
        (data, start)
    }

    #[test]
    fn the_dense_sweep_equals_the_cell_walk_bit_for_bit_on_row_major_cells() {
        let (data, start) = two_dyes_with_holes();
        assert!(DenseCells::new(&data).is_some_and(|c| c.takes(&start.rows, &start.columns)));
        let fast = masked_nmf(&data, start.clone(), 40);
        let reference = sparse_masked_nmf(&data, start, 40);
        let bits = |f: &Factors| -> Vec<u64> {
            f.rows
                .iter()
                .chain(&f.columns)
                .flatten()
                .map(|x| x.to_bits())
                .collect()
        };
        assert_eq!(bits(&fast), bits(&reference));
        // The factorisation did move: a test of two copies of the start would pass too.
        assert!(
            fast.rows[1]
                .iter()
                .zip(0..)
                .any(|(x, i)| (x - (0.1 + 0.05 * i as f64)).abs() > 1e-3)
        );
    }

    #[test]
    fn cells_out_of_row_major_order_or_not_finite_take_the_cell_walk() {
        let (mut data, start) = two_dyes_with_holes();
        // Factors of other lengths than the grid's are not the dense sweep's either.
        let cells = DenseCells::new(&data).unwrap();
        assert!(!cells.takes(&start.rows[..1], &start.columns));
        assert!(!cells.takes(&[vec![0.5; 3]], &start.columns[..1]));
        data.off_diagonal.swap(0, 1);
        assert!(DenseCells::new(&data).is_none());
        data.off_diagonal.swap(0, 1);
        data.off_diagonal[3].value = f64::NAN;
        assert!(DenseCells::new(&data).is_none());
    }

    #[test]
    fn the_dense_weighted_rank_one_equals_the_cell_walk_bit_for_bit() {
        let (data, _) = two_dyes_with_holes();
        // Weights of every kind the starts give: zeros (cells another component
        // explains), large and small, on cells with negative values (the noise term).
        let weights: Vec<f64> = data
            .off_diagonal
            .iter()
            .enumerate()
            .map(|(k, c)| match k % 7 {
                0 => 0.0,
                1 => 1e4,
                _ => 1.0 / (c.value.abs() + 0.03).powi(2),
            })
            .collect();
        assert!(data.off_diagonal.iter().any(|c| c.value < 0.0));
        let cells = DenseCells::new(&data).unwrap();
        let column = positive_column_mass(&data, &weights);
        let dense = WeightedRankOne::new(&cells, &data, &weights)
            .and_then(|fit| fit.sweep(column.clone(), 50))
            .expect("finite weights and factors take the dense sweep");
        let reference = weighted_rank_one_by_cells(&data, &weights, 50);
        let bits = |(r, c): &(Vec<f64>, Vec<f64>)| -> Vec<u64> {
            r.iter().chain(c).map(|x| x.to_bits()).collect()
        };
        assert_eq!(bits(&dense), bits(&reference));
        assert_eq!(
            bits(&weighted_rank_one(&data, &weights, 50)),
            bits(&reference)
        );
        // The fit did move from its start, and follows the first dye's rows.
        assert!(
            dense
                .1
                .iter()
                .zip(&column)
                .any(|(a, b)| (a - b).abs() > 1e-6 * b.abs())
        );
        assert!(dense.0[3] > dense.0[12]);
    }

    #[test]
    fn weights_or_factors_that_are_not_finite_take_the_cell_walk() {
        let (data, _) = two_dyes_with_holes();
        let cells = DenseCells::new(&data).unwrap();
        let mut weights = vec![1.0; data.off_diagonal.len()];
        weights[4] = f64::INFINITY;
        assert!(WeightedRankOne::new(&cells, &data, &weights).is_none());
        assert!(WeightedRankOne::new(&cells, &data, &weights[1..]).is_none());
        // A column start that is not finite: a 0·∞ term would be NaN, not the walk's.
        weights[4] = 1.0;
        let fit = WeightedRankOne::new(&cells, &data, &weights).unwrap();
        let mut column = positive_column_mass(&data, &weights);
        column[2] = f64::INFINITY;
        assert!(fit.sweep(column, 5).is_none());
    }
}
