//! Reading a sample: the file's matrix, prepared as an instrument EEM (units, blank, inner
//! filter, scatter) when it is one.

use std::path::{Path, PathBuf};

use crate::eem::correct::Absorbance;
use crate::eem::scatter::{ScatterLine, ScatterOptions, WATER_RAMAN_SHIFT_CM};
use crate::eem::{EemOptions, Preprocessing, UnitsChoice, prepare};
use crate::error::{Error, Result};
use crate::formats::{ReadOptions, read};
use crate::measurement::Measurement;

/// How raw instrument EEMs are prepared: the options of `fit` for them, with the blank and
/// absorbance files still as paths (one for all inputs or one per input).
#[derive(Debug, Clone, PartialEq)]
pub struct EemSettings {
    /// Units of the values (`--units`).
    pub units: UnitsChoice,
    /// Blank files (`--blank`): none, one for all inputs, or one per input in order.
    pub blank: Vec<PathBuf>,
    /// Absorbance spectra (`--absorbance`): none, or one per input in order.
    pub absorbance: Vec<PathBuf>,
    /// Keep Rayleigh and Raman scatter instead of masking it (`--keep-scatter`).
    pub keep_scatter: bool,
    /// Half-width (nm) per scatter line in [`ScatterLine::ALL`] order (`--scatter-width`);
    /// `None`: measured on the data.
    pub scatter_half_width_nm: [Option<f64>; 4],
    /// The instrument's spectral bandwidth in nm (`--bandwidth`).
    pub bandwidth_nm: Option<f64>,
    /// Raman shift of the solvent in cm⁻¹ (`--raman-shift`).
    pub raman_shift_cm: f64,
}

impl Default for EemSettings {
    fn default() -> Self {
        EemSettings {
            units: UnitsChoice::Auto,
            blank: Vec::new(),
            absorbance: Vec::new(),
            keep_scatter: false,
            scatter_half_width_nm: [None; 4],
            bandwidth_nm: None,
            raman_shift_cm: WATER_RAMAN_SHIFT_CM,
        }
    }
}

impl EemSettings {
    /// Sets the half-width of scatter line `line` (rayleigh1, raman1, rayleigh2, raman2,
    /// or all of them with `all`) to `nm`; the width itself is checked when the options are
    /// used.
    pub fn set_scatter_width(&mut self, line: &str, nm: f64) -> Result<()> {
        self.set_width(line, nm)
            .map_err(|message| Error::invalid("--scatter-width", message))
    }

    /// Sets a scatter width written `LINE=NM` (the command line's form).
    pub fn parse_scatter_width(&mut self, item: &str) -> Result<()> {
        let invalid =
            |message: String| Error::invalid(format!("--scatter-width {item:?}"), message);
        let (line, nm) = item
            .split_once('=')
            .ok_or_else(|| invalid("expected LINE=NM, e.g. rayleigh2=12 or all=10".into()))?;
        // EemOptions::validate checks the width; a word is not one.
        let nm: f64 = nm
            .trim()
            .parse()
            .map_err(|_| invalid(format!("{nm:?} is not a width in nm (a number ≥ 0)")))?;
        self.set_width(line, nm).map_err(invalid)
    }

    fn set_width(&mut self, line: &str, nm: f64) -> std::result::Result<(), String> {
        let line = line.trim().to_ascii_lowercase();
        let mut matched = false;
        for (k, l) in ScatterLine::ALL.iter().enumerate() {
            if line == "all" || line == l.name() {
                self.scatter_half_width_nm[k] = Some(nm);
                matched = true;
            }
        }
        if matched {
            Ok(())
        } else {
            Err(format!(
                "unknown line {line:?}; use rayleigh1, raman1, rayleigh2, raman2 or all"
            ))
        }
    }

    /// The preparation of input number `index` of `count`: picks its blank and absorbance
    /// files and reads them (the blank with `read`).
    pub fn options_for(
        &self,
        index: usize,
        count: usize,
        read: &ReadOptions,
    ) -> Result<EemOptions> {
        let blank = match pick(&self.blank, "blank", true, index, count)? {
            Some(path) => {
                let m = crate::formats::read(&path, read)
                    .map_err(|e| e.context(format!("--blank {}", path.display())))?;
                Some((m, path))
            }
            None => None,
        };
        let absorbance = match pick(&self.absorbance, "absorbance", false, index, count)? {
            Some(path) => Some((
                Absorbance::read(&path)
                    .map_err(|e| e.context(format!("--absorbance {}", path.display())))?,
                path,
            )),
            None => None,
        };
        Ok(EemOptions {
            units: self.units,
            zero_is_missing: read.zero_is_missing,
            blank,
            absorbance,
            keep_scatter: self.keep_scatter,
            scatter: ScatterOptions {
                half_width_nm: self.scatter_half_width_nm,
                bandwidth_nm: self.bandwidth_nm,
                raman_shift_cm: Some(self.raman_shift_cm),
            },
        })
    }
}

