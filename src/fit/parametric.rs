//! Parametric models: K fluorescent components whose absorption and emission are sums
//! of Gaussian bands, and a reflectance that is a sigmoid of a Legendre polynomial (or
//! tabulated), fitted to the matrix cells and to the colour (CIELAB) of the flat patch
//! under the scene's lights (model.md §7).
//!
//! The model on the grid is F_ij = Σk s_k·a_ik·e_jk·u_j off the diagonal, with
//! s_k = κ_k/(γ_k·S_k) as in the tabulated objective (S_k normalises e, γ_k is the photon
//! factor, κ_k the smallest feasible concentration), and d_j = (1 − Σk κ_k·a_jk)·r_j on
//! it. κ_k = sin²t_k keeps each κ in [0, 1] and r = sigmoid(p) keeps r in (0, 1); with
//! several components a stiff penalty keeps Σk κ_k·a_k ≤ 1 on the grid (components
//! absorbing in different bands may each absorb nearly all light there), and the
//! material is scaled onto the bound exactly when it is built.

use crate::colour::{Light, PatchColorimeter, Xyz, lab_jacobian};
use crate::error::Result;
use crate::material::{Fluorophore, Material, YieldForm};
use crate::parametric::{
    BandDomain, FluorophoreForms, GaussianBands, MaterialForms, PARAMS_PER_BAND, SigmoidPolynomial,
    SpectralForm, bands_value_gradient, legendre, position, sigmoid,
};
use crate::spectrum::Spectrum;

use super::data::FitData;

/// Absorption below this fraction of its peak counts as none for the photon law: a
/// Gaussian tail never reaches zero, and without a floor every band would be "absorbing"
/// down to the shortest measured wavelength.
pub const ABSORPTION_FLOOR: f64 = 1e-4;

/// Weight of the terms fixing the free heights (max a = 1, ∫e = 1 on the grid); they
/// change no fitted material.
const HEIGHT_GAUGE_WEIGHT: f64 = 1e-4;

/// Weight of the penalty on Σk κ_k·a_k > 1 (several components): stiff against the
/// residuals (cells ≤ 1), so the optimum overshoots by at most about 1e-4.
const ABSORPTION_PENALTY: f64 = 1e4;

/// Weight of the soft box keeping band centres near the measured range and widths
/// sensible: it acts only outside the box, where the data no longer pull on a band.
const BAND_BOX_PENALTY: f64 = 1.0;

/// Smallest weight of an excitation row that no chosen light reaches.
const ROW_WEIGHT_FLOOR: f64 = 0.02;

/// How the reflectance is represented.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReflectanceForm {
    /// One free sample per diagonal cell (projected onto its feasible interval).
    Tabulated,
    /// A sigmoid of a Legendre polynomial of this degree.
    Polynomial(usize),
}

/// The structure of a parametric model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelSpec {
    /// Number of fluorescent components K.
    pub components: usize,
    /// Gaussian bands of each absorption spectrum.
    pub absorption_bands: usize,
    /// Gaussian bands of each emission spectrum.
    pub emission_bands: usize,
    /// The reflectance representation.
    pub reflectance: ReflectanceForm,
    /// The axis the bands are Gaussian in.
    pub domain: BandDomain,
    /// The yield form of every component: a constant energy yield Q (the paper's form) or
    /// a constant photon yield Φ (row factor a(λi)·λi/λ̄e, model.md §3).
    pub yield_form: YieldForm,
}

/// The suffix naming the photon-yield form in model names (`gaussian:1x1+r6/photon`).
pub const PHOTON_SUFFIX: &str = "/photon";

impl ModelSpec {
    /// The model's name: `gaussian:KxB` (A = E = B bands) or `gaussian:KxA/E`, then
    /// `+rD` (sigmoid-polynomial reflectance of degree D) or `+rt` (tabulated), then
    /// `@wavelength` when the bands are Gaussian in wavelength, then `/photon` when the
    /// components have a constant photon yield (none: the energy form).
    pub fn name(&self) -> String {
        let bands = if self.absorption_bands == self.emission_bands {
            format!("{}", self.absorption_bands)
        } else {
            format!("{}/{}", self.absorption_bands, self.emission_bands)
        };
        let reflectance = match self.reflectance {
            ReflectanceForm::Tabulated => "+rt".to_string(),
            ReflectanceForm::Polynomial(d) => format!("+r{d}"),
        };
        let domain = match self.domain {
            BandDomain::Wavenumber => "",
            BandDomain::Wavelength => "@wavelength",
        };
        let form = match self.yield_form {
            YieldForm::Energy => "",
            YieldForm::Photon => PHOTON_SUFFIX,
        };
        format!(
            "gaussian:{}x{bands}{reflectance}{domain}{form}",
            self.components
        )
    }

    /// Whether component rows carry the photon factor λi/λ̄e.
    fn photon(&self) -> bool {
        self.yield_form == YieldForm::Photon
    }

    /// Solver parameters per component (bands only).
    fn component_params(&self) -> usize {
        PARAMS_PER_BAND * (self.absorption_bands + self.emission_bands)
    }

    /// Free parameters of the material the model describes (the solver has a few more:
    /// the band heights' scales, fixed by normalisation). `diagonal_samples` counts the
    /// samples of a tabulated reflectance.
    pub fn parameter_count(&self, diagonal_samples: usize) -> usize {
        let per_component = self.component_params() - 2 + 1;
        let reflectance = match self.reflectance {
            ReflectanceForm::Tabulated => diagonal_samples,
            ReflectanceForm::Polynomial(d) => d + 1,
        };
        self.components * per_component + reflectance
    }
}

/// Where each block of parameters sits in the solver vector.
#[derive(Debug, Clone, Copy)]
pub struct Layout {
    /// The model.
    pub spec: ModelSpec,
    /// Index of the first component's absorption bands.
    first_component: usize,
    /// Index of the reflectance coefficients.
    reflectance: usize,
    /// Total length.
    pub len: usize,
}

impl Layout {
    /// The layout of `spec`.
    pub fn new(spec: ModelSpec) -> Self {
        let first_component = spec.components;
        let reflectance = first_component + spec.components * spec.component_params();
        let len = reflectance
            + match spec.reflectance {
                ReflectanceForm::Tabulated => 0,
                ReflectanceForm::Polynomial(d) => d + 1,
            };
        Layout {
            spec,
            first_component,
            reflectance,
            len,
        }
    }

    /// Range of component `k`'s absorption band parameters.
    pub fn absorption(&self, k: usize) -> std::ops::Range<usize> {
        let start = self.first_component + k * self.spec.component_params();
        start..start + PARAMS_PER_BAND * self.spec.absorption_bands
    }

