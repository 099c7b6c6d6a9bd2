//! The hard floor on a band's width: a Gaussian narrower than the grid step at its centre
//! falls between the samples it is fitted to, and its colour off the grid (a light's
//! narrow line between two rows) is then free of any data.
//!
//! The solver's third band parameter θ is not the ln width itself: with f(c)
//! [`FLOOR_STEPS`] times the local grid step at the centre c and x = e^θ/f, the band's
//! width is w = f·(1 + x²/4) below x = 2 and e^θ above. w never falls below f, the map
//! is continuously differentiable in θ and c, and a band at least twice the floor is
//! exactly the one θ names as its ln width (fits of broad bands do not move).

use crate::parametric::{BandTerms, BandWork, PARAMS_PER_BAND};

/// The narrowest band, in local grid steps Δ. At σ = ¾Δ the samples within ±2σ of any
/// centre span 3Δ, so at least three see the band's core; midway between two samples
/// each still sees exp(−2/9) = 80 % of the peak, and the band's content at the grid's
/// Nyquist frequency, exp(−π²σ²/2Δ²), is 6 % (29 % at σ = Δ/2): the samples fix the
/// band's value between them, where a light's narrow line may fall. Measured on the
/// class sweep's sub-grid cases (README, "Band width floor"): at Δ/2 the fitted colour
/// on the grid and off it still differed by up to 2.2 ΔE2000 under uv, at ¾Δ by 0.9.
pub const FLOOR_STEPS: f64 = 0.75;

/// Width floor of bands fitted on one grid (in the band domain's coordinate).
#[derive(Debug, Clone)]
pub struct WidthFloor {
    /// Midpoints of the grid's intervals, ascending.
    midpoints: Vec<f64>,
    /// The floor at each midpoint: [`FLOOR_STEPS`] times the interval, at least
    /// `1/200` of the grid's span.
    floor: Vec<f64>,
}

/// ∂ln w/∂θ and ∂ln w/∂c of one floored band.
#[derive(Debug, Clone, Copy)]
pub struct WidthChain {
    by_theta: f64,
    by_centre: f64,
}

impl WidthFloor {
    /// The floor of bands sampled on `grid` (any order; repeated points ignored).
    pub fn new(grid: &[f64]) -> Self {
        let mut sorted = grid.to_vec();
        sorted.sort_by(f64::total_cmp);
        sorted.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
        let span = match (sorted.first(), sorted.last()) {
            (Some(lo), Some(hi)) => (hi - lo).max(1e-6),
            _ => 1e-6,
        };
        let (midpoints, floor) = sorted
            .windows(2)
            .map(|w| {
                (
                    0.5 * (w[0] + w[1]),
                    (FLOOR_STEPS * (w[1] - w[0])).max(span / 200.0),
                )
            })
            .unzip();
        WidthFloor { midpoints, floor }
    }

    /// The floor at centre `u` and its slope: linear between interval midpoints, the end
    /// intervals' value beyond them.
    pub fn at(&self, u: f64) -> (f64, f64) {
        let (m, f) = (&self.midpoints, &self.floor);
        let (Some(&first), Some(&last)) = (m.first(), m.last()) else {
            return (1e-6, 0.0);
        };
        if u <= first || u.is_nan() {
            return (f[0], 0.0);
        }
        if u >= last {
            return (f[f.len() - 1], 0.0);
        }
        let i = m.partition_point(|&x| x <= u);
        let slope = (f[i] - f[i - 1]) / (m[i] - m[i - 1]);
        (f[i - 1] + slope * (u - m[i - 1]), slope)
    }

    /// The smallest floor anywhere on the grid (that of [`WidthFloor::at`] for a grid
    /// of one point).
    pub fn smallest(&self) -> f64 {
        let smallest = self.floor.iter().cloned().fold(f64::INFINITY, f64::min);
        if smallest.is_finite() { smallest } else { 1e-6 }
    }

    /// Gaussian parameters (ln height, centre, ln width) of solver parameters
    /// `params`, and per band the derivatives of its ln width.
    pub fn widen(&self, params: &[f64]) -> (Vec<f64>, Vec<WidthChain>) {
        let (mut gaussian, mut chains) = (Vec::new(), Vec::new());
        self.widen_into(params, &mut gaussian, &mut chains);
        (gaussian, chains)
    }

    /// [`WidthFloor::widen`] written into `gaussian` and `chains`, reusing their storage.
    pub fn widen_into(
        &self,
        params: &[f64],
        gaussian: &mut Vec<f64>,
        chains: &mut Vec<WidthChain>,
    ) {
        gaussian.clear();
        gaussian.extend_from_slice(params);
        chains.clear();
        chains.extend(gaussian.chunks_exact_mut(PARAMS_PER_BAND).map(|band| {
            let (f, slope) = self.at(band[1]);
            let ln_x = band[2] - f.ln();
            if ln_x >= BLEND_END.ln() {
                return WidthChain {
                    by_theta: 1.0,
                    by_centre: 0.0,
                };
            }
            // w = f·g(x), g = 1 + x²/4: g(2) = 2 and g'(2) = 1 meet w = e^θ.
            let x2 = (2.0 * ln_x).exp();
            let g = 1.0 + 0.25 * x2;
            band[2] = f.ln() + g.ln();
            let by_theta = 0.5 * x2 / g;
            WidthChain {
                by_theta,
                by_centre: (1.0 - by_theta) * slope / f,
            }
        }));
    }

