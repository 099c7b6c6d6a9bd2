//! Speed against accuracy: every method on every input, timed over repeated runs.
//!
//! Accuracy is what `fit` reports against the input itself: the largest ΔE2000 over the
//! standard lights (measured against fitted patch colour) and the relative residual of
//! the fluorescent (Stokes-side) cells. Inputs without a calibrated diagonal (solution
//! EEMs) have no colour; their ΔE is NaN.

use std::fmt::Write as _;
use std::time::Instant;

use crate::error::Result;
use crate::fit::{FitOutcome, fit};
use crate::measurement::Measurement;

use super::{Method, median};

/// One (input, method) cell of the benchmark.
#[derive(Debug, Clone)]
pub struct BenchRow {
    /// Input name (file stem).
    pub input: String,
    /// Method name.
    pub method: String,
    /// Timed runs.
    pub runs: usize,
    /// Median wall time per fit (ms).
    pub median_ms: f64,
    /// Fastest run (ms).
    pub min_ms: f64,
    /// Slowest run (ms).
    pub max_ms: f64,
    /// Largest ΔE2000 over the lights (NaN without colour).
    pub max_delta_e: f64,
    /// Relative residual of the fluorescent cells.
    pub rel_residual: f64,
    /// Whether the solver converged.
    pub converged: bool,
    /// Solver iterations.
    pub iterations: u64,
    /// Number of warnings the fit issued.
    pub warnings: usize,
    /// Whether no other method on this input is at least as fast and as accurate (ΔE,
    /// or the residual when there is no ΔE) and strictly better in one.
    pub pareto: bool,
}

/// Fits every input with every method `repeats` times (sequentially, so runs do not
/// compete for cores) and tabulates time and accuracy. Parametric methods skip inputs
/// without a calibrated diagonal (they would refuse them).
pub fn run(inputs: &[Measurement], methods: &[Method], repeats: usize) -> Result<Vec<BenchRow>> {
    crate::limits::check_runs(repeats, "--repeats")?;
    let mut rows = Vec::new();
    for m in inputs {
        for method in methods {
            // Parametric models need a calibrated diagonal (reflectance).
            let calibrated = m.has_diagonal && !m.arbitrary_scale;
            if method.model != crate::fit::ModelChoice::Tabulated && !calibrated {
                continue;
            }
            let options = method.options();
            let mut times = Vec::with_capacity(repeats);
            let mut last = None;
            for _ in 0..repeats {
                let t = Instant::now();
                let outcome = fit(m, &options)?;
                times.push(t.elapsed().as_secs_f64() * 1e3);
                last = Some(outcome);
            }
            let outcome = last.expect("repeats ≥ 1");
            let report = outcome.report();
            let max_delta_e = match &outcome {
                FitOutcome::Material(_) => report
                    .delta_e2000
                    .values()
                    .copied()
                    .fold(f64::NAN, f64::max),
                FitOutcome::Shapes(_) => f64::NAN,
            };
            rows.push(BenchRow {
                input: m.name.clone(),
                method: method.name.clone(),
                runs: repeats,
                median_ms: median(&times),
                min_ms: times.iter().copied().fold(f64::INFINITY, f64::min),
                max_ms: times.iter().copied().fold(0.0, f64::max),
                max_delta_e,
                rel_residual: report.rel_residual_fluorescence,
                converged: report.converged,
                iterations: report.iterations,
                warnings: report.warnings.len(),
                pareto: false,
            });
        }
    }
    mark_pareto(&mut rows);
    Ok(rows)
}

/// The error a row is judged by: ΔE when the input has colour, else the residual.
pub fn error_of(row: &BenchRow) -> f64 {
    if row.max_delta_e.is_finite() {
        row.max_delta_e
    } else {
        row.rel_residual
    }
}

/// Marks, per input, the rows on the Pareto front of (median time, error).
pub fn mark_pareto(rows: &mut [BenchRow]) {
    let snapshot: Vec<(String, f64, f64)> = rows
        .iter()
        .map(|r| (r.input.clone(), r.median_ms, error_of(r)))
        .collect();
    for (k, row) in rows.iter_mut().enumerate() {
        let (input, t, e) = &snapshot[k];
        row.pareto = !snapshot.iter().enumerate().any(|(l, (i, t2, e2))| {
            l != k && i == input && t2 <= t && e2 <= e && (t2 < t || e2 < e)
        });
    }
}

/// The CSV header of [`to_csv`].
pub const CSV_HEADER: &str = "input,method,runs,median_ms,min_ms,max_ms,max_delta_e2000,rel_residual_fluorescence,converged,iterations,warnings,pareto";

/// The table as CSV (one row per input and method).
pub fn to_csv(rows: &[BenchRow]) -> String {
    let mut out = String::from(CSV_HEADER);
    out.push('\n');
    for r in rows {
        let _ = writeln!(
            out,
            "{},{},{},{:.6},{:.6},{:.6},{:.6e},{:.6e},{},{},{},{}",
            r.input,
            r.method,
            r.runs,
            r.median_ms,
            r.min_ms,
            r.max_ms,
            r.max_delta_e,
            r.rel_residual,
            r.converged,
            r.iterations,
            r.warnings,
            r.pareto
        );
    }
    out
}

/// The table as Markdown, for terminals and reports.
pub fn to_markdown(rows: &[BenchRow]) -> String {
    let mut out = String::from(
        "| input | method | median ms (min–max) | max ΔE2000 | rel. residual | converged | iterations | Pareto |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            out,
            "| {} | {} | {:.3} ({:.3}–{:.3}) | {} | {:.4} | {} | {} | {} |",
            r.input,
            r.method,
            r.median_ms,
            r.min_ms,
            r.max_ms,
            if r.max_delta_e.is_finite() {
                format!("{:.3}", r.max_delta_e)
            } else {
                "–".into()
            },
            r.rel_residual,
            if r.converged { "yes" } else { "no" },
            r.iterations,
            if r.pareto { "★" } else { "" }
        );
    }
    out
}
