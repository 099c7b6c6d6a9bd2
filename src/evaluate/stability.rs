//! Where each method fails: sweeps over synthetic matrices with known truth.
//!
//! Every case starts from a preset of [`SynthSpec`] (green dye, red pigment, optical
//! brightener, cycled over the seeds) at the BFC-450 noise level and changes one
//! condition. A run succeeds when the truth is recovered — the fluorescent strength
//! profile k·a(λi) and the emission e(λo) each within [`RECOVERY_TOLERANCE`] relative L2
//! error on the fit's grids (for k = 0: a fitted k below [`ZERO_K_TOLERANCE`]) — and the
//! colour is right: the largest ΔE2000 between fitted and true material over the four
//! standard lights is at most [`DELTA_E_TOLERANCE`]. A run is *flagged* when `fit`
//! warned, did not converge or refused the input: the share of failures that were
//! flagged tells whether a user would notice.

use std::fmt::Write as _;

use rayon::prelude::*;

use crate::colour::{Light, delta_e2000, material_xyz, xyz_to_lab};
use crate::error::Result;
use crate::fit::{FitOutcome, Solver, Start, fit};
use crate::material::Material;
use crate::measurement::Measurement;
use crate::spectrum::uniform_grid;
use crate::synth::{MEASURED_NOISE_SIGMA, SynthSpec};

use super::{Method, median};

/// Largest relative L2 error of k·a and of e for the truth to count as recovered.
pub const RECOVERY_TOLERANCE: f64 = 0.1;
/// Largest ΔE2000 (over the four standard lights) against the truth for success.
pub const DELTA_E_TOLERANCE: f64 = 1.0;
/// For a non-fluorescent truth: largest fitted k = c·Q that still counts as "none".
pub const ZERO_K_TOLERANCE: f64 = 0.005;
/// Presets the seeds cycle through.
pub const SWEEP_PRESETS: [&str; 3] = ["green-dye", "red-pigment", "brightener"];

/// A swept condition.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Sweep {
    /// Gaussian noise σ per cell.
    Noise,
    /// Fraction of off-diagonal cells unmeasured.
    Missing,
    /// Concentration c (k = c·Q falls with it), down to 0.
    Strength,
    /// Stokes shift: emission peak minus absorption peak (nm); small = strong overlap.
    Overlap,
    /// Crosstalk next to the diagonal (a monochromator offset: a fraction of the diagonal
    /// moved from one step above it to one step below), which the fit does not model.
    Crosstalk,
    /// Excitation grid step (nm): few excitation rows.
    ExcitationStep,
    /// Noise σ with the iterative solvers started flat instead of from the closed form.
    PoorStart,
}

impl Sweep {
    /// All sweeps in report order.
    pub const ALL: [Sweep; 7] = [
        Sweep::Noise,
        Sweep::Missing,
        Sweep::Strength,
        Sweep::Overlap,
        Sweep::Crosstalk,
        Sweep::ExcitationStep,
        Sweep::PoorStart,
    ];

