//! `--band-axis`: the model search runs with its Gaussian bands on wavenumber and on
//! wavelength and keeps the result that meets its rule, of two the one of lower BIC.
//! Judged against the truth the synthetic matrices were made from (bands Gaussian in
//! wavelength, `fluorite::synth`), never against the fit's own report.

use std::process::Command;

use fluorite::Material;
use fluorite::colour::Light;
use fluorite::evaluate::stability::{material_delta_e, recovery_error};
use fluorite::fit::{BandAxisChoice, FitOptions, FitOutcome, ModelChoice, fit};
use fluorite::synth::SynthSpec;

use crate::common;

fn search(band_axis: BandAxisChoice) -> FitOptions {
    FitOptions {
        model: ModelChoice::Auto,
        max_delta_e: Some(1.0),
        band_axis,
        ..FitOptions::default()
    }
}

fn material(outcome: FitOutcome) -> Material {
    match outcome {
        FitOutcome::Material(m) => *m,
        FitOutcome::Shapes(_) => panic!("expected a material"),
    }
}

/// Broad one-band dyes whose bands are Gaussian in wavelength (σ 35–50 nm: over the
/// 100–200 nm such a band spans, its shape in wavenumber is visibly skewed), at σ 3·10⁻⁴
/// on the BFC-450 grid. The search on both axes fits them on wavelength, names the axis
/// and why, and ends nearer the truth than the search on wavenumber alone: in colour
/// (median over the draws) and in the recovered spectra (c·Q·a and e, relative L2) on
/// every draw. `-- --nocapture` prints each draw.
#[test]
fn dyes_gaussian_in_wavelength_are_fitted_on_wavelength_and_nearer_their_truth() {
    let lights = Light::standard();
    let dyes = [
        ((400.0, 45.0), (480.0, 40.0)),
        ((450.0, 50.0), (540.0, 45.0)),
        ((360.0, 35.0), (440.0, 50.0)),
        ((520.0, 40.0), (600.0, 45.0)),
    ];
    let (mut both_colour, mut wavenumber_colour) = (Vec::new(), Vec::new());
    for (n, (absorption, emission)) in dyes.into_iter().enumerate() {
        let spec = SynthSpec::one_band_dye(absorption, emission, 0.5, 3e-4, 10.0, 40 + n as u64);
        let (m, truth) = spec.generate().unwrap();
        let both = material(fit(&m, &search(BandAxisChoice::Both)).unwrap());
        let wavenumber = material(fit(&m, &search(BandAxisChoice::Wavenumber)).unwrap());
        let report = both.fit.as_ref().unwrap();
        let searched = report.model_search.as_ref().unwrap();
        let (de_both, de_wn) = (
            material_delta_e(&both, &truth, &lights),
            material_delta_e(&wavenumber, &truth, &lights),
        );
        let (rec_both, rec_wn) = (
            recovery_error(&both, &truth),
            recovery_error(&wavenumber, &truth),
        );
        println!(
            "{}: both {} ΔE {de_both:.3} recovery {rec_both:.4}; wavenumber {} ΔE {de_wn:.3} recovery {rec_wn:.4}; {}",
            spec.name,
            report.model,
            wavenumber.fit.as_ref().unwrap().model,
            searched.band_axis.as_deref().unwrap_or("–")
        );
        assert!(report.model.contains("@wavelength"), "{}", report.model);
        let words = searched.band_axis.as_deref().unwrap();
        assert!(words.starts_with("wavelength: "), "{words}");
        // Both ladders are listed, each candidate named with its axis.
        assert!(searched.candidates.iter().any(|c| !c.model.contains('@')));
        assert!(
            searched
                .candidates
                .iter()
                .any(|c| c.model.contains("@wavelength"))
        );
        // The search on one axis says nothing of axes and tries that axis only.
        let single = wavenumber
            .fit
            .as_ref()
            .unwrap()
            .model_search
            .as_ref()
            .unwrap();
        assert!(single.band_axis.is_none());
        assert!(single.candidates.iter().all(|c| !c.model.contains('@')));
        assert!(
            rec_both < rec_wn,
            "{}: recovery {rec_both} against {rec_wn}",
            spec.name
        );
        both_colour.push(de_both);
        wavenumber_colour.push(de_wn);
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        0.5 * (v[(v.len() - 1) / 2] + v[v.len() / 2])
    };
    let (b, w) = (median(both_colour), median(wavenumber_colour));
    assert!(
        b < w,
        "median ΔE2000 to the truth: both {b:.3}, wavenumber {w:.3}"
    );
}

