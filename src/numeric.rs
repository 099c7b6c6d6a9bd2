//! Small numeric helpers at the ground floor, used by every layer above: dot products,
//! medians and quantiles, a grid's typical step.

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

/// The median spacing |g_k+1 − g_k| of a grid (0 for a single sample).
pub fn median_step(grid: &[f64]) -> f64 {
    let steps: Vec<f64> = grid.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    if steps.is_empty() {
        0.0
    } else {
        median(&steps)
    }
}
