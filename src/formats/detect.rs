//! Telling the format of a file: by its content first, its extension as a hint.

use std::path::Path;

use super::text::{Delimiter, Line, Number, parse_number, split_cells};
use super::{Format, bfc, long};

/// How many leading lines may come before the BFC-450 header line.
const BFC_HEADER_WITHIN: usize = 20;

/// The format the content shows, or the one the extension suggests, or `None`.
pub(super) fn detect(path: &Path, bytes: &[u8], lines: &[Line]) -> Option<Format> {
    // Binary data is no matrix, whatever the extension says.
    if bytes.iter().take(4096).any(|&b| b == 0) {
        return None;
    }
    if lines.iter().take(BFC_HEADER_WITHIN).any(bfc::is_header) {
        return Some(Format::Bfc);
    }
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    // A damaged BFC file is best explained by the BFC reader.
    if extension.as_deref() == Some("bfc") {
        return Some(Format::Bfc);
    }
    if let Some(format) = from_first_line(lines) {
        return Some(format);
    }
    match extension.as_deref() {
        Some("csv" | "tsv") => Some(Format::Wide),
        _ => None,
    }
}

fn from_first_line(lines: &[Line]) -> Option<Format> {
    let first = lines
        .iter()
        .find(|l| !l.is_blank() && !l.text.trim_start().starts_with('#'))?;
    if long::looks_like_header(first.text) {
        return Some(Format::Long);
    }
    match Delimiter::detect(first.text) {
        Delimiter::Char(_) => Some(Format::Wide),
        Delimiter::Whitespace => {
            let cells = split_cells(first.text, Delimiter::Whitespace);
            let numeric = |c: &str| matches!(parse_number(c, false), Number::Finite(_));
            match cells.first() {
                // Starts with a wavelength: WebFluor (its reader judges the rest).
                Some(c) if numeric(c) => Some(Format::Webfluor),
                // A corner label, then wavelengths: a space-separated wide matrix.
                Some(_) if cells.len() >= 2 && numeric(&cells[1]) => Some(Format::Wide),
                _ => None,
            }
        }
    }
}
