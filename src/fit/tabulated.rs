//! The grid (tabulated) fit: the closed-form start, the refinement in one or both
//! yield forms, the gauge and the material, the noise bootstrap, and the shapes-only
//! outcome of matrices without a calibrated diagonal.

use super::grid_material::*;
use super::start::{flat_start, start_spectra};
use super::*;
use crate::material::CrosstalkCorrection;

/// How many times what pure noise explains a rank-1 fit must beat to count as signal:
/// pure noise of level σ on an m×n grid lets an unconstrained rank-1 fit explain about
/// σ²(√m + √n)² (the top singular value squared; its spread at these sizes is about 16 %,
/// and σ's estimate from the anti-Stokes side adds about 20 %: 1.4 covers both), and the
/// non-negative fit explains less: at most 0.86 of it on the 751 dye-free twins of five
/// `fluorite class` seeds (noise, crosstalk, missing cells, 5–20 nm grids). It was 4,
/// which called a red pigment at σ 0.02 a plain reflector 26 ΔE2000 from its truth and
/// 12 of the 750 fluorescent class cases plain (2 at 1.5).
const SIGNIFICANCE_FACTOR: f64 = 1.5;
/// Rows whose fitted cells hold less than this share of the emission are unobservable.
const OBSERVABILITY_THRESHOLD: f64 = 0.05;

/// How much costlier than the closed-form estimate a refined result may end before the
/// start is blamed (absorbs round-off of costs that agree).
const POOR_START_MARGIN: f64 = 1e-6;

/// A refined κ at least this high counts as the photon law binding (`--yield auto`): the
/// smallest feasible c is 1, so the fluorescence is held at its limit.
const PHOTON_BINDS_KAPPA: f64 = 0.999;

/// One yield form fitted: the objective, the refinement and where it ended.
struct FormFit<'a> {
    objective: Objective<'a>,
    refined: crate::optimise::Refined,
    spectra: GridSpectra,
    cost: f64,
    cost_history: Vec<f64>,
    kappa_unbounded: f64,
}

/// Starts and refines the grid model in one yield form; `noise_sigma` (the cells' noise
/// level, estimated once by the caller) scales the pruning of unsupported samples.
#[allow(clippy::too_many_arguments)]
fn refine_form<'a>(
    data: &'a FitData,
    representation: &Tabulated,
    start: &init::RankOne,
    form: YieldForm,
    colour: Option<objective::ColourTerm>,
    options: &FitOptions,
    total_energy: f64,
    noise_sigma: f64,
) -> Result<FormFit<'a>> {
    let objective = Objective::new(data, form).with_colour(colour);
    let estimate = start_spectra(&objective, start);
    let closed_form = estimate.spectra;
    let start_spectra = match options.start {
        Start::ClosedForm => closed_form.clone(),
        Start::Flat => flat_start(&closed_form),
    };
    let theta0 = representation.encode(&start_spectra);
    let energy_scale = total_energy + data.diagonal.iter().map(|c| c.value * c.value).sum::<f64>();
    // Stop when the gradient is negligible against the data, or when an iteration
    // improves the cost by less than `tolerance` of the closed-form estimate's cost (the
    // problem's scale: a worse start must not loosen the criterion).
    let scale_cost = objective.cost_gradient(&closed_form).0;
    let start_cost = match options.start {
        // The same spectra: one evaluation less.
        Start::ClosedForm => scale_cost,
        Start::Flat => objective.cost_gradient(&start_spectra).0,
    };
    let stopping = crate::optimise::Stopping {
        max_iterations: options.max_iterations,
        gradient_tolerance: options.tolerance * energy_scale.sqrt().max(1e-300),
        cost_tolerance: options.tolerance * scale_cost.max(1e-300),
    };
    let refined = match options.solver {
        Solver::Init => crate::optimise::Refined {
            theta: theta0.clone(),
            iterations: start.sweeps as u64,
            converged: start.converged,
            termination: if start.converged {
                "alternating least squares converged".into()
            } else {
                "alternating least squares sweep limit".into()
            },
            cost_history: start.cost_history.clone(),
        },
        iterative => solve::refine_tabulated(
            iterative,
            objective.clone(),
            representation,
            &theta0,
            stopping,
        )
        .map_err(Error::Fit)?,
    };
    let mut cost_history = if options.solver == Solver::Init {
        refined.cost_history.clone()
    } else {
        let mut h = vec![start_cost];
        h.extend(&refined.cost_history);
        h
    };
    cost_history.retain(|c| c.is_finite());
    let mut spectra = representation.spectra(&refined.theta);
    prune::prune_insignificant(&objective, data, &mut spectra, noise_sigma);
    let cost = objective.cost_gradient(&spectra).0;
    Ok(FormFit {
        objective,
        refined,
        spectra,
        cost,
        cost_history,
        kappa_unbounded: estimate.kappa_unbounded,
    })
}

