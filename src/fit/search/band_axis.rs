//! The axis the search's Gaussian bands are Gaussian in, chosen by the data.
//!
//! Dye spectra are nearer Gaussian in wavenumber (`fluorite bands`: one band fewer per
//! emission curve), but on a surface's matrix the likelihood often says otherwise: the
//! same structure fitted to the cells alone has the lower BIC on wavelength in 32 of 42
//! structures over the six shared surfaces (docs/results.md, "The band axis chosen by the
//! data"). With [`crate::fit::BandAxisChoice::Both`] the search runs on each axis from the same grid
//! fit, and the result that meets its rule is kept, of two that do the one of lower BIC
//! (the same cells and noise: the matrix's likelihood, the parameter count charged).

use super::starts::StartCache;
use super::*;

/// A search on one band axis: the material it keeps, and what decides between two axes,
/// as that search judged them on its own cells and σ.
pub(super) struct OnAxis {
    pub(super) material: Material,
    /// The kept model's BIC (the grid model's where it kept the grid fit).
    pub(super) bic: f64,
    /// Where it met no bound: Σ over the lights of ΔE2000 beyond max(bound, 3 × the
    /// colour's noise RMS), as its own fallback judged the fit it kept; else 0.
    pub(super) excess: f64,
}

/// The search on every axis `options` allows (a model that names one structure: its
/// name's), from the grid fit `base`; of two, the one [`prefer_second`] says. Outside a
/// rayon pool the two run beside each other, each with its own fits in parallel (rayon
/// shares the cores between them); inside a caller's pool (a batch, the class sweep,
/// images), whose outer loop fills the cores, one after the other.
pub(super) fn search_each_axis(
    m: &Measurement,
    options: &FitOptions,
    base: Material,
    started: Instant,
) -> Result<FitOutcome> {
    let axes: Vec<BandDomain> = match options.model {
        ModelChoice::Fixed(request) => vec![request.domain],
        _ => options.band_axis.axes().to_vec(),
    };
    let parallel = rayon::current_thread_index().is_none();
    // What the starts share, for both axes: its keys name the band axis where a value
    // depends on it, and the fresh split of the grid fit, which does not, is made once.
    let starts = StartCache::default();
    let [first, second] = axes[..] else {
        let axis = axes.first().copied().unwrap_or(DEFAULT_DOMAIN);
        return search_on_axis(m, options, base, axis, parallel, started, &starts)
            .map(|on| FitOutcome::Material(Box::new(on.material)));
    };
    let other = base.clone();
    let search = |base: Material, axis: BandDomain| {
        search_on_axis(m, options, base, axis, parallel, started, &starts)
    };
    let (a, b) = if parallel {
        rayon::join(|| search(base, first), || search(other, second))
    } else {
        (search(base, first), search(other, second))
    };
    let (a, b) = match (a, b) {
        (Ok(a), Ok(b)) => (a, b),
        (Ok(a), Err(e)) => return Ok(with_failed_axis(a.material, first, second, &e, started)),
        (Err(e), Ok(b)) => return Ok(with_failed_axis(b.material, second, first, &e, started)),
        (Err(e), Err(_)) => return Err(e),
    };
    let (ja, jb) = (Judged::of(&a), Judged::of(&b));
    let (kept, kept_axis, passed, passed_axis, why) = match prefer_second(&ja, &jb) {
        Some(why) => (b.material, second, a.material, first, why),
        None => (a.material, first, b.material, second, why_kept(&ja, &jb)),
    };
    Ok(FitOutcome::Material(Box::new(merged(
        kept,
        kept_axis,
        &passed,
        passed_axis,
        &why,
        started,
    ))))
}

/// What decides between the searches of two axes.
#[derive(Debug, Clone, PartialEq)]
struct Judged {
    model: String,
    met: bool,
    bic: f64,
    excess: f64,
}

impl Judged {
    fn of(on: &OnAxis) -> Judged {
        let fit = on.material.fit.as_ref();
        Judged {
            model: fit.map(|f| f.model.clone()).unwrap_or_default(),
            met: fit
                .and_then(|f| f.model_search.as_ref())
                .is_none_or(|s| s.met),
            bic: on.bic,
            excess: on.excess,
        }
    }
}

/// Whether the second axis's search wins, and why: it met the rule where the first did
/// not; or both met it and it has the lower BIC; or neither did and it exceeds the
/// noise-widened bounds less (then the lower BIC), as the search's own fallback judges.
/// The same model on both, met alike (the grid fit both kept), stays with the first.
fn prefer_second(first: &Judged, second: &Judged) -> Option<String> {
    let wins = match (first.met, second.met) {
        _ if first.model == second.model && first.met == second.met => false,
        (false, true) => true,
        (true, false) => false,
        (true, true) => second.bic < first.bic,
        (false, false) => second
            .excess
            .total_cmp(&first.excess)
            .then(second.bic.total_cmp(&first.bic))
            .is_lt(),
    };
    wins.then(|| why_kept(second, first))
}

