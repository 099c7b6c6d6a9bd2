//! What `fluorite fit` and `fluorite check` print: fit's per-file summary and Markdown
//! tables, the joint and series fits' reports, check's report (output formatting apart
//! from the commands and the library, as ripgrep keeps its printer).

use std::collections::BTreeMap;
use std::path::Path;

use fluorite::YieldForm;
use fluorite::check::{CheckReport, FORM_TOLERANCE, Law, Status};
use fluorite::fit::FitOutcome;
use fluorite::fit::joint::JointFit;
use fluorite::fit::joint::reference::{AnalyteMatch, Reference};
use fluorite::fit::series::SeriesFit;
use fluorite::measurement::Measurement;

/// How the energy form's photon yield peaks, after its range.
const PHOTON_LIMIT: &str = " (Φ(λmin) = Q·λ̄e/λmin)";

/// The Markdown table of accuracy and speed over all inputs (`fit --table`): the model
/// table for parametric fits, the grid table otherwise.
pub fn fit_table(parametric: bool, rows: &[String]) -> String {
    let header = if parametric {
        "| material | model chosen | parameters | ΔE D65 | ΔE A | ΔE F11 | ΔE UV | bound met | conservation laws | candidates | fit time (ms) |"
    } else {
        "| material | k = c·Q | c (feasible) | fluorescence residual | diagonal RMSE | ΔE D65 | ΔE A | ΔE F11 | ΔE UV | iterations | time (ms) |"
    };
    let mut out = format!("\n{header}\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    for row in rows {
        out.push_str(row);
        out.push('\n');
    }
    out
}

