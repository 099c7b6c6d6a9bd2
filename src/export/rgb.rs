//! `--to rgb`: the material reduced to one 3×3 matrix per light for RGB (or XYZ)
//! renderers, by the non-orthogonal reduction of Fichet, Belcour and Barla ("Non-Orthogonal
//! Reduction for Rendering Fluorescent Materials in Non-Spectral Engines", CGF 2024;
//! `reduce_matrix_ours` of afichet/fluorescence-rgb, `Reduce Matrix.ipynb`).
//!
//! With C the colour-matching functions of the space sampled at 1 nm (n × 3) and F the
//! material's reradiation matrix on the same samples (n × n, excitation rows), the
//! notebook's reduced matrix is R = (CᵀC)⁻¹·Cᵀ·F·C and a light of colour ℓ (a row,
//! ℓ = L·C) renders as ℓ·R. The file stores Rᵀ, so that out = M·in for column vectors.
//! The reduction is exact for lights in the span of C and an approximation otherwise; the
//! file reports, per light, the ΔE2000 between ℓ·R and the full spectral colour L·F·C.
//! The notebook samples 300–799 nm with the CIE 2006 observer; fluorite uses its own CIE
//! 1931 2° tables over 300–830 nm (trapezoid weights, as [`crate::colour::material_xyz`]).

use nalgebra::{Matrix3, Vector3};

use crate::colour::{
    Light, Xyz, cie1931, delta_e2000, material_xyz, xyz_to_lab, xyz_to_linear_srgb,
};
use crate::error::{Error, Result};
use crate::material::Material;
use crate::spectrum::{bin_widths, uniform_grid};

use super::{VERSION, one_line};

/// The colour space of the reduced matrix.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RgbSpace {
    /// Linear sRGB (ITU-R BT.709 primaries, D65 white).
    #[default]
    Srgb,
    /// CIE 1931 XYZ.
    Xyz,
}

impl RgbSpace {
    /// Parses `srgb` or `xyz`.
    pub fn parse(name: &str) -> Result<RgbSpace> {
        match name.to_ascii_lowercase().as_str() {
            "srgb" => Ok(RgbSpace::Srgb),
            "xyz" => Ok(RgbSpace::Xyz),
            _ => Err(Error::invalid(
                "--space",
                format!("\"{name}\" is not a colour space fluorite reduces to; choose srgb or xyz"),
            )),
        }
    }

    /// What the space is, for the file's header.
    pub fn description(self) -> &'static str {
        match self {
            RgbSpace::Srgb => {
                "linear sRGB (ITU-R BT.709 primaries, D65 white), CIE 1931 2° observer"
            }
            RgbSpace::Xyz => "CIE 1931 XYZ (2° observer)",
        }
    }

    /// A colour in this space from XYZ.
    fn of_xyz(self, xyz: Xyz) -> Vector3<f64> {
        Vector3::from(match self {
            RgbSpace::Srgb => xyz_to_linear_srgb(xyz),
            RgbSpace::Xyz => xyz,
        })
    }

    /// XYZ of a colour in this space.
    fn xyz_of(self, v: Vector3<f64>) -> Xyz {
        match self {
            RgbSpace::Xyz => [v[0], v[1], v[2]],
            RgbSpace::Srgb => {
                let unit = |c: usize| {
                    let mut xyz = [0.0; 3];
                    xyz[c] = 1.0;
                    self.of_xyz(xyz)
                };
                let to_rgb = Matrix3::from_columns(&[unit(0), unit(1), unit(2)]);
                let xyz = to_rgb.try_inverse().expect("the sRGB matrix is invertible") * v;
                [xyz[0], xyz[1], xyz[2]]
            }
        }
    }
}

/// The reduction of a material for one light.
#[derive(Debug, Clone, PartialEq)]
pub struct Reduction {
    /// The light's name.
    pub light: String,
    /// The space of every colour and of the matrix.
    pub space: RgbSpace,
    /// The reduced matrix M = Rᵀ: out = M·in for column vectors.
    pub matrix: [[f64; 3]; 3],
    /// The light's colour in the space, scaled to Y = 1.
    pub light_colour: [f64; 3],
    /// M·light_colour: what an RGB renderer shows for the patch under the light.
    pub reduced: [f64; 3],
    /// The full spectral colour of the patch under the light (the perfect white has Y = 1).
    pub spectral: [f64; 3],
    /// CIEDE2000 between `reduced` and `spectral` (CIELAB against the light's white).
    pub delta_e2000: f64,
}

