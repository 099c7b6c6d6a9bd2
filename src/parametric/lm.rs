//! Levenberg-Marquardt for the small least-squares problems of the band and sigmoid
//! fits (a handful of parameters, tens of samples: a dense solve per step).

use nalgebra::{DMatrix, DVector};

use crate::numeric::dot;

/// A nonlinear least-squares problem: minimise Σᵢ rᵢ(p)².
pub(super) trait LeastSquares {
    /// The number of residuals.
    fn residual_count(&self) -> usize;
    /// Writes the residuals at `params` and, when asked, the Jacobian ∂rᵢ/∂pⱼ by columns:
    /// the derivatives by parameter j of all m residuals are at [j·m, (j + 1)·m).
    fn evaluate(&self, params: &[f64], residuals: &mut [f64], jacobian: Option<&mut [f64]>);
    /// The interval parameter `j` must lie in (default: unbounded).
    fn bounds(&self, _j: usize) -> (f64, f64) {
        (f64::NEG_INFINITY, f64::INFINITY)
    }
    /// Moves `params` into their bounds.
    fn project(&self, params: &mut [f64]) {
        for (j, p) in params.iter_mut().enumerate() {
            let (lower, upper) = self.bounds(j);
            // NaN stays NaN and is rejected by the solver's cost comparison.
            *p = p.clamp(lower, upper);
        }
    }
}

/// The solver's buffers: residuals and Jacobian at the current point and at the trial
/// point, and the normal equations JᵀJ, Jᵀr at the current point.
pub(super) struct Workspace {
    residuals: Vec<f64>,
    jacobian: Vec<f64>,
    trial_residuals: Vec<f64>,
    trial_jacobian: Vec<f64>,
    jtj: Vec<f64>,
    jtr: Vec<f64>,
}

impl Workspace {
    pub(super) fn new(m: usize, n: usize) -> Self {
        Workspace {
            residuals: vec![0.0; m],
            jacobian: vec![0.0; m * n],
            trial_residuals: vec![0.0; m],
            trial_jacobian: vec![0.0; m * n],
            jtj: vec![0.0; n * n],
            jtr: vec![0.0; n],
        }
    }

    /// Σ r² at the trial point `params`, keeping its Jacobian: most trials are accepted,
    /// and the Jacobian costs little beside the residuals' exponentials.
    pub(super) fn evaluate_trial(&mut self, problem: &impl LeastSquares, params: &[f64]) -> f64 {
        problem.evaluate(
            params,
            &mut self.trial_residuals,
            Some(&mut self.trial_jacobian),
        );
        self.trial_residuals.iter().map(|r| r * r).sum()
    }

    /// Makes the trial point current and forms its normal equations.
    pub(super) fn accept_trial(&mut self) {
        std::mem::swap(&mut self.residuals, &mut self.trial_residuals);
        std::mem::swap(&mut self.jacobian, &mut self.trial_jacobian);
        self.form_normal_equations();
    }

    /// JᵀJ (upper triangle, row-major) and Jᵀr of the current point, as dot products of
    /// the Jacobian's contiguous columns.
    pub(super) fn form_normal_equations(&mut self) {
        let n = self.jtr.len();
        let m = self.residuals.len();
        let column = |j: usize| &self.jacobian[j * m..(j + 1) * m];
        for j in 0..n {
            self.jtr[j] = dot(column(j), &self.residuals);
            for k in j..n {
                self.jtj[j * n + k] = dot(column(j), column(k));
            }
        }
    }
}

/// Minimises Σ r² from `params` (updated in place) by Levenberg–Marquardt with
/// Marquardt's diagonal scaling and Nielsen's damping update; returns the final Σ r².
/// Stops when a step gains less than `stop_gain` times the cost, when the damping shows
/// no step can gain, or after `max_iterations` linear solves.
pub(super) fn levenberg_marquardt(
    problem: &impl LeastSquares,
    params: &mut [f64],
    stop_gain: f64,
    max_iterations: usize,
) -> f64 {
    let n = params.len();
    let mut work = Workspace::new(problem.residual_count(), n);
    let mut current = work.evaluate_trial(problem, params);
    if n == 0 {
        return current;
    }
    work.accept_trial();
    let mut trial = params.to_vec();
    let mut damping = 1e-3;
    let mut growth = 2.0;
    for _ in 0..max_iterations {
        if current.is_nan() || current <= 0.0 {
            break;
        }
        let jtj = &work.jtj;
        // A parameter on a bound that the gradient pushes outwards stays there: solving
        // for it anyway would have every step clipped and the solver crawl along the
        // bound.
        let frozen: Vec<bool> = (0..n)
            .map(|j| {
                let (lower, upper) = problem.bounds(j);
                (params[j] <= lower && work.jtr[j] > 0.0)
                    || (params[j] >= upper && work.jtr[j] < 0.0)
            })
            .collect();
        let largest = (0..n).map(|j| jtj[j * n + j]).fold(0.0, f64::max);
        let floor = 1e-12 * largest + f64::MIN_POSITIVE;
        let scale: Vec<f64> = (0..n).map(|j| jtj[j * n + j].max(floor)).collect();
        let system = DMatrix::from_fn(n, n, |j, k| {
            if frozen[j] || frozen[k] {
                return if j == k { 1.0 } else { 0.0 };
            }
            let v = jtj[j.min(k) * n + j.max(k)];
            if j == k { v + damping * scale[j] } else { v }
        });
        let Some(cholesky) = system.cholesky() else {
            damping *= growth;
            growth *= 2.0;
            continue;
        };
        let gradient = (0..n).map(|j| if frozen[j] { 0.0 } else { -work.jtr[j] });
        let step = cholesky.solve(&DVector::from_iterator(n, gradient));
        // Predicted gain of the linearised model: δᵀ(λDδ − Jᵀr), doubled for Σ r².
        let predicted: f64 = (0..n)
            .filter(|&j| !frozen[j])
            .map(|j| step[j] * (damping * scale[j] * step[j] - work.jtr[j]))
            .sum();
        for ((t, p), s) in trial.iter_mut().zip(params.iter()).zip(step.iter()) {
            *t = p + s;
        }
        problem.project(&mut trial);
        let next = work.evaluate_trial(problem, &trial);
        if next < current {
            let gain = current - next;
            params.copy_from_slice(&trial);
            work.accept_trial();
            current = next;
            let ratio = if predicted > 0.0 {
                gain / predicted
            } else {
                1.0
            };
            damping *= (1.0 - (2.0 * ratio - 1.0).powi(3)).max(1.0 / 3.0);
            growth = 2.0;
            if gain <= stop_gain * next {
                break;
            }
        } else {
            damping *= growth;
            growth *= 2.0;
            if damping > 1e16 {
                break;
            }
        }
    }
    current
}

/// The relative cost gain below which a fit stops: parameters are then settled far below
/// any spectrum's measurement noise.
pub(super) const STOP_GAIN: f64 = 1e-10;

/// The relative cost gain below which a fit that only seeds the next band count stops:
/// the next band's start hardly depends on the last digits.
pub(super) const SEED_STOP_GAIN: f64 = 1e-4;
