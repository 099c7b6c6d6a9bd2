//! The UV-tail pigment class ([`SynthSpec::uv_tail_pigment`]) against its truth: per case
//! the one-fluorophore grid fit (`--model tabulated`), the default fit and the model
//! search (`--max-delta-e 1`, all four lights), the same search with
//! `--noise-aware-bound`, each as its largest ΔE2000 against the
//! truth under d65, a and f11, then under uv, and (in brackets) under uv against the
//! matrix as measured.
//!
//! `cargo run --release --example uv_tail -- [CASES] [SEED]` (default 40 cases, seed 11;
//! every second case carries the weak UV-excited blue emitter). With `UVTAIL_DUMP=DIR`
//! it writes each case's matrix, truth and spec there.

use fluorite::Material;
use fluorite::colour::Light;
use fluorite::evaluate::stability::material_delta_e;
use fluorite::fit::{FitOptions, FitOutcome, ModelChoice, fit};
use fluorite::formats::{RowsAre, write_wide_csv};
use fluorite::numeric::SplitMix64;
use fluorite::synth::SynthSpec;

/// Model, worst ΔE2000 against the truth under d65/a/f11 and under uv, uv as measured.
fn judge(outcome: fluorite::Result<FitOutcome>, truth: &Material) -> (String, f64, f64, f64) {
    let visible: Vec<Light> = ["d65", "a", "f11"]
        .iter()
        .map(|l| Light::builtin(l).expect("built in"))
        .collect();
    let uv = [Light::builtin("uv").expect("built in")];
    match outcome {
        Ok(FitOutcome::Material(fitted)) => {
            let report = fitted.fit.as_ref().expect("fits carry a report");
            (
                report.model.clone(),
                material_delta_e(&fitted, truth, &visible),
                material_delta_e(&fitted, truth, &uv),
                report.delta_e2000.get("uv").copied().unwrap_or(f64::NAN),
            )
        }
        _ => ("failed".into(), f64::INFINITY, f64::INFINITY, f64::NAN),
    }
}

fn main() {
    let mut args = std::env::args().skip(1);
    let cases: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(40);
    let seed: u64 = args.next().and_then(|a| a.parse().ok()).unwrap_or(11);
    let dump = std::env::var("UVTAIL_DUMP").ok();
    let grid = FitOptions {
        model: ModelChoice::Tabulated,
        ..FitOptions::default()
    };
    let search = FitOptions {
        model: ModelChoice::Auto,
        max_delta_e: Some(1.0),
        ..FitOptions::default()
    };
    let noise_aware = FitOptions {
        noise_aware_bound: true,
        ..search.clone()
    };
    let mut rng = SplitMix64::new(seed);
    println!(
        "| case | fluorophores | σ | grid: truth vis / uv (uv measured) | default | search | search, noise-aware |"
    );
    println!("|---|---|---|---|---|---|---|");
    for index in 0..cases {
        let spec = SynthSpec::uv_tail_pigment(&mut rng, index, index % 2 == 1);
        let Ok((m, truth)) = spec.generate() else {
            println!("| {} | refused by the synthesiser | | | | | |", spec.name);
            continue;
        };
        if let Some(dir) = &dump {
            let write = |ext: &str, text: String| {
                std::fs::write(format!("{dir}/{}.{ext}", spec.name), text).expect("writable")
            };
            write("csv", write_wide_csv(&m, RowsAre::Excitation));
            write(
                "truth.json",
                serde_json::to_string_pretty(&truth).expect("json"),
            );
            write(
                "synth.json",
                serde_json::to_string_pretty(&spec).expect("json"),
            );
        }
        let cell = |(model, vis, uv, measured): (String, f64, f64, f64)| {
            format!("{model} {vis:.2} / {uv:.2} ({measured:.2})")
        };
        println!(
            "| {} | {} | {:.1e} | {} | {} | {} | {} |",
            spec.name,
            truth.fluorophores.len(),
            spec.noise_sigma,
            cell(judge(fit(&m, &grid), &truth)),
            cell(judge(fit(&m, &FitOptions::default()), &truth)),
            cell(judge(fit(&m, &search), &truth)),
            cell(judge(fit(&m, &noise_aware), &truth)),
        );
    }
}