    /// Range of component `k`'s emission band parameters.
    pub fn emission(&self, k: usize) -> std::ops::Range<usize> {
        let start = self.absorption(k).end;
        start..start + PARAMS_PER_BAND * self.spec.emission_bands
    }

    /// Range of the reflectance coefficients (empty when tabulated).
    pub fn reflectance(&self) -> std::ops::Range<usize> {
        self.reflectance..self.len
    }

    /// κ_k = sin²t_k for every component.
    fn kappas(&self, theta: &[f64]) -> Vec<f64> {
        theta[..self.spec.components]
            .iter()
            .map(|t| t.sin().powi(2))
            .collect()
    }
}

/// The colour weights of one light on the fit grids: CIELAB of the patch, linearised at
/// the measured colour, as linear functionals of the cell residuals.
#[derive(Debug, Clone)]
struct PatchLight {
    /// ∫L·h_i over the excitation grid.
    light_weights: Vec<f64>,
    /// Per Lab channel and emission column: ∂Lab/∂(reradiated density at j).
    emitted: [Vec<f64>; 3],
    /// Per Lab channel and emission column: ∂Lab/∂(diagonal at j).
    reflected: [Vec<f64>; 3],
}

/// A diagonal position of the fit.
#[derive(Debug, Clone, Copy)]
struct DiagonalSample {
    row: usize,
    column: usize,
    /// Measured value, if the cell is measured.
    value: Option<f64>,
    /// Legendre position of its wavelength.
    x: f64,
}

/// Everything an evaluation needs, precomputed from the data, the lights and the spec.
pub struct Problem<'a> {
    /// The cells.
    pub data: &'a FitData,
    /// Parameter layout.
    pub layout: Layout,
    excitation_u: Vec<f64>,
    emission_u: Vec<f64>,
    /// u_j: e_j·u_j is the model's column value (bin width per bin, 1 per nm).
    column_factor: Vec<f64>,
    /// f_j turning a column sum into an emitted density (1/Δλ per bin, 1 per nm).
    density_factor: Vec<f64>,
    diagonal: Vec<DiagonalSample>,
    /// Index into `diagonal` for each emission column with a diagonal position.
    diagonal_of_column: Vec<Option<usize>>,
    /// Weight of each excitation row's residuals (how much light the scene sends there).
    row_weight: Vec<f64>,
    /// The off-diagonal cells, dense (row-major, excitation × emission): 1 where a cell
    /// is fitted, 0 elsewhere, and the measured values (0 elsewhere). The objective runs
    /// over whole rows, which vectorises; scattered cell lists did not.
    cell_mask: Vec<f64>,
    cell_value: Vec<f64>,
    patches: Vec<PatchLight>,
    colour_weight: f64,
    /// The reflectance's Legendre support (nm).
    pub reflectance_support: [f64; 2],
}

/// The model's quantities on the grids for one parameter vector.
#[derive(Debug, Clone)]
pub struct GridModel {
    /// κ_k.
    pub kappa: Vec<f64>,
    /// a_ik normalised to max 1 on the excitation grid, per component.
    pub absorption: Vec<Vec<f64>>,
    /// G_k: the unnormalised absorption peak on the grid, per component.
    pub absorption_peak: Vec<f64>,
    /// Index of the absorption peak.
    pub peak_index: Vec<usize>,
    /// e_jk (unnormalised density), per component.
    pub emission: Vec<Vec<f64>>,
    /// S_k = Σ e_j·Δλ_j.
    pub normaliser: Vec<f64>,
    /// λ̄e_k.
    pub emission_mean_nm: Vec<f64>,
    /// λmin_k (absorption above [`ABSORPTION_FLOOR`]).
    pub shortest_absorbed_nm: Vec<f64>,
    /// γ_k: max(1, λ̄e/λmin) in the energy form (c = κ is the smallest feasible c =
    /// k·γ), 1 in the photon form (c = k, Φ = 1).
    pub photon_factor: Vec<f64>,
    /// s_k = κ_k/(γ_k·S_k).
    pub scale: Vec<f64>,
    /// x_ik: the row factor beside a_ik on the excitation grid, 1 in the energy form and
    /// λi/λ̄e in the photon form (the energy yield over Φ).
    pub excitation_factor: Vec<Vec<f64>>,
    /// m_ik = max(1, x_ik): the diagonal's cap is 1 − Σk κ_k·a_ik·m_ik (r ≤ 1 and, where
    /// a photon-form component emits more energy than it absorbs, ρ ≤ 1).
    pub cap_factor: Vec<Vec<f64>>,
    /// r at each diagonal sample (polynomial reflectance only).
    pub reflectance: Vec<f64>,
    /// ∂g/∂(band parameters) of the unnormalised absorption at each excitation sample,
    /// row-major (sample × parameter), per component: the adjoint reuses them.
    absorption_jacobian: Vec<Vec<f64>>,
    /// The same for the emission at each emission sample.
    emission_jacobian: Vec<Vec<f64>>,
}

