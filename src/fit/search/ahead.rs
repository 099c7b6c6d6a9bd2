//! Fitting ahead: the next structure's energy form refined beside this structure's photon
//! form.
//!
//! With `--yield auto` a structure's photon form starts from its energy form's optimum, and
//! the next structure's energy form starts from energy-form fits only (its one-component
//! parent, the smaller models it contains), so the two need not wait for each other. Run
//! side by side they fill the second core the photon form leaves idle. Whether the search
//! stops at this structure (so that the next is never needed) is known once the photon
//! form is fitted, and the fit ahead is then cancelled; otherwise the search takes its
//! result as it would have fitted it, the same to the last bit (its starts are refined
//! and compared in a fixed order, and what they share is memoised by value).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use super::adequacy::{GridReference, Verdict, judge};
use super::candidate::{CandidateContext, choose_between, fit_candidate};
use super::{Fitted, ModelSpec};
use crate::error::Result;
use crate::fit::data::FitData;
use crate::material::YieldForm;
use crate::measurement::Measurement;

/// The next structure's energy form, fitted ahead of the decision that needs it.
pub(super) struct Ahead {
    /// The candidate fitted.
    pub(super) spec: ModelSpec,
    /// Its fit.
    pub(super) result: Result<Fitted>,
    /// Its wall time in seconds.
    pub(super) seconds: f64,
}

/// `fit` with its wall time in seconds.
pub(super) fn timed(fit: impl FnOnce() -> Result<Fitted>) -> (Result<Fitted>, f64) {
    let started = Instant::now();
    let result = fit();
    (result, started.elapsed().as_secs_f64())
}

/// Fits `spec` (a structure's photon form, from its `energy_twin`) and, beside it, `next`
/// (the next structure's energy form). `stops` tells from the photon form's fit whether
/// the search stops at this structure; if so the fit of `next` is cancelled and not
/// returned.
pub(super) fn fit_beside(
    ctx: &CandidateContext<'_>,
    spec: ModelSpec,
    energy_twin: Option<&Fitted>,
    next: ModelSpec,
    fitted: &[Fitted],
    stops: &(dyn Fn(&Result<Fitted>) -> bool + Sync),
) -> ((Result<Fitted>, f64), Option<Ahead>) {
    let cancel = AtomicBool::new(false);
    let ahead_ctx = CandidateContext {
        cancel: Some(&cancel),
        ..*ctx
    };
    let (this, later) = rayon::join(
        || {
            let this = timed(|| fit_candidate(ctx, spec, fitted, energy_twin));
            if stops(&this.0) {
                cancel.store(true, Ordering::Relaxed);
            }
            this
        },
        || timed(|| fit_candidate(&ahead_ctx, next, fitted, None)),
    );
    let later = (!cancel.load(Ordering::Relaxed)).then_some(Ahead {
        spec: next,
        result: later.0,
        seconds: later.1,
    });
    (this, later)
}

/// Whether the search stops at a structure whose yield forms were fitted as `energy` and
/// `photon`: where [`choose_between`] picks one (`auto_form` as the search's), unless the
/// matrix test, where one is given (the grid reference, the measurement, its cells and
/// σ), sends the search on.
pub(super) fn stops_at(
    energy: Option<&Fitted>,
    photon: Option<&Fitted>,
    auto_form: bool,
    matrix_test: Option<(&GridReference, &Measurement, &FitData, f64)>,
) -> bool {
    let pick = match choose_between(energy, photon, auto_form) {
        Some((YieldForm::Energy, _)) => energy,
        Some((YieldForm::Photon, _)) => photon,
        None => None,
    };
    let Some(pick) = pick else {
        return false;
    };
    match matrix_test {
        None => true,
        Some((grid, m, data, sigma)) => {
            !matches!(judge(pick, grid, m, data, sigma), Verdict::LookFurther(_))
        }
    }
}
