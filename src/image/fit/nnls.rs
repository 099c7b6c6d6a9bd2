//! Non-negative least squares for a handful of unknowns, from the normal equations:
//! minimise ½·cᵀHc − gᵀc subject to c ≥ 0 (Lawson and Hanson's active-set method). Exact,
//! allocation-free and deterministic: what every pixel's concentrations need.

/// Most unknowns [`solve`] takes (the image fit's largest number of fluorophores).
pub const MAX_UNKNOWNS: usize = 8;

/// The non-negative minimiser of ½·cᵀHc − gᵀc; `h` is K×K row-major, symmetric and
/// positive semi-definite, K ≤ [`MAX_UNKNOWNS`]. Columns of H with a zero diagonal stay
/// at zero.
pub fn solve(h: &[f64], g: &[f64]) -> [f64; MAX_UNKNOWNS] {
    let k = g.len();
    debug_assert!(k <= MAX_UNKNOWNS && h.len() == k * k);
    let mut c = [0.0; MAX_UNKNOWNS];
    let mut passive = [false; MAX_UNKNOWNS];
    let scale = g
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    let tolerance = 1e-12 * scale;
    for _ in 0..3 * k + 3 {
        // The most negative gradient among the variables held at zero.
        let mut best = None;
        let mut best_w = tolerance;
        for j in 0..k {
            if passive[j] || h[j * k + j] <= 0.0 {
                continue;
            }
            let w = g[j] - (0..k).map(|i| h[j * k + i] * c[i]).sum::<f64>();
            if w > best_w {
                best_w = w;
                best = Some(j);
            }
        }
        let Some(j) = best else { break };
        passive[j] = true;
        for _ in 0..3 * k + 3 {
            let Some(z) = solve_passive(h, g, &passive, k) else {
                passive[j] = false;
                break;
            };
            if (0..k).all(|i| !passive[i] || z[i] > 0.0) {
                c = z;
                break;
            }
            // Step towards z until the first passive variable reaches zero.
            let mut alpha = 1.0f64;
            for i in 0..k {
                if passive[i] && z[i] <= 0.0 {
                    let denominator = c[i] - z[i];
                    if denominator > 0.0 {
                        alpha = alpha.min(c[i] / denominator);
                    }
                }
            }
            for i in 0..k {
                c[i] += alpha * (z[i] - c[i]);
                if passive[i] && c[i] <= 1e-15 * scale.max(1.0) {
                    passive[i] = false;
                    c[i] = 0.0;
                }
            }
        }
    }
    c
}

/// The unconstrained minimiser over the passive variables (others zero), by Gaussian
/// elimination with partial pivoting; None when that block of H is singular.
fn solve_passive(
    h: &[f64],
    g: &[f64],
    passive: &[bool; MAX_UNKNOWNS],
    k: usize,
) -> Option<[f64; MAX_UNKNOWNS]> {
    let index: Vec<usize> = (0..k).filter(|&i| passive[i]).collect();
    let n = index.len();
    let mut a = [[0.0f64; MAX_UNKNOWNS + 1]; MAX_UNKNOWNS];
    for (r, &i) in index.iter().enumerate() {
        for (c, &j) in index.iter().enumerate() {
            a[r][c] = h[i * k + j];
        }
        a[r][n] = g[i];
    }
    for col in 0..n {
        let pivot = (col..n).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))?;
        if a[pivot][col].abs() <= 1e-300 {
            return None;
        }
        a.swap(col, pivot);
        for r in col + 1..n {
            let f = a[r][col] / a[col][col];
            for c in col..=n {
                a[r][c] -= f * a[col][c];
            }
        }
    }
    let mut x = [0.0; MAX_UNKNOWNS];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|c| a[r][c] * x[c]).sum();
        x[r] = (a[r][n] - s) / a[r][r];
    }
    let mut out = [0.0; MAX_UNKNOWNS];
    for (r, &i) in index.iter().enumerate() {
        out[i] = x[r];
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force over every active set: the exact answer for small problems.
    fn brute(h: &[f64], g: &[f64]) -> Vec<f64> {
        let k = g.len();
        let objective = |c: &[f64]| {
            let mut v = 0.0;
            for i in 0..k {
                v -= g[i] * c[i];
                for j in 0..k {
                    v += 0.5 * c[i] * h[i * k + j] * c[j];
                }
            }
            v
        };
        let mut best = (0.0, vec![0.0; k]);
        for mask in 1u32..(1 << k) {
            let mut passive = [false; MAX_UNKNOWNS];
            for i in 0..k {
                passive[i] = mask & (1 << i) != 0;
            }
            if let Some(z) = solve_passive(h, g, &passive, k) {
                let z: Vec<f64> = z[..k].to_vec();
                if z.iter().all(|&v| v >= 0.0) && objective(&z) < best.0 {
                    best = (objective(&z), z);
                }
            }
        }
        best.1
    }

    #[test]
    fn matches_the_brute_force_answer() {
        let mut rng = crate::numeric::SplitMix64::new(7);
        for _ in 0..500 {
            let k = 1 + (rng.next_u64() % 5) as usize;
            let m = 8;
            let a: Vec<f64> = (0..m * k).map(|_| rng.uniform()).collect();
            let y: Vec<f64> = (0..m).map(|_| rng.normal()).collect();
            let mut h = vec![0.0; k * k];
            let mut g = vec![0.0; k];
            for r in 0..m {
                for i in 0..k {
                    g[i] += a[r * k + i] * y[r];
                    for j in 0..k {
                        h[i * k + j] += a[r * k + i] * a[r * k + j];
                    }
                }
            }
            let c = solve(&h, &g);
            let expected = brute(&h, &g);
            for i in 0..k {
                assert!((c[i] - expected[i]).abs() < 1e-9, "{c:?} vs {expected:?}");
            }
        }
    }
}