impl<'a> Problem<'a> {
    /// Prepares the fit of `spec` to `data`. `lights` weight the rows by how much light
    /// reaches them and, with `reference` (the measured patch's XYZ under each light),
    /// give the colour term: ½·`colour_weight`·Σ ΔE76², linearised at the reference.
    pub fn new(
        data: &'a FitData,
        spec: ModelSpec,
        lights: &[Light],
        reference: &[Xyz],
        colour_weight: f64,
    ) -> Self {
        let domain = spec.domain;
        let widths = &data.emission_bin_widths;
        let column_factor: Vec<f64> = widths
            .iter()
            .zip(&data.emission_weight)
            .map(|(w, ew)| w / ew)
            .collect();
        let density_factor: Vec<f64> = column_factor.iter().map(|u| 1.0 / u).collect();
        let diagonal_nm: Vec<f64> = data
            .diagonal_positions
            .iter()
            .map(|&(_, j)| data.emission_nm[j])
            .collect();
        let reflectance_support = [
            diagonal_nm.first().copied().unwrap_or(380.0),
            diagonal_nm.last().copied().unwrap_or(780.0),
        ];
        let mut diagonal: Vec<DiagonalSample> = data
            .diagonal_positions
            .iter()
            .map(|&(row, column)| DiagonalSample {
                row,
                column,
                value: None,
                x: position(reflectance_support, data.emission_nm[column]),
            })
            .collect();
        for c in &data.diagonal {
            if let Some(d) = diagonal
                .iter_mut()
                .find(|d| d.row == c.row && d.column == c.column)
            {
                d.value = Some(c.value);
            }
        }
        let mut diagonal_of_column = vec![None; data.n_emission()];
        for (p, d) in diagonal.iter().enumerate() {
            diagonal_of_column[d.column] = Some(p);
        }
        let mut row_weight = vec![0.0f64; data.n_excitation()];
        let patches: Vec<PatchLight> = lights
            .iter()
            .zip(reference)
            .map(|(light, xyz)| {
                let pc = PatchColorimeter::cached(light, &data.excitation_nm, &data.emission_nm);
                let (light_weights, reflected, emitted, _, scale) = pc.weights();
                let peak = light_weights.iter().cloned().fold(0.0, f64::max);
                if peak > 0.0 {
                    for (w, lw) in row_weight.iter_mut().zip(light_weights) {
                        *w = w.max(lw / peak);
                    }
                }
                let jacobian = lab_jacobian(*xyz, pc.white);
                let project = |weights: &[Xyz], channel: usize| -> Vec<f64> {
                    weights
                        .iter()
                        .map(|w| scale * (0..3).map(|x| jacobian[channel][x] * w[x]).sum::<f64>())
                        .collect()
                };
                PatchLight {
                    light_weights: light_weights.to_vec(),
                    emitted: [0, 1, 2].map(|c| project(emitted, c)),
                    reflected: [0, 1, 2].map(|c| project(reflected, c)),
                }
            })
            .collect();
        if lights.is_empty() {
            row_weight.iter_mut().for_each(|w| *w = 1.0);
        }
        let row_weight = row_weight.iter().map(|w| w.max(ROW_WEIGHT_FLOOR)).collect();
        let n_em = data.n_emission();
        let mut cell_mask = vec![0.0; data.n_excitation() * n_em];
        let mut cell_value = vec![0.0; data.n_excitation() * n_em];
        for c in &data.off_diagonal {
            cell_mask[c.row * n_em + c.column] = 1.0;
            cell_value[c.row * n_em + c.column] = c.value;
        }
        Problem {
            data,
            layout: Layout::new(spec),
            excitation_u: data
                .excitation_nm
                .iter()
                .map(|&l| domain.coordinate(l))
                .collect(),
            emission_u: data
                .emission_nm
                .iter()
                .map(|&l| domain.coordinate(l))
                .collect(),
            column_factor,
            density_factor,
            diagonal,
            diagonal_of_column,
            row_weight,
            cell_mask,
            cell_value,
            patches,
            colour_weight,
            reflectance_support,
        }
    }

    /// The model's grid quantities at `theta`.
    pub fn grid_model(&self, theta: &[f64]) -> GridModel {
        let layout = &self.layout;
        let data = self.data;
        let k_count = layout.spec.components;
        let mut m = GridModel {
            kappa: layout.kappas(theta),
            absorption: Vec::with_capacity(k_count),
            absorption_peak: Vec::with_capacity(k_count),
            peak_index: Vec::with_capacity(k_count),
            emission: Vec::with_capacity(k_count),
            normaliser: Vec::with_capacity(k_count),
            emission_mean_nm: Vec::with_capacity(k_count),
            shortest_absorbed_nm: Vec::with_capacity(k_count),
            photon_factor: Vec::with_capacity(k_count),
            scale: Vec::with_capacity(k_count),
            excitation_factor: Vec::with_capacity(k_count),
            cap_factor: Vec::with_capacity(k_count),
            reflectance: Vec::new(),
            absorption_jacobian: Vec::with_capacity(k_count),
            emission_jacobian: Vec::with_capacity(k_count),
        };
        for k in 0..k_count {
            let ap = &theta[layout.absorption(k)];
            let ep = &theta[layout.emission(k)];
            let mut absorption_jacobian = vec![0.0; self.excitation_u.len() * ap.len()];
            let raw: Vec<f64> = self
                .excitation_u
                .iter()
                .zip(absorption_jacobian.chunks_exact_mut(ap.len().max(1)))
                .map(|(&u, g)| bands_value_gradient(ap, u, g))
                .collect();
            let (peak_index, peak) =
                raw.iter().enumerate().fold(
                    (0, f64::MIN),
                    |best, (i, &v)| if v > best.1 { (i, v) } else { best },
                );
            let peak = peak.max(1e-300);
            let absorption: Vec<f64> = raw.iter().map(|v| v / peak).collect();
            let mut emission_jacobian = vec![0.0; self.emission_u.len() * ep.len()];
            let emission: Vec<f64> = self
                .emission_u
                .iter()
                .zip(emission_jacobian.chunks_exact_mut(ep.len().max(1)))
                .map(|(&u, g)| bands_value_gradient(ep, u, g))
                .collect();
            m.absorption_jacobian.push(absorption_jacobian);
            m.emission_jacobian.push(emission_jacobian);
            let (mut normaliser, mut moment) = (0.0, 0.0);
            for ((e, w), l) in emission
                .iter()
                .zip(&data.emission_bin_widths)
                .zip(&data.emission_nm)
            {
                normaliser += e * w;
                moment += e * w * l;
            }
            let normaliser = normaliser.max(1e-300);
            let mean = moment / normaliser;
            let shortest = absorption
                .iter()
                .position(|&a| a >= ABSORPTION_FLOOR)
                .map(|i| data.excitation_nm[i.saturating_sub(1)])
                .unwrap_or(data.excitation_nm[0]);
            let photon = layout.spec.photon();
            let photon_factor = if photon {
                1.0
            } else {
                (mean / shortest).max(1.0)
            };
            m.scale.push(m.kappa[k] / (photon_factor * normaliser));
            let excitation_factor: Vec<f64> = if photon {
                data.excitation_nm.iter().map(|l| l / mean).collect()
            } else {
                vec![1.0; data.excitation_nm.len()]
            };
            m.cap_factor
                .push(excitation_factor.iter().map(|x| x.max(1.0)).collect());
            m.excitation_factor.push(excitation_factor);
            m.absorption.push(absorption);
            m.absorption_peak.push(peak);
            m.peak_index.push(peak_index);
            m.emission.push(emission);
            m.normaliser.push(normaliser);
            m.emission_mean_nm.push(mean);
            m.shortest_absorbed_nm.push(shortest);
            m.photon_factor.push(photon_factor);
        }
        if let ReflectanceForm::Polynomial(_) = layout.spec.reflectance {
            let coefficients = &theta[layout.reflectance()];
            m.reflectance = self
                .diagonal
                .iter()
                .map(|d| {
                    let mut p = 0.0;
                    legendre(d.x, coefficients.len(), |n, pn| p += coefficients[n] * pn);
                    sigmoid(p)
                })
                .collect();
        }
        m
    }

