//! `fluorite export`: write a material in the forms renderers and other tools read.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use fluorite::colour::Light;
use fluorite::export::{
    ExportFormat, ExportOptions, RgbSpace, export_with_notes, parse_grid, write_files,
};
use fluorite::{Error, Material, Units};

/// Arguments of `fluorite export`.
#[derive(clap::Args, Debug)]
pub struct ExportArgs {
    /// The material JSON to export.
    pub material: PathBuf,
    /// Target format: csv, matrix, bfc, mitsuba, pbrt, pearray, art, exr (bispectral
    /// OpenEXR) or rgb (3×3 reduced matrices).
    #[arg(long)]
    pub to: String,
    /// Output: a file for csv, matrix, bfc, art, exr and rgb (or a folder, given as an
    /// existing folder or ending in `/`, to get NAME.csv, NAME.matrix.csv, NAME.BFC,
    /// NAME.ark, NAME.exr or NAME.rgb.json inside); a folder for mitsuba, pbrt and pearray
    /// (created if missing).
    #[arg(short, long)]
    pub out: PathBuf,
    /// Excitation and emission grid of the matrix (matrix, bfc, pbrt, art, exr, and mitsuba for
    /// materials with several fluorophores): start:end:step in nm, or comma-separated
    /// segments (300:400:10,405:780:5). Default: the material's own samples (for a fit,
    /// the measurement's grids).
    #[arg(long)]
    pub grid: Option<String>,
    /// Excitation grid alone (overrides --grid for the rows).
    #[arg(long)]
    pub excitation_grid: Option<String>,
    /// Emission grid alone (overrides --grid for the columns).
    #[arg(long)]
    pub emission_grid: Option<String>,
    /// Write matrix values as densities per nm of emission instead of per emission bin
    /// (read back with `fluorite fit --per-nm`).
    #[arg(long)]
    pub per_nm: bool,
    /// Lights, comma-separated: d65, a, f11, uv or two-column CSV files (default d65).
    /// Baked exports (mitsuba, pbrt) write one baked spectrum per light; the first also
    /// lights the fluorescence fork's scene and picks the fluorophore kept by targets that
    /// hold one (mitsuba's fork, pearray); rgb writes one 3×3 matrix per light.
    #[arg(long)]
    pub light: Option<String>,
    /// Colour space of the rgb reduction: srgb (linear sRGB, the default) or xyz.
    #[arg(long)]
    pub space: Option<String>,
}

/// Runs `fluorite export`.
pub fn run(args: ExportArgs) -> anyhow::Result<ExitCode> {
    let format = ExportFormat::parse(&args.to)?;
    let grid =
        |g: &Option<String>, name: &str| g.as_deref().map(|t| parse_grid(t, name)).transpose();
    let both = grid(&args.grid, "--grid")?;
    let excitation = grid(&args.excitation_grid, "--excitation-grid")?.or(both.clone());
    let emission = grid(&args.emission_grid, "--emission-grid")?.or(both);
    let space = args.space.as_deref().map(RgbSpace::parse).transpose()?;
    let lights = args
        .light
        .as_deref()
        .map(|list| list.split(',').map(|l| parse_light(l.trim())).collect())
        .transpose()?
        .unwrap_or_default();
    let material = Material::load(&args.material)?;
    // Which options apply to which format is the library's to decide.
    let options = ExportOptions {
        format,
        excitation_nm: excitation,
        emission_nm: emission,
        units: if args.per_nm {
            Units::PerNm
        } else {
            Units::PerBin
        },
        lights,
        space,
    };
    // Everything is rendered before anything is written.
    let exported = export_with_notes(&material, &options)?;
    let files = exported.files;
    let names_a_folder = args.out.is_dir() || args.out.as_os_str().to_string_lossy().ends_with('/');
    let targets: Vec<(PathBuf, Vec<u8>)> = if format.is_single_file() && !names_a_folder {
        files
            .into_iter()
            .map(|f| (args.out.clone(), f.contents))
            .collect()
    } else {
        create_folder(&args.out)?;
        files
            .into_iter()
            .map(|f| (args.out.join(&f.name), f.contents))
            .collect()
    };
    write_files(&targets)?;
    for (path, _) in &targets {
        println!("{}", path.display());
    }
    for line in &exported.notes {
        println!("{line}");
    }
    Ok(ExitCode::SUCCESS)
}

/// A light of `--light`, its errors naming the flag.
fn parse_light(name_or_path: &str) -> fluorite::Result<Light> {
    Light::parse(name_or_path).map_err(|e| match e {
        Error::Invalid { message, .. } => Error::invalid("--light", message),
        other => other,
    })
}

fn create_folder(dir: &Path) -> fluorite::Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| {
        Error::io(
            dir,
            std::io::Error::new(e.kind(), format!("cannot create the output folder: {e}")),
        )
    })
}
