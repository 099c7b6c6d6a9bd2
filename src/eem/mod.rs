//! Raw instrument EEMs (excitation-emission matrices of solutions): telling them from
//! radiance-factor matrices, and cleaning them before a shapes fit.
//!
//! [`prepare`] runs the steps spectroscopists run in staRdom or drEEM, in their order:
//! 1. units ([`units`]): a matrix whose values cannot be radiance factors is an
//!    uncalibrated EEM; its λo = λi line is Rayleigh scatter, not a diagonal, and the fit
//!    gives absorption and emission shapes and a scale only;
//! 2. zeros read as missing (instruments write 0 where nothing was recorded);
//! 3. blank subtraction ([`correct::subtract_blank`]);
//! 4. inner-filter correction from an absorbance spectrum ([`correct::inner_filter`]);
//! 5. masking first- and second-order Rayleigh and water-Raman scatter ([`scatter`]).
//!
//! Sets of prepared EEMs are fitted jointly by [`crate::fit::joint`] (non-negative
//! PARAFAC, judged by core consistency and split-half).
//!
//! A radiance-factor matrix passes through untouched, so surface fits are unchanged; one
//! written ×100 (percent, [`units::classify_percent`]) is divided by 100 with a note and
//! then passes through. A forced `--units radiance-factor` on percent values, or
//! `--units percent` on values that are not percent, is an error naming the likely unit.
//! Every step is recorded in a [`Preprocessing`] report (the fit report's
//! `preprocessing` block) and as notes on the measurement.

pub mod correct;
pub mod scatter;
pub mod units;

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::measurement::Measurement;
use correct::{Absorbance, BlankReport, InnerFilterReport};
use scatter::{MaskedBand, ScatterLine, ScatterOptions};
pub use units::UnitsChoice;

/// How to prepare a matrix; the default infers everything and masks scatter.
#[derive(Debug, Clone, Default)]
pub struct EemOptions {
    /// Units, or `Auto` to infer them.
    pub units: UnitsChoice,
    /// Treat zeros as missing in an EEM (default: yes); `Some(false)` keeps them.
    pub zero_is_missing: Option<bool>,
    /// A blank (e.g. Milli-Q water) measured with the same settings, and its file.
    pub blank: Option<(Measurement, PathBuf)>,
    /// An absorbance spectrum of the sample (per cm), and its file.
    pub absorbance: Option<(Absorbance, PathBuf)>,
    /// Do not mask scatter.
    pub keep_scatter: bool,
    /// Scatter band widths, instrument bandwidth and Raman shift.
    pub scatter: ScatterOptions,
}

impl EemOptions {
    /// Refuses options [`prepare`] cannot use: a scatter half-width that is not a width in
    /// nm (≥ 0), a bandwidth or Raman shift that is not positive, a blank that is no
    /// matrix and an absorbance spectrum that is no spectrum. Errors name the
    /// `fluorite fit` flag.
    pub fn validate(&self) -> Result<()> {
        let scatter = &self.scatter;
        for (line, width) in ScatterLine::ALL.iter().zip(&scatter.half_width_nm) {
            if let Some(w) = width.filter(|w| !(w.is_finite() && *w >= 0.0)) {
                return Err(Error::invalid(
                    format!("--scatter-width \"{}={w}\"", line.name()),
                    format!("\"{w}\" is not a width in nm (a number ≥ 0)"),
                ));
            }
        }
        for (value, flag, fix) in [
            (
                scatter.bandwidth_nm,
                "--bandwidth",
                "must be a positive width in nm (e.g. 5 for 5 nm slits)",
            ),
            (
                scatter.raman_shift_cm,
                "--raman-shift",
                "must be a positive wavenumber in cm⁻¹ (water: 3400)",
            ),
        ] {
            if let Some(v) = value.filter(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(Error::invalid(format!("{flag} {v}"), fix));
            }
        }
        if let Some((blank, path)) = &self.blank {
            blank.validate().map_err(|e| {
                Error::invalid(format!("--blank {}", path.display()), e.to_string())
            })?;
        }
        if let Some((absorbance, path)) = &self.absorbance {
            absorbance.validate(path)?;
        }
        Ok(())
    }
}

/// What [`prepare`] did to a matrix (written into the fit report).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
pub struct Preprocessing {
    /// `radiance-factor` or `arbitrary`.
    pub units: String,
    /// Whether the units were inferred (false: set with `--units`).
    pub units_inferred: bool,
    /// Why, in words.
    pub units_reason: String,
    /// Cells holding 0 read as missing.
    #[serde(default)]
    pub zeros_missing: usize,
    /// Blank subtraction, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub blank: Option<BlankReport>,
    /// Inner-filter correction, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inner_filter: Option<InnerFilterReport>,
    /// Masked scatter bands (empty when scatter was kept).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub scatter: Vec<MaskedBand>,
    /// The Raman shift (cm⁻¹) that placed the Raman bands; absent: water's
    /// [`scatter::WATER_RAMAN_SHIFT_CM`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raman_shift_cm: Option<f64>,
}

