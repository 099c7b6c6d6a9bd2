//! Blank subtraction and the absorbance-based inner-filter correction.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::measurement::Measurement;

/// Total absorbance (A_ex + A_em) above which the inner-filter correction is unreliable
/// (Kothawala et al. 2013 validate it up to about 1.5; dilute the sample beyond).
pub const MAX_RELIABLE_ABSORBANCE: f64 = 1.5;

/// An absorbance spectrum: absorbance per cm at increasing wavelengths.
#[derive(Debug, Clone, PartialEq)]
pub struct Absorbance {
    /// Wavelengths (nm), strictly increasing.
    pub wavelength_nm: Vec<f64>,
    /// Decadic absorbance per cm.
    pub absorbance: Vec<f64>,
}

/// Largest absorbance magnitude (per cm) the inner-filter correction accepts: real spectra
/// hold a few units, and beyond this the factor 10^(A/2) overflows the corrected cells to
/// infinity (a 42-digit absorbance did; found by tests/suite/fuzz.rs).
pub const MAX_ABSORBANCE: f64 = 100.0;

impl Absorbance {
    /// Reads a two-column text file (wavelength nm, absorbance per cm), separated by
    /// commas, semicolons, tabs or spaces; header lines before the numbers are skipped,
    /// and the rows may run in either direction.
    pub fn read(path: &Path) -> Result<Absorbance> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let mut rows: Vec<(f64, f64)> = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let cells: Vec<&str> = line
                .split([',', ';', '\t', ' '])
                .filter(|c| !c.trim().is_empty())
                .collect();
            let numbers: Vec<Option<f64>> = cells
                .iter()
                .map(|c| c.trim().trim_matches('"').parse::<f64>().ok())
                .collect();
            match numbers.as_slice() {
                [Some(l), Some(a), ..] if l.is_finite() && a.is_finite() => {
                    if let Err(message) = crate::limits::check_wavelength(*l) {
                        return Err(Error::parse(
                            path,
                            n + 1,
                            1,
                            format!("wavelength {message}"),
                        ));
                    }
                    rows.push((*l, *a));
                }
                _ if rows.is_empty() => continue, // a header
                _ => {
                    return Err(Error::parse(
                        path,
                        n + 1,
                        0,
                        format!(
                            "expected two numbers (wavelength nm, absorbance per cm), found {line:?}; an absorbance file holds one such pair per line"
                        ),
                    ));
                }
            }
        }
        if rows.len() < 2 {
            return Err(Error::parse(
                path,
                0,
                0,
                "holds fewer than two (wavelength, absorbance) lines; --absorbance needs an absorbance spectrum covering the excitation and emission wavelengths",
            ));
        }
        rows.sort_by(|a, b| a.0.total_cmp(&b.0));
        if let Some(w) = rows.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(Error::parse(
                path,
                0,
                0,
                format!(
                    "wavelength {} nm appears twice; keep one line per wavelength",
                    w[0].0
                ),
            ));
        }
        Ok(Absorbance {
            wavelength_nm: rows.iter().map(|r| r.0).collect(),
            absorbance: rows.iter().map(|r| r.1).collect(),
        })
    }

    /// Refuses a spectrum [`inner_filter`] cannot use: fewer than two wavelengths, not
    /// one absorbance per wavelength, wavelengths not positive and strictly increasing,
    /// or an absorbance that is not finite or beyond ±[`MAX_ABSORBANCE`]. `source` (the
    /// file) is named in errors.
    pub fn validate(&self, source: &Path) -> Result<()> {
        let parameter = format!("--absorbance {}", source.display());
        let (n, k) = (self.wavelength_nm.len(), self.absorbance.len());
        if n < 2 || n != k {
            return Err(Error::invalid(
                parameter,
                format!(
                    "holds {n} wavelengths and {k} absorbances; give one absorbance per wavelength, at two wavelengths or more covering the excitation and emission wavelengths"
                ),
            ));
        }
        crate::spectrum::check_grid(&self.wavelength_nm, &format!("{parameter}: wavelength_nm"))?;
        if let Some((l, a)) = self
            .wavelength_nm
            .iter()
            .zip(&self.absorbance)
            .find(|(_, a)| !(a.is_finite() && a.abs() <= MAX_ABSORBANCE))
        {
            return Err(Error::invalid(
                parameter,
                format!(
                    "absorbance at {l} nm is {a}; give a finite absorbance per cm within ±{MAX_ABSORBANCE} (the correction multiplies by 10^(A/2))"
                ),
            ));
        }
        Ok(())
    }

    /// Linear interpolation at `nm`; `None` outside the measured range and for a
    /// spectrum [`Absorbance::validate`] refuses for its size (empty, lengths differing).
    pub fn at(&self, nm: f64) -> Option<f64> {
        let (w, a) = (&self.wavelength_nm, &self.absorbance);
        if w.len() != a.len() {
            return None;
        }
        let (first, last) = span(w)?;
        if nm < first - 1e-9 || nm > last + 1e-9 {
            return None;
        }
        let k = w.partition_point(|&x| x < nm);
        if k == 0 {
            return Some(a[0]);
        }
        if k >= w.len() {
            return Some(a[w.len() - 1]);
        }
        let t = (nm - w[k - 1]) / (w[k] - w[k - 1]);
        Some(a[k - 1] + t * (a[k] - a[k - 1]))
    }
}

