//! The masked factorisation's sweeps over a dense matrix: the same half-steps as
//! [`super::init::masked_nmf`]'s walk over the cell list, bit for bit, in loops that
//! vectorise.
//!
//! Each half-step sums, per factor entry, terms over that entry's cells in cell order.
//! Over whole rows with a 0/1 mask, a missing cell adds 0 × (a finite term), a zero
//! that leaves the sum as it was (the sums start at +0 and never become −0), and a
//! present cell adds 1 × term, the term itself; so a row-major cell list gives the same
//! additions in the same order (for finite factors, which non-negative quotients of
//! finite sums keep). The factorisation of a model search's split start took
//! 5–8 % of a noise-aware search walking the list, whose row half-steps wait on each
//! addition's store and whose column half-steps scatter.

use super::data::FitData;

/// The off-diagonal cells as a dense row-major mask and values.
pub(super) struct DenseCells {
    n_em: usize,
    /// 1 where a cell is fitted, 0 elsewhere.
    mask: Vec<f64>,
    /// The measured values (0 outside the cells).
    value: Vec<f64>,
}

impl DenseCells {
    /// The dense cells of `data`, or `None` where a dense sweep would not equal the
    /// list's: cells not strictly row-major (sorted by row, then column, each once) or
    /// values that are not finite.
    pub(super) fn new(data: &FitData) -> Option<Self> {
        let (n_ex, n_em) = (data.n_excitation(), data.n_emission());
        let cells = &data.off_diagonal;
        let row_major = cells
            .windows(2)
            .all(|w| (w[0].row, w[0].column) < (w[1].row, w[1].column));
        let in_grid = cells
            .iter()
            .all(|c| c.row < n_ex && c.column < n_em && c.value.is_finite());
        if n_ex == 0 || n_em == 0 || !(row_major && in_grid) {
            return None;
        }
        let mut mask = vec![0.0; n_ex * n_em];
        let mut value = vec![0.0; n_ex * n_em];
        for c in cells {
            mask[c.row * n_em + c.column] = 1.0;
            value[c.row * n_em + c.column] = c.value;
        }
        Some(DenseCells { n_em, mask, value })
    }

    /// Whether factors `rows` and `columns` (per component) fit these cells' grid, as
    /// [`DenseCells::sweep`] needs.
    pub(super) fn takes(&self, rows: &[Vec<f64>], columns: &[Vec<f64>]) -> bool {
        let n_ex = self.mask.len() / self.n_em;
        rows.len() == columns.len()
            && rows.iter().all(|r| r.len() == n_ex)
            && columns.iter().all(|c| c.len() == self.n_em)
    }

    /// `sweeps` sweeps of [`super::init::masked_nmf`] on the factors `rows` and
    /// `columns` (per component, of lengths [`DenseCells::takes`] accepts).
    pub(super) fn sweep(&self, rows: &mut [Vec<f64>], columns: &mut [Vec<f64>], sweeps: usize) {
        let n_em = self.n_em;
        // The residual of every component, as the list walk computes it per cell (0
        // outside the cells, where the mask keeps it).
        let mut residual: Vec<f64> = self
            .value
            .iter()
            .zip(&self.mask)
            .enumerate()
            .map(|(p, (v, mask))| {
                if *mask == 0.0 {
                    return 0.0;
                }
                let (i, j) = (p / n_em, p % n_em);
                v - (0..rows.len())
                    .map(|k| rows[k][i] * columns[k][j])
                    .sum::<f64>()
            })
            .collect();
        for _ in 0..sweeps {
            for k in 0..rows.len() {
                self.refit_rows(&mut residual, &mut rows[k], &columns[k]);
                self.refit_columns(&mut residual, &mut columns[k], &rows[k]);
            }
        }
    }