/// ΔE2000 from its own cells' colour beyond which the fit without the crosstalk counts
/// as another optimum (where the fit of the cells as measured came closer to theirs by
/// more than the crosstalk is worth): the bound the default fit holds a grid fit to,
/// or 3 × the RMS ΔE2000 the colour's own noise gives, if larger.
const CROSSTALK_OWN_COLOUR_BOUND: f64 = 1.0;

/// [`fit`], with or without the noise bootstrap (its own refits skip it). Where the
/// matrix carries crosstalk next to the diagonal ([`super::crosstalk`]) the cells are
/// fitted without it, unless that moves the fit to another optimum: removing it can tip
/// one fluorophore over from one emitter to another where two share the matrix (a
/// UV-tail pigment beside a blue emitter, `tests/suite/uv_tail.rs`), and the colour then
/// misses by far more than the crosstalk is worth. The fit of the cells as measured is
/// kept there, and its report says why. With `record_noise` the report's colour noise
/// (`delta_e2000_noise`) comes from the fit's own cells and colour term where they give it
/// (then [`fit`] need not gather the cells again).
pub(super) fn fit_checked(
    m: &Measurement,
    options: &FitOptions,
    bootstrap: bool,
    record_noise: bool,
) -> Result<FitOutcome> {
    fit_checked_as(m, options, bootstrap, record_noise, CrosstalkPlan::Estimate)
}

/// How [`fit_checked_as`] treats the crosstalk next to the diagonal.
#[derive(Debug, Clone, Copy)]
pub(super) enum CrosstalkPlan<'a> {
    /// Estimate it, and decide whether to fit the cells without it ([`fit_checked`]).
    Estimate,
    /// As an earlier fit of the same matrix decided (its report's `crosstalk`): removed
    /// where that says so, else the cells as measured, with its note. The default fit's
    /// search starts from the cells its grid fit used, though it judges other lights.
    Decided(Option<&'a CrosstalkCorrection>),
}

/// [`fit_checked`], with the crosstalk handled as `plan` says.
pub(super) fn fit_checked_as(
    m: &Measurement,
    options: &FitOptions,
    bootstrap: bool,
    record_noise: bool,
    plan: CrosstalkPlan,
) -> Result<FitOutcome> {
    validate_options(options)?;
    m.validate()?;
    let guard_nm = options.guard_nm.unwrap_or(0.0);
    let sigma = FitData::new(m, guard_nm).noise_sigma();
    let started = Instant::now();
    let kept = match plan {
        // Removed or kept as decided; its block goes with the cells to the report.
        CrosstalkPlan::Decided(decided) => fit_cells(m, options, record_noise, decided)?,
        CrosstalkPlan::Estimate => match super::crosstalk::estimate(m, sigma, &options.lights) {
            None => fit_cells(m, options, record_noise, None)?,
            Some(found) => match fit_cells(m, options, record_noise, Some(&found)) {
                Ok(cleaned) => {
                    keep_cleaned_or_not(m, options, record_noise, &found, sigma, cleaned)
                }
                // The cells as measured are what a fit without the removal would have
                // used: an error in the cleaned fit is no reason to fail.
                Err(e) => {
                    let kept = kept_as_measured(
                        &found,
                        format!("the fit without it failed ({e}); fitted as measured"),
                    );
                    fit_cells(m, options, record_noise, Some(&kept))?
                }
            },
        },
    };
    // The noise bootstrap (its refits cost many fits) for the kept fit only.
    Ok(match kept {
        (FitOutcome::Material(mut material), Some(at)) if bootstrap => {
            let mut warnings = Vec::new();
            noise_colour_check(m, &material, options, &mut warnings);
            let fit = material
                .fit
                .as_mut()
                .expect("fitted materials carry a report");
            for (k, w) in warnings.into_iter().enumerate() {
                fit.warnings.insert((at + k).min(fit.warnings.len()), w);
            }
            fit.seconds = started.elapsed().as_secs_f64();
            FitOutcome::Material(material)
        }
        (outcome, _) => outcome,
    })
}