/// The per-file summary printed after a fit.
pub fn summary(input: &Path, out: &Path, m: &Measurement, outcome: &FitOutcome) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let report = outcome.report();
    let _ = writeln!(s, "{} → {}", input.display(), out.display());
    for note in &m.notes {
        let _ = writeln!(s, "  note: {note}");
    }
    match outcome {
        FitOutcome::Material(material) => {
            if !report.model.is_empty() {
                let _ = writeln!(
                    s,
                    "  model {} ({} parameters{})",
                    report.model,
                    report.parameter_count,
                    report
                        .bic
                        .map(|b| format!(", BIC {b:.1}"))
                        .unwrap_or_default()
                );
            }
            if let Some(escalation) = &report.escalation {
                let _ = writeln!(
                    s,
                    "  default fit: {}",
                    if escalation.escalated {
                        format!("escalated beyond one fluorophore: {}", escalation.reason)
                    } else {
                        escalation.reason.clone()
                    }
                );
            }
            if let Some(search) = &report.model_search {
                let _ = writeln!(
                    s,
                    "  search ({}): {} of {} candidates tried in {:.1} ms; {}; lowest BIC: {}",
                    search.rule,
                    search.chosen,
                    search.candidates.len(),
                    1e3 * search.seconds,
                    if search.met { "met" } else { "NOT met" },
                    search.lowest_bic
                );
                if search.met && !search.misses_within_noise.is_empty() {
                    let _ = writeln!(
                        s,
                        "    met within the measured colour's noise only: {}",
                        search
                            .misses_within_noise
                            .iter()
                            .map(|(l, [de, noise])| format!(
                                "{l} {de:.2} (bound {}, noise RMS {noise:.2})",
                                search.max_delta_e.unwrap_or(f64::NAN)
                            ))
                            .collect::<Vec<_>>()
                            .join(", ")
                    );
                }
                if let Some(skipped) = &search.skipped {
                    let _ = writeln!(s, "    skipped {skipped}");
                }
                if let Some(verdict) = &search.matrix_test {
                    let _ = writeln!(s, "    matrix test: {verdict}");
                }
                if let Some(axis) = &search.band_axis {
                    let _ = writeln!(s, "    band axis: {axis}");
                }
                for c in &search.candidates {
                    let _ = writeln!(
                        s,
                        "    {:<22} {:>4} p   ΔE {}   BIC {:.1}   {:.1} ms{}",
                        c.model,
                        c.parameters,
                        if c.delta_e2000.is_empty() {
                            "–".into()
                        } else {
                            per_light(&c.delta_e2000, " ")
                        },
                        c.bic,
                        1e3 * c.seconds,
                        c.error
                            .as_ref()
                            .map(|e| format!("   failed: {e}"))
                            .unwrap_or_default()
                    );
                }
            }
            if material.fluorophores.is_empty() {
                let _ = writeln!(s, "  plain reflector: c = 0 (no fluorescence)");
            }
            for (n, f) in material.fluorophores.iter().enumerate() {
                let [c_lo, c_hi] = f
                    .concentration_range
                    .unwrap_or([f.concentration, f.concentration]);
                let label = if material.fluorophores.len() > 1 {
                    format!("  [{}] ", n + 1)
                } else {
                    "  ".into()
                };
                let mean = f.emission_mean_nm();
                // The yield that varies with λi, over the absorbed wavelengths: Φ(λ) from
                // the longest to the shortest (energy form), Q(λ) from the shortest to the
                // longest (photon form).
                let [lo, hi] = absorbed_nm(f).unwrap_or([f64::NAN; 2]);
                let photon = [hi, lo].map(|l| f.photon_yield_with_mean(l, mean));
                let energy = [lo, hi].map(|l| f.energy_yield_with_mean(l, mean));
                let (symbol, varying, range, note) = match f.yield_form {
                    YieldForm::Energy => ("Q", "photon yield Φ(λ)", photon, PHOTON_LIMIT),
                    YieldForm::Photon => ("Φ", "energy yield Q(λ) = Φ·λ/λ̄e", energy, ""),
                };
                let varying = format!("{varying} = {:.3}–{:.3}{note}", range[0], range[1]);
                let _ = writeln!(
                    s,
                    "{label}k = c·{symbol} = {:.4}   c = {:.4} (feasible {:.4}–{:.4})   {symbol} = {:.4} ({} form)   λ̄e = {:.1} nm   {varying}",
                    f.k(),
                    f.concentration,
                    c_lo,
                    c_hi,
                    f.quantum_yield,
                    f.yield_form.name(),
                    mean,
                );
            }
            if !material.fluorophores.is_empty() {
                let _ = writeln!(s, "  gauge: {}", report.gauge);
            }
            if !report.yield_choice.is_empty() {
                let _ = writeln!(s, "  yield form: {}", report.yield_choice);
            }
        }
        FitOutcome::Shapes(shapes) => {
            let _ = writeln!(
                s,
                "  absorption and emission shapes only; k = {:.4e} in data units",
                shapes.k_data_units
            );
            for u in &shapes.undetermined {
                let _ = writeln!(s, "  undetermined: {u}");
            }
        }
    }
    let diagonal = if m.has_diagonal {
        format!(", diagonal RMSE {:.4}", report.rmse_diagonal)
    } else {
        String::new()
    };
    let guard = if report.guard_nm > 0.0 {
        format!(
            "guard band ({} nm) set aside measured cells holding {:.1} % of the fluorescent signal",
            report.guard_nm,
            100.0 * report.guard_signal_fraction
        )
    } else {
        "every measured cell fitted (no guard band)".to_string()
    };
    let _ = writeln!(
        s,
        "  residual: fluorescent cells {:.1} % (relative){diagonal}; noise σ ≈ {:.3e}; {guard}",
        100.0 * report.rel_residual_fluorescence,
        report.noise_sigma,
    );
    if let Some(crosstalk) = &report.crosstalk {
        let _ = writeln!(s, "  {}", fluorite::fit::crosstalk::describe(crosstalk));
    }
    if !report.delta_e2000.is_empty() {
        let reference = if report.reference_filled_cells == 0 {
            "against every cell as measured".to_string()
        } else {
            let worth = report.reference_filled_worth();
            format!(
                "against the cells as measured; {} missing cells filled from the model carry {:.2} % of the patch's light, worth ΔE2000 up to {worth:.2}",
                report.reference_filled_cells,
                100.0 * report.reference_filled_share
            )
        };
        let _ = writeln!(
            s,
            "  ΔE2000: {}   ({reference})",
            per_light(&report.delta_e2000, "   ")
        );
        if !report.delta_e2000_noise.is_empty() {
            let _ = writeln!(
                s,
                "  the measured colour's own noise (σ alone, RMS ΔE2000): {}",
                per_light(&report.delta_e2000_noise, "   ")
            );
        }
    }
    let _ = writeln!(
        s,
        "  solver {}: {} after {} iterations, {:.2} ms",
        report.solver,
        if report.converged {
            "converged"
        } else {
            "NOT converged"
        },
        report.iterations,
        1e3 * report.seconds
    );
    for w in &report.warnings {
        let _ = writeln!(s, "  warning: {w}");
    }
    s
}

