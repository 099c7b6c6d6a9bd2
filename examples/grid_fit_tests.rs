//! Calibrates the two noise tests the default fit and the noise-aware search put to the
//! one-fluorophore grid fit, on `fluorite class` draws whose truth is known: per true
//! number of dyes, the spread of
//!
//! - its misfit colour χ² (`assess::misfit_colour_chi2`, the largest over the lights the
//!   default fit judges), held to `assess::NOISE_CHI2_LIMIT` = 25.9 before a miss counts
//!   as the noise's doing;
//! - the energy of the non-negative rank-1 component its residual holds away from the
//!   diagonal (`assess::second_fluorophore_energy`, in units of σ²(√m + √n)²), above
//!   `assess::SECOND_FLUOROPHORE_ENERGY` = 5 a second fluorophore.
//!
//! Where one dye made the matrix the grid model is right, so both mostly follow the noise;
//! where two did, they should not. `cargo run --release --example grid_fit_tests -- [SEED
//! ...]` (decimal or 0x hex; default: the class's default seed).

use fluorite::colour::Light;
use fluorite::evaluate::class::{ClassConfig, draw, parse_seed};
use fluorite::fit::assess::{
    NOISE_CHI2_LIMIT, SECOND_FLUOROPHORE_ENERGY, misfit_colour_chi2, second_fluorophore_energy,
};
use fluorite::fit::data::FitData;
use fluorite::fit::escalate::judged_light_names;
use fluorite::fit::{FitOptions, FitOutcome, ModelChoice, fit};
use fluorite::model::predict_like;
use fluorite::numeric::quantile;

/// `n`, median, p90, p99, max and the share above `limit`, as one table row.
fn row(what: &str, values: &[f64], limit: f64) -> String {
    let above = values.iter().filter(|v| **v > limit).count();
    format!(
        "| {what} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {above} ({:.1} %) |",
        values.len(),
        quantile(values, 0.5),
        quantile(values, 0.9),
        quantile(values, 0.99),
        values.iter().cloned().fold(f64::NAN, f64::max),
        100.0 * above as f64 / values.len().max(1) as f64
    )
}

fn main() {
    let seeds: Vec<u64> = {
        let given: Vec<u64> = std::env::args()
            .skip(1)
            .filter_map(|a| parse_seed(&a).ok())
            .collect();
        if given.is_empty() {
            vec![ClassConfig::default().seed]
        } else {
            given
        }
    };
    let grid = FitOptions {
        model: ModelChoice::Tabulated,
        ..FitOptions::default()
    };
    // Per true dye count (1, 2): χ² and second-fluorophore energy of each grid fit.
    let mut chi2: [Vec<f64>; 2] = Default::default();
    let mut second: [Vec<f64>; 2] = Default::default();
    for &seed in &seeds {
        let draws = match draw(&ClassConfig {
            seed,
            ..ClassConfig::default()
        }) {
            Ok(d) => d,
            Err(e) => {
                eprintln!("seed {seed:#X}: {e}");
                continue;
            }
        };
        for spec in &draws.specs {
            let Ok((m, truth)) = spec.generate() else {
                continue;
            };
            let dyes = truth.fluorophores.len();
            if !(1..=2).contains(&dyes) {
                continue;
            }
            let Ok(FitOutcome::Material(material)) = fit(&m, &grid) else {
                continue;
            };
            let Some(report) = material.fit.as_ref() else {
                continue;
            };
            if material.fluorophores.is_empty() {
                continue;
            }
            let data = FitData::as_fitted(&m, report);
            let lights: Vec<Light> = judged_light_names(&m)
                .iter()
                .filter_map(|l| Light::builtin(l))
                .collect();
            let sigma = report.noise_sigma;
            let worst = misfit_colour_chi2(&m, &material, &data, &lights, sigma)
                .into_iter()
                .fold(f64::NAN, f64::max);
            chi2[dyes - 1].push(worst);
            second[dyes - 1].push(second_fluorophore_energy(
                &predict_like(&material, &m),
                &m,
                &data,
                sigma,
            ));
        }
    }
    let names: Vec<String> = seeds.iter().map(|s| format!("{s:#X}")).collect();
    println!(
        "seeds {}; the grid fit of every fluorescent draw\n",
        names.join(", ")
    );
    println!("| grid fit of | fits | median | p90 | p99 | max | above the limit |");
    println!("|---|---|---|---|---|---|---|");
    for (k, values) in chi2.iter().enumerate() {
        println!(
            "{}",
            row(
                &format!(
                    "{} dye(s): misfit colour χ² (limit {NOISE_CHI2_LIMIT})",
                    k + 1
                ),
                values,
                NOISE_CHI2_LIMIT
            )
        );
    }
    for (k, values) in second.iter().enumerate() {
        println!(
            "{}",
            row(
                &format!(
                    "{} dye(s): second-fluorophore energy (limit {SECOND_FLUOROPHORE_ENERGY})",
                    k + 1
                ),
                values,
                SECOND_FLUOROPHORE_ENERGY
            )
        );
    }
}
