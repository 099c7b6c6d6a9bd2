//! Input formats: read a reradiation matrix from any supported file into a [`Measurement`].
//!
//! | format | layout | rows |
//! |---|---|---|
//! | [`Format::Wide`] | corner cell, column wavelengths; rows start with their wavelength; `,` `;` or tab | corner label, `--rows`, or inferred |
//! | [`Format::Long`] | header naming excitation, emission and value columns in any order (`excitation_nm,emission_nm,value`, `Ex (nm);Em (nm);Intensity`, …) | — |
//! | [`Format::Bfc`] | Labsphere BFC-450 matrix file | emission |
//! | [`Format::Webfluor`] | whitespace; first line emission wavelengths, rows start with excitation | excitation |
//! | [`Format::Exr`] | bispectral spectral OpenEXR (channels `T.<λ>nm`, `T.<λi>nm.<λo>nm`; see [`exr`]) | — |
//!
//! The format is told by content first (OpenEXR's magic number, the `BFC-450 Matrix
//! File` line, a header naming excitation and emission columns, delimiters, a corner
//! label), the extension second.
//! A unit row right under a wide or long header (`nm,nm,a.u.`) is skipped with a note.
//! Empty cells, `NaN` and `NA` (any case) are missing values; zeros are missing too in
//! WebFluor files, where they mean "not measured". Whatever the file's orientation, the
//! [`Measurement`] is stored excitation-major. Every malformed file gives an
//! [`Error::Parse`] naming the file, line and column, what is wrong and how to fix it.
//!
//! [`write_wide_csv`], [`write_long_csv`] and [`write_bfc`] write the same layouts, so that
//! what fluorite writes it reads back exactly.

mod bfc;
mod detect;
pub mod exr;
mod long;
mod table;
mod text;

pub(crate) use text::delimited_fields;
mod webfluor;
mod wide;

use std::path::Path;

use crate::error::{Error, Result};
use crate::measurement::{Measurement, Units};

pub use bfc::write_bfc;
pub use text::sha256_hex;

/// The file formats fluorite reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Wide CSV: corner cell, column wavelengths, one row per wavelength.
    Wide,
    /// Long CSV: excitation, emission and value columns (`excitation_nm,emission_nm,value`,
    /// `Ex (nm),Em (nm),Intensity`, …).
    Long,
    /// Labsphere BFC-450 matrix file.
    Bfc,
    /// WebFluor-style whitespace matrix (solution EEM).
    Webfluor,
    /// Bispectral spectral OpenEXR (Fichet, Mercier, Wilkie 2021), one uniform image.
    Exr,
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Format::Wide => "wide CSV",
            Format::Long => "long CSV",
            Format::Bfc => "BFC-450 matrix file",
            Format::Webfluor => "WebFluor matrix",
            Format::Exr => "bispectral OpenEXR",
        })
    }
}

/// What the rows of a wide matrix are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum RowsAre {
    /// Each row is one excitation wavelength.
    Excitation,
    /// Each row is one emission wavelength.
    Emission,
}

/// How to read a file; the defaults auto-detect everything.
#[derive(Debug, Clone, Default)]
pub struct ReadOptions {
    /// Force a format instead of detecting it.
    pub format: Option<Format>,
    /// Force the orientation of a wide matrix (also WebFluor; BFC-450 rows are always
    /// emission).
    pub rows: Option<RowsAre>,
    /// Treat zeros as missing cells (default: on for WebFluor, off otherwise).
    pub zero_is_missing: Option<bool>,
    /// Values are spectral densities per nm rather than per emission bin.
    pub per_nm: bool,
}

/// What a format reader hands back: the matrix excitation-major and what it knows
/// about it; [`finish`] turns it into a [`Measurement`].
struct Parsed {
    excitation_nm: Vec<f64>,
    emission_nm: Vec<f64>,
    values: Vec<f64>,
    has_diagonal: bool,
    arbitrary_scale: bool,
    zeros_missing_by_default: bool,
    notes: Vec<String>,
}

impl Parsed {
    /// A surface matrix in radiance factors (a diagonal; zeros are measured zeros).
    fn surface(
        excitation_nm: Vec<f64>,
        emission_nm: Vec<f64>,
        values: Vec<f64>,
        notes: Vec<String>,
    ) -> Parsed {
        Parsed {
            excitation_nm,
            emission_nm,
            values,
            has_diagonal: true,
            arbitrary_scale: false,
            zeros_missing_by_default: false,
            notes,
        }
    }
}

/// Reads a reradiation matrix from `path`, detecting the format unless
/// `options.format` names it.
pub fn read(path: &Path, options: &ReadOptions) -> Result<Measurement> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    read_bytes(&bytes, path, options)
}

