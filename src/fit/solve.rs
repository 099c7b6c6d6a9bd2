//! Refinement with argmin: L-BFGS (More-Thuente line search) on the objective's
//! gradient, Gauss-Newton (with line search) on its residuals and Jacobian, or
//! Nelder-Mead on the cost alone (no derivatives: the baseline that shows what they buy).

use std::cell::RefCell;
use std::sync::atomic::{AtomicBool, Ordering};

use argmin::core::{CostFunction, Gradient, IterState, Jacobian, Operator, State};
use argmin::solver::gaussnewton::GaussNewtonLS;
use argmin::solver::linesearch::{
    BacktrackingLineSearch, MoreThuenteLineSearch, condition::ArmijoCondition,
};
use argmin::solver::neldermead::NelderMead;
use argmin::solver::quasinewton::LBFGS;
use nalgebra::{DMatrix, DVector};

use crate::optimise::{Refined, Stopping, run};

use super::Solver;
use super::objective::Objective;
use super::representation::{GridSpectra, Representation};

/// A point θ with its cost and θ-gradient.
type Evaluation = (Vec<f64>, f64, Vec<f64>);

/// Residuals r(θ) and their Jacobian ∂r/∂θ: what Gauss-Newton needs of a problem (the
/// tabulated fit of one matrix, the joint fit of a concentration series).
pub trait ResidualModel {
    /// The residual vector at `theta`; the objective is ½‖r‖².
    fn residuals(&self, theta: &[f64]) -> Vec<f64>;
    /// ∂r/∂θ at `theta`, one row per residual.
    fn jacobian(&self, theta: &[f64]) -> DMatrix<f64>;
}

/// The tabulated fit as residuals and their Jacobian.
struct TabulatedResiduals<'a> {
    objective: Objective<'a>,
    representation: &'a dyn Representation,
}

impl ResidualModel for TabulatedResiduals<'_> {
    fn residuals(&self, theta: &[f64]) -> Vec<f64> {
        let sp = self.representation.spectra(theta);
        self.objective.residuals(&sp)
    }

    fn jacobian(&self, theta: &[f64]) -> DMatrix<f64> {
        let sp = self.representation.spectra(theta);
        self.objective.jacobian(&sp) * self.representation.jacobian(theta)
    }
}

/// A residual model with Gauss-Newton's prior, as argmin sees it.
struct ResidualProblem<'a> {
    model: &'a dyn ResidualModel,
    /// Prior rows √μ·(θ − θ₀) for Gauss-Newton: they make JᵀJ invertible along the
    /// model's flat directions (the κ·a scale, samples at a bound) without moving the
    /// optimum more than μ/curvature.
    prior: (f64, Vec<f64>),
}

impl Operator for ResidualProblem<'_> {
    type Param = DVector<f64>;
    type Output = DVector<f64>;
    fn apply(&self, theta: &Self::Param) -> Result<Self::Output, argmin::core::Error> {
        let mut r = self.model.residuals(theta.as_slice());
        let (mu, theta0) = &self.prior;
        r.extend(theta.iter().zip(theta0).map(|(t, t0)| mu.sqrt() * (t - t0)));
        Ok(DVector::from_vec(r))
    }
}

impl Jacobian for ResidualProblem<'_> {
    type Param = DVector<f64>;
    type Jacobian = DMatrix<f64>;
    fn jacobian(&self, theta: &Self::Param) -> Result<Self::Jacobian, argmin::core::Error> {
        let mut j = self.model.jacobian(theta.as_slice());
        let (rows, n) = (j.nrows(), j.ncols());
        j = j.resize_vertically(rows + n, 0.0);
        for k in 0..n {
            j[(rows + k, k)] = self.prior.0.sqrt();
        }
        Ok(j)
    }
}

/// An argmin state over θ, whatever else the solver keeps (gradient, Jacobian, Hessian,
/// residuals).
type ThetaState<G, J, H, R> = IterState<DVector<f64>, G, J, H, R, f64>;

/// The state setup of a solver that starts at `theta0` (all but Nelder-Mead, which
/// starts from its simplex).
fn start_at<G, J, H, R>(
    theta0: &[f64],
    stopping: Stopping,
) -> impl FnOnce(ThetaState<G, J, H, R>) -> ThetaState<G, J, H, R>
where
    ThetaState<G, J, H, R>: State<Float = f64>,
{
    move |state| {
        state
            .param(DVector::from_column_slice(theta0))
            .max_iters(stopping.max_iterations)
    }
}

/// Correction pairs L-BFGS keeps.
const LBFGS_MEMORY: usize = 10;

