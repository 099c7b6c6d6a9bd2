//! EEM preparation refuses impossible options and empty inputs in the library
//! (`eem::prepare`, `EemOptions::validate`), naming the `fluorite fit` flag, and never
//! panics on them; the command prints the same messages.

use crate::common;

use std::path::Path;
use std::process::Command;

use fluorite::Units;
use fluorite::eem::correct::{Absorbance, inner_filter, subtract_blank};
use fluorite::eem::scatter::ScatterOptions;
use fluorite::eem::{EemOptions, prepare, units::classify};
use fluorite::formats::{RowsAre, write_wide_csv};
use fluorite::measurement::Measurement;

/// A synthetic solution EEM in counts: one fluorescence peak (ex 330, em 420 nm) of
/// 5000 counts on first-order Rayleigh scatter of 20000 counts.
fn eem() -> Measurement {
    let ex: Vec<f64> = (0..=15).map(|i| 250.0 + 10.0 * i as f64).collect();
    let em: Vec<f64> = (0..=68).map(|i| 260.0 + 5.0 * i as f64).collect();
    let gauss = |x: f64, centre: f64, width: f64| (-0.5 * ((x - centre) / width).powi(2)).exp();
    let values = ex
        .iter()
        .flat_map(|&i| {
            em.iter().map(move |&o| {
                10.0 + 5000.0 * gauss(i, 330.0, 25.0) * gauss(o, 420.0, 30.0)
                    + 20000.0 * gauss(o, i, 3.0)
            })
        })
        .collect();
    Measurement::new("synthetic-eem", ex, em, values, Units::PerBin).unwrap()
}

/// A radiance-factor matrix: reflectance 0.5 on the diagonal, nothing else.
fn surface() -> Measurement {
    let grid: Vec<f64> = (0..=10).map(|i| 400.0 + 10.0 * i as f64).collect();
    let n = grid.len();
    let values = (0..n * n)
        .map(|k| if k / n == k % n { 0.5 } else { 0.0 })
        .collect();
    Measurement::new("surface", grid.clone(), grid, values, Units::PerBin).unwrap()
}

fn with_scatter(scatter: ScatterOptions) -> EemOptions {
    EemOptions {
        scatter,
        ..EemOptions::default()
    }
}

fn refusal(m: Measurement, options: &EemOptions) -> String {
    match prepare(m, options) {
        Ok(_) => panic!("prepared with {options:?}"),
        Err(e) => e.to_string(),
    }
}

/// Each impossible scatter option, and the start of the message naming its flag.
fn impossible_scatter_options() -> Vec<(ScatterOptions, &'static str)> {
    let width = |k: usize, w: f64| {
        let mut half_width_nm = [None; 4];
        half_width_nm[k] = Some(w);
        ScatterOptions {
            half_width_nm,
            ..ScatterOptions::default()
        }
    };
    let bandwidth = |b: f64| ScatterOptions {
        bandwidth_nm: Some(b),
        ..ScatterOptions::default()
    };
    let shift = |s: f64| ScatterOptions {
        raman_shift_cm: Some(s),
        ..ScatterOptions::default()
    };
    vec![
        (
            width(1, -2.0),
            "--scatter-width \"raman1=-2\": \"-2\" is not a width in nm (a number ≥ 0)",
        ),
        (width(3, f64::NAN), "--scatter-width \"raman2=NaN\""),
        (width(0, f64::INFINITY), "--scatter-width \"rayleigh1=inf\""),
        (
            bandwidth(0.0),
            "--bandwidth 0: must be a positive width in nm",
        ),
        (bandwidth(-5.0), "--bandwidth -5: must be a positive width"),
        (bandwidth(f64::NAN), "--bandwidth NaN"),
        (
            shift(0.0),
            "--raman-shift 0: must be a positive wavenumber in cm⁻¹",
        ),
        (shift(-3400.0), "--raman-shift -3400"),
        (shift(f64::INFINITY), "--raman-shift inf"),
    ]
}

#[test]
fn impossible_scatter_options_are_refused_for_eems_and_surfaces() {
    for (scatter, expected) in impossible_scatter_options() {
        let options = with_scatter(scatter);
        assert!(options.validate().is_err(), "{expected}");
        for m in [eem(), surface()] {
            let e = refusal(m, &options);
            assert!(e.starts_with(expected), "{e}");
        }
    }
}

#[test]
fn possible_scatter_options_prepare() {
    let options = with_scatter(ScatterOptions {
        half_width_nm: [Some(0.0), None, Some(12.0), None],
        bandwidth_nm: Some(5.0),
        raman_shift_cm: Some(3400.0),
    });
    let (m, report) = prepare(eem(), &options).unwrap();
    assert!(m.arbitrary_scale);
    let report = report.unwrap();
    assert_eq!(report.scatter.len(), 4);
    // Width 0 masks exactly the cells on the line (λo = λi), here one per excitation
    // row inside the emission range: 250 and 255 nm lie below it.
    assert_eq!(report.scatter[0].cells, 16 - 1);
}

