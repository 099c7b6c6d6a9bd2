//! Evaluation of the fitting methods: speed against accuracy on given inputs
//! ([`mod@bench`]) and where each method fails on synthetic data with known truth
//! ([`stability`]). Both produce tables (CSV, Markdown) and charts
//! ([`crate::plot::evaluation`]). [`class`] measures the accuracy of the grid fit and the
//! model search on a randomized class of synthetic materials (Markdown, CSV).

pub mod bench;
pub mod class;
pub mod stability;

use crate::fit::{FitOptions, ModelChoice, Solver, Start};

/// A fitting method: a solver with its stopping rules and starting point.
#[derive(Debug, Clone, PartialEq)]
pub struct Method {
    /// Short name for tables and legends (`lbfgs`, `lbfgs-tight`, ...).
    pub name: String,
    /// Solver.
    pub solver: Solver,
    /// Relative tolerance ([`FitOptions::tolerance`]).
    pub tolerance: f64,
    /// Iteration limit.
    pub max_iterations: u64,
    /// Starting point of the iterative solvers.
    pub start: Start,
    /// The spectral model (tabulated, or the parametric search).
    pub model: ModelChoice,
    /// The search's ΔE2000 bound ([`FitOptions::max_delta_e`]).
    pub max_delta_e: Option<f64>,
}

/// The ΔE2000 bound of the benchmark's `search` method.
pub const SEARCH_BOUND: f64 = 1.0;

/// Default tolerance of `fit`.
pub use crate::fit::DEFAULT_TOLERANCE;
/// The tightened tolerance of the "-tight" methods (a thousand times tighter).
pub const TIGHT_TOLERANCE: f64 = 1e-9;
/// Iteration limit of Nelder-Mead: it needs far more (cheap) iterations than the
/// gradient methods, a few hundred per parameter to get anywhere on ~90 parameters.
pub const NELDER_MEAD_ITERATIONS: u64 = 20_000;
/// Iteration limit of the tightened Nelder-Mead.
pub const NELDER_MEAD_TIGHT_ITERATIONS: u64 = 100_000;

impl Method {
    /// A method with the default tolerance and iteration limit of its solver.
    pub fn new(solver: Solver) -> Method {
        Method {
            name: solver.name().to_string(),
            solver,
            tolerance: DEFAULT_TOLERANCE,
            max_iterations: if solver == Solver::NelderMead {
                NELDER_MEAD_ITERATIONS
            } else {
                FitOptions::default().max_iterations
            },
            start: Start::ClosedForm,
            model: ModelChoice::Tabulated,
            max_delta_e: None,
        }
    }

    /// The parametric model search (`fit --max-delta-e bound`): the smallest model
    /// meeting ΔE2000 ≤ `bound` under every light, tabulated start and candidates
    /// included.
    pub fn search(bound: f64) -> Method {
        Method {
            name: "search".to_string(),
            model: ModelChoice::Auto,
            max_delta_e: Some(bound),
            ..Method::new(Solver::Lbfgs)
        }
    }

    /// The same solver with the tightened tolerance (and more iterations for it).
    pub fn tightened(solver: Solver) -> Method {
        let mut m = Method::new(solver);
        m.name = format!("{}-tight", solver.name());
        m.tolerance = TIGHT_TOLERANCE;
        m.max_iterations = if solver == Solver::NelderMead {
            NELDER_MEAD_TIGHT_ITERATIONS
        } else {
            5 * m.max_iterations
        };
        m
    }

    /// Fit options for this method.
    pub fn options(&self) -> FitOptions {
        FitOptions {
            solver: self.solver,
            tolerance: self.tolerance,
            max_iterations: self.max_iterations,
            start: self.start,
            model: self.model,
            max_delta_e: self.max_delta_e,
            ..FitOptions::default()
        }
    }
}

/// Every method `fit` offers, each with default and tightened tolerance (the closed-form
/// estimate has no tolerance and appears once), then the parametric model search with
/// the bound [`SEARCH_BOUND`].
pub fn all_methods() -> Vec<Method> {
    let mut methods = vec![Method::new(Solver::Init)];
    for solver in [Solver::Lbfgs, Solver::GaussNewton, Solver::NelderMead] {
        methods.push(Method::new(solver));
        methods.push(Method::tightened(solver));
    }
    methods.push(Method::search(SEARCH_BOUND));
    methods
}

pub use crate::numeric::{median, quantile};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_interpolate_and_skip_nan() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, f64::NAN, 2.0, 3.0]), 2.5);
        assert_eq!(quantile(&[0.0, 10.0], 0.25), 2.5);
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn every_solver_appears_with_both_tolerances_then_the_search() {
        let methods = all_methods();
        let names: Vec<String> = methods.iter().map(|m| m.name.clone()).collect();
        assert_eq!(
            names,
            [
                "init",
                "lbfgs",
                "lbfgs-tight",
                "gauss-newton",
                "gauss-newton-tight",
                "nelder-mead",
                "nelder-mead-tight",
                "search"
            ]
        );
        // Only the search is parametric, and it asks for the bound.
        for m in &methods {
            let options = m.options();
            let search = m.name == "search";
            assert_eq!(options.model == ModelChoice::Auto, search, "{}", m.name);
            assert_eq!(options.max_delta_e, search.then_some(SEARCH_BOUND));
        }
    }
}