/// The table cells of the worst ΔE2000 under d65, A, F11 and UV ("–" where the fit did
/// not report one).
fn delta_e_cells(report: &fluorite::material::FitReport) -> String {
    ["d65", "a", "f11", "uv"]
        .iter()
        .map(|l| {
            report
                .delta_e2000
                .get(*l)
                .map(|v| format!("{v:.2}"))
                .unwrap_or_else(|| "–".into())
        })
        .collect::<Vec<_>>()
        .join(" | ")
}

/// One Markdown table row for `--table` with a parametric model or the search.
pub fn model_table_row(m: &Measurement, outcome: &FitOutcome) -> String {
    let report = outcome.report();
    let delta_e = delta_e_cells(report);
    let laws = match outcome {
        FitOutcome::Material(material) => {
            let report = fluorite::check::check_material(material);
            if report.failed().is_empty() {
                "all hold".to_string()
            } else {
                format!("FAILED: {}", report.failed_names())
            }
        }
        FitOutcome::Shapes(_) => "–".into(),
    };
    let (met, tried) = match &report.model_search {
        Some(search) => (
            if search.met { "yes" } else { "no" },
            search.candidates.len(),
        ),
        None => ("–", 1),
    };
    format!(
        "| {} | {} | {} | {delta_e} | {met} | {laws} | {tried} | {:.1} |",
        m.name,
        report.model,
        report.parameter_count,
        1e3 * report.seconds
    )
}

/// Shortest and longest wavelength where a > 0 (nm): the zero samples beside the absorbed
/// ones bound the interval (a is linear between samples).
fn absorbed_nm(f: &fluorite::Fluorophore) -> Option<[f64; 2]> {
    let a = &f.absorption;
    let first = a.value.iter().position(|&v| v > 0.0)?;
    let last = a.value.iter().rposition(|&v| v > 0.0)?;
    Some([
        a.wavelength_nm[first.saturating_sub(1)],
        a.wavelength_nm[(last + 1).min(a.len() - 1)],
    ])
}

/// One Markdown table row for `--table`.
pub fn table_row(m: &Measurement, outcome: &FitOutcome) -> String {
    let report = outcome.report();
    let delta_e = delta_e_cells(report);
    let (k, c) = match outcome {
        FitOutcome::Material(material) => match material.fluorophores.first() {
            Some(f) => {
                let [lo, hi] = f.concentration_range.unwrap_or([f.concentration; 2]);
                let k = match f.yield_form {
                    YieldForm::Energy => format!("{:.3}", f.k()),
                    YieldForm::Photon => format!("{:.3} (c·Φ, photon form)", f.k()),
                };
                (k, format!("{:.3} ({lo:.3}–{hi:.3})", f.concentration))
            }
            None => ("0".into(), "0 (plain reflector)".into()),
        },
        FitOutcome::Shapes(s) => (
            format!("{:.3e} (data units)", s.k_data_units),
            "undetermined".into(),
        ),
    };
    format!(
        "| {} | {k} | {c} | {:.1} % | {:.4} | {delta_e} | {} | {:.2} |",
        m.name,
        100.0 * report.rel_residual_fluorescence,
        report.rmse_diagonal,
        report.iterations,
        1e3 * report.seconds
    )
}

