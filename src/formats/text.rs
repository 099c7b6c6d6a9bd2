//! Text handling shared by the readers: decoding, lines, cells, numbers and grid checks.
//!
//! Every function that can fail returns an [`Error::Parse`] naming the file, the 1-based
//! line and the 1-based field (column), so readers only say what a cell means.

use std::borrow::Cow;
use std::path::Path;

use crate::error::{Error, Result};

/// Decodes file bytes: UTF-8 when valid (a byte-order mark is dropped), otherwise
/// latin-1, which is what the BFC-450 software writes and which maps every byte to a
/// character, so decoding never fails.
pub(crate) fn decode(bytes: &[u8]) -> Cow<'_, str> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    match std::str::from_utf8(bytes) {
        Ok(text) => Cow::Borrowed(text),
        Err(_) => Cow::Owned(bytes.iter().map(|&b| char::from(b)).collect()),
    }
}

/// One line of a file with its 1-based number.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Line<'a> {
    /// 1-based line number, as an editor shows it.
    pub number: usize,
    /// The line without its line end.
    pub text: &'a str,
}

impl Line<'_> {
    /// True for lines holding nothing but whitespace.
    pub fn is_blank(&self) -> bool {
        self.text.trim().is_empty()
    }
}

/// Splits text into lines. LF and CRLF ends are both accepted, as are the doubled CRs of
/// some WebFluor exports (`\r\r\n`); a file with bare CR ends (classic Mac) is split on CR.
pub(crate) fn split_lines(text: &str) -> Vec<Line<'_>> {
    let separator = if text.contains('\n') { '\n' } else { '\r' };
    text.split(separator)
        .enumerate()
        .map(|(i, t)| Line {
            number: i + 1,
            text: t.trim_end_matches('\r'),
        })
        .collect()
}

/// The data lines of a small delimited text file (a light, an absorbance spectrum): for
/// every line neither blank nor a `#` comment, its number (from 1) and its fields, split
/// at commas, semicolons, tabs and spaces.
pub(crate) fn delimited_fields(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.lines().enumerate().filter_map(|(n, line)| {
        let line = line.trim();
        let data = !(line.is_empty() || line.starts_with('#'));
        data.then(|| {
            let fields = line
                .split([',', ';', '\t', ' '])
                .filter(|f| !f.is_empty())
                .collect();
            (n + 1, fields)
        })
    })
}

/// How the cells of a line are separated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Delimiter {
    /// A single character: `,`, `;` or tab.
    Char(char),
    /// Runs of spaces or tabs (WebFluor).
    Whitespace,
}

impl Delimiter {
    /// Picks the delimiter of a header line: the most frequent of tab, `;` and `,`
    /// outside quotes (ties go to tab, then `;`, since those files may use decimal
    /// commas), or whitespace when none occurs.
    pub fn detect(header: &str) -> Delimiter {
        let mut counts = [0usize; 3];
        let mut in_quotes = false;
        for c in header.chars() {
            match c {
                '"' => in_quotes = !in_quotes,
                '\t' if !in_quotes => counts[0] += 1,
                ';' if !in_quotes => counts[1] += 1,
                ',' if !in_quotes => counts[2] += 1,
                _ => {}
            }
        }
        let candidates = ['\t', ';', ','];
        let best = (0..3).fold(0, |best, k| if counts[k] > counts[best] { k } else { best });
        if counts[best] == 0 {
            Delimiter::Whitespace
        } else {
            Delimiter::Char(candidates[best])
        }
    }

    /// Whether a cell like `0,5` may be read as a decimal comma: only when the comma
    /// cannot be a separator.
    pub fn allows_decimal_comma(self) -> bool {
        self != Delimiter::Char(',')
    }
}

/// Splits a line into trimmed cells. Double-quoted cells (RFC 4180, `""` for a quote)
/// may contain the delimiter; the quotes are removed.
pub(crate) fn split_cells(line: &str, delimiter: Delimiter) -> Vec<Cow<'_, str>> {
    match delimiter {
        Delimiter::Whitespace => line.split_whitespace().map(Cow::Borrowed).collect(),
        Delimiter::Char(d) if !line.contains('"') => {
            line.split(d).map(|c| Cow::Borrowed(c.trim())).collect()
        }
        Delimiter::Char(d) => split_quoted(line, d),
    }
}

