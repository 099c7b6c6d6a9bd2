//! Building a material from published spectra (as the paper does): an absorption (or
//! excitation) spectrum, an emission spectrum, a reflectance spectrum or constant, and
//! the concentration c and a quantum yield: the energy yield Q (constant over the
//! excitation wavelength, the paper's form) or the photon yield Φ that chemists tabulate
//! (constant photon yield, energy yield Φ·λi/λ̄e).
//!
//! Spectra files are delimited text (`,`, `;`, tab or whitespace), `#` comment lines
//! skipped, a header row naming the columns (first column the wavelength in nm), e.g.
//! `wavelength_nm,excitation,emission` as in the McNamara-Boswell dye files. The curves
//! are normalised (max a = 1, ∫e dλ = 1 by the trapezoid rule), trimmed of the zero
//! samples beyond their support (keeping one zero at each end, so the linear
//! interpolation still falls to zero), and the material is checked with
//! [`crate::check`] before it is returned.

use std::path::{Path, PathBuf};

use crate::check::{CheckReport, Law, check_material};
use crate::error::{Error, Result};
use crate::material::{Fluorophore, Material, YieldForm};
use crate::spectrum::Spectrum;

/// Where a spectrum comes from: a file and, optionally, the column to read.
#[derive(Debug, Clone)]
pub struct SpectrumSource {
    /// The file.
    pub path: PathBuf,
    /// The column's header name; `None` picks by name (see [`read_spectrum`]).
    pub column: Option<String>,
}

/// The reflectance r of the non-fluorescent part.
#[derive(Debug, Clone)]
pub enum ReflectanceSource {
    /// The same r at every wavelength.
    Constant(f64),
    /// A spectrum file (r in [0, 1]).
    File(SpectrumSource),
}

/// What [`import_spectra`] builds a material from.
#[derive(Debug, Clone)]
pub struct ImportOptions {
    /// The material's name.
    pub name: String,
    /// Absorption or excitation spectrum (any scale).
    pub absorption: SpectrumSource,
    /// Emission spectrum (any scale).
    pub emission: SpectrumSource,
    /// Reflectance.
    pub reflectance: ReflectanceSource,
    /// c: fraction absorbed at the absorption peak.
    pub concentration: f64,
    /// The yield of `yield_form`: the energy quantum yield Q (emitted / absorbed energy)
    /// or the photon quantum yield Φ (emitted / absorbed photons).
    pub quantum_yield: f64,
    /// Which yield is constant over the excitation wavelength (and so what
    /// `quantum_yield` is).
    pub yield_form: YieldForm,
}

impl ImportOptions {
    /// The command-line name of the yield option (`--quantum-yield` or `--photon-yield`),
    /// for messages.
    pub fn yield_option(&self) -> &'static str {
        match self.yield_form {
            YieldForm::Energy => "--quantum-yield",
            YieldForm::Photon => "--photon-yield",
        }
    }
}

/// Column names tried, in order, when no column is named.
const ABSORPTION_COLUMNS: [&str; 4] = ["absorption", "absorbance", "excitation", "a"];
const EMISSION_COLUMNS: [&str; 3] = ["emission", "fluorescence", "e"];
const REFLECTANCE_COLUMNS: [&str; 3] = ["reflectance", "reflectance_factor", "r"];