    /// The half-step that refits row factor `this` given column factor `other`: per row,
    /// Σ_j (r + this_i·v_j)·v_j over Σ_j v_j² on its cells, four rows at a time (one
    /// row's sum is a chain of dependent additions).
    fn refit_rows(&self, residual: &mut [f64], this: &mut [f64], other: &[f64]) {
        let n_em = self.n_em;
        let squares: Vec<f64> = other.iter().map(|v| v * v).collect();
        let mut num = vec![0.0; this.len()];
        let mut den = vec![0.0; this.len()];
        let mut rows = residual
            .chunks_exact(n_em)
            .zip(self.mask.chunks_exact(n_em));
        let mut at = 0;
        for (num4, den4) in num.chunks_exact_mut(4).zip(den.chunks_exact_mut(4)) {
            let (Some((r0, m0)), Some((r1, m1)), Some((r2, m2)), Some((r3, m3))) =
                (rows.next(), rows.next(), rows.next(), rows.next())
            else {
                return;
            };
            let t = [this[at], this[at + 1], this[at + 2], this[at + 3]];
            let (mut n, mut d) = ([0.0; 4], [0.0; 4]);
            for j in 0..n_em {
                let v = other[j];
                n[0] += m0[j] * ((r0[j] + t[0] * v) * v);
                n[1] += m1[j] * ((r1[j] + t[1] * v) * v);
                n[2] += m2[j] * ((r2[j] + t[2] * v) * v);
                n[3] += m3[j] * ((r3[j] + t[3] * v) * v);
                d[0] += m0[j] * squares[j];
                d[1] += m1[j] * squares[j];
                d[2] += m2[j] * squares[j];
                d[3] += m3[j] * squares[j];
            }
            num4.copy_from_slice(&n);
            den4.copy_from_slice(&d);
            at += 4;
        }
        for (i, (r, m)) in rows.enumerate() {
            let i = at + i;
            let (mut n, mut d) = (0.0, 0.0);
            for j in 0..n_em {
                let v = other[j];
                n += m[j] * ((r[j] + this[i] * v) * v);
                d += m[j] * squares[j];
            }
            num[i] = n;
            den[i] = d;
        }
        for (i, (r, m)) in residual
            .chunks_exact_mut(n_em)
            .zip(self.mask.chunks_exact(n_em))
            .enumerate()
        {
            let old = this[i];
            this[i] = nonnegative_quotient(num[i], den[i]);
            let change = this[i] - old;
            for ((r, m), v) in r.iter_mut().zip(m).zip(other) {
                *r -= m * (change * v);
            }
        }
    }

    /// The half-step that refits column factor `this` given row factor `other`: per
    /// column, the sums over its cells in row order, every column advancing together.
    fn refit_columns(&self, residual: &mut [f64], this: &mut [f64], other: &[f64]) {
        let n_em = self.n_em;
        let mut num = vec![0.0; n_em];
        let mut den = vec![0.0; n_em];
        for ((r, m), &v) in residual
            .chunks_exact(n_em)
            .zip(self.mask.chunks_exact(n_em))
            .zip(other)
        {
            let square = v * v;
            for j in 0..n_em {
                num[j] += m[j] * ((r[j] + this[j] * v) * v);
                den[j] += m[j] * square;
            }
        }
        let old = this.to_vec();
        for (x, (&n, &d)) in this.iter_mut().zip(num.iter().zip(&den)) {
            *x = nonnegative_quotient(n, d);
        }
        for ((r, m), &v) in residual
            .chunks_exact_mut(n_em)
            .zip(self.mask.chunks_exact(n_em))
            .zip(other)
        {
            for j in 0..n_em {
                r[j] -= m[j] * ((this[j] - old[j]) * v);
            }
        }
    }
}

/// A non-negative rank-1 fit of the cells with per-cell weights, by alternating weighted
/// least squares: the same half-steps as the model search's list walk
/// ([`super::init::fit_factor`] with weights), bit for bit, over the dense layout. A
/// missing cell has weight 0 and value 0, so its terms (0·0)·x and (0·x)·x are zeros
/// that leave each sum as it was, for finite x: where a weight or a factor entry is not
/// finite, `None`, and the caller walks the list.
pub(super) struct WeightedRankOne<'a> {
    cells: &'a DenseCells,
    /// The weights laid out as the cells are (0 outside them).
    weight: Vec<f64>,
}

