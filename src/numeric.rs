//! Small numeric helpers at the ground floor, used by every layer above: dot products,
//! medians and quantiles, a grid's typical step, a reproducible random generator.

/// The median of `values` (NaN when empty; NaNs are ignored).
pub fn median(values: &[f64]) -> f64 {
    quantile(values, 0.5)
}

/// The `q`-quantile of the finite `values`, linearly interpolated (NaN when none).
pub fn quantile(values: &[f64], q: f64) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    v[lo] + (v[hi] - v[lo]) * (pos - lo as f64)
}

/// Σ a_k·b_k with four partial sums, so the reduction vectorises (a single running sum
/// fixes the order of the additions and stays scalar).
#[inline(always)]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut partial = [0.0; 4];
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in a4.zip(b4) {
        for k in 0..4 {
            partial[k] += x[k] * y[k];
        }
    }
    partial.iter().sum::<f64>() + tail
}

/// Σ_j m_ij·v_j for each row i of the row-major `matrix` (rows as long as `v`) into
/// `out`. Each row's sum runs in column order from 0, as a running sum does (the same
/// bits), and several rows advance together, so the additions of one row no longer wait
/// on each other.
#[inline(always)]
pub fn row_dots(matrix: &[f64], v: &[f64], out: &mut [f64]) {
    row_sums(matrix, v.len(), out, |row, j| row[j] * v[j]);
}

/// Σ_j m_ij² for each row i of the row-major `matrix` (rows of `n`) into `out`, each row
/// in column order as in [`row_dots`].
#[inline(always)]
pub fn row_squares(matrix: &[f64], n: usize, out: &mut [f64]) {
    row_sums(matrix, n, out, |row, j| row[j] * row[j]);
}

/// Σ_j term(row_i, j) for each row of `n` of `matrix`: eight rows at a time, then four,
/// then one. One row's sum is a chain of dependent additions; four rows in one vector
/// still waited on that chain, eight keep two vectors' chains in flight (perf annotate
/// on the parametric objective).
#[inline(always)]
fn row_sums(matrix: &[f64], n: usize, out: &mut [f64], term: impl Fn(&[f64], usize) -> f64) {
    if n == 0 {
        out.iter_mut().for_each(|o| *o = 0.0);
        return;
    }
    let mut rows = matrix.chunks_exact(n);
    let mut octets = out.chunks_exact_mut(8);
    for octet in octets.by_ref() {
        let (Some(r0), Some(r1), Some(r2), Some(r3), Some(r4), Some(r5), Some(r6), Some(r7)) = (
            rows.next(),
            rows.next(),
            rows.next(),
            rows.next(),
            rows.next(),
            rows.next(),
            rows.next(),
            rows.next(),
        ) else {
            return;
        };
        let (mut s, mut t) = ([0.0; 4], [0.0; 4]);
        for j in 0..n {
            s[0] += term(r0, j);
            s[1] += term(r1, j);
            s[2] += term(r2, j);
            s[3] += term(r3, j);
            t[0] += term(r4, j);
            t[1] += term(r5, j);
            t[2] += term(r6, j);
            t[3] += term(r7, j);
        }
        octet[..4].copy_from_slice(&s);
        octet[4..].copy_from_slice(&t);
    }
    let mut quads = octets.into_remainder().chunks_exact_mut(4);
    for quad in quads.by_ref() {
        let (Some(r0), Some(r1), Some(r2), Some(r3)) =
            (rows.next(), rows.next(), rows.next(), rows.next())
        else {
            return;
        };
        let mut s = [0.0; 4];
        for j in 0..n {
            s[0] += term(r0, j);
            s[1] += term(r1, j);
            s[2] += term(r2, j);
            s[3] += term(r3, j);
        }
        quad.copy_from_slice(&s);
    }
    for (o, row) in quads.into_remainder().iter_mut().zip(rows) {
        let mut s = 0.0;
        for j in 0..n {
            s += term(row, j);
        }
        *o = s;
    }
}

/// `n` zeros, allocated through `malloc` and filled: `vec![0.0; n]` asks for zeroed
/// memory, and glibc's `calloc` bypasses its thread cache (callgrind: ~360 instructions a
/// call against ~60 for `malloc` and the fill, on the grid objective's small buffers).
#[inline]
pub fn zeros(n: usize) -> Vec<f64> {
    let mut v = Vec::with_capacity(n);
    v.resize(n, 0.0);
    v
}

/// The median spacing |g_k+1 − g_k| of a grid (0 for a single sample).
pub fn median_step(grid: &[f64]) -> f64 {
    let steps: Vec<f64> = grid.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    if steps.is_empty() {
        0.0
    } else {
        median(&steps)
    }
}

/// A small, fast, reproducible random generator (SplitMix64). Synthetic data and the
/// fit's noise bootstrap must be identical across platforms and crate versions, which a
/// fixed generator guarantees.
#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box-Muller).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform();
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_sums_are_each_rows_running_sum_bit_for_bit() {
        // 39 rows (four blocks of eight, one of four and a remainder of three) of values
        // whose sums round differently in another order.
        let (rows, n) = (39, 13);
        let matrix: Vec<f64> = (0..rows * n)
            .map(|k| ((k * 7919 % 101) as f64 - 50.0) * 10f64.powi((k % 9) as i32 - 4))
            .collect();
        let v: Vec<f64> = (0..n).map(|j| 1.0 / (j as f64 + 0.3)).collect();
        let (mut dots, mut squares) = (vec![f64::NAN; rows], vec![f64::NAN; rows]);
        row_dots(&matrix, &v, &mut dots);
        row_squares(&matrix, n, &mut squares);
        for (i, row) in matrix.chunks_exact(n).enumerate() {
            let (mut dot, mut square) = (0.0, 0.0);
            for j in 0..n {
                dot += row[j] * v[j];
                square += row[j] * row[j];
            }
            assert_eq!(dots[i].to_bits(), dot.to_bits(), "row {i}");
            assert_eq!(squares[i].to_bits(), square.to_bits(), "row {i}");
        }
        assert_eq!(matrix.chunks_exact(n).count(), rows);
    }
}
