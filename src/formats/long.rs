//! Long CSV: one cell per line, with a header naming an excitation, an emission and a
//! value column in any order (other columns are ignored). Combinations that do not appear
//! are missing cells.
//!
//! Header names are matched the way labs write them: case-insensitively, with units in
//! brackets and `nm` dropped and `wavelength`/`lambda`/`λ` ignored, so `Ex (nm)`, `EX`,
//! `Excitation`, `excitation_wavelength`, `lambda_ex` and `λex [nm]` all name the
//! excitation column; `Intensity`, `Signal`, `value`, `Counts`, `RF` and the like the
//! values. When the excitation and emission columns are found and exactly one other
//! column is left, that column holds the values (with a note). A unit row right under the
//! header (`nm,nm,a.u.`) is skipped with a note.

use std::path::Path;

use crate::error::{Error, Result};

use super::Parsed;
use super::table::unit_row;
use super::text::{CellReader, Delimiter, Line, drop_trailing_empty, quote, split_cells};

/// Guard against a file whose few lines span an enormous grid (memory, not correctness).
const MAX_CELLS: usize = 10_000_000;

/// Words that name the excitation column (after [`words`] has normalised the header).
const EXCITATION_WORDS: [&str; 5] = ["ex", "exc", "excit", "excitation", "lambdaex"];
/// Words that name the emission column.
const EMISSION_WORDS: [&str; 5] = ["em", "emi", "emis", "emission", "lambdaem"];
/// Words any of which marks the value column.
const VALUE_WORDS: [&str; 16] = [
    "value",
    "values",
    "intensity",
    "signal",
    "counts",
    "count",
    "cps",
    "rf",
    "fluorescence",
    "fl",
    "radiance",
    "reflectance",
    "reradiation",
    "response",
    "amplitude",
    "reading",
];
/// Words that carry no meaning in a header (`Wavelength Ex (nm)`, `lambda_em`).
const FILLER_WORDS: [&str; 5] = ["nm", "wavelength", "wavelengths", "wl", "lambda"];

/// What a long header's column holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Role {
    Excitation,
    Emission,
    Value,
}

/// The words of a header cell: lower case, bracketed parts (units) dropped, `λ` spelled
/// `lambda`, split at everything that is not a letter or digit, filler words dropped.
fn words(cell: &str) -> Vec<String> {
    let mut kept = String::with_capacity(cell.len());
    let mut depth = 0usize;
    for c in cell.chars() {
        match c {
            '(' | '[' | '{' => depth += 1,
            ')' | ']' | '}' => depth = depth.saturating_sub(1),
            'λ' | 'Λ' if depth == 0 => kept.push_str(" lambda "),
            _ if depth == 0 => kept.extend(c.to_lowercase()),
            _ => {}
        }
    }
    kept.split(|c: char| !c.is_alphanumeric())
        .filter(|w| !w.is_empty() && !FILLER_WORDS.contains(w))
        .map(str::to_string)
        .collect()
}

/// The role a header cell names, if any: one excitation or emission word (`lambda ex`
/// and `ex_nm` reduce to `ex`), or any value word.
fn role(cell: &str) -> Option<Role> {
    let words = words(cell);
    let joined = words.concat();
    let is = |names: &[&str]| names.contains(&joined.as_str());
    if words.len() <= 2 && is(&EXCITATION_WORDS) {
        Some(Role::Excitation)
    } else if words.len() <= 2 && is(&EMISSION_WORDS) {
        Some(Role::Emission)
    } else if words.iter().any(|w| VALUE_WORDS.contains(&w.as_str())) {
        Some(Role::Value)
    } else {
        None
    }
}

fn role_of(role_wanted: Role, cells: &[std::borrow::Cow<str>]) -> Option<usize> {
    cells.iter().position(|c| role(c) == Some(role_wanted))
}

/// True when a header line names excitation and emission columns (for detection).
pub(super) fn looks_like_header(line: &str) -> bool {
    let cells = split_cells(line, Delimiter::detect(line));
    role_of(Role::Excitation, &cells).is_some() && role_of(Role::Emission, &cells).is_some()
}

/// The header names a long CSV accepts, for messages.
const ACCEPTED: &str = "excitation: ex, excitation, excitation_nm, lambda_ex, \"Ex (nm)\"; emission: em, emission, emission_nm, lambda_em, \"Em (nm)\"; values: value, intensity, signal, counts, RF (any case; units in brackets and the words wavelength and nm are ignored)";

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
    let missing = |what: &str| {
        reader.error(
            header.number,
            0,
            format!(
                "the header {} has no {what} column; a long CSV names its excitation, emission and value columns in any order ({ACCEPTED}). Rename the column, or if this is another layout, pass --format with one of the layouts fluorite reads ({})",
                quote(header.text),
                super::SUPPORTED
            ),
        )
    };
    let ex_col = role_of(Role::Excitation, &names).ok_or_else(|| missing("excitation_nm"))?;
    let em_col = role_of(Role::Emission, &names).ok_or_else(|| missing("emission_nm"))?;
    let mut notes = Vec::new();
    let value_col = match role_of(Role::Value, &names) {
        Some(k) => k,
        // Three columns, two of them wavelengths: the third can only be the values.
        None if names.len() == 3 && !names[3 - ex_col - em_col].is_empty() => {
            let k = 3 - ex_col - em_col;
            notes.push(format!(
                "column {} {} read as the values: it is the only column besides excitation and emission",
                k + 1,
                quote(&names[k])
            ));
            k
        }
        None => return Err(missing("value")),
    };
    let mut data_lines: Vec<Line> = lines[header_index + 1..].to_vec();
    if let Some(k) = unit_row(&data_lines, delimiter) {
        let unit = data_lines.remove(k);
        notes.push(format!(
            "line {} {} read as a unit row under the header and skipped",
            unit.number,
            quote(unit.text.trim())
        ));
    }
    let width = names.len();

    // (excitation, emission, value, line)
    let mut entries: Vec<(f64, f64, f64, usize)> = Vec::new();
    for line in &data_lines {
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
    Ok(Parsed::surface(excitation_nm, emission_nm, values, notes))
}
