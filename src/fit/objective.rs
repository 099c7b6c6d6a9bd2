//! The least-squares objective on the grid spectra (κ, a, v) and its derivatives.
//!
//! Off the diagonal the model is F_ij = s·a_i·v_j with s = κ/(γ·S): S normalises the
//! emission (∫e = 1), γ = max(1, λ̄e/λmin) is the photon factor, and κ = k·γ is the
//! smallest concentration the constraints allow (κ ≤ 1 is exactly "some valid c exists"
//! when max a = 1). On the diagonal the reflectance d_j is eliminated in closed form:
//! it is the projection of M_jj − F_jj onto its feasible interval [0, 1 − κ·a_j] (r ≤ 1
//! and photon conservation), so every point the solver visits is a valid material and
//! the diagonal residual is what that projection cannot absorb.

use nalgebra::DMatrix;

use super::data::FitData;
use super::representation::GridSpectra;

/// Weight of the term that fixes the free scale of the emission samples (S = 1). The
/// model does not depend on that scale, so the term changes no fitted material.
const SCALE_GAUGE_WEIGHT: f64 = 1e-4;

/// Quantities derived from the grid spectra that the model needs.
#[derive(Debug, Clone, Copy)]
pub struct Derived {
    /// S = Σ v_j·w_j: the emission normaliser.
    pub normaliser: f64,
    /// λ̄e, the mean emission wavelength (nm).
    pub emission_mean_nm: f64,
    /// λmin, the infimum of absorbed wavelengths (nm).
    pub shortest_absorbed_nm: f64,
    /// γ = max(1, λ̄e/λmin).
    pub photon_factor: f64,
    /// Whether γ > 1 (the photon law is stricter than Q ≤ 1).
    pub photon_limited: bool,
    /// s = κ/(γ·S), the scale of the off-diagonal product.
    pub scale: f64,
}

/// Where a fitted diagonal reflectance sits in its feasible interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiagonalRegime {
    /// Inside: the diagonal is matched exactly.
    Free,
    /// Clamped at d = 0: the fluorescent term alone exceeds the measured diagonal.
    AtZero,
    /// Clamped at d = 1 − κ·a: conservation caps the reflectance.
    AtCap,
}

/// The objective for one measurement.
pub struct Objective<'a> {
    /// The cells.
    pub data: &'a FitData,
}

impl<'a> Objective<'a> {
    /// Derived quantities for the spectra `sp`.
    pub fn derived(&self, sp: &GridSpectra) -> Derived {
        let data = self.data;
        let mut normaliser = 0.0;
        let mut moment = 0.0;
        for ((v, w), l) in sp
            .emission
            .iter()
            .zip(&data.emission_weight)
            .zip(&data.emission_nm)
        {
            normaliser += v * w;
            moment += v * w * l;
        }
        let emission_mean_nm = if normaliser > 0.0 {
            moment / normaliser
        } else {
            f64::NAN
        };
        let shortest_absorbed_nm = shortest_positive(&sp.absorption, &data.excitation_nm);
        let ratio = emission_mean_nm / shortest_absorbed_nm;
        let photon_limited = ratio.is_finite() && ratio > 1.0;
        let photon_factor = if photon_limited { ratio } else { 1.0 };
        let scale = if normaliser > 0.0 {
            sp.kappa / (photon_factor * normaliser)
        } else {
            0.0
        };
        Derived {
            normaliser,
            emission_mean_nm,
            shortest_absorbed_nm,
            photon_factor,
            photon_limited,
            scale,
        }
    }

    /// The fitted diagonal reflectance d_j (per diagonal cell of `data.diagonal`) and where
    /// it sits in its feasible interval.
    pub fn diagonal(&self, sp: &GridSpectra, d: &Derived) -> Vec<(f64, DiagonalRegime)> {
        self.data
            .diagonal
            .iter()
            .map(|c| {
                let raw = c.value - d.scale * sp.absorption[c.row] * sp.emission[c.column];
                let cap = 1.0 - sp.kappa * sp.absorption[c.row];
                if raw < 0.0 {
                    (0.0, DiagonalRegime::AtZero)
                } else if raw > cap {
                    (cap, DiagonalRegime::AtCap)
                } else {
                    (raw, DiagonalRegime::Free)
                }
            })
            .collect()
    }

