//! One candidate of the search: fitted from its starts (the smaller model it contains
//! included), its yield form chosen, its material built and judged.

use super::*;
use rayon::prelude::*;
use std::cell::RefCell;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};

/// Whether the energy form's photon law binds in `material` and may cost fit: for some
/// fluorophore it alone sets the smallest feasible c (Q at λmin/λ̄e < 1), and either c
/// cannot grow (its feasible interval has collapsed onto its upper bound, c = 1 or
/// r = 1) or the energy form `misses` the bound. The photon form, whose smallest c is k
/// and whose energy yield follows λi, may then fit better.
pub(super) fn photon_law_binds(material: &Material, misses: bool) -> bool {
    material.fluorophores.iter().any(|f| {
        let photon_limited = f.yield_form == YieldForm::Energy
            && f.max_photon_yield().is_some_and(|p| p >= 1.0 - 1e-6)
            && f.shortest_absorbed_nm()
                .is_some_and(|l| l < f.emission_mean_nm());
        let pinned = f
            .concentration_range
            .is_none_or(|[lo, hi]| hi - lo <= BINDING_SLACK);
        photon_limited && (pinned || misses)
    })
}

/// The yield forms a search fits: the model name's, else `--yield`'s; and whether that is
/// `auto`, which fits the energy form and, where its photon law binds, the photon form too.
pub(super) fn yield_forms(options: &FitOptions) -> (Vec<YieldForm>, bool) {
    match (options.model, options.yield_choice) {
        (
            ModelChoice::Fixed(ModelRequest {
                yield_form: Some(form),
                ..
            }),
            _,
        ) => (vec![form], false),
        (_, YieldChoice::Energy) => (vec![YieldForm::Energy], false),
        (_, YieldChoice::Photon) => (vec![YieldForm::Photon], false),
        (_, YieldChoice::Auto) => (vec![YieldForm::Energy, YieldForm::Photon], true),
    }
}

/// The choice among one structure's yield forms (`here`, indices into `fitted`): the
/// energy form when it meets the bound (every light within its own) and the photon form
/// does not fit better (a lower objective), else the photon form when it meets it.
/// Returns the index and why.
pub(super) fn choose_form(
    fitted: &[Fitted],
    here: &[usize],
    auto_form: bool,
) -> Option<(usize, String)> {
    let of_form = |form: YieldForm| {
        here.iter()
            .copied()
            .find(|&i| fitted[i].spec.yield_form == form)
    };
    let (energy, photon) = (of_form(YieldForm::Energy), of_form(YieldForm::Photon));
    let (form, why) = choose_between(
        energy.map(|i| &fitted[i]),
        photon.map(|i| &fitted[i]),
        auto_form,
    )?;
    Some((
        if form == YieldForm::Energy {
            energy?
        } else {
            photon?
        },
        why,
    ))
}

/// [`choose_form`] between one structure's `energy` and `photon` fits: which form, and
/// why.
pub(super) fn choose_between(
    energy: Option<&Fitted>,
    photon: Option<&Fitted>,
    auto_form: bool,
) -> Option<(YieldForm, String)> {
    let meets = |f: &Fitted| f.within;
    let describe = |f: &Fitted| format!("{} {:.2}", f.spec.name(), f.worst);
    match (energy, photon) {
        (Some(e), Some(p)) if meets(p) && (!meets(e) || p.cost < e.cost) => Some((
            YieldForm::Photon,
            if meets(e) {
                format!(
                    "photon form: the energy form's photon law binds (it sets c_min, and c is pinned or the energy form misses) and the photon form fits better (objective {:.4e} vs {:.4e}; worst ΔE2000 {} vs {})",
                    p.cost,
                    e.cost,
                    describe(p),
                    describe(e)
                )
            } else {
                format!(
                    "photon form: the energy form's photon law binds (it sets c_min, and c is pinned or the energy form misses) and only the photon form meets the bound (worst ΔE2000 {} vs {})",
                    describe(p),
                    describe(e)
                )
            },
        )),
        (Some(e), photon) if meets(e) => Some((
            YieldForm::Energy,
            match (photon, auto_form) {
                (Some(p), _) => format!(
                    "energy form: its photon law binds, but the photon form fits no better (objective {:.4e} vs {:.4e})",
                    p.cost, e.cost
                ),
                (None, true) => {
                    "energy form (the paper's constant Q): its photon law does not bind".into()
                }
                (None, false) => "energy form, as asked".into(),
            },
        )),
        (None, Some(p)) if meets(p) => Some((YieldForm::Photon, "photon form, as asked".into())),
        _ => None,
    }
}