/// What the inner-filter correction did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InnerFilterReport {
    /// The absorbance file.
    pub source: String,
    /// Largest correction factor 10^((A_ex + A_em)/2) applied.
    pub max_factor: f64,
    /// Largest A_ex + A_em over the corrected cells.
    pub max_total_absorbance: f64,
}

/// What the blank subtraction did.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BlankReport {
    /// The blank file.
    pub source: String,
    /// Cells the blank was subtracted from.
    pub cells: usize,
    /// Sum of |blank| over those cells relative to the sample's sum of |value| there.
    pub signal_share: f64,
}

fn same_grid(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
}

/// The first and last wavelength of a grid; `None` when it is empty.
fn span(g: &[f64]) -> Option<(f64, f64)> {
    Some((*g.first()?, *g.last()?))
}

fn describe(g: &[f64]) -> String {
    match span(g) {
        Some((first, last)) => format!("{first}–{last} nm ({} wavelengths)", g.len()),
        None => "no wavelengths".to_string(),
    }
}

/// The excitation and emission spans of `m`; refuses a matrix without wavelengths or
/// whose values do not fill its grids (the corrections visit every cell).
fn spans(m: &Measurement) -> Result<((f64, f64), (f64, f64))> {
    let cells = m.excitation_nm.len() * m.emission_nm.len();
    match (span(&m.excitation_nm), span(&m.emission_nm)) {
        (Some(excitation), Some(emission)) if m.values.len() == cells => Ok((excitation, emission)),
        _ => Err(Error::invalid(
            format!("{}: values", m.name),
            format!(
                "holds {} cells for {} excitation × {} emission wavelengths; a correction needs a complete matrix",
                m.values.len(),
                m.excitation_nm.len(),
                m.emission_nm.len()
            ),
        )),
    }
}

/// Subtracts `blank` cell by cell. Grids must match; a cell the blank does not hold
/// keeps its value (counted as not subtracted in the report's cell count).
pub fn subtract_blank(
    m: &mut Measurement,
    blank: &Measurement,
    source: &Path,
) -> Result<BlankReport> {
    spans(m)?;
    spans(blank)?;
    if !same_grid(&m.excitation_nm, &blank.excitation_nm)
        || !same_grid(&m.emission_nm, &blank.emission_nm)
    {
        return Err(Error::invalid(
            "--blank",
            format!(
                "{}: its grid (excitation {}, emission {}) differs from the sample's (excitation {}, emission {}); use the blank measured with the same settings",
                source.display(),
                describe(&blank.excitation_nm),
                describe(&blank.emission_nm),
                describe(&m.excitation_nm),
                describe(&m.emission_nm)
            ),
        ));
    }
    let (mut cells, mut removed, mut total) = (0, 0.0, 0.0);
    for (v, b) in m.values.iter_mut().zip(&blank.values) {
        if v.is_finite() && b.is_finite() {
            total += v.abs();
            removed += b.abs();
            *v -= b;
            cells += 1;
        }
    }
    Ok(BlankReport {
        source: source.display().to_string(),
        cells,
        signal_share: if total > 0.0 { removed / total } else { 0.0 },
    })
}

