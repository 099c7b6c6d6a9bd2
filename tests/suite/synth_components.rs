//! Synthetic specs with several fluorescent components (`SynthSpec::components`), the
//! `two-dyes` preset, and that the one-fluorophore presets are unchanged by them.

use std::path::Path;

use fluorite::formats::{RowsAre, write_wide_csv};
use fluorite::model::predict;
use fluorite::spectrum::bin_widths;
use fluorite::synth::{Band, PRESETS, SynthSpec};
use fluorite::{Material, Units, YieldForm};

fn data(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("data")
        .join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn gauss(bands: &[Band], nm: f64) -> f64 {
    bands
        .iter()
        .map(|b| b.weight * (-0.5 * ((nm - b.centre_nm) / b.width_nm).powi(2)).exp())
        .sum()
}

#[test]
fn two_dyes_truth_has_two_valid_components() {
    let spec = SynthSpec::preset("two-dyes").unwrap();
    assert_eq!(spec.components.len(), 1);
    let truth = spec.truth().unwrap();
    truth.validate().unwrap();
    assert_eq!(truth.fluorophores.len(), 2);
    let c = truth.conservation_margins();
    assert!(c.max_energy_albedo <= 1.0 && c.max_photon_ratio <= 1.0);
    // Σ c·a ≤ 1 everywhere on the excitation grid.
    for &l in &spec.excitation_nm {
        assert!(truth.absorbed(l) <= 1.0 + 1e-12, "Σ c·a at {l} nm");
    }
    // Each component separately: max a = 1, ∫e = 1, Q = fraction × λmin/λ̄e.
    let parts = [
        (
            &spec.absorption,
            &spec.emission,
            spec.concentration,
            spec.yield_fraction_of_limit,
        ),
        (
            &spec.components[0].absorption,
            &spec.components[0].emission,
            spec.components[0].concentration,
            spec.components[0].yield_fraction_of_limit,
        ),
    ];
    for (f, (absorption, emission, c, fraction)) in truth.fluorophores.iter().zip(parts) {
        assert_eq!(f.concentration, c);
        assert!((f.absorption.max() - 1.0).abs() < 1e-12);
        assert!((f.emission.integral() - 1.0).abs() < 1e-12);
        // Independent: the shape is the bands' sum, rescaled.
        let peak = spec
            .excitation_nm
            .iter()
            .map(|&l| gauss(absorption, l))
            .fold(0.0, f64::max);
        for (l, v) in f.absorption.wavelength_nm.iter().zip(&f.absorption.value) {
            assert!((v - gauss(absorption, *l) / peak).abs() < 1e-12);
        }
        let area: f64 = spec
            .emission_nm
            .iter()
            .zip(bin_widths(&spec.emission_nm))
            .map(|(&l, w)| gauss(emission, l) * w)
            .sum();
        let mean: f64 = spec
            .emission_nm
            .iter()
            .zip(bin_widths(&spec.emission_nm))
            .map(|(&l, w)| l * gauss(emission, l) * w / area)
            .sum();
        // Every Gaussian is positive on the grid, so λmin is the grid's first wavelength.
        let limit = spec.excitation_nm[0] / mean;
        assert!(
            (f.quantum_yield - fraction * limit).abs() < 1e-3 * f.quantum_yield,
            "Q {} against {}",
            f.quantum_yield,
            fraction * limit
        );
    }
    // Well separated: the brightener absorbs in the UV and emits blue, the dye absorbs
    // green and emits orange-red.
    let [b, d] = [&truth.fluorophores[0], &truth.fluorophores[1]];
    assert!(b.absorption.eval_zero_outside(365.0) > 0.99);
    assert!(d.absorption.eval_zero_outside(545.0) > 0.99);
    assert!(b.absorption.eval_zero_outside(545.0) < 1e-6);
    assert!(d.absorption.eval_zero_outside(365.0) < 1e-6);
    assert!((430.0..460.0).contains(&b.emission_mean_nm()));
    assert!((600.0..640.0).contains(&d.emission_mean_nm()));
}

#[test]
fn two_dyes_noise_free_matrix_is_the_model() {
    let mut spec = SynthSpec::preset("two-dyes").unwrap();
    spec.noise_sigma = 0.0;
    spec.crosstalk = 0.0;
    spec.missing_fraction = 0.0;
    let (m, truth) = spec.generate().unwrap();
    let model = predict(
        &truth,
        &spec.name,
        &spec.excitation_nm,
        &spec.emission_nm,
        Units::PerBin,
        true,
    );
    assert_eq!(m.values, model.values);
    // Independently of `predict`: an off-diagonal cell is Σ c·Q·a(λi)·e(λo)·Δλo and a
    // diagonal cell (1 − Σ c·a)·r.
    let widths = bin_widths(&spec.emission_nm);
    for (i, &li) in spec.excitation_nm.iter().enumerate() {
        for (j, &lo) in spec.emission_nm.iter().enumerate() {
            let mut expected: f64 = truth
                .fluorophores
                .iter()
                .map(|f| {
                    let a = f.absorption.value[i];
                    let e = f.emission.value[j];
                    f.concentration * f.quantum_yield * a * e * widths[j]
                })
                .sum();
            if (li - lo).abs() < 1e-9 {
                let absorbed: f64 = truth
                    .fluorophores
                    .iter()
                    .map(|f| f.concentration * f.absorption.value[i])
                    .sum();
                expected += (1.0 - absorbed) * truth.reflectance.value[j];
            }
            assert!(
                (m.get(i, j) - expected).abs() < 1e-12,
                "cell ({li}, {lo}): {} against {expected}",
                m.get(i, j)
            );
        }
    }
    // Both components fluoresce clearly above the measurement noise.
    let cell = |li: f64, lo: f64| {
        let i = spec.excitation_nm.iter().position(|&l| l == li).unwrap();
        let j = spec.emission_nm.iter().position(|&l| l == lo).unwrap();
        m.get(i, j)
    };
    let sigma = fluorite::synth::MEASURED_NOISE_SIGMA;
    assert!(cell(360.0, 440.0) > 50.0 * sigma, "{}", cell(360.0, 440.0));
    assert!(cell(550.0, 610.0) > 50.0 * sigma, "{}", cell(550.0, 610.0));
    // Cross cells (brightener light into dye emission and back) stay near zero.
    assert!(cell(360.0, 610.0) < sigma);
    assert!(cell(550.0, 440.0) < sigma);
}

#[test]
fn noisy_two_dyes_differs_from_the_model_by_the_noise() {
    let spec = SynthSpec::preset("two-dyes").unwrap();
    let mut clean = spec.clone();
    clean.noise_sigma = 0.0;
    clean.crosstalk = 0.0;
    let (noisy, _) = spec.generate().unwrap();
    let (model, _) = clean.generate().unwrap();
    let guard = model.default_guard_nm();
    let mut sum = 0.0;
    let mut n = 0usize;
    for i in 0..model.n_excitation() {
        for j in 0..model.n_emission() {
            if (spec.emission_nm[j] - spec.excitation_nm[i]).abs() > guard + 1e-6 {
                let d = noisy.get(i, j) - model.get(i, j);
                sum += d * d;
                n += 1;
            }
        }
    }
    let rms = (sum / n as f64).sqrt();
    assert!(
        (rms / spec.noise_sigma - 1.0).abs() < 0.1,
        "rms {rms} against σ {}",
        spec.noise_sigma
    );
}

#[test]
fn committed_two_dyes_files_are_what_synth_writes() {
    let mut spec = SynthSpec::preset("two-dyes").unwrap();
    spec.missing_fraction = 0.02;
    spec.seed = 1;
    let (m, truth) = spec.generate().unwrap();
    assert_eq!(
        write_wide_csv(&m, RowsAre::Excitation),
        data("two-dyes.csv")
    );
    assert_eq!(truth.to_json(), data("two-dyes.truth.json"));
    let read: SynthSpec = serde_json::from_str(&data("two-dyes.synth.json")).unwrap();
    assert_eq!(read, spec);
    let loaded: Material = serde_json::from_str(&data("two-dyes.truth.json")).unwrap();
    loaded.validate().unwrap();
    assert_eq!(loaded.fluorophores.len(), 2);
}

/// The one-fluorophore presets write exactly the committed files (made before specs
/// could hold several components), and their old spec files still load.
#[test]
fn one_fluorophore_presets_are_byte_for_byte_unchanged() {
    for preset in PRESETS {
        if preset == "two-dyes" {
            continue;
        }
        let mut spec = SynthSpec::preset(preset).unwrap();
        assert!(spec.components.is_empty());
        spec.missing_fraction = 0.02;
        spec.seed = 1;
        let (m, truth) = spec.generate().unwrap();
        assert_eq!(
            write_wide_csv(&m, RowsAre::Excitation),
            data(&format!("{preset}.csv")),
            "{preset}.csv"
        );
        assert_eq!(
            truth.to_json(),
            data(&format!("{preset}.truth.json")),
            "{preset}.truth.json"
        );
        let spec_json = serde_json::to_string_pretty(&spec).unwrap() + "\n";
        let committed = data(&format!("{preset}.synth.json"));
        assert_eq!(spec_json, committed, "{preset}.synth.json");
        assert!(!committed.contains("components"));
        let read: SynthSpec = serde_json::from_str(&committed).unwrap();
        assert_eq!(read, spec);
    }
}

#[test]
fn bad_components_are_errors_not_panics() {
    let mut spec = SynthSpec::preset("two-dyes").unwrap();
    spec.components[0].emission.clear();
    let err = spec.truth().unwrap_err().to_string();
    assert!(err.contains("components[0].emission"), "{err}");
    // Two components absorbing fully at the same wavelength absorb more than all light.
    let mut spec = SynthSpec::preset("two-dyes").unwrap();
    spec.components[0].absorption = spec.absorption.clone();
    spec.concentration = 0.8;
    spec.components[0].concentration = 0.8;
    let err = spec.truth().unwrap_err().to_string();
    assert!(err.contains("Σc·a"), "{err}");
    // A component with zero concentration is left out.
    let mut spec = SynthSpec::preset("two-dyes").unwrap();
    spec.components[0].concentration = 0.0;
    assert_eq!(spec.truth().unwrap().fluorophores.len(), 1);
}

#[test]
fn truth_with_forms_holds_the_generating_bands() {
    let spec = SynthSpec::preset("two-dyes").unwrap();
    let material = spec.truth_with_forms().unwrap();
    material.validate().unwrap();
    let forms = material.forms.as_ref().unwrap();
    assert_eq!(forms.model, "synth");
    assert!(forms.reflectance.is_none());
    assert_eq!(forms.fluorophores.len(), 2);
    // Without the block it is the plain truth.
    let mut bare = material.clone();
    bare.forms = None;
    assert_eq!(bare, spec.truth().unwrap());
    // Off the grid the form is the bands' sum divided by the grid peak (absorption) or
    // the trapezoid area (emission).
    let bands = &spec.components[0];
    let f = &material.fluorophores[1];
    let peak = spec
        .excitation_nm
        .iter()
        .map(|&l| gauss(&bands.absorption, l))
        .fold(0.0, f64::max);
    let a = forms.fluorophores[1].absorption.eval(545.0);
    assert!((a - gauss(&bands.absorption, 545.0) / peak).abs() < 1e-12);
    assert!(a > 1.0, "the band centre lies between samples: {a}");
    let area: f64 = spec
        .emission_nm
        .iter()
        .zip(bin_widths(&spec.emission_nm))
        .map(|(&l, w)| gauss(&bands.emission, l) * w)
        .sum();
    let e = forms.fluorophores[1].emission.eval(613.0);
    assert!((e - gauss(&bands.emission, 613.0) / area).abs() < 1e-15);
    assert!(
        (forms.fluorophores[1].emission.eval(610.0) - f.emission.eval_zero_outside(610.0)).abs()
            < 1e-15
    );
    // Zero outside the grids, like the samples.
    assert_eq!(forms.fluorophores[0].absorption.eval(299.0), 0.0);
    assert_eq!(forms.fluorophores[0].emission.eval(379.0), 0.0);
}

#[test]
fn a_photon_form_component_gives_a_photon_form_truth_and_matrix() {
    // two-dyes with the dye (second component) in the photon form: Φ = the fraction of
    // its limit 1, and the matrix cell c·Φ·(λi/λ̄e)·a(λi)·e(λo)·Δλo (λ̄e by the trapezoid
    // rule, computed here).
    let mut spec = SynthSpec::preset("two-dyes").unwrap();
    spec.noise_sigma = 0.0;
    spec.crosstalk = 0.0;
    spec.missing_fraction = 0.0;
    spec.components[0].yield_form = YieldForm::Photon;
    spec.components[0].yield_fraction_of_limit = 0.9;
    let (m, truth) = spec.generate().unwrap();
    assert_eq!(truth.fluorophores[0].yield_form, YieldForm::Energy);
    let dye = &truth.fluorophores[1];
    assert_eq!(dye.yield_form, YieldForm::Photon);
    assert_eq!(dye.quantum_yield, 0.9);
    let widths = bin_widths(&spec.emission_nm);
    let mean = |f: &fluorite::Fluorophore| {
        let e = &f.emission.value;
        let num: f64 = (0..e.len())
            .map(|j| widths[j] * e[j] * spec.emission_nm[j])
            .sum();
        let den: f64 = (0..e.len()).map(|j| widths[j] * e[j]).sum();
        num / den
    };
    let means: Vec<f64> = truth.fluorophores.iter().map(mean).collect();
    for (i, &li) in spec.excitation_nm.iter().enumerate() {
        for (j, &lo) in spec.emission_nm.iter().enumerate() {
            if (li - lo).abs() < 1e-9 {
                continue;
            }
            let expected: f64 = truth
                .fluorophores
                .iter()
                .zip(&means)
                .map(|(f, mean)| {
                    let x = match f.yield_form {
                        YieldForm::Energy => 1.0,
                        YieldForm::Photon => li / mean,
                    };
                    f.concentration
                        * f.quantum_yield
                        * x
                        * f.absorption.value[i]
                        * f.emission.value[j]
                        * widths[j]
                })
                .sum();
            assert!(
                (m.get(i, j) - expected).abs() < 1e-12,
                "cell ({li}, {lo}): {} against {expected}",
                m.get(i, j)
            );
        }
    }

    // The spec's JSON: the form is written only when it is not the default, and read
    // back; a spec without it is the energy form.
    let json = serde_json::to_string(&spec).unwrap();
    assert_eq!(
        json.matches("\"yield_form\":\"photon\"").count(),
        1,
        "{json}"
    );
    let back: SynthSpec = serde_json::from_str(&json).unwrap();
    assert_eq!(back, spec);
    let energy = serde_json::to_string(&SynthSpec::preset("two-dyes").unwrap()).unwrap();
    assert!(!energy.contains("yield_form"));

    // The first component in the photon form too.
    let mut spec = SynthSpec::preset("green-dye").unwrap();
    spec.yield_form = YieldForm::Photon;
    let truth = spec.truth().unwrap();
    assert_eq!(truth.fluorophores[0].yield_form, YieldForm::Photon);
    assert_eq!(
        truth.fluorophores[0].quantum_yield,
        spec.yield_fraction_of_limit
    );
}

/// Impossible noise, crosstalk or missing fractions are errors of the library naming the
/// field and the `fluorite synth` flag, from `generate` and `concentration_series` alike;
/// the CLI reports them and writes nothing.
#[test]
fn impossible_measurement_parameters_are_errors() {
    type Set = fn(&mut SynthSpec, f64);
    let cases: [(Set, f64, &str, &str); 6] = [
        (
            |s, v| s.noise_sigma = v,
            -0.1,
            "noise_sigma (--noise)",
            "give a non-negative number",
        ),
        (
            |s, v| s.noise_sigma = v,
            f64::NAN,
            "noise_sigma (--noise)",
            "is NaN",
        ),
        (
            |s, v| s.crosstalk = v,
            -1e-3,
            "crosstalk (--crosstalk)",
            "give a non-negative number",
        ),
        (
            |s, v| s.crosstalk = v,
            f64::INFINITY,
            "crosstalk (--crosstalk)",
            "is inf",
        ),
        (
            |s, v| s.missing_fraction = v,
            1.0,
            "missing_fraction (--missing)",
            "give a fraction in [0, 1)",
        ),
        (
            |s, v| s.missing_fraction = v,
            -0.5,
            "missing_fraction (--missing)",
            "is -0.5",
        ),
    ];
    for (set, value, field, says) in cases {
        let mut spec = SynthSpec::preset("green-dye").unwrap();
        set(&mut spec, value);
        for err in [
            spec.validate().unwrap_err(),
            spec.generate().unwrap_err(),
            spec.concentration_series(&[0.5, 1.0]).unwrap_err(),
        ] {
            let err = err.to_string();
            assert!(err.starts_with(&format!("{field}: ")), "{err}");
            assert!(err.contains(says), "{err}");
        }
    }
    // The bounds themselves are allowed.
    let mut spec = SynthSpec::preset("green-dye").unwrap();
    spec.noise_sigma = 0.0;
    spec.crosstalk = 0.0;
    spec.missing_fraction = 0.0;
    spec.validate().unwrap();

    let dir = std::env::temp_dir().join(format!("fluorite-synth-flags-{}", std::process::id()));
    for (flag, value, says) in [
        (
            "--noise",
            "-0.1",
            "--noise): is -0.1; give a non-negative number",
        ),
        (
            "--crosstalk",
            "NaN",
            "--crosstalk): is NaN; give a non-negative number",
        ),
        (
            "--missing",
            "1",
            "--missing): is 1; give a fraction in [0, 1)",
        ),
    ] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(["synth", "--out"])
            .arg(&dir)
            .args(["--preset", "green-dye,plain", &format!("{flag}={value}")])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && stderr.contains(says), "{stderr}");
        assert!(!dir.exists(), "{flag} {value}: nothing is written");
    }
}

