//! How to export, and which options each format uses: [`ExportOptions::validate`] refuses
//! an option the format would ignore, so a caller never gets files that silently differ
//! from what was asked. Errors name the `fluorite export` flag of the option.

use crate::colour::Light;
use crate::error::{Error, Result};
use crate::material::Material;
use crate::measurement::Units;

use super::ExportFormat;
use super::rgb::RgbSpace;

/// How to export. Each field is a flag of `fluorite export`, named in the errors of
/// [`ExportOptions::validate`].
#[derive(Debug, Clone)]
pub struct ExportOptions {
    /// The target format (`--to`).
    pub format: ExportFormat,
    /// Excitation grid of the matrix (`--excitation-grid`, `--grid`); default: the
    /// material's absorption and reflectance samples. For the formats that write the
    /// matrix ([`ExportFormat::writes_matrix`], and mitsuba for several fluorophores).
    pub excitation_nm: Option<Vec<f64>>,
    /// Emission grid of the matrix (`--emission-grid`, `--grid`); default: the
    /// material's emission and reflectance samples. For the same formats.
    pub emission_nm: Option<Vec<f64>>,
    /// Matrix values per emission bin (the default, like a BFC-450) or per nm
    /// (`--per-nm`: matrix, bfc, pbrt, and mitsuba for several fluorophores; art and exr
    /// hold per-bin cells only).
    pub units: Units,
    /// The lights (`--light`, each once) of the formats that use them
    /// ([`ExportFormat::uses_lights`]): baked exports (mitsuba, pbrt) write one baked
    /// spectrum per light; the first also picks the fluorophore kept by targets that hold
    /// one (mitsuba's fork, pearray); rgb writes one reduction per light. Empty: D65.
    pub lights: Vec<Light>,
    /// The colour space of the `rgb` reduction (`--space`); `None`: linear sRGB.
    pub space: Option<RgbSpace>,
}

impl ExportOptions {
    /// Options for `format` with default grids, per bin, under D65.
    pub fn new(format: ExportFormat) -> Self {
        ExportOptions {
            format,
            excitation_nm: None,
            emission_nm: None,
            units: Units::PerBin,
            lights: Vec::new(),
            space: None,
        }
    }

    /// Refuses every option `material`'s export in this format would not use (a grid or
    /// `--per-nm` without a matrix, lights without baked spectra or reductions, a colour
    /// space without the rgb reduction), per-nm cells in the layouts that hold per-bin
    /// cells only (art, exr), an empty or unsorted grid and a light given twice. The
    /// error names the flag and what to do.
    pub fn validate(&self, material: &Material) -> Result<()> {
        let format = self.format;
        let name = format.name();
        let per_nm = self.units == Units::PerNm;
        // The EXR layout's cells are per emission bin, as its reference implementation
        // reads them, and the layout has no field to say otherwise.
        if format == ExportFormat::Exr && per_nm {
            return Err(Error::invalid(
                "--per-nm",
                "does not apply to exr: the layout's reradiation cells are per emission bin",
            ));
        }
        if format == ExportFormat::Art && per_nm {
            return Err(Error::invalid(
                "--per-nm",
                "ART archives hold radiance factors per emission bin, like the BFC-450; leave --per-nm out",
            ));
        }
        if !format.uses_lights() && !self.lights.is_empty() {
            return Err(Error::invalid(
                "--light",
                format!(
                    "applies to mitsuba, pbrt, pearray and rgb (baked spectra, reductions), not to {name}"
                ),
            ));
        }
        if format != ExportFormat::Rgb && self.space.is_some() {
            return Err(Error::invalid(
                "--space",
                format!("applies to the rgb reduction, not to {name}"),
            ));
        }
        let matrix_options = self.excitation_nm.is_some() || self.emission_nm.is_some() || per_nm;
        // Mitsuba exports carry the matrix only for several fluorophores.
        let without_matrix = match format {
            ExportFormat::Mitsuba if material.fluorophores.len() < 2 => Some(format!(
                "{name} with fewer than two fluorophores (only then does it include the matrix)"
            )),
            ExportFormat::Mitsuba => None,
            _ => (!format.writes_matrix()).then(|| name.to_string()),
        };
        if let Some(what) = without_matrix.filter(|_| matrix_options) {
            return Err(Error::invalid(
                "--grid/--per-nm",
                format!("apply to the matrix formats (matrix, bfc, pbrt, art, exr), not to {what}"),
            ));
        }
        for (grid, flag) in [
            (&self.excitation_nm, "--excitation-grid"),
            (&self.emission_nm, "--emission-grid"),
        ] {
            match grid.as_deref() {
                Some([]) => {
                    return Err(Error::invalid(
                        flag,
                        "is empty; give at least one wavelength in nm",
                    ));
                }
                Some(grid) => crate::spectrum::check_grid(grid, flag)?,
                None => {}
            }
        }
        if let Some(twice) = self
            .lights
            .iter()
            .enumerate()
            .find(|(i, l)| self.lights[..*i].iter().any(|o| o.name == l.name))
        {
            return Err(Error::invalid(
                "--light",
                format!("names {} twice; give each light once", twice.1.name),
            ));
        }
        Ok(())
    }

    /// The lights the export uses: those given, or D65.
    pub(super) fn lights_or_d65(&self) -> Vec<Light> {
        if self.lights.is_empty() {
            Light::builtin("d65").into_iter().collect()
        } else {
            self.lights.clone()
        }
    }
}