    /// Σk κ_k·a_k·m_k at diagonal sample `d`: one minus the diagonal's cap (Σk κ_k·a_k
    /// in the energy form).
    fn absorbed(&self, m: &GridModel, d: &DiagonalSample) -> f64 {
        (0..m.kappa.len())
            .map(|k| m.kappa[k] * m.absorption[k][d.row] * m.cap_factor[k][d.row])
            .sum()
    }

    /// The fluorescent model value of cell (i, j).
    fn fluorescence(&self, m: &GridModel, i: usize, j: usize) -> f64 {
        let u = self.column_factor[j];
        (0..m.kappa.len())
            .map(|k| {
                m.scale[k] * m.absorption[k][i] * m.excitation_factor[k][i] * m.emission[k][j] * u
            })
            .sum()
    }

    /// The diagonal d_j at sample `p` and, for a tabulated reflectance, how it was
    /// projected (`None` for a polynomial reflectance).
    pub fn diagonal_value(&self, m: &GridModel, p: usize) -> (f64, Option<Projection>) {
        let d = &self.diagonal[p];
        let cap = 1.0 - self.absorbed(m, d);
        match self.layout.spec.reflectance {
            ReflectanceForm::Polynomial(_) => (cap * m.reflectance[p], None),
            ReflectanceForm::Tabulated => {
                let Some(value) = d.value else {
                    return (f64::NAN, Some(Projection::Unmeasured));
                };
                let raw = value - self.fluorescence(m, d.row, d.column);
                if raw < 0.0 {
                    (0.0, Some(Projection::AtZero))
                } else if raw > cap {
                    (cap, Some(Projection::AtCap))
                } else {
                    (raw, Some(Projection::Free))
                }
            }
        }
    }

