//! The colour term of the grid fit: CIELAB of the flat patch under the scene's lights,
//! linearised at the measured colour, as linear functionals of the cell residuals, with a
//! robust loss that leaves the noise to the matrix term (model.md §7).

use crate::colour::{Light, PatchColorimeter, Xyz};

use super::data::FitData;
use crate::numeric::{dot, zeros};

/// τ of the colour term's robust loss (ΔE76 units): about the difference a person sees.
pub const COLOUR_SCALE: f64 = 1.0;

/// The colour term: per light, CIELAB of the flat patch linearised at the measured
/// colour, as linear functionals of the cell residuals (measured − model).
#[derive(Debug, Clone)]
pub struct ColourTerm {
    /// w: the cost is ½·w·Σ_lights s_l·τ²·ln(1 + ΔE76²/τ²).
    pub(super) weight: f64,
    /// s_l per light, in [0, 1]: how much of the weight that light's colour gets (1 unless
    /// [`ColourTerm::with_light_shares`] says otherwise).
    pub(super) light_share: Vec<f64>,
    /// Number of lights.
    pub(super) n_lights: usize,
    /// Per light: the RMS ΔE76 the measurement's noise alone gives the patch (the square
    /// root of `noise_covariance`'s trace); the colour term pulls only on the difference
    /// beyond it.
    pub(super) noise_delta_e: Vec<f64>,
    /// Per light: the covariance of (ΔL*, Δa*, Δb*) that independent cell noise gives the
    /// patch colour (linearised).
    pub(super) noise_covariance: Vec<[[f64; 3]; 3]>,
    /// ∫L·h_i, row-major (excitation row × light).
    pub(super) row_lights: Vec<f64>,
    /// Per light and Lab channel: ∂Lab/∂(off-diagonal cell of column j) / L_i.
    pub(super) emitted: Vec<[Vec<f64>; 3]>,
    /// Per light and Lab channel: ∂Lab/∂(diagonal cell of column j).
    pub(super) reflected: Vec<[Vec<f64>; 3]>,
    /// `reflected` by column: the 3·lights coefficients (light-major, then channel) of
    /// column j at `3·lights·j`, so that a diagonal cell's pulls on every channel are
    /// contiguous.
    reflected_by_column: Vec<f64>,
}

impl ColourTerm {
    /// The colour term of `lights` on the grids of `data`, linearised at the measured
    /// patch colours `reference` (XYZ per light, as [`PatchColorimeter::xyz`] gives them).
    /// `noise_sigma` is the cells' noise level: the colour difference it alone explains is
    /// left to the matrix term (least squares is the right estimate under noise; the
    /// colour term is for structure the model cannot follow).
    pub fn new(
        data: &FitData,
        lights: &[Light],
        reference: &[Xyz],
        weight: f64,
        noise_sigma: f64,
    ) -> Self {
        let n_lights = lights.len().min(reference.len());
        let mut term = ColourTerm {
            weight,
            light_share: vec![1.0; n_lights],
            n_lights,
            noise_delta_e: Vec::new(),
            noise_covariance: Vec::new(),
            row_lights: vec![0.0; data.n_excitation() * n_lights],
            emitted: Vec::with_capacity(n_lights),
            reflected: Vec::with_capacity(n_lights),
            reflected_by_column: Vec::new(),
        };
        for (l, (light, xyz)) in lights.iter().zip(reference).enumerate() {
            let pc = PatchColorimeter::cached(light, &data.excitation_nm, &data.emission_nm);
            let (light_weights, reflected, emitted, widths, scale) = pc.weights();
            let jacobian = crate::colour::lab_jacobian(*xyz, pc.white);
            // Cells are in the data's units: per bin, or per nm (then ×Δλ = emission_weight).
            let project = |weights: &[Xyz], channel: usize, per_bin: bool| -> Vec<f64> {
                weights
                    .iter()
                    .enumerate()
                    .map(|(j, w)| {
                        let unit = data.emission_weight[j] / if per_bin { widths[j] } else { 1.0 };
                        scale * unit * (0..3).map(|x| jacobian[channel][x] * w[x]).sum::<f64>()
                    })
                    .collect()
            };
            for (i, w) in light_weights.iter().enumerate() {
                term.row_lights[i * n_lights + l] = *w;
            }
            term.emitted
                .push([0, 1, 2].map(|channel| project(emitted, channel, true)));
            term.reflected
                .push([0, 1, 2].map(|channel| project(reflected, channel, false)));
        }
        term.reflected_by_column = (0..data.n_emission())
            .flat_map(|j| {
                term.reflected
                    .iter()
                    .flat_map(move |light| light.each_ref().map(|c| c[j]))
            })
            .collect();
        term.noise_covariance = term.covariance_of_noise(data, noise_sigma);
        term.noise_delta_e = term
            .noise_covariance
            .iter()
            .map(|cov| (cov[0][0] + cov[1][1] + cov[2][2]).max(0.0).sqrt())
            .collect();
        term
    }

