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
mod fit_image;
mod image_diff;
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
    /// Fit a bispectral image into a material map: shared fluorophores, per-pixel
    /// concentrations and reflectance.
    FitImage(fit_image::FitImageArgs),
    /// Compare two bispectral images pixel by pixel: ΔE2000 percentiles per light (and,
    /// given their material maps, how their concentration maps correlate).
    ImageDiff(image_diff::ImageDiffArgs),
    /// Write synthetic matrices (or, with --image, bispectral images) with known ground
    /// truth.
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
    /// Measure the grid fit, the model search and the default fit on a randomized class
    /// of synthetic materials with known truth.
    Class(class::ClassArgs),
    /// Count the Gaussian bands each curve of spectrum files needs, per band domain.
    Bands(bands::BandsArgs),
}

/// The guide page each subcommand's help names (`More: docs/<page>`), and the top-level
/// help's.
const GUIDE_PAGES: [(&str, &str); 14] = [
    ("fluorite", "docs/README.md"),
    ("fit", "docs/fitting.md"),
    ("fit-image", "docs/images.md"),
    ("image-diff", "docs/images.md"),
    ("synth", "docs/formats.md"),
    ("render", "docs/render.md"),
    ("plot", "docs/plots.md"),
    ("check", "docs/material.md"),
    ("export", "docs/export.md"),
    ("import-spectra", "docs/export.md"),
    ("bench", "docs/results.md"),
    ("stability", "docs/results.md"),
    ("class", "docs/results.md"),
    ("bands", "docs/fitting.md"),
];

/// The guide page of subcommand `name` (the index for the top level or an unknown name).
fn guide_page(name: &str) -> &'static str {
    GUIDE_PAGES
        .iter()
        .find(|(command, _)| *command == name)
        .map_or(GUIDE_PAGES[0].1, |(_, page)| page)
}

/// The command line's grammar: the derived one, each help ending with its guide page
/// (`fit`'s also with the input layouts).
fn command() -> clap::Command {
    let mut command = <Cli as clap::CommandFactory>::command()
        .after_help(format!("More: {}", guide_page("fluorite")));
    for (name, page) in &GUIDE_PAGES[1..] {
        let text = match *name {
            "fit" => format!(
                "{}\n\nMore: {page} (raw instrument EEMs: docs/eem.md; concentration series: docs/series.md)",
                fit::INPUT_LAYOUTS
            ),
            _ => format!("More: {page}"),
        };
        command = command.mut_subcommand(name, |sub| sub.after_help(text));
    }
    command
}

/// Parses the command line and runs the chosen subcommand.
pub fn run() -> anyhow::Result<ExitCode> {
    let parsed = command()
        .try_get_matches()
        .and_then(|matches| <Cli as clap::FromArgMatches>::from_arg_matches(&matches));
    let cli = match parsed {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => {
            // --help and --version: print and succeed.
            e.print()?;
            return Ok(ExitCode::SUCCESS);
        }
        Err(e) => {
            // Usage errors as clap renders them: what is missing or wrong, suggestions,
            // possible values, the subcommand's usage line; then the guide page.
            e.print()?;
            eprintln!("More: {}", guide_page(&subcommand_named()));
            return Ok(ExitCode::from(2));
        }
    };
    match cli.command {
        Command::Fit(args) => fit::run(args),
        Command::FitImage(args) => fit_image::run(args),
        Command::ImageDiff(args) => image_diff::run(args),
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

/// The subcommand the command line names (its first argument that is one), or "" when
/// none is.
fn subcommand_named() -> String {
    let cli = command();
    std::env::args()
        .skip(1)
        .find(|a| cli.find_subcommand(a).is_some())
        .unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grammar_is_consistent_and_every_subcommand_has_a_guide_page() {
        let command = command();
        command.clone().debug_assert();
        let named: Vec<&str> = command.get_subcommands().map(|s| s.get_name()).collect();
        let paged: Vec<&str> = GUIDE_PAGES[1..].iter().map(|(name, _)| *name).collect();
        assert_eq!(named, paged);
    }
}