/// Reads a reradiation matrix from a file's bytes; `path` names it in errors and gives
/// the measurement its name (the file stem) and source.
pub fn read_bytes(bytes: &[u8], path: &Path, options: &ReadOptions) -> Result<Measurement> {
    // Binary: told by its magic number before any text decoding.
    if options.format == Some(Format::Exr) || (options.format.is_none() && exr::is_exr(bytes)) {
        return finish(path, bytes, exr::read(path, bytes)?, options);
    }
    let text = text::decode(bytes);
    if text.trim().is_empty() {
        let what = if bytes.is_empty() {
            "the file is empty"
        } else {
            "the file holds only blank lines"
        };
        return Err(Error::parse(
            path,
            0,
            0,
            format!("{what}; expected a reradiation matrix ({SUPPORTED})"),
        ));
    }
    let lines = text::split_lines(&text);
    let format = match options.format {
        Some(format) => format,
        None => detect::detect(path, bytes, &lines).ok_or_else(|| {
            Error::parse(
                path,
                0,
                0,
                format!(
                    "unknown format: the content matches none that fluorite reads ({SUPPORTED}); pass the --format of one to choose it"
                ),
            )
        })?,
    };
    let parsed = match format {
        Format::Wide => wide::read(path, &lines, options)?,
        Format::Long => long::read(path, &lines)?,
        Format::Bfc => bfc::read(path, &lines, options)?,
        Format::Webfluor => webfluor::read(path, &lines, options)?,
        Format::Exr => exr::read(path, bytes)?,
    };
    finish(path, bytes, parsed, options)
}

/// Tells the format of a file from its bytes (content first, extension as a hint), as
/// [`read`] does when no format is given; `None` when nothing matches.
pub fn detect_format(path: &Path, bytes: &[u8]) -> Option<Format> {
    if exr::is_exr(bytes) {
        return Some(Format::Exr);
    }
    let text = text::decode(bytes);
    detect::detect(path, bytes, &text::split_lines(&text))
}

/// The layouts fluorite reads, for messages about files that match none.
const SUPPORTED: &str = "a wide CSV (--format wide: a corner cell, then column wavelengths; each row starts with its wavelength), a long CSV (--format long: excitation, emission and value columns such as excitation_nm,emission_nm,value or Ex (nm),Em (nm),Intensity), a BFC-450 matrix file (--format bfc), a WebFluor whitespace matrix (--format webfluor) or a bispectral OpenEXR (--format exr)";

fn finish(path: &Path, bytes: &[u8], parsed: Parsed, options: &ReadOptions) -> Result<Measurement> {
    let Parsed {
        excitation_nm,
        emission_nm,
        mut values,
        has_diagonal,
        arbitrary_scale,
        zeros_missing_by_default,
        mut notes,
    } = parsed;
    let zeros_missing = options.zero_is_missing.unwrap_or(zeros_missing_by_default);
    if zeros_missing {
        let mut zeros = 0;
        for v in values.iter_mut().filter(|v| **v == 0.0) {
            *v = f64::NAN;
            zeros += 1;
        }
        if zeros > 0 && options.zero_is_missing.is_none() {
            notes.push(format!(
                "{zeros} cells holding 0 read as missing (not measured), as this format means; pass --zero-is-missing false to keep them as measured zeros"
            ));
        }
    }
    if values.iter().all(|v| v.is_nan()) {
        return Err(Error::parse(
            path,
            0,
            0,
            format!(
                "no usable cell: all {} cells are empty, NaN or NA{}; a matrix needs at least one measured value",
                values.len(),
                if zeros_missing {
                    " or 0 (zeros count as missing here)"
                } else {
                    ""
                }
            ),
        ));
    }
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "measurement".to_string());
    let measurement = Measurement {
        name,
        source: Some(path.to_path_buf()),
        source_sha256: Some(text::sha256_hex(bytes)),
        excitation_nm,
        emission_nm,
        values,
        units: if options.per_nm {
            Units::PerNm
        } else {
            Units::PerBin
        },
        has_diagonal,
        arbitrary_scale,
        notes,
    };
    // The readers have checked everything already; this is the last line of defence.
    measurement
        .validate()
        .map_err(|e| Error::parse(path, 0, 0, e.to_string()))?;
    Ok(measurement)
}

/// Writes `m` as a wide CSV with one row per excitation or emission wavelength, the
/// corner labelled `ex_nm\em_nm` or `em_nm\ex_nm` accordingly. Numbers are written so
/// that they read back exactly; missing cells as `NaN`. The units are not stored.
pub fn write_wide_csv(m: &Measurement, rows: RowsAre) -> String {
    let (corner, row_nm, column_nm) = match rows {
        RowsAre::Excitation => ("ex_nm\\em_nm", &m.excitation_nm, &m.emission_nm),
        RowsAre::Emission => ("em_nm\\ex_nm", &m.emission_nm, &m.excitation_nm),
    };
    let mut out = String::with_capacity(12 * (m.values.len() + row_nm.len() + column_nm.len()));
    out.push_str(corner);
    for &l in column_nm {
        out.push(',');
        out.push_str(&text::format_number(l));
    }
    out.push('\n');
    for (r, &l) in row_nm.iter().enumerate() {
        out.push_str(&text::format_number(l));
        for c in 0..column_nm.len() {
            let v = match rows {
                RowsAre::Excitation => m.get(r, c),
                RowsAre::Emission => m.get(c, r),
            };
            out.push(',');
            out.push_str(&text::format_number(v));
        }
        out.push('\n');
    }
    out
}

/// Writes `m` as a long CSV (`excitation_nm,emission_nm,value`, one line per cell,
/// missing cells as `NaN` so that the grids survive a round trip).
pub fn write_long_csv(m: &Measurement) -> String {
    let mut out = String::with_capacity(24 * (m.values.len() + 1));
    out.push_str("excitation_nm,emission_nm,value\n");
    for (i, &ex) in m.excitation_nm.iter().enumerate() {
        for (j, &em) in m.emission_nm.iter().enumerate() {
            out.push_str(&format!(
                "{},{},{}\n",
                text::format_number(ex),
                text::format_number(em),
                text::format_number(m.get(i, j))
            ));
        }
    }
    out
}
