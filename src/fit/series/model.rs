//! The stacked model of a concentration series: every file's cells as one residual
//! vector, with shared spectra and one concentration per file.
//!
//! For file j, off the diagonal F_j[i, l] = c_j·g·a_i·x_i·v_l / N(v), and on it
//! D_j = (1 − c_j·a_i)·r_p + F_j[i, l]. The emission column values v carry any scale: N
//! normalises them, so the model sees only the shape. In the energy form x_i = 1 and
//! N = max(S, M/λmin) with S = Σ v·w and M = Σ v·w·λ, so the energy yield Q = g·S/N is at
//! most its photon limit λmin/λ̄e for every g ≤ 1 (the single fit's γ, model.md §3); in the
//! photon form x_i = λ_i, N = M and Φ = g. Every parameter is a squared sine or a square
//! of a solver variable, so c_j, g, a, r ∈ [0, 1] and v ≥ 0 at every iterate, and with them
//! c_j·a ≤ 1 and the energy law of the energy form. One absorption sample (the start's
//! peak) is held at 1: a and c trade scale (c·a is what the diagonal sees), and max a = 1
//! is the project's normalisation.

use nalgebra::DMatrix;

use crate::fit::data::FitData;
use crate::fit::objective::{SCALE_GAUGE_WEIGHT, shortest_positive};
use crate::fit::solve::ResidualModel;
use crate::material::YieldForm;

/// The physical parameters of a series fit.
#[derive(Debug, Clone, PartialEq)]
pub struct SeriesParameters {
    /// a_i on the excitation grid, in [0, 1]; 1 at the held peak.
    pub absorption: Vec<f64>,
    /// Emission column values v_l on the emission grid, ≥ 0, any scale.
    pub emission: Vec<f64>,
    /// r_p at the fitted diagonal positions, in [0, 1].
    pub reflectance: Vec<f64>,
    /// g: the yield as a fraction of its limit (Q·N/S in the energy form, Φ in the photon
    /// form), in [0, 1].
    pub yield_fraction: f64,
    /// c_j per file, in [0, 1].
    pub concentrations: Vec<f64>,
}

/// N(v), the normaliser of the emission column values, with what it is made of.
#[derive(Debug, Clone)]
pub struct Normaliser {
    /// N: max(S, M/λmin) in the energy form, M in the photon form.
    pub value: f64,
    /// S = Σ v_l·w_l.
    pub sum: f64,
    /// ∂N/∂v_l.
    pub derivative: Vec<f64>,
}

/// The series as residuals of solver variables θ (see the module doc).
pub struct SeriesModel<'a> {
    /// The files' cells, on one pair of grids.
    pub files: &'a [FitData],
    /// The yield form.
    pub form: YieldForm,
    /// x_i: 1 (energy form) or λ_i (photon form).
    row_factor: Vec<f64>,
    /// The excitation sample held at a = 1.
    pub peak: usize,
    /// Diagonal positions (row, column) measured in at least one file: where r is fitted.
    pub positions: Vec<(usize, usize)>,
    /// Per file, per cell of its `diagonal`: the index of its position in `positions`.
    pub diagonal_index: Vec<Vec<usize>>,
}

impl<'a> SeriesModel<'a> {
    /// The model of `files` (same grids) in yield form `form`, holding a = 1 at `peak`.
    pub fn new(files: &'a [FitData], form: YieldForm, peak: usize) -> Self {
        let first = &files[0];
        let row_factor = match form {
            YieldForm::Energy => vec![1.0; first.n_excitation()],
            YieldForm::Photon => first.excitation_nm.clone(),
        };
        let mut positions: Vec<(usize, usize)> = files
            .iter()
            .flat_map(|d| d.diagonal.iter().map(|c| (c.row, c.column)))
            .collect();
        positions.sort_by_key(|&(_, column)| column);
        positions.dedup();
        let diagonal_index = files
            .iter()
            .map(|d| {
                d.diagonal
                    .iter()
                    .map(|c| {
                        positions
                            .iter()
                            .position(|&p| p == (c.row, c.column))
                            .expect("every measured diagonal cell has a position")
                    })
                    .collect()
            })
            .collect();
        SeriesModel {
            files,
            form,
            row_factor,
            peak,
            positions,
            diagonal_index,
        }
    }

    fn n_excitation(&self) -> usize {
        self.files[0].n_excitation()
    }

    fn n_emission(&self) -> usize {
        self.files[0].n_emission()
    }

    /// x_i of excitation row `row`.
    pub fn row_factor(&self, row: usize) -> f64 {
        self.row_factor[row]
    }

