//! The colour noise the fits allow for against Monte Carlo: noise of known σ added to
//! every cell of a noise-free matrix and the patch's colour recomputed by the colorimeter
//! for each draw. `fit::assess::colour_noise` (a linearised propagation of the cells'
//! noise into CIELAB) against the RMS of |ΔLab| over the draws; the plain-reflector
//! gate's `fit::assess::colour_noise_chi2` against the χ² distribution with three degrees
//! of freedom it should follow; the fit's reported RMS ΔE2000 against the draws'.

use fluorite::colour::{Light, PatchColorimeter, delta_e2000};
use fluorite::fit::assess::{colour_noise, colour_noise_chi2};
use fluorite::fit::data::FitData;
use fluorite::numeric::SplitMix64;
use fluorite::synth::SynthSpec;

#[test]
fn propagated_colour_noise_matches_noise_draws() {
    let sigma = 1e-3;
    let draws = 400;
    for preset in ["green-dye", "red-pigment"] {
        let mut spec = SynthSpec::preset(preset).unwrap();
        spec.noise_sigma = 0.0;
        spec.crosstalk = 0.0;
        let (clean, _) = spec.generate().unwrap();
        let lights = Light::standard();
        let reference: Vec<_> = lights
            .iter()
            .map(|light| {
                PatchColorimeter::new(light, &clean.excitation_nm, &clean.emission_nm)
                    .xyz(&clean.to_per_bin())
            })
            .collect();
        let propagated = colour_noise(&FitData::new(&clean, 0.0), &lights, &reference, sigma);
        let mut rng = SplitMix64::new(17);
        for (light, expected) in lights.iter().zip(&propagated) {
            let pc = PatchColorimeter::new(light, &clean.excitation_nm, &clean.emission_nm);
            let lab = pc.lab(&clean);
            let mut sum = 0.0;
            for _ in 0..draws {
                let mut noisy = clean.clone();
                for v in noisy.values.iter_mut().filter(|v| v.is_finite()) {
                    *v += sigma * rng.normal();
                }
                let drawn = pc.lab(&noisy);
                sum += (0..3).map(|c| (drawn[c] - lab[c]).powi(2)).sum::<f64>();
            }
            let observed = (sum / draws as f64).sqrt();
            eprintln!(
                "{preset} under {}: propagated {expected:.3}, drawn {observed:.3}",
                light.name
            );
            // 400 draws estimate an RMS to about 4 %; the linearisation adds little at
            // these sizes.
            assert!(
                (expected / observed - 1.0).abs() < 0.15,
                "{preset} under {}: propagated {expected}, drawn {observed}",
                light.name
            );
        }
    }
}

/// The χ² of a colour difference that is cell noise alone, as the plain-reflector gate
/// judges it, follows the χ² distribution with three degrees of freedom: mean 3 (400
/// draws per light estimate it to ±0.12) and 1 % of draws beyond 11.34.
#[test]
fn colour_noise_chi2_of_noise_draws_follows_chi_square_with_three_degrees() {
    let sigma = 2e-3;
    let draws = 400;
    let lights = Light::standard();
    let (mut beyond, mut total) = (0, 0);
    for preset in ["green-dye", "red-pigment"] {
        let mut spec = SynthSpec::preset(preset).unwrap();
        spec.noise_sigma = 0.0;
        spec.crosstalk = 0.0;
        let (clean, _) = spec.generate().unwrap();
        let data = FitData::new(&clean, 0.0);
        let colorimeters: Vec<_> = lights
            .iter()
            .map(|light| PatchColorimeter::new(light, &clean.excitation_nm, &clean.emission_nm))
            .collect();
        let xyz = |m: &fluorite::Measurement| -> Vec<_> {
            colorimeters
                .iter()
                .map(|pc| pc.xyz(&m.to_per_bin()))
                .collect()
        };
        let truth = xyz(&clean);
        let mut rng = SplitMix64::new(29);
        let mut sums = vec![0.0; lights.len()];
        for _ in 0..draws {
            let mut noisy = clean.clone();
            for v in noisy.values.iter_mut().filter(|v| v.is_finite()) {
                *v += sigma * rng.normal();
            }
            let chi2 = colour_noise_chi2(&data, &lights, &xyz(&noisy), &truth, sigma);
            for (sum, x) in sums.iter_mut().zip(&chi2) {
                *sum += x;
                beyond += usize::from(*x > 11.34);
                total += 1;
            }
        }
        for (light, sum) in lights.iter().zip(&sums) {
            let mean = sum / draws as f64;
            eprintln!("{preset} under {}: mean χ² {mean:.2}", light.name);
            assert!(
                (mean - 3.0).abs() < 0.4,
                "{preset} under {}: {mean}",
                light.name
            );
        }
    }
    let share = beyond as f64 / total as f64;
    eprintln!("beyond 11.34: {beyond} of {total}");
    assert!((0.003..0.025).contains(&share), "{share}");
}

/// The fit's report of how well the measurement knows its own colour
/// (`fit.delta_e2000_noise`, RMS ΔE2000 per light) against Monte Carlo: the fit sees one
/// noisy matrix and estimates σ from it; the draws add noise of the true σ to the
/// noise-free matrix and take the RMS ΔE2000 of the patch against the noise-free one.
#[test]
fn reported_colour_noise_matches_noise_draws_in_delta_e2000() {
    let draws = 300;
    for (preset, sigma) in [
        ("green-dye", 2e-3),
        ("red-pigment", 1e-3),
        ("brightener", 5e-4),
    ] {
        let mut spec = SynthSpec::preset(preset).unwrap();
        spec.noise_sigma = sigma;
        spec.crosstalk = 0.0;
        spec.missing_fraction = 0.0;
        let (measured, _) = spec.generate().unwrap();
        let material =
            match fluorite::fit::fit(&measured, &fluorite::fit::FitOptions::default()).unwrap() {
                fluorite::fit::FitOutcome::Material(m) => *m,
                _ => panic!("{preset}: expected a material"),
            };
        let reported = &material.fit.as_ref().unwrap().delta_e2000_noise;
        spec.noise_sigma = 0.0;
        let (clean, _) = spec.generate().unwrap();
        let clean = clean.to_per_bin();
        let mut rng = SplitMix64::new(29);
        for light in Light::standard() {
            let pc = PatchColorimeter::new(&light, &clean.excitation_nm, &clean.emission_nm);
            let lab = pc.lab(&clean);
            let mut sum = 0.0;
            for _ in 0..draws {
                let mut noisy = clean.clone();
                for v in noisy.values.iter_mut().filter(|v| v.is_finite()) {
                    *v += sigma * rng.normal();
                }
                sum += delta_e2000(pc.lab(&noisy), lab).powi(2);
            }
            let observed = (sum / draws as f64).sqrt();
            let expected = reported[&light.name];
            eprintln!(
                "{preset} under {}: reported {expected:.3}, drawn {observed:.3}",
                light.name
            );
            // 300 draws estimate an RMS to about 4 %, σ's estimate from the anti-Stokes
            // cells adds a few %, the linearisation little at these sizes.
            let ratio = expected / observed;
            assert!(
                (ratio - 1.0).abs() < 0.15,
                "{preset} under {}: reported {expected}, drawn {observed}",
                light.name
            );
        }
    }
}