/// What every candidate fit of one search shares.
#[derive(Clone, Copy)]
pub(super) struct CandidateContext<'a> {
    pub(super) m: &'a Measurement,
    pub(super) base: &'a Material,
    pub(super) data: &'a FitData,
    pub(super) options: &'a FitOptions,
    pub(super) reference: &'a [crate::colour::Xyz],
    pub(super) sigma: f64,
    pub(super) focus: &'a [f64],
    pub(super) tolerance: f64,
    /// Per light, the ΔE2000 a candidate must stay within to meet the bound.
    pub(super) light_bounds: &'a BTreeMap<String, f64>,
    /// Per light, its share of the colour weight (empty: 1 each).
    pub(super) light_weights: &'a [f64],
    /// Whether K > 1 candidates also start as if there were no one-component parent
    /// (the parent and split starts from the grid fit alone): where the search fits its
    /// one-component parent only as a start, that parent may be the worse start.
    pub(super) parentless_starts_too: bool,
    /// What the search's starts share, each computed once.
    pub(super) start_cache: &'a StartCache,
    /// Whether the search runs its fits in parallel: a candidate's starts, and the next
    /// structure's energy form beside this one's photon form (`ahead`). Set when the
    /// search itself runs outside a rayon pool, and kept inside the joins it makes; not
    /// inside a caller's pool (the class sweep, batches, images), where the outer loop
    /// already fills the cores, and a nested join would steal other fits' work into this
    /// one's time (the class's per-case search median 4.6 → 6.0 ms, its total unchanged).
    pub(super) parallel: bool,
    /// Set when the candidate's result is no longer wanted (it was begun ahead of the
    /// decision that needs it): its refinements stop at their next evaluation.
    pub(super) cancel: Option<&'a AtomicBool>,
}

impl CandidateContext<'_> {
    /// Whether this candidate's result is no longer wanted.
    fn cancelled(&self) -> bool {
        self.cancel.is_some_and(|c| c.load(Ordering::Relaxed))
    }
}

/// Whether `big` contains `small`: the same axis, yield form and reflectance kind, and no
/// more components, bands or reflectance degree (with the extra parts at zero it is
/// `small`).
pub(super) fn contains(big: &ModelSpec, small: &ModelSpec) -> bool {
    big != small
        && big.domain == small.domain
        && big.yield_form == small.yield_form
        && small.components <= big.components
        && small.absorption_bands <= big.absorption_bands
        && small.emission_bands <= big.emission_bands
        && match (small.reflectance, big.reflectance) {
            (ReflectanceForm::Tabulated, ReflectanceForm::Tabulated) => true,
            (ReflectanceForm::Polynomial(a), ReflectanceForm::Polynomial(b)) => a <= b,
            _ => false,
        }
}

