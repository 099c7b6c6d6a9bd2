//! `check`: every fitted and synthetic material passes; each law broken alone is named,
//! in the report and through the CLI's exit code.

use std::path::Path;
use std::process::Command;

use fluorite::check::{Law, Status, check_file, check_material};
use fluorite::fit::{FitOptions, FitOutcome, fit};
use fluorite::formats::{ReadOptions, read};
use fluorite::material::{Fluorophore, Material, YieldForm};
use fluorite::parametric::SpectralForm;
use fluorite::spectrum::Spectrum;
use fluorite::synth::{PRESETS, SynthSpec};

use crate::common;

/// `fluorite check`'s text report on `material` (saved in a folder named by `tag`).
fn check_text(material: &Material, tag: &str) -> String {
    let dir = common::temp_dir(tag);
    let path = dir.join("material.json");
    material.save(&path).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_fluorite"))
        .arg("check")
        .arg(&path)
        .output()
        .unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn every_fitted_measured_material_passes() {
    let Some(files) = common::measured_files() else {
        return;
    };
    assert!(files.len() >= 6);
    for path in files {
        let m = read(&path, &ReadOptions::default()).unwrap();
        let FitOutcome::Material(material) = fit(&m, &FitOptions::default()).unwrap() else {
            panic!("{}: expected a material", path.display());
        };
        let report = check_material(&material);
        let energy = report.law(Law::Energy);
        let photons = report.law(Law::Photons);
        println!(
            "{}: valid {} energy margin {:.3e} at {:?} nm, photon margin {:.3e}, Φ range {:?}",
            material.name,
            report.valid,
            energy.margin,
            energy.worst_nm,
            photons.margin,
            report
                .fluorophores
                .first()
                .and_then(|f| f.photon_yield_range)
        );
        assert!(report.valid, "{}", report.to_json());
        // The block the file carries is what the laws report (both from the law engine).
        let c = material.conservation_margins();
        assert_eq!(energy.worst_value, c.max_energy_albedo);
        assert_eq!(photons.worst_value, c.max_photon_ratio);
    }
}

#[test]
fn synthetic_truths_pass() {
    for preset in PRESETS {
        let (_, truth) = SynthSpec::preset(preset).unwrap().generate().unwrap();
        let report = check_material(&truth);
        assert!(report.valid, "{preset}: {}", report.to_json());
        for f in &report.fluorophores {
            let [lo, hi] = f.photon_yield_range.unwrap();
            assert!(lo <= hi && hi <= 1.0 + 1e-9);
        }
    }
}

fn triangle(grid: &[f64], centre: f64, half: f64) -> Vec<f64> {
    grid.iter()
        .map(|l| (1.0 - (l - centre).abs() / half).max(0.0))
        .collect()
}

/// A valid hand-made material: r = 0.5 (with a plateau sample set so a single r sample
/// can be raised under the absorption plateau), a = 1 on 400–500 nm falling to 0 at 350
/// and 550, e a triangle around 600 nm with ∫e = 1, c = 0.5, Q = 0.3.
fn base() -> Material {
    let r = Spectrum::new(vec![300.0, 420.0, 450.0, 480.0, 800.0], vec![0.5; 5], "r").unwrap();
    let a = Spectrum::new(
        vec![340.0, 350.0, 400.0, 500.0, 550.0, 560.0],
        vec![0.0, 0.0, 1.0, 1.0, 0.0, 0.0],
        "a",
    )
    .unwrap();
    let grid: Vec<f64> = (0..=40).map(|i| 500.0 + 5.0 * i as f64).collect();
    let mut e = Spectrum::new(grid.clone(), triangle(&grid, 600.0, 50.0), "e").unwrap();
    let area = e.integral();
    e.value.iter_mut().for_each(|v| *v /= area);
    Material::new(
        "base",
        r,
        vec![Fluorophore {
            concentration: 0.5,
            quantum_yield: 0.3,
            yield_form: YieldForm::Energy,
            concentration_range: None,
            absorption: a,
            emission: e,
        }],
    )
}

/// Each case breaks one law and keeps every other (see the comments for how).
fn violating() -> Vec<(Law, String, String)> {
    let json = |m: &Material| serde_json::to_string_pretty(m).unwrap();
    let mut cases = Vec::new();
    let mut push =
        |law: Law, what: &str, m: Material| cases.push((law, what.to_string(), json(&m)));

    let mut m = base();
    m.schema = "fluorite-material/0".into();
    push(Law::Schema, "wrong schema", m);

    // A negative reflectance sample lowers the albedo: only non-negativity breaks.
    let mut m = base();
    m.reflectance.value[0] = -0.1;
    push(Law::FiniteNonNegative, "negative reflectance", m);

    // Swapped wavelengths of a constant reflectance change nothing else.
    let mut m = base();
    m.reflectance.wavelength_nm.swap(0, 1);
    push(Law::SortedWavelengths, "unsorted reflectance", m);

    // r = 1.2 only under the absorption plateau (a = 1 on 420–480 nm), where
    // ρ = (1 − c)·r + c·Q ≤ 0.5·1.2 + 0.15 = 0.75.
    let mut m = base();
    m.reflectance.value[2] = 1.2;
    push(Law::ReflectanceRange, "r > 1 under the absorption", m);

    // a exceeds 1 by 5e-7: beyond the bound tolerance 1e-9 of a ≤ 1, within the
    // normalisation tolerance 1e-6 of max a = 1.
    let mut m = base();
    m.fluorophores[0].absorption.value[2] = 1.0 + 5e-7;
    push(Law::AbsorptionRange, "a slightly above 1", m);

    // c < 0 lowers both absorption and emission: only its range breaks.
    let mut m = base();
    m.fluorophores[0].concentration = -0.1;
    push(Law::ConcentrationRange, "negative concentration", m);

    // Q < 0 likewise.
    let mut m = base();
    m.fluorophores[0].quantum_yield = -0.1;
    push(Law::QuantumYieldRange, "negative quantum yield", m);

    let mut m = base();
    m.fluorophores[0]
        .absorption
        .value
        .iter_mut()
        .for_each(|v| *v *= 0.8);
    push(Law::AbsorptionPeak, "max a = 0.8", m);

    // ∫e = 1.1: ρ ≤ 0.5·... + 0.15·1.1 stays below 1.
    let mut m = base();
    m.fluorophores[0]
        .emission
        .value
        .iter_mut()
        .for_each(|v| *v *= 1.1);
    push(Law::EmissionIntegral, "∫e = 1.1", m);

    // Two fluorophores of c = 0.6 with the same a absorb 1.2 on the plateau.
    let mut m = base();
    m.fluorophores[0].concentration = 0.6;
    let second = m.fluorophores[0].clone();
    m.fluorophores.push(second);
    push(Law::TotalAbsorption, "Σc·a = 1.2", m);

    // Energy breaks alone only at the edge of the tolerances (the model guarantees ρ ≤ 1
    // when every other law holds): r = 1, c = Q = 1, ∫e = 1 + 5e-7 (within 1e-6), emission
    // at shorter wavelengths than absorption so photons hold; ρ = 1 + 5e-7 on the plateau.
    let mut m = base();
    m.reflectance.value.iter_mut().for_each(|v| *v = 1.0);
    m.fluorophores[0].concentration = 1.0;
    m.fluorophores[0].quantum_yield = 1.0;
    let grid: Vec<f64> = (0..=20).map(|i| 250.0 + 5.0 * i as f64).collect();
    let mut e = Spectrum::new(grid.clone(), triangle(&grid, 300.0, 40.0), "e").unwrap();
    let area = e.integral();
    e.value.iter_mut().for_each(|v| *v *= (1.0 + 5e-7) / area);
    m.fluorophores[0].emission = e;
    push(Law::Energy, "ρ = 1 + 5e-7", m);

    // Q = 0.9 with λ̄e = 600 nm and absorption from 350 nm: Q·λ̄e/λ = 1.54;
    // ρ = 0.5·(1 − 0.5·a) + 0.45·a ≤ 0.7.
    let mut m = base();
    m.fluorophores[0].quantum_yield = 0.9;
    push(Law::Photons, "Q·λ̄e/λ = 1.54", m);

    // Forms that no longer match their samples (one band 1 % higher): nothing else moves.
    let mut m = SynthSpec::preset("two-dyes")
        .unwrap()
        .truth_with_forms()
        .unwrap();
    if let Some(forms) = &mut m.forms
        && let SpectralForm::GaussianBands(bands) = &mut forms.fluorophores[1].emission
    {
        bands.bands[0].height *= 1.01;
    }
    push(Law::Forms, "emission form 1 % off its samples", m);

    // A null value (not a number): only finiteness breaks (derived laws not evaluated).
    let text = json(&base()).replacen("0.5", "null", 1);
    cases.push((Law::FiniteNonNegative, "null reflectance".into(), text));
    cases
}

#[test]
fn base_is_valid_and_each_law_broken_alone_is_named() {
    let report = check_material(&base());
    assert!(report.valid, "{}", report.to_json());
    let dir = common::temp_dir("laws");
    let mut seen = Vec::new();
    for (n, (law, what, text)) in violating().into_iter().enumerate() {
        let path = dir.join(format!("case{n}.json"));
        std::fs::write(&path, &text).unwrap();
        let report = check_file(&path).unwrap();
        assert_eq!(report.failed(), vec![law], "{what}:\n{}", report.to_json());
        assert!(!report.valid);
        let result = report.law(law);
        assert_eq!(result.status, Status::Fail);
        assert!(!result.violations.is_empty());
        // Every other law passes or, where the inputs are malformed, is not evaluated.
        assert!(
            report
                .laws
                .iter()
                .filter(|l| l.law != law)
                .all(|l| l.status != Status::Fail)
        );
        seen.push(law);

        // The CLI: exit 1, the law named in the text report and in the JSON.
        let out = Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .arg("check")
            .arg(&path)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{what}");
        let stdout = String::from_utf8(out.stdout).unwrap();
        assert!(
            stdout.contains(&format!("VIOLATES {}", law.name())),
            "{what}: {stdout}"
        );
        assert!(
            stdout
                .lines()
                .any(|l| l.contains("FAIL") && l.contains(law.name())),
            "{what}: {stdout}"
        );
        let out = Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(["check", "--json"])
            .arg(&path)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1));
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["valid"], false);
        let failed: Vec<&str> = json["laws"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|l| l["status"] == "fail")
            .map(|l| l["law"].as_str().unwrap())
            .collect();
        assert_eq!(failed, vec![law.name()], "{what}");
    }
    for law in Law::ALL {
        assert!(seen.contains(&law), "no case breaks {law}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn margins_and_worst_wavelengths_are_the_analytic_ones() {
    // Photons: Q·λ̄e/λ is worst at the shortest absorbed wavelength, 350 nm (the zero
    // sample before the first positive one bounds the absorbed interval).
    let mut m = base();
    m.fluorophores[0].quantum_yield = 0.9;
    let report = check_material(&m);
    let photons = report.law(Law::Photons);
    let mean = m.fluorophores[0].emission.mean_wavelength_nm();
    assert!((mean - 600.0).abs() < 1e-9);
    assert_eq!(photons.worst_nm, Some(350.0));
    assert!((photons.worst_value - 0.9 * 600.0 / 350.0).abs() < 1e-12);
    assert!((photons.margin - (1.0 - 0.9 * 600.0 / 350.0)).abs() < 1e-12);
    let f = &report.fluorophores[0];
    assert_eq!(f.absorbed_nm, Some([350.0, 550.0]));
    let [lo, hi] = f.photon_yield_range.unwrap();
    assert!((lo - 0.9 * 600.0 / 550.0).abs() < 1e-12 && (hi - 0.9 * 600.0 / 350.0).abs() < 1e-12);

    // Energy of the base material: ρ = (1 − 0.5·a)·0.5 + 0.15·a is largest where a = 0:
    // 0.5, margin 0.5.
    let report = check_material(&base());
    assert!((report.law(Law::Energy).margin - 0.5).abs() < 1e-12);

    // A quadratic albedo between samples: r and a rising together on 400–500 nm (and
    // falling together on 500–600 nm) make ρ = (1 − a)·r = (1 − t)·t concave there, with
    // maximum 1/4 at 450 and 550 nm; the samples alone would give 0.
    let r = Spectrum::new(vec![400.0, 500.0, 600.0], vec![0.0, 1.0, 0.0], "r").unwrap();
    let a = r.clone();
    let e = Spectrum::new(vec![600.0, 700.0], vec![0.01, 0.01], "e").unwrap();
    let m = Material::new(
        "q",
        r,
        vec![Fluorophore {
            concentration: 1.0,
            quantum_yield: 0.0,
            yield_form: YieldForm::Energy,
            concentration_range: None,
            absorption: a,
            emission: e,
        }],
    );
    let energy = check_material(&m).law(Law::Energy).clone();
    assert!((energy.worst_value - 0.25).abs() < 1e-12, "{energy:?}");
    let nm = energy.worst_nm.unwrap();
    assert!(
        (nm - 450.0).abs() < 1e-9 || (nm - 550.0).abs() < 1e-9,
        "{nm}"
    );
}

#[test]
fn cli_exit_codes() {
    let dir = common::temp_dir("cli");
    let good = dir.join("good.json");
    base().save(&good).unwrap();
    let run = |args: &[&Path]| {
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .arg("check")
            .args(args)
            .output()
            .unwrap()
    };
    let out = run(&[&good]);
    assert_eq!(out.status.code(), Some(0));
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(
        stdout.contains("valid") && stdout.contains("photon quantum yield"),
        "{stdout}"
    );

    let not_json = dir.join("bad.json");
    std::fs::write(&not_json, "{ \"schema\": ").unwrap();
    let missing = dir.join("absent.json");
    let no_fluorophores = dir.join("shape.json");
    std::fs::write(
        &no_fluorophores,
        "{\"reflectance\": {\"wavelength_nm\": [400], \"value\": [0.5]}}",
    )
    .unwrap();
    for path in [&not_json, &missing, &no_fluorophores] {
        let out = run(&[path]);
        assert_eq!(out.status.code(), Some(2), "{}", path.display());
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(
            stderr.starts_with("fluorite: error: ") && stderr.contains(&*path.to_string_lossy()),
            "{stderr}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---- several fluorophores and continuous forms ----------------------------------------

fn two_dyes() -> SynthSpec {
    SynthSpec::preset("two-dyes").unwrap()
}

#[test]
fn two_fluorophores_are_checked_per_component() {
    let spec = two_dyes();
    let m = spec.truth().unwrap();
    let report = check_material(&m);
    assert!(report.valid, "{}", report.to_json());
    assert_eq!(report.model, None);
    assert!(report.forms.is_none());
    assert_eq!(report.fluorophores.len(), 2);
    for (summary, f) in report.fluorophores.iter().zip(&m.fluorophores) {
        assert_eq!(summary.k, f.concentration * f.quantum_yield);
    }
    // Photons: each yield is its fraction of the limit λmin/λ̄e, so Q·λ̄e/λmin is the
    // fraction itself; the dye's 0.85 is the worst.
    let photons = report.law(Law::Photons);
    assert_eq!(photons.worst_at.as_deref(), Some("fluorophores[1]"));
    assert!((photons.worst_value - spec.components[0].yield_fraction_of_limit).abs() < 1e-12);
    assert_eq!(photons.worst_nm, Some(300.0));
    let b = &report.fluorophores[0];
    let [_, high] = b.photon_yield_range.unwrap();
    assert!((high - spec.yield_fraction_of_limit).abs() < 1e-12);
    // Total absorption: the dye (c = 0.7) peaks where the brightener barely absorbs.
    let total = report.law(Law::TotalAbsorption);
    let expected = (0.7f64 + 0.6 * m.fluorophores[0].absorption.eval_zero_outside(540.0))
        .max(0.7 + 0.6 * m.fluorophores[0].absorption.eval_zero_outside(550.0));
    assert!((total.worst_value - expected).abs() < 1e-12, "{total:?}");
    let text = check_text(&m, "two-dyes");
    assert!(text.contains("fluorophores[0]: k = c·Q") && text.contains("fluorophores[1]: k = c·Q"));
    assert!(
        text.contains("(no forms block: tabulated spectra)"),
        "{text}"
    );

    // Breaking one component's law names that component and only it.
    let mut m2 = m.clone();
    m2.fluorophores[1].quantum_yield = 0.9;
    let report = check_material(&m2);
    assert_eq!(report.failed(), vec![Law::Photons]);
    let photons = report.law(Law::Photons);
    assert_eq!(photons.violations.len(), 1, "{:?}", photons.violations);
    assert!(photons.violations[0].starts_with("fluorophores[1] "));
    // Two components that each absorb ≤ 1 but together more.
    let mut m3 = m.clone();
    m3.fluorophores[1].absorption = m3.fluorophores[0].absorption.clone();
    m3.fluorophores[1].concentration = 0.5;
    let report = check_material(&m3);
    assert!(
        report.failed().contains(&Law::TotalAbsorption),
        "{}",
        report.to_json()
    );
    let total = report.law(Law::TotalAbsorption);
    assert!((total.worst_value - 1.1).abs() < 1e-12);
}

#[test]
fn forms_are_compared_with_their_samples_and_named() {
    let m = two_dyes().truth_with_forms().unwrap();
    let report = check_material(&m);
    assert!(report.valid, "{}", report.to_json());
    assert_eq!(report.model.as_deref(), Some("synth"));
    let forms = report.forms.as_ref().unwrap();
    assert_eq!(forms.model, "synth");
    // Two fluorophores × (absorption, emission); bands: 1 + 2 and 1 + 2, 3 numbers each.
    assert_eq!(forms.forms, 4);
    assert_eq!(forms.parameters, 18);
    assert!(forms.worst_deviation < 1e-12, "{}", forms.worst_deviation);
    let law = report.law(Law::Forms);
    assert_eq!(law.status, Status::Pass);
    assert!(law.margin <= 0.0 && law.margin > -1e-12);
    // Both absorption bands are centred between 10 nm samples (365 and 545 nm), so the
    // forms rise above the samples' max 1 there: 1/exp(−½(5/15)²) and 1/exp(−½(5/18)²).
    assert_eq!(forms.notes.len(), 2, "{:?}", forms.notes);
    let brightener = 1.0 / (-0.5f64 * (5.0 / 15.0f64).powi(2)).exp();
    assert!(
        forms.notes[0].starts_with(&format!(
            "forms.fluorophores[0].absorption reaches {brightener:.4} at 365 nm"
        )),
        "{:?}",
        forms.notes
    );
    let text = check_text(&m, "forms-text");
    assert!(
        text.contains("forms: synth, 4 forms with 18 parameters, samples match within"),
        "{text}"
    );
    assert!(text.contains("note: forms.fluorophores[1].absorption reaches"));

    // Through the CLI: text and JSON name the model.
    let dir = common::temp_dir("forms");
    let path = dir.join("forms.json");
    m.save(&path).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_fluorite"))
        .args(["check", "--json"])
        .arg(&path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(0));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["model"], "synth");
    assert_eq!(json["forms"]["model"], "synth");
    assert_eq!(json["forms"]["parameters"], 18);
    assert_eq!(json["fluorophores"].as_array().unwrap().len(), 2);
    let forms_law = json["laws"]
        .as_array()
        .unwrap()
        .iter()
        .find(|l| l["law"] == "forms")
        .unwrap();
    assert_eq!(forms_law["status"], "pass");

    // A forms block that does not read, or has the wrong number of entries, breaks the
    // forms law (exit 1), not the reading (exit 2).
    let text = std::fs::read_to_string(&path).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    value["forms"]["fluorophores"] = serde_json::json!("oops");
    let broken = dir.join("broken-forms.json");
    std::fs::write(&broken, serde_json::to_string(&value).unwrap()).unwrap();
    let report = check_file(&broken).unwrap();
    assert_eq!(report.failed(), vec![Law::Forms], "{}", report.to_json());
    assert!(report.law(Law::Forms).violations[0].contains("does not read"));
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    value["forms"]["fluorophores"].as_array_mut().unwrap().pop();
    std::fs::write(&broken, serde_json::to_string(&value).unwrap()).unwrap();
    let report = check_file(&broken).unwrap();
    assert_eq!(report.failed(), vec![Law::Forms]);
    assert!(
        report.law(Law::Forms).violations[0].contains("has 1 entries for 2 fluorophores"),
        "{:?}",
        report.law(Law::Forms).violations
    );
    let out = Command::new(env!("CARGO_BIN_EXE_fluorite"))
        .arg("check")
        .arg(&broken)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(stdout.contains("VIOLATES forms"), "{stdout}");
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---- the photon-yield form --------------------------------------------------------------

/// The base material in the photon form with photon yield Φ.
fn base_photon(phi: f64) -> Material {
    let mut m = base();
    m.fluorophores[0].yield_form = YieldForm::Photon;
    m.fluorophores[0].quantum_yield = phi;
    m
}

#[test]
fn photon_form_laws_and_summary_are_the_analytic_ones() {
    // Φ = 0.9, λ̄e = 600 nm, absorbed 350–550 nm. In the energy form Q = 0.9 breaks the
    // photon law (0.9·600/350 > 1); a constant photon yield of 0.9 keeps it.
    let report = check_material(&base_photon(0.9));
    assert!(report.valid, "{}", report.to_json());
    let photons = report.law(Law::Photons);
    assert_eq!(photons.worst_value, 0.9);
    assert!((photons.margin - 0.1).abs() < 1e-12);
    assert_eq!(photons.worst_nm, None);
    let f = &report.fluorophores[0];
    assert_eq!(f.yield_form, YieldForm::Photon);
    assert_eq!(f.yield_value, 0.9);
    assert_eq!(f.k, 0.5 * 0.9);
    assert_eq!(f.absorbed_nm, Some([350.0, 550.0]));
    assert_eq!(f.photon_yield_range, Some([0.9, 0.9]));
    let [lo, hi] = f.energy_yield_range.unwrap();
    assert!((lo - 0.9 * 350.0 / 600.0).abs() < 1e-12, "{lo}");
    assert!((hi - 0.9 * 550.0 / 600.0).abs() < 1e-12, "{hi}");
    // Energy: ρ = (1 − 0.5·a)·0.5 + 0.5·0.9·(λ/600)·a; on the plateau a = 1 (400–500 nm)
    // ρ = 0.25 + 0.45·λ/600, largest at 500 nm: 0.625. Beyond, a falls to 0 at 550 nm
    // and ρ(λ) = 0.5 − 0.25·a + 0.00075·λ·a with a = (550 − λ)/50 has its vertex below
    // 500 nm, so 500 nm is the maximum.
    let energy = report.law(Law::Energy);
    assert!((energy.worst_value - 0.625).abs() < 1e-12, "{energy:?}");
    assert_eq!(energy.worst_nm, Some(500.0));

    // The text and the JSON report name the form, Φ and the energy-yield range.
    let text = check_text(&base_photon(0.9), "photon-text");
    assert!(
        text.contains("fluorophores[0]: k = c·Φ = 0.450000 (photon form, Φ = 0.900000)"),
        "{text}"
    );
    assert!(
        text.contains(
            "energy quantum yield Q(λ) = Φ·λ/λ̄e from 0.5250 (at 350 nm) to 0.8250 (at 550 nm)"
        ),
        "{text}"
    );
    let json: serde_json::Value = serde_json::from_str(&report.to_json()).unwrap();
    let f = &json["fluorophores"][0];
    assert_eq!(f["yield_form"], "photon");
    assert_eq!(f["yield"], 0.9);
    assert_eq!(f["photon_yield_range"], serde_json::json!([0.9, 0.9]));
    // The energy form states Q and the Φ(λ) range.
    let text = check_text(&base(), "energy-text");
    assert!(
        text.contains("fluorophores[0]: k = c·Q = 0.150000 (energy form, Q = 0.300000)")
            && text.contains("photon quantum yield Φ(λ) = Q·λ̄e/λ"),
        "{text}"
    );

    // Φ above 1 breaks the yield range and the photon law, and only those.
    let report = check_material(&base_photon(1.2));
    assert_eq!(
        report.failed(),
        vec![Law::QuantumYieldRange, Law::Photons],
        "{}",
        report.to_json()
    );
    assert!(report.law(Law::QuantumYieldRange).violations[0].contains("photon_yield"));
}

/// Largest value of c0 + c1·t + c2·t² on [0, 1].
fn quadratic_max(c0: f64, c1: f64, c2: f64) -> f64 {
    let mut best = c0.max(c0 + c1 + c2);
    if c2 < 0.0 {
        let t = -c1 / (2.0 * c2);
        if (0.0..=1.0).contains(&t) {
            best = best.max(c0 + c1 * t + c2 * t * t);
        }
    }
    best
}

#[test]
fn photon_form_energy_law_finds_the_maximum_between_samples_and_above_the_mean_emission() {
    // r = a rising 400 → 500 nm and falling to 600 nm, c = 1, Φ = 0.5, e flat on
    // 600–700 nm (λ̄e = 650): ρ = (1 − a)·a + 0.5·(λ/650)·a is quadratic on each
    // interval with its maximum inside, found exactly (not just at samples or midpoints).
    let r = Spectrum::new(vec![400.0, 500.0, 600.0], vec![0.0, 1.0, 0.0], "r").unwrap();
    let e = Spectrum::new(vec![600.0, 700.0], vec![0.01, 0.01], "e").unwrap();
    let m = Material::new(
        "q",
        r.clone(),
        vec![Fluorophore {
            concentration: 1.0,
            quantum_yield: 0.5,
            yield_form: YieldForm::Photon,
            concentration_range: None,
            absorption: r,
            emission: e,
        }],
    );
    // On 400–500: a = t, λ = 400 + 100t: ρ = t − t² + (200t + 50t²)/650.
    let rising = quadratic_max(0.0, 1.0 + 200.0 / 650.0, -1.0 + 50.0 / 650.0);
    // On 500–600: a = 1 − s, λ = 500 + 100s: ρ = s − s² + 0.5·(500 + 100s)(1 − s)/650.
    let falling = quadratic_max(
        250.0 / 650.0,
        1.0 + (50.0 - 250.0) / 650.0,
        -1.0 - 50.0 / 650.0,
    );
    let exact = rising.max(falling);
    let energy = check_material(&m).law(Law::Energy).clone();
    assert!(
        (energy.worst_value - exact).abs() < 1e-12,
        "{energy:?} vs {exact}"
    );
    let nm = energy.worst_nm.unwrap();
    assert!(nm % 50.0 != 0.0, "the maximum lies between samples: {nm}");

    // Absorbing above the mean emission, a constant Φ ≤ 1 can break energy conservation:
    // r = 0.5, c = 1, a = 1 on 500–600 nm (0 at 450 and 650), Φ = 0.9, e flat on
    // 350–450 nm (λ̄e = 400): ρ(600) = 0.9·600/400 = 1.35 (beyond, the vertex of
    // 0.5·(1 − a) + 0.9·(λ/400)·a lies below 600 nm). The energy form with Q = 0.9 holds.
    let a = Spectrum::new(
        vec![450.0, 500.0, 600.0, 650.0],
        vec![0.0, 1.0, 1.0, 0.0],
        "a",
    )
    .unwrap();
    let e = Spectrum::new(vec![350.0, 450.0], vec![0.01, 0.01], "e").unwrap();
    let r = Spectrum::new(vec![300.0, 800.0], vec![0.5, 0.5], "r").unwrap();
    let f = Fluorophore {
        concentration: 1.0,
        quantum_yield: 0.9,
        yield_form: YieldForm::Photon,
        concentration_range: None,
        absorption: a,
        emission: e,
    };
    let m = Material::new("anti-Stokes", r, vec![f]);
    let report = check_material(&m);
    assert_eq!(report.failed(), vec![Law::Energy], "{}", report.to_json());
    let energy = report.law(Law::Energy);
    assert!((energy.worst_value - 1.35).abs() < 1e-12, "{energy:?}");
    assert_eq!(energy.worst_nm, Some(600.0));
    assert!(m.validate().is_err());
    let mut energy_form = m.clone();
    energy_form.fluorophores[0].yield_form = YieldForm::Energy;
    let report = check_material(&energy_form);
    assert!(
        (report.law(Law::Energy).worst_value - 0.9).abs() < 1e-12,
        "{}",
        report.to_json()
    );
}

#[test]
fn a_yield_given_wrongly_for_its_form_is_reported_not_fatal() {
    let dir = common::temp_dir("yield-form");
    let good: serde_json::Value = serde_json::from_str(&base_photon(0.7).to_json()).unwrap();
    assert_eq!(good["fluorophores"][0]["yield_form"], "photon");
    assert_eq!(good["fluorophores"][0]["photon_yield"], 0.7);
    let edit = |f: &dyn Fn(&mut serde_json::Map<String, serde_json::Value>)| {
        let mut v = good.clone();
        f(v["fluorophores"][0].as_object_mut().unwrap());
        v.to_string()
    };
    let cases = [
        (
            "photon form without photon_yield",
            edit(&|f| {
                f.remove("photon_yield");
            }),
            "photon_yield is missing",
        ),
        (
            "photon form with quantum_yield",
            edit(&|f| {
                f.remove("photon_yield");
                f.insert("quantum_yield".into(), 0.7.into());
            }),
            "gives `quantum_yield`",
        ),
        (
            "photon form with both yields",
            edit(&|f| {
                f.insert("quantum_yield".into(), 0.7.into());
            }),
            "drop `quantum_yield`",
        ),
        (
            "photon_yield without the form",
            edit(&|f| {
                f.remove("yield_form");
            }),
            "without \"yield_form\": \"photon\"",
        ),
        (
            "unknown form",
            edit(&|f| {
                f.insert("yield_form".into(), "photons".into());
            }),
            "yield_form is \"photons\"",
        ),
        (
            "energy form without any yield",
            edit(&|f| {
                f.remove("yield_form");
                f.remove("photon_yield");
            }),
            "quantum_yield is missing",
        ),
    ];
    for (n, (what, text, expected)) in cases.iter().enumerate() {
        let path = dir.join(format!("yield{n}.json"));
        std::fs::write(&path, text).unwrap();
        let report = check_file(&path).unwrap();
        assert_eq!(
            report.failed(),
            vec![Law::QuantumYieldRange],
            "{what}: {}",
            report.to_json()
        );
        let law = report.law(Law::QuantumYieldRange);
        assert!(
            law.violations.iter().any(|v| v.contains(expected)),
            "{what}: {:?}",
            law.violations
        );
        // Nothing is guessed: the laws that need the yield are not evaluated.
        assert_eq!(
            report.law(Law::Energy).status,
            Status::NotEvaluated,
            "{what}"
        );
        // The strict reader refuses the same file.
        assert!(Material::load(&path).is_err(), "{what}");
        let out = Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .arg("check")
            .arg(&path)
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{what}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn validate_compares_forms_with_samples_but_not_the_notes() {
    // The two-dye truth with its forms: valid, though both absorption forms rise above 1
    // between samples (notes of the report, which break no law).
    let m = two_dyes().truth_with_forms().unwrap();
    assert_eq!(check_material(&m).forms.unwrap().notes.len(), 2);
    m.validate().unwrap();
    // One absorption sample 1 % of the peak below its form: the forms law breaks.
    let mut off = m.clone();
    let a = &mut off.fluorophores[0].absorption;
    let i = a.value.iter().position(|&v| v > 0.3 && v < 0.9).unwrap();
    a.value[i] -= 0.01;
    let err = off.validate().unwrap_err().to_string();
    assert!(err.contains("forms"), "{err}");
    assert_eq!(check_material(&off).failed(), vec![Law::Forms]);
}
