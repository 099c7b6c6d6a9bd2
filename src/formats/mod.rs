//! Input formats: read a reradiation matrix from any supported file into a [`Measurement`].
//!
//! (Being implemented: wide CSV, long CSV, BFC-450, WebFluor.)

use std::path::Path;

use crate::error::{Error, Result};
use crate::measurement::Measurement;

/// The file formats fluorite reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// Wide CSV: corner cell, column wavelengths, one row per wavelength.
    Wide,
    /// Long CSV with columns `excitation_nm,emission_nm,value`.
    Long,
    /// Labsphere BFC-450 matrix file.
    Bfc,
    /// WebFluor-style whitespace matrix (solution EEM).
    Webfluor,
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
    /// Force the orientation of a wide matrix.
    pub rows: Option<RowsAre>,
    /// Treat zeros as missing cells (default: on for WebFluor, off otherwise).
    pub zero_is_missing: Option<bool>,
    /// Values are spectral densities per nm rather than per emission bin.
    pub per_nm: bool,
}

/// Reads a reradiation matrix from `path`.
pub fn read(path: &Path, _options: &ReadOptions) -> Result<Measurement> {
    Err(Error::parse(
        path,
        0,
        0,
        "reading matrices is not available yet",
    ))
}
