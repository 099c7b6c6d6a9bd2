//! `fluorite bench`: time every fitting method on every input against its accuracy, and
//! chart the trade-off.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use fluorite::evaluate::{Method, all_methods, bench};
use fluorite::files::write_atomic;
use fluorite::formats::{ReadOptions, read};
use fluorite::plot::ImageFormat;
use fluorite::plot::evaluation::speed_accuracy;

/// Arguments of `fluorite bench`.
#[derive(clap::Args, Debug)]
pub struct BenchArgs {
    /// Measured or synthetic matrices (any format `fit` reads).
    #[arg(required = true)]
    pub inputs: Vec<PathBuf>,
    /// Chart of time against error (`.svg` or `.png`).
    #[arg(long)]
    pub chart: PathBuf,
    /// CSV table of the numbers behind the chart.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Timed runs per input and method (the median is reported, with min and max).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Methods to compare, comma-separated (default: all: init, lbfgs, lbfgs-tight,
    /// gauss-newton, gauss-newton-tight, nelder-mead, nelder-mead-tight, and search: the
    /// parametric model search for ΔE2000 ≤ 1, on inputs with a calibrated diagonal).
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Print nothing but errors.
    #[arg(short, long)]
    pub quiet: bool,
}

/// The image format a chart path asks for.
pub fn image_format(path: &Path, flag: &str) -> anyhow::Result<ImageFormat> {
    match path.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("svg") => Ok(ImageFormat::Svg),
        Some(e) if e.eq_ignore_ascii_case("png") => Ok(ImageFormat::Png),
        _ => anyhow::bail!(
            "{flag} {}: give a file name ending in .svg or .png",
            path.display()
        ),
    }
}

fn chosen_methods(names: &[String]) -> anyhow::Result<Vec<Method>> {
    let all = all_methods();
    if names.is_empty() {
        return Ok(all);
    }
    names
        .iter()
        .map(|n| {
            all.iter().find(|m| &m.name == n).cloned().ok_or_else(|| {
                let known: Vec<&str> = all.iter().map(|m| m.name.as_str()).collect();
                anyhow::anyhow!(
                    "--methods: unknown method \"{n}\"; choose from {}",
                    known.join(", ")
                )
            })
        })
        .collect()
}

/// Runs `fluorite bench`.
pub fn run(args: BenchArgs) -> anyhow::Result<ExitCode> {
    let format = image_format(&args.chart, "--chart")?;
    let methods = chosen_methods(&args.methods)?;
    let inputs = args
        .inputs
        .iter()
        .map(|p| read(p, &ReadOptions::default()))
        .collect::<Result<Vec<_>, _>>()?;
    let rows = bench::run(&inputs, &methods, args.repeats)?;
    // Render everything before writing anything.
    let chart = speed_accuracy(&rows, format)?;
    let csv = bench::to_csv(&rows);
    write_atomic(&args.chart, &chart).with_context(|| "--chart")?;
    if let Some(path) = &args.csv {
        write_atomic(path, csv.as_bytes()).with_context(|| "--csv")?;
    }
    if !args.quiet {
        print!("{}", bench::to_markdown(&rows));
    }
    Ok(ExitCode::SUCCESS)
}