/// The command line: `--band-axis` takes both (the default), wavenumber or wavelength;
/// the printed search names the axis kept only where it ran on both, and lists the
/// candidates of the axes it ran; a model that names one structure keeps its name's axis,
/// and `--band-axis` beside it is refused.
#[test]
fn the_command_line_takes_the_band_axis() {
    let out = common::temp_dir("cli");
    let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/green-dye.csv");
    let run = |extra: &[&str]| {
        let output = Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .arg("fit")
            .arg(&input)
            .args(["--max-delta-e", "1", "-o"])
            .arg(out.join("fit.json"))
            .args(extra)
            .output()
            .unwrap();
        assert!(output.status.success(), "{output:?}");
        String::from_utf8(output.stdout).unwrap()
    };
    let both = run(&[]);
    assert!(both.contains("band axis: "), "{both}");
    // The candidate rows of the printed search: each names its model first.
    let models = |printed: &str| -> Vec<String> {
        printed
            .lines()
            .filter_map(|l| l.trim_start().strip_prefix("gaussian:"))
            .map(|l| l.split_whitespace().next().unwrap_or("").to_string())
            .collect()
    };
    assert!(models(&both).iter().any(|m| m.contains("@wavelength")));
    assert!(models(&both).iter().any(|m| !m.contains('@')));
    for axis in ["wavenumber", "wavelength"] {
        let printed = run(&["--band-axis", axis]);
        assert!(!printed.contains("band axis: "), "{printed}");
        let tried = models(&printed);
        assert!(!tried.is_empty(), "{printed}");
        assert!(
            tried
                .iter()
                .all(|m| m.contains("@wavelength") == (axis == "wavelength")),
            "{axis}: {tried:?}"
        );
    }
    let fixed = run(&["--model", "gaussian:1x1+rt"]);
    assert!(!fixed.contains("@wavelength"), "{fixed}");
    // A model that names one structure names its axis: --band-axis beside it is refused
    // and a value that is no axis is refused with the axes named.
    let refused = |extra: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .arg("fit")
            .arg(&input)
            .args(extra)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{extra:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let both_given = refused(&["--model", "gaussian:1x1+rt", "--band-axis", "wavelength"]);
    assert!(both_given.contains("@wavelength"), "{both_given}");
    // Refused before any file is read or folder made: once, however many inputs.
    let folder = out.join("never-made");
    let twice = refused(&[
        input.to_str().unwrap(),
        "--model",
        "gaussian:1x1+rt",
        "--band-axis",
        "wavelength",
        "-o",
        &format!("{}/", folder.display()),
    ]);
    assert_eq!(twice.matches("--band-axis: ").count(), 1, "{twice}");
    assert!(!folder.exists());
    let wrong = refused(&["--max-delta-e", "1", "--band-axis", "energy"]);
    assert!(wrong.contains("wavenumber"), "{wrong}");
}

/// The library refuses a band axis beside a model that names one structure (the model's
/// name says its axis), naming the option and how to mend the call, as the CLI prints it.
#[test]
fn a_band_axis_beside_a_fixed_model_is_refused_by_the_library() {
    let input = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/green-dye.csv");
    let m = fluorite::formats::read(&input, &Default::default()).unwrap();
    let options = FitOptions {
        model: "gaussian:1x1+rt".parse().unwrap(),
        band_axis: BandAxisChoice::Wavelength,
        ..FitOptions::default()
    };
    let error = fit(&m, &options).unwrap_err().to_string();
    assert!(error.starts_with("--band-axis: "), "{error}");
    assert!(error.contains("@wavelength"), "{error}");
    let on_its_own = FitOptions {
        band_axis: BandAxisChoice::Both,
        ..options
    };
    assert!(fit(&m, &on_its_own).is_ok());
}