/// `fluorite check`'s report: one line per law, then the violations and the yields.
pub fn check_report(report: &CheckReport) -> String {
    let mut out = format!(
        "{}{}: {}\n",
        report.material,
        report
            .source
            .as_ref()
            .map(|s| format!(" ({s})"))
            .unwrap_or_default(),
        if report.valid {
            "valid".to_string()
        } else {
            format!("VIOLATES {}", report.failed_names())
        }
    );
    for l in &report.laws {
        let status = match l.status {
            Status::Pass => "ok  ",
            Status::Fail => "FAIL",
            Status::NotEvaluated => "n/a ",
        };
        let mut line = format!("  {status} {:<20} {:<40}", l.law.name(), l.statement);
        // Structural laws have a verdict, not a meaningful margin.
        let structural = matches!(
            l.law,
            Law::Schema | Law::FiniteNonNegative | Law::SortedWavelengths
        );
        if l.law == Law::Forms && l.status == Status::Pass && report.forms.is_none() {
            line.push_str(" (no forms block: tabulated spectra)");
        } else if !structural && l.status != Status::NotEvaluated && !l.margin.is_nan() {
            // `+ 0.0` turns −0 into 0 for printing.
            line.push_str(&format!(" margin {:+.3e}", l.margin + 0.0));
            if let Some(at) = &l.worst_at {
                if l.law == Law::Forms {
                    line.push_str(&format!(" worst {} off by {:.3e}", at, l.worst_value));
                } else {
                    line.push_str(&format!(" worst {} = {:.6}", at, l.worst_value));
                }
            }
            if let Some(nm) = l.worst_nm {
                line.push_str(&format!(" at {nm} nm"));
            }
        }
        out.push_str(line.trim_end());
        out.push('\n');
        if l.status == Status::Fail {
            for v in &l.violations {
                out.push_str(&format!("         - {v}\n"));
            }
        }
    }
    for (n, f) in report.fluorophores.iter().enumerate() {
        let symbol = match f.yield_form {
            YieldForm::Energy => "Q",
            YieldForm::Photon => "Φ",
        };
        out.push_str(&format!(
            "  fluorophores[{n}]: k = c·{symbol} = {:.6} ({} form, {symbol} = {:.6}), λ̄e = {:.2} nm",
            f.k,
            f.yield_form.name(),
            f.yield_value,
            f.mean_emission_nm
        ));
        match (f.yield_form, f.absorbed_nm) {
            (YieldForm::Energy, Some([lo, hi])) => {
                if let Some([pl, ph]) = f.photon_yield_range {
                    out.push_str(&format!(
                        ", photon quantum yield Φ(λ) = Q·λ̄e/λ from {pl:.4} (at {hi} nm) to {ph:.4} (at {lo} nm)"
                    ));
                }
            }
            (YieldForm::Photon, Some([lo, hi])) => {
                if let Some([el, eh]) = f.energy_yield_range {
                    out.push_str(&format!(
                        ", energy quantum yield Q(λ) = Φ·λ/λ̄e from {el:.4} (at {lo} nm) to {eh:.4} (at {hi} nm)"
                    ));
                }
            }
            _ => {}
        }
        out.push('\n');
    }
    if let Some(f) = &report.forms {
        let model = if f.model.is_empty() {
            "(no model name)"
        } else {
            &f.model
        };
        let agreement = if f.worst_deviation.is_nan() {
            "not compared with the samples".to_string()
        } else if f.worst_deviation <= FORM_TOLERANCE {
            format!(
                "samples match within {:.1e} of the peak (tolerance {FORM_TOLERANCE:.0e})",
                f.worst_deviation
            )
        } else {
            format!(
                "samples DO NOT match: off by up to {:.3e} of the peak (tolerance {FORM_TOLERANCE:.0e})",
                f.worst_deviation
            )
        };
        out.push_str(&format!(
            "  forms: {model}, {} forms with {} parameters, {agreement}\n",
            f.forms, f.parameters
        ));
        for note in &f.notes {
            out.push_str(&format!("  note: {note}\n"));
        }
    }
    out
}

/// ΔE2000 per light as `light value` pairs (two decimals) joined by `separator`.
fn per_light(delta_e2000: &BTreeMap<String, f64>, separator: &str) -> String {
    delta_e2000
        .iter()
        .map(|(light, de)| format!("{light} {de:.2}"))
        .collect::<Vec<_>>()
        .join(separator)
}