/// Why `kept`'s search won over `passed`'s (see [`prefer_second`]).
fn why_kept(kept: &Judged, passed: &Judged) -> String {
    match (kept.met, passed.met) {
        _ if kept.model == passed.model && kept.met == passed.met => {
            format!("both searches kept {}", kept.model)
        }
        (true, false) => "only its search met the rule".into(),
        (true, true) => format!(
            "both searches met the rule; its model has the lower BIC ({:.1} against {:.1})",
            kept.bic, passed.bic
        ),
        _ => format!(
            "neither search met the rule; it exceeds it no more beyond the measured colour's noise ({:.2} against {:.2})",
            kept.excess, passed.excess
        ),
    }
}

/// `kept` with the other axis's search recorded in its report: the axis line, and that
/// search's candidates after its own (their names say their axis), the lowest BIC over
/// both.
fn merged(
    mut kept: Material,
    kept_axis: BandDomain,
    passed: &Material,
    passed_axis: BandDomain,
    why: &str,
    started: Instant,
) -> Material {
    let passed_search = passed.fit.as_ref().and_then(|f| f.model_search.as_ref());
    if let Some(fit) = kept.fit.as_mut() {
        if let Some(search) = fit.model_search.as_mut() {
            let other_model = passed.fit.as_ref().map_or("–", |f| f.model.as_str());
            search.band_axis = Some(format!(
                "{}: {why}; on {} the search kept {other_model} (the search's other words are the {} search's)",
                kept_axis.name(),
                passed_axis.name(),
                kept_axis.name()
            ));
            if let Some(other) = passed_search {
                search.candidates.extend(other.candidates.iter().cloned());
            }
            if let Some(lowest) = search
                .candidates
                .iter()
                .filter(|c| c.error.is_none())
                .min_by(|a, b| a.bic.total_cmp(&b.bic))
            {
                search.lowest_bic = lowest.model.clone();
            }
            search.seconds = started.elapsed().as_secs_f64();
        }
        fit.seconds = started.elapsed().as_secs_f64();
    }
    kept
}

/// `material` (the search on `kept`) with the failure of the search on `failed` recorded.
fn with_failed_axis(
    mut material: Material,
    kept: BandDomain,
    failed: BandDomain,
    error: &Error,
    started: Instant,
) -> FitOutcome {
    if let Some(fit) = material.fit.as_mut() {
        if let Some(search) = fit.model_search.as_mut() {
            search.band_axis = Some(format!(
                "{}: the search on {} failed ({error})",
                kept.name(),
                failed.name()
            ));
            search.seconds = started.elapsed().as_secs_f64();
        }
        fit.seconds = started.elapsed().as_secs_f64();
    }
    FitOutcome::Material(Box::new(material))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn judged(model: &str, met: bool, bic: f64, excess: f64) -> Judged {
        Judged {
            model: model.into(),
            met,
            bic,
            excess,
        }
    }

    #[test]
    fn the_search_that_meets_its_rule_wins_then_the_lower_bic() {
        let wn = judged("gaussian:1x1+rt", true, 2000.0, 0.0);
        let wl = judged("gaussian:1x1+rt@wavelength", true, 1900.0, 0.0);
        assert!(
            prefer_second(&wn, &wl)
                .unwrap()
                .contains("lower BIC (1900.0")
        );
        assert!(prefer_second(&wl, &wn).is_none());
        // Meeting the rule comes before BIC.
        let unmet = judged("gaussian:2x2+rt@wavelength", false, 100.0, 0.5);
        assert!(prefer_second(&wn, &unmet).is_none());
        assert_eq!(
            prefer_second(&unmet, &wn).as_deref(),
            Some("only its search met the rule")
        );
        // Neither met: the smaller excess, then the lower BIC.
        let a = judged("gaussian:1x1+rt", false, 100.0, 0.8);
        let b = judged("gaussian:1x1+rt@wavelength", false, 900.0, 0.3);
        assert!(prefer_second(&a, &b).unwrap().contains("0.30 against 0.80"));
        let c = judged("gaussian:1x1+rt@wavelength", false, 90.0, 0.8);
        assert!(prefer_second(&a, &c).is_some());
        // The grid fit both kept stays with the first axis.
        let grid = judged("tabulated", true, 500.0, 0.0);
        assert!(prefer_second(&grid, &grid.clone()).is_none());
        assert_eq!(why_kept(&grid, &grid), "both searches kept tabulated");
    }
}