impl Preprocessing {
    /// Whether the cell at excitation `ex_nm`, emission `em_nm` lies in a masked scatter
    /// band (plots draw such cells as masked, not as unrecorded).
    pub fn masks(&self, ex_nm: f64, em_nm: f64) -> bool {
        let shift = self.raman_shift_cm.unwrap_or(scatter::WATER_RAMAN_SHIFT_CM);
        self.scatter
            .iter()
            .any(|band| band.contains(ex_nm, em_nm, shift))
    }

    /// One line per step, for the command line.
    pub fn lines(&self) -> Vec<String> {
        let mut out = vec![format!(
            "units: {} ({}): {}",
            self.units,
            if self.units_inferred {
                "inferred; --units radiance-factor|percent|arbitrary overrides"
            } else {
                "set with --units"
            },
            self.units_reason
        )];
        if self.zeros_missing > 0 {
            out.push(format!(
                "{} cells holding 0 read as not recorded (missing); --zero-is-missing false keeps them",
                self.zeros_missing
            ));
        }
        if let Some(b) = &self.blank {
            out.push(format!(
                "blank {} subtracted from {} cells (it held {:.1} % of their signal)",
                b.source,
                b.cells,
                100.0 * b.signal_share
            ));
        }
        if let Some(f) = &self.inner_filter {
            out.push(format!(
                "inner-filter correction from {} (1 cm, F·10^((A_ex+A_em)/2)): factors up to {:.3} (A_ex + A_em up to {:.3})",
                f.source, f.max_factor, f.max_total_absorbance
            ));
        }
        if !self.scatter.is_empty() {
            let bands: Vec<String> = self
                .scatter
                .iter()
                .map(|b| {
                    format!(
                        "{} −{:.1}/+{:.1} nm ({}{}; {} cells, {:.1} % of the signal)",
                        b.line.name(),
                        b.below_nm,
                        b.above_nm,
                        match b.source {
                            scatter::WidthSource::Option => "set".to_string(),
                            scatter::WidthSource::Measured =>
                                format!("measured in {} rows", b.rows_measured),
                            scatter::WidthSource::Bandwidth => "from --bandwidth".to_string(),
                            scatter::WidthSource::Default => "default".to_string(),
                            scatter::WidthSource::Bounded => format!(
                                "measured in {} rows, held to the line's physics bounds from rayleigh1",
                                b.rows_measured
                            ),
                        },
                        "",
                        b.cells,
                        100.0 * b.signal_share
                    )
                })
                .collect();
            out.push(format!(
                "scatter masked: {} (--scatter-width LINE=NM or --bandwidth NM set the bands, --keep-scatter keeps them)",
                bands.join("; ")
            ));
        }
        out
    }
}

/// Divides `m`'s values by 100 and says so in a note.
fn read_percent(m: &mut Measurement, verdict: &units::PercentVerdict, inferred: bool) {
    m.values.iter_mut().for_each(|v| *v /= units::PERCENT);
    m.notes.push(format!(
        "values read as percent radiance factors and divided by 100 ({}): {}; {}",
        if inferred {
            "inferred"
        } else {
            "set with --units percent"
        },
        verdict.reason,
        if inferred {
            "--units arbitrary fits shapes only"
        } else {
            "--units auto infers the units"
        }
    ));
}