    /// The objective and its gradient.
    // The adjoint loops index several parallel per-component arrays by the same sample.
    #[allow(clippy::needless_range_loop)]
    pub fn cost_gradient(&self, theta: &[f64]) -> (f64, Vec<f64>) {
        let data = self.data;
        let layout = &self.layout;
        let m = self.grid_model(theta);
        let k_count = m.kappa.len();
        let (n_ex, n_em) = (data.n_excitation(), data.n_emission());
        let n_lights = self.patches.len();
        // The model matrix, dense: F_ij = Σk s_k·a_ik·(e_jk·u_j).
        let weighted_emission: Vec<Vec<f64>> = m
            .emission
            .iter()
            .map(|e| {
                e.iter()
                    .zip(&self.column_factor)
                    .map(|(e, u)| e * u)
                    .collect()
            })
            .collect();
        let mut model = vec![0.0; n_ex * n_em];
        for k in 0..k_count {
            for (i, row) in model.chunks_exact_mut(n_em).enumerate() {
                let sa = m.scale[k] * m.absorption[k][i] * m.excitation_factor[k][i];
                for (f, ue) in row.iter_mut().zip(&weighted_emission[k]) {
                    *f += sa * ue;
                }
            }
        }
        // Residuals (0 outside the cells), and the patch rows they add up to.
        let residual: Vec<f64> = self
            .cell_value
            .iter()
            .zip(&self.cell_mask)
            .zip(&model)
            .map(|((v, mask), f)| mask * (v - f))
            .collect();
        let diag: Vec<(f64, Option<Projection>)> = (0..self.diagonal.len())
            .map(|p| {
                let (d, projection) = self.diagonal_value(&m, p);
                let s = &self.diagonal[p];
                let residual = match (s.value, projection) {
                    (None, _) | (_, Some(Projection::Free)) => 0.0,
                    (Some(v), _) => v - model[s.row * n_em + s.column] - d,
                };
                (residual, projection)
            })
            .collect();
        // Column sums Σ_i L_i·r_ij per light, then ΔLab per light.
        let mut column_sum = vec![0.0; n_lights * n_em];
        for (i, row) in residual.chunks_exact(n_em).enumerate() {
            for (light, sums) in self.patches.iter().zip(column_sum.chunks_exact_mut(n_em)) {
                let w = light.light_weights[i];
                for (s, r) in sums.iter_mut().zip(row) {
                    *s += w * r;
                }
            }
        }
        let mut patch = vec![0.0; n_lights * 3];
        for (l, light) in self.patches.iter().enumerate() {
            for channel in 0..3 {
                let mut v = 0.0;
                for j in 0..n_em {
                    v += light.emitted[channel][j]
                        * self.density_factor[j]
                        * column_sum[l * n_em + j];
                    if let Some(p) = self.diagonal_of_column[j] {
                        v += light.reflected[channel][j] * diag[p].0;
                    }
                }
                patch[l * 3 + channel] = v;
            }
        }
        let mut cost = 0.0;
        for (row, w) in residual.chunks_exact(n_em).zip(&self.row_weight) {
            cost += 0.5 * w * row.iter().map(|r| r * r).sum::<f64>();
        }
        for (s, (r, _)) in self.diagonal.iter().zip(&diag) {
            cost += 0.5 * self.row_weight[s.row] * r * r;
        }
        cost += 0.5 * self.colour_weight * patch.iter().map(|p| p * p).sum::<f64>();
        // The colour term's pull on residuals of column j: q (reradiated) and h (diagonal).
        let mut q = vec![0.0; n_lights * n_em];
        let mut h = vec![0.0; n_lights * n_em];
        for (l, light) in self.patches.iter().enumerate() {
            for j in 0..n_em {
                let (mut qe, mut hr) = (0.0, 0.0);
                for channel in 0..3 {
                    let p = self.colour_weight * patch[l * 3 + channel];
                    qe += p * light.emitted[channel][j];
                    hr += p * light.reflected[channel][j];
                }
                q[l * n_em + j] = qe * self.density_factor[j];
                h[l * n_em + j] = hr;
            }
        }

        // Adjoints: ∂cost/∂F for every cell (F̄ = −δ), gathered densely, then through
        // the factors (two matrix-vector products per component).
        let mut scale_bar = vec![0.0; k_count];
        let mut a_bar = vec![vec![0.0; n_ex]; k_count];
        let mut e_bar = vec![vec![0.0; n_em]; k_count];
        let mut kappa_bar = vec![0.0; k_count];
        // ∂cost/∂λ̄e_k through the photon form's row and cap factors.
        let mut mean_bar = vec![0.0; k_count];
        let mut r_bar = vec![0.0; self.diagonal.len()];
        let mut f_bar = vec![0.0; n_ex * n_em];
        let mut pull = vec![0.0; n_em];
        for (i, ((f_row, r_row), mask_row)) in f_bar
            .chunks_exact_mut(n_em)
            .zip(residual.chunks_exact(n_em))
            .zip(self.cell_mask.chunks_exact(n_em))
            .enumerate()
        {
            // δ_ij = w_i·r_ij + Σ_l L_li·q_lj on the cells.
            pull.iter_mut().for_each(|p| *p = 0.0);
            for (light, q_row) in self.patches.iter().zip(q.chunks_exact(n_em)) {
                let w = light.light_weights[i];
                for (p, qv) in pull.iter_mut().zip(q_row) {
                    *p += w * qv;
                }
            }
            let w = self.row_weight[i];
            for (((fb, r), mask), p) in f_row.iter_mut().zip(r_row).zip(mask_row).zip(&pull) {
                *fb -= mask * (w * r + p);
            }
        }
        for (p, (s, (r, projection))) in self.diagonal.iter().zip(&diag).enumerate() {
            if s.value.is_none() || *projection == Some(Projection::Free) {
                continue;
            }
            let mut delta = self.row_weight[s.row] * r;
            for l in 0..n_lights {
                delta += h[l * n_em + s.column];
            }
            // r = M − F − d: F̄ = −δ; d̄ = −δ.
            f_bar[s.row * n_em + s.column] -= delta;
            let d_bar = -delta;
            let absorbed_bar = match projection {
                None => {
                    let cap = 1.0 - self.absorbed(&m, s);
                    r_bar[p] += d_bar * cap;
                    -d_bar * m.reflectance[p]
                }
                Some(Projection::AtCap) => -d_bar,
                _ => 0.0,
            };
            for k in 0..k_count {
                let (a, cf) = (m.absorption[k][s.row], m.cap_factor[k][s.row]);
                kappa_bar[k] += absorbed_bar * a * cf;
                a_bar[k][s.row] += absorbed_bar * m.kappa[k] * cf;
                if m.excitation_factor[k][s.row] > 1.0 {
                    // m = λ/λ̄e: ∂m/∂λ̄e = −m/λ̄e.
                    mean_bar[k] -= absorbed_bar * m.kappa[k] * a * cf / m.emission_mean_nm[k];
                }
            }
        }

        let mut column_adjoint = vec![0.0; n_em];
        for k in 0..k_count {
            column_adjoint.iter_mut().for_each(|v| *v = 0.0);
            for (i, row) in f_bar.chunks_exact(n_em).enumerate() {
                let x = m.excitation_factor[k][i];
                let a = m.absorption[k][i] * x;
                let mut t = 0.0;
                for ((fb, ue), v) in row
                    .iter()
                    .zip(&weighted_emission[k])
                    .zip(column_adjoint.iter_mut())
                {
                    t += fb * ue;
                    *v += fb * a;
                }
                a_bar[k][i] += m.scale[k] * x * t;
                scale_bar[k] += a * t;
                if self.layout.spec.photon() {
                    // x = λi/λ̄e: ∂x/∂λ̄e = −x/λ̄e.
                    mean_bar[k] -= m.scale[k] * a * t / m.emission_mean_nm[k];
                }
            }
            for ((eb, v), u) in e_bar[k]
                .iter_mut()
                .zip(&column_adjoint)
                .zip(&self.column_factor)
            {
                *eb += m.scale[k] * u * v;
            }
        }

        // Σk κ_k·a_ik·m_ik ≤ 1 on the excitation grid (several components, or the photon
        // form, whose m exceeds 1 where a component absorbs above its mean emission).
        if k_count > 1 || self.layout.spec.photon() {
            for i in 0..n_ex {
                let excess: f64 = (0..k_count)
                    .map(|k| m.kappa[k] * m.absorption[k][i] * m.cap_factor[k][i])
                    .sum::<f64>()
                    - 1.0;
                if excess > 0.0 {
                    cost += 0.5 * ABSORPTION_PENALTY * excess * excess;
                    for k in 0..k_count {
                        let (a, cf) = (m.absorption[k][i], m.cap_factor[k][i]);
                        let p = ABSORPTION_PENALTY * excess;
                        kappa_bar[k] += p * a * cf;
                        a_bar[k][i] += p * m.kappa[k] * cf;
                        if m.excitation_factor[k][i] > 1.0 {
                            mean_bar[k] -= p * m.kappa[k] * a * cf / m.emission_mean_nm[k];
                        }
                    }
                }
            }
        }
        let mut gradient = vec![0.0; layout.len];
        for k in 0..k_count {
            // s = κ/(γ·S): through κ, S and γ (γ = λ̄e/λmin when photon-limited).
            kappa_bar[k] += scale_bar[k] / (m.photon_factor[k] * m.normaliser[k]);
            let s = m.scale[k];
            let photon_limited = !self.layout.spec.photon()
                && m.emission_mean_nm[k] / m.shortest_absorbed_nm[k] > 1.0;
            let gauge_s = m.normaliser[k] - 1.0;
            for j in 0..n_em {
                let w = data.emission_bin_widths[j];
                let mut d_scale = -s * w / m.normaliser[k];
                // ∂λ̄e/∂e_j = w_j·(λ_j − λ̄e)/S.
                let d_mean = w * (data.emission_nm[j] - m.emission_mean_nm[k]) / m.normaliser[k];
                if photon_limited {
                    let d_gamma = d_mean / m.shortest_absorbed_nm[k];
                    d_scale -= s * d_gamma / m.photon_factor[k];
                }
                e_bar[k][j] += scale_bar[k] * d_scale
                    + mean_bar[k] * d_mean
                    + HEIGHT_GAUGE_WEIGHT * gauge_s * w;
            }
            // a = g/G with G the grid peak.
            let peak = m.absorption_peak[k];
            let mut g_bar: Vec<f64> = a_bar[k].iter().map(|ab| ab / peak).collect();
            let through_peak: f64 = a_bar[k]
                .iter()
                .zip(&m.absorption[k])
                .map(|(ab, a)| ab * a)
                .sum::<f64>()
                / peak;
            g_bar[m.peak_index[k]] += -through_peak + HEIGHT_GAUGE_WEIGHT * (peak - 1.0);
            let ar = layout.absorption(k);
            for (gb, g) in g_bar
                .iter()
                .zip(m.absorption_jacobian[k].chunks_exact(ar.len().max(1)))
            {
                for (t, gp) in gradient[ar.clone()].iter_mut().zip(g) {
                    *t += gb * gp;
                }
            }
            let er = layout.emission(k);
            for (eb, g) in e_bar[k]
                .iter()
                .zip(m.emission_jacobian[k].chunks_exact(er.len().max(1)))
            {
                for (t, gp) in gradient[er.clone()].iter_mut().zip(g) {
                    *t += eb * gp;
                }
            }
            cost += 0.5 * HEIGHT_GAUGE_WEIGHT * (gauge_s * gauge_s + (peak - 1.0).powi(2));
        }
        // κ_k = sin²t_k.
        for k in 0..k_count {
            gradient[k] = kappa_bar[k] * (2.0 * theta[k]).sin();
        }
        cost += self.band_penalty(theta, &mut gradient);
        if let ReflectanceForm::Polynomial(_) = layout.spec.reflectance {
            let range = layout.reflectance();
            let count = range.len();
            for (p, s) in self.diagonal.iter().enumerate() {
                if r_bar[p] == 0.0 {
                    continue;
                }
                let r = m.reflectance[p];
                let dp = r_bar[p] * r * (1.0 - r);
                legendre(s.x, count, |n, pn| gradient[range.start + n] += dp * pn);
            }
        }
        (cost, gradient)
    }

