//! How camera paths draw their wavelengths: the observer's density mixed with the
//! radiance the scene is expected to send.

use super::spectra::*;

/// Share of the camera's wavelengths drawn from the observer's own density (the rest
/// follow the observer times the scene's expected radiance).
pub const OBSERVER_SHARE: f32 = 0.25;

/// The density with which a scene's camera paths draw their wavelengths: the mixture
/// OBSERVER_SHARE·p_obs + (1 − OBSERVER_SHARE)·p_S of the [`Observer`]'s density
/// (piecewise constant) and of p_S ∝ the linear interpolant of max(x̄, ȳ, z̄)·S between
/// the 1 nm nodes, S the radiance the scene is expected to send (its light spectrum plus
/// what its fluorescent surfaces emit under it). Within each 1 nm interval the mixture is
/// linear and is sampled exactly. Under a light with lines (F11) or a strongly
/// fluorescent surface the estimate of each pixel's colour then varies far less with the
/// wavelengths drawn; the observer's share keeps every wavelength the observer sees
/// reachable.
#[derive(Debug, Clone)]
pub struct WavelengthSampler {
    cdf: IntervalCdf,
    /// Density (1/nm) at the start and at the end of each 1 nm interval.
    ends: Vec<[f32; 2]>,
}

impl WavelengthSampler {
    /// The observer's density alone.
    pub fn observer() -> WavelengthSampler {
        let o = Observer::get();
        WavelengthSampler {
            cdf: o.cdf.clone(),
            ends: o.density.iter().map(|&p| [p, p]).collect(),
        }
    }

    /// The mixture for the radiances `guides` a scene is expected to send (each at the
    /// 1 nm nodes): p_S is the equal-weight mixture of the densities ∝ max(x̄, ȳ, z̄)·S
    /// of every guide S that the observer sees (so that each is sampled at least in its
    /// share of proportion to its own colour signal); the observer's density alone when
    /// none is seen.
    pub fn guided(guides: &[Table]) -> WavelengthSampler {
        let o = Observer::get();
        let mut h = vec![0.0f64; TABLE_LEN];
        for guide in guides {
            let hc: Vec<f64> = (0..TABLE_LEN)
                .map(|i| o.cmf[i].max_element() as f64 * (guide.values[i] as f64).max(0.0))
                .collect();
            let mass: f64 = hc.windows(2).map(|w| 0.5 * (w[0] + w[1])).sum();
            if mass > 0.0 && mass.is_finite() {
                for (sum, v) in h.iter_mut().zip(&hc) {
                    *sum += v / mass;
                }
            }
        }
        let total: f64 = h.windows(2).map(|w| 0.5 * (w[0] + w[1])).sum();
        if !(total > 0.0 && total.is_finite()) {
            return WavelengthSampler::observer();
        }
        let share = OBSERVER_SHARE as f64;
        let ends: Vec<[f64; 2]> = (0..TABLE_LEN - 1)
            .map(|i| {
                let base = share * o.density[i] as f64;
                [
                    base + (1.0 - share) * h[i] / total,
                    base + (1.0 - share) * h[i + 1] / total,
                ]
            })
            .collect();
        match IntervalCdf::new(ends.iter().map(|e| 0.5 * (e[0] + e[1]))) {
            Some(cdf) => {
                // Renormalise so that the densities match the CDF's masses exactly.
                let sum: f64 = ends.iter().map(|e| 0.5 * (e[0] + e[1])).sum();
                let ends = ends
                    .iter()
                    .map(|e| [(e[0] / sum) as f32, (e[1] / sum) as f32])
                    .collect();
                WavelengthSampler { cdf, ends }
            }
            None => WavelengthSampler::observer(),
        }
    }

    /// Draws a wavelength from `u` in [0, 1); returns it and its density (1/nm).
    #[inline]
    pub fn sample(&self, u: f32) -> (f32, f32) {
        let (i, v) = self.cdf.locate(u);
        let [y0, y1] = self.ends[i];
        let t = linear_inverse(y0, y1, v);
        (LAMBDA_MIN_NM + i as f32 + t, y0 + t * (y1 - y0))
    }
}
