//! How to fit and what a fit produces: solver, start, yield form, the model to fit, and
//! the options' checks.

use super::*;
use crate::fit::parametric::ReflectanceForm;
use crate::parametric::BandDomain;

/// Default relative tolerance of the refinement. Measured on the four BFC-450 files with
/// the colour term: against 1e-6, ΔE2000 moves by at most 0.017 and the objective by at
/// most 2 %, at a fifth to a half of the L-BFGS iterations (CIBA12 28 against 152,
/// HERPICER 76 against 162; `fluorite fit FILE --tolerance 1e-6`).
pub const DEFAULT_TOLERANCE: f64 = 1e-5;

/// Weight of the colour term ½·w·Σ ΔE76² (one term per light, see [`crate::fit::parametric::Problem::new`])
/// against the matrix's ½·Σ r². At 0.01 a ΔE of 1 under one light costs as much as a
/// residual of 0.1 in one cell. Measured on the six real surfaces (`fluorite fit
/// ../shared/data/measured/* --max-delta-e 1 --colour-weight w --table`): with 0 (matrix
/// only) four meet the bound, with larger models (18–52 parameters, 3–10 candidates); 0.01
/// and 0.1 both meet it on five with the same models, mostly the first candidate. 0.01 is
/// the smaller weight that does, so the matrix term still decides the shapes.
pub const DEFAULT_COLOUR_WEIGHT: f64 = 0.01;

/// With [`FitOptions::noise_aware_bound`], a light's colour term keeps its full weight
/// while the measured colour's noise RMS is at most this share of the bound; beyond, the
/// weight falls as 1/noise² (inverse-variance weighting), so a colour known only to a few
/// ΔE2000 does not drag the model onto its noise. Measured with `fluorite class` on five
/// seeds (docs/results.md): 0.1, 0.15, 0.2 and 0.25 all lower the search's median, 90th
/// percentile and maximum against the truth; 0.2 lowered all three on every seed.
pub const NOISE_PULL_SHARE: f64 = 0.2;

/// What model to fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ModelChoice {
    /// The default (`as-needed`): the one-fluorophore grid fit when it explains the
    /// matrix, else the first parametric model the noise-aware search keeps under d65, a
    /// and f11 (and uv where the grid holds its LED's rows), each held to ΔE2000 ≤ 1 or
    /// its measured colour's noise (see [`crate::fit::escalate`]); a miss the crosstalk it
    /// removed explains (within 1 of the cells it fitted) does not escalate. Matrices
    /// without a calibrated diagonal and fits
    /// with a pinned yield or concentration keep the grid fit.
    #[default]
    AsNeeded,
    /// One sample per grid wavelength, one fluorophore, never escalated (`tabulated`: the
    /// default before `as-needed`).
    Tabulated,
    /// The smallest parametric model meeting the rule.
    Auto,
    /// A given parametric model.
    Fixed(ModelRequest),
}

/// A parametric model as requested: the reflectance may be left to the search.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelRequest {
    /// Fluorescent components K.
    pub components: usize,
    /// Bands per absorption spectrum.
    pub absorption_bands: usize,
    /// Bands per emission spectrum.
    pub emission_bands: usize,
    /// The reflectance; `None` lets the fit choose the degree.
    pub reflectance: Option<ReflectanceForm>,
    /// The band axis.
    pub domain: BandDomain,
    /// The yield form (`/photon` in the name); `None` leaves it to `--yield`.
    pub yield_form: Option<YieldForm>,
}

/// The refinement method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Solver {
    /// The closed-form estimate alone (no refinement).
    Init,
    /// L-BFGS with a More-Thuente line search (the default).
    Lbfgs,
    /// Gauss-Newton with a backtracking line search.
    GaussNewton,
    /// Nelder-Mead simplex search (no derivatives; slow, for comparison).
    NelderMead,
}

/// Where the iterative solvers start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Start {
    /// The closed-form rank-1 estimate (the default).
    #[default]
    ClosedForm,
    /// A flat absorption (½ everywhere) and a flat emission at the estimate's mean level:
    /// what a solver faces without the closed-form estimate (for the stability sweeps).
    Flat,
}

impl Solver {
    /// The name recorded in the material.
    pub fn name(self) -> &'static str {
        match self {
            Solver::Init => "init",
            Solver::Lbfgs => "lbfgs",
            Solver::GaussNewton => "gauss-newton",
            Solver::NelderMead => "nelder-mead",
        }
    }
}

/// Which yield form the fitted fluorophores take (model.md §3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum YieldChoice {
    /// The paper's constant energy yield Q.
    Energy,
    /// A constant photon yield Φ (energy yield Φ·λi/λ̄e).
    Photon,
    /// The energy form unless its photon law binds and costs fit; then the photon form,
    /// and the report says why.
    #[default]
    Auto,
}

