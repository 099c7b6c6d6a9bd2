//! Long CSV: one cell per line, with a header naming the columns `excitation_nm`,
//! `emission_nm` and `value` in any order (other columns are ignored). Combinations that
//! do not appear are missing cells.

use std::path::Path;

use crate::error::{Error, Result};

use super::Parsed;
use super::text::{CellReader, Delimiter, Line, drop_trailing_empty, split_cells};

/// Guard against a file whose few lines span an enormous grid (memory, not correctness).
const MAX_CELLS: usize = 10_000_000;

/// Column roles, by the names a header may use for them.
const EXCITATION_NAMES: [&str; 4] = ["excitation_nm", "excitation", "ex_nm", "ex"];
const EMISSION_NAMES: [&str; 4] = ["emission_nm", "emission", "em_nm", "em"];
const VALUE_NAMES: [&str; 2] = ["value", "values"];

fn role_of(names: &[&str], cells: &[std::borrow::Cow<str>]) -> Option<usize> {
    cells
        .iter()
        .position(|c| names.iter().any(|n| c.trim().eq_ignore_ascii_case(n)))
}

/// True when a header line names excitation and emission columns (for detection).
pub(super) fn looks_like_header(line: &str) -> bool {
    let cells = split_cells(line, Delimiter::detect(line));
    role_of(&EXCITATION_NAMES, &cells).is_some() && role_of(&EMISSION_NAMES, &cells).is_some()
}

pub(super) fn read(path: &Path, lines: &[Line]) -> Result<Parsed> {
    let skipped = |l: &Line| l.is_blank() || l.text.trim_start().starts_with('#');
    let Some(header_index) = lines.iter().position(|l| !skipped(l)) else {
        return Err(Error::parse(path, 0, 0, "holds no header line"));
    };
    let header = lines[header_index];
    let delimiter = Delimiter::detect(header.text);
    let reader = CellReader {
        path,
        decimal_comma: delimiter.allows_decimal_comma(),
    };
    let mut names = split_cells(header.text, delimiter);
    drop_trailing_empty(&mut names);
    let find = |role: &[&str], what: &str| {
        role_of(role, &names).ok_or_else(|| {
            reader.error(
                header.number,
                0,
                format!(
                    "the header has no {what} column; a long CSV needs the columns excitation_nm, emission_nm and value (in any order)"
                ),
            )
        })
    };
    let (ex_col, em_col, value_col) = (
        find(&EXCITATION_NAMES, "excitation_nm")?,
        find(&EMISSION_NAMES, "emission_nm")?,
        find(&VALUE_NAMES, "value")?,
    );
    let width = names.len();

    // (excitation, emission, value, line)
    let mut entries: Vec<(f64, f64, f64, usize)> = Vec::new();
    for line in lines.iter().skip(header_index + 1) {
        if skipped(line) {
            continue;
        }
        let mut cells = split_cells(line.text, delimiter);
        if cells.iter().all(|c| c.is_empty()) {
            continue;
        }
        if cells.len() > width {
            drop_trailing_empty(&mut cells);
        }
        if cells.len() != width {
            let why = format!(
                "the header on line {} names {width} columns; give every row one cell per column",
                header.number
            );
            return Err(reader.ragged_row(line.number, cells.len(), width, &why));
        }
        let ex = reader.wavelength(
            &cells[ex_col],
            line.number,
            ex_col + 1,
            "excitation wavelength",
        )?;
        let em = reader.wavelength(
            &cells[em_col],
            line.number,
            em_col + 1,
            "emission wavelength",
        )?;
        let v = reader.value(&cells[value_col], line.number, value_col + 1)?;
        entries.push((ex, em, v, line.number));
    }
    if entries.is_empty() {
        return Err(Error::parse(
            path,
            header.number,
            0,
            "has a header line but no data rows; the file seems truncated",
        ));
    }

    let grid = |pick: fn(&(f64, f64, f64, usize)) -> f64| {
        let mut g: Vec<f64> = entries.iter().map(pick).collect();
        g.sort_by(f64::total_cmp);
        g.dedup();
        g
    };
    let excitation_nm = grid(|e| e.0);
    let emission_nm = grid(|e| e.1);
    let cells = excitation_nm.len().saturating_mul(emission_nm.len());
    if cells > MAX_CELLS {
        return Err(Error::parse(
            path,
            0,
            0,
            format!(
                "the {} excitation × {} emission wavelengths span {cells} cells, more than the {MAX_CELLS} fluorite handles; check the wavelength columns",
                excitation_nm.len(),
                emission_nm.len()
            ),
        ));
    }
    let mut values = vec![f64::NAN; cells];
    let mut first_line = vec![0usize; cells];
    for &(ex, em, v, line) in &entries {
        let i = excitation_nm.partition_point(|&x| x < ex);
        let j = emission_nm.partition_point(|&x| x < em);
        let k = i * emission_nm.len() + j;
        if first_line[k] != 0 {
            return Err(reader.error(
                line,
                0,
                format!(
                    "duplicate cell: excitation {ex} nm, emission {em} nm already appears on line {}; give each combination once",
                    first_line[k]
                ),
            ));
        }
        first_line[k] = line;
        values[k] = v;
    }
    Ok(Parsed::surface(
        excitation_nm,
        emission_nm,
        values,
        Vec::new(),
    ))
}