impl<'a> WeightedRankOne<'a> {
    /// The fit of `cells` (from [`DenseCells::new`] on `data`) with `weights`, one per
    /// cell of `data` in its order; `None` where their count differs or one is not
    /// finite.
    pub(super) fn new(cells: &'a DenseCells, data: &FitData, weights: &[f64]) -> Option<Self> {
        let n_em = cells.n_em;
        if weights.len() != data.off_diagonal.len() || weights.iter().any(|w| !w.is_finite()) {
            return None;
        }
        let mut weight = vec![0.0; cells.mask.len()];
        for (c, w) in data.off_diagonal.iter().zip(weights) {
            weight[c.row * n_em + c.column] = *w;
        }
        Some(WeightedRankOne { cells, weight })
    }

    /// `sweeps` sweeps (rows, then columns) from column factor `column`: the row and
    /// column factors, or `None` where an entry stops being finite.
    pub(super) fn sweep(
        &self,
        mut column: Vec<f64>,
        sweeps: usize,
    ) -> Option<(Vec<f64>, Vec<f64>)> {
        let n_em = self.cells.n_em;
        let n_ex = self.weight.len() / n_em;
        // Each factor is checked before the other is fitted from it: a 0·∞ term is NaN,
        // and a NaN quotient would come back as 0 (`f64::max`), not as the list's value.
        let finite = |x: &[f64]| x.iter().all(|x| x.is_finite());
        let mut row = vec![0.0; n_ex];
        if !finite(&column) {
            return None;
        }
        for _ in 0..sweeps {
            row = self.refit_rows(&column);
            if !finite(&row) {
                return None;
            }
            column = self.refit_columns(&row);
            if !finite(&column) {
                return None;
            }
        }
        Some((row, column))
    }

    /// Per row, Σ_j (w·v)·c_j over Σ_j (w·c_j)·c_j, four rows at a time (one row's sum is
    /// a chain of dependent additions).
    fn refit_rows(&self, column: &[f64]) -> Vec<f64> {
        let n_em = self.cells.n_em;
        let (weights, values) = (&self.weight, &self.cells.value);
        let mut out = Vec::with_capacity(weights.len() / n_em);
        let block = 4 * n_em;
        for (w4, v4) in weights.chunks_exact(block).zip(values.chunks_exact(block)) {
            let w: [&[f64]; 4] = std::array::from_fn(|t| &w4[t * n_em..(t + 1) * n_em]);
            let v: [&[f64]; 4] = std::array::from_fn(|t| &v4[t * n_em..(t + 1) * n_em]);
            let (mut n, mut d) = ([0.0; 4], [0.0; 4]);
            for (j, &c) in column.iter().enumerate() {
                for t in 0..4 {
                    n[t] += w[t][j] * v[t][j] * c;
                    d[t] += w[t][j] * c * c;
                }
            }
            out.extend((0..4).map(|t| nonnegative_quotient(n[t], d[t])));
        }
        // The rows left over (fewer than four), one at a time.
        let done = out.len();
        for (w, v) in weights
            .chunks_exact(n_em)
            .zip(values.chunks_exact(n_em))
            .skip(done)
        {
            let (mut n, mut d) = (0.0, 0.0);
            for (j, &c) in column.iter().enumerate() {
                n += w[j] * v[j] * c;
                d += w[j] * c * c;
            }
            out.push(nonnegative_quotient(n, d));
        }
        out
    }

    /// Per column, Σ_i (w·v)·r_i over Σ_i (w·r_i)·r_i in row order, every column
    /// advancing together.
    fn refit_columns(&self, row: &[f64]) -> Vec<f64> {
        let n_em = self.cells.n_em;
        let (mut num, mut den) = (vec![0.0; n_em], vec![0.0; n_em]);
        for ((w, v), &r) in self
            .weight
            .chunks_exact(n_em)
            .zip(self.cells.value.chunks_exact(n_em))
            .zip(row)
        {
            for j in 0..n_em {
                num[j] += w[j] * v[j] * r;
                den[j] += w[j] * r * r;
            }
        }
        num.iter()
            .zip(&den)
            .map(|(&n, &d)| nonnegative_quotient(n, d))
            .collect()
    }
}

/// The exact non-negative least-squares solution num/den of one factor entry, 0 where no
/// cell constrains it (the dense sweep's and the cell walk's).
pub(super) fn nonnegative_quotient(num: f64, den: f64) -> f64 {
    if den > 0.0 { (num / den).max(0.0) } else { 0.0 }
}
