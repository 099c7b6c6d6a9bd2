//! Wide CSV: a corner cell, then the column wavelengths; each further row starts with its
//! wavelength. Separated by commas, semicolons or tabs (or runs of spaces).
//!
//! The corner label says what the rows are (`ex\em`, `excitation\emission`,
//! `ex_nm\em_nm`: excitation rows; `em\ex`, `em_nm\ex_nm`, `emission\excitation`:
//! emission rows; `/` works like `\`). [`ReadOptions::rows`] overrides it. With neither,
//! the orientation is inferred from the side of the diagonal that holds the signal, since
//! fluorescence appears at emission wavelengths above the excitation wavelength.

use std::path::Path;

use crate::error::{Error, Result};

use super::table::{Table, TableLayout, unit_row};
use super::text::{Delimiter, Line, Number, check_increasing, parse_number, quote, split_cells};
use super::{Parsed, ReadOptions, RowsAre};

/// How much larger one side's signal must be to call the orientation.
const DECISIVE_RATIO: f64 = 2.0;

pub(super) fn read(path: &Path, lines: &[Line], options: &ReadOptions) -> Result<Parsed> {
    let header_index = lines
        .iter()
        .position(|l| !l.is_blank() && !l.text.trim_start().starts_with('#'))
        .ok_or_else(|| Error::parse(path, 0, 0, "holds no header line"))?;
    let header = lines[header_index];
    let delimiter = Delimiter::detect(header.text);
    check_header(path, &header, delimiter)?;
    let mut notes = Vec::new();
    let mut lines = lines.to_vec();
    if let Some(k) = unit_row(&lines[header_index + 1..], delimiter) {
        let unit = lines.remove(header_index + 1 + k);
        notes.push(format!(
            "line {} {} read as a unit row under the header and skipped",
            unit.number,
            quote(unit.text.trim())
        ));
    }
    let layout = TableLayout::commented(path, delimiter);
    let table = layout.read(&lines)?;
    table.require_rows(
        path,
        "has a header line of column wavelengths but no data rows",
    )?;
    check_increasing(path, &table.columns, "column wavelength", false)?;
    check_increasing(path, &table.rows, "row wavelength", true)?;

    let rows_are = orientation(&table, options.rows, &mut notes);
    let (excitation_nm, emission_nm, values) = table.to_excitation_major(rows_are);
    Ok(Parsed::surface(excitation_nm, emission_nm, values, notes))
}

/// Refuses a header whose column cells hold words, not wavelengths: the file is likely
/// another layout, so the error lists the layouts fluorite reads and `--format`.
fn check_header(path: &Path, header: &Line, delimiter: Delimiter) -> Result<()> {
    let cells = split_cells(header.text, delimiter);
    let number = |c: &str| parse_number(c, delimiter.allows_decimal_comma());
    let has_corner = cells
        .first()
        .is_some_and(|c| matches!(number(c), Number::Invalid | Number::Missing));
    let word = cells
        .iter()
        .enumerate()
        .skip(usize::from(has_corner))
        .find(|(_, c)| number(c) == Number::Invalid);
    match word {
        Some((k, cell)) => Err(Error::parse(
            path,
            header.number,
            k + 1,
            format!(
                "column wavelength {} is not a number, so this is no wide matrix (a corner cell, then one wavelength in nm per column). fluorite reads {}; rename the header cells to match one layout, or pass its --format",
                quote(cell),
                super::SUPPORTED
            ),
        )),
        None => Ok(()),
    }
}

/// What a corner label says the rows are, if it says anything.
pub(super) fn rows_from_corner(corner: &str) -> Option<RowsAre> {
    let label = corner.trim().to_ascii_lowercase();
    let mut sides = label.split(['\\', '/']).map(str::trim);
    let rows_side = sides.next().map(side_meaning)?;
    let columns_side = sides.next().map(side_meaning);
    if sides.next().is_some() {
        return None;
    }
    match (rows_side, columns_side) {
        (Some(rows), None) => Some(rows),
        (Some(rows), Some(Some(columns))) if rows != columns => Some(rows),
        (None, Some(Some(columns))) => Some(match columns {
            RowsAre::Excitation => RowsAre::Emission,
            RowsAre::Emission => RowsAre::Excitation,
        }),
        _ => None,
    }
}

