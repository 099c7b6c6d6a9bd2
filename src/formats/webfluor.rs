//! WebFluor-style excitation-emission matrices of fluorophores in solution: whitespace
//! separated; the first line lists the emission wavelengths; each further row starts with
//! its excitation wavelength (rows often run from long to short wavelengths, and blank
//! lines may separate them). A 0 means "not measured" (Rayleigh cut, second order), so
//! zeros are missing by default. The values are counts: there is no diagonal and the
//! scale is arbitrary.

use std::path::Path;

use crate::error::Result;

use super::table::TableLayout;
use super::text::{Delimiter, Line, check_increasing, check_unique};
use super::{Parsed, ReadOptions, RowsAre};

pub(super) fn read(path: &Path, lines: &[Line], options: &ReadOptions) -> Result<Parsed> {
    let layout = TableLayout::commented(path, Delimiter::Whitespace);
    let mut table = layout.read(lines)?;
    table.require_rows(
        path,
        "has a line of emission wavelengths but no excitation rows",
    )?;
    check_increasing(path, &table.columns, "emission wavelength", false)?;
    check_unique(path, &table.rows, "excitation wavelength", true)?;
    table.sort_rows();
    let rows_are = options.rows.unwrap_or(RowsAre::Excitation);
    let (excitation_nm, emission_nm, values) = table.to_excitation_major(rows_are);
    Ok(Parsed {
        excitation_nm,
        emission_nm,
        values,
        has_diagonal: false,
        arbitrary_scale: true,
        zeros_missing_by_default: true,
        notes: Vec::new(),
    })
}