/// A fit's outcome and, for a fitted material, where among its warnings the noise
/// bootstrap's belongs (the bootstrap runs after [`fit_cells`], for the fit kept).
type CellsFit = (FitOutcome, Option<usize>);

/// [`fit_checked`]'s choice where crosstalk was found: the fit of the cells less `found`
/// (`cleaned`), unless it misses its own cells' colour and the fit of the cells as
/// measured comes closer by more than the crosstalk is worth (see [`fit_checked`]).
fn keep_cleaned_or_not(
    m: &Measurement,
    options: &FitOptions,
    record_noise: bool,
    found: &CrosstalkCorrection,
    sigma: f64,
    cleaned: CellsFit,
) -> CellsFit {
    let started = Instant::now();
    // Shapes (no diagonal, arbitrary scale) carry no crosstalk estimate.
    let FitOutcome::Material(material) = &cleaned.0 else {
        return cleaned;
    };
    // Within the bound of its own cells' colour the cleaned fit is kept without fitting
    // the cells as measured: the common case costs one fit.
    let misses = super::crosstalk_check::own_colour_misses(
        m,
        material,
        found,
        &options.lights,
        sigma,
        options.guard_nm.unwrap_or(0.0),
        CROSSTALK_OWN_COLOUR_BOUND,
    );
    if misses.is_empty() {
        return cleaned;
    }
    // The cleaned fit stands where the cells as measured cannot be fitted.
    let Ok((FitOutcome::Material(mut as_measured), at)) = fit_cells(m, options, record_noise, None)
    else {
        return cleaned;
    };
    let measured_de = as_measured
        .fit
        .as_ref()
        .map(|f| f.delta_e2000.clone())
        .unwrap_or_default();
    let moved = misses.iter().find(|(light, de)| {
        let worth = found.delta_e2000.get(light).copied().unwrap_or(0.0);
        let before = measured_de.get(light).copied().unwrap_or(f64::INFINITY);
        *de > before + worth
    });
    let Some((light, de)) = moved else {
        return cleaned;
    };
    let report = as_measured
        .fit
        .as_mut()
        .expect("fitted materials carry a report");
    report.crosstalk = Some(kept_as_measured(
        found,
        format!(
            "without it the fit moves to another optimum: ΔE2000 {de:.2} under {light} from the colour of the cells it fitted, against {:.2} with the cells as measured (the crosstalk is worth {:.2})",
            measured_de.get(light).copied().unwrap_or(f64::NAN),
            found.delta_e2000.get(light).copied().unwrap_or(0.0)
        ),
    ));
    report.seconds += started.elapsed().as_secs_f64();
    (FitOutcome::Material(as_measured), at)
}

/// `found`, left in the cells (fitted as measured) for the reason `note`.
fn kept_as_measured(found: &CrosstalkCorrection, note: String) -> CrosstalkCorrection {
    CrosstalkCorrection {
        removed: false,
        note,
        ..found.clone()
    }
}

