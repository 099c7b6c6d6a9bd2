//! How far `fluorite class`'s truth (each case's material sampled on its own grids, linear
//! between samples, as the tabulated model represents it) lies from the Gaussian bands it
//! samples, evaluated every 1 nm; and, given the folder `fluorite class --dump DIR` wrote,
//! each method's fit against both (the cases as the dump's `NAME.synth.json` holds them,
//! so a `--truth-bands wavenumber` dump is judged against its own truths). Per case: name, grid step (nm), true fluorophores, the
//! gap (largest ΔE2000 over d65, a, f11 and uv), then per method its ΔE2000 to the sampled
//! truth and to the bands.
//!
//! `cargo run --release --example class_truth_gap -- [SEED] [DUMP_DIR] [METHODS]`
//! (default: the class's seed, no fits; METHODS comma-separated, default
//! grid,search,search-noise,default).

use std::path::Path;

use fluorite::colour::Light;
use fluorite::evaluate::class::{ClassConfig, DEFAULT_SEED, draw, parse_seed};
use fluorite::evaluate::stability::material_delta_e;
use fluorite::material::Material;
use fluorite::parametric::SpectralForm;
use fluorite::spectrum::{Spectrum, uniform_grid};
use fluorite::synth::SynthSpec;

/// The truth's bands and sigmoid evaluated every 1 nm over the case's grids, scaled as its
/// samples are (`SynthSpec::truth_with_forms`).
fn banded_truth(spec: &SynthSpec) -> anyhow::Result<Material> {
    let sampled = spec.truth_with_forms()?;
    let first_last = |g: &[f64]| (g[0], g[g.len() - 1]);
    let (ex0, ex1) = first_last(&spec.excitation_nm);
    let (em0, em1) = first_last(&spec.emission_nm);
    let (ex, em) = (uniform_grid(ex0, ex1, 1.0), uniform_grid(em0, em1, 1.0));
    let on = |grid: &[f64], form: &SpectralForm, what: &str| {
        Spectrum::new(
            grid.to_vec(),
            grid.iter().map(|&l| form.eval(l)).collect(),
            what,
        )
    };
    let mut fluorophores = sampled.fluorophores.clone();
    if let Some(forms) = &sampled.forms {
        for (f, form) in fluorophores.iter_mut().zip(&forms.fluorophores) {
            f.absorption = on(&ex, &form.absorption, "absorption")?;
            f.emission = on(&em, &form.emission, "emission")?;
        }
    }
    let reflectance: Vec<f64> = em
        .iter()
        .map(|&l| {
            let t =
                1.0 / (1.0 + (-(l - spec.reflectance_edge_nm) / spec.reflectance_width_nm).exp());
            spec.reflectance_low + (spec.reflectance_high - spec.reflectance_low) * t
        })
        .collect();
    let reflectance = Spectrum::new(em, reflectance, "reflectance")?;
    Ok(Material::new(spec.name.clone(), reflectance, fluorophores))
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let seed = args.get(1).map_or(Ok(DEFAULT_SEED), |s| {
        parse_seed(s).map_err(anyhow::Error::msg)
    })?;
    let dump = args.get(2);
    let methods = args
        .get(3)
        .cloned()
        .unwrap_or_else(|| "grid,search,search-noise,default".into());
    let lights = Light::standard();
    let draws = draw(&ClassConfig {
        seed,
        ..ClassConfig::default()
    })?;
    for drawn in &draws.specs {
        // A dump holds the specs its fits were made from (`--truth-bands` included).
        let dumped = dump
            .map(|dir| format!("{dir}/{}.synth.json", drawn.name))
            .filter(|path| Path::new(path).exists());
        let spec: &SynthSpec = &match dumped {
            Some(path) => serde_json::from_str(&std::fs::read_to_string(path)?)?,
            None => drawn.clone(),
        };
        let sampled = spec.truth()?;
        let banded = banded_truth(spec)?;
        let step = spec.excitation_nm[1] - spec.excitation_nm[0];
        let mut line = format!(
            "{} {step} {} {:.4}",
            spec.name,
            sampled.fluorophores.len(),
            material_delta_e(&sampled, &banded, &lights)
        );
        if let Some(dir) = dump {
            for method in methods.split(',') {
                let path = format!("{dir}/{}.{method}.json", spec.name);
                let fitted = Material::load(Path::new(&path))?;
                line += &format!(
                    " {method} {:.4} {:.4}",
                    material_delta_e(&fitted, &sampled, &lights),
                    material_delta_e(&fitted, &banded, &lights)
                );
            }
        }
        println!("{line}");
    }
    Ok(())
}
