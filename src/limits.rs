//! The ranges the physics allows for every quantity a file or an option sets, and the
//! bounds on work that grows with an input.
//!
//! A typo in a file (`1e12` for `420`) must end in an error that names the place and the
//! range, not in a fine grid of 10¹² samples. Readers check each wavelength where they read
//! it ([`check_wavelength`], so the error names the file, line and column); the types
//! check again when they are built ([`crate::spectrum::check_grid`], the material's
//! validation), so a value built in code or read from JSON meets the same ranges. Work that
//! grows with an input (fine tabulation grids, integration sub-steps, the renderer's
//! paths) is bounded by these constants, never by the number in the file.

use std::ops::RangeInclusive;

/// Wavelengths fluorite reads, in nm: from the vacuum ultraviolet (100 nm, below which no
/// spectrofluorimeter or bispectral camera measures in air) to the far infrared (100 µm).
/// Every instrument, dye spectrum and light of the field lies well inside.
pub const WAVELENGTH_NM: RangeInclusive<f64> = 100.0..=100_000.0;

/// Most wavelengths on one axis of a matrix or in one spectrum: a 0.1 nm grid over the
/// whole 200–1200 nm range of a spectrofluorimeter is 10,001 samples.
pub const MAX_GRID_POINTS: usize = 20_000;

/// Most cells of one matrix (excitation × emission): a 1 nm × 1 nm EEM over 200–800 nm
/// holds 361,201; bispectral cameras hold a few thousand. Sixteen million is 128 MiB of
/// values, the most a fit holds in memory at once.
pub const MAX_CELLS: usize = 1 << 24;

/// Most samples of one image read whole (pixels × channels): 512 MiB as 32-bit floats.
pub const MAX_IMAGE_SAMPLES: u64 = 1 << 27;

/// Most iterations a solver may be asked for (`--max-iterations`): far beyond what any
/// fit here needs (hundreds), small enough that a run ends.
pub const MAX_ITERATIONS: u64 = 1_000_000;

/// Most samples a tabulation built from an input's wavelength range may hold: the fine
/// grid of a parametric material, a spectral export's 1 nm grid. A range wider than this
/// many nm is tabulated on a coarser step (see [`tabulation_step_nm`]).
pub const MAX_TABULATION_SAMPLES: usize = 8_192;

/// Most camera paths of one render (width × height × samples per pixel): a 4K image at
/// 1,024 samples per pixel is 8.5 × 10⁹.
pub const MAX_RENDER_PATHS: u64 = 10_000_000_000;

/// Most repetitions a count option may ask for (`--timing-runs`, `--repeats`, `--seeds`,
/// `class --cases`): each repeats a fit or a sweep, so this many is already a day's work.
pub const MAX_RUNS: usize = 100_000;

/// Most threads a parallel batch (`fit_many`) is given: far more than any machine's cores,
/// few enough that asking for them cannot exhaust the system's threads.
pub const MAX_THREADS: usize = 1024;

/// Checks a count option (`flag`) against 1..=[`MAX_RUNS`].
pub fn check_runs(value: usize, flag: &str) -> crate::Result<()> {
    if value == 0 || value > MAX_RUNS {
        return Err(crate::Error::invalid(
            flag,
            format!("is {value}; give a count from 1 to {MAX_RUNS}"),
        ));
    }
    Ok(())
}

/// Checks that `nm` is a wavelength fluorite reads. The error message names the value and
/// the range and asks for the typo to be fixed; the caller adds where it was read.
pub fn check_wavelength(nm: f64) -> Result<(), String> {
    if WAVELENGTH_NM.contains(&nm) {
        Ok(())
    } else {
        Err(format!(
            "{} nm is outside {}, the wavelengths fluorite reads (vacuum ultraviolet to far infrared); check the number for a typo or a unit other than nm",
            crate::limits::display_nm(nm),
            range_text()
        ))
    }
}

/// The wavelength range as a user reads it: `100–100,000 nm`.
pub fn range_text() -> String {
    format!(
        "{}–{} nm",
        group_thousands(*WAVELENGTH_NM.start()),
        group_thousands(*WAVELENGTH_NM.end())
    )
}

/// A wavelength for a message: plain for ordinary numbers, scientific for huge or tiny ones
/// (so a 42-digit typo does not fill the line).
pub fn display_nm(nm: f64) -> String {
    if nm.is_finite() && (nm == 0.0 || (1e-3..1e9).contains(&nm.abs())) {
        format!("{nm}")
    } else {
        format!("{nm:e}")
    }
}

/// The step (nm) of a tabulation over `span_nm` that wants `preferred_step_nm`: the
/// preferred step, or the step that keeps the tabulation within
/// [`MAX_TABULATION_SAMPLES`] when the span is wider.
pub fn tabulation_step_nm(span_nm: f64, preferred_step_nm: f64) -> f64 {
    let bound = span_nm / (MAX_TABULATION_SAMPLES - 1) as f64;
    if bound.is_finite() && bound > preferred_step_nm {
        bound
    } else {
        preferred_step_nm
    }
}

fn group_thousands(v: f64) -> String {
    let digits = format!("{}", v.round() as u64);
    let mut out = String::new();
    for (k, c) in digits.chars().enumerate() {
        if k > 0 && (digits.len() - k) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wavelengths_inside_the_range_pass_and_typos_name_the_range() {
        for nm in [100.0, 250.0, 780.0, 2500.0, 100_000.0] {
            assert!(check_wavelength(nm).is_ok(), "{nm}");
        }
        for nm in [99.9, 0.0, -5.0, 1e12, 1e300, 100_000.5] {
            let message = check_wavelength(nm).unwrap_err();
            assert!(message.contains("100–100,000 nm"), "{message}");
        }
        assert!(check_wavelength(1e12).unwrap_err().starts_with("1e12 nm"));
        assert!(check_wavelength(f64::NAN).is_err());
    }

    #[test]
    fn tabulation_step_keeps_the_preferred_step_on_ordinary_ranges() {
        assert_eq!(tabulation_step_nm(480.0, 1.0), 1.0);
        assert_eq!(tabulation_step_nm(8_191.0, 1.0), 1.0);
        let step = tabulation_step_nm(99_900.0, 1.0);
        assert!(99_900.0 / step <= (MAX_TABULATION_SAMPLES - 1) as f64 + 1e-9);
        assert_eq!(tabulation_step_nm(f64::INFINITY, 1.0), 1.0);
    }
}
