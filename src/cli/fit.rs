//! `fluorite fit`: read matrices, fit, write material JSON, print a summary per file (the
//! work between reading and writing is [`fluorite::pipeline`]'s).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use fluorite::colour::Light;
use fluorite::fit::{FitOptions, FitOutcome, ModelChoice, Solver, Start};
use fluorite::formats::{Format, ReadOptions, RowsAre};
use fluorite::pipeline::single::{
    Fitted, create_folders, fit_file_timed, output_paths, write_outcome,
};
use fluorite::pipeline::{InputOptions, JointRequest, beside};
use rayon::prelude::*;

use crate::cli::joint::{JointArgs, JointRun};
use crate::cli::printer;

/// The input layouts `fit --help` lists (after the options).
pub const INPUT_LAYOUTS: &str = "\
Input layouts (told from the content; --format forces one; details: docs/formats.md):
  wide CSV   a corner cell, then the column wavelengths (nm); each row starts with its
             wavelength. Rows are excitation by default; a corner label `ex\\em` or
             `em\\ex`, or --rows, says otherwise (else the signal's side of the diagonal).
             Delimiter `,` `;` or tab.
  long CSV   one cell per line, columns excitation_nm, emission_nm, value (any order).
  BFC-450    Labsphere BFC-450 matrix files (rows are emission).
  WebFluor   whitespace matrix: first line emission wavelengths, rows excitation;
             zeros are missing cells.
  OpenEXR    bispectral spectral OpenEXR (Fichet, Mercier, Wilkie 2021), one uniform image.
  raw EEMs   instrument EEMs in arbitrary units (--units, --blank, --absorbance,
             --keep-scatter, --scatter-width; docs/eem.md).";

/// Arguments of `fluorite fit`.
#[derive(clap::Args, Debug, Clone)]
pub struct FitArgs {
    /// Measured matrices (wide CSV, long CSV, BFC-450, WebFluor, OpenEXR, raw instrument
    /// EEMs; layouts below).
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
    /// Iteration limit of the refinement (with --joint: of the PARAFAC sweeps, or of the
    /// series' Gauss-Newton).
    #[arg(long, default_value_t = 500)]
    pub max_iterations: u64,
    /// Relative tolerance of the refinement (the automatic model search fits its candidates
    /// to at least 1e-5; a fixed --model gets this one). Joint fits keep their own
    /// convergence tests (PARAFAC: relative loss change; series: change of ‖r‖ against ‖M‖,
    /// 1e-9).
    #[arg(long, default_value_t = fluorite::fit::DEFAULT_TOLERANCE)]
    pub tolerance: f64,
    /// Lights of the scene: the ΔE2000 report, the model search's bound and the colour
    /// term of parametric fits. Built-in names (d65, a, f11, uv) or CSV files, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "d65,a,f11,uv")]
    pub lights: Vec<String>,
    /// Spectral model. `as-needed` (the default): one fluorophore sampled at every grid
    /// wavelength, kept when its ΔE2000 against the matrix is ≤ 1 under d65, a and f11,
    /// and uv where the excitation grid holds the 365 nm LED's rows (or within the
    /// colour's noise, in ΔE2000 and in χ², or within 1 of the cells it fitted where the
    /// rest of the miss is the crosstalk next to the diagonal it removed), unless that colour rests on cells the file does not hold, filled
    /// from a fit that leaves structure; otherwise the first parametric model the noise-aware search keeps under
    /// those lights (as `auto --max-delta-e 1 --noise-aware-bound --lights d65,a,f11,uv`: each light held to
    /// that bound or its measured colour's noise, candidates tested against the matrix; when none meets them
    /// all, whichever of the grid fit, the search's closest and the search under d65, a
    /// and f11 alone exceeds the bounds least in total, with a warning); the summary and the JSON (`fit.escalation`) say which and why. Raw or
    /// arbitrary-scale EEMs, --quantum-yield/--concentration and --solver other than
    /// lbfgs keep one fluorophore. `tabulated`: one fluorophore, never escalated (the
    /// default before as-needed). `auto`: search from the smallest parametric model up.
    /// `gaussian:KxB[/E][+rD|+rt]`: K fluorophores with B Gaussian bands, or A absorption
    /// and E emission bands; reflectance a sigmoid polynomial of degree D or tabulated
    /// (default degree: chosen).
    #[arg(long, value_parser = parse_model)]
    pub model: Option<ModelChoice>,
    /// Choose the smallest model whose ΔE2000 under every light of --lights is at most
    /// this (implies --model auto). Without it, `--model auto` takes the lowest BIC.
    #[arg(long)]
    pub max_delta_e: Option<f64>,
    /// Weight of the patch spectra under --lights against the matrix residual in
    /// parametric fits (0: matrix only).
    #[arg(long, default_value_t = fluorite::fit::DEFAULT_COLOUR_WEIGHT)]
    pub colour_weight: f64,
    /// With --max-delta-e: hold each light to max(bound, 3 × the measured colour's own
    /// noise RMS ΔE2000; at most the grid fit's ΔE2000 + bound) and weigh its colour term
    /// by that noise (a noisy one also by the share of what the grid fit leaves beyond the
    /// noise, in its residual or that colour), so noisy data are not fitted to their
    /// noise (the report lists the
    /// lights judged so); take the reflectance tabulated where no polynomial fits the
    /// grid fit's diagonal within the cells' noise; pass over a candidate that meets the bound but that the matrix
    /// tells from the grid model by more than noise: for the grid fit where it leaves only
    /// noise and meets the bound (or, where it meets a light only within that light's
    /// noise, for the larger one-component model of lowest BIC below its own, fitted to
    /// the matrix alone, that meets the bound and passes), else for a later candidate that
    /// passes.
    #[arg(long, requires = "max_delta_e")]
    pub noise_aware_bound: bool,
    /// The axis the model search's Gaussian bands are Gaussian in: both (the search runs
    /// on each and keeps the one that meets its rule, of two the one of lower BIC; the
    /// report says which), wavenumber or wavelength. A --model that names one structure
    /// takes its name's axis (@wavelength, else wavenumber).
    #[arg(long = "band-axis", value_enum, default_value = "both")]
    pub band_axis: fluorite::fit::BandAxisChoice,
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
    /// Joint fits of sample sets (--joint).
    #[command(flatten)]
    pub joint: Box<JointArgs>,
}

fn parse_model(text: &str) -> Result<ModelChoice, String> {
    text.parse::<ModelChoice>().map_err(|e| e.to_string())
}

impl FitArgs {
    /// The lights `--lights` names.
    pub fn parsed_lights(&self) -> anyhow::Result<Vec<Light>> {
        self.lights
            .iter()
            .map(|l| Light::parse(l))
            .collect::<Result<Vec<_>, _>>()
            .context("--lights")
    }
}

/// What a joint fit (`--joint`) takes from `fit`'s arguments; refuses the flags of single
/// fits it has no use for rather than ignoring them.
fn joint_run(args: &FitArgs, input: InputOptions) -> anyhow::Result<JointRun<'_>> {
    let single_fit_only = [
        ("--quantum-yield", args.quantum_yield.is_some()),
        ("--concentration", args.concentration.is_some()),
        ("--model", args.model.is_some()),
        ("--max-delta-e", args.max_delta_e.is_some()),
        ("--plot", args.plot),
        ("--render", args.render),
        ("--strict", args.strict),
    ];
    if let Some((flag, _)) = single_fit_only.iter().find(|(_, given)| *given) {
        anyhow::bail!(
            "{flag} applies to single fits, not to --joint (a joint fit writes its own figure and report); leave it out or fit the files one by one"
        );
    }
    let request = args.joint.request(JointRequest {
        yield_choice: args.yield_choice,
        guard_nm: args.guard,
        max_iterations: args.max_iterations,
        lights: args.parsed_lights()?,
        timing_runs: args.timing_runs,
        ..JointRequest::default()
    })?;
    Ok(JointRun {
        inputs: &args.inputs,
        output: args.output.clone(),
        input,
        request,
        table: args.table,
        quiet: args.quiet,
    })
}