    /// Turns a Jacobian by Gaussian parameters (sample × parameter, row-major) into one
    /// by the solver parameters [`WidthFloor::widen`] took.
    pub fn chain(&self, chains: &[WidthChain], jacobian: &mut [f64]) {
        let width = chains.len() * PARAMS_PER_BAND;
        if width == 0 {
            return;
        }
        for row in jacobian.chunks_exact_mut(width) {
            for (band, c) in row.chunks_exact_mut(PARAMS_PER_BAND).zip(chains) {
                let by_ln_width = band[2];
                band[1] += by_ln_width * c.by_centre;
                band[2] = by_ln_width * c.by_theta;
            }
        }
    }

    /// Solver parameters for Gaussian parameters `gaussian` (the inverse of
    /// [`WidthFloor::widen`]): a band at or below the floor starts just above it, where
    /// the solver can still widen it.
    pub fn solver_params(&self, gaussian: &[f64]) -> Vec<f64> {
        let mut params = gaussian.to_vec();
        for band in params.chunks_exact_mut(PARAMS_PER_BAND) {
            let (f, _) = self.at(band[1]);
            let ratio = (band[2] - f.ln()).exp();
            if ratio < BLEND_END {
                // Invert g(x) = 1 + x²/4 (a band at or below the floor starts at x_min).
                let x = (2.0 * (ratio - 1.0).max(0.0).sqrt()).max(START_X);
                band[2] = f.ln() + x.ln();
            }
        }
        params
    }
}

/// x = e^θ/f from which the width is e^θ itself (twice the floor).
const BLEND_END: f64 = 2.0;

/// The smallest x a start gives a band: a band pinned at the floor has ∂w/∂θ ≈ 0, so it
/// starts where the data can still widen it (w = 1.06·f, ∂ln w/∂θ = 0.12).
const START_X: f64 = 0.5;

/// What [`floored_bands_with_jacobian`] works in, kept from one evaluation to the next.
#[derive(Debug, Clone, Default)]
pub(super) struct BandBuffers {
    gaussian: Vec<f64>,
    chains: Vec<WidthChain>,
    terms: BandTerms,
    work: BandWork,
}

/// The bands of solver parameters `params` (widths held above `floor`) at every abscissa
/// of `u`, written to `values`, with their derivatives by the parameters written to
/// `jacobian` (one row of `params.len()` per abscissa).
pub(super) fn floored_bands_with_jacobian(
    floor: &WidthFloor,
    params: &[f64],
    u: &[f64],
    buffers: &mut BandBuffers,
    values: &mut Vec<f64>,
    jacobian: &mut Vec<f64>,
) {
    floor.widen_into(params, &mut buffers.gaussian, &mut buffers.chains);
    buffers.terms.set(&buffers.gaussian);
    buffers
        .terms
        .values_gradients(u, values, jacobian, &mut buffers.work);
    floor.chain(&buffers.chains, jacobian);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_follows_the_local_step() {
        // Wavenumber (kK) of a 10 nm grid from 300 to 400 nm: steps shrink with λ.
        let grid: Vec<f64> = (0..11).map(|n| 1e4 / (300.0 + 10.0 * n as f64)).collect();
        let floor = WidthFloor::new(&grid);
        // Midway between 360 and 370 nm the local step is 1e4/360 − 1e4/370.
        let u = 0.5 * (1e4 / 360.0 + 1e4 / 370.0);
        let step = 1e4 / 360.0 - 1e4 / 370.0;
        let (f, _) = floor.at(u);
        assert!(
            (f - FLOOR_STEPS * step).abs() < 1e-12,
            "{f} vs {}",
            FLOOR_STEPS * step
        );
        // Far below the grid: the widest end interval (300–310 nm), held.
        let (f, slope) = floor.at(100.0);
        assert!((f - FLOOR_STEPS * (1e4 / 300.0 - 1e4 / 310.0)).abs() < 1e-12 && slope == 0.0);
    }

    #[test]
    fn widened_bands_respect_the_floor_and_chain_matches_differences() {
        let grid: Vec<f64> = (0..41).map(|n| 1e4 / (380.0 + 10.0 * n as f64)).collect();
        let floor = WidthFloor::new(&grid);
        for theta_width in [-40.0, -2.0, -0.9, 0.0, 1.0, 40.0] {
            let params = [0.3, 24.1, theta_width];
            let (gaussian, chains) = floor.widen(&params);
            let (f, _) = floor.at(24.1);
            assert!(gaussian[2].exp() >= f * (1.0 - 1e-12), "{theta_width}");
            // θ well above the floor: w ≈ e^θ.
            if theta_width > 5.0 {
                assert!((gaussian[2] - theta_width).abs() < 1e-9);
            }
            // ∂ln w/∂θ and ∂ln w/∂c against central differences.
            let h = 1e-6;
            let ln_w = |p: [f64; 3]| floor.widen(&p).0[2];
            let by_theta = (ln_w([0.3, 24.1, theta_width + h])
                - ln_w([0.3, 24.1, theta_width - h]))
                / (2.0 * h);
            let by_centre = (ln_w([0.3, 24.1 + h, theta_width])
                - ln_w([0.3, 24.1 - h, theta_width]))
                / (2.0 * h);
            assert!(
                (by_theta - chains[0].by_theta).abs() < 1e-6,
                "{theta_width}"
            );
            assert!(
                (by_centre - chains[0].by_centre).abs() < 1e-6,
                "{theta_width}"
            );
        }
        // The inverse: a band above the floor comes back unchanged.
        let gaussian = [0.0, 20.0, 1.2f64.ln()];
        let back = floor.widen(&floor.solver_params(&gaussian)).0;
        assert!((back[2] - gaussian[2]).abs() < 1e-12);
    }
}
