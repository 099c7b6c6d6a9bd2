//! Lights built from samples held in memory (the Python package's arrays), checked as a
//! CSV light is ([`Light::from_csv`]).

use crate::error::{Error, Result};
use crate::spectrum::Spectrum;

use super::Light;

impl Light {
    /// A light from samples: `wavelengths` in nm (strictly increasing, within the accepted
    /// range), relative `values` (finite, ≥ 0, not all zero), linear between samples and
    /// zero outside them, as a CSV light is read. `name` names it in reports.
    pub fn from_samples(name: &str, wavelengths: Vec<f64>, values: Vec<f64>) -> Result<Light> {
        let what = format!("light {name}");
        if wavelengths.len() != values.len() {
            return Err(Error::invalid(
                what,
                format!(
                    "has {} wavelengths but {} values; give one power per wavelength",
                    wavelengths.len(),
                    values.len()
                ),
            ));
        }
        if wavelengths.len() < 2 {
            return Err(Error::invalid(
                what,
                "needs at least two samples (wavelength in nm, power)",
            ));
        }
        for (l, v) in wavelengths.iter().zip(&values) {
            if let Err(message) = crate::limits::check_wavelength(*l) {
                return Err(Error::invalid(what, format!("wavelength {message}")));
            }
            if !v.is_finite() || *v < 0.0 {
                return Err(Error::invalid(
                    what,
                    format!("power {v} at {l} nm must be a non-negative finite number"),
                ));
            }
        }
        let spectrum = Spectrum::new(wavelengths, values, &what)?;
        if spectrum.value.iter().all(|&v| v == 0.0) {
            return Err(Error::invalid(what, "has no power at any wavelength"));
        }
        Ok(Light {
            name: name.to_string(),
            spectrum,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_light_from_samples_is_checked_like_a_csv_light() {
        let d65 = Light::builtin("d65").unwrap();
        let again = Light::from_samples(
            "d65",
            d65.spectrum.wavelength_nm.clone(),
            d65.spectrum.value.clone(),
        )
        .unwrap();
        assert_eq!(again, d65);
        for (wavelengths, values, why) in [
            (vec![400.0], vec![1.0], "at least two"),
            (vec![400.0, 500.0], vec![1.0], "one power per wavelength"),
            (vec![400.0, 500.0], vec![0.0, 0.0], "no power"),
            (vec![400.0, 500.0], vec![1.0, -1.0], "non-negative"),
            (vec![400.0, 500.0], vec![1.0, f64::NAN], "non-negative"),
            (vec![500.0, 400.0], vec![1.0, 1.0], "increasing"),
            (vec![10.0, 400.0], vec![1.0, 1.0], "wavelength"),
        ] {
            let e = Light::from_samples("x", wavelengths, values).unwrap_err();
            assert!(e.to_string().contains(why), "{why}: {e}");
        }
    }
}