    /// Moves band parameters into the box the objective penalises leaving (for starts).
    pub fn clamp_to_box(&self, theta: &mut [f64]) {
        for (n, (low, high)) in self.band_box() {
            let p = &mut theta[n];
            *p = if p.is_finite() {
                p.clamp(low, high)
            } else {
                0.5 * (low + high)
            };
        }
    }

    /// (parameter index, lower, upper) for every band parameter: centres within half the
    /// measured span beyond its ends, widths between 1/200 and twice the span, heights
    /// below e⁶.
    fn band_box(&self) -> Vec<(usize, (f64, f64))> {
        let mut boxes = Vec::new();
        for k in 0..self.layout.spec.components {
            for (range, grid) in [
                (self.layout.absorption(k), &self.excitation_u),
                (self.layout.emission(k), &self.emission_u),
            ] {
                let lo = grid.iter().cloned().fold(f64::INFINITY, f64::min);
                let hi = grid.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                let span = (hi - lo).max(1e-6);
                // A band narrower than half the grid step falls between samples: the data
                // see it as a spike on one row or column (an instrument artefact fits it
                // as well as a fluorophore), so widths stay above that.
                let narrowest = (0.5 * median_step(grid)).max(span / 200.0);
                let bounds = [
                    (-30.0, 6.0),
                    (lo - 0.5 * span, hi + 0.5 * span),
                    (narrowest.ln(), (2.0 * span).ln()),
                ];
                for band in range.step_by(PARAMS_PER_BAND) {
                    for (n, b) in bounds.iter().enumerate() {
                        boxes.push((band + n, *b));
                    }
                }
            }
        }
        boxes
    }

    /// The soft box on band parameters: centres within half the measured span beyond
    /// its ends, widths between half the median grid step (at least 1/200 of the span)
    /// and twice the span, heights below e⁶. Adds its
    /// gradient to `gradient` and returns its cost.
    fn band_penalty(&self, theta: &[f64], gradient: &mut [f64]) -> f64 {
        let mut cost = 0.0;
        for (n, (low, high)) in self.band_box() {
            let p = theta[n];
            let outside = if p < low {
                p - low
            } else if p > high {
                p - high
            } else {
                continue;
            };
            cost += 0.5 * BAND_BOX_PENALTY * outside * outside;
            gradient[n] += BAND_BOX_PENALTY * outside;
        }
        cost
    }

    /// The matrix-residual part of the cost alone (unweighted ½Σr² over the data cells),
    /// for the information criterion.
    pub fn residual_sum_of_squares(&self, theta: &[f64]) -> f64 {
        let m = self.grid_model(theta);
        let mut rss = 0.0;
        for c in &self.data.off_diagonal {
            rss += (c.value - self.fluorescence(&m, c.row, c.column)).powi(2);
        }
        for p in 0..self.diagonal.len() {
            let s = &self.diagonal[p];
            if let Some(v) = s.value {
                let (d, _) = self.diagonal_value(&m, p);
                if d.is_finite() {
                    rss += (v - self.fluorescence(&m, s.row, s.column) - d).powi(2);
                }
            }
        }
        rss
    }

    /// Number of residuals the information criterion counts.
    pub fn residual_count(&self) -> usize {
        self.data.off_diagonal.len() + self.data.diagonal.len()
    }

    /// The central-difference gradient of the cost (to test [`Problem::cost_gradient`]).
    pub fn numerical_gradient(&self, theta: &[f64], step: f64) -> Vec<f64> {
        (0..theta.len())
            .map(|n| {
                let mut plus = theta.to_vec();
                let mut minus = theta.to_vec();
                plus[n] += step;
                minus[n] -= step;
                (self.cost_gradient(&plus).0 - self.cost_gradient(&minus).0) / (2.0 * step)
            })
            .collect()
    }

    /// The diagonal sample positions (row, column) in order.
    pub fn diagonal_positions(&self) -> Vec<(usize, usize)> {
        self.diagonal.iter().map(|d| (d.row, d.column)).collect()
    }
}

/// Step (nm) of the tabulation a parametric material carries beside its forms.
pub const TABULATION_STEP_NM: f64 = 1.0;

/// The measurement grid refined to [`TABULATION_STEP_NM`] (grid points kept).
pub fn fine_grid(coarse: &[f64]) -> Vec<f64> {
    let (Some(&first), Some(&last)) = (coarse.first(), coarse.last()) else {
        return Vec::new();
    };
    let steps = ((last - first) / TABULATION_STEP_NM).floor() as usize;
    let mut grid: Vec<f64> = (0..=steps)
        .map(|n| first + n as f64 * TABULATION_STEP_NM)
        .chain(coarse.iter().copied())
        .collect();
    grid.sort_by(f64::total_cmp);
    grid.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    grid
}