/// Fits one candidate from every start that applies and keeps the lowest objective: the
/// grid fit (and, for K > 1, the one-component parent plus a small component, a fresh
/// split), the optimum of the best smaller model it contains (extra bands and
/// components small), that optimum embedded exactly (extra parts at zero, so the
/// candidate never ends above the model it contains), and, for the photon form, the
/// energy form's optimum of the same structure.
pub(super) fn fit_candidate(
    ctx: &CandidateContext<'_>,
    spec: ModelSpec,
    fitted: &[Fitted],
    energy_twin: Option<&Fitted>,
) -> Result<Fitted> {
    let data = ctx.data;
    let options = ctx.options;
    let problem = Problem::new(
        data,
        spec,
        &options.lights,
        ctx.reference,
        options.colour_weight,
    )
    .with_light_weights(ctx.light_weights);
    let one_component: Vec<(ModelSpec, Vec<f64>)> = fitted
        .iter()
        .filter(|f| f.spec.components == 1 && f.spec.yield_form == spec.yield_form)
        .map(|f| (f.spec, f.theta.clone()))
        .collect();
    // K > 1 starts from the one-component fit with the same bands (or the last).
    let parent = one_component
        .iter()
        .find(|(p, _)| {
            p.absorption_bands == spec.absorption_bands && p.emission_bands == spec.emission_bands
        })
        .or(one_component.last());
    // The best smaller model this one contains.
    let nested = fitted
        .iter()
        .filter(|f| contains(&spec, &f.spec))
        .min_by(|a, b| a.cost.total_cmp(&b.cost));
    let starts: Vec<Start> = if energy_twin.is_some() {
        // The photon form starts from the energy form's optimum of the same structure.
        vec![Start::Twin]
    } else if spec.components == 1 {
        vec![Start::Parent]
    } else {
        // Every K > 1 candidate tries all three, also where the grid model misses the
        // bound. The base start alone there (what the grid model leaves empty under the
        // light it misses) left two dyes on a 20 nm grid (`fluorite class --seed 31`,
        // case148) with every two-component model worse on the matrix than 1x1, 3.4
        // ΔE2000 from its own measurement; with the others it ends at 2x1+rt within 0.2.
        // Fifteen class seeds: the noise-aware search's p90 lower on 8 and higher on 2,
        // its max lower on 8 and higher on none; HERPICER's search 11.3 → 12.8 ms.
        vec![Start::Parent, Start::Split, Start::Base]
    };
    // Each start with whether it builds on the one-component parent (where there is one).
    let mut starts: Vec<(Start, bool)> = starts.into_iter().map(|k| (k, true)).collect();
    if ctx.parentless_starts_too && spec.components > 1 && energy_twin.is_none() && parent.is_some()
    {
        starts.push((Start::Parent, false));
        starts.push((Start::Split, false));
    }
    // The nested start when the contained model has as many components (extra bands
    // only). An added component is seeded by the starts above (the parent plus a small
    // component, the residual of the grid fit); refining a third start there doubled
    // HERPICER's search (36 → 66 ms) without changing a choice, and the exact embedding
    // below keeps the guarantee.
    if let Some(n) = nested
        && n.spec.components == spec.components
    {
        starts.push((Start::Nested, true));
    }
    // Each start is refined on its own, so a single fit refines them in parallel (the
    // nested start, the longest, took 60–75 % of CIBA12's two-component fits); they are
    // then compared in the order above, so the kept optimum is the one a sequential loop
    // keeps. Inside a caller's rayon pool they run in turn (`CandidateContext::parallel`).
    let refine_start = |&(kind, with_parent): &(Start, bool)| {
        let theta0 = match kind {
            Start::Twin => energy_twin
                .map(|t| Ok(convert_yield_form(&problem, &t.spec, &t.theta)))
                .unwrap_or_else(|| Err(Error::Fit("no energy-form optimum".into()))),
            Start::Nested => match nested {
                Some(n) => nested_start(&problem, ctx, n),
                None => Err(Error::Fit("no nested model".into())),
            },
            _ => start(&problem, ctx, parent.filter(|_| with_parent), kind),
        };
        theta0.and_then(|t| refine(&problem, &t, options, ctx.tolerance, ctx.cancel))
    };
    let refined_starts: Vec<Result<(Vec<f64>, crate::optimise::Refined, f64)>> = if ctx.parallel {
        // The nested start, the longest, begins first: begun last, the others' time
        // came before it on the critical path.
        let mut order: Vec<usize> = (0..starts.len()).collect();
        order.sort_by_key(|&i| starts[i].0 != Start::Nested);
        let mut outcomes: Vec<(usize, _)> = order
            .par_iter()
            .map(|&i| (i, refine_start(&starts[i])))
            .collect();
        outcomes.sort_by_key(|(i, _)| *i);
        outcomes.into_iter().map(|(_, o)| o).collect()
    } else {
        starts.iter().map(refine_start).collect()
    };
    let mut best: Option<(Vec<f64>, crate::optimise::Refined, f64)> = None;
    let mut last_error: Option<Error> = None;
    for outcome in refined_starts {
        match outcome {
            Ok(candidate) => {
                if best.as_ref().is_none_or(|b| candidate.2 < b.2) {
                    best = Some(candidate);
                }
            }
            Err(e) => last_error = Some(e),
        }
    }
    // The exact embedding: the nested model's optimum, unrefined, guarantees the
    // candidate's objective is no higher than that model's.
    if let Some(n) = nested {
        let theta = embed(&problem, &n.spec, &n.theta, EMBEDDED_EXTRA);
        let cost = problem.cost_gradient(&theta).0;
        if cost.is_finite() && best.as_ref().is_none_or(|b| cost < b.2) {
            let refined = crate::optimise::Refined {
                theta: theta.clone(),
                iterations: 0,
                converged: true,
                termination: format!(
                    "no start improved on {} (the model it contains), taken with its extra parts at zero",
                    n.spec.name()
                ),
                cost_history: vec![cost],
            };
            best = Some((theta, refined, cost));
        }
    }
    if ctx.cancelled() {
        return Err(Error::Fit(format!("{}: no longer wanted", spec.name())));
    }
    let Some((theta, refined, cost)) = best else {
        return Err(last_error.unwrap_or_else(|| Error::Fit("no start".into())));
    };
    let m = ctx.m;
    // Its conservation block comes from lowering r onto the energy bound, below.
    let mut material = problem.material_without_margins(&theta, &m.name)?;
    // The model bounds ρ on the grid; between samples (photon form: c·Φ·a(λ)·λ/λ̄e is
    // quadratic) it may pass 1 by a hair. Lowering r there keeps the law; a reflectance
    // form no longer matches the lowered samples and is dropped (r stays tabulated).
    let (lowered, margins) = material.lower_reflectance_to_energy_bound_with_margins();
    if lowered > 0.0
        && let Some(forms) = material.forms.as_mut()
    {
        forms.reflectance = None;
    }
    material.conservation = Some(margins);
    // The samples were just tabulated from the forms: the search validates the chosen
    // candidate's forms against them once, not every candidate's.
    material
        .validate_except_forms()
        .map_err(|e| Error::Fit(format!("{}: candidate {}: {e}", m.name, spec.name())))?;
    let accuracy = assess::accuracy(&material, m, data, &options.lights);
    let delta_e = accuracy.delta_e2000.clone();
    let parameters = spec.parameter_count(data.diagonal_positions.len());
    let mut report = FitReport {
        solver: "lbfgs".into(),
        converged: refined.converged,
        iterations: refined.iterations,
        gauge: match spec.yield_form {
            YieldForm::Energy => "smallest feasible c per component (Q at its photon or energy limit); only k = c·Q is identified",
            YieldForm::Photon => "smallest feasible c per component (Φ = 1 where the reflectance allows); only k = c·Φ is identified",
        }
        .into(),
        cost_history: refined.cost_history,
        model: spec.name(),
        parameter_count: parameters,
        // The cells this candidate fitted (the search removes crosstalk the grid fit kept).
        crosstalk: data.crosstalk.clone(),
        ..ctx.base.fit.clone().unwrap_or_default()
    };
    // Its own residuals, ΔE2000 and filled-reference figures, not the grid fit's.
    accuracy.record_in(&mut report);
    report.warnings = Vec::new();
    let unconfirmed = accuracy.unconfirmed_fill(report.noise_sigma, m, options.colour_bound());
    if !refined.converged {
        report.warnings.push(
            if refined.termination.to_lowercase().contains("line search") {
                // Kinks (a tabulated reflectance at a bound, a band crossing the
                // absorption floor) stop the line search, not the budget.
                format!(
                    "lbfgs stopped after {} iterations: its line search found no descent at a kink of the objective; the fit is the best point found (the ΔE above are its own)",
                    refined.iterations
                )
            } else {
                format!(
                    "lbfgs stopped before converging ({}) after {} iterations; raise --max-iterations",
                    refined.termination, refined.iterations
                )
            },
        );
    }
    report.warnings.extend(unconfirmed);
    material.fit = Some(report);
    let worst = worst(&delta_e);
    let within = options.lights.iter().all(|l| {
        let bound = ctx
            .light_bounds
            .get(&l.name)
            .copied()
            .unwrap_or(f64::INFINITY);
        delta_e.get(&l.name).is_some_and(|de| *de <= bound)
    });
    Ok(Fitted {
        spec,
        theta,
        cost,
        material,
        delta_e,
        worst,
        within,
    })
}

