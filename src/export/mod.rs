//! The export of materials to the forms renderers and other tools read (files are
//! written through [`crate::files`]).
//!
//! | format | files | content |
//! |---|---|---|
//! | [`ExportFormat::Csv`] | `NAME.csv` | wavelength, a, e, r columns; c and Q in the header |
//! | [`ExportFormat::Matrix`] | `NAME.matrix.csv` | the model's reradiation matrix as a wide CSV fluorite reads |
//! | [`ExportFormat::Bfc`] | `NAME.BFC` | the same matrix in the BFC-450 layout |
//! | [`ExportFormat::Mitsuba`] | `NAME_<light>.xml` per light, `NAME_fluoro.xml` | stock Mitsuba 3 scenes with the baked βT per light; a `diffusefluoro` scene for the fluorescence fork |
//! | [`ExportFormat::Pbrt`] | `NAME_*.spd`, `NAME_baked_<light>.spd`, `NAME_reradiation.csv`, `NAME.pbrt` | pbrt-v4 spectra, the baked βT per light, the matrix and named materials |
//! | [`ExportFormat::Pearray`] | `NAME.prc`, `NAME_pearray.csv` | PearRay's `fluorescent` material and its spectra |
//! | [`ExportFormat::Art`] | `NAME.ark` | the reradiation matrix as an ART bispectral archive entry |
//! | [`ExportFormat::Exr`] | `NAME.exr` | a uniform bispectral spectral OpenEXR ([`exr`]; `fluorite fit` reads it back) |
//! | [`ExportFormat::Rgb`] | `NAME.rgb.json` | the 3×3 reduced matrix per light and its ΔE2000 ([`rgb`]) |
//!
//! Every file states in its header the quantity and units it holds, the material's name
//! and the fluorite version. Every fluorophore of a material is exported (per-component
//! columns or files, and the matrices sum them); a material with continuous forms has
//! them sampled, and the `csv` and matrix headers carry the forms' parameters. Exports are rendered in memory first ([`export`]) and then
//! written all-or-nothing ([`crate::files::write_files`]), so a failure leaves no partial
//! output.

mod art;
pub mod baked;
pub mod exr;
mod grid;
mod matrix;
mod mitsuba;
mod options;
mod pbrt;
mod pearray;
pub mod rgb;
mod spectra;

use crate::error::{Error, Result};
use crate::material::Material;
use crate::measurement::Measurement;

pub use crate::files::{write_atomic, write_files};
pub use baked::{BakedSpectrum, total_radiance_factor, total_radiance_factor_at};
pub use grid::parse_grid;
pub use matrix::{default_grids, matrix};
pub use options::ExportOptions;
pub use rgb::RgbSpace;

/// The forms a material can be exported to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ExportFormat {
    /// One CSV: wavelength with a, e, r columns; c and Q in the header.
    Csv,
    /// The model's reradiation matrix as a wide CSV (fluorite reads it back).
    Matrix,
    /// The model's reradiation matrix in the BFC-450 layout.
    Bfc,
    /// Mitsuba 3 scenes: the baked total radiance factor per light for stock Mitsuba, and
    /// a `diffusefluoro` scene for the fluorescence fork.
    Mitsuba,
    /// pbrt-v4 spectra, the baked total radiance factor per light, the reradiation matrix
    /// and named materials.
    Pbrt,
    /// PearRay's `fluorescent` material and a CSV of its spectra.
    Pearray,
    /// An ART bispectral measurement archive entry (`.ark`).
    Art,
    /// A uniform bispectral spectral OpenEXR (Fichet, Mercier, Wilkie 2021).
    Exr,
    /// The 3×3 reduced matrix per light (Fichet, Belcour, Barla 2024).
    Rgb,
}

impl ExportFormat {
    /// Whether the format is a single file (`-o` may name it) or a set (`-o` is a folder).
    pub fn is_single_file(self) -> bool {
        matches!(
            self,
            ExportFormat::Csv
                | ExportFormat::Matrix
                | ExportFormat::Bfc
                | ExportFormat::Art
                | ExportFormat::Exr
                | ExportFormat::Rgb
        )
    }