    /// ½‖r‖² and its gradient with respect to (κ, a, v).
    pub fn cost_gradient(&self, sp: &GridSpectra) -> (f64, f64, Vec<f64>, Vec<f64>) {
        let data = self.data;
        let d = self.derived(sp);
        let (a, v, s) = (&sp.absorption, &sp.emission, d.scale);
        let mut cost = 0.0;
        let mut g_scale = 0.0;
        let mut g_kappa = 0.0;
        let mut g_a = vec![0.0; a.len()];
        let mut g_v = vec![0.0; v.len()];
        for c in &data.off_diagonal {
            let (ai, vj) = (a[c.row], v[c.column]);
            let r = c.value - s * ai * vj;
            cost += 0.5 * r * r;
            g_scale -= r * ai * vj;
            g_a[c.row] -= r * s * vj;
            g_v[c.column] -= r * s * ai;
        }
        for c in &data.diagonal {
            let (ai, vj) = (a[c.row], v[c.column]);
            let raw = c.value - s * ai * vj;
            let cap = 1.0 - sp.kappa * ai;
            let r = if raw < 0.0 {
                raw
            } else if raw > cap {
                raw - cap
            } else {
                continue;
            };
            cost += 0.5 * r * r;
            g_scale -= r * ai * vj;
            g_a[c.row] -= r * s * vj;
            g_v[c.column] -= r * s * ai;
            if raw > cap {
                g_kappa += r * ai;
                g_a[c.row] += r * sp.kappa;
            }
        }
        if d.normaliser > 0.0 {
            g_kappa += g_scale / (d.photon_factor * d.normaliser);
            for (j, g) in g_v.iter_mut().enumerate() {
                *g += g_scale * self.scale_derivative(&d, j);
            }
        }
        let gauge = d.normaliser - 1.0;
        cost += 0.5 * SCALE_GAUGE_WEIGHT * gauge * gauge;
        for (g, w) in g_v.iter_mut().zip(&data.emission_weight) {
            *g += SCALE_GAUGE_WEIGHT * gauge * w;
        }
        (cost, g_kappa, g_a, g_v)
    }

    /// ∂s/∂v_j.
    fn scale_derivative(&self, d: &Derived, j: usize) -> f64 {
        let data = self.data;
        let w = data.emission_weight[j];
        let d_gamma = if d.photon_limited {
            w * (data.emission_nm[j] - d.emission_mean_nm) / (d.normaliser * d.shortest_absorbed_nm)
        } else {
            0.0
        };
        -d.scale * (d_gamma / d.photon_factor + w / d.normaliser)
    }

    /// The residual vector r (off-diagonal cells, diagonal cells, the scale gauge); the
    /// objective is ½‖r‖².
    pub fn residuals(&self, sp: &GridSpectra) -> Vec<f64> {
        let data = self.data;
        let d = self.derived(sp);
        let mut r = Vec::with_capacity(data.off_diagonal.len() + data.diagonal.len() + 1);
        for c in &data.off_diagonal {
            r.push(c.value - d.scale * sp.absorption[c.row] * sp.emission[c.column]);
        }
        for (c, (dj, _)) in data.diagonal.iter().zip(self.diagonal(sp, &d)) {
            r.push(c.value - d.scale * sp.absorption[c.row] * sp.emission[c.column] - dj);
        }
        r.push(SCALE_GAUGE_WEIGHT.sqrt() * (d.normaliser - 1.0));
        r
    }

    /// ∂r/∂(κ, a, v): one row per residual of [`Objective::residuals`].
    pub fn jacobian(&self, sp: &GridSpectra) -> DMatrix<f64> {
        let data = self.data;
        let d = self.derived(sp);
        let (n_ex, n_em) = (data.n_excitation(), data.n_emission());
        let rows = data.off_diagonal.len() + data.diagonal.len() + 1;
        let mut j = DMatrix::zeros(rows, 1 + n_ex + n_em);
        let ds: Vec<f64> = if d.normaliser > 0.0 {
            (0..n_em).map(|l| self.scale_derivative(&d, l)).collect()
        } else {
            vec![0.0; n_em]
        };
        let kappa_scale = if d.normaliser > 0.0 {
            1.0 / (d.photon_factor * d.normaliser)
        } else {
            0.0
        };
        let regimes = self.diagonal(sp, &d);
        let cells = data
            .off_diagonal
            .iter()
            .map(|c| (c, DiagonalRegime::AtZero))
            .chain(data.diagonal.iter().zip(regimes.iter().map(|x| x.1)));
        for (row, (c, regime)) in cells.enumerate() {
            if regime == DiagonalRegime::Free {
                continue;
            }
            let (ai, vj) = (sp.absorption[c.row], sp.emission[c.column]);
            j[(row, 0)] = -ai * vj * kappa_scale;
            j[(row, 1 + c.row)] = -d.scale * vj;
            for (l, dsl) in ds.iter().enumerate() {
                j[(row, 1 + n_ex + l)] = -ai * vj * dsl;
            }
            j[(row, 1 + n_ex + c.column)] -= d.scale * ai;
            if regime == DiagonalRegime::AtCap {
                j[(row, 0)] += ai;
                j[(row, 1 + c.row)] += sp.kappa;
            }
        }
        let gauge_row = rows - 1;
        for (l, w) in data.emission_weight.iter().enumerate() {
            j[(gauge_row, 1 + n_ex + l)] = SCALE_GAUGE_WEIGHT.sqrt() * w;
        }
        j
    }
}

/// The infimum of wavelengths where a > 0 for a piecewise-linear a: the sample before
/// the first positive one (absorption rises from it). NaN when a vanishes.
pub fn shortest_positive(absorption: &[f64], grid: &[f64]) -> f64 {
    match absorption.iter().position(|&x| x > 0.0) {
        Some(0) => grid[0],
        Some(i) => grid[i - 1],
        None => f64::NAN,
    }
}