/// L-BFGS on the candidate's objective: the optimum, the run, and the objective there.
fn refine(
    problem: &Problem<'_>,
    theta0: &[f64],
    options: &FitOptions,
    tolerance: f64,
    cancel: Option<&AtomicBool>,
) -> Result<(Vec<f64>, crate::optimise::Refined, f64)> {
    let (start_cost, start_gradient) = problem.cost_gradient(theta0);
    if !start_cost.is_finite() || start_gradient.iter().any(|g| !g.is_finite()) {
        return Err(Error::Fit(
            "the start has a non-finite cost or gradient".into(),
        ));
    }
    let gradient_norm = start_gradient.iter().map(|g| g * g).sum::<f64>().sqrt();
    // L-BFGS's first step is the raw gradient: scale the cost so that step moves the
    // parameters (each of order one) by FIRST_STEP, not by whatever the data's units
    // make it (a step of 10³ overflows the bands). Later steps are scale-free.
    let scale = if gradient_norm > 0.0 {
        FIRST_STEP / gradient_norm
    } else {
        1.0
    };
    let ceiling = 1e12 * start_cost.max(1e-300) * scale;
    // The objective at the points evaluated last, as (θ, cost): the solver's first
    // evaluation is the start, whose objective is known, and its optimum is a point it
    // evaluated, whose objective the candidate needs. Each was evaluated again (two of
    // a start's 20–200 evaluations).
    let recent: RefCell<VecDeque<(Vec<f64>, f64)>> = RefCell::new(VecDeque::new());
    let function = |theta: &[f64]| {
        let (cost, gradient) = if same_bits(theta, theta0) {
            (start_cost, start_gradient.clone())
        } else {
            problem.cost_gradient(theta)
        };
        let mut recent = recent.borrow_mut();
        if recent.len() == RECENT_EVALUATIONS {
            recent.pop_front();
        }
        recent.push_back((theta.to_vec(), cost));
        if cost.is_finite() && gradient.iter().all(|g| g.is_finite()) {
            (cost * scale, gradient.iter().map(|g| g * scale).collect())
        } else {
            // Far outside the data's reach: a high wall the line search backs off from.
            (ceiling, vec![0.0; theta.len()])
        }
    };
    let stopping = crate::optimise::Stopping {
        max_iterations: options.max_iterations.max(2000),
        gradient_tolerance: tolerance * FIRST_STEP,
        cost_tolerance: tolerance * start_cost.max(1e-300) * scale,
    };
    let mut refined =
        solve::lbfgs_function_until(&function, theta0, stopping, cancel).map_err(Error::Fit)?;
    refined.cost_history.iter_mut().for_each(|c| *c /= scale);
    if refined.theta.iter().any(|t| !t.is_finite()) {
        return Err(Error::Fit(
            "the solver left the parameter space (non-finite parameters)".into(),
        ));
    }
    let known = recent
        .borrow()
        .iter()
        .rev()
        .find(|(theta, _)| same_bits(theta, &refined.theta))
        .map(|&(_, cost)| cost);
    let cost = known.unwrap_or_else(|| problem.cost_gradient(&refined.theta).0);
    Ok((refined.theta.clone(), refined, cost))
}

/// Whether `a` and `b` are the same parameters to the bit (the objective's bits follow
/// its parameters' bits; −0 and 0 compare equal but need not give the same ones).
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// How many of its last evaluations [`refine`] keeps to find its optimum's objective
/// among: the optimum is the last accepted point, and a line search evaluates a few
/// trial points after it at most.
const RECENT_EVALUATIONS: usize = 8;
