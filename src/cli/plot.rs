//! `fluorite plot`: draw the residual map, spectra, colour swatches and convergence of a
//! fitted material, next to the material file (or into `-o DIR`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use fluorite::Material;
use fluorite::formats::{self, Format, ReadOptions, RowsAre};
use fluorite::pipeline::beside::write_figures;
use fluorite::plot::ImageFormat;

/// Arguments of `fluorite plot`.
#[derive(clap::Args)]
pub struct PlotArgs {
    /// Material JSON to plot (written by `fluorite fit`).
    pub material: PathBuf,
    /// The measured matrix the material was fitted to; adds the residual map, the colour
    /// swatches and the data points on the spectra. Default: the source file the
    /// material records, when it is there with the SHA-256 recorded.
    #[arg(long, value_name = "FILE")]
    pub data: Option<PathBuf>,
    /// Format of the data file, --data or the recorded source (default: detected).
    #[arg(long, value_enum)]
    pub format: Option<Format>,
    /// What the rows of a wide data matrix are (default: detected).
    #[arg(long, value_enum)]
    pub rows: Option<RowsAre>,
    /// The data are spectral densities per nm rather than per emission bin.
    #[arg(long)]
    pub per_nm: bool,
    /// Folder for the figures (created if missing; default: the material's folder).
    #[arg(short = 'o', long = "output-dir", value_name = "DIR")]
    pub output_dir: Option<PathBuf>,
    /// Write SVG instead of PNG.
    #[arg(long)]
    pub svg: bool,
}

/// Runs `fluorite plot`.
pub fn run(args: PlotArgs) -> anyhow::Result<ExitCode> {
    let read_options = ReadOptions {
        format: args.format,
        rows: args.rows,
        per_nm: args.per_nm,
        ..ReadOptions::default()
    };
    let format = if args.svg {
        ImageFormat::Svg
    } else {
        ImageFormat::Png
    };
    plot_files(
        &args.material,
        args.data.as_deref(),
        &read_options,
        args.output_dir.as_deref(),
        format,
    )?;
    Ok(ExitCode::SUCCESS)
}

/// Loads, renders every figure in memory, then writes them all; prints each written path
/// and what was skipped. Returns the written paths.
fn plot_files(
    material_path: &Path,
    data_path: Option<&Path>,
    read_options: &ReadOptions,
    output_dir: Option<&Path>,
    format: ImageFormat,
) -> anyhow::Result<Vec<PathBuf>> {
    let material = Material::load(material_path)?;
    let data = match data_path {
        Some(path) => Some(formats::read(path, read_options)?),
        None => recorded_source(&material, material_path, read_options)?,
    };
    let figures = write_figures(&material, data.as_ref(), material_path, output_dir, format)?;
    crate::cli::printer::figures(&figures, false);
    Ok(figures.written)
}

/// The matrix `material` records as its source (`fit.source`, `fit.source_sha256`), read
/// when the file is there and unchanged, saying so on stderr; None with a note when it
/// is not there or cannot be told unchanged. A changed file is an error.
fn recorded_source(
    material: &Material,
    material_path: &Path,
    read_options: &ReadOptions,
) -> anyhow::Result<Option<fluorite::Measurement>> {
    let Some(fit) = material.fit.as_ref().filter(|f| !f.source.is_empty()) else {
        return Ok(None);
    };
    let source = Path::new(&fit.source);
    let skipped = "the figures that need the measured matrix are skipped; give it with --data FILE";
    if fit.preprocessing.is_some() {
        // A raw EEM was blank-subtracted, corrected and masked at fit time; the figures
        // would compare the fit with the unprepared file.
        eprintln!(
            "fluorite: the recorded source {} is a raw EEM prepared at fit time (plot it with fit --plot); {skipped}",
            source.display()
        );
        return Ok(None);
    }
    let Ok(bytes) = std::fs::read(source) else {
        eprintln!(
            "fluorite: the recorded source {} is not there (paths are relative to the folder fit ran in); {skipped}",
            source.display()
        );
        return Ok(None);
    };
    if fit.source_sha256.is_empty() {
        eprintln!(
            "fluorite: the material records no SHA-256 of its source {}, so it cannot be told unchanged; {skipped}",
            source.display()
        );
        return Ok(None);
    }
    let found = formats::sha256_hex(&bytes);
    if found != fit.source_sha256 {
        anyhow::bail!(
            "{}: its recorded source {} has changed since the fit (SHA-256 now {found}, recorded {}); give the matrix it was fitted to with --data FILE, or refit",
            material_path.display(),
            source.display(),
            fit.source_sha256
        );
    }
    eprintln!(
        "fluorite: plotting against {}, the material's recorded source (SHA-256 matches)",
        source.display()
    );
    Ok(Some(formats::read(source, read_options)?))
}
