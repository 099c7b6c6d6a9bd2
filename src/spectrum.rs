//! Tabulated spectra and wavelength grids.
//!
//! A spectrum is a function of wavelength sampled at increasing wavelengths and linear
//! between samples. Outside its samples it is either zero (absorption, emission, lights)
//! or holds its end values (reflectance); the caller says which by the evaluation method.
//!
//! Integrals use the trapezoid rule, which is exact for the linear interpolant inside the
//! samples. On a measurement grid the same rule gives each sample its *bin width*
//! ([`bin_widths`]): half the distance to each neighbour, so the end bins are half wide.
//! Using one rule for the model's bins, the emission normalisation and the colour
//! integrals keeps conservation exact: a row of the model matrix sums to k·a(λi)·∫e.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A sampled spectrum: `value[i]` at `wavelength_nm[i]`, linear in between.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Spectrum {
    /// Sample wavelengths in nm, strictly increasing.
    pub wavelength_nm: Vec<f64>,
    /// Sample values, one per wavelength.
    pub value: Vec<f64>,
}

impl Spectrum {
    /// Builds a spectrum, checking that it is usable: equal lengths, at least one sample,
    /// finite values, strictly increasing positive wavelengths. `what` names the spectrum in
    /// the error (`fluorophores[0].absorption`).
    pub fn new(wavelength_nm: Vec<f64>, value: Vec<f64>, what: &str) -> Result<Self> {
        let s = Spectrum {
            wavelength_nm,
            value,
        };
        s.validate(what)?;
        Ok(s)
    }

    /// Checks the invariants [`Spectrum::new`] establishes (for spectra read with serde).
    pub fn validate(&self, what: &str) -> Result<()> {
        if self.wavelength_nm.len() != self.value.len() {
            return Err(Error::invalid(
                what,
                format!(
                    "has {} wavelengths but {} values; give one value per wavelength",
                    self.wavelength_nm.len(),
                    self.value.len()
                ),
            ));
        }
        if self.wavelength_nm.is_empty() {
            return Err(Error::invalid(what, "has no samples; give at least one"));
        }
        check_grid(&self.wavelength_nm, &format!("{what}.wavelength_nm"))?;
        if let Some(i) = self.value.iter().position(|v| !v.is_finite()) {
            return Err(Error::invalid(
                format!("{what}.value[{i}]"),
                format!(
                    "is {} at {} nm; values must be finite numbers",
                    self.value[i], self.wavelength_nm[i]
                ),
            ));
        }
        Ok(())
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.value.len()
    }

    /// True when the spectrum has no samples (never for a validated spectrum).
    pub fn is_empty(&self) -> bool {
        self.value.is_empty()
    }

    /// Value at `nm`, linear between samples and zero outside them.
    pub fn eval_zero_outside(&self, nm: f64) -> f64 {
        let w = &self.wavelength_nm;
        match w.len() {
            0 => 0.0,
            1 => {
                if (nm - w[0]).abs() < 1e-9 {
                    self.value[0]
                } else {
                    0.0
                }
            }
            _ if nm < w[0] - 1e-9 || nm > w[w.len() - 1] + 1e-9 => 0.0,
            _ => self.eval_clamped(nm),
        }
    }

    /// Value at `nm`, linear between samples and holding the end values outside them.
    pub fn eval_clamped(&self, nm: f64) -> f64 {
        let w = &self.wavelength_nm;
        if w.is_empty() {
            return 0.0;
        }
        if nm <= w[0] {
            return self.value[0];
        }
        let last = w.len() - 1;
        if nm >= w[last] {
            return self.value[last];
        }
        // First sample strictly above nm; nm lies in [w[hi-1], w[hi]). On a uniform grid
        // (every tabulated and fitted spectrum) the step gives it; else the search does.
        let guess = ((nm - w[0]) / (w[last] - w[0]) * last as f64) as usize;
        let hi = if guess < last && w[guess] <= nm && nm < w[guess + 1] {
            guess + 1
        } else {
            w.partition_point(|&x| x <= nm)
        };
        let lo = hi - 1;
        let t = (nm - w[lo]) / (w[hi] - w[lo]);
        self.value[lo] + t * (self.value[hi] - self.value[lo])
    }

    /// ∫ value dλ by the trapezoid rule (exact for the linear interpolant).
    pub fn integral(&self) -> f64 {
        bin_widths(&self.wavelength_nm)
            .iter()
            .zip(&self.value)
            .map(|(w, v)| w * v)
            .sum()
    }