fn split_quoted(line: &str, delimiter: char) -> Vec<Cow<'_, str>> {
    let mut cells = Vec::new();
    let mut cell = String::new();
    let mut in_quotes = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        if in_quotes {
            if c == '"' {
                if chars.peek() == Some(&'"') {
                    cell.push('"');
                    chars.next();
                } else {
                    in_quotes = false;
                }
            } else {
                cell.push(c);
            }
        } else if c == '"' && cell.trim().is_empty() {
            cell.clear();
            in_quotes = true;
        } else if c == delimiter {
            cells.push(Cow::Owned(cell.trim().to_string()));
            cell.clear();
        } else {
            cell.push(c);
        }
    }
    cells.push(Cow::Owned(cell.trim().to_string()));
    cells
}

/// Drops empty cells at the end of a line (trailing delimiters, as BFC-450 writes).
pub(crate) fn drop_trailing_empty(cells: &mut Vec<Cow<'_, str>>) {
    while cells.last().is_some_and(|c| c.is_empty()) {
        cells.pop();
    }
}

/// What a numeric cell holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Number {
    /// Empty, `NaN` or `NA` (any case): no measured value.
    Missing,
    /// A finite number.
    Finite(f64),
    /// An infinity, written out or overflowing.
    Infinite,
    /// Not a number at all.
    Invalid,
}

/// Reads a cell as a number. `decimal_comma` also accepts `0,5` for 0.5.
pub(crate) fn parse_number(cell: &str, decimal_comma: bool) -> Number {
    if cell.is_empty() || cell.eq_ignore_ascii_case("na") {
        return Number::Missing;
    }
    let parsed = cell.parse::<f64>().ok().or_else(|| {
        let one_comma = decimal_comma && cell.matches(',').count() == 1 && !cell.contains('.');
        one_comma
            .then(|| cell.replace(',', ".").parse::<f64>().ok())
            .flatten()
    });
    match parsed {
        Some(v) if v.is_nan() => Number::Missing,
        Some(v) if v.is_infinite() => Number::Infinite,
        Some(v) => Number::Finite(v),
        None => Number::Invalid,
    }
}

/// Shortens a cell for quoting in a message.
pub(crate) fn quote(cell: &str) -> String {
    const MAX: usize = 40;
    if cell.chars().count() <= MAX {
        format!("\"{cell}\"")
    } else {
        let head: String = cell.chars().take(MAX).collect();
        format!("\"{head}…\"")
    }
}

/// Reads one line's cells and positions for errors.
pub(crate) struct CellReader<'p> {
    /// The file, for errors.
    pub path: &'p Path,
    /// Whether `0,5` reads as 0.5.
    pub decimal_comma: bool,
}

impl CellReader<'_> {
    /// A parse error at `line`, `column` (1-based).
    pub fn error(&self, line: usize, column: usize, message: impl Into<String>) -> Error {
        Error::parse(self.path, line, column, message)
    }

    /// A ragged row at `line`: it has `cells` cells where `width` are due; `why` says what
    /// sets the width and how to mend the row.
    pub fn ragged_row(&self, line: usize, cells: usize, width: usize, why: &str) -> Error {
        self.error(
            line,
            cells.min(width) + 1,
            format!("ragged row: it has {cells} cells, but {why}"),
        )
    }

    /// A measured value; missing cells become NaN.
    pub fn value(&self, cell: &str, line: usize, column: usize) -> Result<f64> {
        match parse_number(cell, self.decimal_comma) {
            Number::Finite(v) => Ok(v),
            Number::Missing => Ok(f64::NAN),
            Number::Infinite => Err(self.error(
                line,
                column,
                format!(
                    "value {} is infinite (or too large for a 64-bit number); values must be finite: write NaN or leave the cell empty for a missing value",
                    quote(cell)
                ),
            )),
            Number::Invalid => Err(self.error(
                line,
                column,
                format!(
                    "value {} is not a number; write a decimal number such as 0.0123, or leave the cell empty (or write NaN or NA) for a missing value",
                    quote(cell)
                ),
            )),
        }
    }

    /// A wavelength in nm: must be present and within [`crate::limits::WAVELENGTH_NM`]. `what` says which
    /// (`column wavelength`, `row wavelength`, `excitation wavelength`).
    pub fn wavelength(&self, cell: &str, line: usize, column: usize, what: &str) -> Result<f64> {
        match parse_number(cell, self.decimal_comma) {
            Number::Finite(v) if v > 0.0 => crate::limits::check_wavelength(v)
                .map(|()| v)
                .map_err(|message| self.error(line, column, format!("{what} {message}"))),
            Number::Finite(v) => Err(self.error(
                line,
                column,
                format!("{what} {v} nm is not positive; wavelengths are in nm and must be greater than 0"),
            )),
            Number::Missing => Err(self.error(
                line,
                column,
                format!(
                    "{what} is missing ({}); every row and column needs its wavelength in nm",
                    if cell.is_empty() { "empty cell".to_string() } else { quote(cell) }
                ),
            )),
            Number::Infinite => Err(self.error(
                line,
                column,
                format!(
                    "{what} {} is infinite (or too large for a 64-bit number); wavelengths are in nm, within {}",
                    quote(cell),
                    crate::limits::range_text()
                ),
            )),
            Number::Invalid => Err(self.error(
                line,
                column,
                format!("{what} {} is not a number; write the wavelength in nm, such as 380", quote(cell)),
            )),
        }
    }
}