/// Reads one spectrum column from a delimited text file. `column` names it; without a
/// name the first header matching one of `preferred` (case-insensitive) is taken, or the
/// only value column of a two-column file. Every malformed cell is an error naming the
/// file, line and column.
pub fn read_spectrum(path: &Path, column: Option<&str>, preferred: &[&str]) -> Result<Spectrum> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut rows = data_rows(&text);
    let (header_line, names) = header(path, &mut rows)?;
    let pick = match column {
        Some(c) => names
            .iter()
            .skip(1)
            .position(|n| n.eq_ignore_ascii_case(c))
            .map(|i| i + 1)
            .ok_or_else(|| {
                Error::parse(
                    path,
                    header_line,
                    0,
                    format!(
                        "has no column \"{c}\"; its columns are {}",
                        names[1..].join(", ")
                    ),
                )
            })?,
        None => preferred
            .iter()
            .find_map(|p| {
                names
                    .iter()
                    .skip(1)
                    .position(|n| n.eq_ignore_ascii_case(p))
                    .map(|i| i + 1)
            })
            .or((names.len() == 2).then_some(1))
            .ok_or_else(|| {
                Error::parse(
                    path,
                    header_line,
                    0,
                    format!(
                        "has no column named {}; name the column to read (its columns are {})",
                        preferred.join(" or "),
                        names[1..].join(", ")
                    ),
                )
            })?,
    };
    let mut wavelength = Vec::new();
    let mut value = Vec::new();
    for (line, row) in rows {
        let cells = split_cells(row);
        if cells.len() != names.len() {
            return Err(Error::parse(
                path,
                line,
                0,
                format!(
                    "has {} cells but the header names {} columns",
                    cells.len(),
                    names.len()
                ),
            ));
        }
        let number = |col: usize| -> Result<f64> {
            let v: f64 = cells[col].parse().map_err(|_| {
                Error::parse(
                    path,
                    line,
                    col + 1,
                    format!("\"{}\" is not a number", cells[col]),
                )
            })?;
            if !v.is_finite() {
                return Err(Error::parse(
                    path,
                    line,
                    col + 1,
                    format!("{v} is not a finite number"),
                ));
            }
            Ok(v)
        };
        let l = number(0)?;
        if l > 0.0
            && let Err(message) = crate::limits::check_wavelength(l)
        {
            return Err(Error::parse(path, line, 1, format!("wavelength {message}")));
        }
        let v = number(pick)?;
        if l <= 0.0 || wavelength.last().is_some_and(|&p| l <= p) {
            return Err(Error::parse(
                path,
                line,
                1,
                format!(
                    "wavelength {l} nm is not positive or not above the previous row's; sort the rows by wavelength"
                ),
            ));
        }
        if v < 0.0 {
            return Err(Error::parse(
                path,
                line,
                pick + 1,
                format!(
                    "{} is {v} at {l} nm; spectra must be non-negative (clip measurement noise to 0 first)",
                    names[pick]
                ),
            ));
        }
        wavelength.push(l);
        value.push(v);
    }
    Spectrum::new(
        wavelength,
        value,
        &format!("{} ({})", path.display(), names[pick]),
    )
    .map_err(|e| Error::parse(path, 0, 0, e.to_string()))
}

/// The names of the value columns (every column after the wavelength) of a spectrum
/// file that [`read_spectrum`] reads, in file order.
pub fn spectrum_columns(path: &Path) -> Result<Vec<String>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let (_, mut names) = header(path, &mut data_rows(&text))?;
    names.remove(0);
    Ok(names)
}

