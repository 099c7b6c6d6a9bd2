//! How the fitted spectra are parameterised. The objective works on the spectra sampled
//! on the measurement grids; a representation maps solver parameters θ to those samples
//! and pulls gradients back. Every representation keeps the model feasible by
//! construction: κ ∈ [0, 1], a ∈ [0, 1], emission ≥ 0.

use nalgebra::DMatrix;

/// The largest κ a start may have, grid or parametric: with κ = sin²t the bound κ = 1 is
/// a stationary point, where a start exactly on it would stay.
pub const START_KAPPA_CAP: f64 = 0.98;

/// The spectra a parameter vector stands for, on the fit grids.
#[derive(Debug, Clone, PartialEq)]
pub struct GridSpectra {
    /// κ = c_min = k·γ: the smallest feasible concentration, in [0, 1].
    pub kappa: f64,
    /// Absorption shape on the excitation grid, in [0, 1] (normalised to max 1 later).
    pub absorption: Vec<f64>,
    /// Emission column values on the emission grid, ≥ 0, any scale.
    pub emission: Vec<f64>,
}

/// A parameterisation of (κ, a, e) for the solver. Implement this to add a spectral
/// representation (the fit, its objective and its solvers stay unchanged).
pub trait Representation: Send + Sync {
    /// A short name recorded in the material's fit block.
    fn name(&self) -> &str;
    /// Number of solver parameters.
    fn n_params(&self) -> usize;
    /// The spectra for parameters `theta`.
    fn spectra(&self, theta: &[f64]) -> GridSpectra;
    /// Parameters reproducing (as closely as the representation allows) given spectra.
    fn encode(&self, spectra: &GridSpectra) -> Vec<f64>;
    /// ∂(κ, a, e)/∂θ as a dense matrix with 1 + n_ex + n_em rows and `n_params` columns.
    fn jacobian(&self, theta: &[f64]) -> DMatrix<f64>;
    /// θ-gradient from the `gradient` with respect to κ, the absorption and the emission
    /// samples (laid out as the spectra). The default multiplies by
    /// [`Representation::jacobian`]; override when cheaper.
    fn pull_back(&self, theta: &[f64], gradient: &GridSpectra) -> Vec<f64> {
        let j = self.jacobian(theta);
        let mut g = Vec::with_capacity(1 + gradient.absorption.len() + gradient.emission.len());
        g.push(gradient.kappa);
        g.extend_from_slice(&gradient.absorption);
        g.extend_from_slice(&gradient.emission);
        (0..j.ncols())
            .map(|c| (0..j.nrows()).map(|r| j[(r, c)] * g[r]).sum())
            .collect()
    }
}

/// One free sample per grid wavelength (the tabulated model): κ = sin²t, a_i = sin²α_i,
/// e_j = q_j². The squares keep every sample in range without bounds; a sample at a bound
/// has zero derivative there, so zeros found by the non-negative start stay exact zeros.
#[derive(Debug, Clone)]
pub struct Tabulated {
    /// Excitation samples.
    pub n_excitation: usize,
    /// Emission samples.
    pub n_emission: usize,
}

impl Representation for Tabulated {
    fn name(&self) -> &str {
        "tabulated"
    }

    fn n_params(&self) -> usize {
        1 + self.n_excitation + self.n_emission
    }

    fn spectra(&self, theta: &[f64]) -> GridSpectra {
        let n = self.n_excitation;
        GridSpectra {
            kappa: theta[0].sin().powi(2),
            absorption: theta[1..1 + n].iter().map(|t| t.sin().powi(2)).collect(),
            emission: theta[1 + n..].iter().map(|q| q * q).collect(),
        }
    }

    fn encode(&self, s: &GridSpectra) -> Vec<f64> {
        let mut theta = Vec::with_capacity(self.n_params());
        theta.push(s.kappa.clamp(0.0, 1.0).sqrt().asin());
        theta.extend(s.absorption.iter().map(|a| a.clamp(0.0, 1.0).sqrt().asin()));
        theta.extend(s.emission.iter().map(|e| e.max(0.0).sqrt()));
        theta
    }

    fn jacobian(&self, theta: &[f64]) -> DMatrix<f64> {
        let n = self.n_params();
        let mut j = DMatrix::zeros(n, n);
        for (k, t) in theta.iter().enumerate().take(1 + self.n_excitation) {
            j[(k, k)] = (2.0 * t).sin();
        }
        for (k, q) in theta.iter().enumerate().skip(1 + self.n_excitation) {
            j[(k, k)] = 2.0 * q;
        }
        j
    }

    fn pull_back(&self, theta: &[f64], gradient: &GridSpectra) -> Vec<f64> {
        let mut g = Vec::with_capacity(self.n_params());
        g.push(gradient.kappa * (2.0 * theta[0]).sin());
        g.extend(
            gradient
                .absorption
                .iter()
                .zip(&theta[1..])
                .map(|(ga, t)| ga * (2.0 * t).sin()),
        );
        g.extend(
            gradient
                .emission
                .iter()
                .zip(&theta[1 + self.n_excitation..])
                .map(|(ge, q)| ge * 2.0 * q),
        );
        g
    }
}