    /// Index of a_i in θ (None for the held peak).
    fn a_index(&self, i: usize) -> Option<usize> {
        match i.cmp(&self.peak) {
            std::cmp::Ordering::Less => Some(i),
            std::cmp::Ordering::Equal => None,
            std::cmp::Ordering::Greater => Some(i - 1),
        }
    }

    fn v_index(&self, l: usize) -> usize {
        self.n_excitation() - 1 + l
    }

    fn r_index(&self, p: usize) -> usize {
        self.v_index(self.n_emission()) + p
    }

    /// Index of g in θ.
    pub fn g_index(&self) -> usize {
        self.r_index(self.positions.len())
    }

    /// Index of c_j in θ.
    pub fn c_index(&self, j: usize) -> usize {
        self.g_index() + 1 + j
    }

    /// Number of solver variables.
    pub fn n_params(&self) -> usize {
        self.c_index(self.files.len())
    }

    /// Number of residuals: every file's fitted off-diagonal and diagonal cells, and the
    /// emission scale gauge.
    pub fn n_residuals(&self) -> usize {
        self.files
            .iter()
            .map(|d| d.off_diagonal.len() + d.diagonal.len())
            .sum::<usize>()
            + 1
    }

    /// The physical parameters of solver variables `theta`.
    pub fn decode(&self, theta: &[f64]) -> SeriesParameters {
        let sine2 = |t: f64| t.sin().powi(2);
        SeriesParameters {
            absorption: (0..self.n_excitation())
                .map(|i| self.a_index(i).map_or(1.0, |k| sine2(theta[k])))
                .collect(),
            emission: (0..self.n_emission())
                .map(|l| theta[self.v_index(l)].powi(2))
                .collect(),
            reflectance: (0..self.positions.len())
                .map(|p| sine2(theta[self.r_index(p)]))
                .collect(),
            yield_fraction: sine2(theta[self.g_index()]),
            concentrations: (0..self.files.len())
                .map(|j| sine2(theta[self.c_index(j)]))
                .collect(),
        }
    }

    /// Solver variables for physical parameters (clamped into range).
    pub fn encode(&self, p: &SeriesParameters) -> Vec<f64> {
        let arcsine = |x: f64| x.clamp(0.0, 1.0).sqrt().asin();
        let mut theta = vec![0.0; self.n_params()];
        for (i, a) in p.absorption.iter().enumerate() {
            if let Some(k) = self.a_index(i) {
                theta[k] = arcsine(*a);
            }
        }
        for (l, v) in p.emission.iter().enumerate() {
            theta[self.v_index(l)] = v.max(0.0).sqrt();
        }
        for (q, r) in p.reflectance.iter().enumerate() {
            theta[self.r_index(q)] = arcsine(*r);
        }
        theta[self.g_index()] = arcsine(p.yield_fraction);
        for (j, c) in p.concentrations.iter().enumerate() {
            theta[self.c_index(j)] = arcsine(*c);
        }
        theta
    }

    /// ∂(physical parameter)/∂θ, per θ index (each θ moves one physical parameter).
    fn chain(&self, theta: &[f64]) -> Vec<f64> {
        (0..self.n_params())
            .map(|k| {
                let emission = k >= self.v_index(0) && k < self.r_index(0);
                if emission {
                    2.0 * theta[k]
                } else {
                    (2.0 * theta[k]).sin()
                }
            })
            .collect()
    }

    /// N(v) for emission column values `emission` with absorption `absorption` (whose
    /// shortest absorbed wavelength enters the energy form's photon limit).
    pub fn normaliser(&self, absorption: &[f64], emission: &[f64]) -> Normaliser {
        let data = &self.files[0];
        let (sum, moment) = data.emission_sum_moment(emission);
        let moment_derivative = || -> Vec<f64> {
            data.emission_weight
                .iter()
                .zip(&data.emission_nm)
                .map(|(w, l)| w * l)
                .collect()
        };
        let (value, derivative) = match self.form {
            YieldForm::Photon => (moment, moment_derivative()),
            YieldForm::Energy => {
                let shortest = shortest_positive(absorption, &data.excitation_nm);
                if shortest.is_finite() && moment / shortest > sum {
                    let d = moment_derivative().iter().map(|x| x / shortest).collect();
                    (moment / shortest, d)
                } else {
                    (sum, data.emission_weight.clone())
                }
            }
        };
        Normaliser {
            value,
            sum,
            derivative,
        }
    }

