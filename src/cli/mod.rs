//! Command-line interface: one file per subcommand, each parsing its arguments and
//! calling the library (`eem` holds `fit`'s raw-EEM flags, `joint` its `--joint` path);
//! `printer` formats what `fit` and `check` print.

mod bands;
mod bench;
mod check;
mod class;
mod eem;
mod export;
mod fit;
mod import_spectra;
mod joint;
mod plot;
mod printer;
mod progress;
mod render;
mod stability;
mod synth;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Fit, check, export, plot and render diffuse fluorescent materials from bispectral
/// reradiation matrices (Jung et al. 2018).
#[derive(Parser)]
#[command(name = "fluorite", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fit the fluorescent BBRRDF to measured matrices and write material JSON.
    Fit(fit::FitArgs),
    /// Write synthetic matrices with known ground truth.
    Synth(synth::SynthArgs),
    /// Render a material in the built-in spectral path tracer.
    Render(render::RenderArgs),
    /// Plot a fitted material: residual maps, spectra, colour swatches, convergence.
    Plot(plot::PlotArgs),
    /// Check materials against energy and photon conservation and the model's ranges
    /// (exit 0 valid, 1 violated, 2 unreadable).
    Check(check::CheckArgs),
    /// Export a material: csv, matrix, bfc, mitsuba, pbrt, pearray, art, exr or rgb.
    Export(export::ExportArgs),
    /// Build a material from absorption and emission spectra, c and Q.
    ImportSpectra(import_spectra::ImportSpectraArgs),
    /// Time every fitting method on inputs against its accuracy; chart the trade-off.
    Bench(bench::BenchArgs),
    /// Map where each fitting method fails on synthetic data with known truth.
    Stability(stability::StabilityArgs),
    /// Measure the grid fit and the model search on a randomized class of synthetic
    /// materials with known truth.
    Class(class::ClassArgs),
    /// Count the Gaussian bands each curve of spectrum files needs, per band domain.
    Bands(bands::BandsArgs),
}

/// Parses the command line and runs the chosen subcommand.
pub fn run() -> anyhow::Result<ExitCode> {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => {
            // --help and --version: print and succeed.
            e.print()?;
            return Ok(ExitCode::SUCCESS);
        }
        Err(e) => {
            // Usage errors as one line, like every other error.
            let text = e.render().to_string();
            let first = text.lines().next().unwrap_or("invalid arguments");
            anyhow::bail!(
                "{} (see fluorite --help)",
                first.trim_start_matches("error: ")
            );
        }
    };
    match cli.command {
        Command::Fit(args) => fit::run(args),
        Command::Synth(args) => synth::run(args),
        Command::Render(args) => render::run(args),
        Command::Plot(args) => plot::run(args),
        Command::Check(args) => check::run(args),
        Command::Export(args) => export::run(args),
        Command::ImportSpectra(args) => import_spectra::run(args),
        Command::Bench(args) => bench::run(args),
        Command::Stability(args) => stability::run(args),
        Command::Class(args) => class::run(args),
        Command::Bands(args) => bands::run(args),
    }
}