/// The axis the model search's Gaussian bands are Gaussian in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum BandAxisChoice {
    /// Both: the search runs on wavenumber and on wavelength and keeps the result that
    /// meets its rule, of the two the one of lower BIC (the data decide; the fit report's
    /// model search says which and why).
    #[default]
    Both,
    /// Gaussian in wavenumber (energy), the shape dye spectra take
    /// ([`crate::parametric::fit::DEFAULT_BAND_DOMAIN`]).
    Wavenumber,
    /// Gaussian in wavelength.
    Wavelength,
}

impl BandAxisChoice {
    /// The axes a search runs on, wavenumber first.
    pub fn axes(self) -> &'static [BandDomain] {
        match self {
            BandAxisChoice::Both => &[BandDomain::Wavenumber, BandDomain::Wavelength],
            BandAxisChoice::Wavenumber => &[BandDomain::Wavenumber],
            BandAxisChoice::Wavelength => &[BandDomain::Wavelength],
        }
    }
}

/// How to fit.
#[derive(Debug, Clone)]
pub struct FitOptions {
    /// Refinement method.
    pub solver: Solver,
    /// Cells within this many nm of the diagonal are set aside (default: none; the cells
    /// next to the diagonal are mostly fluorescence, model.md §5).
    pub guard_nm: Option<f64>,
    /// The yield form of the fitted fluorophores.
    pub yield_choice: YieldChoice,
    /// Pin the energy quantum yield Q (outside knowledge); c = k/Q.
    pub quantum_yield: Option<f64>,
    /// Pin the concentration c; Q = k/c.
    pub concentration: Option<f64>,
    /// Iteration limit of the refinement.
    pub max_iterations: u64,
    /// Relative tolerance of the refinement: stop when an iteration improves the cost by
    /// less than this fraction of the starting cost, or the gradient norm falls below
    /// this fraction of the data's norm.
    pub tolerance: f64,
    /// Lights of the ΔE2000 report, of the colour term the fits weigh, and of the search's
    /// bound.
    pub lights: Vec<Light>,
    /// Starting point of the iterative solvers.
    pub start: Start,
    /// The spectral model: as needed (the default), tabulated, a parametric model, or the
    /// search.
    pub model: ModelChoice,
    /// The search's bound: the first model with ΔE2000 at most this under every light in
    /// `lights` is chosen (without it the search takes the lowest BIC).
    pub max_delta_e: Option<f64>,
    /// Weight of the patch colour under `lights` against the matrix residual in the
    /// objective (grid and parametric models alike; the grid fit scales it by the share of
    /// its start's residual that noise does not explain).
    pub colour_weight: f64,
    /// Judge the search's bound against the measurement's precision: each light is held
    /// to max(`max_delta_e`, [`crate::fit::assess::NOISE_COVERAGE`] × the measured colour's
    /// own noise RMS) (but to no more than `max_delta_e` beyond the grid fit's own ΔE2000
    /// there), and its colour term pulls no harder than that noise allows
    /// (weight × min(1, ([`NOISE_PULL_SHARE`] × bound / noise)²), and where that is below 1
    /// times the share of what the grid fit leaves, in its residual or that light's
    /// colour, that noise does not explain); the candidates' reflectance is tabulated
    /// where no sigmoid polynomial fits the grid fit's diagonal within the cells' noise;
    /// where the grid model misses a light beyond its widened bound the search starts at
    /// two components. Off:
    /// every light is held to `max_delta_e` as given. Without `max_delta_e` the fit refuses
    /// it (there is no bound to widen).
    pub noise_aware_bound: bool,
    /// The axes the model search's Gaussian bands may be Gaussian in (a `--model` that
    /// names one structure takes its name's axis instead: `@wavelength`, else wavenumber).
    pub band_axis: BandAxisChoice,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            solver: Solver::Lbfgs,
            guard_nm: None,
            yield_choice: YieldChoice::Auto,
            quantum_yield: None,
            concentration: None,
            max_iterations: 500,
            tolerance: DEFAULT_TOLERANCE,
            lights: Light::standard(),
            start: Start::ClosedForm,
            model: ModelChoice::AsNeeded,
            max_delta_e: None,
            colour_weight: DEFAULT_COLOUR_WEIGHT,
            noise_aware_bound: false,
            band_axis: BandAxisChoice::Both,
        }
    }
}

impl FitOptions {
    /// The ΔE2000 a colour difference must pass to count as visible: the search's bound
    /// when set, else the default fit's ([`super::escalate::ESCALATION_BOUND`], 1).
    pub fn colour_bound(&self) -> f64 {
        self.max_delta_e
            .unwrap_or(super::escalate::ESCALATION_BOUND)
    }
}

/// What a fit produces.
#[derive(Debug, Clone)]
pub enum FitOutcome {
    /// A complete material (the data had a calibrated diagonal).
    Material(Box<Material>),
    /// Absorption and emission shapes only (solution EEMs): the rest is undetermined.
    Shapes(Box<FluorophoreShapes>),
}

