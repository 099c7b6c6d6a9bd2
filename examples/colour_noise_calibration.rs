//! Whether the colour noise the fits allow for matches what `fluorite class` draws: per
//! case and light, the χ² (three degrees of freedom) of the measured colour (the case's
//! cells, missing ones filled from the truth) against the truth's colour, in the Lab
//! covariance `fit::assess` propagates from the cells' σ (the true σ and the σ the fit
//! estimates). Where only noise separates the two, χ² follows the χ² distribution with
//! three degrees of freedom (mean 3, 99th percentile 11.34); crosstalk next to the
//! diagonal, which moves the measured colour as no noise does, is drawn as the class
//! draws it, or left out with `--no-crosstalk`.
//!
//! `cargo run --release --example colour_noise_calibration -- [SEED ...] [--no-crosstalk]`
//! prints one CSV line per case and light and, on stderr, the summary per light in the
//! true σ and in the σ the fit estimates (default: the class's seed).

use fluorite::colour::{Light, PatchColorimeter, delta_e2000};
use fluorite::evaluate::class::{ClassConfig, DEFAULT_SEED, draw, parse_seed};
use fluorite::fit::assess;
use fluorite::fit::data::FitData;
use fluorite::numeric::quantile;

fn main() -> anyhow::Result<()> {
    let arguments: Vec<String> = std::env::args().skip(1).collect();
    let without_crosstalk = arguments.iter().any(|a| a == "--no-crosstalk");
    let mut seeds: Vec<u64> = arguments
        .iter()
        .filter(|a| !a.starts_with("--"))
        .map(|a| parse_seed(a))
        .collect::<Result<_, String>>()
        .map_err(anyhow::Error::msg)?;
    if seeds.is_empty() {
        seeds.push(DEFAULT_SEED);
    }
    let lights = Light::standard();
    // Per σ (the true one, the fit's estimate), per light: the χ² of every case.
    let mut chi2_by_light = [
        vec![Vec::new(); lights.len()],
        vec![Vec::new(); lights.len()],
    ];
    println!(
        "seed,case,light,sigma,sigma_estimated,delta_e2000_measured_truth,noise_rms_delta_e2000,chi2,chi2_estimated_sigma"
    );
    for seed in seeds {
        let draws = draw(&ClassConfig {
            seed,
            ..ClassConfig::default()
        })?;
        for drawn in &draws.specs {
            let mut spec = drawn.clone();
            if without_crosstalk {
                spec.crosstalk = 0.0;
            }
            let (m, truth) = spec.generate()?;
            let data = FitData::new(&m, 0.0);
            let estimated = data.noise_sigma();
            let chi2 = assess::misfit_colour_chi2(&m, &truth, &data, &lights, spec.noise_sigma);
            let chi2_estimated = assess::misfit_colour_chi2(&m, &truth, &data, &lights, estimated);
            let rms = assess::colour_noise_delta_e2000(&m, &truth, &data, &lights, estimated);
            let true_cells = fluorite::model::predict_like(&truth, &m).to_per_bin();
            let measured = m.to_per_bin().filled_from(&true_cells);
            for (l, light) in lights.iter().enumerate() {
                let pc = PatchColorimeter::cached(light, &m.excitation_nm, &m.emission_nm);
                let de = delta_e2000(pc.lab(&measured), pc.lab(&true_cells));
                println!(
                    "{seed:#X},{},{},{:.4e},{estimated:.4e},{de:.3},{:.3},{:.3},{:.3}",
                    spec.name, light.name, spec.noise_sigma, rms[l], chi2[l], chi2_estimated[l]
                );
                chi2_by_light[0][l].push(chi2[l]);
                chi2_by_light[1][l].push(chi2_estimated[l]);
            }
        }
    }
    for (sigma, by_light) in ["true σ", "estimated σ"].iter().zip(&chi2_by_light) {
        for (light, values) in lights.iter().zip(by_light) {
            let n = values.len();
            let mean = values.iter().sum::<f64>() / n.max(1) as f64;
            let beyond = values.iter().filter(|&&x| x > 11.34).count();
            eprintln!(
                "{} ({sigma}): {n} cases, χ² mean {mean:.2} (noise alone: 3), median {:.2} (2.37), p90 {:.2} (6.25), p99 {:.2} (11.34), beyond 11.34: {beyond} ({:.1} expected)",
                light.name,
                quantile(values, 0.5),
                quantile(values, 0.9),
                quantile(values, 0.99),
                0.01 * n as f64
            );
        }
    }
    Ok(())
}
