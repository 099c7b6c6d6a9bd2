//! The band search's limits are the library's (`check_band_search`); `fluorite bands`
//! names its own flags, not the library's parameter names, in the same refusals.

use crate::common;

use std::process::Command;

use fluorite::parametric::BandDomain;
use fluorite::parametric::fit::{check_band_search, fit_bands_to_tolerance};

/// 31 samples, 400–700 nm, of two Gaussian bands in wavelength (centres 480 and 600 nm).
fn curve() -> (Vec<f64>, Vec<f64>) {
    let nm: Vec<f64> = (0..=30).map(|i| 400.0 + 10.0 * i as f64).collect();
    let gauss = |x: f64, centre: f64, width: f64| (-0.5 * ((x - centre) / width).powi(2)).exp();
    let values = nm
        .iter()
        .map(|&l| gauss(l, 480.0, 30.0) + 0.5 * gauss(l, 600.0, 25.0))
        .collect();
    (nm, values)
}

#[test]
fn the_library_refuses_searches_it_cannot_run() {
    let (nm, values) = curve();
    for (max_bands, tolerance, expected) in [
        (0, 0.01, "max_bands: is 0; allow at least one band"),
        (
            3,
            0.0,
            "tolerance_rel_rms: is 0; give a positive fraction of the peak",
        ),
        (3, -0.1, "tolerance_rel_rms: is -0.1"),
        (3, f64::NAN, "tolerance_rel_rms: is NaN"),
        (3, f64::INFINITY, "tolerance_rel_rms: is inf"),
    ] {
        let e = check_band_search(max_bands, tolerance)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(expected), "{e}");
        let e = fit_bands_to_tolerance(&nm, &values, BandDomain::Wavelength, max_bands, tolerance)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with(expected), "{e}");
    }
    assert!(check_band_search(1, 1e-12).is_ok());
    // A tolerance below what one band reaches on two bands tries every count allowed.
    let fits = fit_bands_to_tolerance(&nm, &values, BandDomain::Wavelength, 1, 1e-12).unwrap();
    assert_eq!(fits.len(), 1);
    assert!(fits[0].rel_rms > 1e-12);
}

#[test]
fn the_command_names_its_flags() {
    let dir = crate::common::temp_dir("command");
    let (nm, values) = curve();
    let mut text = String::from("wavelength_nm,emission\n");
    for (l, v) in nm.iter().zip(&values) {
        text.push_str(&format!("{l},{v}\n"));
    }
    std::fs::write(dir.join("curve.csv"), text).unwrap();
    for (flags, expected) in [
        (
            vec!["--tolerance", "0"],
            "--tolerance: is 0; give a positive fraction of the peak, such as 0.01",
        ),
        (
            vec!["--max-bands", "0"],
            "--max-bands: is 0; allow at least one band",
        ),
        // 11 bands need 33 samples; the curve has 31 (refused by the fit itself).
        (
            vec!["--max-bands", "11"],
            "curve.csv: emission: --max-bands: is 11, which needs at least 33 samples",
        ),
    ] {
        let (code, stderr) = common::refused(
            Command::new(env!("CARGO_BIN_EXE_fluorite"))
                .args(["bands", "curve.csv"])
                .args(&flags)
                .current_dir(&dir),
        );
        assert_eq!(code, Some(2), "{flags:?}: {stderr}");
        assert!(stderr.contains(expected), "{flags:?}: {stderr}");
        assert!(
            !stderr.contains("max_bands") && !stderr.contains("tolerance_rel_rms"),
            "{stderr}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
