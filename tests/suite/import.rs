//! `import-spectra`: the dye spectra in ../shared/data/spectra become valid materials
//! whose a and e are the source curves, normalised.

use crate::common;

use std::path::Path;
use std::process::Command;

use fluorite::YieldForm;
use fluorite::check::Law;
use fluorite::import::{ImportOptions, ReflectanceSource, SpectrumSource, import_spectra};

const DYES: [&str; 3] = [
    "fluorescein_0.1MNaOH_wave_excitation_emission.csv",
    "Rhodamine6G_EtOH_wave_excitation_emission.csv",
    "QuinineSulfate_0.5MH2SO4_wave_excitation_emission.csv",
];

/// An independent reader of `wavelength_nm,excitation,emission`.
fn source(path: &Path) -> Vec<[f64; 3]> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap().trim(),
        "wavelength_nm,excitation,emission"
    );
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|c| c.trim().parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}

/// The photon limit of Q from the source curves: λmin / λ̄e, λmin the last zero sample
/// before the excitation turns positive, λ̄e the trapezoid mean of the emission.
fn photon_limit(rows: &[[f64; 3]]) -> f64 {
    let first = rows.iter().position(|r| r[1] > 0.0).unwrap();
    let shortest = rows[first.saturating_sub(1)][0];
    let (mut num, mut den) = (0.0, 0.0);
    for w in rows.windows(2) {
        let h = w[1][0] - w[0][0];
        num += 0.5 * h * (w[0][0] * w[0][2] + w[1][0] * w[1][2]);
        den += 0.5 * h * (w[0][2] + w[1][2]);
    }
    shortest / (num / den)
}

fn options(path: &Path, q: f64) -> ImportOptions {
    ImportOptions {
        name: "dye".into(),
        absorption: SpectrumSource {
            path: path.to_path_buf(),
            column: None,
        },
        emission: SpectrumSource {
            path: path.to_path_buf(),
            column: None,
        },
        reflectance: ReflectanceSource::Constant(0.8),
        concentration: 0.6,
        quantum_yield: q,
        yield_form: YieldForm::Energy,
    }
}

#[test]
fn dyes_become_valid_materials_matching_their_spectra() {
    let Some(dir) = common::shared("spectra") else {
        return;
    };
    for dye in DYES {
        let path = dir.join(dye);
        let rows = source(&path);
        let limit = photon_limit(&rows);
        let q = 0.9 * limit;
        let (material, report) = import_spectra(&options(&path, q)).unwrap();
        assert!(report.valid, "{dye}: {}", report.to_json());
        let f = &material.fluorophores[0];
        assert_eq!((f.concentration, f.quantum_yield), (0.6, q));
        let peak = rows.iter().map(|r| r[1]).fold(0.0, f64::max);
        let area: f64 = rows
            .windows(2)
            .map(|w| 0.5 * (w[1][0] - w[0][0]) * (w[0][2] + w[1][2]))
            .sum();
        for r in &rows {
            let (a, e) = (
                f.absorption.eval_zero_outside(r[0]),
                f.emission.eval_zero_outside(r[0]),
            );
            assert!((a - r[1] / peak).abs() < 1e-12, "{dye} a({})", r[0]);
            assert!((e - r[2] / area).abs() < 1e-12, "{dye} e({})", r[0]);
        }
        assert_eq!(f.absorption.max(), 1.0);
        assert!((f.emission.integral() - 1.0).abs() < 1e-12);
        // The photon quantum yield reported at the shortest absorbed wavelength is 0.9.
        let [_, phi_max] = report.fluorophores[0].photon_yield_range.unwrap();
        assert!((phi_max - 0.9).abs() < 1e-9, "{dye}: Φ max {phi_max}");
        assert!((material.reflectance.eval_clamped(500.0) - 0.8).abs() < 1e-15);
        println!(
            "{dye}: photon limit of Q {limit:.4}, λ̄e {:.2} nm",
            f.emission_mean_nm()
        );

        // Above the photon limit: refused, naming the law and the largest allowed Q.
        let err = import_spectra(&options(&path, 1.1 * limit))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(Law::Photons.name()) && err.contains("--quantum-yield"),
            "{err}"
        );
        assert!(err.contains(&format!("Q ≤ {limit:.6}")), "{err}");
    }
}

#[test]
fn cli_writes_a_checked_material_or_nothing() {
    let Some(dir) = common::shared("spectra") else {
        return;
    };
    let out = common::temp_dir("dyes");
    let dye = dir.join(DYES[0]);
    let bin = env!("CARGO_BIN_EXE_fluorite");
    let target = out.join("fluorescein.json");
    let run = |q: &str, target: &Path| {
        Command::new(bin)
            .args(["import-spectra", "--absorption"])
            .arg(&dye)
            .args([
                "--reflectance",
                "0.9",
                "-c",
                "0.5",
                "-q",
                q,
                "--name",
                "fluorescein",
                "-o",
            ])
            .arg(target)
            .output()
            .unwrap()
    };
    let o = run("0.4", &target);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let check = Command::new(bin)
        .arg("check")
        .arg(&target)
        .output()
        .unwrap();
    assert_eq!(check.status.code(), Some(0));
    // The published fluorescein yield of 0.93 is a photon yield; as an energy yield it
    // breaks photon conservation for absorption reaching 249 nm.
    let refused = out.join("refused.json");
    let o = run("0.93", &refused);
    assert_ne!(o.status.code(), Some(0));
    let stderr = String::from_utf8(o.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains("photons") && stderr.contains("lower --quantum-yield"),
        "{stderr}"
    );
    assert!(!refused.exists());
    std::fs::remove_dir_all(&out).unwrap();
}

