//! `fluorite plot`: draw the residual map, spectra, colour swatches and convergence of a
//! fitted material, next to the material file (or into `-o DIR`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;

use fluorite::Material;
use fluorite::fit::FitOutcome;
use fluorite::formats::{self, Format, ReadOptions, RowsAre};
use fluorite::plot::{self, ImageFormat, PlotOptions};

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

/// Plots a fit just made, handed over in memory (`fit --plot`): the material, or an EEM's
/// shapes, beside the JSON it was written to, named after it, against the measurement it
/// was fitted to (as prepared: masked scatter is drawn as masked). `quiet` (`fit -q`)
/// prints nothing but what was skipped.
pub fn plot_fit(
    outcome: &FitOutcome,
    measurement: &fluorite::Measurement,
    material_path: &Path,
    quiet: bool,
) -> anyhow::Result<()> {
    let shapes_material;
    let material = match outcome {
        FitOutcome::Material(material) => material.as_ref(),
        FitOutcome::Shapes(shapes) => {
            shapes_material = plot::shapes_material(shapes);
            &shapes_material
        }
    };
    write_figures(
        material,
        Some(measurement),
        material_path,
        None,
        ImageFormat::Png,
    )
    .map(|written| {
        if !quiet {
            print_written(&written);
        }
    })
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
    let written = write_figures(&material, data.as_ref(), material_path, output_dir, format)?;
    print_written(&written);
    Ok(written)
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

fn print_written(written: &[PathBuf]) {
    for path in written {
        println!("wrote {}", path.display());
    }
}

/// Renders every figure of `material` (against `data`) in memory, then writes them all
/// into `output_dir` or beside `material_path`, named after it; prints what was skipped
/// and returns the written paths.
fn write_figures(
    material: &Material,
    data: Option<&fluorite::Measurement>,
    material_path: &Path,
    output_dir: Option<&Path>,
    format: ImageFormat,
) -> anyhow::Result<Vec<PathBuf>> {
    let plots = plot::plot(
        material,
        data,
        &PlotOptions {
            format,
            guard_nm: None,
        },
    )?;
    let dir = match output_dir {
        Some(dir) => {
            std::fs::create_dir_all(dir).with_context(|| {
                format!(
                    "{}: cannot create the output folder; choose another with -o DIR",
                    dir.display()
                )
            })?;
            dir.to_path_buf()
        }
        None => match material_path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        },
    };
    let stem = material_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| material.name.clone());
    let written = plot::write_plots(&plots, &dir, &stem)?;
    for reason in &plots.skipped {
        eprintln!("fluorite: skipped {reason}");
    }
    Ok(written)
}