/// Runs `fluorite fit`.
pub fn run(args: FitArgs) -> anyhow::Result<ExitCode> {
    fluorite::limits::check_runs(args.timing_runs, "--timing-runs")?;
    let lights = args.parsed_lights()?;
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
            (None, None) => ModelChoice::AsNeeded,
        },
        max_delta_e: args.max_delta_e,
        colour_weight: args.colour_weight,
        noise_aware_bound: args.noise_aware_bound,
        band_axis: args.band_axis,
    };
    // Before any file is read or folder made (every fit would refuse it, once per file).
    options.check_band_axis()?;
    let input = InputOptions {
        read: ReadOptions {
            format: args.format,
            rows: args.rows,
            zero_is_missing: args.zero_is_missing,
            per_nm: args.per_nm,
        },
        eem: args.eem.settings()?,
    };
    if args.joint.joint {
        return crate::cli::joint::run(&joint_run(&args, input)?, &args.joint);
    }
    let outputs = output_paths(&args.inputs, args.output.as_deref())?;
    create_folders(&outputs)?;
    let count = args.inputs.len();
    let progress = crate::cli::progress::Progress::start("fitting", count, args.quiet);
    // Files are independent: fit them in parallel, report in input order.
    let results: Vec<fluorite::Result<Fitted>> = args
        .inputs
        .par_iter()
        .zip(&outputs)
        .enumerate()
        .map(|(index, (path, out))| {
            progress.working_on(path);
            let fitted = fit_file_timed(path, index, count, &input, &options, args.timing_runs)
                .and_then(|fitted| write_outcome(out, &fitted.outcome).map(|()| fitted));
            progress.done_one();
            fitted
        })
        .collect();
    progress.finish();
    let mut failed = 0;
    let mut flagged = 0;
    let mut rows = Vec::new();
    for ((input, out), result) in args.inputs.iter().zip(&outputs).zip(results) {
        match result {
            Err(e) => {
                failed += 1;
                eprintln!("fluorite: error: {}", e.to_string().replace('\n', " "));
            }
            Ok(Fitted {
                measurement: m,
                outcome,
            }) => {
                let report = outcome.report();
                if !report.converged || !report.warnings.is_empty() {
                    flagged += 1;
                }
                if !args.quiet {
                    print!("{}", printer::summary(input, out, &m, &outcome));
                }
                rows.push((
                    printer::table_row(&m, &outcome),
                    printer::model_table_row(&m, &outcome),
                    report.model_search.is_some(),
                ));
                if args.plot {
                    let figures = beside::plot_fit(&outcome, &m, out)
                        .with_context(|| format!("plotting {}", out.display()))?;
                    crate::cli::printer::figures(&figures, args.quiet);
                }
                if let FitOutcome::Material(material) = &outcome
                    && args.render
                {
                    crate::cli::render::preview(material, out, args.quiet)
                        .with_context(|| format!("rendering {}", out.display()))?;
                }
            }
        }
    }
    if args.table {
        // The model table once any file's model was chosen by a search (the default fit
        // escalates per file), the grid table otherwise.
        let parametric = match options.model {
            ModelChoice::Tabulated => false,
            ModelChoice::AsNeeded => rows.iter().any(|r| r.2),
            _ => true,
        };
        let rows: Vec<String> = rows
            .into_iter()
            .map(|(grid, model, _)| if parametric { model } else { grid })
            .collect();
        print!("{}", printer::fit_table(parametric, &rows));
    }
    Ok(if failed > 0 {
        ExitCode::from(2)
    } else if args.strict && flagged > 0 {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
