//! Joint non-negative PARAFAC of EEM sets: Dorrit's four analytes are recovered against
//! their known concentrations (../shared, skipped with a message when absent), and a
//! synthetic set of known Gaussian shapes and scores comes back, with core consistency
//! telling the true K from K + 2.

use crate::common;

use std::path::PathBuf;

use fluorite::fit::joint::parafac::ParafacOptions;
use fluorite::fit::joint::reference::Reference;
use fluorite::fit::joint::{JointOptions, fit_joint};
use fluorite::measurement::{Measurement, Units};

use crate::common::eem_sim::pearson_squared;

fn tucker(u: &[f64], v: &[f64]) -> f64 {
    let d = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    d(u, v) / (d(u, u) * d(v, v)).sqrt()
}

/// The classic Dorrit analysis (the data README): emission 250–681 nm, excitation
/// 230–315 nm, QAB, QAC, QAE and QAA left out, four components, scatter masked.
#[test]
fn dorrit_four_analytes() {
    let (Some(dir), Some(set)) = (
        common::shared("eem-instrument/dorrit"),
        common::dorrit_classic(),
    ) else {
        return;
    };
    let truth = std::fs::read_to_string(dir.join("concentrations.csv")).unwrap();
    let mut lines = truth.lines();
    let analytes: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .skip(1)
        .map(String::from)
        .collect();
    let concentrations: Vec<(String, Vec<f64>)> = lines
        .map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            (
                cells[0].to_string(),
                cells[1..].iter().map(|c| c.parse().unwrap()).collect(),
            )
        })
        .collect();
    // Each sample of the set with its known concentrations, in the set's order.
    let samples: Vec<(String, Vec<f64>)> = set
        .iter()
        .map(|(name, _)| {
            concentrations
                .iter()
                .find(|(n, _)| n == name)
                .unwrap_or_else(|| panic!("{name} has no row in concentrations.csv"))
                .clone()
        })
        .collect();
    assert_eq!(samples.len(), 23);
    let measurements: Vec<Measurement> = set.into_iter().map(|(_, m)| m).collect();
    let options = common::dorrit_classic_options(true);
    let fit = fit_joint(&measurements, &options).unwrap();
    // tensorly 0.9's masked non-negative PARAFAC on the same preparation: 0.996 (Trp),
    // 0.996 (HQ), 0.981 (DOPA), 0.939 (Phe); the thresholds.
    let need = |analyte: &str| {
        if analyte.starts_with("phenylalanine") {
            0.93
        } else {
            0.95
        }
    };
    for (a, analyte) in analytes.iter().enumerate() {
        let truth: Vec<f64> = samples.iter().map(|s| s.1[a]).collect();
        let best = (0..4)
            .map(|c| {
                let scores: Vec<f64> = fit.scores.iter().map(|r| r[c]).collect();
                pearson_squared(&scores, &truth)
            })
            .fold(0.0, f64::max);
        eprintln!("{analyte}: R² = {best:.4}");
        assert!(best >= need(analyte), "{analyte}: R² = {best:.4}");
    }
    eprintln!(
        "explained {:.5}, core consistency {:.1}, iterations {}, {:.1} ms, split-half {:?}",
        fit.explained_variance,
        fit.core_consistency,
        fit.iterations,
        1e3 * fit.seconds,
        fit.split_half.as_ref().map(|s| s.min_congruence)
    );
    assert!(fit.explained_variance > 0.99, "{}", fit.explained_variance);
}

/// The synthetic set: matrices, per component [excitation, emission] shapes, and per
/// sample the true scores.
type Synthetic = (Vec<Measurement>, Vec<[Vec<f64>; 2]>, Vec<Vec<f64>>);

