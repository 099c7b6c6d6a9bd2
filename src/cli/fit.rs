//! `fluorite fit`: read matrices, fit, write material JSON, print a summary per file.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use fluorite::YieldForm;
use fluorite::colour::Light;
use fluorite::export::write_atomic;
use fluorite::fit::{FitOptions, FitOutcome, ModelChoice, Solver, Start, fit};
use fluorite::formats::{Format, ReadOptions, RowsAre};
use fluorite::measurement::Measurement;
use rayon::prelude::*;

/// Arguments of `fluorite fit`.
#[derive(clap::Args, Debug, Clone)]
pub struct FitArgs {
    /// Measured matrices (wide CSV, long CSV, BFC-450, WebFluor).
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Output file for one input, or a folder (existing, or ending in `/`) for several.
    /// Default: `fits/<input stem>.json`.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Input format (default: detected from the content).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
    /// What the rows of a wide matrix are (default: the corner label, else inferred).
    #[arg(long, value_enum)]
    pub rows: Option<RowsAre>,
    /// Treat zeros as missing cells (default: on for WebFluor, off otherwise).
    #[arg(long)]
    pub zero_is_missing: Option<bool>,
    /// Values are spectral densities per nm instead of radiance factors per emission bin.
    #[arg(long)]
    pub per_nm: bool,
    /// Refinement solver.
    #[arg(long, value_enum, default_value = "lbfgs")]
    pub solver: Solver,
    /// Starting point of the iterative solvers.
    #[arg(long, value_enum, default_value = "closed-form")]
    pub start: Start,
    /// Set aside cells within this many nm of the diagonal. Default: none (they are
    /// mostly fluorescence); the output says how much measured signal a guard sets aside.
    #[arg(long)]
    pub guard: Option<f64>,
    /// Yield form of the fluorophores: `energy` (constant energy yield Q, the paper's),
    /// `photon` (constant photon yield Φ; energy yield Φ·λi/λ̄e), or `auto` (energy unless
    /// its photon law binds and costs fit).
    #[arg(long = "yield", value_enum, default_value = "auto")]
    pub yield_choice: fluorite::fit::YieldChoice,
    /// Pin the energy quantum yield Q from outside knowledge (c = k/Q).
    #[arg(long, conflicts_with = "concentration")]
    pub quantum_yield: Option<f64>,
    /// Pin the concentration c from outside knowledge (Q = k/c).
    #[arg(long)]
    pub concentration: Option<f64>,
    /// Iteration limit of the refinement.
    #[arg(long, default_value_t = 500)]
    pub max_iterations: u64,
    /// Relative tolerance of the refinement (the automatic model search fits its candidates
    /// to at least 1e-5; a fixed --model gets this one).
    #[arg(long, default_value_t = fluorite::fit::DEFAULT_TOLERANCE)]
    pub tolerance: f64,
    /// Lights of the scene: the ΔE2000 report, the model search's bound and the colour
    /// term of parametric fits. Built-in names (d65, a, f11, uv) or CSV files, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "d65,a,f11,uv")]
    pub lights: Vec<String>,
    /// Spectral model: `tabulated` (one sample per grid wavelength, the default), `auto`
    /// (search from the smallest parametric model up), or `gaussian:KxB[/E][+rD|+rt]`
    /// (K fluorophores with B Gaussian bands, or A absorption and E emission bands;
    /// reflectance a sigmoid polynomial of degree D or tabulated; default degree: chosen).
    #[arg(long, value_parser = parse_model)]
    pub model: Option<ModelChoice>,
    /// Choose the smallest model whose ΔE2000 under every light of --lights is at most
    /// this (implies --model auto). Without it, `--model auto` takes the lowest BIC.
    #[arg(long)]
    pub max_delta_e: Option<f64>,
    /// Weight of the patch spectra under --lights against the matrix residual in
    /// parametric fits (0: matrix only).
    #[arg(long, default_value_t = fluorite::fit::search::DEFAULT_COLOUR_WEIGHT)]
    pub colour_weight: f64,
    /// Exit with code 1 when a fit did not converge or carries warnings.
    #[arg(long)]
    pub strict: bool,
    /// Also plot each fit against its data (next to the JSON).
    #[arg(long)]
    pub plot: bool,
    /// Also render a preview of each fitted material (next to the JSON).
    #[arg(long)]
    pub render: bool,
    /// After the summaries, print a Markdown table of accuracy and speed over all inputs.
    #[arg(long)]
    pub table: bool,
    /// Time each fit this many times and report the median (the table's and summary's
    /// time; the fit written is the first).
    #[arg(long, default_value_t = 1)]
    pub timing_runs: usize,
    /// Print nothing but errors.
    #[arg(short, long)]
    pub quiet: bool,
    /// Raw instrument EEMs: units, blank, inner filter, scatter.
    #[command(flatten)]
    pub eem: crate::cli::eem::EemArgs,
}