/// `ex`, `ex_nm`, `excitation`, `excitation_nm` → excitation; `em…`/`emission…` → emission.
fn side_meaning(side: &str) -> Option<RowsAre> {
    let (has_ex, has_em) = (side.contains("ex"), side.contains("em"));
    match (has_ex, has_em) {
        (true, false) => Some(RowsAre::Excitation),
        (false, true) => Some(RowsAre::Emission),
        _ => None,
    }
}

fn name(rows: RowsAre) -> &'static str {
    match rows {
        RowsAre::Excitation => "excitation",
        RowsAre::Emission => "emission",
    }
}

fn other(rows: RowsAre) -> RowsAre {
    match rows {
        RowsAre::Excitation => RowsAre::Emission,
        RowsAre::Emission => RowsAre::Excitation,
    }
}

/// Decides the orientation: option, then corner label, then the signal; notes what was
/// decided whenever the file itself does not say it.
fn orientation(table: &Table, option: Option<RowsAre>, notes: &mut Vec<String>) -> RowsAre {
    let from_corner = table.corner.as_deref().and_then(rows_from_corner);
    if let Some(rows) = option {
        if let Some(label) = from_corner.filter(|&c| c != rows) {
            notes.push(format!(
                "the corner label {:?} says rows are {} wavelengths, but rows were set to {} (--rows {})",
                table.corner.as_deref().unwrap_or_default(),
                name(label),
                name(rows),
                name(rows)
            ));
        }
        return rows;
    }
    if let Some(rows) = from_corner {
        return rows;
    }
    let why_unsure = match table.corner.as_deref() {
        None => "the file has no corner label".to_string(),
        Some("") => "the corner cell is empty".to_string(),
        Some(label) => format!("the corner label {label:?} does not name excitation or emission"),
    };
    let (above, below) = table.off_diagonal_energy();
    let inferred = if above > DECISIVE_RATIO * below {
        Some(RowsAre::Excitation)
    } else if below > DECISIVE_RATIO * above {
        Some(RowsAre::Emission)
    } else {
        None
    };
    match inferred {
        Some(rows) => {
            notes.push(format!(
                "rows read as {} wavelengths: {why_unsure}, and the off-diagonal signal lies where the column wavelength is {} the row wavelength ({:.0}% of it), as fluorescence lies at emission above excitation; if that is wrong, pass --rows {} (or label the corner ex\\em or em\\ex)",
                name(rows),
                if rows == RowsAre::Excitation { "above" } else { "below" },
                100.0 * above.max(below) / (above + below),
                name(other(rows)),
            ));
            rows
        }
        None => {
            notes.push(format!(
                "rows assumed to be excitation wavelengths: {why_unsure}, and the signal off the diagonal is about the same on both sides, so the orientation cannot be inferred; pass --rows excitation or --rows emission (or label the corner ex\\em or em\\ex) to be sure"
            ));
            RowsAre::Excitation
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corner_labels() {
        use RowsAre::*;
        for (label, rows) in [
            ("ex\\em", Some(Excitation)),
            ("excitation\\emission", Some(Excitation)),
            ("ex_nm\\em_nm", Some(Excitation)),
            ("Ex_nm/Em_nm", Some(Excitation)),
            ("em\\ex", Some(Emission)),
            ("em_nm\\ex_nm", Some(Emission)),
            ("emission/excitation", Some(Emission)),
            ("excitation", Some(Excitation)),
            ("\\em", Some(Excitation)),
            ("wavelength", None),
            ("", None),
            ("ex\\ex", None),
            ("a\\b\\c", None),
        ] {
            assert_eq!(rows_from_corner(label), rows, "{label}");
        }
    }
}
