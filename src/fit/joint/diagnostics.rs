//! What users of drEEM and staRdom judge a PARAFAC model by: core consistency
//! (CORCONDIA, Bro & Kiers 2003), split-half validation with Tucker congruence, and the
//! squared correlation ([`r_squared`]) that [`super::reference`] uses to match scores to
//! known concentrations.

use serde::{Deserialize, Serialize};

use super::parafac::image::Image;
use super::parafac::{Factors, ParafacOptions, Tensor, fit_with_image};
use crate::error::Result;

/// Tucker's congruence coefficient of two loadings: u·v / (|u|·|v|) (0 when one is 0).
pub fn congruence(u: &[f64], v: &[f64]) -> f64 {
    let uv = crate::numeric::dot(u, v);
    let uu = crate::numeric::dot(u, u);
    let vv = crate::numeric::dot(v, v);
    if uu > 0.0 && vv > 0.0 {
        uv / (uu * vv).sqrt()
    } else {
        0.0
    }
}

/// Squared Pearson correlation of `x` and `y` (NaN when either is constant).
pub fn r_squared(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len()) as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx) * (a - mx);
        syy += (b - my) * (b - my);
    }
    sxy * sxy / (sxx * syy)
}

/// Core consistency in per cent (Bro & Kiers 2003): the least-squares Tucker3 core of
/// the data given the CP loadings, compared with the superdiagonal core a CP model
/// implies: 100·(1 − Σ(G − T)² / K). Near 100: the data are trilinear with these K
/// components; low or negative: too many components. Cells not measured are filled with
/// the model (the data cannot speak there).
pub fn core_consistency(t: &Tensor, f: &Factors) -> f64 {
    let k = f.k;
    let (samples, n_ex, n_em) = (t.samples, t.n_ex, t.n_em);
    let pinv = |rows: usize, get: &dyn Fn(usize, usize) -> f64| -> Option<nalgebra::DMatrix<f64>> {
        nalgebra::DMatrix::from_fn(rows, k, get)
            .pseudo_inverse(1e-12)
            .ok()
    };
    let (Some(a), Some(x), Some(e)) = (
        pinv(samples, &|s, c| f.scores[s * k + c]),
        pinv(n_ex, &|j, c| f.excitation[c * n_ex + j]),
        pinv(n_em, &|i, c| f.emission[c * n_em + i]),
    ) else {
        return f64::NAN;
    };
    // y[(s·n_ex + ex)·K + q] = Σ_em X·E⁺[q, em].
    let mut y = vec![0.0; samples * n_ex * k];
    for s in 0..samples {
        for ex in 0..n_ex {
            for em in 0..n_em {
                let v = t.values[t.index(s, ex, em)];
                let v = if v.is_finite() {
                    v
                } else {
                    f.model(t, s, ex, em)
                };
                for q in 0..k {
                    y[(s * n_ex + ex) * k + q] += v * e[(q, em)];
                }
            }
        }
    }
    let mut core = vec![0.0; k * k * k];
    for s in 0..samples {
        for ex in 0..n_ex {
            for q in 0..k {
                let yq = y[(s * n_ex + ex) * k + q];
                for r in 0..k {
                    let z = yq * x[(r, ex)];
                    for p in 0..k {
                        core[(p * k + q) * k + r] += a[(p, s)] * z;
                    }
                }
            }
        }
    }
    let mut misfit = 0.0;
    for p in 0..k {
        for q in 0..k {
            for r in 0..k {
                let target = if p == q && q == r { 1.0 } else { 0.0 };
                misfit += (core[(p * k + q) * k + r] - target).powi(2);
            }
        }
    }
    100.0 * (1.0 - misfit / k as f64)
}

/// One matched pair of components of the two halves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MatchedPair {
    /// Component of the first half.
    pub first: usize,
    /// Component of the second half.
    pub second: usize,
    /// Tucker congruence of their excitation loadings.
    pub excitation_congruence: f64,
    /// Tucker congruence of their emission loadings.
    pub emission_congruence: f64,
}

/// Split-half validation: the samples split into two halves (alternating, as listed),
/// each half fitted alone, components matched between halves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SplitHalf {
    /// How the samples were split, in words.
    pub split: String,
    /// The matched components (ordered by the first half's components).
    pub pairs: Vec<MatchedPair>,
    /// The smallest congruence of any matched pair in either mode.
    pub min_congruence: f64,
    /// Whether every matched pair reaches [`VALIDATION_CONGRUENCE`] in both modes.
    pub validated: bool,
}

/// Tucker congruence both modes of every matched pair must reach for a model to count
/// as validated (drEEM's and staRdom's usual criterion).
pub const VALIDATION_CONGRUENCE: f64 = 0.95;