/// Reduces `material` to a 3×3 matrix for `light` in `space`. A light the observer does
/// not see (Y = 0, e.g. UV only) has no white to judge colours against and is refused.
pub fn reduce(material: &Material, light: &Light, space: RgbSpace) -> Result<Reduction> {
    let observer = cie1931();
    let grid = uniform_grid(300.0, 830.0, 1.0);
    let widths = bin_widths(&grid);
    let basis: Vec<Vector3<f64>> = grid.iter().map(|&l| space.of_xyz(observer.at(l))).collect();
    // CᵀC, and CᵀFC: F is the diagonal d plus one rank-one term per fluorophore,
    // (c·Q·a)(λi)·e(λo)·Δλo.
    let mut gram = Matrix3::zeros();
    let mut reduced_f = Matrix3::zeros();
    let mut light_row = Vector3::zeros();
    for ((&l, w), c) in grid.iter().zip(&widths).zip(&basis) {
        gram += c * c.transpose();
        reduced_f += material.diagonal(l) * c * c.transpose();
        light_row += light.power(l) * w * c;
    }
    for f in &material.fluorophores {
        let mean = f.emission_mean_nm();
        let (mut absorbed, mut emitted) = (Vector3::zeros(), Vector3::zeros());
        for ((&l, w), c) in grid.iter().zip(&widths).zip(&basis) {
            absorbed += f.reradiated_with_mean(l, mean) * c;
            emitted += f.emission.eval_zero_outside(l) * w * c;
        }
        reduced_f += absorbed * emitted.transpose();
    }
    let r = gram
        .try_inverse()
        .expect("the colour-matching functions are independent")
        * reduced_f;
    let m = r.transpose();
    let (xyz, white) = material_xyz(material, light);
    let white_y = space.xyz_of(light_row)[1];
    if white_y.is_nan() || white_y <= 0.0 {
        return Err(Error::invalid(
            "--light",
            format!(
                "{} has no power the observer sees (Y = 0 over 360-830 nm): the reduction needs a visible light to scale colours against; add visible light or choose d65, a, f11 or uv",
                light.name
            ),
        ));
    }
    let light_colour = light_row / white_y;
    let reduced = m * light_colour;
    let spectral = space.of_xyz(xyz.map(|v| v / 100.0));
    let lab = |v: Vector3<f64>| xyz_to_lab(space.xyz_of(v).map(|c| 100.0 * c), white);
    let array = |v: Vector3<f64>| [v[0], v[1], v[2]];
    Ok(Reduction {
        light: light.name.clone(),
        space,
        matrix: [0, 1, 2].map(|i| [m[(i, 0)], m[(i, 1)], m[(i, 2)]]),
        light_colour: array(light_colour),
        reduced: array(reduced),
        spectral: array(spectral),
        delta_e2000: delta_e2000(lab(reduced), lab(spectral)),
    })
}

/// The JSON file of the reductions of `material` for `lights` in `space`, and the
/// reductions.
pub(super) fn rgb_json(
    material: &Material,
    lights: &[Light],
    space: RgbSpace,
) -> Result<(String, Vec<Reduction>)> {
    let reduced = lights
        .iter()
        .map(|light| reduce(material, light, space))
        .collect::<Result<Vec<Reduction>>>()?;
    let reductions: Vec<serde_json::Value> = reduced
        .iter()
        .map(|r| {
            serde_json::json!({
                "light": r.light,
                "matrix": r.matrix,
                "light_colour": r.light_colour,
                "reduced": r.reduced,
                "spectral": r.spectral,
                "delta_e2000": r.delta_e2000,
            })
        })
        .collect();
    let doc = serde_json::json!({
        "format": "fluorite-rgb-reduction/1",
        "fluorite_version": VERSION,
        "material": one_line(&material.name),
        "method": "non-orthogonal reduction of Fichet, Belcour, Barla (CGF 2024; afichet/fluorescence-rgb reduce_matrix_ours): R = (C^T C)^-1 C^T F C with C the colour-matching functions of the space and F the material's reradiation matrix, both at 1 nm over 300-830 nm; matrix = R^T",
        "convention": "column vectors: colour out = matrix . colour of the light in (matrix[row][column]); valid for the named light only, exact for lights in the span of the colour-matching functions",
        "space": space.description(),
        "scale": "light_colour is the light's colour with Y = 1; reduced = matrix . light_colour; spectral is the full spectral colour of the patch under the light (perfect white Y = 1)",
        "delta_e2000": "CIEDE2000 between reduced and spectral, CIELAB against the light's white",
        "reductions": reductions,
    });
    let mut text = serde_json::to_string_pretty(&doc).expect("JSON values serialise");
    text.push('\n');
    Ok((text, reduced))
}