    /// Per light, Cov(ΔLab) = σ²·Σ over the measured cells of the cell's coefficient
    /// vector times itself. An off-diagonal cell (i, j)'s coefficients are L_li·e_lj, so
    /// the off-diagonal part is Σ_j (Σ_i L_li²)·e_lj·e_ljᵀ over each column's measured
    /// rows: one pass over the cells per light, then 9 products per column.
    fn covariance_of_noise(&self, data: &FitData, noise_sigma: f64) -> Vec<[[f64; 3]; 3]> {
        let sigma2 = if noise_sigma.is_finite() {
            noise_sigma * noise_sigma
        } else {
            0.0
        };
        let n_em = data.n_emission();
        let mut diagonal_count = vec![0.0; n_em];
        for c in &data.diagonal {
            diagonal_count[c.column] += 1.0;
        }
        (0..self.n_lights)
            .map(|l| {
                let mut light_squared = vec![0.0; n_em];
                for c in data.off_diagonal.iter().chain(&data.guard) {
                    light_squared[c.column] += self.row_lights[c.row * self.n_lights + l].powi(2);
                }
                let (emitted, reflected) = (&self.emitted[l], &self.reflected[l]);
                std::array::from_fn(|a| {
                    std::array::from_fn(|b| {
                        let sum: f64 = (0..n_em)
                            .map(|j| {
                                light_squared[j] * emitted[a][j] * emitted[b][j]
                                    + diagonal_count[j] * reflected[a][j] * reflected[b][j]
                            })
                            .sum();
                        sigma2 * sum
                    })
                })
            })
            .collect()
    }

    /// The same term with light `l`'s weight scaled by `shares[l]` (clamped to [0, 1];
    /// lights beyond `shares` keep theirs).
    pub fn with_light_shares(mut self, shares: &[f64]) -> Self {
        for (s, share) in self.light_share.iter_mut().zip(shares) {
            *s = share.clamp(0.0, 1.0);
        }
        self
    }

    /// The weight of light `l`'s colour: w·s_l.
    pub(super) fn light_weight(&self, l: usize) -> f64 {
        self.weight * self.light_share.get(l).copied().unwrap_or(1.0)
    }

    /// ∫L·h_i of every light for excitation row `row`.
    pub(super) fn lights_of_row(&self, row: usize) -> &[f64] {
        &self.row_lights[row * self.n_lights..(row + 1) * self.n_lights]
    }

    /// ΔLab (measured − model, linearised) per light and channel, from the column sums
    /// Σ_i L_li·r_ij of the off-diagonal residuals (light-major) and the diagonal
    /// residuals (column, r). An iterator, not a list: the objective calls this every
    /// evaluation (perf: building the pairs was a third of it).
    #[inline(always)]
    pub(super) fn patch(
        &self,
        column_sum: &[f64],
        diagonal: impl Iterator<Item = (usize, f64)>,
        n_em: usize,
    ) -> Vec<f64> {
        // The diagonal's share of every channel at once, cell by cell: each channel's
        // running sum (from −0.0, as `sum` does) takes the cells in their order.
        let n = 3 * self.n_lights;
        let mut reflected = vec![-0.0; n];
        for (j, r) in diagonal {
            let coefficients = &self.reflected_by_column[j * n..(j + 1) * n];
            for (sum, c) in reflected.iter_mut().zip(coefficients) {
                *sum += c * r;
            }
        }
        let mut patch = zeros(n);
        for l in 0..self.n_lights {
            let sums = &column_sum[l * n_em..(l + 1) * n_em];
            for channel in 0..3 {
                let k = 3 * l + channel;
                patch[k] = dot(&self.emitted[l][channel], sums) + reflected[k];
            }
        }
        patch
    }

    /// The colour cost ½·w·Σ_l τ²·ln(1 + u_l²/τ²) of the patch ΔLab, with ΔE_l = |ΔLab_l|
    /// beyond the noise, u_l = max(0, ΔE_l − δ_l) (δ_l = the noise's RMS ΔE76, τ =
    /// [`COLOUR_SCALE`]), and ∂cost/∂ΔLab / w. A colour difference the noise explains costs
    /// nothing (the matrix term alone decides there); beyond it the cost is ½·w·u² while
    /// u < τ, and a light whose difference the model cannot bring near τ (a second emitter
    /// a one-fluorophore model cannot follow) pulls less and less instead of trading the
    /// other lights' colour for a small gain of its own.
    pub(super) fn robust(&self, patch: &[f64]) -> (f64, Vec<f64>) {
        let tau2 = COLOUR_SCALE * COLOUR_SCALE;
        let mut cost = 0.0;
        let mut pull = patch.to_vec();
        for ((light, delta), share) in pull
            .chunks_exact_mut(3)
            .zip(&self.noise_delta_e)
            .zip(&self.light_share)
        {
            let t = light.iter().map(|p| p * p).sum::<f64>().sqrt();
            let u = (t - delta).max(0.0);
            cost += 0.5 * self.weight * share * tau2 * (u * u / tau2).ln_1p();
            // ∂cost/∂ΔLab = w·s·u/(1 + u²/τ²)·ΔLab/t.
            let factor = share
                * if t > 0.0 {
                    u / (1.0 + u * u / tau2) / t
                } else {
                    1.0
                };
            light.iter_mut().for_each(|p| *p *= factor);
        }
        (cost, pull)
    }

