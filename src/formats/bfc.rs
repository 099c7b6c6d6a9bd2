//! Labsphere BFC-450 matrix files.
//!
//! ```text
//! VEC_01  5167
//! BFC-450 Matrix File
//! ;sample name, instrument, date, time (metadata lines start with `;`)
//! 380  780  10  49  300  10          em_start em_end em_step n_ex ex_start ex_step
//! r:c:  300  310  …  780             the excitation wavelengths
//! 380   0.01 0.02 …                  one row per emission wavelength
//! …
//! EOD
//! ```
//! Tab-separated (trailing tabs occur), CRLF line ends, latin-1. Rows are emission.

use std::path::Path;

use crate::error::{Error, Result};
use crate::measurement::Measurement;

use super::table::TableLayout;
use super::text::{
    Delimiter, Line, Located, check_increasing, format_number, parse_number, split_cells,
};
use super::{Parsed, ReadOptions, RowsAre};

/// The line that identifies a BFC-450 matrix file.
pub(super) const HEADER: &str = "BFC-450 Matrix File";

/// Largest grid a grid line may announce (see [`crate::limits::MAX_GRID_POINTS`]).
const MAX_SAMPLES: f64 = crate::limits::MAX_GRID_POINTS as f64;

/// True for the identifying header line.
pub(super) fn is_header(line: &Line) -> bool {
    line.text.trim().eq_ignore_ascii_case(HEADER)
}

/// The grid line: `em_start em_end em_step n_ex ex_start ex_step`.
struct GridLine {
    line: usize,
    em_start: f64,
    em_end: f64,
    em_step: f64,
    n_em: usize,
    n_ex: usize,
    ex_start: f64,
    ex_step: f64,
}

const GRID_FIELDS: [&str; 6] = [
    "em_start", "em_end", "em_step", "n_ex", "ex_start", "ex_step",
];
const GRID_HELP: &str = "a BFC-450 grid line holds em_start em_end em_step n_ex ex_start ex_step, such as 380 780 10 49 300 10";

impl GridLine {
    fn parse(path: &Path, line: &Line) -> Result<GridLine> {
        let at = |column: usize, message: String| Error::parse(path, line.number, column, message);
        let cells = split_cells(line.text, Delimiter::Whitespace);
        if cells.len() < GRID_FIELDS.len() {
            return Err(at(
                0,
                format!(
                    "the grid line has {} fields, expected 6: {GRID_HELP}",
                    cells.len()
                ),
            ));
        }
        let mut f = [0.0; 6];
        for (k, name) in GRID_FIELDS.iter().enumerate() {
            f[k] = match parse_number(&cells[k], false) {
                super::text::Number::Finite(v) => v,
                _ => {
                    return Err(at(
                        k + 1,
                        format!(
                            "grid line field {name} is {}, not a finite number; {GRID_HELP}",
                            super::text::quote(&cells[k])
                        ),
                    ));
                }
            };
        }
        let [em_start, em_end, em_step, n_ex, ex_start, ex_step] = f;
        let positive = [
            (0, em_start, "wavelengths"),
            (4, ex_start, "wavelengths"),
            (2, em_step, "steps"),
            (5, ex_step, "steps"),
        ];
        for (k, value, what) in positive {
            if value <= 0.0 {
                return Err(at(
                    k + 1,
                    format!(
                        "grid line field {} is {value} nm; {what} must be positive",
                        GRID_FIELDS[k]
                    ),
                ));
            }
        }
        for (k, value) in [(0, em_start), (1, em_end), (4, ex_start)] {
            if let Err(message) = crate::limits::check_wavelength(value) {
                return Err(at(
                    k + 1,
                    format!("grid line field {}: {message}", GRID_FIELDS[k]),
                ));
            }
        }
        let ex_end = ex_start + (n_ex - 1.0) * ex_step;
        if n_ex >= 1.0
            && let Err(message) = crate::limits::check_wavelength(ex_end)
        {
            return Err(at(
                6,
                format!(
                    "the last excitation wavelength, ex_start + (n_ex − 1)·ex_step = {ex_start} + {}·{ex_step}: {message}",
                    n_ex - 1.0
                ),
            ));
        }
        let em_intervals = (em_end - em_start) / em_step;
        if em_intervals < -1e-6
            || (em_intervals - em_intervals.round()).abs() > 1e-6
            || em_intervals > MAX_SAMPLES
        {
            return Err(at(
                2,
                format!(
                    "the emission range {em_start}–{em_end} nm is not a whole number of {em_step} nm steps; {GRID_HELP}"
                ),
            ));
        }
        if n_ex < 1.0 || n_ex != n_ex.round() || n_ex > MAX_SAMPLES {
            return Err(at(
                4,
                format!(
                    "grid line field n_ex is {n_ex}; it must be a positive whole number of excitation wavelengths"
                ),
            ));
        }
        Ok(GridLine {
            line: line.number,
            em_start,
            em_end,
            em_step,
            n_em: em_intervals.round() as usize + 1,
            n_ex: n_ex as usize,
            ex_start,
            ex_step,
        })
    }
}

