//! The layout shared by wide CSV, WebFluor and the body of BFC-450 files: a header line
//! of column wavelengths (after an optional corner cell), then rows that start with their
//! wavelength and hold one value per column.

use std::path::Path;

use crate::error::{Error, Result};

use super::RowsAre;
use super::text::{
    CellReader, Delimiter, Line, Located, Number, drop_trailing_empty, parse_number, split_cells,
};

/// A matrix as laid out in the file, rows in file order.
#[derive(Debug)]
pub(crate) struct Table {
    /// The corner cell's text, `None` when the header starts with a wavelength.
    pub corner: Option<String>,
    /// Line of the header.
    pub header_line: usize,
    /// Column wavelengths with their positions.
    pub columns: Vec<Located>,
    /// Row wavelengths with their positions (column 1).
    pub rows: Vec<Located>,
    /// Row-major values, `rows.len() × columns.len()`, NaN = missing.
    pub values: Vec<f64>,
    /// Index into the lines where reading stopped: the terminator line, or the end.
    pub stopped_at: usize,
    /// True when the terminator line was found.
    pub terminated: bool,
}

/// How to read a table.
pub(crate) struct TableLayout<'a> {
    /// The file, for errors.
    pub path: &'a Path,
    /// Cell separator.
    pub delimiter: Delimiter,
    /// A line that ends the table (`EOD`), compared case-insensitively after trimming.
    pub terminator: Option<&'a str>,
    /// Skip lines starting with `#` (comments in CSV files).
    pub skip_comments: bool,
}

impl<'a> TableLayout<'a> {
    /// A table of `path` that runs to the end of the file, `#` lines being comments (the
    /// wide CSV and WebFluor layouts).
    pub fn commented(path: &'a Path, delimiter: Delimiter) -> Self {
        TableLayout {
            path,
            delimiter,
            terminator: None,
            skip_comments: true,
        }
    }

    fn skipped(&self, line: &Line) -> bool {
        line.is_blank() || (self.skip_comments && line.text.trim_start().starts_with('#'))
    }

    fn is_terminator(&self, line: &Line) -> bool {
        self.terminator
            .is_some_and(|t| line.text.trim().eq_ignore_ascii_case(t))
    }

    /// Reads the table whose header is the first non-skipped line of `lines`.
    pub fn read(&self, lines: &[Line]) -> Result<Table> {
        let reader = CellReader {
            path: self.path,
            decimal_comma: self.delimiter.allows_decimal_comma(),
        };
        let Some(header_index) = lines.iter().position(|l| !self.skipped(l)) else {
            return Err(Error::parse(
                self.path,
                0,
                0,
                "holds no header line; expected a line of column wavelengths",
            ));
        };
        let header = lines[header_index];
        let mut cells = split_cells(header.text, self.delimiter);
        drop_trailing_empty(&mut cells);
        // A header that starts with a number has no corner cell (WebFluor layout).
        let has_corner = cells
            .first()
            .is_none_or(|c| matches!(parse_number(c, false), Number::Invalid | Number::Missing));
        let first_wavelength = usize::from(has_corner);
        let corner = has_corner.then(|| cells.first().map(|c| c.to_string()).unwrap_or_default());
        if cells.len() <= first_wavelength {
            return Err(reader.error(
                header.number,
                cells.len() + 1,
                "the header line has no column wavelengths; after the corner cell it must list one wavelength (nm) per column",
            ));
        }
        let mut columns = Vec::with_capacity(cells.len());
        for (k, cell) in cells.iter().enumerate().skip(first_wavelength) {
            let nm = reader.wavelength(cell, header.number, k + 1, "column wavelength")?;
            columns.push(Located {
                nm,
                line: header.number,
                column: k + 1,
            });
        }
        let width = columns.len() + 1;

        let mut rows = Vec::new();
        let mut values = Vec::new();
        let mut stopped_at = lines.len();
        let mut terminated = false;
        for (index, line) in lines.iter().enumerate().skip(header_index + 1) {
            if self.is_terminator(line) {
                stopped_at = index;
                terminated = true;
                break;
            }
            if self.skipped(line) {
                continue;
            }
            let mut cells = split_cells(line.text, self.delimiter);
            if cells.iter().all(|c| c.is_empty()) {
                continue;
            }
            if cells.len() > width {
                // Trailing delimiters are harmless; only real extra cells are ragged.
                drop_trailing_empty(&mut cells);
            }
            let is_last = lines[index + 1..].iter().all(|l| l.is_blank());
            if cells.len() < width && is_last && self.terminator.is_some() {
                return Err(reader.error(
                    line.number,
                    0,
                    format!(
                        "the file ends in the middle of a row ({} of {width} cells) without the closing {} line; it is truncated",
                        cells.len(),
                        self.terminator.unwrap_or_default()
                    ),
                ));
            }
            if cells.len() != width {
                let corner_note = if has_corner {
                    format!(
                        "the header on line {} has a corner cell and {} column wavelengths",
                        header.number,
                        columns.len()
                    )
                } else {
                    format!(
                        "the header on line {} has {} column wavelengths",
                        header.number,
                        columns.len()
                    )
                };
                let mend = if cells.len() < width {
                    "add the missing cells (leave them empty for missing values)"
                } else {
                    "remove the extra cells or add their wavelengths to the header"
                };
                let why = format!(
                    "{corner_note}, so every row needs {width} cells (its wavelength, then one value per column); {mend}"
                );
                return Err(reader.ragged_row(line.number, cells.len(), width, &why));
            }
            let nm = reader.wavelength(&cells[0], line.number, 1, "row wavelength")?;
            rows.push(Located {
                nm,
                line: line.number,
                column: 1,
            });
            for (k, cell) in cells.iter().enumerate().skip(1) {
                values.push(reader.value(cell, line.number, k + 1)?);
            }
        }
        Ok(Table {
            corner,
            header_line: header.number,
            columns,
            rows,
            values,
            stopped_at,
            terminated,
        })
    }
}