    /// Short identifier (CSV, anchors).
    pub fn id(self) -> &'static str {
        match self {
            Sweep::Noise => "noise",
            Sweep::Missing => "missing",
            Sweep::Strength => "strength",
            Sweep::Overlap => "overlap",
            Sweep::Crosstalk => "crosstalk",
            Sweep::ExcitationStep => "excitation-step",
            Sweep::PoorStart => "poor-start",
        }
    }

    /// Axis label of the swept variable.
    pub fn variable(self) -> &'static str {
        match self {
            Sweep::Noise => "noise σ",
            Sweep::Missing => "missing fraction",
            Sweep::Strength => "concentration c",
            Sweep::Overlap => "Stokes shift (nm)",
            Sweep::Crosstalk => "crosstalk (fraction of the diagonal)",
            Sweep::ExcitationStep => "excitation step (nm)",
            Sweep::PoorStart => "noise σ, flat start",
        }
    }

    /// The swept values, from benign to hostile.
    pub fn values(self) -> Vec<f64> {
        match self {
            Sweep::Noise => vec![1e-4, 6e-4, 2e-3, 6e-3, 2e-2, 6e-2, 0.2],
            Sweep::Missing => vec![0.0, 0.3, 0.6, 0.8, 0.9, 0.95, 0.98],
            Sweep::Strength => vec![0.8, 0.3, 0.1, 0.03, 0.01, 0.003, 0.0],
            Sweep::Overlap => vec![120.0, 80.0, 50.0, 30.0, 20.0, 10.0, 0.0],
            Sweep::Crosstalk => vec![0.0, 0.001, 0.01, 0.04, 0.08],
            Sweep::ExcitationStep => vec![10.0, 20.0, 30.0, 40.0, 60.0, 80.0, 120.0],
            Sweep::PoorStart => vec![1e-4, 6e-4, 6e-3, 6e-2],
        }
    }

    /// How a value prints in tables and on axes.
    pub fn label(self, value: f64) -> String {
        match self {
            Sweep::Noise | Sweep::PoorStart => format!("{value:.0e}"),
            Sweep::Missing | Sweep::Strength | Sweep::Crosstalk => format!("{value}"),
            _ => format!("{value:.0}"),
        }
    }

    /// Why a method breaks along this sweep (mechanism; the tables give the numbers).
    pub fn mechanism(self) -> &'static str {
        match self {
            Sweep::Noise => {
                "Noise enters a and e directly: once σ approaches the fluorescent peak the rank-1 factors follow the noise, and when the signal sinks under the noise floor `fit` falls back to a plain reflector. All solvers minimise the same objective, so they break together; the closed-form estimate alone is as good as the refined fit here."
            }
            Sweep::Missing => {
                "Each row and column of the rank-1 model needs enough measured cells; with most cells missing, rows and columns lose their support, the factors become under-determined and the colour integral relies on interpolated samples."
            }
            Sweep::Strength => {
                "The data determine k·a and e only as far as the fluorescence rises above the noise: as k falls to the noise level the shapes are lost (recovery fails) although the colour error stays small, and at k = 0 the fitter must (and does) report a plain reflector."
            }
            Sweep::Overlap => {
                "With a small Stokes shift most of the fluorescence lies on the diagonal, where it adds to the reflectance and the fit cannot tell them apart, and in the cells next to it; a and e near the diagonal rest on those neighbouring cells (fitted by default) and on their tails."
            }
            Sweep::Crosstalk => {
                "The cells next to the diagonal are fitted as fluorescence (they mostly are, model.md §5). A monochromator offset puts a signed band along the diagonal there, which is not rank 1: a few per cent of the diagonal (POLGREE and TEXTYELL show 4 %) would bias a and e near the diagonal. `fit` measures it in the rows without fluorescence and fits the cells without it (fitting.md); where that would move the fit to another optimum it fits them as measured and flags the residual next to the diagonal, which `--guard` sets aside."
            }
            Sweep::ExcitationStep => {
                "With few excitation rows the absorption band is sampled by one or two points; the material interpolates between them, so the absorbed energy under lights with structure (UV LED, F11) is wrong even though the fit matches every measured cell."
            }
            Sweep::PoorStart => {
                "Started flat, the iterative solvers must find the spectral shapes themselves. Gradient solvers still descend to the global minimum on clean data but need more iterations; Nelder-Mead on ~90 parameters does not get there within its budget, and the flat start itself (`init`) is no fit at all."
            }
        }
    }
}

/// Configuration of a stability run.
#[derive(Debug, Clone)]
pub struct Config {
    /// Seeded repetitions per condition (seeds cycle the presets).
    pub seeds: usize,
    /// Sweeps to run.
    pub sweeps: Vec<Sweep>,
    /// Methods to compare.
    pub methods: Vec<Method>,
}

impl Config {
    /// The full sweep: every condition, `init`, `lbfgs`, `gauss-newton` and
    /// `nelder-mead` at default tolerance.
    pub fn full(seeds: usize) -> Config {
        Config {
            seeds,
            sweeps: Sweep::ALL.to_vec(),
            methods: [
                Solver::Init,
                Solver::Lbfgs,
                Solver::GaussNewton,
                Solver::NelderMead,
            ]
            .into_iter()
            .map(Method::new)
            .collect(),
        }
    }

    /// A fast version for tests and smoke runs: Nelder-Mead with a tenth of its
    /// iterations.
    pub fn quick(seeds: usize) -> Config {
        let mut c = Config::full(seeds);
        for m in &mut c.methods {
            if m.solver == Solver::NelderMead {
                m.max_iterations /= 10;
            }
        }
        c
    }
}