/// The file of `files` that applies to input `index` of `count`: none, the one given (when
/// `shared`, or for a single input), or the input's own.
fn pick(
    files: &[PathBuf],
    what: &str,
    shared: bool,
    index: usize,
    count: usize,
) -> Result<Option<PathBuf>> {
    match files.len() {
        0 => Ok(None),
        1 if shared || count == 1 => Ok(Some(files[0].clone())),
        n if n == count => Ok(files.get(index).cloned()),
        n => Err(Error::invalid(
            format!("--{what}"),
            format!(
                "{n} files for {count} inputs; give {}one per input, in the inputs' order",
                if shared { "one for all inputs or " } else { "" }
            ),
        )),
    }
}

/// How to read and prepare samples.
#[derive(Debug, Clone, Default)]
pub struct InputOptions {
    /// How the files are read (format, orientation, zeros, per nm).
    pub read: ReadOptions,
    /// How raw instrument EEMs are prepared.
    pub eem: EemSettings,
}

/// A sample ready to fit: its matrix and, for an instrument EEM, what preparing it did.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The matrix, prepared.
    pub measurement: Measurement,
    /// What was done to an instrument EEM (units, blank, inner filter, scatter masked);
    /// `None` for a radiance-factor surface matrix.
    pub preprocessing: Option<Preprocessing>,
}

impl Prepared {
    /// Prepares a matrix held in memory (no blank or absorbance files are read unless the
    /// settings name them).
    pub fn from_measurement(m: Measurement, input: &InputOptions) -> Result<Prepared> {
        let options = input.eem.options_for(0, 1, &input.read)?;
        let (measurement, preprocessing) = prepare(m, &options)?;
        Ok(Prepared {
            measurement,
            preprocessing,
        })
    }

    /// Whether this is an uncalibrated instrument EEM (fitted for shapes and a scale).
    pub fn is_eem(&self) -> bool {
        self.preprocessing.is_some()
    }
}

/// Reads input number `index` of `count` (which blank and absorbance apply) and prepares it.
pub fn read_input(
    path: &Path,
    index: usize,
    count: usize,
    options: &InputOptions,
) -> Result<Prepared> {
    let eem = options.eem.options_for(index, count, &options.read)?;
    let m = read(path, &options.read)?;
    let (measurement, preprocessing) = prepare(m, &eem)?;
    Ok(Prepared {
        measurement,
        preprocessing,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scatter_widths_are_set_per_line_or_all_and_bad_items_name_the_flag() {
        let mut s = EemSettings::default();
        s.parse_scatter_width("rayleigh2=12").unwrap();
        assert_eq!(s.scatter_half_width_nm, [None, None, Some(12.0), None]);
        s.set_scatter_width("ALL", 7.5).unwrap();
        assert_eq!(s.scatter_half_width_nm, [Some(7.5); 4]);
        for (item, expected) in [
            (
                "rayleigh2",
                "--scatter-width \"rayleigh2\": expected LINE=NM",
            ),
            (
                "raman1=wide",
                "--scatter-width \"raman1=wide\": \"wide\" is not a width",
            ),
            ("mie=3", "--scatter-width \"mie=3\": unknown line \"mie\""),
        ] {
            let message = s.parse_scatter_width(item).unwrap_err().to_string();
            assert!(message.starts_with(expected), "{item}: {message}");
        }
    }

    #[test]
    fn blank_and_absorbance_files_are_picked_per_input() {
        let mut s = EemSettings {
            blank: vec!["b.csv".into()],
            ..EemSettings::default()
        };
        assert_eq!(
            pick(&s.blank, "blank", true, 2, 3).unwrap(),
            Some("b.csv".into())
        );
        assert!(pick(&s.blank, "absorbance", false, 2, 3).is_err());
        s.absorbance = vec!["a1".into(), "a2".into(), "a3".into()];
        assert_eq!(
            pick(&s.absorbance, "absorbance", false, 1, 3).unwrap(),
            Some("a2".into())
        );
        let message = pick(&s.absorbance, "absorbance", false, 0, 2)
            .unwrap_err()
            .to_string();
        assert_eq!(
            message,
            "--absorbance: 3 files for 2 inputs; give one per input, in the inputs' order"
        );
    }
}