/// All of a run's files or none: a folder in the way of the last preset's spec file
/// leaves every target unwritten.
#[test]
fn synth_writes_all_files_or_none() {
    let dir = std::env::temp_dir().join(format!("fluorite-synth-all-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("plain.synth.json")).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_fluorite"))
        .args(["synth", "--out"])
        .arg(&dir)
        .args(["--preset", "green-dye,plain"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(
        left,
        ["plain.synth.json"],
        "only the folder in the way remains"
    );
}

/// The matrix on a grid is each cell's `fluorescence_with`, bit for bit: two components,
/// one of them in the photon form (Q(λ) grows with λ), on grids that reach past the
/// spectra's samples (zero outside) and fall between them.
#[test]
fn the_fluorescence_on_a_grid_is_each_cells_value_bit_for_bit() {
    let mut truth = SynthSpec::preset("two-dyes").unwrap().truth().unwrap();
    assert_eq!(truth.fluorophores.len(), 2);
    truth.fluorophores[1].yield_form = YieldForm::Photon;
    let excitation: Vec<f64> = (0..37).map(|i| 251.5 + 13.0 * i as f64).collect();
    let emission: Vec<f64> = (0..29).map(|j| 333.3 + 17.0 * j as f64).collect();
    let grid = truth.fluorescence_on_grid(&excitation, &emission);
    let moments = truth.emission_moments();
    let mut nonzero = 0;
    for (i, &li) in excitation.iter().enumerate() {
        for (j, &lo) in emission.iter().enumerate() {
            let cell = truth.fluorescence_with(li, lo, &moments);
            assert_eq!(
                grid[i * emission.len() + j].to_bits(),
                cell.to_bits(),
                "{li} → {lo}"
            );
            nonzero += usize::from(cell > 0.0);
        }
    }
    assert!(nonzero > 100, "{nonzero}");
}