/// One fit in the sweep.
#[derive(Debug, Clone)]
pub struct Run {
    /// Sweep.
    pub sweep: Sweep,
    /// Swept value.
    pub value: f64,
    /// Method name.
    pub method: String,
    /// Seed (also picks the preset).
    pub seed: usize,
    /// Relative L2 error of k·a and e (the larger); NaN for a non-fluorescent truth or a
    /// refused fit.
    pub recovery_error: f64,
    /// Largest ΔE2000 against the truth over the four lights (∞ when refused).
    pub delta_e: f64,
    /// Fit time (ms).
    pub ms: f64,
    /// Truth recovered and ΔE within tolerance.
    pub success: bool,
    /// `fit` warned, did not converge, or refused the input.
    pub flagged: bool,
    /// The warnings (or the error) of the fit.
    pub warnings: Vec<String>,
}

/// Aggregate over the seeds of one (sweep, value, method).
#[derive(Debug, Clone)]
pub struct Summary {
    /// Sweep.
    pub sweep: Sweep,
    /// Swept value.
    pub value: f64,
    /// Method name.
    pub method: String,
    /// Runs.
    pub runs: usize,
    /// Share of successful runs.
    pub success_rate: f64,
    /// Median ΔE2000 against the truth.
    pub median_delta_e: f64,
    /// Median recovery error (NaN for a non-fluorescent truth).
    pub median_recovery_error: f64,
    /// Median fit time (ms).
    pub median_ms: f64,
    /// Share of runs `fit` flagged.
    pub flagged_rate: f64,
    /// Share of the failed runs that `fit` flagged (NaN without failures).
    pub flagged_failures: f64,
}

/// The spec (and start) for one case.
fn case(sweep: Sweep, value: f64, seed: usize) -> Result<(SynthSpec, Start)> {
    let mut spec = SynthSpec::preset(SWEEP_PRESETS[seed % SWEEP_PRESETS.len()])?;
    spec.seed = 1000 + seed as u64;
    spec.noise_sigma = MEASURED_NOISE_SIGMA;
    let mut start = Start::ClosedForm;
    match sweep {
        Sweep::Noise => spec.noise_sigma = value,
        Sweep::Missing => spec.missing_fraction = value,
        Sweep::Strength => spec.concentration = value,
        Sweep::Overlap => {
            // Move every emission band with the main one, keeping the spectrum's shape.
            let shift = spec.absorption[0].centre_nm + value - spec.emission[0].centre_nm;
            spec.emission.iter_mut().for_each(|b| b.centre_nm += shift);
        }
        Sweep::Crosstalk => spec.crosstalk = value,
        Sweep::ExcitationStep => spec.excitation_nm = uniform_grid(300.0, 780.0, value),
        Sweep::PoorStart => {
            spec.noise_sigma = value;
            start = Start::Flat;
        }
    }
    Ok((spec, start))
}

/// Largest ΔE2000 between two materials over `lights`.
pub fn material_delta_e(a: &Material, b: &Material, lights: &[Light]) -> f64 {
    lights
        .iter()
        .map(|light| {
            let (xa, white) = material_xyz(a, light);
            let (xb, _) = material_xyz(b, light);
            delta_e2000(xyz_to_lab(xa, white), xyz_to_lab(xb, white))
        })
        .fold(0.0, f64::max)
}

/// Relative L2 error of the fitted row factor c·Q(λ)·a (k·a in the energy form,
/// c·Φ·(λ/λ̄e)·a in the photon form: what the matrix determines, whatever the yield
/// forms of fit and truth) and e against the truth, on the fit's grids (the truth
/// evaluated there). NaN when the truth has no fluorophore; 1 when the fit has none.
pub fn recovery_error(fitted: &Material, truth: &Material) -> f64 {
    let Some(t) = truth.fluorophores.first() else {
        return f64::NAN;
    };
    let Some(f) = fitted.fluorophores.first() else {
        return 1.0;
    };
    let rel = |got: &[f64], want: &[f64]| {
        let num: f64 = got.iter().zip(want).map(|(g, w)| (g - w).powi(2)).sum();
        let den: f64 = want.iter().map(|w| w * w).sum();
        if den > 0.0 {
            (num / den).sqrt()
        } else {
            f64::INFINITY
        }
    };
    let (mean_fit, mean_true) = (f.emission_mean_nm(), t.emission_mean_nm());
    // Both on the fitted spectra's wavelengths.
    let on = |grid: &[f64], value: &dyn Fn(f64) -> f64| -> Vec<f64> {
        grid.iter().map(|&l| value(l)).collect()
    };
    let absorbed = &f.absorption.wavelength_nm;
    let ka_fit = on(absorbed, &|l| f.reradiated_with_mean(l, mean_fit));
    let ka_true = on(absorbed, &|l| t.reradiated_with_mean(l, mean_true));
    let e_true = on(&f.emission.wavelength_nm, &|l| {
        t.emission.eval_zero_outside(l)
    });
    rel(&ka_fit, &ka_true).max(rel(&f.emission.value, &e_true))
}