#[test]
fn empty_matrices_are_errors_not_panics() {
    let mut empty = eem();
    empty.excitation_nm.clear();
    empty.values.clear();
    let verdict = classify(&empty);
    assert!(!verdict.radiance_factor && verdict.reason.contains("grid"));
    assert!(refusal(empty.clone(), &EemOptions::default()).contains("grid"));
    let mut short = eem();
    short.values.pop();
    assert!(!classify(&short).radiance_factor);
    assert!(refusal(short.clone(), &EemOptions::default()).contains("values"));

    let source = Path::new("blank.csv");
    let e = subtract_blank(&mut eem(), &empty, source)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("synthetic-eem: values") && e.contains("0 excitation"),
        "{e}"
    );
    let e = subtract_blank(&mut short.clone(), &eem(), source)
        .unwrap_err()
        .to_string();
    assert!(e.contains("values"), "{e}");
    let options = EemOptions {
        blank: Some((empty.clone(), source.to_path_buf())),
        ..EemOptions::default()
    };
    let e = refusal(eem(), &options);
    assert!(e.starts_with("--blank blank.csv: "), "{e}");

    let absorbance = Absorbance {
        wavelength_nm: vec![200.0, 800.0],
        absorbance: vec![0.1, 0.1],
    };
    let e = inner_filter(&mut empty.clone(), &absorbance, Path::new("a.csv"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("values"), "{e}");
}

#[test]
fn unusable_absorbance_spectra_are_errors_not_panics() {
    let empty = Absorbance {
        wavelength_nm: vec![],
        absorbance: vec![],
    };
    assert_eq!(empty.at(400.0), None);
    let uneven = Absorbance {
        wavelength_nm: vec![200.0, 500.0, 800.0],
        absorbance: vec![0.1],
    };
    assert_eq!(uneven.at(500.0), None);
    let unsorted = Absorbance {
        wavelength_nm: vec![800.0, 200.0],
        absorbance: vec![0.1, 0.2],
    };
    let infinite = Absorbance {
        wavelength_nm: vec![200.0, 800.0],
        absorbance: vec![0.1, f64::INFINITY],
    };
    let source = Path::new("a.csv");
    for (a, expected) in [
        (&empty, "holds 0 wavelengths and 0 absorbances"),
        (&uneven, "holds 3 wavelengths and 1 absorbances"),
        (&unsorted, "wavelength_nm[1]"),
        (&infinite, "absorbance at 800 nm is inf"),
    ] {
        let e = a.validate(source).unwrap_err().to_string();
        assert!(
            e.starts_with("--absorbance a.csv") && e.contains(expected),
            "{e}"
        );
        let e = inner_filter(&mut eem(), a, source).unwrap_err().to_string();
        assert!(e.contains(expected), "{e}");
        let options = EemOptions {
            absorbance: Some((a.clone(), source.to_path_buf())),
            ..EemOptions::default()
        };
        assert!(refusal(eem(), &options).contains(expected));
    }
    // Linear interpolation between the samples of a usable spectrum.
    assert_eq!(infinite.at(200.0), Some(0.1));
    let usable = Absorbance {
        wavelength_nm: vec![200.0, 800.0],
        absorbance: vec![0.1, 0.4],
    };
    assert!((usable.at(400.0).unwrap() - 0.2).abs() < 1e-12);
}

#[test]
fn the_command_prints_the_library_messages() {
    let dir = common::temp_dir("command");
    std::fs::write(
        dir.join("eem.csv"),
        write_wide_csv(&eem(), RowsAre::Excitation),
    )
    .unwrap();
    for (flags, expected) in [
        (
            vec!["--bandwidth", "0"],
            "--bandwidth 0: must be a positive width in nm (e.g. 5 for 5 nm slits)",
        ),
        (
            vec!["--raman-shift=-1"],
            "--raman-shift -1: must be a positive wavenumber in cm⁻¹ (water: 3400)",
        ),
        (
            vec!["--scatter-width", "raman1=-2"],
            "--scatter-width \"raman1=-2\": \"-2\" is not a width in nm (a number ≥ 0)",
        ),
        (
            vec!["--scatter-width", "raman1=wide"],
            "--scatter-width \"raman1=wide\": \"wide\" is not a width in nm (a number ≥ 0)",
        ),
    ] {
        let (_, stderr) = common::refused(
            Command::new(env!("CARGO_BIN_EXE_fluorite"))
                .args(["fit", "eem.csv"])
                .args(&flags)
                .current_dir(&dir),
        );
        assert!(stderr.contains(expected), "{flags:?}: {stderr}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