/// The grid fit of `m`'s cells, less `crosstalk` where it is `removed` (see [`fit_checked`]), and
/// for a fitted material with a diagonal the index among its warnings where the noise
/// bootstrap's belongs (the caller runs it for the fit it keeps).
fn fit_cells(
    m: &Measurement,
    options: &FitOptions,
    record_noise: bool,
    crosstalk: Option<&CrosstalkCorrection>,
) -> Result<CellsFit> {
    let started = Instant::now();
    validate_options(options)?;
    m.validate()?;
    let guard_nm = options.guard_nm.unwrap_or(0.0);
    // Arbitrary-scale data (counts) are brought to a scale where the rank-1 start has
    // κ = ½, so that the bound κ ≤ 1 (meaningless in counts) never binds; the scale is
    // reported back in data units.
    let data_scale = if m.arbitrary_scale {
        arbitrary_data_scale(m, guard_nm)
    } else {
        1.0
    };
    let scaled;
    let m_fit = if data_scale != 1.0 {
        scaled = Measurement {
            values: m.values.iter().map(|v| v / data_scale).collect(),
            ..m.clone()
        };
        &scaled
    } else {
        m
    };
    let data = FitData::with_crosstalk(m_fit, guard_nm, crosstalk);
    if data.off_diagonal.is_empty() {
        return Err(Error::Fit(format!(
            "{}: no measured cell lies outside the diagonal and its {guard_nm} nm guard band; fluorescence cannot be fitted (lower --guard or supply a matrix with off-diagonal cells)",
            m.name
        )));
    }
    let noise_sigma = data.noise_sigma();
    let representation = Tabulated {
        n_excitation: data.n_excitation(),
        n_emission: data.n_emission(),
    };
    let mut warnings = Vec::new();

    // 1. Closed-form start.
    let start = init::rank_one(&data, init::MAX_SWEEPS);
    let total_energy: f64 = data.off_diagonal.iter().map(|c| c.value * c.value).sum();
    let explained = start.explained(&data);
    let noise_floor = SIGNIFICANCE_FACTOR
        * init::noise_rank_one_energy(noise_sigma, data.n_excitation(), data.n_emission());
    let fluorescent =
        explained > noise_floor.max(1e-24 * total_energy.max(1e-300)) && explained > 0.0;

    if !fluorescent {
        if !m.has_diagonal {
            return Err(Error::Fit(format!(
                "{}: the matrix holds no signal above its noise (σ ≈ {noise_sigma:.3e}) and has no diagonal; there is nothing to fit",
                m.name
            )));
        }
        // A plain reflector is its diagonal: with none measured it would be a material
        // without a reflectance sample, which breaks the finite-non-negative law (a
        // BFC-450 file cut to its UV rows, 300–350 nm against emission from 380 nm, found
        // by the fuzz campaign).
        if data.diagonal.is_empty() {
            return Err(Error::Fit(format!(
                "{}: the matrix holds no signal above its noise (σ ≈ {noise_sigma:.3e}) and its diagonal (reflectance) is measured at no wavelength ({}); there is nothing to fit: supply the rows whose excitation lies on the emission grid",
                m.name,
                if data.diagonal_positions.is_empty() {
                    format!(
                        "excitation {} and emission {} share no wavelength",
                        span(&m.excitation_nm),
                        span(&m.emission_nm)
                    )
                } else {
                    "every diagonal cell is missing".to_string()
                }
            )));
        }
        let mut plain = plain_reflector(
            m,
            &data,
            options,
            started,
            noise_sigma,
            vec![format!(
                "no fluorescent signal above the noise (a rank-1 fit explains {explained:.3e}, pure noise of σ = {noise_sigma:.2e} would explain up to {noise_floor:.3e}): fitted as a plain reflector with c = 0"
            )],
        );
        let bound = options.max_delta_e.unwrap_or(PLAIN_COLOUR_BOUND);
        match plain_reflector_colour_miss(m_fit, &data, options, &plain, noise_sigma) {
            Some(miss) if miss.chi2 > assess::NOISE_CHI2_LIMIT => warnings.push(format!(
                "the fluorescence is below the noise cell by cell (a rank-1 fit explains {explained:.3e}, noise alone up to {noise_floor:.3e}), but a plain reflector misses the measured colour under {} by ΔE2000 {:.2}, more than {bound} and more than the cells' noise explains (χ² {:.1} over the colour's three channels; noise alone passes {} in 1 of 10⁵ draws): fitted as fluorescent",
                miss.light,
                miss.delta_e2000,
                miss.chi2,
                assess::NOISE_CHI2_LIMIT
            )),
            miss => {
                // Where the plain reflector misses by more than the bound, say how far
                // within the noise that is: a weak dye can hide there.
                if let (Some(miss), FitOutcome::Material(material)) = (miss, &mut plain)
                    && let Some(report) = material.fit.as_mut()
                {
                    report.warnings.push(format!(
                        "the plain reflector misses the measured colour under {} by ΔE2000 {:.2}, more than {bound}, but no more than the cells' noise explains (χ² {:.1} over the colour's three channels, at most {}): a fluorophore weaker than the noise may hide there; average repeated measurements to tell",
                        miss.light,
                        miss.delta_e2000,
                        miss.chi2,
                        assess::NOISE_CHI2_LIMIT
                    ));
                }
                return Ok((plain, None));
            }
        }
    }

    // Colour term: the flat patch under the scene's lights, so that the grid model is
    // good in colour as well as in cells (a least-squares fit of the cells alone misses
    // CIBA12 under A by ΔE2000 1.4).
    let mut colour_reference = Vec::new();
    let colour = if m.has_diagonal && !m.arbitrary_scale && options.colour_weight > 0.0 {
        let reference = patch_reference(m_fit, &options.lights);
        // The colour term is for structure the model cannot follow; where the rank-1
        // start already leaves only noise (χ² per cell ≈ 1: the model is right), least
        // squares is the right estimate and the colour term would fit the noise. Its
        // weight is the share of the start's residual that noise does not explain, and no
        // more, per light, than that share in the rows the light reaches: the `uv` light's
        // LED sends half its energy to two rows, whose samples the colour term would
        // otherwise bend to chase the noise of the measured colour (see
        // `colour_term::misfit_shares`).
        let residual_energy = 2.0 * start.cost_history.last().copied().unwrap_or(0.0);
        let noise_energy = data.off_diagonal.len() as f64 * noise_sigma * noise_sigma;
        let misfit_share = if residual_energy > 0.0 {
            (1.0 - noise_energy / residual_energy).max(0.0)
        } else {
            0.0
        };
        let term = objective::ColourTerm::new(
            &data,
            &options.lights,
            &reference,
            options.colour_weight,
            noise_sigma,
        );
        let shares: Vec<f64> =
            colour_term::misfit_shares(&data, &start.row, &start.column, noise_sigma, &term)
                .into_iter()
                .map(|s| s.min(misfit_share))
                .collect();
        colour_reference = reference;
        Some(term.with_light_shares(&shares))
    } else {
        None
    };
    let forms: &[YieldForm] = if !m.has_diagonal || m.arbitrary_scale {
        // Without a calibrated diagonal only the shapes are fitted; the form changes none.
        &[YieldForm::Energy]
    } else {
        match options.yield_choice {
            // A pinned --quantum-yield is an energy yield Q unless --yield photon says Φ.
            YieldChoice::Energy | YieldChoice::Auto => &[YieldForm::Energy],
            YieldChoice::Photon => &[YieldForm::Photon],
        }
    };
    let auto = options.yield_choice == YieldChoice::Auto
        && options.quantum_yield.is_none()
        && forms[0] == YieldForm::Energy
        && m.has_diagonal
        && !m.arbitrary_scale;
    let refine = |form: YieldForm| {
        refine_form(
            &data,
            &representation,
            &start,
            form,
            colour.clone(),
            options,
            total_energy,
            noise_sigma,
        )
    };
    // When the start already shows the energy form's photon law binding, both forms are
    // needed: fit them side by side (two cores halve the wait for one file; in a batch the
    // pool is busy and they run in turn).
    let binds_at_start = auto
        && start_spectra(&Objective::new(&data, YieldForm::Energy), &start).kappa_unbounded > 1.0;
    let (chosen, mut photon) = if binds_at_start {
        let (energy, photon) =
            rayon::join(|| refine(YieldForm::Energy), || refine(YieldForm::Photon));
        (energy?, Some(photon?))
    } else {
        (refine(forms[0])?, None)
    };
    let mut chosen = chosen;
    let mut yield_reason = match options.yield_choice {
        YieldChoice::Energy => "energy form (constant Q), as asked (--yield energy)".to_string(),
        YieldChoice::Photon => "photon form (constant Φ), as asked (--yield photon)".to_string(),
        YieldChoice::Auto => String::new(),
    };
    if options.yield_choice == YieldChoice::Auto && options.quantum_yield.is_some() {
        yield_reason =
            "energy form (constant Q): --quantum-yield pins Q (give --yield photon to pin Φ)"
                .into();
    } else if auto {
        let binds = chosen.kappa_unbounded > 1.0 || chosen.spectra.kappa >= PHOTON_BINDS_KAPPA;
        if binds {
            let photon = match photon.take() {
                Some(fitted) => fitted,
                None => refine(YieldForm::Photon)?,
            };
            if assess::photon_form_fits_better(chosen.cost, photon.cost, noise_sigma) {
                yield_reason = format!(
                    "photon form (constant Φ): in the energy form the photon law binds (c ≥ {:.3} needed for the cells, so the fluorescence is scaled down) and the photon form fits better (objective {:.4e} against {:.4e})",
                    chosen.kappa_unbounded, photon.cost, chosen.cost
                );
                chosen = photon;
            } else {
                yield_reason = format!(
                    "energy form (constant Q): its photon law binds but the photon form fits no better (objective {:.4e} against {:.4e})",
                    photon.cost, chosen.cost
                );
            }
        } else {
            yield_reason = format!(
                "energy form (constant Q): its photon law does not bind (c ≥ {:.3} suffices)",
                chosen.kappa_unbounded
            );
        }
    }
    let FormFit {
        objective,
        refined,
        spectra,
        cost_history,
        kappa_unbounded,
        ..
    } = chosen;
    if kappa_unbounded > 1.0 {
        warnings.push(format!(
            "the unconstrained rank-1 estimate needs c ≥ {kappa_unbounded:.3} > 1 in the {} form: conservation caps the fluorescence, the fit scales it down",
            objective.form.name()
        ));
    }
    if !refined.converged {
        warnings.push(format!(
            "{} stopped before converging ({}) after {} iterations; raise --max-iterations or try another --solver",
            options.solver.name(),
            refined.termination,
            refined.iterations
        ));
    }
    // A solver started away from the closed-form estimate can stall in a local minimum
    // or a flat region (the stability sweep's "poor start" regime): a result costlier
    // than the estimate it skipped is worse than no refinement at all.
    if options.start != Start::ClosedForm {
        let refined_cost = objective.cost_gradient(&spectra).0;
        let closed_form = start_spectra(&objective, &start).spectra;
        let closed_form_cost = objective.cost_gradient(&closed_form).0;
        // Costs differing by less than what p fitted parameters absorb of the noise
        // (½·p·σ²) are equally good fits.
        let noise_margin = 0.5 * representation.n_params() as f64 * noise_sigma * noise_sigma;
        if refined_cost > closed_form_cost * (1.0 + POOR_START_MARGIN) + noise_margin {
            warnings.push(format!(
                "{} from the {:?} start ended at cost {refined_cost:.3e}, above the closed-form estimate's {closed_form_cost:.3e}: stuck in a local minimum or flat region; use the default start",
                options.solver.name(),
                options.start
            ));
        }
    }
    checks::after_refinement(&objective, &spectra, noise_sigma, &mut warnings);

    // 3. Material and gauge.
    let report = FitReport {
        solver: options.solver.name().to_string(),
        converged: refined.converged,
        iterations: refined.iterations,
        seconds: 0.0,
        guard_nm,
        gauge: String::new(),
        noise_sigma: noise_sigma * data_scale,
        guard_signal_fraction: guard_fraction(&data),
        // The cells' own record of what was taken out of them: the one source of the
        // report's crosstalk (the plain reflector's report reads it too).
        crosstalk: data.crosstalk.clone(),
        cost_history,
        model: "tabulated".into(),
        yield_choice: yield_reason,
        parameter_count: 1
            + (data.n_excitation() - 1)
            + (data.n_emission() - 1)
            + data.diagonal_positions.len(),
        ..data::provenance(m)
    };
    let unobservable =
        assess::unobservable_absorption(&data, &spectra.emission, OBSERVABILITY_THRESHOLD);
    if unobservable.iter().any(|&u| u) {
        warnings.push(format!(
            "absorption is barely constrained at {}: little of the emission falls in those rows' measured cells",
            assess::ranges(&data.excitation_nm, &unobservable)
        ));
    }
    if !m.has_diagonal || m.arbitrary_scale {
        return Ok((
            shapes(
                m, &data, &objective, &spectra, report, data_scale, warnings, started,
            ),
            None,
        ));
    }
    let mut material = build_material(
        m,
        &data,
        &objective,
        &spectra,
        options,
        report,
        &mut warnings,
    )?;

    // 4. Assessment.
    let accuracy = assess::accuracy(&material, m, &data, &options.lights);
    let bootstrap_at = warnings.len();
    if accuracy.leaves_structure(noise_sigma, m) {
        warnings.push(format!(
            "off-diagonal residual RMS {:.2e} is {:.1}× the noise level σ = {:.2e} (anti-Stokes side): {}",
            accuracy.rms_off_diagonal,
            accuracy.rms_off_diagonal / noise_sigma,
            noise_sigma,
            assess::STRUCTURE_WARNING
        ));
    }
    warnings.extend(accuracy.unconfirmed_fill(noise_sigma, m, options.colour_bound()));
    let fit = material.fit.as_mut().expect("report set above");
    accuracy.record_in(fit);
    let rss = accuracy.rms_off_diagonal.powi(2) * data.off_diagonal.len() as f64
        + accuracy.rmse_diagonal.powi(2) * data.diagonal.len() as f64;
    fit.bic = Some(assess::bic(rss, noise_sigma, fit.parameter_count, &data));
    fit.warnings = warnings;
    fit.seconds = started.elapsed().as_secs_f64();
    let (lowered, margins) = material.lower_reflectance_to_energy_bound_with_margins();
    if lowered > 1e-3 {
        material
            .fit
            .as_mut()
            .expect("report set above")
            .warnings
            .push(format!(
                "reflectance lowered by up to {lowered:.4} between grid samples to keep the energy albedo ≤ 1"
            ));
    }
    material.conservation = Some(margins);
    material.validate().map_err(|e| {
        Error::Fit(format!(
            "{}: the fitted material violates a constraint ({e}); this is a bug, please report it",
            m.name
        ))
    })?;
    if record_noise && data_scale == 1.0 {
        super::record_own_colour_noise(
            m,
            &mut material,
            options,
            &data,
            colour.as_ref(),
            &colour_reference,
        );
    }
    Ok((FitOutcome::Material(Box::new(material)), Some(bootstrap_at)))
}