/// The absorbance-based inner-filter correction for a 1 cm cuvette (Lakowicz; Kothawala
/// et al. 2013): F_corr = F_obs · 10^((A_ex + A_em)/2).
pub fn inner_filter(
    m: &mut Measurement,
    a: &Absorbance,
    source: &Path,
) -> Result<InnerFilterReport> {
    let ((ex_lo, ex_hi), (em_lo, em_hi)) = spans(m)?;
    a.validate(source)?;
    // Validated: two wavelengths or more (an empty span would fail the coverage test).
    let (lo, hi) = span(&a.wavelength_nm).unwrap_or((f64::INFINITY, f64::NEG_INFINITY));
    let need_lo = ex_lo.min(em_lo);
    let need_hi = ex_hi.max(em_hi);
    if lo > need_lo + 1e-9 || hi < need_hi - 1e-9 {
        return Err(Error::invalid(
            "--absorbance",
            format!(
                "{}: covers {lo}–{hi} nm, but the matrix needs {need_lo}–{need_hi} nm (excitation {ex_lo}–{ex_hi}, emission {em_lo}–{em_hi}); supply an absorbance spectrum over the whole range",
                source.display()
            ),
        ));
    }
    let a_ex: Vec<f64> = m
        .excitation_nm
        .iter()
        .map(|&l| a.at(l).unwrap_or(0.0))
        .collect();
    let a_em: Vec<f64> = m
        .emission_nm
        .iter()
        .map(|&l| a.at(l).unwrap_or(0.0))
        .collect();
    let (mut max_factor, mut max_total) = (1.0f64, 0.0f64);
    for (i, ae) in a_ex.iter().enumerate() {
        for (j, am) in a_em.iter().enumerate() {
            let v = m.get_mut(i, j);
            if v.is_finite() {
                let total = ae + am;
                let factor = 10f64.powf(0.5 * total);
                *v *= factor;
                max_factor = max_factor.max(factor);
                max_total = max_total.max(total);
            }
        }
    }
    Ok(InnerFilterReport {
        source: source.display().to_string(),
        max_factor,
        max_total_absorbance: max_total,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::Units;

    #[test]
    fn inner_filter_factor() {
        let mut m = Measurement::new(
            "t",
            vec![300.0],
            vec![300.0, 400.0],
            vec![1.0, 2.0],
            Units::PerBin,
        )
        .unwrap();
        let a = Absorbance {
            wavelength_nm: vec![300.0, 400.0],
            absorbance: vec![0.2, 0.0],
        };
        let r = inner_filter(&mut m, &a, Path::new("a.csv")).unwrap();
        // (0.2 + 0.2)/2 = 0.2 at 300/300; (0.2 + 0)/2 = 0.1 at 300/400.
        assert!((m.values[0] - 10f64.powf(0.2)).abs() < 1e-12);
        assert!((m.values[1] - 2.0 * 10f64.powf(0.1)).abs() < 1e-12);
        assert!((r.max_total_absorbance - 0.4).abs() < 1e-12);
        let short = Absorbance {
            wavelength_nm: vec![350.0, 400.0],
            absorbance: vec![0.2, 0.0],
        };
        let e = inner_filter(&mut m, &short, Path::new("a.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("--absorbance") && e.contains("300–400"), "{e}");
    }
}