impl FitOutcome {
    /// Records how a raw EEM was prepared ([`crate::eem::prepare`]) in the fit report, so
    /// the written file says what was done to the data before the fit.
    pub fn record_preprocessing(&mut self, preprocessing: crate::eem::Preprocessing) {
        match self {
            FitOutcome::Material(m) => {
                if let Some(f) = m.fit.as_mut() {
                    f.preprocessing = Some(preprocessing);
                }
            }
            FitOutcome::Shapes(s) => s.fit.preprocessing = Some(preprocessing),
        }
    }

    /// The fit report of either outcome.
    pub fn report(&self) -> &FitReport {
        match self {
            FitOutcome::Material(m) => m.fit.as_ref().expect("fitted materials carry a report"),
            FitOutcome::Shapes(s) => &s.fit,
        }
    }

    /// Overrides the recorded fit time (e.g. with a median over repeated runs).
    pub fn set_seconds(&mut self, seconds: f64) {
        match self {
            FitOutcome::Material(m) => {
                if let Some(f) = m.fit.as_mut() {
                    f.seconds = seconds;
                }
            }
            FitOutcome::Shapes(s) => s.fit.seconds = seconds,
        }
    }

    /// The JSON to write.
    pub fn to_json(&self) -> String {
        match self {
            FitOutcome::Material(m) => m.to_json(),
            FitOutcome::Shapes(s) => s.to_json(),
        }
    }
}

/// Checks the options every refinement shares: the guard band, the iteration limit and
/// the tolerance.
pub(super) fn validate_refinement(
    guard_nm: Option<f64>,
    max_iterations: u64,
    tolerance: f64,
) -> Result<()> {
    if let Some(g) = guard_nm
        && (!g.is_finite() || g < 0.0)
    {
        return Err(Error::invalid(
            "--guard",
            format!("is {g}; give a distance in nm ≥ 0"),
        ));
    }
    if max_iterations == 0 || max_iterations > crate::limits::MAX_ITERATIONS {
        return Err(Error::invalid(
            "--max-iterations",
            format!(
                "is {max_iterations}; give a count from 1 to {} (fits here converge in hundreds)",
                crate::limits::MAX_ITERATIONS
            ),
        ));
    }
    if !(tolerance > 0.0 && tolerance < 1.0) {
        return Err(Error::invalid(
            "--tolerance",
            format!("is {tolerance}; give a value in (0, 1)"),
        ));
    }
    Ok(())
}

impl FitOptions {
    /// Refuses a band axis asked for beside a model that names one structure: the model's
    /// name names its axis too (`@wavelength`), and the axis would be silently ignored.
    /// Every fit checks it; a front end may check it before reading any file.
    pub fn check_band_axis(&self) -> Result<()> {
        if matches!(self.model, ModelChoice::Fixed(_)) && self.band_axis != BandAxisChoice::Both {
            return Err(Error::invalid(
                "--band-axis",
                "chooses the model search's axis; a --model that names one structure takes its name's (append @wavelength for bands Gaussian in wavelength): drop --band-axis or --model",
            ));
        }
        Ok(())
    }
}

pub(super) fn validate_options(options: &FitOptions) -> Result<()> {
    validate_refinement(options.guard_nm, options.max_iterations, options.tolerance)?;
    for (value, name) in [
        (options.quantum_yield, "--quantum-yield"),
        (options.concentration, "--concentration"),
    ] {
        if let Some(v) = value
            && !(v > 0.0 && v <= 1.0)
        {
            return Err(Error::invalid(
                name,
                format!("is {v}; it must lie in (0, 1]"),
            ));
        }
    }
    if options.quantum_yield.is_some() && options.concentration.is_some() {
        return Err(Error::invalid(
            "--quantum-yield/--concentration",
            "both given; k = c·Q is fixed by the data, so pin only one of them",
        ));
    }
    if let Some(bound) = options.max_delta_e
        && !(bound.is_finite() && bound > 0.0)
    {
        return Err(Error::invalid(
            "--max-delta-e",
            format!("is {bound}; give a positive ΔE2000 (1 is invisible side by side)"),
        ));
    }
    options.check_band_axis()?;
    // The widening is of a bound: without one there is nothing to widen, and ignoring the
    // flag would let a caller believe the noise was allowed for.
    if options.noise_aware_bound && options.max_delta_e.is_none() {
        return Err(Error::invalid(
            "--noise-aware-bound",
            "needs a bound to widen; give --max-delta-e too (e.g. --max-delta-e 1)",
        ));
    }
    if !(options.colour_weight.is_finite() && options.colour_weight >= 0.0) {
        return Err(Error::invalid(
            "--colour-weight",
            format!("is {}; give a weight ≥ 0", options.colour_weight),
        ));
    }
    if !matches!(
        options.model,
        ModelChoice::Tabulated | ModelChoice::AsNeeded
    ) && options.solver != Solver::Lbfgs
    {
        return Err(Error::invalid(
            "--solver",
            "parametric models are refined with L-BFGS only; drop --solver or use --model tabulated",
        ));
    }
    Ok(())
}
