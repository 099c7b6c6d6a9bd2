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
    /// swatches and the data points on the spectra.
    #[arg(long, value_name = "FILE")]
    pub data: Option<PathBuf>,
    /// Format of the data file (default: detected).
    #[arg(long, value_enum, requires = "data")]
    pub format: Option<Format>,
    /// What the rows of a wide data matrix are (default: detected).
    #[arg(long, value_enum, requires = "data")]
    pub rows: Option<RowsAre>,
    /// The data are spectral densities per nm rather than per emission bin.
    #[arg(long, requires = "data")]
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
    let data = data_path
        .map(|p| formats::read(p, read_options))
        .transpose()?;
    let written = write_figures(&material, data.as_ref(), material_path, output_dir, format)?;
    print_written(&written);
    Ok(written)
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
