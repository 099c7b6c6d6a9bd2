//! `fluorite stability`: sweep conditions on synthetic data with known truth and map
//! where each fitting method fails.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use fluorite::evaluate::stability::{self, Config};
use fluorite::files::write_atomic;
use fluorite::plot::evaluation::stability as stability_chart;

use super::bench::image_format;

/// Arguments of `fluorite stability`.
#[derive(clap::Args, Debug)]
pub struct StabilityArgs {
    /// Chart of success rate against each swept condition (`.svg` or `.png`).
    #[arg(long)]
    pub chart: PathBuf,
    /// Markdown report: definitions, summary of where each method breaks, tables.
    #[arg(long)]
    pub report: PathBuf,
    /// CSV of the tables.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// CSV of every single fit, with its warnings.
    #[arg(long)]
    pub runs_csv: Option<PathBuf>,
    /// Seeded repetitions per condition (the seeds cycle the presets).
    #[arg(long, default_value_t = 6)]
    pub seeds: usize,
    /// Fast smoke run: Nelder-Mead gets a tenth of its iterations.
    #[arg(long)]
    pub quick: bool,
}

/// Runs `fluorite stability`.
pub fn run(args: StabilityArgs) -> anyhow::Result<ExitCode> {
    let chart_format = image_format(&args.chart, "--chart")?;
    fluorite::limits::check_runs(args.seeds, "--seeds")?;
    let config = if args.quick {
        Config::quick(args.seeds)
    } else {
        Config::full(args.seeds)
    };
    let runs = stability::run(&config)?;
    let summaries = stability::summarise(&runs);
    let command = format!(
        "fluorite stability --seeds {}{}",
        args.seeds,
        if args.quick { " --quick" } else { "" }
    );
    let chart = stability_chart(&summaries, &config.sweeps, chart_format)?;
    let report = stability::report(&config, &summaries, &command);
    write_atomic(&args.chart, &chart).with_context(|| "--chart")?;
    write_atomic(&args.report, report.as_bytes()).with_context(|| "--report")?;
    if let Some(path) = &args.csv {
        write_atomic(path, stability::to_csv(&summaries).as_bytes()).with_context(|| "--csv")?;
    }
    if let Some(path) = &args.runs_csv {
        write_atomic(path, stability::runs_to_csv(&runs).as_bytes())
            .with_context(|| "--runs-csv")?;
    }
    Ok(ExitCode::SUCCESS)
}