impl Problem<'_> {
    /// The material `theta` stands for: forms, their fine tabulation, c at its smallest
    /// feasible value per component (the gauge of the tabulated fit), and Q = k/c.
    pub fn material(&self, theta: &[f64], name: &str) -> Result<Material> {
        let data = self.data;
        let spec = self.layout.spec;
        let gm = self.grid_model(theta);
        let excitation_fine = fine_grid(&data.excitation_nm);
        let emission_fine = fine_grid(&data.emission_nm);
        let mut fluorophores = Vec::with_capacity(spec.components);
        let mut forms = Vec::with_capacity(spec.components);
        for k in 0..spec.components {
            // Absorption: normalise on the fit grid, trim the support where the bands fall
            // below the floor (the photon law's λmin), renormalise on the fine grid.
            let mut absorption = GaussianBands::from_params(
                spec.domain,
                [
                    data.excitation_nm[0],
                    *data.excitation_nm.last().unwrap_or(&0.0),
                ],
                &theta[self.layout.absorption(k)],
            );
            absorption.scale(1.0 / gm.absorption_peak[k]);
            if let Some(first) = gm.absorption[k].iter().position(|&a| a >= ABSORPTION_FLOOR) {
                absorption.support_nm[0] = data.excitation_nm[first];
            }
            let fine_peak = excitation_fine
                .iter()
                .map(|&l| absorption.eval(l))
                .fold(0.0, f64::max)
                .max(1e-300);
            absorption.scale(1.0 / fine_peak);
            let absorption = SpectralForm::GaussianBands(absorption);
            let what = format!("fluorophores[{k}]");
            let absorption_samples =
                absorption.tabulate(&excitation_fine, &format!("{what}.absorption"))?;
            // Emission: ∫e = 1 on the fine grid.
            let mut emission = GaussianBands::from_params(
                spec.domain,
                [
                    data.emission_nm[0],
                    *data.emission_nm.last().unwrap_or(&0.0),
                ],
                &theta[self.layout.emission(k)],
            );
            let raw = SpectralForm::GaussianBands(emission.clone())
                .tabulate(&emission_fine, &format!("{what}.emission"))?;
            let integral = raw.integral().max(1e-300);
            emission.scale(1.0 / integral);
            let emission = SpectralForm::GaussianBands(emission);
            let emission_samples =
                emission.tabulate(&emission_fine, &format!("{what}.emission"))?;
            // c·a is what the fit determined: c = κ·(fine peak); k = c·Q keeps the
            // fitted product: k = (κ/γ)·peak·∫/S.
            let concentration = (gm.kappa[k] * fine_peak).min(1.0);
            // (γ = 1 in the photon form: c = k, Φ = 1.)
            let k_product =
                gm.kappa[k] / gm.photon_factor[k] * fine_peak * integral / gm.normaliser[k];
            let mut absorption_samples = absorption_samples;
            // Rounding of the renormalisation may leave the peak a hair above 1.
            absorption_samples
                .value
                .iter_mut()
                .for_each(|a| *a = a.min(1.0));
            let mut fluorophore = Fluorophore {
                concentration,
                quantum_yield: 0.0,
                yield_form: spec.yield_form,
                concentration_range: None,
                absorption: absorption_samples,
                emission: emission_samples,
            };
            let limit = yield_limit(&fluorophore);
            fluorophore.quantum_yield = if concentration > 0.0 {
                (k_product / concentration).min(limit)
            } else {
                0.0
            };
            fluorophores.push(fluorophore);
            forms.push(FluorophoreForms {
                absorption,
                emission,
            });
        }
        // The penalty lets Σ c·a overshoot 1 by ~1e-4, and the fine grid sees peaks the
        // fit grid missed: scale the concentrations onto the bound (k = c·Q is kept where
        // the yield allows).
        let mut wavelengths: Vec<f64> = excitation_fine.clone();
        wavelengths.extend(&emission_fine);
        let means: Vec<f64> = fluorophores.iter().map(|f| f.emission_mean_nm()).collect();
        // Σ c·a·m with m = max(1, λ/λ̄e) in the photon form: where the energy yield
        // exceeds Φ the emitted energy must fit under 1 too.
        let capped_by = |fluorophores: &[Fluorophore], l: f64| -> f64 {
            fluorophores
                .iter()
                .zip(&means)
                .map(|(f, &mean)| {
                    f.concentration
                        * f.absorption.eval_zero_outside(l)
                        * f.excitation_factor_with_mean(l, mean).max(1.0)
                })
                .sum()
        };
        let total_peak = wavelengths
            .iter()
            .map(|&l| capped_by(&fluorophores, l))
            .fold(0.0, f64::max);
        if total_peak > 1.0 {
            for f in &mut fluorophores {
                let k_product = f.k();
                f.concentration /= total_peak;
                f.quantum_yield = (k_product / f.concentration).min(yield_limit(f));
            }
        }
        // Reflectance.
        let diagonal_nm: Vec<f64> = self
            .diagonal
            .iter()
            .map(|d| data.emission_nm[d.column])
            .collect();
        let absorbed_by = |l: f64| -> f64 {
            fluorophores
                .iter()
                .map(|f| f.concentration * f.absorption.eval_zero_outside(l))
                .sum()
        };
        let (reflectance, reflectance_form) = match spec.reflectance {
            ReflectanceForm::Polynomial(_) => {
                let form = SpectralForm::SigmoidPolynomial(SigmoidPolynomial {
                    support_nm: self.reflectance_support,
                    coefficients: theta[self.layout.reflectance()].to_vec(),
                });
                let mut samples = form.tabulate(&fine_grid(&diagonal_nm), "reflectance")?;
                if spec.photon() {
                    // The fit's diagonal is d = (1 − Σκ·a·m)·σ(p): r = d/(1 − Σc·a) is the
                    // sigmoid only where no component absorbs above its mean emission.
                    for (r, &l) in samples.value.iter_mut().zip(&samples.wavelength_nm) {
                        let transmitted = 1.0 - absorbed_by(l);
                        if transmitted > 0.0 {
                            *r = (*r * (1.0 - capped_by(&fluorophores, l)) / transmitted)
                                .clamp(0.0, 1.0);
                        }
                    }
                    let agrees = form
                        .agreement(
                            &samples.wavelength_nm,
                            &samples.value,
                            0.5 * crate::check::FORM_TOLERANCE,
                        )
                        .is_none_or(|a| a.worst <= 0.5 * crate::check::FORM_TOLERANCE);
                    let form = agrees.then_some(form);
                    (samples, form)
                } else {
                    (samples, Some(form))
                }
            }
            ReflectanceForm::Tabulated => {
                let mut values: Vec<f64> = (0..self.diagonal.len())
                    .map(|p| self.diagonal_value(&gm, p).0)
                    .collect();
                let unbounded = vec![f64::INFINITY; values.len()];
                super::data::fill_missing(&mut values, &diagonal_nm, &unbounded, name)?;
                let r = values
                    .iter()
                    .zip(&diagonal_nm)
                    .map(|(d, &l)| {
                        let transmitted = 1.0 - absorbed_by(l);
                        if transmitted > 0.0 {
                            (d / transmitted).clamp(0.0, 1.0)
                        } else {
                            0.0
                        }
                    })
                    .collect();
                (Spectrum::new(diagonal_nm.clone(), r, "reflectance")?, None)
            }
        };
        let mut material = Material::new(name.to_string(), reflectance, fluorophores);
        let absorbed_by = |l: f64| material.absorbed(l);
        // Feasible interval of each c with the others held: c ≥ k·γ, c·a ≤ 1 − d − Σ others.
        let ranges: Vec<[f64; 2]> = (0..material.fluorophores.len())
            .map(|k| {
                let f = &material.fluorophores[k];
                let mut upper: f64 = 1.0;
                for &l in &diagonal_nm {
                    let a = f.absorption.eval_zero_outside(l);
                    if a > 0.0 {
                        let others = absorbed_by(l) - f.concentration * a;
                        upper = upper.min((1.0 - material.diagonal(l) - others) / a);
                    }
                }
                [f.concentration, upper.max(f.concentration)]
            })
            .collect();
        for (f, range) in material.fluorophores.iter_mut().zip(ranges) {
            f.concentration_range = Some(range);
        }
        material.forms = Some(MaterialForms {
            model: spec.name(),
            reflectance: reflectance_form,
            fluorophores: forms,
        });
        material.conservation = Some(material.conservation_margins());
        Ok(material)
    }
}