/// Refines the tabulated fit's `theta0` with an iterative `solver`: L-BFGS and
/// Nelder-Mead on its cost (and gradient), Gauss-Newton on its residuals. The closed-form
/// estimate ([`Solver::Init`]) has nothing to refine here.
pub fn refine_tabulated(
    solver: Solver,
    objective: Objective<'_>,
    representation: &dyn Representation,
    theta0: &[f64],
    stopping: Stopping,
) -> Result<Refined, String> {
    let function = || tabulated_cost_gradient(&objective, representation);
    match solver {
        Solver::Init => Err("the closed-form estimate is not refined iteratively".into()),
        Solver::Lbfgs => lbfgs_function(&function(), theta0, stopping),
        Solver::NelderMead => nelder_mead(&function(), theta0, stopping),
        Solver::GaussNewton => gauss_newton(objective, representation, theta0, stopping),
    }
}

/// The tabulated fit's cost and θ-gradient as a function of θ.
fn tabulated_cost_gradient<'a>(
    objective: &'a Objective<'a>,
    representation: &'a dyn Representation,
) -> impl Fn(&[f64]) -> (f64, Vec<f64>) + 'a {
    move |theta: &[f64]| {
        let sp = representation.spectra(theta);
        let (cost, kappa, absorption, emission) = objective.cost_gradient(&sp);
        let gradient = GridSpectra {
            kappa,
            absorption,
            emission,
        };
        (cost, representation.pull_back(theta, &gradient))
    }
}

/// Refines `theta0` with Gauss-Newton and a backtracking (Armijo) line search.
fn gauss_newton(
    objective: Objective<'_>,
    representation: &dyn Representation,
    theta0: &[f64],
    stopping: Stopping,
) -> Result<Refined, String> {
    let model = TabulatedResiduals {
        objective,
        representation,
    };
    gauss_newton_model(&model, theta0, stopping)
}

/// Minimises ½‖r(θ)‖² of `model` from `theta0` with Gauss-Newton and a backtracking
/// (Armijo) line search; the cost history is in the same units as L-BFGS's (½‖r‖²).
pub fn gauss_newton_model(
    model: &dyn ResidualModel,
    theta0: &[f64],
    stopping: Stopping,
) -> Result<Refined, String> {
    // μ relative to the curvature scale at the start.
    let j0 = model.jacobian(theta0);
    let curvature = j0
        .column_iter()
        .map(|c| c.norm_squared())
        .fold(0.0, f64::max)
        .max(1e-300);
    let problem = ResidualProblem {
        model,
        prior: (1e-10 * curvature, theta0.to_vec()),
    };
    let linesearch =
        BacktrackingLineSearch::new(ArmijoCondition::new(1e-4).map_err(|e| e.to_string())?);
    let solver = GaussNewtonLS::new(linesearch)
        .with_tolerance(stopping.cost_tolerance)
        .map_err(|e| e.to_string())?;
    let mut refined = run(
        problem,
        solver,
        start_at(theta0, stopping),
        theta0,
        "Gauss-Newton",
    )?;
    // GN reports ‖r‖ as its cost; keep the history in the same units as L-BFGS (½‖r‖²).
    refined
        .cost_history
        .iter_mut()
        .for_each(|c| *c = 0.5 * *c * *c);
    Ok(refined)
}

/// Relative size of the initial Nelder-Mead simplex: each vertex moves one parameter by
/// this fraction of its magnitude (at least this much in absolute terms), large enough to
/// leave the start's basin of numerical noise, small enough to stay near the start.
const NELDER_MEAD_STEP: f64 = 0.05;

/// Refines `theta0` with Nelder-Mead, which uses cost values only. It stops when the
/// standard deviation of the simplex's costs falls below the cost tolerance.
fn nelder_mead(
    function: CostGradient<'_>,
    theta0: &[f64],
    stopping: Stopping,
) -> Result<Refined, String> {
    let problem = FunctionProblem::new(function);
    let start = DVector::from_column_slice(theta0);
    let mut simplex = vec![start.clone()];
    for k in 0..theta0.len() {
        let mut vertex = start.clone();
        vertex[k] += NELDER_MEAD_STEP * theta0[k].abs().max(1.0);
        simplex.push(vertex);
    }
    let solver = NelderMead::new(simplex)
        .with_sd_tolerance(stopping.cost_tolerance)
        .map_err(|e| e.to_string())?;
    run(
        problem,
        solver,
        |state| state.max_iters(stopping.max_iterations),
        theta0,
        "Nelder-Mead",
    )
}

/// A cost with its gradient, as a function of the parameters.
pub type CostGradient<'a> = &'a dyn Fn(&[f64]) -> (f64, Vec<f64>);

/// A problem given by a cost-and-gradient function (L-BFGS and Nelder-Mead on the
/// tabulated fit, L-BFGS on the parametric models).
struct FunctionProblem<'a> {
    function: CostGradient<'a>,
    /// The last (θ, cost, θ-gradient): the line search asks for the cost and the gradient
    /// of the same point separately, and one pass computes both.
    cache: RefCell<Option<Evaluation>>,
    /// Set by another thread when this fit's result is no longer wanted: the next
    /// evaluation fails, which ends the run.
    cancel: Option<&'a AtomicBool>,
}