    /// The format's name, as `--to` spells it.
    pub fn name(self) -> &'static str {
        match self {
            ExportFormat::Csv => "csv",
            ExportFormat::Matrix => "matrix",
            ExportFormat::Bfc => "bfc",
            ExportFormat::Mitsuba => "mitsuba",
            ExportFormat::Pbrt => "pbrt",
            ExportFormat::Pearray => "pearray",
            ExportFormat::Art => "art",
            ExportFormat::Exr => "exr",
            ExportFormat::Rgb => "rgb",
        }
    }

    /// Whether the format always writes the reradiation matrix, so that the grids and
    /// the units of [`ExportOptions`] apply (mitsuba writes it only for materials with
    /// several fluorophores).
    pub fn writes_matrix(self) -> bool {
        matches!(
            self,
            ExportFormat::Matrix
                | ExportFormat::Bfc
                | ExportFormat::Pbrt
                | ExportFormat::Art
                | ExportFormat::Exr
        )
    }

    /// Whether the format uses lights: baked spectra (mitsuba, pbrt), the fluorophore kept
    /// by a target that holds one (pearray) or one reduction per light (rgb).
    pub fn uses_lights(self) -> bool {
        matches!(
            self,
            ExportFormat::Mitsuba | ExportFormat::Pbrt | ExportFormat::Pearray | ExportFormat::Rgb
        )
    }

    /// Parses a format name (`csv`, `matrix`, `bfc`, `mitsuba`, `pbrt`, `pearray`, `art`,
    /// `exr`, `rgb`).
    pub fn parse(name: &str) -> Result<ExportFormat> {
        let lower = name.to_ascii_lowercase();
        <ExportFormat as clap::ValueEnum>::value_variants()
            .iter()
            .copied()
            .find(|format| format.name() == lower)
            .ok_or_else(|| {
                Error::invalid(
                    "--to",
                    format!(
                        "\"{name}\" is not a known format; choose csv, matrix, bfc, mitsuba, pbrt, pearray, art, exr or rgb"
                    ),
                )
            })
    }
}

/// One exported file: its name (relative to the output folder) and its content.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportFile {
    /// File name, derived from the material's name.
    pub name: String,
    /// The file's bytes.
    pub contents: Vec<u8>,
}

/// Renders `material` in `options.format`, in memory. The options are checked first (an
/// option the format does not use is an error, [`ExportOptions::validate`]), then the
/// material: a material that breaks a law of the model is not exported.
pub fn export(material: &Material, options: &ExportOptions) -> Result<Vec<ExportFile>> {
    Ok(export_with_notes(material, options)?.files)
}

/// An export's files and what it dropped or approximated, one line each (the anti-Stokes
/// share the `exr` layout cannot hold and the one `art` folds into the diagonal, the
/// ΔE2000 of each `rgb` reduction; none for the other formats), for the command to print.
#[derive(Debug, Clone, PartialEq)]
pub struct Exported {
    /// The files, as [`export`] renders them.
    pub files: Vec<ExportFile>,
    /// What the files drop or approximate.
    pub notes: Vec<String>,
}