    /// The yield of the form (energy Q = g·S/N, or photon Φ = g) and its gradient with
    /// respect to the physical parameters (θ's layout).
    pub fn yield_with_gradient(&self, p: &SeriesParameters) -> (f64, Vec<f64>) {
        let mut gradient = vec![0.0; self.n_params()];
        match self.form {
            YieldForm::Photon => {
                gradient[self.g_index()] = 1.0;
                (p.yield_fraction, gradient)
            }
            YieldForm::Energy => {
                let n = self.normaliser(&p.absorption, &p.emission);
                let g = p.yield_fraction;
                gradient[self.g_index()] = n.sum / n.value;
                for (l, (w, dn)) in self.files[0]
                    .emission_weight
                    .iter()
                    .zip(&n.derivative)
                    .enumerate()
                {
                    gradient[self.v_index(l)] = g * (w * n.value - n.sum * dn) / n.value.powi(2);
                }
                (g * n.sum / n.value, gradient)
            }
        }
    }

    /// The residuals (measured − model) of physical parameters `p`, in the order of
    /// [`SeriesModel::n_residuals`].
    pub fn residuals_of(&self, p: &SeriesParameters) -> Vec<f64> {
        let n = self.normaliser(&p.absorption, &p.emission);
        let mut r = Vec::with_capacity(self.n_residuals());
        for (j, data) in self.files.iter().enumerate() {
            let scale = p.concentrations[j] * p.yield_fraction / n.value;
            let fluorescence = |row: usize, column: usize| {
                scale * p.absorption[row] * self.row_factor[row] * p.emission[column]
            };
            r.extend(
                data.off_diagonal
                    .iter()
                    .map(|c| c.value - fluorescence(c.row, c.column)),
            );
            for (c, &q) in data.diagonal.iter().zip(&self.diagonal_index[j]) {
                let reflected =
                    (1.0 - p.concentrations[j] * p.absorption[c.row]) * p.reflectance[q];
                r.push(c.value - reflected - fluorescence(c.row, c.column));
            }
        }
        r.push(SCALE_GAUGE_WEIGHT.sqrt() * (n.sum - 1.0));
        r
    }

    /// ∂r/∂(physical parameters), columns in θ's layout (the held peak has none).
    pub fn jacobian_physical(&self, p: &SeriesParameters) -> DMatrix<f64> {
        let n = self.normaliser(&p.absorption, &p.emission);
        let mut jac = DMatrix::zeros(self.n_residuals(), self.n_params());
        let g_index = self.g_index();
        let mut row = 0;
        for (j, data) in self.files.iter().enumerate() {
            let c = p.concentrations[j];
            let c_index = self.c_index(j);
            // ∂F/∂(c_j, g, a_i, v) of the fluorescent term at (i, l), written negated.
            let fluorescent = |jac: &mut DMatrix<f64>, row: usize, i: usize, l: usize| {
                let (a, x, v) = (p.absorption[i], self.row_factor[i], p.emission[l]);
                let shape = a * x * v / n.value;
                jac[(row, c_index)] -= p.yield_fraction * shape;
                jac[(row, g_index)] -= c * shape;
                if let Some(k) = self.a_index(i) {
                    jac[(row, k)] -= c * p.yield_fraction * x * v / n.value;
                }
                let base = c * p.yield_fraction * a * x / n.value;
                for (m, dn) in n.derivative.iter().enumerate() {
                    jac[(row, self.v_index(m))] += base * v * dn / n.value;
                }
                jac[(row, self.v_index(l))] -= base;
            };
            for cell in &data.off_diagonal {
                fluorescent(&mut jac, row, cell.row, cell.column);
                row += 1;
            }
            for (cell, &q) in data.diagonal.iter().zip(&self.diagonal_index[j]) {
                fluorescent(&mut jac, row, cell.row, cell.column);
                let (a, r) = (p.absorption[cell.row], p.reflectance[q]);
                jac[(row, self.r_index(q))] -= 1.0 - c * a;
                jac[(row, c_index)] += a * r;
                if let Some(k) = self.a_index(cell.row) {
                    jac[(row, k)] += c * r;
                }
                row += 1;
            }
        }
        for (l, w) in self.files[0].emission_weight.iter().enumerate() {
            jac[(row, self.v_index(l))] = SCALE_GAUGE_WEIGHT.sqrt() * w;
        }
        jac
    }
}

impl ResidualModel for SeriesModel<'_> {
    fn residuals(&self, theta: &[f64]) -> Vec<f64> {
        self.residuals_of(&self.decode(theta))
    }

    fn jacobian(&self, theta: &[f64]) -> DMatrix<f64> {
        let mut jac = self.jacobian_physical(&self.decode(theta));
        for (k, factor) in self.chain(theta).into_iter().enumerate() {
            jac.column_mut(k).scale_mut(factor);
        }
        jac
    }
}