/// What `fit --joint` prints for a concentration series: the shared yield, per file c, k
/// and accuracy, the noise, the solver and every warning.
pub fn series_summary(fit: &SeriesFit) -> String {
    let symbol = match fit.yield_form {
        YieldForm::Energy => "Q",
        YieldForm::Photon => "Φ",
    };
    let mut out = format!(
        "concentration series of {} files, {} form: {symbol} = {:.4} ± {:.4}, shared with r, a, e (mean emission {:.1} nm)\n",
        fit.files.len(),
        fit.yield_form.name(),
        fit.quantum_yield,
        fit.quantum_yield_std_error,
        fit.emission.mean_wavelength_nm()
    );
    for f in &fit.files {
        out += &format!(
            "  {}: c = {:.4} ± {:.4}, k = {:.4} ± {:.4}, residual RMS {:.2e}, ΔE2000 {}\n",
            f.name,
            f.concentration,
            f.concentration_std_error,
            f.k,
            f.k_std_error,
            f.residual_rms,
            per_light(&f.delta_e2000, ", ")
        );
    }
    out += &format!(
        "  noise σ ≈ {:.2e} (anti-Stokes), residual σ {:.2e}: errors scaled by {:.2e}\n  gauss-newton: {} after {} iterations, {:.3} s\n",
        fit.noise_sigma,
        fit.residual_sigma,
        fit.error_sigma,
        if fit.converged {
            "converged"
        } else {
            "stopped"
        },
        fit.iterations,
        fit.seconds
    );
    for w in &fit.warnings {
        out += &format!("  warning: {w}\n");
    }
    out
}

/// The split-half verdict in words.
fn split_text(fit: &JointFit) -> String {
    match &fit.split_half {
        Some(s) => format!(
            "min Tucker congruence {:.3} ({})",
            s.min_congruence,
            if s.validated {
                "validated, ≥ 0.95"
            } else {
                "NOT validated, < 0.95"
            }
        ),
        None if fit.samples.len() < 4 => "not run (it needs at least 4 samples)".into(),
        None => "skipped (--no-split-half)".into(),
    }
}

/// What `fit --joint` prints for one EEM fit: where it went, how good it is (explained
/// variance, core consistency, split-half), its components, residuals and, with a
/// reference, each analyte's best component.
pub fn joint_summary(fit: &JointFit, dir: &Path, matches: Option<&[AnalyteMatch]>) -> String {
    let k = fit.components.len();
    let mut out = format!(
        "K = {k} → {}/ (model.json, scores.csv, component-*.json, components.png)\n  explained variance {:.4} %, core consistency {:.1} %, split-half {}\n  {} sweeps ({}), fit {:.1} ms (+ {:.1} ms diagnostics); {} cells fitted, {} missing or masked\n",
        dir.display().to_string().trim_end_matches('/'),
        100.0 * fit.explained_variance,
        fit.core_consistency,
        split_text(fit),
        fit.iterations,
        if fit.converged {
            "converged"
        } else {
            "NOT converged: raise --max-iterations"
        },
        1e3 * fit.seconds,
        1e3 * fit.diagnostics_seconds,
        fit.measured_cells,
        fit.missing_cells
    );
    for (c, comp) in fit.components.iter().enumerate() {
        out.push_str(&format!(
            "  component {}: excitation max {} nm, emission max {} nm, {:.1} % of the model\n",
            c + 1,
            comp.peak_excitation_nm,
            comp.peak_emission_nm,
            100.0 * comp.share
        ));
        if let Some(o) = &comp.scatter {
            out.push_str(&format!("    {}\n", scatter_text(o)));
        }
        if let Some(share) = comp.image_share {
            out.push_str(&format!(
                "    second-order image: {:.1} % of its signal on the emission grid (its emission above is first order)\n",
                100.0 * share
            ));
        }
    }
    if let Some(note) = &fit.second_order_note {
        out.push_str(&format!("  second-order image: none ({note})\n"));
    }
    if let Some(image) = &fit.second_order {
        let nodes: Vec<String> = image
            .wavelength_nm
            .iter()
            .zip(&image.gain)
            .map(|(l, g)| format!("{l:.0} {g:.3}"))
            .collect();
        out.push_str(&format!(
            "  second-order image: the data see e(λo) + G(λo)·e(λo/2); G fitted, shared (nm G: {})\n",
            nodes.join(", ")
        ));
    }
    if let Some((worst, r)) = fit
        .samples
        .iter()
        .zip(&fit.residual_per_sample)
        .max_by(|a, b| a.1.total_cmp(b.1))
    {
        out.push_str(&format!(
            "  residual per sample (RMS relative): worst {worst} {:.2} %, median {:.2} % (scores.csv lists all)\n",
            100.0 * r,
            100.0 * fluorite::numeric::median(&fit.residual_per_sample)
        ));
    }
    for m in matches.into_iter().flatten() {
        out.push_str(&format!(
            "  {}: best component {}, R² {:.4} (squared Pearson correlation of scores and reference)\n",
            m.analyte, m.component, m.r_squared
        ));
    }
    out
}