/// The synthetic measurement of one case, its truth (on the fine 10 nm grids: a coarse
/// grid's own truth would hide what the coarse sampling misses) and the start the
/// iterative solvers get.
pub fn case_data(sweep: Sweep, value: f64, seed: usize) -> Result<(Measurement, Material, Start)> {
    let (spec, start) = case(sweep, value, seed)?;
    let (m, _) = spec.generate()?;
    let truth = SynthSpec {
        excitation_nm: uniform_grid(300.0, 780.0, 10.0),
        ..spec.clone()
    }
    .truth()?;
    Ok((m, truth, start))
}

fn one_run(sweep: Sweep, value: f64, method: &Method, seed: usize) -> Result<Run> {
    let (m, truth, start) = case_data(sweep, value, seed)?;
    let mut options = method.options();
    options.start = start;
    let lights = Light::standard();
    let run = |recovery_error: f64, delta_e: f64, ms: f64, flagged, warnings| {
        let recovered = if truth.fluorophores.is_empty() {
            true
        } else {
            recovery_error <= RECOVERY_TOLERANCE
        };
        Run {
            sweep,
            value,
            method: method.name.clone(),
            seed,
            recovery_error,
            delta_e,
            ms,
            success: recovered && delta_e <= DELTA_E_TOLERANCE,
            flagged,
            warnings,
        }
    };
    let started = std::time::Instant::now();
    let outcome = fit(&m, &options);
    let ms = started.elapsed().as_secs_f64() * 1e3;
    Ok(match outcome {
        Ok(FitOutcome::Material(fitted)) => {
            let report = fitted.fit.clone().unwrap_or_default();
            let mut recovery = recovery_error(&fitted, &truth);
            let delta_e = material_delta_e(&fitted, &truth, &lights);
            let mut r = run(
                recovery,
                delta_e,
                ms,
                !report.converged || !report.warnings.is_empty(),
                report.warnings,
            );
            if truth.fluorophores.is_empty() {
                // The largest fitted row factor c·Q(λ)·a: k itself in the energy form
                // (max a = 1), c·Φ·λ/λ̄e at its largest in the photon form.
                let k = fitted
                    .fluorophores
                    .first()
                    .map(|f| {
                        let mean = f.emission_mean_nm();
                        f.absorption
                            .wavelength_nm
                            .iter()
                            .map(|&l| f.reradiated_with_mean(l, mean))
                            .fold(0.0, f64::max)
                    })
                    .unwrap_or(0.0);
                recovery = f64::NAN;
                r.recovery_error = recovery;
                r.success = k <= ZERO_K_TOLERANCE && delta_e <= DELTA_E_TOLERANCE;
            }
            r
        }
        Ok(FitOutcome::Shapes(_)) => run(f64::NAN, f64::INFINITY, ms, true, vec![]),
        Err(e) => run(f64::NAN, f64::INFINITY, ms, true, vec![e.to_string()]),
    })
}

/// Runs every (sweep, value, method, seed) in parallel.
pub fn run(config: &Config) -> Result<Vec<Run>> {
    let mut jobs = Vec::new();
    for &sweep in &config.sweeps {
        for value in sweep.values() {
            for method in &config.methods {
                for seed in 0..config.seeds {
                    jobs.push((sweep, value, method, seed));
                }
            }
        }
    }
    jobs.into_par_iter()
        .map(|(sweep, value, method, seed)| one_run(sweep, value, method, seed))
        .collect()
}