fn close(a: f64, b: f64, step: f64) -> bool {
    (a - b).abs() <= 1e-6 * step.max(1.0)
}

pub(super) fn read(path: &Path, lines: &[Line], options: &ReadOptions) -> Result<Parsed> {
    let truncated = |line: usize, what: &str| {
        Error::parse(
            path,
            line,
            0,
            format!("the file ends {what}; it is truncated (a BFC-450 file ends with a line EOD)"),
        )
    };
    let last_line = lines
        .iter()
        .rev()
        .find(|l| !l.is_blank())
        .map_or(0, |l| l.number);
    let header_index = lines.iter().position(is_header).ok_or_else(|| {
        Error::parse(
            path,
            0,
            0,
            format!("has no line {HEADER:?}, so it is not a BFC-450 matrix file; pass --format to read it as another format"),
        )
    })?;
    let next_content = |from: usize| {
        (from..lines.len())
            .find(|&k| !lines[k].is_blank() && !lines[k].text.trim_start().starts_with(';'))
    };
    let grid_index = next_content(header_index + 1).ok_or_else(|| {
        truncated(
            last_line,
            "before the grid line (em_start em_end em_step n_ex ex_start ex_step)",
        )
    })?;
    let grid = GridLine::parse(path, &lines[grid_index])?;
    let rc_index = next_content(grid_index + 1)
        .ok_or_else(|| truncated(last_line, "before the r:c: line of excitation wavelengths"))?;
    let rc_line = lines[rc_index];
    if !rc_line
        .text
        .trim_start()
        .to_ascii_lowercase()
        .starts_with("r:c:")
    {
        return Err(Error::parse(
            path,
            rc_line.number,
            1,
            format!(
                "expected the line r:c: followed by the excitation wavelengths after the grid line (line {}), found {}",
                grid.line,
                super::text::quote(rc_line.text.trim())
            ),
        ));
    }
    let delimiter = if rc_line.text.contains('\t') {
        Delimiter::Char('\t')
    } else {
        Delimiter::Whitespace
    };
    let layout = TableLayout {
        path,
        delimiter,
        terminator: Some("EOD"),
        skip_comments: false,
    };
    let table = layout.read(&lines[rc_index..])?;
    check_increasing(path, &table.columns, "excitation wavelength", false)?;
    check_increasing(path, &table.rows, "emission wavelength", true)?;

    if table.columns.len() != grid.n_ex {
        return Err(Error::parse(
            path,
            rc_line.number,
            0,
            format!(
                "the r:c: line lists {} excitation wavelengths, but the grid line (line {}) says n_ex = {}; make them agree",
                table.columns.len(),
                grid.line,
                grid.n_ex
            ),
        ));
    }
    check_against_grid(
        path,
        &table.columns,
        grid.ex_start,
        grid.ex_step,
        "excitation",
        grid.line,
    )?;
    let rows_found = table.rows.len();
    if rows_found > grid.n_em {
        let extra = table.rows[grid.n_em];
        return Err(Error::parse(
            path,
            extra.line,
            0,
            format!(
                "more emission rows than the grid line (line {}) announces: {} nm to {} nm in {} nm steps makes {} rows; remove the extra rows or fix the grid line",
                grid.line, grid.em_start, grid.em_end, grid.em_step, grid.n_em
            ),
        ));
    }
    if !table.terminated {
        return Err(truncated(
            last_line,
            &format!(
                "without the EOD line, after {rows_found} of the {} emission rows the grid line (line {}) announces",
                grid.n_em, grid.line
            ),
        ));
    }
    if rows_found < grid.n_em {
        return Err(Error::parse(
            path,
            lines[table.stopped_at + rc_index].number,
            0,
            format!(
                "EOD comes after {rows_found} emission rows, but the grid line (line {}) announces {} ({} nm to {} nm in {} nm steps); the file is truncated",
                grid.line, grid.n_em, grid.em_start, grid.em_end, grid.em_step
            ),
        ));
    }
    check_against_grid(
        path,
        &table.rows,
        grid.em_start,
        grid.em_step,
        "emission",
        grid.line,
    )?;

    let mut notes = Vec::new();
    if options.rows == Some(RowsAre::Excitation) {
        notes.push(
            "--rows excitation ignored: BFC-450 files always hold one row per emission wavelength"
                .to_string(),
        );
    }
    let (excitation_nm, emission_nm, values) = table.to_excitation_major(RowsAre::Emission);
    Ok(Parsed::surface(excitation_nm, emission_nm, values, notes))
}

