//! One-dye matrices written without crosstalk, fitted with the grid fit (`--model
//! tabulated`): how many get a crosstalk correction removed from their cells, and what
//! each is worth in the measured colour. A fluorescence tail next to the diagonal can
//! pass for crosstalk in rows whose cells beyond the neighbour are quiet; the truth here
//! is that there is none.
//!
//! `cargo run --release --example crosstalk_false_positives`: 2,268 matrices (absorption
//! peak 320–680 nm, widths 15/40 nm, Stokes shift 15/40/90 nm, emission width 15/35 nm,
//! c 0.02/0.2/1, noise σ 1e-4/1e-3/3e-3, steps 5/10/20 nm), a line per correction.

use fluorite::fit::{FitOptions, FitOutcome, ModelChoice, fit};
use fluorite::synth::SynthSpec;
use rayon::prelude::*;

fn main() {
    let mut specs = Vec::new();
    for &peak in &[320.0_f64, 380.0, 440.0, 500.0, 560.0, 620.0, 680.0] {
        for &absorption_width in &[15.0, 40.0] {
            for &shift in &[15.0, 40.0, 90.0] {
                for &emission_width in &[15.0, 35.0] {
                    for &concentration in &[0.02, 0.2, 1.0] {
                        for &sigma in &[1e-4, 1e-3, 3e-3] {
                            for &step in &[5.0, 10.0, 20.0] {
                                let emission = (peak + shift).clamp(390.0, 770.0);
                                let mut spec = SynthSpec::one_band_dye(
                                    (peak, absorption_width),
                                    (emission, emission_width),
                                    concentration,
                                    sigma,
                                    step,
                                    specs.len() as u64 + 1,
                                );
                                spec.name = format!(
                                    "peak {peak} ± {absorption_width}, emission {emission} ± {emission_width}, c {concentration}, σ {sigma}, step {step}"
                                );
                                specs.push(spec);
                            }
                        }
                    }
                }
            }
        }
    }
    let options = FitOptions {
        model: ModelChoice::Tabulated,
        ..FitOptions::default()
    };
    let results: Vec<Option<String>> = specs
        .par_iter()
        .map(|spec| {
            let outcome = spec.generate().and_then(|(m, _)| fit(&m, &options));
            match outcome {
                Ok(FitOutcome::Material(material)) => {
                    let x = material.fit.as_ref()?.crosstalk.as_ref()?;
                    let worth = x.delta_e2000.values().fold(0.0_f64, |a, b| a.max(*b));
                    x.removed.then(|| {
                        format!(
                            "{}: below {:+.4} ± {:.4}, above {:+.4} ± {:.4} from {} rows, worth ΔE2000 {worth:.3}",
                            spec.name, x.below, x.below_error, x.above, x.above_error, x.quiet_rows
                        )
                    })
                }
                Ok(FitOutcome::Shapes(_)) => Some(format!("{}: no material", spec.name)),
                Err(e) => Some(format!("{}: {e}", spec.name)),
            }
        })
        .collect();
    let corrected: Vec<&String> = results.iter().flatten().collect();
    println!(
        "{} one-dye matrices without crosstalk, {} with a correction removed",
        specs.len(),
        corrected.len()
    );
    for line in corrected {
        println!("  {line}");
    }
}
