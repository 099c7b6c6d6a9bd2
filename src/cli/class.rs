//! `fluorite class`: accuracy of the grid fit and the model search on a randomized class
//! of synthetic materials with known truth.

use std::path::PathBuf;
use std::process::ExitCode;

use fluorite::evaluate::class::{self, ClassConfig, DEFAULT_CASES, DEFAULT_SEED};
use fluorite::files::write_files;

/// Arguments of `fluorite class`.
#[derive(clap::Args, Debug)]
pub struct ClassArgs {
    /// Number of drawn materials.
    #[arg(long, default_value_t = DEFAULT_CASES)]
    pub cases: usize,
    /// Seed of the draws (decimal or 0x-prefixed hexadecimal).
    #[arg(long, default_value_t = DEFAULT_SEED, value_parser = parse_seed)]
    pub seed: u64,
    /// Markdown report: what was drawn, summaries, the worst cases.
    #[arg(long)]
    pub report: PathBuf,
    /// CSV with one line per case and method.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Print nothing (otherwise the report's summary tables are printed).
    #[arg(short, long)]
    pub quiet: bool,
}

fn parse_seed(text: &str) -> Result<u64, String> {
    let parsed = match text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        Some(hex) => u64::from_str_radix(&hex.replace('_', ""), 16),
        None => text.parse(),
    };
    parsed.map_err(|e| format!("\"{text}\" is not a seed ({e}); give e.g. 42 or 0xC1A55EE9"))
}

/// Runs `fluorite class`.
pub fn run(args: ClassArgs) -> anyhow::Result<ExitCode> {
    fluorite::limits::check_runs(args.cases, "--cases")?;
    let config = ClassConfig {
        cases: args.cases,
        seed: args.seed,
    };
    let sweep = class::run(&config)?;
    let command = format!(
        "fluorite class --cases {} --seed {:#X}",
        args.cases, args.seed
    );
    let report = class::to_markdown(&sweep, &command);
    let mut files = vec![(args.report.clone(), report.clone().into_bytes())];
    if let Some(path) = &args.csv {
        files.push((path.clone(), class::to_csv(&sweep).into_bytes()));
    }
    write_files(&files)?;
    if !args.quiet {
        // The summary tables: everything before the lists of worst cases.
        print!("{}", report.split("\n## ").next().unwrap_or(&report));
    }
    Ok(ExitCode::SUCCESS)
}