/// Three Gaussian fluorophores of known shapes and scores, 2 % noise, a scatter-like
/// masked band and a few cells missing in single samples.
fn synthetic(samples: usize) -> Synthetic {
    let ex: Vec<f64> = (0..20).map(|i| 240.0 + 5.0 * i as f64).collect();
    let em: Vec<f64> = (0..120).map(|i| 280.0 + 2.5 * i as f64).collect();
    let gauss = |x: f64, mu: f64, sigma: f64| (-(x - mu).powi(2) / (2.0 * sigma * sigma)).exp();
    let shapes: Vec<[Vec<f64>; 2]> = [
        (260.0, 15.0, 330.0, 18.0),
        (300.0, 12.0, 420.0, 30.0),
        (320.0, 20.0, 500.0, 25.0),
    ]
    .iter()
    .map(|&(xm, xs, em_m, em_s)| {
        [
            ex.iter().map(|&l| gauss(l, xm, xs)).collect(),
            em.iter().map(|&l| gauss(l, em_m, em_s)).collect(),
        ]
    })
    .collect();
    // Scores from a fixed pseudo-random sequence (a linear congruential generator).
    let mut state: u64 = 12345;
    let mut uniform = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let scores: Vec<Vec<f64>> = (0..samples)
        .map(|_| (0..3).map(|_| 0.1 + uniform() * 10.0).collect())
        .collect();
    let mut measurements = Vec::new();
    for (s, row) in scores.iter().enumerate() {
        let mut values = Vec::new();
        for (i, &x) in ex.iter().enumerate() {
            for (j, &l) in em.iter().enumerate() {
                let clean: f64 = (0..3)
                    .map(|k| row[k] * shapes[k][0][i] * shapes[k][1][j])
                    .sum();
                // Box-Muller-free noise: uniform with the variance of 2 % of the peak.
                let noise = (uniform() - 0.5) * 12f64.sqrt() * 0.02 * 10.0;
                let masked = (l - x).abs() < 12.0 || l < x || ((s * 31 + i * 7 + j) % 97 == 0);
                values.push(if masked { f64::NAN } else { clean + noise });
            }
        }
        let mut m = Measurement::new(
            format!("s{s}"),
            ex.clone(),
            em.clone(),
            values,
            Units::PerBin,
        )
        .unwrap();
        m.has_diagonal = false;
        m.arbitrary_scale = true;
        measurements.push(m);
    }
    (measurements, shapes, scores)
}