/// Aggregates runs per (sweep, value, method), in the order they first appear.
pub fn summarise(runs: &[Run]) -> Vec<Summary> {
    let mut keys: Vec<(Sweep, f64, String)> = Vec::new();
    for r in runs {
        let key = (r.sweep, r.value, r.method.clone());
        if !keys.contains(&key) {
            keys.push(key);
        }
    }
    keys.into_iter()
        .map(|(sweep, value, method)| {
            let group: Vec<&Run> = runs
                .iter()
                .filter(|r| r.sweep == sweep && r.value == value && r.method == method)
                .collect();
            let n = group.len();
            let share = |f: &dyn Fn(&Run) -> bool| {
                group.iter().filter(|r| f(r)).count() as f64 / n.max(1) as f64
            };
            let failures: Vec<&&Run> = group.iter().filter(|r| !r.success).collect();
            let flagged_failures = if failures.is_empty() {
                f64::NAN
            } else {
                failures.iter().filter(|r| r.flagged).count() as f64 / failures.len() as f64
            };
            Summary {
                sweep,
                value,
                method,
                runs: n,
                success_rate: share(&|r| r.success),
                median_delta_e: median(&group.iter().map(|r| r.delta_e).collect::<Vec<_>>()),
                median_recovery_error: median(
                    &group.iter().map(|r| r.recovery_error).collect::<Vec<_>>(),
                ),
                median_ms: median(&group.iter().map(|r| r.ms).collect::<Vec<_>>()),
                flagged_rate: share(&|r| r.flagged),
                flagged_failures,
            }
        })
        .collect()
}

/// The first three CSV columns of both tables: the condition a run and its summary
/// belong to (the key [`summarise`] groups by).
fn condition_columns(sweep: Sweep, value: f64, method: &str) -> String {
    format!("{},{},{}", sweep.id(), value, method)
}

/// The CSV header of [`to_csv`].
pub const CSV_HEADER: &str = "sweep,value,method,runs,success_rate,median_delta_e2000,median_recovery_error,median_ms,flagged_rate,flagged_failures";

/// The summaries as CSV.
pub fn to_csv(summaries: &[Summary]) -> String {
    let mut out = String::from(CSV_HEADER);
    out.push('\n');
    for s in summaries {
        let _ = writeln!(
            out,
            "{},{},{:.4},{:.6e},{:.6e},{:.4},{:.4},{:.4}",
            condition_columns(s.sweep, s.value, &s.method),
            s.runs,
            s.success_rate,
            s.median_delta_e,
            s.median_recovery_error,
            s.median_ms,
            s.flagged_rate,
            s.flagged_failures
        );
    }
    out
}

/// Every run as CSV (one line per fit, warnings joined by " | "), for inspection.
pub fn runs_to_csv(runs: &[Run]) -> String {
    let mut out = String::from(
        "sweep,value,method,seed,preset,success,flagged,recovery_error,max_delta_e2000,ms,warnings\n",
    );
    for r in runs {
        let warnings = r.warnings.join(" | ").replace('"', "'");
        let _ = writeln!(
            out,
            "{},{},{},{},{},{:.6e},{:.6e},{:.4},\"{}\"",
            condition_columns(r.sweep, r.value, &r.method),
            r.seed,
            SWEEP_PRESETS[r.seed % SWEEP_PRESETS.len()],
            r.success,
            r.flagged,
            r.recovery_error,
            r.delta_e,
            r.ms,
            warnings
        );
    }
    out
}

fn fmt(v: f64, decimals: usize) -> String {
    if v.is_nan() {
        "–".into()
    } else if v.is_infinite() {
        "refused".into()
    } else {
        format!("{v:.decimals$}")
    }
}

/// The first swept value (benign to hostile) at which `method` succeeds in less than
/// half the runs, if any.
pub fn breaking_point(summaries: &[Summary], sweep: Sweep, method: &str) -> Option<f64> {
    summaries
        .iter()
        .filter(|s| s.sweep == sweep && s.method == method)
        .find(|s| s.success_rate < 0.5)
        .map(|s| s.value)
}