/// Decides the units of `m` and, for an uncalibrated EEM, cleans it (see the module
/// doc). Returns the matrix to fit and, unless it is a radiance-factor matrix left
/// untouched, what was done (also appended to the matrix's notes). The options
/// ([`EemOptions::validate`]) and the matrix ([`Measurement::validate`]) are checked
/// first.
pub fn prepare(
    mut m: Measurement,
    options: &EemOptions,
) -> Result<(Measurement, Option<Preprocessing>)> {
    options.validate()?;
    m.validate()?;
    let mut verdict = units::classify(&m);
    let percent = units::classify_percent(&m, &verdict);
    match options.units {
        UnitsChoice::Percent if !percent.bounds_fit => {
            return Err(Error::invalid(
                "--units percent",
                format!(
                    "{}: {}; {}",
                    m.name,
                    percent.reason,
                    if verdict.radiance_factor {
                        "drop --units percent (or pass --units radiance-factor)"
                    } else {
                        "if it is an uncalibrated EEM in counts, pass --units arbitrary"
                    }
                ),
            ));
        }
        UnitsChoice::RadianceFactor if percent.percent => {
            return Err(Error::invalid(
                "--units radiance-factor",
                format!(
                    "{}: {}; as they stand they cannot be radiance factors (no cell may exceed {}); pass --units percent (or --units auto) to read them ÷ 100",
                    m.name,
                    percent.reason,
                    units::MAX_RADIANCE_FACTOR_CELL
                ),
            ));
        }
        _ => {}
    }
    let inferred_percent = options.units == UnitsChoice::Auto && percent.percent;
    if options.units == UnitsChoice::Percent || inferred_percent {
        read_percent(&mut m, &percent, inferred_percent);
        verdict = units::classify(&m);
    }
    let arbitrary = match options.units {
        UnitsChoice::Auto => !verdict.radiance_factor || m.arbitrary_scale,
        UnitsChoice::RadianceFactor | UnitsChoice::Percent => false,
        UnitsChoice::Arbitrary => true,
    };
    let wants_eem_steps = options.blank.is_some() || options.absorbance.is_some();
    if !arbitrary {
        // A forced unit the data contradict would fit an unphysical material: refuse it
        // and name the unit the data look like.
        if options.units == UnitsChoice::RadianceFactor && !verdict.radiance_factor {
            return Err(Error::invalid(
                "--units radiance-factor",
                format!(
                    "{}: the values cannot be radiance factors (largest cell {:.4e}, largest excitation-row sum {:.4e} at {} nm; bounds {} and {}); they look like an uncalibrated EEM: pass --units arbitrary (shapes and a scale), or drop --units to let fluorite infer them",
                    m.name,
                    verdict.max_cell,
                    verdict.max_row_sum,
                    verdict.max_row_nm,
                    units::MAX_RADIANCE_FACTOR_CELL,
                    units::MAX_RADIANCE_FACTOR_ROW
                ),
            ));
        }
        if wants_eem_steps {
            return Err(Error::invalid(
                if options.blank.is_some() {
                    "--blank"
                } else {
                    "--absorbance"
                },
                format!(
                    "{}: blank subtraction and inner-filter correction are for uncalibrated EEMs of solutions, but this matrix is a radiance-factor matrix ({}); drop the option, or pass --units arbitrary if it is an EEM",
                    m.name, verdict.reason
                ),
            ));
        }
        return Ok((m, None));
    }
    let mut report = Preprocessing {
        units: "arbitrary".into(),
        units_inferred: options.units == UnitsChoice::Auto,
        units_reason: match options.units {
            UnitsChoice::Auto if m.arbitrary_scale && verdict.radiance_factor => {
                "the file's format holds counts (arbitrary scale)".into()
            }
            // A dark or odd surface in percent: say how to read it so.
            UnitsChoice::Auto if percent.bounds_fit => format!(
                "{}; {}; pass --units percent if they are radiance factors ×100",
                verdict.reason, percent.reason
            ),
            UnitsChoice::Auto => verdict.reason.clone(),
            _ => "treated as an uncalibrated EEM: the λo = λi line is scatter, not a reflectance"
                .into(),
        },
        ..Preprocessing::default()
    };
    m.has_diagonal = false;
    m.arbitrary_scale = true;
    if options.zero_is_missing != Some(false) {
        for v in m.values.iter_mut().filter(|v| **v == 0.0) {
            *v = f64::NAN;
            report.zeros_missing += 1;
        }
    }
    // Scatter widths are measured on the sample as recorded: a blank holds the same
    // scatter, so after subtracting it there would be little left to measure.
    let mut bands = (!options.keep_scatter).then(|| scatter::plan(&m, &options.scatter));
    if let Some((blank, path)) = &options.blank {
        let mut blank = blank.clone();
        if options.zero_is_missing != Some(false) {
            for v in blank.values.iter_mut().filter(|v| **v == 0.0) {
                *v = f64::NAN;
            }
        }
        report.blank = Some(correct::subtract_blank(&mut m, &blank, path)?);
    }
    if let Some((a, path)) = &options.absorbance {
        report.inner_filter = Some(correct::inner_filter(&mut m, a, path)?);
    }
    if let Some(bands) = bands.as_mut() {
        scatter::apply(&mut m, bands, options.scatter.raman_shift_cm);
        report.scatter = std::mem::take(bands);
        report.raman_shift_cm = options.scatter.raman_shift_cm;
    }
    if m.values.iter().all(|v| v.is_nan()) {
        return Err(Error::invalid(
            "--scatter-width",
            format!(
                "{}: masking scatter left no measured cell; narrow the bands (--scatter-width LINE=NM) or pass --keep-scatter",
                m.name
            ),
        ));
    }
    if let Some(f) = report
        .inner_filter
        .as_ref()
        .filter(|f| f.max_total_absorbance > correct::MAX_RELIABLE_ABSORBANCE)
    {
        m.notes.push(format!(
            "A_ex + A_em reaches {:.2} (> {}): the inner-filter correction is unreliable there; dilute the sample",
            f.max_total_absorbance,
            correct::MAX_RELIABLE_ABSORBANCE
        ));
    }
    m.notes.extend(report.lines());
    Ok((m, Some(report)))
}