/// Refits of the noise bootstrap.
const BOOTSTRAP_DRAWS: u64 = 8;
/// RMS ΔE2000 the noise alone may cause before the colour is called unresolved: the
/// stability sweep's noise failures (ΔE2000 > 1 against the truth) start where the
/// bootstrap RMS passes about this value.
const BOOTSTRAP_DELTA_E: f64 = 0.7;

/// Fluorescence peak in noise σ above which the bootstrap is skipped: the stability
/// sweep's noise-limited colours start below a ratio of about 60 (σ = 2·10⁻³ on the
/// presets), while four of the six real files (the .BFC ones) sit above 100.
const BOOTSTRAP_SIGNAL_RATIO: f64 = 100.0;

/// Parametric bootstrap of the colour: how far measurement noise alone moves the fitted
/// colour. Adds noise of the estimated σ to the fitted matrix (measured cells only),
/// refits with the closed-form estimate, and compares colours under the report's lights.
/// Noise of a few 10⁻³ already moves colours by ΔE2000 ≈ 1 (the sweep's noise regime),
/// though every other check passes.
fn noise_colour_check(
    m: &Measurement,
    material: &Material,
    options: &FitOptions,
    warnings: &mut Vec<String>,
) {
    let noise_sigma = material.fit.as_ref().map_or(f64::NAN, |f| f.noise_sigma);
    if noise_sigma.is_nan() || noise_sigma <= 0.0 || options.lights.is_empty() {
        return;
    }
    // The refits cost ~30× a fit; skip them where the sweeps never saw noise move the
    // colour: fluorescence peaks above BOOTSTRAP_SIGNAL_RATIO·σ (every real BFC-450 file).
    let bin = match m.units {
        Units::PerBin => crate::spectrum::bin_widths(&m.emission_nm)
            .into_iter()
            .fold(0.0, f64::max),
        Units::PerNm => 1.0,
    };
    let peak = material
        .fluorophores
        .iter()
        .map(|f| {
            let mean = f.emission_mean_nm();
            let row_peak = f
                .absorption
                .wavelength_nm
                .iter()
                .map(|&l| f.reradiated_with_mean(l, mean))
                .fold(0.0, f64::max);
            row_peak * f.emission.value.iter().cloned().fold(0.0, f64::max) * bin
        })
        .fold(0.0, f64::max);
    if peak > BOOTSTRAP_SIGNAL_RATIO * noise_sigma {
        return;
    }
    let clean = crate::model::predict_like(material, m);
    // The closed-form estimate in the material's own form: the colour term and the
    // choice of form belong to the refinement, which the draws skip.
    let refit_options = FitOptions {
        solver: Solver::Init,
        start: Start::ClosedForm,
        colour_weight: 0.0,
        yield_choice: match material.fluorophores.first().map(|f| f.yield_form) {
            Some(YieldForm::Photon) => YieldChoice::Photon,
            _ => YieldChoice::Energy,
        },
        ..options.clone()
    };
    // Colour on the data's own grids, as in the accuracy report (cached colorimeters).
    let lab = |mat: &Material| assess::predicted_labs(mat, m, &options.lights);
    let reference = lab(material);
    let mut rng = crate::numeric::SplitMix64::new(0x5EED);
    let mut sum_sq = 0.0;
    let mut draws = 0.0;
    for _ in 0..BOOTSTRAP_DRAWS {
        let mut noisy = clean.clone();
        for (v, measured) in noisy.values.iter_mut().zip(&m.values) {
            *v = if measured.is_finite() {
                *v + noise_sigma * rng.normal()
            } else {
                f64::NAN
            };
        }
        if let Ok(FitOutcome::Material(refit)) = fit_checked(&noisy, &refit_options, false, false) {
            let de = lab(&refit)
                .into_iter()
                .zip(&reference)
                .map(|(a, b)| delta_e2000(a, *b))
                .fold(0.0, f64::max);
            sum_sq += de * de;
            draws += 1.0;
        }
    }
    let rms = if draws > 0.0 {
        (sum_sq / draws).sqrt()
    } else {
        0.0
    };
    if rms > BOOTSTRAP_DELTA_E {
        warnings.push(format!(
            "noise limits the colour: refits of the fit plus noise of σ = {noise_sigma:.2e} differ from it by ΔE2000 ≈ {rms:.2} (RMS over {BOOTSTRAP_DRAWS} draws, largest over the lights), so colour errors of about 1 are not resolved; average repeated measurements"
        ));
    }
}

/// The factor dividing arbitrary-scale data so that the rank-1 start has κ = ½.
fn arbitrary_data_scale(m: &Measurement, guard_nm: f64) -> f64 {
    let data = FitData::new(m, guard_nm);
    let start = init::rank_one(&data, init::MAX_SWEEPS);
    let kappa = start_spectra(&Objective::new(&data, YieldForm::Energy), &start).kappa_unbounded;
    if kappa.is_finite() && kappa > 0.0 {
        kappa / 0.5
    } else {
        1.0
    }
}

/// `300–350 nm`, or `300 nm` for a grid of one wavelength.
fn span(grid: &[f64]) -> String {
    match (grid.first(), grid.last()) {
        (Some(a), Some(b)) if a != b => format!("{a:.0}–{b:.0} nm"),
        (Some(a), _) => format!("{a:.0} nm"),
        _ => "no wavelength".to_string(),
    }
}
