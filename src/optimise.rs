//! The one optimiser runner: every iterative solve of a model to a matrix or a spectrum in
//! fluorite (the tabulated and parametric fits, the concentration series, the 1-D band
//! fits) runs through [`run`], which builds the argmin executor, records the cost after
//! every iteration and reads the result back as a [`Refined`]; each is given one
//! [`Stopping`] rule. Solvers are argmin's, or fluorite's own argmin
//! [`Solver`](argmin::core::Solver)s (the Levenberg-Marquardt of [`crate::parametric`]).
//! The joint PARAFAC of EEM sets ([`crate::fit::joint::parafac`]) is the one exception:
//! its sweeps are closed-form non-negative least-squares updates of whole factor matrices
//! with an extrapolation step, not the iterates of a solver argmin runs, so it keeps its
//! own loop and its own relative-loss tolerance.

use std::sync::{Arc, Mutex};

use argmin::core::observers::{Observe, ObserverMode};
use argmin::core::{Executor, KV, State, TerminationReason, TerminationStatus};
use nalgebra::DVector;

/// When a solve stops: the one rule type every solver is given (L-BFGS reads both
/// tolerances; Gauss-Newton, Nelder-Mead and Levenberg-Marquardt the cost change).
#[derive(Debug, Clone, Copy)]
pub struct Stopping {
    /// Iteration limit.
    pub max_iterations: u64,
    /// Gradient-norm tolerance (L-BFGS), relative to the data's scale.
    pub gradient_tolerance: f64,
    /// Cost-change tolerance, relative to the data's scale (Levenberg-Marquardt: the
    /// relative cost gain of a step).
    pub cost_tolerance: f64,
}

/// What a refinement run produced.
#[derive(Debug, Clone)]
pub struct Refined {
    /// Best parameters found.
    pub theta: Vec<f64>,
    /// Iterations performed.
    pub iterations: u64,
    /// Whether the solver met its convergence test (not the iteration limit).
    pub converged: bool,
    /// Why the solver stopped, in words.
    pub termination: String,
    /// Objective ½‖r‖² after each iteration.
    pub cost_history: Vec<f64>,
}

/// Records the cost after every iteration.
#[derive(Clone, Default)]
struct CostRecorder(Arc<Mutex<Vec<f64>>>);

impl<I: State<Float = f64>> Observe<I> for CostRecorder {
    fn observe_iter(&mut self, state: &I, _kv: &KV) -> Result<(), argmin::core::Error> {
        if let Ok(mut h) = self.0.lock() {
            h.push(state.get_cost());
        }
        Ok(())
    }
}

fn finish<I: State<Float = f64, Param = DVector<f64>>>(
    state: &I,
    history: CostRecorder,
    fallback: &[f64],
) -> Refined {
    let theta = state
        .get_best_param()
        .map(|p| p.as_slice().to_vec())
        .unwrap_or_else(|| fallback.to_vec());
    let status = state.get_termination_status();
    let converged = matches!(
        status,
        TerminationStatus::Terminated(TerminationReason::SolverConverged)
    );
    let termination = match status {
        TerminationStatus::Terminated(reason) => reason.text().to_string(),
        TerminationStatus::NotTerminated => "not terminated".to_string(),
    };
    let cost_history = history.0.lock().map(|h| h.clone()).unwrap_or_default();
    Refined {
        theta,
        iterations: state.get_iter(),
        converged,
        termination,
        cost_history,
    }
}

/// Runs `solver` on `problem`, the one place fluorite builds an argmin executor: the
/// state is set up by `configure` (start, iteration limit), the cost recorded after every
/// iteration, and the result read back as a [`Refined`] (`theta0` if no best point).
pub fn run<O, S, I>(
    problem: O,
    solver: S,
    configure: impl FnOnce(I) -> I,
    theta0: &[f64],
    name: &str,
) -> Result<Refined, String>
where
    S: argmin::core::Solver<O, I>,
    I: State<Float = f64, Param = DVector<f64>>,
{
    let recorder = CostRecorder::default();
    let result = Executor::new(problem, solver)
        .configure(configure)
        // No per-iteration clock: nothing reads it, and it is a measurable share of the
        // small band fits' iterations.
        .timer(false)
        .add_observer(recorder.clone(), ObserverMode::Always)
        .run()
        .map_err(|e| format!("{name}: {e}"))?;
    Ok(finish(&result.state, recorder, theta0))
}