/// The largest yield of a fluorophore's form in the gauge of the smallest feasible c: Φ ≤ 1
/// in the photon form; Q ≤ min(1, λmin/λ̄e) in the energy form (photon conservation).
fn yield_limit(f: &Fluorophore) -> f64 {
    match f.yield_form {
        YieldForm::Photon => 1.0,
        YieldForm::Energy => f
            .shortest_absorbed_nm()
            .map(|l| (l / f.emission_mean_nm()).min(1.0))
            .unwrap_or(1.0),
    }
}

/// How a tabulated diagonal sample was projected onto its feasible interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Projection {
    /// Matched exactly.
    Free,
    /// Clamped at zero.
    AtZero,
    /// Clamped at 1 − Σκ·a.
    AtCap,
    /// Not measured (filled later).
    Unmeasured,
}

/// The median spacing of a grid (in whatever coordinate it is given).
fn median_step(grid: &[f64]) -> f64 {
    let mut steps: Vec<f64> = grid.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
    if steps.is_empty() {
        return 0.0;
    }
    steps.sort_by(f64::total_cmp);
    steps[steps.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::SynthSpec;

    fn problem_data() -> FitData {
        let (m, _) = SynthSpec::preset("green-dye").unwrap().generate().unwrap();
        FitData::new(&m, m.default_guard_nm())
    }

    fn theta_for(layout: &Layout) -> Vec<f64> {
        let spec = layout.spec;
        let mut theta = vec![0.0; layout.len];
        for k in 0..spec.components {
            // Both components absorb almost everything near 21 kK: the Σκa penalty acts.
            theta[k] = 1.2 + 0.1 * k as f64;
            let centres = [20.5 + 3.0 * k as f64, 26.0];
            for (b, chunk) in theta[layout.absorption(k)].chunks_mut(3).enumerate() {
                chunk.copy_from_slice(&[-0.2 * b as f64, centres[b % 2], 0.1]);
            }
            for (b, chunk) in theta[layout.emission(k)].chunks_mut(3).enumerate() {
                chunk.copy_from_slice(&[
                    0.3 - 0.4 * b as f64,
                    19.0 - 2.0 * k as f64 - b as f64,
                    -0.3,
                ]);
            }
        }
        // One band wider than the box allows: the box penalty acts.
        theta[layout.emission(0).start + 2] = 4.0;
        for (n, t) in theta[layout.reflectance()].iter_mut().enumerate() {
            *t = [1.0, -1.5, 0.4, 0.2, -0.1][n % 5];
        }
        theta
    }

    #[test]
    fn bands_stay_wider_than_half_the_grid_step() {
        let data = problem_data();
        let spec = ModelSpec {
            components: 1,
            absorption_bands: 1,
            emission_bands: 1,
            reflectance: ReflectanceForm::Tabulated,
            domain: BandDomain::Wavenumber,
            yield_form: YieldForm::Energy,
        };
        let problem = Problem::new(&data, spec, &[], &[], 0.0);
        let layout = problem.layout;
        let mut theta = theta_for(&layout);
        theta[layout.emission(0).start + 2] = -0.3;
        let width = layout.absorption(0).start + 2;
        // The grid is 10 nm: about 0.44 kK at 480 nm, the median excitation step.
        let floor = 0.5 * median_step(&problem.excitation_u);
        assert!((0.15..0.3).contains(&floor), "{floor}");
        let mut gradient = vec![0.0; layout.len];
        theta[width] = (0.9 * floor).ln();
        let below = problem.band_penalty(&theta, &mut gradient);
        assert!(below > 0.0 && gradient[width] < 0.0, "{below}");
        gradient.iter_mut().for_each(|g| *g = 0.0);
        theta[width] = (1.1 * floor).ln();
        assert_eq!(problem.band_penalty(&theta, &mut gradient), 0.0);
        theta[width] = (0.1 * floor).ln();
        problem.clamp_to_box(&mut theta);
        assert!(theta[width].exp() >= floor * (1.0 - 1e-12));
    }

    #[test]
    fn gradient_matches_central_differences() {
        let data = problem_data();
        let lights = Light::standard();
        let cases = [ReflectanceForm::Polynomial(4), ReflectanceForm::Tabulated]
            .into_iter()
            .flat_map(|r| [YieldForm::Energy, YieldForm::Photon].map(|y| (r, y)));
        for (reflectance, yield_form) in cases {
            for (components, absorption_bands, emission_bands) in [(1, 1, 1), (2, 2, 1)] {
                let spec = ModelSpec {
                    components,
                    absorption_bands,
                    emission_bands,
                    reflectance,
                    domain: BandDomain::Wavenumber,
                    yield_form,
                };
                let reference: Vec<Xyz> = lights.iter().map(|_| [40.0, 35.0, 20.0]).collect();
                let problem = Problem::new(&data, spec, &lights, &reference, 0.3);
                let theta = theta_for(&problem.layout);
                let (_, analytic) = problem.cost_gradient(&theta);
                let numeric = problem.numerical_gradient(&theta, 1e-6);
                let norm = numeric.iter().map(|g| g * g).sum::<f64>().sqrt();
                assert!(norm > 1e-6, "a test point away from the optimum");
                for (n, (a, b)) in analytic.iter().zip(&numeric).enumerate() {
                    assert!(
                        (a - b).abs() <= 1e-5 * norm + 1e-9,
                        "{}: parameter {n}: analytic {a} vs numeric {b} (norm {norm})",
                        spec.name()
                    );
                }
            }
        }
    }
}