/// λ̄e of the source emission (trapezoid mean), written out here.
fn mean_emission(rows: &[[f64; 3]]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for w in rows.windows(2) {
        let h = w[1][0] - w[0][0];
        num += 0.5 * h * (w[0][0] * w[0][2] + w[1][0] * w[1][2]);
        den += 0.5 * h * (w[0][2] + w[1][2]);
    }
    num / den
}

#[test]
fn a_published_photon_yield_builds_a_photon_form_material() {
    let Some(dir) = common::shared("spectra") else {
        return;
    };
    for dye in DYES {
        let path = dir.join(dye);
        let rows = source(&path);
        let limit = photon_limit(&rows);
        // 0.95 is above every dye's energy-form photon limit: refused as Q, kept as Φ.
        assert!(limit < 0.95, "{dye}: {limit}");
        assert!(import_spectra(&options(&path, 0.95)).is_err());
        let photon = ImportOptions {
            yield_form: YieldForm::Photon,
            ..options(&path, 0.95)
        };
        let (material, report) = import_spectra(&photon).unwrap();
        assert!(report.valid, "{dye}: {}", report.to_json());
        let f = &material.fluorophores[0];
        assert_eq!(f.yield_form, YieldForm::Photon);
        assert_eq!((f.concentration, f.quantum_yield), (0.6, 0.95));
        // The summary: Φ = 0.95 everywhere, the energy yield Φ·λ/λ̄e over the absorbed
        // wavelengths (the zero samples beside the positive ones bound them).
        let s = &report.fluorophores[0];
        assert_eq!(s.photon_yield_range, Some([0.95, 0.95]));
        let first = rows.iter().position(|r| r[1] > 0.0).unwrap();
        let last = rows.iter().rposition(|r| r[1] > 0.0).unwrap();
        let (lo, hi) = (
            rows[first.saturating_sub(1)][0],
            rows[(last + 1).min(rows.len() - 1)][0],
        );
        let mean = mean_emission(&rows);
        let [qlo, qhi] = s.energy_yield_range.unwrap();
        assert!((qlo - 0.95 * lo / mean).abs() < 1e-9, "{dye}: {qlo}");
        assert!((qhi - 0.95 * hi / mean).abs() < 1e-9, "{dye}: {qhi}");
        let json: serde_json::Value = serde_json::from_str(&material.to_json()).unwrap();
        assert_eq!(json["fluorophores"][0]["yield_form"], "photon");
        assert_eq!(json["fluorophores"][0]["photon_yield"], 0.95);
        assert!(json["fluorophores"][0].get("quantum_yield").is_none());

        // Φ above 1 (a percentage, say) is refused naming --photon-yield.
        let err = import_spectra(&ImportOptions {
            quantum_yield: 95.0,
            ..photon.clone()
        })
        .unwrap_err()
        .to_string();
        assert!(
            err.contains("--photon-yield") && err.contains("divided by 100"),
            "{err}"
        );
    }
}

#[test]
fn cli_takes_a_photon_yield() {
    let Some(dir) = common::shared("spectra") else {
        return;
    };
    let out = tempfile::tempdir().unwrap();
    let dye = dir.join(DYES[0]);
    let bin = env!("CARGO_BIN_EXE_fluorite");
    let target = out.path().join("fluorescein.json");
    let run = |extra: &[&str], target: &Path| {
        Command::new(bin)
            .args(["import-spectra", "--absorption"])
            .arg(&dye)
            .args(["--reflectance", "0.9", "-c", "0.5", "--name", "fluorescein"])
            .args(extra)
            .arg("-o")
            .arg(target)
            .output()
            .unwrap()
    };
    // Fluorescein's published photon yield, 0.93.
    let o = run(&["--photon-yield", "0.93"], &target);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stdout = String::from_utf8(o.stdout).unwrap();
    assert!(stdout.contains("photon form, Φ = 0.930000"), "{stdout}");
    let material = fluorite::Material::load(&target).unwrap();
    assert_eq!(material.fluorophores[0].yield_form, YieldForm::Photon);
    assert_eq!(material.fluorophores[0].quantum_yield, 0.93);
    let check = Command::new(bin)
        .arg("check")
        .arg(&target)
        .output()
        .unwrap();
    assert_eq!(check.status.code(), Some(0));
    // Both yields, or neither: a usage error, nothing written.
    let other = out.path().join("other.json");
    for extra in [&["-q", "0.4", "--photon-yield", "0.9"][..], &[][..]] {
        let o = run(extra, &other);
        assert_eq!(o.status.code(), Some(2), "{extra:?}");
        assert!(!other.exists());
    }
    let o = run(&["--photon-yield", "1.5"], &other);
    assert_ne!(o.status.code(), Some(0));
    let stderr = String::from_utf8(o.stderr).unwrap();
    assert!(
        stderr.contains("--photon-yield") && stderr.contains("[0, 1]"),
        "{stderr}"
    );
    assert!(!other.exists());
}