    /// ∫ λ·value dλ / ∫ value dλ: the mean wavelength, in nm (NaN when the integral is 0).
    pub fn mean_wavelength_nm(&self) -> f64 {
        let widths = bin_widths(&self.wavelength_nm);
        let mut num = 0.0;
        let mut den = 0.0;
        for ((w, v), l) in widths.iter().zip(&self.value).zip(&self.wavelength_nm) {
            num += w * v * l;
            den += w * v;
        }
        num / den
    }

    /// Largest sample value.
    pub fn max(&self) -> f64 {
        self.value.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
    }

    /// Resamples onto `grid`, zero outside the samples.
    pub fn resample_zero_outside(&self, grid: &[f64]) -> Spectrum {
        Spectrum {
            wavelength_nm: grid.to_vec(),
            value: grid.iter().map(|&l| self.eval_zero_outside(l)).collect(),
        }
    }

    /// Resamples onto `grid`, holding end values outside the samples.
    pub fn resample_clamped(&self, grid: &[f64]) -> Spectrum {
        Spectrum {
            wavelength_nm: grid.to_vec(),
            value: grid.iter().map(|&l| self.eval_clamped(l)).collect(),
        }
    }
}

/// Checks a wavelength grid: at most [`crate::limits::MAX_GRID_POINTS`] samples, each within
/// [`crate::limits::WAVELENGTH_NM`], strictly increasing. `what` names it.
pub fn check_grid(grid: &[f64], what: &str) -> Result<()> {
    if grid.len() > crate::limits::MAX_GRID_POINTS {
        return Err(Error::invalid(
            what,
            format!(
                "has {} wavelengths; at most {} are read on one axis (a 0.1 nm step over 200–1200 nm needs 10,001)",
                grid.len(),
                crate::limits::MAX_GRID_POINTS
            ),
        ));
    }
    for (i, &l) in grid.iter().enumerate() {
        if !l.is_finite() || l <= 0.0 {
            return Err(Error::invalid(
                format!("{what}[{i}]"),
                format!("is {l}; wavelengths must be positive finite numbers in nm"),
            ));
        }
        if let Err(message) = crate::limits::check_wavelength(l) {
            return Err(Error::invalid(format!("{what}[{i}]"), message));
        }
        if i > 0 && l <= grid[i - 1] {
            let kind = if l == grid[i - 1] {
                "repeats"
            } else {
                "is below"
            };
            return Err(Error::invalid(
                format!("{what}[{i}]"),
                format!(
                    "{l} nm {kind} the previous wavelength {} nm; wavelengths must be strictly increasing",
                    grid[i - 1]
                ),
            ));
        }
    }
    Ok(())
}

/// Trapezoid weights of a grid: the width of the bin each sample stands for, half the
/// distance to each neighbour (so end bins are half wide). A single sample gets width 1,
/// so that a lone value is read as already integrated.
pub fn bin_widths(grid: &[f64]) -> Vec<f64> {
    let n = grid.len();
    match n {
        0 => Vec::new(),
        1 => vec![1.0],
        _ => (0..n)
            .map(|i| {
                let lo = if i == 0 { grid[0] } else { grid[i - 1] };
                let hi = if i + 1 == n { grid[n - 1] } else { grid[i + 1] };
                0.5 * (hi - lo)
            })
            .collect(),
    }
}

/// Most trapezoids [`hat_integrals`] spends on one grid interval: 0.25 nm steps over a
/// 2,500 nm interval.
pub const MAX_HAT_SUBSTEPS: usize = 10_000;

/// For each sample of `grid`, ∫ f(λ)·h_i(λ) dλ where h_i is the hat function of the linear
/// interpolation basis (1 at sample i, 0 at its neighbours). This projects a finely
/// varying function (a light, a colour-matching function) onto a coarse grid so that
/// Σ_i g_i·∫f·h_i = ∫ f·g for any spectrum g linear between the grid's samples.
/// `f` is integrated with `substeps` trapezoids per grid interval.
pub fn hat_integrals(grid: &[f64], f: impl Fn(f64) -> f64, substeps: usize) -> Vec<f64> {
    hat_integrals_with(grid, f, |_| substeps)
}