fn parse_model(text: &str) -> Result<ModelChoice, String> {
    text.parse::<ModelChoice>().map_err(|e| e.to_string())
}

/// Where each input's result goes.
fn output_paths(args: &FitArgs) -> anyhow::Result<Vec<PathBuf>> {
    let stem = |p: &Path| {
        p.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "material".into())
    };
    let into_folder = |dir: &Path| -> Vec<PathBuf> {
        args.inputs
            .iter()
            .map(|p| dir.join(format!("{}.json", stem(p))))
            .collect()
    };
    let paths = match &args.output {
        None => into_folder(Path::new("fits")),
        Some(out) => {
            let is_folder = out.is_dir() || out.as_os_str().to_string_lossy().ends_with('/');
            if is_folder {
                into_folder(out)
            } else if args.inputs.len() == 1 {
                vec![out.clone()]
            } else {
                anyhow::bail!(
                    "-o {}: several inputs need an output folder (an existing one, or a path ending in '/')",
                    out.display()
                );
            }
        }
    };
    let mut seen = std::collections::HashSet::new();
    for (p, input) in paths.iter().zip(&args.inputs) {
        if !seen.insert(p.clone()) {
            anyhow::bail!(
                "two inputs would write {} (second: {}); rename one or fit them separately",
                p.display(),
                input.display()
            );
        }
    }
    Ok(paths)
}

