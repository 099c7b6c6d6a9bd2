//! The sigmoid-polynomial reflectance fitted to samples ([`fit_sigmoid_polynomial`]):
//! a linear fit of the logit to start, refined by Levenberg–Marquardt on the true
//! residual.

use nalgebra::{DMatrix, DVector};

use super::lm::{LeastSquares, STOPPING, levenberg_marquardt};
use super::{SigmoidPolynomial, check_samples, legendre, logit, position, sigmoid};
use crate::error::{Error, Result};

/// A sigmoid-polynomial reflectance fitted to samples.
#[derive(Debug, Clone, PartialEq)]
pub struct SigmoidFit {
    /// The form; its support is [first, last] sample wavelength.
    pub form: SigmoidPolynomial,
    /// Root mean square of fit − data over the samples, weighted by the weights when
    /// given (√(Σ wᵢ rᵢ² / Σ wᵢ)).
    pub rms: f64,
}

/// Fits a sigmoid of a degree-`degree` Legendre series to reflectance `values` sampled at
/// `nm` (strictly increasing), minimising Σ wᵢ (fit − value)² with `weights` (default 1).
///
/// Values are expected in about [0, 1] and may hold noise slightly outside. The start is
/// a weighted linear fit of the logit of the values (clamped into (0, 1)), which the
/// Levenberg–Marquardt refinement then corrects on the true residual. Fails when the
/// samples or weights are unusable or fewer samples have positive weight than the series
/// has coefficients (degree + 1).
pub fn fit_sigmoid_polynomial(
    nm: &[f64],
    values: &[f64],
    weights: Option<&[f64]>,
    degree: usize,
) -> Result<SigmoidFit> {
    let count = degree.checked_add(1).ok_or_else(|| {
        Error::invalid(
            "degree",
            "is too large; use a degree below the sample count",
        )
    })?;
    check_samples(nm, values, 1)?;
    let weights: Vec<f64> = match weights {
        None => vec![1.0; nm.len()],
        Some(w) => {
            if w.len() != nm.len() {
                return Err(Error::invalid(
                    "weights",
                    format!(
                        "has {} entries but there are {} samples; give one weight per sample",
                        w.len(),
                        nm.len()
                    ),
                ));
            }
            if let Some(i) = w.iter().position(|w| !(w.is_finite() && *w >= 0.0)) {
                return Err(Error::invalid(
                    format!("weights[{i}]"),
                    format!("is {}; weights must be finite and non-negative", w[i]),
                ));
            }
            w.to_vec()
        }
    };
    let weighted = weights.iter().filter(|&&w| w > 0.0).count();
    if weighted < count {
        return Err(Error::invalid(
            "degree",
            format!(
                "is {degree}, which needs at least {count} samples of positive weight, but there are {weighted}; lower the degree or give more samples"
            ),
        ));
    }
    let total_weight: f64 = weights.iter().sum();
    if !total_weight.is_finite() {
        return Err(Error::invalid(
            "weights",
            "sum beyond floating point; rescale them (only their ratios matter)",
        ));
    }
    // Normalised weights keep the solver's scale independent of the caller's.
    let root_weight: Vec<f64> = weights.iter().map(|w| (w / total_weight).sqrt()).collect();
    if root_weight.iter().any(|w| !w.is_finite()) {
        return Err(Error::invalid(
            "weights",
            "span too many orders of magnitude; rescale them",
        ));
    }
    let support_nm = [nm[0], nm[nm.len() - 1]];
    let mut basis = Vec::with_capacity(nm.len() * count);
    for &l in nm {
        legendre(position(support_nm, l), count, |_, p| basis.push(p));
    }
    let mut coefficients = logit_start(&basis, values, &weights, count);
    let problem = SigmoidProblem {
        basis: &basis,
        values,
        root_weight: &root_weight,
        count,
    };
    let cost = levenberg_marquardt(&problem, &mut coefficients, STOPPING);
    if !(cost.is_finite() && coefficients.iter().all(|c| c.is_finite())) {
        return Err(Error::Fit(
            "the reflectance fit diverged (non-finite coefficients); check that the values are a reflectance in about [0, 1]"
                .into(),
        ));
    }
    Ok(SigmoidFit {
        form: SigmoidPolynomial {
            support_nm,
            coefficients,
        },
        // The residuals carry the normalised weights, so the cost is the weighted mean.
        rms: cost.sqrt(),
    })
}

/// A reflectance fit: residual √wᵢ (σ(Σⱼ cⱼ Pⱼ(xᵢ)) − vᵢ) with normalised weights.
struct SigmoidProblem<'a> {
    /// Pⱼ(xᵢ), row-major with `count` columns.
    basis: &'a [f64],
    values: &'a [f64],
    root_weight: &'a [f64],
    count: usize,
}

impl LeastSquares for SigmoidProblem<'_> {
    fn residual_count(&self) -> usize {
        self.values.len()
    }

    fn evaluate(&self, params: &[f64], residuals: &mut [f64], mut jacobian: Option<&mut [f64]>) {
        let count = self.count;
        for (i, r) in residuals.iter_mut().enumerate() {
            let row = &self.basis[i * count..(i + 1) * count];
            let p: f64 = row.iter().zip(params).map(|(b, c)| b * c).sum();
            let s = sigmoid(p);
            let w = self.root_weight[i];
            *r = w * (s - self.values[i]);
            if let Some(jacobian) = jacobian.as_deref_mut() {
                let slope = w * s * (1.0 - s);
                for (j, b) in row.iter().enumerate() {
                    jacobian[j * self.values.len() + i] = slope * b;
                }
            }
        }
    }
}

/// Coefficients of the weighted linear least-squares fit of logit(values) on the basis.
/// Each sample is weighted by σ'² at its value, the linearisation of the true residual,
/// so that values near 0 or 1 (where the logit is unreliable) count little.
fn logit_start(basis: &[f64], values: &[f64], weights: &[f64], count: usize) -> Vec<f64> {
    let mut a = DMatrix::<f64>::zeros(count, count);
    let mut b = DVector::<f64>::zeros(count);
    let (mut sum_w, mut sum_wv) = (0.0, 0.0);
    for (i, (&v, &w)) in values.iter().zip(weights).enumerate() {
        let clamped = v.clamp(1e-4, 1.0 - 1e-4);
        let slope = clamped * (1.0 - clamped);
        let omega = w * slope * slope;
        let target = logit(clamped);
        let row = &basis[i * count..(i + 1) * count];
        for j in 0..count {
            b[j] += omega * row[j] * target;
            for k in 0..count {
                a[(j, k)] += omega * row[j] * row[k];
            }
        }
        sum_w += w;
        sum_wv += w * v;
    }
    let scale = (0..count).map(|j| a[(j, j)]).fold(0.0, f64::max);
    for j in 0..count {
        a[(j, j)] += 1e-12 * scale;
    }
    match a.cholesky() {
        Some(c) if scale > 0.0 => {
            let x = c.solve(&b);
            if x.iter().all(|v| v.is_finite()) {
                return x.iter().copied().collect();
            }
            flat_start(sum_wv / sum_w, count)
        }
        _ => flat_start(sum_wv / sum_w, count),
    }
}

/// A constant reflectance at `mean` as Legendre coefficients.
fn flat_start(mean: f64, count: usize) -> Vec<f64> {
    let mut c = vec![0.0; count];
    c[0] = logit(if mean.is_finite() { mean } else { 0.5 });
    c
}
