//! Levenberg-Marquardt for the small least-squares problems of the band and sigmoid
//! fits (a handful of parameters, tens of samples: a dense solve per step).

use argmin::core::{IterState, KV, Problem, Solver, State, TerminationReason, TerminationStatus};
use nalgebra::{DMatrix, DVector};

use crate::numeric::dot;
use crate::optimise::Stopping;

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

/// A borrowed problem is the same problem (the runner takes its problem by value).
impl<T: LeastSquares> LeastSquares for &T {
    fn residual_count(&self) -> usize {
        (**self).residual_count()
    }
    fn evaluate(&self, params: &[f64], residuals: &mut [f64], jacobian: Option<&mut [f64]>) {
        (**self).evaluate(params, residuals, jacobian)
    }
    fn bounds(&self, j: usize) -> (f64, f64) {
        (**self).bounds(j)
    }
    fn project(&self, params: &mut [f64]) {
        (**self).project(params)
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

/// The state argmin keeps for [`LevenbergMarquardt`]: parameters and Σ r².
type LmState = IterState<DVector<f64>, (), (), (), (), f64>;

/// Levenberg–Marquardt with Marquardt's diagonal scaling and Nielsen's damping update, as
/// an argmin [`Solver`] on a [`LeastSquares`] problem. One argmin iteration is one linear
/// solve (accepted or not). It converges when an accepted step gains less than
/// `stop_gain` times the cost, and stops when the damping shows no step can gain.
struct LevenbergMarquardt {
    stop_gain: f64,
    work: Workspace,
    trial: Vec<f64>,
    /// Σ r² at the current parameters.
    current: f64,
    damping: f64,
    growth: f64,
    stopped: Option<TerminationReason>,
}

impl LevenbergMarquardt {
    fn new(residual_count: usize, parameter_count: usize, stop_gain: f64) -> Self {
        LevenbergMarquardt {
            stop_gain,
            work: Workspace::new(residual_count, parameter_count),
            trial: vec![0.0; parameter_count],
            current: f64::NAN,
            damping: 1e-3,
            growth: 2.0,
            stopped: None,
        }
    }

    /// One linear solve from `params` (updated when the step is accepted).
    fn step(&mut self, problem: &impl LeastSquares, params: &mut [f64]) {
        let n = params.len();
        if self.current.is_nan() || self.current <= 0.0 {
            self.stopped = Some(TerminationReason::SolverExit(
                "the cost is zero or not a number".into(),
            ));
            return;
        }
        let work = &mut self.work;
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
        let damping = self.damping;
        let system = DMatrix::from_fn(n, n, |j, k| {
            if frozen[j] || frozen[k] {
                return if j == k { 1.0 } else { 0.0 };
            }
            let v = jtj[j.min(k) * n + j.max(k)];
            if j == k { v + damping * scale[j] } else { v }
        });
        let Some(cholesky) = system.cholesky() else {
            self.damping *= self.growth;
            self.growth *= 2.0;
            return;
        };
        let gradient = (0..n).map(|j| if frozen[j] { 0.0 } else { -work.jtr[j] });
        let step = cholesky.solve(&DVector::from_iterator(n, gradient));
        // Predicted gain of the linearised model: δᵀ(λDδ − Jᵀr), doubled for Σ r².
        let predicted: f64 = (0..n)
            .filter(|&j| !frozen[j])
            .map(|j| step[j] * (damping * scale[j] * step[j] - work.jtr[j]))
            .sum();
        for ((t, p), s) in self.trial.iter_mut().zip(params.iter()).zip(step.iter()) {
            *t = p + s;
        }
        problem.project(&mut self.trial);
        let next = work.evaluate_trial(problem, &self.trial);
        if next < self.current {
            let gain = self.current - next;
            params.copy_from_slice(&self.trial);
            work.accept_trial();
            self.current = next;
            let ratio = if predicted > 0.0 {
                gain / predicted
            } else {
                1.0
            };
            self.damping *= (1.0 - (2.0 * ratio - 1.0).powi(3)).max(1.0 / 3.0);
            self.growth = 2.0;
            if gain <= self.stop_gain * next {
                self.stopped = Some(TerminationReason::SolverConverged);
            }
        } else {
            self.damping *= self.growth;
            self.growth *= 2.0;
            if self.damping > 1e16 {
                self.stopped = Some(TerminationReason::SolverExit(
                    "no step lowers the cost".into(),
                ));
            }
        }
    }
}

impl<P: LeastSquares> Solver<P, LmState> for LevenbergMarquardt {
    fn name(&self) -> &str {
        "Levenberg-Marquardt"
    }

    fn init(
        &mut self,
        problem: &mut Problem<P>,
        state: LmState,
    ) -> Result<(LmState, Option<KV>), argmin::core::Error> {
        let params = state
            .get_param()
            .cloned()
            .ok_or_else(|| argmin::core::Error::msg("Levenberg-Marquardt needs a start"))?;
        let work = &mut self.work;
        self.current = problem.problem("residuals", |p| {
            Ok(work.evaluate_trial(p, params.as_slice()))
        })?;
        work.accept_trial();
        if params.is_empty() {
            self.stopped = Some(TerminationReason::SolverConverged);
        }
        Ok((state.param(params).cost(self.current), None))
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<P>,
        mut state: LmState,
    ) -> Result<(LmState, Option<KV>), argmin::core::Error> {
        let mut params = state
            .take_param()
            .ok_or_else(|| argmin::core::Error::msg("Levenberg-Marquardt lost its parameters"))?;
        problem.problem("residuals", |p| {
            self.step(p, params.as_mut_slice());
            Ok(())
        })?;
        Ok((state.param(params).cost(self.current), None))
    }

    fn terminate(&mut self, _state: &LmState) -> TerminationStatus {
        match &self.stopped {
            Some(reason) => TerminationStatus::Terminated(reason.clone()),
            None => TerminationStatus::NotTerminated,
        }
    }
}

/// Minimises Σ r² from `params` (updated in place) by [`LevenbergMarquardt`] through the
/// one optimiser runner ([`crate::optimise::run`]); returns the final Σ r². Stops when a
/// step gains less than `stopping.cost_tolerance` times the cost, when the damping shows
/// no step can gain, or after `stopping.max_iterations` linear solves.
pub(super) fn levenberg_marquardt(
    problem: &impl LeastSquares,
    params: &mut [f64],
    stopping: Stopping,
) -> f64 {
    let solver = LevenbergMarquardt::new(
        problem.residual_count(),
        params.len(),
        stopping.cost_tolerance,
    );
    let max_iterations = stopping.max_iterations;
    let start = DVector::from_column_slice(params);
    // The solver reports a bad start (NaN cost) as its own stop, so the runner fails only
    // on argmin's internal errors; the start is then kept.
    let refined = crate::optimise::run(
        problem,
        solver,
        |state: LmState| state.param(start).max_iters(max_iterations),
        params,
        "Levenberg-Marquardt",
    );
    if let Ok(refined) = &refined {
        params.copy_from_slice(&refined.theta);
        // The cost recorded after the last iteration is the current point's: the solver
        // moves only to lower costs.
        if let Some(&cost) = refined.cost_history.last() {
            return cost;
        }
    }
    let mut residuals = vec![0.0; problem.residual_count()];
    problem.evaluate(params, &mut residuals, None);
    residuals.iter().map(|r| r * r).sum()
}

/// How a fit stops: when a step gains less than 1e-10 of the cost (parameters are then
/// settled far below any spectrum's measurement noise), after at most 200 linear solves
/// (each fit converges in far fewer on spectra).
pub(super) const STOPPING: Stopping = Stopping {
    max_iterations: 200,
    gradient_tolerance: 0.0,
    cost_tolerance: 1e-10,
};

/// How a fit that only seeds the next band count stops: at a relative gain of 1e-4 (the
/// next band's start hardly depends on the last digits).
pub(super) const SEED_STOPPING: Stopping = Stopping {
    cost_tolerance: 1e-4,
    ..STOPPING
};