/// Runs `fluorite fit`.
pub fn run(args: FitArgs) -> anyhow::Result<ExitCode> {
    let lights = args
        .lights
        .iter()
        .map(|l| Light::parse(l))
        .collect::<Result<Vec<_>, _>>()
        .context("--lights")?;
    let options = FitOptions {
        solver: args.solver,
        guard_nm: args.guard,
        yield_choice: args.yield_choice,
        quantum_yield: args.quantum_yield,
        concentration: args.concentration,
        max_iterations: args.max_iterations,
        tolerance: args.tolerance,
        lights,
        start: args.start,
        model: match (args.model, args.max_delta_e) {
            (Some(model), _) => model,
            (None, Some(_)) => ModelChoice::Auto,
            (None, None) => ModelChoice::Tabulated,
        },
        max_delta_e: args.max_delta_e,
        colour_weight: args.colour_weight,
    };
    let read_options = ReadOptions {
        format: args.format,
        rows: args.rows,
        zero_is_missing: args.zero_is_missing,
        per_nm: args.per_nm,
    };
    let outputs = output_paths(&args)?;
    for out in &outputs {
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        }
    }
    // Files are independent: fit them in parallel, report in input order.
    let results: Vec<anyhow::Result<(Measurement, FitOutcome)>> = args
        .inputs
        .par_iter()
        .zip(&outputs)
        .enumerate()
        .map(|(index, (input, out))| {
            let eem = args.eem.options(index, args.inputs.len(), &read_options)?;
            let (m, preprocessing) = crate::cli::eem::read_prepared(input, &eem, &read_options)?;
            let mut outcome = fit(&m, &options)?;
            crate::cli::eem::attach(&mut outcome, preprocessing);
            if args.timing_runs > 1 {
                let mut times = vec![outcome.report().seconds];
                for _ in 1..args.timing_runs {
                    times.push(fit(&m, &options)?.report().seconds);
                }
                times.sort_by(f64::total_cmp);
                outcome.set_seconds(times[times.len() / 2]);
            }
            write_atomic(out, outcome.to_json().as_bytes())?;
            Ok((m, outcome))
        })
        .collect();
    let mut failed = 0;
    let mut flagged = 0;
    let mut rows = Vec::new();
    for ((input, out), result) in args.inputs.iter().zip(&outputs).zip(results) {
        match result {
            Err(e) => {
                failed += 1;
                eprintln!("fluorite: error: {}", format!("{e:#}").replace('\n', " "));
            }
            Ok((m, outcome)) => {
                let report = outcome.report();
                if !report.converged || !report.warnings.is_empty() {
                    flagged += 1;
                }
                if !args.quiet {
                    print!("{}", summary(input, out, &m, &outcome));
                }
                rows.push(if options.model == ModelChoice::Tabulated {
                    table_row(&m, &outcome)
                } else {
                    model_table_row(&m, &outcome)
                });
                if let FitOutcome::Material(material) = &outcome {
                    if args.plot {
                        crate::cli::plot::plot_fit(material, &m, out)
                            .with_context(|| format!("plotting {}", out.display()))?;
                    }
                    if args.render {
                        crate::cli::render::preview(material, out)
                            .with_context(|| format!("rendering {}", out.display()))?;
                    }
                }
            }
        }
    }
    if args.table && options.model != ModelChoice::Tabulated {
        println!(
            "\n| material | model chosen | parameters | ΔE D65 | ΔE A | ΔE F11 | ΔE UV | bound met | conservation laws | candidates | fit time (ms) |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for row in rows {
            println!("{row}");
        }
    } else if args.table {
        println!(
            "\n| material | k = c·Q | c (feasible) | fluorescence residual | diagonal RMSE | ΔE D65 | ΔE A | ΔE F11 | ΔE UV | iterations | time (ms) |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for row in rows {
            println!("{row}");
        }
    }
    Ok(if failed > 0 {
        ExitCode::from(2)
    } else if args.strict && flagged > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

/// The per-file summary printed after a fit.
fn summary(input: &Path, out: &Path, m: &Measurement, outcome: &FitOutcome) -> String {
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
                if let Some(skipped) = &search.skipped {
                    let _ = writeln!(s, "    skipped {skipped}");
                }
                for c in &search.candidates {
                    let de: Vec<String> = c
                        .delta_e2000
                        .iter()
                        .map(|(l, v)| format!("{l} {v:.2}"))
                        .collect();
                    let _ = writeln!(
                        s,
                        "    {:<22} {:>4} p   ΔE {}   BIC {:.1}   {:.1} ms{}",
                        c.model,
                        c.parameters,
                        if de.is_empty() {
                            "–".into()
                        } else {
                            de.join(" ")
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
                let (symbol, varying) = match f.yield_form {
                    YieldForm::Energy => (
                        "Q",
                        format!(
                            "photon yield Φ(λ) = {:.3}–{:.3} (Φ(λmin) = Q·λ̄e/λmin)",
                            f.photon_yield_with_mean(hi, mean),
                            f.photon_yield_with_mean(lo, mean)
                        ),
                    ),
                    YieldForm::Photon => (
                        "Φ",
                        format!(
                            "energy yield Q(λ) = Φ·λ/λ̄e = {:.3}–{:.3}",
                            f.energy_yield_with_mean(lo, mean),
                            f.energy_yield_with_mean(hi, mean)
                        ),
                    ),
                };
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
    if !report.delta_e2000.is_empty() {
        let de: Vec<String> = report
            .delta_e2000
            .iter()
            .map(|(l, v)| format!("{l} {v:.2}"))
            .collect();
        let reference = if report.reference_filled_cells == 0 {
            "against every cell as measured".to_string()
        } else {
            format!(
                "against the cells as measured; {} missing cells filled from the model carry {:.2} % of the patch's light",
                report.reference_filled_cells,
                100.0 * report.reference_filled_share
            )
        };
        let _ = writeln!(s, "  ΔE2000: {}   ({reference})", de.join("   "));
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

/// One Markdown table row for `--table` with a parametric model or the search.
fn model_table_row(m: &Measurement, outcome: &FitOutcome) -> String {
    let report = outcome.report();
    let de = |l: &str| {
        report
            .delta_e2000
            .get(l)
            .map(|v| format!("{v:.2}"))
            .unwrap_or_else(|| "–".into())
    };
    let laws = match outcome {
        FitOutcome::Material(material) => {
            let failed = fluorite::check::check_material(material).failed();
            if failed.is_empty() {
                "all hold".to_string()
            } else {
                format!("FAILED: {failed:?}")
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
        "| {} | {} | {} | {} | {} | {} | {} | {met} | {laws} | {tried} | {:.1} |",
        m.name,
        report.model,
        report.parameter_count,
        de("d65"),
        de("a"),
        de("f11"),
        de("uv"),
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
fn table_row(m: &Measurement, outcome: &FitOutcome) -> String {
    let report = outcome.report();
    let de = |l: &str| {
        report
            .delta_e2000
            .get(l)
            .map(|v| format!("{v:.2}"))
            .unwrap_or_else(|| "–".into())
    };
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
        "| {} | {k} | {c} | {:.1} % | {:.4} | {} | {} | {} | {} | {} | {:.2} |",
        m.name,
        100.0 * report.rel_residual_fluorescence,
        report.rmse_diagonal,
        de("d65"),
        de("a"),
        de("f11"),
        de("uv"),
        report.iterations,
        1e3 * report.seconds
    )
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