impl<'a> FunctionProblem<'a> {
    fn new(function: CostGradient<'a>) -> Self {
        FunctionProblem {
            function,
            cache: RefCell::new(None),
            cancel: None,
        }
    }

    fn evaluate(&self, theta: &[f64]) -> Result<(f64, Vec<f64>), argmin::core::Error> {
        if self.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(argmin::core::Error::msg(CANCELLED));
        }
        if let Some((t, c, g)) = self.cache.borrow().as_ref()
            && t.as_slice() == theta
        {
            return Ok((*c, g.clone()));
        }
        let (cost, gradient) = (self.function)(theta);
        // The cached point's buffers are reused: two allocations fewer per evaluation.
        let mut cache = self.cache.borrow_mut();
        match cache.as_mut() {
            Some((t, c, g)) => {
                t.clear();
                t.extend_from_slice(theta);
                *c = cost;
                g.clear();
                g.extend_from_slice(&gradient);
            }
            None => *cache = Some((theta.to_vec(), cost, gradient.clone())),
        }
        Ok((cost, gradient))
    }
}

impl CostFunction for FunctionProblem<'_> {
    type Param = DVector<f64>;
    type Output = f64;
    fn cost(&self, theta: &Self::Param) -> Result<f64, argmin::core::Error> {
        Ok(self.evaluate(theta.as_slice())?.0)
    }
}

impl Gradient for FunctionProblem<'_> {
    type Param = DVector<f64>;
    type Gradient = DVector<f64>;
    fn gradient(&self, theta: &Self::Param) -> Result<Self::Gradient, argmin::core::Error> {
        Ok(DVector::from_vec(self.evaluate(theta.as_slice())?.1))
    }
}

/// What a cancelled run's error says.
const CANCELLED: &str = "cancelled: its result was no longer wanted";

/// Minimises `function` from `theta0` with L-BFGS and a More-Thuente line search.
pub fn lbfgs_function(
    function: CostGradient<'_>,
    theta0: &[f64],
    stopping: Stopping,
) -> Result<Refined, String> {
    lbfgs_function_until(function, theta0, stopping, None)
}

/// [`lbfgs_function`], ended at the first evaluation after `cancel` is set (a fit begun
/// ahead of the decision that needs it, which that decision made moot): whenever the flag
/// is set by the time the run returns, the result is an error, never a partial fit.
pub fn lbfgs_function_until(
    function: CostGradient<'_>,
    theta0: &[f64],
    stopping: Stopping,
    cancel: Option<&AtomicBool>,
) -> Result<Refined, String> {
    let problem = FunctionProblem {
        cancel,
        ..FunctionProblem::new(function)
    };
    let solver = LBFGS::new(MoreThuenteLineSearch::new(), LBFGS_MEMORY)
        .with_tolerance_grad(stopping.gradient_tolerance)
        .and_then(|s| s.with_tolerance_cost(stopping.cost_tolerance))
        .map_err(|e| e.to_string())?;
    let refined = run(
        problem,
        solver,
        start_at(theta0, stopping),
        theta0,
        "L-BFGS",
    )?;
    // argmin's L-BFGS ends a run whose line search fails (as the cancelled evaluation
    // makes it) with a termination status, not an error.
    match cancel {
        Some(c) if c.load(Ordering::Relaxed) => Err(CANCELLED.to_string()),
        _ => Ok(refined),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quadratic bowl with its minimum at (1, −2).
    fn bowl(theta: &[f64]) -> (f64, Vec<f64>) {
        let (x, y) = (theta[0] - 1.0, theta[1] + 2.0);
        (x * x + 4.0 * y * y, vec![2.0 * x, 8.0 * y])
    }

    fn stopping() -> Stopping {
        Stopping {
            max_iterations: 100,
            gradient_tolerance: 1e-10,
            cost_tolerance: 0.0,
        }
    }

    #[test]
    fn an_uncancelled_run_reaches_the_minimum() {
        let flag = AtomicBool::new(false);
        let refined = lbfgs_function_until(&bowl, &[5.0, 5.0], stopping(), Some(&flag)).unwrap();
        assert!((refined.theta[0] - 1.0).abs() < 1e-6, "{:?}", refined.theta);
        assert!((refined.theta[1] + 2.0).abs() < 1e-6, "{:?}", refined.theta);
    }

    #[test]
    fn a_cancelled_run_ends_with_an_error_at_its_next_evaluation() {
        let flag = AtomicBool::new(false);
        let evaluations = std::cell::Cell::new(0);
        let counting = |theta: &[f64]| {
            evaluations.set(evaluations.get() + 1);
            if evaluations.get() == 3 {
                flag.store(true, Ordering::Relaxed);
            }
            bowl(theta)
        };
        let error = lbfgs_function_until(&counting, &[5.0, 5.0], stopping(), Some(&flag))
            .expect_err("cancelled");
        assert!(error.contains(CANCELLED), "{error}");
        assert_eq!(evaluations.get(), 3);
    }
}
