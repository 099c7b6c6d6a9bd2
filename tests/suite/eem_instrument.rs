//! Raw instrument EEMs (../shared/data/eem-instrument, skipped with a message when
//! absent): units are recognised, the files read without options, scatter is masked
//! where physics puts it, and surfaces pass through untouched.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common;
use crate::common::{files_in, shared};

use fluorite::eem::{EemOptions, UnitsChoice, prepare, units::classify};
use fluorite::fit::{FitOptions, FitOutcome, fit};
use fluorite::formats::{ReadOptions, read};

fn grid(first: f64, last: f64, step: f64) -> Vec<f64> {
    let n = ((last - first) / step).round() as usize;
    (0..=n).map(|i| first + step * i as f64).collect()
}

/// Water Raman, 3400 cm⁻¹ below the excitation wavenumber (written out independently).
fn raman_nm(ex: f64) -> f64 {
    1.0 / (1.0 / ex - 3400e-7)
}

fn dorrit_samples(dir: &Path) -> Vec<PathBuf> {
    files_in(dir, &["csv"])
        .into_iter()
        .filter(|p| !p.ends_with("concentrations.csv"))
        .collect()
}

#[test]
fn units_tell_surfaces_from_instrument_eems() {
    let (Some(measured), Some(eem)) = (shared("measured"), shared("eem-instrument")) else {
        return;
    };
    let mut surfaces = files_in(&measured, &["bfc"]);
    surfaces.extend(files_in(&measured, &["csv"]));
    assert!(surfaces.len() >= 6, "{surfaces:?}");
    for p in &surfaces {
        let m = read(p, &ReadOptions::default()).unwrap();
        let v = classify(&m);
        assert!(v.radiance_factor, "{}: {}", p.display(), v.reason);
        // And prepare leaves them exactly as read: surface fits are unchanged.
        let (prepared, report) = prepare(m.clone(), &EemOptions::default()).unwrap();
        assert!(report.is_none());
        assert_eq!(prepared, m);
    }
    let mut eems = vec![
        eem.join("stardom_d433sf.csv"),
        eem.join("stardom_d457sf.csv"),
    ];
    eems.extend(dorrit_samples(&eem.join("dorrit")));
    assert!(eems.len() >= 29);
    for p in &eems {
        let m = read(p, &ReadOptions::default()).unwrap();
        let v = classify(&m);
        assert!(!v.radiance_factor, "{}: {}", p.display(), v.reason);
        assert!(
            v.reason.contains("cannot be radiance factors"),
            "{}",
            v.reason
        );
    }
}

#[test]
fn instrument_files_read_without_options() {
    let Some(eem) = shared("eem-instrument") else {
        return;
    };
    // staRdom: empty corner, columns = excitation 230–455 nm (5 nm), rows = emission
    // 290–702 nm (4 nm); the orientation must be inferred.
    let m = read(&eem.join("stardom_d433sf.csv"), &ReadOptions::default()).unwrap();
    assert_eq!(m.excitation_nm, grid(230.0, 455.0, 5.0));
    assert_eq!(m.emission_nm, grid(290.0, 702.0, 4.0));
    // The file's second line: emission 290 nm, excitation 265 nm holds 140172.7.
    let (i, j) = (7, 0);
    assert_eq!((m.excitation_nm[i], m.emission_nm[j]), (265.0, 290.0));
    assert_eq!(m.get(i, j), 140172.7);
    // Dorrit: corner em\ex, excitation 200–315 nm, emission 200–750 nm, NaN = missing.
    let path = eem.join("dorrit/QAD.csv");
    let m = read(&path, &ReadOptions::default()).unwrap();
    assert_eq!(m.excitation_nm, grid(200.0, 315.0, 5.0));
    assert_eq!(m.emission_nm, grid(200.0, 750.0, 1.0));
    let text = std::fs::read_to_string(&path).unwrap();
    let nans = text.matches("NaN").count();
    assert!(nans > 0);
    assert_eq!(m.values.iter().filter(|v| v.is_nan()).count(), nans);
}

