//! Unit tests of the PARAFAC iterations.

use super::*;

/// Exact rank-2 non-negative data with a hole: the fit reproduces every cell.
#[test]
fn exact_low_rank_data_are_reproduced() {
    let (samples, n_ex, n_em) = (5, 6, 30);
    let ex = |k: usize, j: usize| (-((j as f64 - 1.5 - 3.0 * k as f64).powi(2)) / 2.0).exp();
    let em = |k: usize, i: usize| (-((i as f64 - 8.0 - 12.0 * k as f64).powi(2)) / 18.0).exp();
    let score = |s: usize, k: usize| 1.0 + ((s * 7 + k * 3) % 5) as f64;
    let mut values = Vec::new();
    for s in 0..samples {
        for j in 0..n_ex {
            for i in 0..n_em {
                let v: f64 = (0..2).map(|k| score(s, k) * ex(k, j) * em(k, i)).sum();
                values.push(if i == j + 3 || (s == 1 && i == 20) {
                    f64::NAN
                } else {
                    v
                });
            }
        }
    }
    let t = Tensor {
        samples,
        n_ex,
        n_em,
        values: values.clone(),
    };
    let weights = vec![1.0; n_em];
    let options = ParafacOptions {
        components: 2,
        tolerance: 1e-12,
        max_iterations: 5000,
    };
    let fit = fit(&t, &weights, &options).unwrap();
    let total: f64 = values.iter().filter(|v| v.is_finite()).map(|v| v * v).sum();
    assert!(fit.loss / total < 1e-8, "{} {}", fit.loss, total);
}
