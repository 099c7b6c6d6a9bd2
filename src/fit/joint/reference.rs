//! Known concentrations of a sample set, and how well a joint fit's scores follow them:
//! the check drEEM and staRdom users run on a calibration set (per analyte, the component
//! whose scores correlate best, and that correlation's R²).

use std::path::Path;

use super::JointFit;
use super::diagnostics::r_squared;
use crate::error::{Error, Result};

/// Known concentrations: analyte names and, per sample, one value per analyte.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// The analytes, in the file's column order.
    pub analytes: Vec<String>,
    /// Per sample: its name (matched to a fit's sample names without regard to case) and
    /// one concentration per analyte.
    pub samples: Vec<(String, Vec<f64>)>,
}

/// The component that follows one analyte best.
#[derive(Debug, Clone, PartialEq)]
pub struct AnalyteMatch {
    /// The analyte.
    pub analyte: String,
    /// The best-correlated component, 1-based; 0 when no component correlates (too few
    /// shared samples, or constant scores or concentrations).
    pub component: usize,
    /// Squared Pearson correlation of that component's scores with the concentrations
    /// (NaN when `component` is 0).
    pub r_squared: f64,
    /// Samples present in both the fit and the reference.
    pub samples: usize,
}

impl Reference {
    /// Reads a reference CSV: a header `sample,<analyte>,<analyte>…`, then one line per
    /// sample, its name and one number per analyte. Blank lines are skipped.
    pub fn read(path: &Path) -> Result<Reference> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Reference::parse(path, &text)
    }

    /// [`Reference::read`] on text already read from `path`.
    pub fn parse(path: &Path, text: &str) -> Result<Reference> {
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let Some((_, header)) = lines.next() else {
            return Err(Error::parse(
                path,
                0,
                0,
                "is empty; give a header `sample,<analyte>,…` and one line per sample",
            ));
        };
        let analytes: Vec<String> = header.split(',').skip(1).map(|s| s.trim().into()).collect();
        if analytes.is_empty() {
            return Err(Error::parse(
                path,
                1,
                0,
                "names no analyte; the header is `sample,<analyte>,…`",
            ));
        }
        let mut samples = Vec::new();
        for (index, line) in lines {
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            if cells.len() != analytes.len() + 1 {
                return Err(Error::parse(
                    path,
                    index + 1,
                    0,
                    format!(
                        "has {} values for {} analytes; give a sample name and one number per analyte of the header",
                        cells.len() - 1,
                        analytes.len()
                    ),
                ));
            }
            let mut values = Vec::with_capacity(analytes.len());
            for (column, cell) in cells.iter().enumerate().skip(1) {
                match cell.parse::<f64>() {
                    Ok(v) if v.is_finite() => values.push(v),
                    _ => {
                        return Err(Error::parse(
                            path,
                            index + 1,
                            column + 1,
                            format!(
                                "\"{cell}\" is not a finite number (a concentration of {})",
                                analytes[column - 1]
                            ),
                        ));
                    }
                }
            }
            samples.push((cells[0].to_string(), values));
        }
        Ok(Reference { analytes, samples })
    }

    /// Per analyte, the component of `fit` whose scores correlate best with the known
    /// concentrations, over the samples present in both.
    pub fn best_matches(&self, fit: &JointFit) -> Vec<AnalyteMatch> {
        // (index in the fit, concentrations) of every shared sample.
        let shared: Vec<(usize, &Vec<f64>)> = fit
            .samples
            .iter()
            .enumerate()
            .filter_map(|(s, name)| {
                self.samples
                    .iter()
                    .find(|(n, _)| n.eq_ignore_ascii_case(name))
                    .map(|(_, v)| (s, v))
            })
            .collect();
        self.analytes
            .iter()
            .enumerate()
            .map(|(a, analyte)| {
                let truth: Vec<f64> = shared.iter().map(|(_, v)| v[a]).collect();
                let (component, r_squared) = (0..fit.components.len())
                    .map(|c| {
                        let scores: Vec<f64> =
                            shared.iter().map(|(s, _)| fit.scores[*s][c]).collect();
                        (c + 1, r_squared(&scores, &truth))
                    })
                    .filter(|(_, r2)| r2.is_finite())
                    .max_by(|x, y| x.1.total_cmp(&y.1))
                    .unwrap_or((0, f64::NAN));
                AnalyteMatch {
                    analyte: analyte.clone(),
                    component,
                    r_squared,
                    samples: shared.len(),
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path() -> &'static Path {
        Path::new("concentrations.csv")
    }

    #[test]
    fn reads_a_reference_and_names_the_bad_cell() {
        let r = Reference::parse(path(), "sample,trp,phe\n\nA, 1.0, 2\nb,0,3.5\n").unwrap();
        assert_eq!(r.analytes, ["trp", "phe"]);
        assert_eq!(
            r.samples,
            [
                ("A".to_string(), vec![1.0, 2.0]),
                ("b".to_string(), vec![0.0, 3.5])
            ]
        );
        let e = Reference::parse(path(), "sample,trp,phe\nA,1,x\n").unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("concentrations.csv:2:3") && text.contains("phe"),
            "{text}"
        );
        let e = Reference::parse(path(), "sample,trp,phe\nA,1\n").unwrap_err();
        assert!(e.to_string().contains(":2"), "{e}");
        assert!(Reference::parse(path(), "\n\n").is_err());
        assert!(Reference::parse(path(), "sample\nA\n").is_err());
    }
}