/// Fits both halves of `t` (samples 0, 2, 4, … and 1, 3, 5, …) with `options` and
/// matches their components; `None` with fewer than two samples per half. With the
/// grating's second-order `image`, each half is fitted with it, as the whole set was, and
/// the halves' first-order emissions are compared (each half fits its own gain).
pub fn split_half(
    t: &Tensor,
    em_weights: &[f64],
    options: &ParafacOptions,
    image: Option<&Image>,
) -> Result<Option<SplitHalf>> {
    if t.samples < 4 {
        return Ok(None);
    }
    let k = options.components;
    let half = |samples: &[usize]| -> Result<Factors> {
        let model = fit_with_image(&t.subset(samples), em_weights, options, image)?;
        let mut factors = model.factors;
        if let (Some(image), Some(g)) = (image, &model.image_gain) {
            let gain = image.gain(g);
            for c in 0..k {
                let range = c * t.n_em..(c + 1) * t.n_em;
                let first_order = image.first_order(&factors.emission[range.clone()], &gain);
                factors.emission[range].copy_from_slice(&first_order);
            }
        }
        Ok(factors)
    };
    let even: Vec<usize> = (0..t.samples).step_by(2).collect();
    let odd: Vec<usize> = (1..t.samples).step_by(2).collect();
    let first = half(&even)?;
    let second = half(&odd)?;
    let pair = |a: usize, b: usize| MatchedPair {
        first: a,
        second: b,
        excitation_congruence: congruence(
            &first.excitation[a * t.n_ex..(a + 1) * t.n_ex],
            &second.excitation[b * t.n_ex..(b + 1) * t.n_ex],
        ),
        emission_congruence: congruence(
            &first.emission[a * t.n_em..(a + 1) * t.n_em],
            &second.emission[b * t.n_em..(b + 1) * t.n_em],
        ),
    };
    let similarity: Vec<f64> = (0..k * k)
        .map(|ab| {
            let p = pair(ab / k, ab % k);
            p.excitation_congruence * p.emission_congruence
        })
        .collect();
    let assignment = best_assignment(&similarity, k);
    let pairs: Vec<MatchedPair> = assignment
        .iter()
        .enumerate()
        .map(|(a, &b)| pair(a, b))
        .collect();
    let min_congruence = pairs
        .iter()
        .map(|p| p.excitation_congruence.min(p.emission_congruence))
        .fold(f64::INFINITY, f64::min);
    Ok(Some(SplitHalf {
        split: format!(
            "alternating: half 1 = samples 1, 3, 5, … ({}), half 2 = samples 2, 4, 6, … ({}) in the order given",
            even.len(),
            odd.len()
        ),
        pairs,
        min_congruence,
        validated: min_congruence >= VALIDATION_CONGRUENCE,
    }))
}

/// Permutation `p` maximising Σ_a similarity[a·K + p[a]]: exhaustive up to 7
/// components, greedy (best remaining pair first) above.
fn best_assignment(similarity: &[f64], k: usize) -> Vec<usize> {
    if k > 7 {
        let mut assigned = vec![usize::MAX; k];
        let mut taken = vec![false; k];
        let mut order: Vec<usize> = (0..k * k).collect();
        order.sort_by(|&x, &y| similarity[y].total_cmp(&similarity[x]));
        for ab in order {
            let (a, b) = (ab / k, ab % k);
            if assigned[a] == usize::MAX && !taken[b] {
                assigned[a] = b;
                taken[b] = true;
            }
        }
        return assigned;
    }
    fn search(
        a: usize,
        k: usize,
        similarity: &[f64],
        current: &mut Vec<usize>,
        taken: &mut [bool],
        best: &mut (f64, Vec<usize>),
        score: f64,
    ) {
        if a == k {
            if score > best.0 {
                *best = (score, current.clone());
            }
            return;
        }
        for b in 0..k {
            if !taken[b] {
                taken[b] = true;
                current.push(b);
                let s = score + similarity[a * k + b];
                search(a + 1, k, similarity, current, taken, best, s);
                current.pop();
                taken[b] = false;
            }
        }
    }
    let mut best = (f64::NEG_INFINITY, (0..k).collect());
    search(
        0,
        k,
        similarity,
        &mut Vec::new(),
        &mut vec![false; k],
        &mut best,
        0.0,
    );
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn congruence_and_r_squared_of_known_vectors() {
        assert!((congruence(&[1.0, 0.0], &[1.0, 1.0]) - 0.5f64.sqrt()).abs() < 1e-12);
        // y = 2x + 1 exactly: R² = 1.
        assert!((r_squared(&[1.0, 2.0, 3.0], &[3.0, 5.0, 7.0]) - 1.0).abs() < 1e-12);
        // Anti-diagonal similarity: the best assignment swaps.
        assert_eq!(best_assignment(&[0.1, 0.9, 0.8, 0.2], 2), vec![1, 0]);
    }
}