/// Checks that wavelengths follow `start + k·step`, as the grid line says.
fn check_against_grid(
    path: &Path,
    found: &[Located],
    start: f64,
    step: f64,
    what: &str,
    grid_line: usize,
) -> Result<()> {
    for (k, at) in found.iter().enumerate() {
        let expected = start + step * k as f64;
        if !close(at.nm, expected, step) {
            return Err(Error::parse(
                path,
                at.line,
                at.column,
                format!(
                    "{what} wavelength {} nm does not match the grid line (line {grid_line}), which puts {} nm here ({start} nm + {k} × {step} nm); make them agree",
                    at.nm, expected
                ),
            ));
        }
    }
    Ok(())
}

/// The uniform step of a grid, or an error naming the grid.
fn uniform_step(grid: &[f64], what: &str) -> Result<f64> {
    if grid.len() < 2 {
        return Ok(1.0);
    }
    let step = (grid[grid.len() - 1] - grid[0]) / (grid.len() - 1) as f64;
    if let Some(k) = (0..grid.len()).find(|&k| !close(grid[k], grid[0] + step * k as f64, step)) {
        return Err(Error::invalid(
            what,
            format!(
                "is not uniform ({} nm at index {k}, a uniform grid would have {} nm); BFC-450 files need uniform grids, so write a wide CSV instead",
                grid[k],
                grid[0] + step * k as f64
            ),
        ));
    }
    Ok(step)
}

/// Writes `m` as a BFC-450 matrix file (CRLF, tab-separated, one row per emission
/// wavelength). Both grids must be uniform. Missing cells are written as `NaN`, which
/// fluorite reads back as missing. The units are not stored: values are written as
/// they are.
pub fn write_bfc(m: &Measurement) -> Result<String> {
    m.validate()?;
    let ex_step = uniform_step(&m.excitation_nm, &format!("{}: excitation_nm", m.name))?;
    let em_step = uniform_step(&m.emission_nm, &format!("{}: emission_nm", m.name))?;
    let name: String = m
        .name
        .chars()
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    let mut out = String::with_capacity(16 * (m.values.len() + 64));
    let mut line = |s: &str| {
        out.push_str(s);
        out.push_str("\r\n");
    };
    line("VEC_01\t5167");
    line(HEADER);
    line(&format!(";{name}"));
    line(&format!(
        ";written by fluorite {}",
        env!("CARGO_PKG_VERSION")
    ));
    for _ in 0..6 {
        line(";<none>");
    }
    let em = &m.emission_nm;
    line(
        &[
            em[0],
            em[em.len() - 1],
            em_step,
            m.n_excitation() as f64,
            m.excitation_nm[0],
            ex_step,
        ]
        .map(format_number)
        .join("\t"),
    );
    let mut rc = String::from("r:c:");
    for &l in &m.excitation_nm {
        rc.push('\t');
        rc.push_str(&format_number(l));
    }
    line(&rc);
    for (j, &l) in em.iter().enumerate() {
        let mut row = format_number(l);
        for i in 0..m.n_excitation() {
            row.push('\t');
            row.push_str(&format_number(m.get(i, j)));
        }
        line(&row);
    }
    line("EOD");
    Ok(out)
}
