//! The fitted parameters as text lines beside the spectra figure's legend: k, c (with its
//! feasible interval), the yield of the fluorophore's form, the model and the gauge; for a
//! shapes-only fit (a matrix without a diagonal) only what it determines.

use super::Comparison;
use super::common::format_significant;
use crate::material::{Fluorophore, Material, YieldForm};

/// The yield line of a fluorophore: `Q = …, mean emission … nm` in the energy form;
/// `Φ = …, Q(λ) = … to …` (the energy yield Φ·λ/λ̄e over the absorbed wavelengths) in
/// the photon form.
pub(super) fn yield_line(f: &Fluorophore, tag: &str) -> String {
    let mean = f.emission_mean_nm();
    match f.yield_form {
        YieldForm::Energy => format!(
            "{tag}Q = {}, mean emission {} nm",
            format_significant(f.quantum_yield, 3),
            format_significant(mean, 3)
        ),
        YieldForm::Photon => {
            let a = &f.absorption;
            let first = a.value.iter().position(|&v| v > 0.0);
            let last = a.value.iter().rposition(|&v| v > 0.0);
            let range = match (first, last) {
                (Some(first), Some(last)) if mean.is_finite() => {
                    // The zero samples beside the absorbed ones bound the interval.
                    let lo = a.wavelength_nm[first.saturating_sub(1)];
                    let hi = a.wavelength_nm[(last + 1).min(a.len() - 1)];
                    format!(
                        ", Q(λ) {}–{}",
                        format_significant(f.energy_yield_with_mean(lo, mean), 2),
                        format_significant(f.energy_yield_with_mean(hi, mean), 2)
                    )
                }
                _ => String::new(),
            };
            format!(
                "{tag}Φ = {} (photon yield){range}",
                format_significant(f.quantum_yield, 3)
            )
        }
    }
}

/// Text lines with the fitted parameters.
pub(super) fn parameter_lines(material: &Material, comparison: Option<&Comparison>) -> Vec<String> {
    let mut lines = Vec::new();
    let several = material.fluorophores.len() > 1;
    // Three lines per fluorophore fit beside the legend for up to two of them.
    let compact = material.fluorophores.len() > 2;
    // A shapes-only fit (no diagonal) knows k at most; c and Q were set for drawing.
    let shapes_only = comparison.is_some_and(|c| !c.measured.has_diagonal);
    for (n, f) in material.fluorophores.iter().enumerate() {
        if shapes_only {
            lines.push(match comparison {
                Some(c) if c.measured.arbitrary_scale => {
                    "shapes only: k on the data's arbitrary scale".to_string()
                }
                _ => format!("k = c·Q = {}", format_significant(f.k(), 3)),
            });
            continue;
        }
        let tag = if several {
            format!("[{}] ", n + 1)
        } else {
            String::new()
        };
        let symbol = match f.yield_form {
            YieldForm::Energy => "Q",
            YieldForm::Photon => "Φ",
        };
        if compact {
            lines.push(format!(
                "{tag}k = {}, c = {}, {symbol} = {}",
                format_significant(f.k(), 3),
                format_significant(f.concentration, 3),
                format_significant(f.quantum_yield, 3)
            ));
            continue;
        }
        lines.push(format!(
            "{tag}k = c·{symbol} = {}",
            format_significant(f.k(), 3)
        ));
        let range = f
            .concentration_range
            .map(|[lo, hi]| {
                format!(
                    " (feasible {}–{})",
                    format_significant(lo, 2),
                    format_significant(hi, 2)
                )
            })
            .unwrap_or_default();
        lines.push(format!(
            "{tag}c = {}{range}",
            format_significant(f.concentration, 3)
        ));
        lines.push(yield_line(f, &tag));
    }
    if let Some(forms) = &material.forms
        && forms.fluorophores.len() == material.fluorophores.len()
    {
        lines.push(format!("model {}", forms.model));
        lines.push("(forms drawn every 1 nm)".to_string());
    }
    // Without a diagonal there is no gauge to name: the last line says what is unknown.
    if let Some(fit) = &material.fit
        && !fit.gauge.is_empty()
        && !shapes_only
    {
        // Its first clause: the rest (the numbers, how to pin) is in the fit summary and
        // would run off the figure.
        let clause = fit.gauge.split(['(', ';']).next().unwrap_or("").trim();
        lines.push(format!("gauge: {clause}"));
    }
    if let Some(c) = comparison {
        lines.push(format!(
            "profiles from Stokes cells, guard {} nm",
            format_significant(c.guard_nm, 3)
        ));
        if !c.measured.has_diagonal {
            lines.push("no diagonal in the data: c, Q, r, d unknown".to_string());
        }
    }
    lines
}
