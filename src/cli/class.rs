//! `fluorite class`: accuracy of the grid fit and the model search on a randomized class
//! of synthetic materials with known truth.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use fluorite::evaluate::class::{self, ClassConfig, DEFAULT_CASES, DEFAULT_SEED};
use fluorite::files::write_files;
use fluorite::parametric::BandDomain;

/// Arguments of `fluorite class`.
#[derive(clap::Args, Debug)]
pub struct ClassArgs {
    /// Number of drawn materials.
    #[arg(long, default_value_t = DEFAULT_CASES)]
    pub cases: usize,
    /// Seed of the draws (decimal or 0x-prefixed hexadecimal).
    #[arg(long, default_value_t = DEFAULT_SEED, value_parser = class::parse_seed)]
    pub seed: u64,
    /// Markdown report: what was drawn, summaries, the worst cases.
    #[arg(long)]
    pub report: PathBuf,
    /// CSV with one line per case and method.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Fit only these cases of the draw (comma-separated names from the report, e.g.
    /// `case069,case124`); the same cases as in a full sweep of this seed. The whole
    /// report is printed then.
    #[arg(long, value_delimiter = ',')]
    pub case: Vec<String>,
    /// Folder (created if missing) for each fitted case's files: `NAME.csv` (the
    /// measurement, which `fluorite fit` reads), `NAME.truth.json` (the true material),
    /// `NAME.synth.json` (the drawn parameters) and `NAME.METHOD.json` (each method's fit
    /// with its report).
    #[arg(long)]
    pub dump: Option<PathBuf>,
    /// The axis the drawn bands are Gaussian in: wavelength (the class as it comes) or
    /// wavenumber (drawn from the same random numbers, each band of the same centre and,
    /// at its centre, the same width; where the synthesiser refuses a draw in one shape
    /// and not the other, the two classes' later cases differ): does a choice the class
    /// makes hold where its truth is of the other shape?
    #[arg(long, value_enum, default_value = "wavelength")]
    pub truth_bands: BandDomain,
    /// The searches' band axis (`search`, `search-noise` and the default fit's
    /// escalation), as `fluorite fit --band-axis`.
    #[arg(long = "band-axis", value_enum, default_value = "both")]
    pub band_axis: fluorite::fit::BandAxisChoice,
    /// Print nothing (otherwise the report's summary tables are printed).
    #[arg(short, long)]
    pub quiet: bool,
}

/// Runs `fluorite class`.
pub fn run(args: ClassArgs) -> anyhow::Result<ExitCode> {
    fluorite::limits::check_runs(args.cases, "--cases")?;
    let config = ClassConfig {
        cases: args.cases,
        seed: args.seed,
        truth_bands: args.truth_bands,
        band_axis: args.band_axis,
    };
    let sweep = class::run_named(&config, &args.case)?;
    let mut command = format!(
        "fluorite class --cases {} --seed {:#X}",
        args.cases, args.seed
    );
    if config.truth_bands != BandDomain::Wavelength {
        command += &format!(" --truth-bands {}", config.truth_bands.name());
    }
    if let [axis] = config.band_axis.axes() {
        command += &format!(" --band-axis {}", axis.name());
    }
    if !args.case.is_empty() {
        command += &format!(" --case {}", args.case.join(","));
    }
    let report = class::to_markdown(&sweep, &command);
    let mut files = vec![(args.report.clone(), report.clone().into_bytes())];
    if let Some(path) = &args.csv {
        files.push((path.clone(), class::to_csv(&sweep).into_bytes()));
    }
    if let Some(dir) = &args.dump {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        for case in &sweep.cases {
            for (name, bytes) in class::case_files(case)? {
                files.push((dir.join(name), bytes));
            }
        }
    }
    write_files(&files)?;
    if !args.quiet {
        if args.case.is_empty() {
            // The summary tables: everything before the lists of worst cases.
            print!("{}", report.split("\n## ").next().unwrap_or(&report));
        } else {
            // A few named cases: the worst-case lists hold every one of them.
            print!("{report}");
        }
    }
    Ok(ExitCode::SUCCESS)
}