#[test]
fn scatter_is_masked_where_physics_puts_it() {
    let Some(eem) = shared("eem-instrument") else {
        return;
    };
    for name in ["stardom_d433sf.csv", "stardom_d457sf.csv"] {
        let raw = read(&eem.join(name), &ReadOptions::default()).unwrap();
        let (m, report) = prepare(raw.clone(), &EemOptions::default()).unwrap();
        let report = report.expect("an EEM is prepared");
        assert_eq!(report.units, "arbitrary");
        assert!(report.units_inferred);
        assert_eq!(report.scatter.len(), 4);
        assert!(!m.has_diagonal && m.arbitrary_scale);
        // The cell nearest each scatter line is masked in every row that reaches it.
        let nearest = |l: f64| {
            let em = &m.emission_nm;
            (l >= em[0] && l <= em[em.len() - 1]).then(|| {
                (0..em.len())
                    .min_by(|&a, &b| (em[a] - l).abs().total_cmp(&(em[b] - l).abs()))
                    .unwrap()
            })
        };
        let mut checked = 0;
        for (i, &ex) in m.excitation_nm.iter().enumerate() {
            for line in [ex, 2.0 * ex, raman_nm(ex), 2.0 * raman_nm(ex)] {
                if let Some(j) = nearest(line) {
                    assert!(
                        m.get(i, j).is_nan(),
                        "{name}: ex {ex}, em {} left",
                        m.emission_nm[j]
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 100, "{checked}");
        // The raw maximum is second-order Rayleigh (λo = 2λi); nothing that large is left.
        let max = |v: &[f64]| {
            v.iter()
                .filter(|x| x.is_finite())
                .fold(0.0f64, |a, &b| a.max(b))
        };
        let k = raw
            .values
            .iter()
            .position(|&v| v == max(&raw.values))
            .unwrap();
        let (i, j) = (k / raw.n_emission(), k % raw.n_emission());
        assert!((raw.emission_nm[j] - 2.0 * raw.excitation_nm[i]).abs() <= 4.0);
        assert!(max(&m.values) < 0.3 * max(&raw.values));

        // The fit gives shapes: DOM's humic-like emission (peak 400–500 nm), not a
        // scatter line of the excitation where it absorbs most.
        let FitOutcome::Shapes(shapes) = fit(&m, &FitOptions::default()).unwrap() else {
            panic!("{name}: an uncalibrated EEM must give shapes, not a material");
        };
        let peak = |s: &fluorite::Spectrum| {
            let k = (0..s.value.len())
                .max_by(|&a, &b| s.value[a].total_cmp(&s.value[b]))
                .unwrap();
            s.wavelength_nm[k]
        };
        let (em_peak, ex_peak) = (peak(&shapes.emission), peak(&shapes.absorption));
        assert!(
            (400.0..=500.0).contains(&em_peak),
            "{name}: emission peak {em_peak}"
        );
        for line in [2.0 * ex_peak, raman_nm(ex_peak), 2.0 * raman_nm(ex_peak)] {
            assert!(
                (em_peak - line).abs() > 15.0,
                "{name}: peak {em_peak} on {line}"
            );
        }
        assert!(shapes.k.is_none());
    }
}

#[test]
fn blank_must_share_the_grid_and_surfaces_refuse_eem_steps() {
    let (Some(eem), Some(measured)) = (shared("eem-instrument"), shared("measured")) else {
        return;
    };
    let sample = read(&eem.join("stardom_d433sf.csv"), &ReadOptions::default()).unwrap();
    let wrong = eem.join("dorrit/QAD.csv");
    let blank = read(&wrong, &ReadOptions::default()).unwrap();
    let options = EemOptions {
        blank: Some((blank, wrong.clone())),
        ..EemOptions::default()
    };
    let e = prepare(sample, &options).unwrap_err().to_string();
    assert!(
        e.contains("--blank") && e.contains("QAD.csv") && e.contains("grid"),
        "{e}"
    );
    // The right blank removes signal and is reported.
    let blank_path = eem.join("stardom_blank_mq11my.csv");
    let sample = read(&eem.join("stardom_d433sf.csv"), &ReadOptions::default()).unwrap();
    let options = EemOptions {
        blank: Some((
            read(&blank_path, &ReadOptions::default()).unwrap(),
            blank_path,
        )),
        ..EemOptions::default()
    };
    let (_, report) = prepare(sample, &options).unwrap();
    let b = report.unwrap().blank.unwrap();
    assert!(b.cells > 1000 && b.signal_share > 0.0 && b.signal_share < 1.0);
    // A surface with --blank: refused, naming the fix.
    let surface = read(&measured.join("HERPICER.BFC"), &ReadOptions::default()).unwrap();
    let blank_path = eem.join("stardom_blank_mq11my.csv");
    let options = EemOptions {
        blank: Some((surface.clone(), blank_path)),
        ..EemOptions::default()
    };
    let e = prepare(surface.clone(), &options).unwrap_err().to_string();
    assert!(e.contains("--units arbitrary"), "{e}");
    // --units arbitrary forces the EEM path even on a surface.
    let forced = EemOptions {
        units: UnitsChoice::Arbitrary,
        ..EemOptions::default()
    };
    let (m, report) = prepare(surface, &forced).unwrap();
    assert!(m.arbitrary_scale && !report.unwrap().units_inferred);
}

#[test]
fn cli_fits_a_stardom_sample_to_shapes_and_says_why() {
    let Some(eem) = shared("eem-instrument") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d433.json");
    let input = eem.join("stardom_d433sf.csv");
    let absorbance = eem.join("stardom_d433sf_absorbance.csv");
    let blank = eem.join("stardom_blank_mq11my.csv");
    let o = Command::new(env!("CARGO_BIN_EXE_fluorite"))
        .args(["fit", input.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(["--blank", blank.to_str().unwrap()])
        .args(["--absorbance", absorbance.to_str().unwrap()])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    for needle in [
        "units: arbitrary (inferred",
        "cannot be radiance factors",
        "scatter masked: rayleigh1",
        "raman2",
        "blank",
        "inner-filter correction",
        "shapes only",
    ] {
        assert!(stdout.contains(needle), "missing {needle:?} in\n{stdout}");
    }
    assert!(!stdout.contains("ΔE2000"), "{stdout}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(json["schema"], "fluorite-fluorophore/1");
    let pre = &json["fit"]["preprocessing"];
    assert_eq!(pre["units"], "arbitrary");
    assert_eq!(pre["scatter"].as_array().unwrap().len(), 4);
    assert!(pre["inner_filter"]["max_factor"].as_f64().unwrap() > 1.0);
    // --units radiance-factor contradicts counts: an error naming the unit they look like,
    // and the material already written is left as it was.
    let before = std::fs::read(&out).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_fluorite"))
        .args(["fit", input.to_str().unwrap(), "-o", out.to_str().unwrap()])
        .args(["--units", "radiance-factor", "-q"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cannot be radiance factors") && err.contains("--units arbitrary"),
        "{err}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), before);
}

/// `fit EEM --plot` draws the shapes fit against the prepared matrix: the figures are
/// written beside the JSON and decode as pictures (which cells they draw as masked is
/// tested in tests/plot_masked.rs).
#[test]
fn cli_plots_an_eem_fit_with_its_masked_scatter() {
    let Some(eem) = shared("eem-instrument") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d433.json");
    common::succeed(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .arg("fit")
            .arg(eem.join("stardom_d433sf.csv"))
            .args(["--plot", "-q", "-o"])
            .arg(&out),
    );
    for figure in ["d433-residuals.png", "d433-spectra.png"] {
        let bytes = std::fs::read(dir.path().join(figure))
            .unwrap_or_else(|e| panic!("{figure} missing: {e}"));
        let (width, height, _) = common::decode_png(&bytes);
        assert!(width > 200 && height > 200, "{figure}: {width}×{height}");
    }
}