/// The non-empty, non-comment lines of `text` with their 1-based line numbers.
fn data_rows(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// Splits a row at commas, else semicolons, else whitespace.
fn split_cells(l: &str) -> Vec<String> {
    if l.contains(',') {
        l.split(',').map(|c| c.trim().to_string()).collect()
    } else if l.contains(';') {
        l.split(';').map(|c| c.trim().to_string()).collect()
    } else {
        l.split_whitespace().map(str::to_string).collect()
    }
}

/// Takes the header row from `rows`: its line number and column names (at least two, the
/// first naming the wavelength).
fn header<'a>(
    path: &Path,
    rows: &mut impl Iterator<Item = (usize, &'a str)>,
) -> Result<(usize, Vec<String>)> {
    let (header_line, header) = rows.next().ok_or_else(|| {
        Error::parse(path, 0, 0, "holds no data; expected a header row such as wavelength_nm,excitation,emission and one row per wavelength")
    })?;
    let names = split_cells(header);
    if names.len() < 2 {
        return Err(Error::parse(
            path,
            header_line,
            0,
            "the header has fewer than two columns; give a wavelength column and a value column",
        ));
    }
    if names[0].parse::<f64>().is_ok() {
        return Err(Error::parse(
            path,
            header_line,
            1,
            "the first row holds numbers, not column names; add a header such as wavelength_nm,excitation,emission",
        ));
    }
    Ok((header_line, names))
}

/// Drops the zero samples beyond the support, keeping one zero at each end.
fn trim_zeros(s: &Spectrum) -> Spectrum {
    let first = s.value.iter().position(|&v| v > 0.0).unwrap_or(0);
    let last = s
        .value
        .iter()
        .rposition(|&v| v > 0.0)
        .unwrap_or(s.len() - 1);
    let lo = first.saturating_sub(1);
    let hi = (last + 1).min(s.len() - 1);
    Spectrum {
        wavelength_nm: s.wavelength_nm[lo..=hi].to_vec(),
        value: s.value[lo..=hi].to_vec(),
    }
}

/// Builds, normalises and checks the material. Fails when a file is malformed, a curve
/// is zero everywhere, or the material breaks a law (e.g. a quantum yield above what
/// photon conservation allows, with the largest allowed value in the message).
pub fn import_spectra(options: &ImportOptions) -> Result<(Material, CheckReport)> {
    let yield_option = options.yield_option();
    for (v, what, meaning) in [
        (
            options.concentration,
            "--concentration",
            "it must lie in [0, 1]",
        ),
        (
            options.quantum_yield,
            yield_option,
            match options.yield_form {
                YieldForm::Energy => {
                    "an energy quantum yield (emitted / absorbed energy) lies in [0, 1]"
                }
                YieldForm::Photon => {
                    "a photon quantum yield (emitted / absorbed photons) lies in [0, 1]; a yield in percent must be divided by 100"
                }
            },
        ),
    ] {
        if !(0.0..=1.0).contains(&v) {
            return Err(Error::invalid(what, format!("is {v}; {meaning}")));
        }
    }
    let read = |s: &SpectrumSource, preferred: &[&str]| {
        read_spectrum(&s.path, s.column.as_deref(), preferred)
    };
    let raw_a = trim_zeros(&read(&options.absorption, &ABSORPTION_COLUMNS)?);
    let raw_e = trim_zeros(&read(&options.emission, &EMISSION_COLUMNS)?);
    let peak = raw_a.max();
    if peak <= 0.0 {
        return Err(Error::parse(
            &options.absorption.path,
            0,
            0,
            "the absorption is zero everywhere; a fluorophore must absorb somewhere",
        ));
    }
    let area = raw_e.integral();
    if area <= 0.0 {
        return Err(Error::parse(
            &options.emission.path,
            0,
            0,
            "the emission integrates to zero; a fluorophore must emit somewhere",
        ));
    }
    let absorption = Spectrum {
        value: raw_a.value.iter().map(|v| v / peak).collect(),
        ..raw_a
    };
    let emission = Spectrum {
        value: raw_e.value.iter().map(|v| v / area).collect(),
        ..raw_e
    };
    let reflectance = match &options.reflectance {
        ReflectanceSource::Constant(r) => {
            if !(0.0..=1.0).contains(r) {
                return Err(Error::invalid(
                    "--reflectance",
                    format!("is {r}; a reflectance lies in [0, 1]"),
                ));
            }
            // Sampled where a and e are, so that the material's grids stay those of the
            // source files (a uniform 1 nm grid for the dye files; BFC export needs one).
            let mut grid: Vec<f64> = absorption
                .wavelength_nm
                .iter()
                .chain(&emission.wavelength_nm)
                .copied()
                .collect();
            grid.sort_by(f64::total_cmp);
            grid.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
            Spectrum {
                value: vec![*r; grid.len()],
                wavelength_nm: grid,
            }
        }
        ReflectanceSource::File(s) => read(s, &REFLECTANCE_COLUMNS)?,
    };
    let material = Material::new(
        options.name.clone(),
        reflectance,
        vec![Fluorophore {
            concentration: options.concentration,
            quantum_yield: options.quantum_yield,
            yield_form: options.yield_form,
            concentration_range: None,
            absorption,
            emission,
        }],
    );
    let report = check_material(&material);
    if !report.valid {
        let mut reasons = Vec::new();
        for law in report.failed() {
            let r = report.law(law);
            let first = r.violations.first().cloned().unwrap_or_default();
            let more = if r.violations.len() > 1 {
                format!(" (and {} more)", r.violations.len() - 1)
            } else {
                String::new()
            };
            let hint = match (law, options.yield_form) {
                (Law::Photons, YieldForm::Energy) => {
                    "; lower --quantum-yield, or give the photon yield Φ that chemists tabulate with --photon-yield (a constant photon yield conserves photons for every Φ ≤ 1)"
                }
                (Law::Photons, YieldForm::Photon) => "; lower --photon-yield",
                (Law::Energy, YieldForm::Photon) => {
                    "; the energy yield Φ·λ/λ̄e exceeds Φ where the dye absorbs above its mean emission wavelength: lower --photon-yield, --concentration or --reflectance"
                }
                (Law::Energy, YieldForm::Energy) => {
                    "; lower --quantum-yield, --concentration or --reflectance"
                }
                _ => "",
            };
            reasons.push(format!("{law}: {first}{more}{hint}"));
        }
        return Err(Error::invalid(
            "material",
            format!("{} would break {}", options.name, reasons.join("; ")),
        ));
    }
    Ok((material, report))
}