impl Table {
    /// An error unless the table has rows; `what` says what the file held instead.
    pub fn require_rows(&self, path: &Path, what: &str) -> Result<()> {
        if self.rows.is_empty() {
            return Err(Error::parse(
                path,
                self.header_line,
                0,
                format!("{what}; the file seems truncated"),
            ));
        }
        Ok(())
    }

    /// Sorts the rows by increasing wavelength (rows must be unique).
    pub fn sort_rows(&mut self) {
        let n = self.columns.len();
        let mut order: Vec<usize> = (0..self.rows.len()).collect();
        order.sort_by(|&a, &b| self.rows[a].nm.total_cmp(&self.rows[b].nm));
        let rows = order.iter().map(|&r| self.rows[r]).collect();
        let values = order
            .iter()
            .flat_map(|&r| self.values[r * n..(r + 1) * n].iter().copied())
            .collect();
        self.rows = rows;
        self.values = values;
    }

    /// The matrix excitation-major: `(excitation_nm, emission_nm, values)`, transposing
    /// when the rows are emission wavelengths.
    pub fn to_excitation_major(&self, rows_are: RowsAre) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let row_nm: Vec<f64> = self.rows.iter().map(|r| r.nm).collect();
        let column_nm: Vec<f64> = self.columns.iter().map(|c| c.nm).collect();
        match rows_are {
            RowsAre::Excitation => (row_nm, column_nm, self.values.clone()),
            RowsAre::Emission => {
                let (n_rows, n_columns) = (row_nm.len(), column_nm.len());
                let mut values = vec![f64::NAN; self.values.len()];
                for r in 0..n_rows {
                    for c in 0..n_columns {
                        values[c * n_rows + r] = self.values[r * n_columns + c];
                    }
                }
                (column_nm, row_nm, values)
            }
        }
    }

    /// Which side of the diagonal holds the signal: the sums of squared values at
    /// column wavelength above (`.0`) and below (`.1`) the row wavelength, leaving out
    /// one grid step around the diagonal, where instruments show crosstalk.
    pub fn off_diagonal_energy(&self) -> (f64, f64) {
        let guard = typical_step(&self.rows).max(typical_step(&self.columns)) + 1e-6;
        let n = self.columns.len();
        let (mut above, mut below) = (0.0, 0.0);
        for (r, row) in self.rows.iter().enumerate() {
            for (c, column) in self.columns.iter().enumerate() {
                let v = self.values[r * n + c];
                if v.is_nan() {
                    continue;
                }
                let offset = column.nm - row.nm;
                if offset > guard {
                    above += v * v;
                } else if offset < -guard {
                    below += v * v;
                }
            }
        }
        (above, below)
    }
}

/// The index in `lines` of a unit row (`nm,nm,a.u.`, `unit,a.u.,a.u.`): the first line
/// that is neither blank nor a `#` comment, when none of its cells is a number and at
/// least one is text. `lines` start right under the header.
pub(crate) fn unit_row(lines: &[Line], delimiter: Delimiter) -> Option<usize> {
    let index = lines
        .iter()
        .position(|l| !l.is_blank() && !l.text.trim_start().starts_with('#'))?;
    let cells = split_cells(lines[index].text, delimiter);
    let kinds: Vec<Number> = cells
        .iter()
        .map(|c| parse_number(c, delimiter.allows_decimal_comma()))
        .collect();
    let no_number = kinds
        .iter()
        .all(|k| matches!(k, Number::Invalid | Number::Missing));
    (no_number && kinds.contains(&Number::Invalid)).then_some(index)
}

/// Median spacing of a set of wavelengths in any order (0 for fewer than two).
fn typical_step(items: &[Located]) -> f64 {
    let mut nm: Vec<f64> = items.iter().map(|l| l.nm).collect();
    nm.sort_by(f64::total_cmp);
    crate::numeric::median_step(&nm)
}