#[test]
fn synthetic_shapes_scores_and_core_consistency() {
    let (measurements, shapes, scores) = synthetic(24);
    let options = |k: usize| JointOptions {
        parafac: ParafacOptions {
            components: k,
            ..ParafacOptions::default()
        },
        ..JointOptions::default()
    };
    let fit = fit_joint(&measurements, &options(3)).unwrap();
    for (k, [ex_true, em_true]) in shapes.iter().enumerate() {
        // The fitted component whose emission matches best.
        let (c, em_cong) = (0..3)
            .map(|c| (c, tucker(&fit.components[c].emission.value, em_true)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        let ex_cong = tucker(&fit.components[c].absorption.value, ex_true);
        assert!(
            em_cong >= 0.99 && ex_cong >= 0.99,
            "true {k}: em {em_cong} ex {ex_cong}"
        );
        // Scores within 5 % of the truth (plus 1 % of the largest score, the noise floor
        // of the smallest) once the shapes' normalisation is accounted for: the true
        // model is s·a·e; max a and ∫e over the grid convert.
        let widths = fluorite::spectrum::bin_widths(&fit.components[c].emission.wavelength_nm);
        let area: f64 = em_true.iter().zip(&widths).map(|(e, w)| e * w).sum();
        let peak = ex_true.iter().cloned().fold(0.0, f64::max);
        for (row, truth) in fit.scores.iter().zip(&scores) {
            let expected = truth[k] * area * peak;
            assert!(
                (row[c] - expected).abs() <= 0.05 * expected + 0.01 * 10.1 * area * peak,
                "component {k}: {} vs {expected}",
                row[c]
            );
        }
    }
    assert!(fit.core_consistency > 90.0, "{}", fit.core_consistency);
    // The true scores as a reference file: each analyte is matched to the component
    // whose emission is its own (found above by shape alone), with R² near 1; the
    // samples are named in another case, and one reference row names no sample.
    let mut csv = String::from("sample,first,second,third\n");
    for (s, truth) in scores.iter().enumerate() {
        csv.push_str(&format!("S{s},{},{},{}\n", truth[0], truth[1], truth[2]));
    }
    csv.push_str("blank,0,0,0\n");
    let reference = Reference::parse(std::path::Path::new("truth.csv"), &csv).unwrap();
    let matches = reference.best_matches(&fit);
    for (k, [_, em_true]) in shapes.iter().enumerate() {
        let own = (0..3)
            .max_by(|&a, &b| {
                tucker(&fit.components[a].emission.value, em_true)
                    .total_cmp(&tucker(&fit.components[b].emission.value, em_true))
            })
            .unwrap();
        let m = &matches[k];
        assert_eq!(m.component, own + 1, "{m:?}");
        assert_eq!(m.samples, 24);
        assert!(m.r_squared > 0.99, "{m:?}");
    }
    let split = fit.split_half.as_ref().unwrap();
    assert!(split.validated, "{split:?}");
    let over = fit_joint(&measurements, &options(5)).unwrap();
    assert!(over.core_consistency < 50.0, "{}", over.core_consistency);
}

/// The command a spectroscopist types: outputs written, the reference read, the outliers
/// left out; surface matrices get the not-yet message, not a PARAFAC.
#[test]
fn cli_joint_fit_and_surface_placeholder() {
    let bin = env!("CARGO_BIN_EXE_fluorite");
    let out = tempfile::tempdir().unwrap();
    if let Some(dir) = common::shared("eem-instrument/dorrit") {
        // Every CSV of the folder, concentrations.csv included: --reference keeps it out.
        let inputs: Vec<PathBuf> = common::files_in(&dir, &["csv"]);
        let o = std::process::Command::new(bin)
            .arg("fit")
            .args(&inputs)
            .args(["--joint", "--components", "2,4", "--em-range", "250:681"])
            .args([
                "--ex-range",
                "230:315",
                "--exclude",
                "QAB,QAC,QAE,QAA",
                "--no-split-half",
            ])
            .arg("--reference")
            .arg(dir.join("concentrations.csv"))
            .arg("-o")
            .arg(out.path())
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(
            o.status.success(),
            "{stdout}{}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(stdout.contains("joint fit of 23 EEMs"), "{stdout}");
        assert!(
            stdout.contains("| 4 |") && stdout.contains("R² tryptophan"),
            "{stdout}"
        );
        let scores = std::fs::read_to_string(out.path().join("k4/scores.csv")).unwrap();
        assert_eq!(scores.lines().count(), 24, "{scores}");
        assert!(!scores.contains("QAB,"));
        for f in ["model.json", "component-4.json", "components.png"] {
            assert!(out.path().join("k4").join(f).exists(), "{f}");
        }
        let component: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(out.path().join("k4/component-1.json")).unwrap(),
        )
        .unwrap();
        assert_eq!(component["schema"], "fluorite-fluorophore/1");
    }
    // Radiance-factor surfaces go to the concentration-series fit: a synthetic series
    // of one dye at two concentrations gives back each file's c (the truth files the
    // generator writes) within 4 of its standard errors, and Q likewise.
    let series = out.path().join("series");
    common::succeed(
        std::process::Command::new(bin)
            .args([
                "synth",
                "--preset",
                "green-dye",
                "--concentrations",
                "0.3,0.8",
                "--out",
            ])
            .arg(&series),
    );
    common::succeed(
        std::process::Command::new(bin)
            .arg("fit")
            .args([
                "green-dye-c0.3.csv",
                "green-dye-c0.8.csv",
                "--joint",
                "-q",
                "-o",
                "fit",
            ])
            .current_dir(&series),
    );
    let read = |p: std::path::PathBuf| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let fit = read(series.join("fit/series.json"));
    for (file, name) in fit["files"]
        .as_array()
        .unwrap()
        .iter()
        .zip(["c0.3", "c0.8"])
    {
        let truth = read(series.join(format!("green-dye-{name}.truth.json")));
        let truth = &truth["fluorophores"][0];
        let c = file["concentration"].as_f64().unwrap();
        let c_error = file["concentration_std_error"].as_f64().unwrap();
        let c_truth = truth["concentration"].as_f64().unwrap();
        assert!(
            (c - c_truth).abs() <= 4.0 * c_error,
            "{name}: c {c} ± {c_error} vs {c_truth}"
        );
        let q_truth = truth["quantum_yield"].as_f64().unwrap();
        let q = fit["quantum_yield"].as_f64().unwrap();
        let q_error = fit["quantum_yield_std_error"].as_f64().unwrap();
        assert!(
            (q - q_truth).abs() <= 4.0 * q_error,
            "Q {q} ± {q_error} vs {q_truth}"
        );
    }
}