/// Where a wavelength was read: for messages about duplicates and order.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Located {
    /// The wavelength in nm.
    pub nm: f64,
    /// 1-based line.
    pub line: usize,
    /// 1-based field.
    pub column: usize,
}

/// Describes a position for a message: `line 4` for rows, `column 7` for header cells.
fn position(at: &Located, by_line: bool) -> String {
    if by_line {
        format!("line {}", at.line)
    } else {
        format!("column {}", at.column)
    }
}

/// Rejects repeated wavelengths, naming both places. `by_line` says whether the
/// wavelengths run down the lines (rows) or along one line (a header).
pub(crate) fn check_unique(
    path: &Path,
    items: &[Located],
    what: &str,
    by_line: bool,
) -> Result<()> {
    let mut order: Vec<usize> = (0..items.len()).collect();
    order.sort_by(|&a, &b| items[a].nm.total_cmp(&items[b].nm).then(a.cmp(&b)));
    // Report the repeat that comes first in the file.
    let repeat = order
        .windows(2)
        .filter(|w| items[w[0]].nm == items[w[1]].nm)
        .map(|w| (w[0], w[1]))
        .min_by_key(|&(_, later)| later);
    if let Some((first, later)) = repeat {
        let (a, b) = (&items[first], &items[later]);
        return Err(Error::parse(
            path,
            b.line,
            b.column,
            format!(
                "duplicate {what} {} nm: it already appears at {}; each wavelength may appear only once",
                b.nm,
                position(a, by_line)
            ),
        ));
    }
    Ok(())
}

/// Rejects wavelengths that do not increase, naming the first out of order.
pub(crate) fn check_increasing(
    path: &Path,
    items: &[Located],
    what: &str,
    by_line: bool,
) -> Result<()> {
    check_unique(path, items, what, by_line)?;
    if let Some(w) = items.windows(2).find(|w| w[1].nm < w[0].nm) {
        let order = if by_line { "rows" } else { "columns" };
        return Err(Error::parse(
            path,
            w[1].line,
            w[1].column,
            format!(
                "unsorted {what}s: {} nm comes after {} nm at {}; order the {order} by increasing wavelength",
                w[1].nm,
                w[0].nm,
                position(&w[0], by_line)
            ),
        ));
    }
    Ok(())
}

/// Hex digest of the file's bytes, for provenance.
pub(crate) fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::{Digest, Sha256};
    use std::fmt::Write;
    let digest = Sha256::digest(bytes);
    digest.iter().fold(String::with_capacity(64), |mut s, b| {
        let _ = write!(s, "{b:02x}");
        s
    })
}

/// Formats a number so that reading it back gives the same `f64`: integers plainly
/// (`380`), others in Rust's shortest round-trip form, NaN as `NaN`.
pub(crate) fn format_number(v: f64) -> String {
    if v.is_nan() {
        "NaN".to_string()
    } else if v == v.trunc() && v.abs() < 1e15 {
        format!("{v}")
    } else {
        format!("{v:?}")
    }
}
