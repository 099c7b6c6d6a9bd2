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
use crate::numeric::{row_dots, row_squares};
use crate::parametric::{
    BandDomain, FluorophoreForms, GaussianBands, MaterialForms, PARAMS_PER_BAND, SigmoidPolynomial,
    SpectralForm, legendre, position, sigmoid,
};
use crate::spectrum::Spectrum;

use super::data::FitData;

mod build;
mod cost;
mod grid_model;
mod scratch;
mod width_floor;

pub use build::{TABULATION_STEP_NM, fine_grid};
pub use width_floor::FLOOR_STEPS;
use width_floor::{BandBuffers, WidthFloor, floored_bands_with_jacobian};

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
/// sensible: it acts only outside the box, where the data no longer pull on a band (the
/// narrowest width is a hard floor, [`width_floor`]).
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
    /// `emitted` times the density factor f_j: ∂Lab/∂(column sum at j).
    emitted_by_column: [Vec<f64>; 3],
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
    /// The narrowest absorption band at each centre (the excitation grid's local step).
    excitation_floor: WidthFloor,
    /// The narrowest emission band at each centre (the emission grid's local step).
    emission_floor: WidthFloor,
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
    /// Each light's share of `colour_weight` (1 unless set).
    light_weight: Vec<f64>,
    /// The reflectance's Legendre support (nm).
    pub reflectance_support: [f64; 2],
    /// P₀(x) … P_d(x) at each diagonal sample's x, row by row (a polynomial reflectance of
    /// degree d; empty otherwise): fixed by the grid, and their recurrence's divisions
    /// took 7 % of an evaluation.
    reflectance_basis: Vec<f64>,
    /// (parameter index, lower, upper) for every band parameter: the box the objective
    /// penalises leaving. Fixed by the grids and the layout; built in every evaluation,
    /// it was about 1 % of a noise-aware search (perf).
    band_box: Vec<(usize, (f64, f64))>,
}

/// The model's quantities on the grids for one parameter vector.
#[derive(Debug, Clone, Default)]
pub struct GridModel {
    /// κ_k = sin²t_k.
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
    /// What the band evaluations work in.
    bands: BandBuffers,
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
            // The second band near the width floor (≈ 0.5 kK at 26 kK): the gradient
            // runs through the floor's dependence on the centre.
            let widths = [0.1, 0.3f64.ln()];
            for (b, chunk) in theta[layout.absorption(k)].chunks_mut(3).enumerate() {
                chunk.copy_from_slice(&[-0.2 * b as f64, centres[b % 2], widths[b % 2]]);
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
    fn bands_stay_wider_than_the_floor_at_the_local_grid_step() {
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
        let band = layout.absorption(0).start;
        // An absorption band midway between the 360 and 370 nm rows of the 10 nm grid,
        // asked to be far narrower than the rows' spacing (1e4/360 − 1e4/370 kK).
        let step: f64 = 1e4 / 360.0 - 1e4 / 370.0;
        theta[band + 1] = 0.5 * (1e4 / 360.0 + 1e4 / 370.0);
        for ln_width in [-30.0, (0.1 * step).ln(), (0.5 * step).ln()] {
            theta[band + 2] = ln_width;
            let [absorption, _] = problem.component_bands(&theta, 0);
            assert!(
                absorption[2].exp() >= FLOOR_STEPS * step * (1.0 - 1e-12),
                "width {} below the floor at step {step}",
                absorption[2].exp()
            );
            // The material carries the floored band too: σ in nm at 365 nm ≥ ¾·10 nm.
            let material = problem.material(&theta, "floor").unwrap();
            let forms = material.forms.unwrap();
            let crate::parametric::SpectralForm::GaussianBands(bands) =
                &forms.fluorophores[0].absorption
            else {
                panic!("a Gaussian absorption");
            };
            let sigma_nm = bands.bands[0].width / 1e7 * 365.0f64.powi(2);
            assert!(sigma_nm >= FLOOR_STEPS * 10.0 * 0.99, "σ {sigma_nm} nm");
        }
        // Starts below the floor come back just above it.
        let narrow = [0.0, theta[band + 1], (0.01 * step).ln()];
        let start = problem.absorption_solver_params(&narrow);
        let [absorption, _] = {
            theta[band..band + 3].copy_from_slice(&start);
            problem.component_bands(&theta, 0)
        };
        let above = absorption[2].exp() / (FLOOR_STEPS * step) - 1.0;
        assert!((0.0..0.1).contains(&above), "{above}");
    }

    #[test]
    fn gradient_matches_central_differences() {
        let data = problem_data();
        // With the lights' colour term, and without lights (the starts' problems).
        let cases = [ReflectanceForm::Polynomial(4), ReflectanceForm::Tabulated]
            .into_iter()
            .flat_map(|r| [YieldForm::Energy, YieldForm::Photon].map(|y| (r, y)))
            .flat_map(|c| [Light::standard(), Vec::new()].map(|l| (c, l)));
        for ((reflectance, yield_form), lights) in cases {
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

    #[test]
    fn an_evaluation_does_not_depend_on_the_one_before_it() {
        // The objective keeps its buffers per thread: evaluations of problems of other
        // sizes (components, lights, reflectance) between two of the same point must not
        // change its bits.
        let data = problem_data();
        let lights = Light::standard();
        let reference: Vec<Xyz> = lights.iter().map(|_| [40.0, 35.0, 20.0]).collect();
        let spec = |components, reflectance| ModelSpec {
            components,
            absorption_bands: 2,
            emission_bands: 1,
            reflectance,
            domain: BandDomain::Wavenumber,
            yield_form: YieldForm::Photon,
        };
        let problem = Problem::new(
            &data,
            spec(2, ReflectanceForm::Tabulated),
            &lights,
            &reference,
            0.3,
        );
        let theta = theta_for(&problem.layout);
        let first = problem.cost_gradient(&theta);
        for (components, reflectance, lit) in [
            (1, ReflectanceForm::Polynomial(4), false),
            (3, ReflectanceForm::Polynomial(2), true),
        ] {
            let (l, r) = if lit {
                (&lights[..], &reference[..])
            } else {
                (&[][..], &[][..])
            };
            let other = Problem::new(&data, spec(components, reflectance), l, r, 0.3);
            other.cost_gradient(&theta_for(&other.layout));
            let again = problem.cost_gradient(&theta);
            assert_eq!(again.0.to_bits(), first.0.to_bits());
            assert!(
                again
                    .1
                    .iter()
                    .zip(&first.1)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
        }
    }
}