/// [`hat_integrals`] with the number of trapezoids chosen per grid interval from its
/// length in nm (`substeps_for(λ[i+1] − λ[i])`), so that a grid with one very wide interval
/// does not spend that interval's count on every other one.
pub fn hat_integrals_with(
    grid: &[f64],
    f: impl Fn(f64) -> f64,
    substeps_for: impl Fn(f64) -> usize,
) -> Vec<f64> {
    let n = grid.len();
    let mut out = vec![0.0; n];
    if n == 1 {
        out[0] = f(grid[0]);
        return out;
    }
    for i in 0..n.saturating_sub(1) {
        let (l0, l1) = (grid[i], grid[i + 1]);
        // Bounded so that no grid spacing, however wide, makes the projection a long loop.
        let substeps = substeps_for(l1 - l0).clamp(1, MAX_HAT_SUBSTEPS);
        let h = (l1 - l0) / substeps as f64;
        for s in 0..=substeps {
            let t = s as f64 / substeps as f64;
            let l = l0 + t * (l1 - l0);
            let weight = if s == 0 || s == substeps { 0.5 * h } else { h };
            let v = f(l) * weight;
            out[i] += v * (1.0 - t);
            out[i + 1] += v * t;
        }
    }
    out
}

/// Finds `nm` in a sorted grid (within 1e-6 nm).
pub fn find_wavelength(grid: &[f64], nm: f64) -> Option<usize> {
    let i = grid.partition_point(|&x| x < nm - 1e-6);
    (i < grid.len() && (grid[i] - nm).abs() <= 1e-6).then_some(i)
}

/// A uniform grid from `start` to `end` inclusive with step `step` (nm).
pub fn uniform_grid(start: f64, end: f64, step: f64) -> Vec<f64> {
    let n = ((end - start) / step + 1e-9).floor() as usize + 1;
    (0..n).map(|i| start + step * i as f64).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_is_exact_for_linear_interpolant() {
        let s = Spectrum::new(vec![400.0, 410.0, 430.0], vec![0.0, 1.0, 0.0], "s").unwrap();
        // Triangle of height 1 over 30 nm.
        assert!((s.integral() - 15.0).abs() < 1e-12);
        assert!((s.eval_clamped(405.0) - 0.5).abs() < 1e-12);
        assert!((s.eval_zero_outside(420.0) - 0.5).abs() < 1e-12);
        assert_eq!(s.eval_zero_outside(399.0), 0.0);
        assert_eq!(s.eval_clamped(999.0), 0.0);
    }

    #[test]
    fn hat_integrals_reproduce_integral_of_products() {
        let grid = uniform_grid(380.0, 780.0, 10.0);
        let g = Spectrum::new(
            grid.clone(),
            grid.iter().map(|l| (l / 100.0).sin() + 1.5).collect(),
            "g",
        )
        .unwrap();
        let f = |l: f64| (-((l - 550.0) / 40.0).powi(2)).exp();
        let weights = hat_integrals(&grid, f, 64);
        let coarse: f64 = weights.iter().zip(&g.value).map(|(w, v)| w * v).sum();
        // Reference: fine trapezoid of f·g with g linear.
        let fine = uniform_grid(380.0, 780.0, 0.01);
        let mut reference = 0.0;
        for w in fine.windows(2) {
            let a = f(w[0]) * g.eval_clamped(w[0]);
            let b = f(w[1]) * g.eval_clamped(w[1]);
            reference += 0.5 * (a + b) * (w[1] - w[0]);
        }
        assert!((coarse - reference).abs() < 1e-6 * reference);
    }

    #[test]
    fn interpolation_is_linear_between_samples_on_any_grid() {
        // The straight line 2λ − 800 sampled on a uniform and on an uneven grid: linear
        // interpolation reproduces it exactly between samples, and holds the ends.
        let line = |l: f64| 2.0 * l - 800.0;
        for grid in [
            uniform_grid(400.0, 500.0, 10.0),
            vec![400.0, 401.0, 403.0, 450.0, 451.0, 500.0],
        ] {
            let s =
                Spectrum::new(grid.clone(), grid.iter().map(|&l| line(l)).collect(), "s").unwrap();
            for k in 0..=400 {
                let l = 400.0 + 0.25 * k as f64;
                assert!((s.eval_clamped(l) - line(l)).abs() < 1e-9, "{l} nm");
            }
            assert_eq!(s.eval_clamped(390.0), line(400.0));
            assert_eq!(s.eval_clamped(510.0), line(500.0));
        }
    }

    #[test]
    fn bad_grids_are_named() {
        let err = Spectrum::new(vec![400.0, 400.0], vec![1.0, 1.0], "absorption").unwrap_err();
        assert!(
            err.to_string().contains("absorption.wavelength_nm[1]"),
            "{err}"
        );
        assert!(Spectrum::new(vec![400.0], vec![f64::NAN], "e").is_err());
        assert!(Spectrum::new(vec![-1.0], vec![1.0], "e").is_err());
    }
}