/// The Markdown report: definitions, a summary of where each method breaks, and one
/// table per sweep.
pub fn report(config: &Config, summaries: &[Summary], command: &str) -> String {
    let mut out = String::new();
    let methods: Vec<&str> = config.methods.iter().map(|m| m.name.as_str()).collect();
    let _ = writeln!(out, "# Where each fitting method fails\n");
    let _ = writeln!(
        out,
        "Made by `{command}`. Synthetic BFC-450-like matrices (excitation 300–780 nm, emission 380–780 nm, 10 nm) from the presets {} (cycled over {} seeds per condition), noise σ = {MEASURED_NOISE_SIGMA} (the BFC-450 level) unless swept, crosstalk 0.001 of the diagonal next to it (+ below, − above, as the real files show). Methods: {}.\n",
        SWEEP_PRESETS.join(", "),
        config.seeds,
        methods.join(", ")
    );
    let _ = writeln!(
        out,
        "**Success** = the truth is recovered (relative L2 error of k·a(λi) and of e(λo) each ≤ {RECOVERY_TOLERANCE}; for k = 0 a fitted k ≤ {ZERO_K_TOLERANCE}) **and** the largest ΔE2000 between fitted and true material over D65, A, F11 and UV is ≤ {DELTA_E_TOLERANCE}. **Flagged** = `fit` issued a warning, did not converge, or refused the input (what `fit --strict` turns into exit code 1). \"flagged failures\" is the share of failed runs that were flagged: 100 % means a user would have been told.\n"
    );
    let _ = writeln!(out, "## Summary\n");
    for &sweep in &config.sweeps {
        let _ = writeln!(out, "- **{}**: {}", sweep.variable(), sweep.mechanism());
        for method in &methods {
            let group: Vec<&Summary> = summaries
                .iter()
                .filter(|s| s.sweep == sweep && s.method == *method)
                .collect();
            let (failed, flagged) = group.iter().fold((0.0, 0.0), |(f, g), s| {
                let fails = (1.0 - s.success_rate) * s.runs as f64;
                let flagged = if s.flagged_failures.is_nan() {
                    0.0
                } else {
                    s.flagged_failures * fails
                };
                (f + fails, g + flagged)
            });
            let flag_text = if failed > 0.0 {
                format!(
                    "; `fit` flagged {:.0} % of its failed runs",
                    100.0 * flagged / failed
                )
            } else {
                String::new()
            };
            let text = match breaking_point(summaries, sweep, method) {
                Some(v) => format!(
                    "breaks at {} = {}{flag_text}",
                    sweep.variable(),
                    sweep.label(v)
                ),
                None => format!("succeeds in at least half the runs everywhere{flag_text}"),
            };
            let _ = writeln!(out, "  - `{method}` {text}.");
        }
    }
    for &sweep in &config.sweeps {
        let _ = writeln!(out, "\n## {}\n", sweep.variable());
        let _ = writeln!(
            out,
            "| {} | method | success | median ΔE2000 | median recovery error | median ms | flagged | flagged failures |\n|---|---|---|---|---|---|---|---|",
            sweep.variable()
        );
        for s in summaries.iter().filter(|s| s.sweep == sweep) {
            let _ = writeln!(
                out,
                "| {} | {} | {:.0} % | {} | {} | {} | {:.0} % | {} |",
                sweep.label(s.value),
                s.method,
                100.0 * s.success_rate,
                fmt(s.median_delta_e, 3),
                fmt(s.median_recovery_error, 3),
                fmt(s.median_ms, 1),
                100.0 * s.flagged_rate,
                if s.flagged_failures.is_nan() {
                    "–".to_string()
                } else {
                    format!("{:.0} %", 100.0 * s.flagged_failures)
                }
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_csv_reads_back_with_a_csv_reader() {
        let run = Run {
            sweep: Sweep::Noise,
            value: 0.002,
            method: "lbfgs".into(),
            seed: 3,
            recovery_error: 0.05,
            delta_e: 0.4,
            ms: 1.25,
            success: true,
            flagged: true,
            warnings: vec![
                "residual is large, check the \"guard\" band".to_string(),
                "did not converge".to_string(),
            ],
        };
        let text = runs_to_csv(&[run]);
        let mut reader = csv::Reader::from_reader(text.as_bytes());
        let columns = reader.headers().unwrap().len();
        let records: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
        assert_eq!(records.len(), 1);
        let record = &records[0];
        assert_eq!(record.len(), columns);
        assert_eq!(&record[0], Sweep::Noise.id());
        assert_eq!(&record[1], "0.002");
        assert_eq!(&record[2], "lbfgs");
        assert_eq!(&record[3], "3");
        // Quotes inside a warning become apostrophes; the comma stays inside the field.
        assert_eq!(
            &record[10],
            "residual is large, check the 'guard' band | did not converge"
        );
    }
}