    /// φ(t) and φ′(t) for light `l` at ΔE t: the residual √w·φ(t)·ΔLab has ½‖·‖² equal
    /// to that light's cost in [`ColourTerm::robust`].
    pub(super) fn residual_factor(&self, l: usize, t: f64) -> (f64, f64) {
        let tau = COLOUR_SCALE;
        let delta = self.noise_delta_e[l];
        if t <= delta {
            return (if t == 0.0 && delta == 0.0 { 1.0 } else { 0.0 }, 0.0);
        }
        let u = t - delta;
        let x = (u / tau).powi(2);
        if x < 1e-10 {
            // g(t) = τ·√ln(1 + u²/τ²) ≈ u: φ = u/t, φ′ = δ/t².
            return (u / t, delta / (t * t));
        }
        let g = tau * x.ln_1p().sqrt();
        let dg = u / (tau * x.ln_1p().sqrt() * (1.0 + x));
        (g / t, dg / t - g / (t * t))
    }

    /// The colour cost's pull on the residuals, given ∂cost/∂ΔLab / w: per light and
    /// column q_lj (light-major; an off-diagonal cell's pull is Σ_l L_li·q_lj) and per
    /// column h_j (a diagonal cell's pull).
    #[inline(always)]
    pub(super) fn pulls(&self, pull_patch: &[f64], n_em: usize) -> (Vec<f64>, Vec<f64>) {
        let mut q = zeros(self.n_lights * n_em);
        let mut h = zeros(n_em);
        // Zipped slices, same order of additions per element as indexed loops: those kept
        // their bounds checks and stayed scalar (perf: 4 % of a grid fit).
        // q in one pass per light: ((0 + p₀·e₀) + p₁·e₁) + p₂·e₂, the additions in the
        // order three passes made them.
        for (l, q_l) in q.chunks_exact_mut(n_em).enumerate() {
            let p: [f64; 3] = std::array::from_fn(|c| self.weight * pull_patch[3 * l + c]);
            let [e0, e1, e2] = &self.emitted[l];
            for (((qj, e0), e1), e2) in q_l.iter_mut().zip(e0).zip(e1).zip(e2) {
                *qj = 0.0 + p[0] * e0 + p[1] * e1 + p[2] * e2;
            }
            for (channel, re) in self.reflected[l].iter().enumerate() {
                let p = p[channel];
                for (hj, r) in h.iter_mut().zip(re) {
                    *hj += p * r;
                }
            }
        }
        (q, h)
    }
}

/// Standard deviations of the noise's own residual energy a light's residual must pass
/// before [`misfit_shares`] counts any of it as structure (the noise-coverage factor of
/// the fit's other noise tests).
const MISFIT_COVERAGE: f64 = 3.0;

/// Per light of `term`, the share of the rank-1 start's residual (`row`·`column`ᵀ against
/// the off-diagonal cells of `data`) that noise of level `sigma` does not explain, in the
/// rows that light excites: rows weighted by the square of the light reaching them (the
/// weight of a row's cells in the patch colour), and the noise allowed its expected
/// energy plus [`MISFIT_COVERAGE`] standard deviations. A light that pours most of its
/// energy into a few rows (the `uv` light's 365 nm LED: rows 360 and 370 nm) sees only
/// those rows; where they hold noise alone, least squares is the right estimate there and
/// the colour term would trade those rows' samples for the noise of the measured colour.
pub(super) fn misfit_shares(
    data: &FitData,
    row: &[f64],
    column: &[f64],
    sigma: f64,
    term: &ColourTerm,
) -> Vec<f64> {
    let n_ex = data.n_excitation();
    let mut energy = vec![0.0; n_ex];
    let mut cells = vec![0.0; n_ex];
    for c in &data.off_diagonal {
        let fitted =
            row.get(c.row).copied().unwrap_or(0.0) * column.get(c.column).copied().unwrap_or(0.0);
        energy[c.row] += (c.value - fitted).powi(2);
        cells[c.row] += 1.0;
    }
    let sigma2 = if sigma.is_finite() {
        sigma * sigma
    } else {
        0.0
    };
    (0..term.n_lights)
        .map(|l| {
            let (mut residual, mut noise, mut variance) = (0.0, 0.0, 0.0);
            for i in 0..n_ex {
                let w2 = term.row_lights[i * term.n_lights + l].powi(2);
                residual += w2 * energy[i];
                noise += w2 * cells[i] * sigma2;
                // A row's noise energy is σ²·χ²(n): variance 2·n·σ⁴.
                variance += w2 * w2 * 2.0 * cells[i] * sigma2 * sigma2;
            }
            if residual > 0.0 {
                (1.0 - (noise + MISFIT_COVERAGE * variance.sqrt()) / residual).max(0.0)
            } else {
                0.0
            }
        })
        .collect()
}