/// [`export`], with the notes of what the files drop or approximate. Options the format
/// does not use are refused first ([`ExportOptions::validate`]).
pub fn export_with_notes(material: &Material, options: &ExportOptions) -> Result<Exported> {
    options.validate(material)?;
    let lights = options.lights_or_d65();
    let report = crate::check::check_material(material);
    if !report.valid {
        return Err(Error::invalid(
            "material",
            format!(
                "{} violates {}; run `fluorite check` for the report",
                material.name,
                report
                    .failed()
                    .iter()
                    .map(|l| l.name())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    let stem = file_stem(&material.name);
    let grids = || -> Result<(Vec<f64>, Vec<f64>)> {
        let (ex, em) = default_grids(material);
        Ok((
            options.excitation_nm.clone().unwrap_or(ex),
            options.emission_nm.clone().unwrap_or(em),
        ))
    };
    // The model's matrix on the export grids, for the formats that write one.
    let model_matrix = || -> Result<Measurement> {
        let (ex, em) = grids()?;
        matrix::matrix(material, &ex, &em, options.units)
    };
    let text = |name: String, s: String| ExportFile {
        name,
        contents: s.into_bytes(),
    };
    let mut notes = Vec::new();
    let files = match options.format {
        ExportFormat::Csv => vec![text(format!("{stem}.csv"), spectra::csv(material))],
        ExportFormat::Matrix => vec![text(
            format!("{stem}.matrix.csv"),
            matrix::wide(material, &model_matrix()?),
        )],
        ExportFormat::Bfc => vec![text(
            format!("{stem}.BFC"),
            matrix::bfc(material, &model_matrix()?)?,
        )],
        ExportFormat::Mitsuba => {
            let mut files: Vec<ExportFile> = mitsuba::mitsuba(material, &stem, &lights)
                .into_iter()
                .map(|(n, s)| text(n, s))
                .collect();
            // The fork's BSDF holds one fluorophore: with several the full matrix keeps
            // every one of them.
            if material.fluorophores.len() > 1 {
                files.push(text(
                    format!("{stem}_reradiation.csv"),
                    matrix::wide(material, &model_matrix()?),
                ));
            }
            files
        }
        ExportFormat::Pbrt => {
            let reradiation = model_matrix()?;
            let mut files: Vec<ExportFile> = pbrt::pbrt(material, &stem, &lights)
                .into_iter()
                .map(|(n, s)| text(n, s))
                .collect();
            files.push(text(
                format!("{stem}_reradiation.csv"),
                matrix::wide(material, &reradiation),
            ));
            files
        }
        ExportFormat::Pearray => pearray::pearray(material, &stem, &lights)
            .into_iter()
            .map(|(n, s)| text(n, s))
            .collect(),
        ExportFormat::Art => {
            let (n, s, fold) = art::art(
                material,
                &stem,
                options.excitation_nm.as_deref(),
                options.emission_nm.as_deref(),
            )?;
            if fold.share > 0.0 {
                notes.push(format!(
                    "{}: anti-Stokes cells (λo < λi), which ART does not render, carry {:.3} % of the off-diagonal energy: folded into the diagonal of their emission wavelength{}",
                    material.name,
                    100.0 * fold.share,
                    if fold.clamped > 0.0 {
                        format!(
                            " ({:.3} % dropped where the fold would raise an albedo above 1)",
                            100.0 * fold.clamped
                        )
                    } else {
                        String::new()
                    }
                ));
            }
            vec![text(n, s)]
        }
        ExportFormat::Exr => {
            let (ex, em) = grids()?;
            let (contents, share) = exr::exr(material, &exr::layout_grid(&ex, &em))?;
            notes.push(format!(
                "{}: anti-Stokes cells (λo < λi), which the spectral EXR layout cannot hold, carry {:.3} % of the off-diagonal energy",
                material.name,
                100.0 * share
            ));
            vec![ExportFile {
                name: format!("{stem}.exr"),
                contents,
            }]
        }
        ExportFormat::Rgb => {
            let (json, reductions) =
                rgb::rgb_json(material, &lights, options.space.unwrap_or_default())?;
            notes.extend(reductions.iter().map(|r| {
                format!(
                    "{}: 3×3 under {}: ΔE2000 {:.3} between the reduced and the spectral colour",
                    material.name, r.light, r.delta_e2000
                )
            }));
            vec![text(format!("{stem}.rgb.json"), json)]
        }
    };
    Ok(Exported { files, notes })
}

/// A file-name-safe stem from a material name.
pub fn file_stem(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    let s = s.trim_start_matches('.').to_string();
    if s.is_empty() {
        "material".to_string()
    } else {
        s
    }
}

/// The material name as it may appear on one header line (control characters removed).
pub(crate) fn one_line(name: &str) -> String {
    name.chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect()
}

/// The fluorite version that writes the exports.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