/// The scatter check of a component: its emission's share inside the Rayleigh bands at
/// its excitation maximum, each band, and the Raman bands' share.
fn scatter_text(o: &fluorite::fit::joint::scatter::ScatterOverlap) -> String {
    use fluorite::eem::scatter::ScatterLine;
    let bands = |raman: bool| {
        o.lines
            .iter()
            .filter(|l| matches!(l.line, ScatterLine::Raman1 | ScatterLine::Raman2) == raman)
            .map(|l| {
                format!(
                    "{} {:.0}–{:.0} nm {:.1} %",
                    l.line.name(),
                    l.from_nm,
                    l.to_nm,
                    100.0 * l.share
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut text = format!(
        "scatter: {:.1} % of its emission inside a scatter band at its excitation maximum ({} nm: {}; water Raman, where Stokes emission may lie, {:.1} %: {})",
        100.0 * o.rayleigh_share,
        o.excitation_nm,
        bands(false),
        100.0 * o.raman_share,
        bands(true)
    );
    if o.on_scatter_line {
        text.push_str(&format!(
            "; ON A SCATTER LINE (over {:.0} %): it may hold scatter, or the second-order image (λo = 2λ) of its own emission near the excitation; widen the band (--scatter-width rayleigh1=NM or rayleigh2=NM) to tell",
            100.0 * fluorite::fit::joint::scatter::MAX_RAYLEIGH_SHARE
        ));
    }
    text
}

/// One row of the joint fit's sweep table ([`joint_sweep_table`]).
pub fn joint_sweep_row(fit: &JointFit, matches: Option<&[AnalyteMatch]>) -> Vec<String> {
    let mut row = vec![
        fit.components.len().to_string(),
        format!("{:.3}", 100.0 * fit.explained_variance),
        format!("{:.1}", fit.core_consistency),
        fit.split_half
            .as_ref()
            .map(|s| format!("{:.3}", s.min_congruence))
            .unwrap_or_else(|| "–".into()),
        format!(
            "{:.2}",
            100.0 * fluorite::numeric::median(&fit.residual_per_sample)
        ),
        fit.iterations.to_string(),
        format!("{:.1}", 1e3 * fit.seconds),
    ];
    if let Some(m) = matches {
        row.extend(
            m.iter()
                .map(|m| format!("{:.3} (C{})", m.r_squared, m.component)),
        );
    }
    row
}

/// The Markdown table over the fitted K (`fit --joint --components 2,3,4`): quality per K
/// and, with a reference, R² per analyte.
pub fn joint_sweep_table(rows: &[Vec<String>], reference: Option<&Reference>) -> String {
    let mut header = vec![
        "K",
        "explained %",
        "core consistency %",
        "split-half min congruence",
        "median residual %",
        "sweeps",
        "fit ms",
    ]
    .into_iter()
    .map(String::from)
    .collect::<Vec<_>>();
    if let Some(r) = reference {
        header.extend(r.analytes.iter().map(|a| format!("R² {a}")));
    }
    let mut out = format!("| {} |\n", header.join(" | "));
    out.push_str(&format!("|{}\n", "---|".repeat(header.len())));
    for row in rows {
        out.push_str(&format!("| {} |\n", row.join(" | ")));
    }
    out
}

/// The head of `render --report`: what was measured, and the table's header.
pub fn furnace_header(settings: &fluorite::render::RenderSettings, runs: usize) -> String {
    format!(
        "Furnace, {}×{}, {} spp, seed {}: relative std of Y over the sphere's pixels; median time of {runs} renders.\n\n| material | light | noise, paper | time | noise, light-aware | time | light-aware noise at the paper's time |\n|---|---|---|---|---|---|---|\n",
        settings.width, settings.height, settings.samples_per_pixel, settings.seed
    )
}

/// One row of `render --report`: the paper's sampling against the light-aware one.
pub fn furnace_row(
    material: &fluorite::Material,
    light: &fluorite::colour::Light,
    paper: &fluorite::render::report::NoiseReport,
    light_aware: &fluorite::render::report::NoiseReport,
) -> String {
    format!(
        "| {} | {} | {:.3} | {:.3} s | {:.3} | {:.3} s | {:.3} |\n",
        material.name,
        light.name,
        paper.noise,
        paper.seconds,
        light_aware.noise,
        light_aware.seconds,
        light_aware.noise_at_time_of(paper)
    )
}

/// Prints the figures written (unless `quiet`) and, always, what was skipped.
pub fn figures(figures: &fluorite::pipeline::beside::Figures, quiet: bool) {
    if !quiet {
        for path in &figures.written {
            println!("wrote {}", path.display());
        }
    }
    for reason in &figures.skipped {
        eprintln!("fluorite: skipped {reason}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fluorite::material::FitReport;
    use fluorite::{Fluorophore, Material, Spectrum};

    /// a: a triangle 400–500 nm (absorbed 400–500), e: flat on 550–650 nm (λ̄e = 600),
    /// c = 0.5 with the yield 0.8 in `form`.
    fn material(form: YieldForm) -> Material {
        let mut m = Material::new(
            "hand",
            Spectrum::new(vec![300.0, 800.0], vec![0.5, 0.5], "r").unwrap(),
            vec![Fluorophore {
                concentration: 0.5,
                quantum_yield: 0.8,
                yield_form: form,
                concentration_range: None,
                absorption: Spectrum::new(vec![400.0, 450.0, 500.0], vec![0.0, 1.0, 0.0], "a")
                    .unwrap(),
                emission: Spectrum::new(vec![550.0, 650.0], vec![0.01, 0.01], "e").unwrap(),
            }],
        );
        m.fit = Some(FitReport::default());
        m
    }

    fn lines(form: YieldForm) -> (String, String) {
        let m = material(form);
        let grid: Vec<f64> = (0..=40).map(|i| 380.0 + 10.0 * i as f64).collect();
        let data =
            fluorite::model::predict(&m, "hand", &grid, &grid, fluorite::Units::PerBin, true);
        let outcome = FitOutcome::Material(Box::new(m));
        (
            summary(Path::new("in.csv"), Path::new("out.json"), &data, &outcome),
            table_row(&data, &outcome),
        )
    }

    #[test]
    fn summary_states_the_yield_form_and_the_varying_yield() {
        // Photon form: Φ = 0.8, energy yield Φ·λ/600 from 400/600·0.8 to 500/600·0.8.
        let (text, row) = lines(YieldForm::Photon);
        assert!(
            text.contains("k = c·Φ = 0.4000")
                && text.contains("Φ = 0.8000 (photon form)")
                && text.contains("λ̄e = 600.0 nm")
                && text.contains("energy yield Q(λ) = Φ·λ/λ̄e = 0.533–0.667"),
            "{text}"
        );
        assert!(row.contains("| 0.400 (c·Φ, photon form) |"), "{row}");
        // Energy form: Q = 0.8, photon yield 0.8·600/λ from 0.960 (500 nm) to 1.200.
        let (text, row) = lines(YieldForm::Energy);
        assert!(
            text.contains("k = c·Q = 0.4000")
                && text.contains("Q = 0.8000 (energy form)")
                && text.contains("photon yield Φ(λ) = 0.960–1.200"),
            "{text}"
        );
        assert!(row.contains("| 0.400 |"), "{row}");
    }
}
