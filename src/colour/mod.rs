//! Colour: the CIE 1931 observer, the lights a material is judged under, CIELAB,
//! CIEDE2000 and sRGB, and the colour of a flat patch described by a reradiation matrix.
//!
//! The CIE tables are embedded (standard colorimetric data), so colour needs no files.

use std::path::Path;
use std::sync::OnceLock;

use crate::error::{Error, Result};
use crate::material::Material;
use crate::spectrum::{Spectrum, uniform_grid};

mod patch;
mod samples;

pub use patch::PatchColorimeter;

/// CIE XYZ tristimulus values.
pub type Xyz = [f64; 3];
/// CIELAB L*, a*, b*.
pub type Lab = [f64; 3];

/// The CIE 1931 2° colour-matching functions x̄, ȳ, z̄ (360–830 nm, 1 nm).
pub struct Observer {
    /// x̄(λ).
    pub x: Spectrum,
    /// ȳ(λ).
    pub y: Spectrum,
    /// z̄(λ).
    pub z: Spectrum,
}

impl Observer {
    /// [x̄, ȳ, z̄] at `nm` (zero outside 360–830 nm).
    pub fn at(&self, nm: f64) -> Xyz {
        [
            self.x.eval_zero_outside(nm),
            self.y.eval_zero_outside(nm),
            self.z.eval_zero_outside(nm),
        ]
    }
}

fn parse_table(text: &str, columns: usize) -> Vec<Vec<f64>> {
    let mut out = vec![Vec::new(); columns];
    for line in text.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        for (col, field) in line.split(',').take(columns).enumerate() {
            out[col].push(field.trim().parse().expect("embedded CIE table is numeric"));
        }
    }
    out
}

/// The CIE 1931 2° standard observer.
pub fn cie1931() -> &'static Observer {
    static OBSERVER: OnceLock<Observer> = OnceLock::new();
    OBSERVER.get_or_init(|| {
        let t = parse_table(include_str!("cie1931_2deg_xyz.csv"), 4);
        let s = |col: usize| Spectrum {
            wavelength_nm: t[0].clone(),
            value: t[col].clone(),
        };
        Observer {
            x: s(1),
            y: s(2),
            z: s(3),
        }
    })
}

fn embedded_illuminant(text: &str) -> Spectrum {
    let t = parse_table(text, 2);
    Spectrum {
        wavelength_nm: t[0].clone(),
        value: t[1].clone(),
    }
}

/// Names of the built-in lights, in the order reports list them.
pub const STANDARD_LIGHTS: [&str; 4] = ["d65", "a", "f11", "uv"];

/// Peak of the UV LED added to D65 in the `uv` light (nm).
pub const UV_LED_PEAK_NM: f64 = 365.0;
/// Full width at half maximum of the UV LED (nm).
pub const UV_LED_FWHM_NM: f64 = 10.0;

/// A light source: a relative spectral power distribution, zero outside its samples.
#[derive(Debug, Clone, PartialEq)]
pub struct Light {
    /// `d65`, `a`, `f11`, `uv`, or the file stem of a custom light.
    pub name: String,
    /// Relative spectral power.
    pub spectrum: Spectrum,
}

impl Light {
    /// A built-in light by name: `d65` (CIE D65 from 300 nm), `a` (CIE A), `f11` (CIE
    /// F11, 380–780 nm) or `uv` (D65 plus a 365 nm LED, Gaussian of 10 nm FWHM, with the
    /// same radiant power over 300–780 nm as the D65 part).
    pub fn builtin(name: &str) -> Option<Light> {
        let spectrum = match name.to_ascii_lowercase().as_str() {
            "d65" => embedded_illuminant(include_str!("illuminant_D65.csv")),
            "a" => embedded_illuminant(include_str!("illuminant_A.csv")),
            "f11" => embedded_illuminant(include_str!("illuminant_F11.csv")),
            "uv" => uv_light(),
            _ => return None,
        };
        Some(Light {
            name: name.to_ascii_lowercase(),
            spectrum,
        })
    }

    /// The four lights every fit is judged under.
    pub fn standard() -> Vec<Light> {
        STANDARD_LIGHTS
            .iter()
            .map(|n| Light::builtin(n).expect("standard light is built in"))
            .collect()
    }

    /// A built-in light by name, or else a two-column CSV file (`wavelength_nm,power`,
    /// an optional header line).
    pub fn parse(name_or_path: &str) -> Result<Light> {
        if let Some(light) = Light::builtin(name_or_path) {
            return Ok(light);
        }
        let path = Path::new(name_or_path);
        if !path.exists() {
            return Err(Error::invalid(
                "light",
                format!(
                    "\"{name_or_path}\" is neither a built-in light ({}) nor an existing CSV file",
                    STANDARD_LIGHTS.join(", ")
                ),
            ));
        }
        Light::from_csv(path)
    }

    /// Reads a two-column CSV light (`wavelength_nm,power`, optional header).
    pub fn from_csv(path: &Path) -> Result<Light> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let mut wavelengths = Vec::new();
        let mut values = Vec::new();
        for (line, fields) in crate::formats::delimited_fields(&text) {
            if fields.len() < 2 {
                return Err(Error::parse(
                    path,
                    line,
                    0,
                    "expected two columns: wavelength_nm,power",
                ));
            }
            let parsed: Vec<Option<f64>> =
                fields[..2].iter().map(|f| f.parse::<f64>().ok()).collect();
            match (parsed[0], parsed[1]) {
                (Some(l), Some(v)) => {
                    if !v.is_finite() || v < 0.0 {
                        return Err(Error::parse(
                            path,
                            line,
                            2,
                            format!("power {v} must be a non-negative finite number"),
                        ));
                    }
                    if let Err(message) = crate::limits::check_wavelength(l) {
                        return Err(Error::parse(path, line, 1, format!("wavelength {message}")));
                    }
                    wavelengths.push(l);
                    values.push(v);
                }
                _ if wavelengths.is_empty() && values.is_empty() => continue, // header line
                (None, _) => {
                    return Err(Error::parse(
                        path,
                        line,
                        1,
                        format!("\"{}\" is not a wavelength", fields[0]),
                    ));
                }
                (_, None) => {
                    return Err(Error::parse(
                        path,
                        line,
                        2,
                        format!("\"{}\" is not a number", fields[1]),
                    ));
                }
            }
        }
        if wavelengths.len() < 2 {
            return Err(Error::parse(
                path,
                0,
                0,
                "a light needs at least two samples (wavelength_nm,power)",
            ));
        }
        let spectrum = Spectrum::new(wavelengths, values, "light")
            .map_err(|e| Error::parse(path, 0, 0, e.to_string()))?;
        if spectrum.value.iter().all(|&v| v == 0.0) {
            return Err(Error::parse(
                path,
                0,
                0,
                "the light has no power at any wavelength",
            ));
        }
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(Light { name, spectrum })
    }

    /// Relative power at `nm` (zero outside the light's samples).
    pub fn power(&self, nm: f64) -> f64 {
        self.spectrum.eval_zero_outside(nm)
    }
}

fn uv_light() -> Spectrum {
    let d65 = embedded_illuminant(include_str!("illuminant_D65.csv"));
    let grid = uniform_grid(300.0, 780.0, 0.5);
    let sigma = UV_LED_FWHM_NM / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt());
    let led: Vec<f64> = grid
        .iter()
        .map(|l| (-0.5 * ((l - UV_LED_PEAK_NM) / sigma).powi(2)).exp())
        .collect();
    let led = Spectrum {
        wavelength_nm: grid.clone(),
        value: led,
    };
    let d65_fine = d65.resample_zero_outside(&grid);
    let scale = d65_fine.integral() / led.integral();
    Spectrum {
        wavelength_nm: grid,
        value: d65_fine
            .value
            .iter()
            .zip(&led.value)
            .map(|(d, l)| d + scale * l)
            .collect(),
    }
}

/// CIE XYZ → CIELAB relative to `white` (same units as `xyz`).
pub fn xyz_to_lab(xyz: Xyz, white: Xyz) -> Lab {
    let f = |t: f64| {
        let delta: f64 = 6.0 / 29.0;
        if t > delta.powi(3) {
            t.cbrt()
        } else {
            t / (3.0 * delta * delta) + 4.0 / 29.0
        }
    };
    let fx = f(xyz[0] / white[0]);
    let fy = f(xyz[1] / white[1]);
    let fz = f(xyz[2] / white[2]);
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// ∂(L*, a*, b*)/∂(X, Y, Z) at `xyz` against `white`.
pub fn lab_jacobian(xyz: Xyz, white: Xyz) -> [[f64; 3]; 3] {
    let delta: f64 = 6.0 / 29.0;
    let slope = |value: f64, reference: f64| {
        let t = value / reference.max(1e-300);
        let df = if t > delta.powi(3) {
            t.powf(-2.0 / 3.0) / 3.0
        } else {
            1.0 / (3.0 * delta * delta)
        };
        df / reference.max(1e-300)
    };
    let (fx, fy, fz) = (
        slope(xyz[0], white[0]),
        slope(xyz[1], white[1]),
        slope(xyz[2], white[2]),
    );
    [
        [0.0, 116.0 * fy, 0.0],
        [500.0 * fx, -500.0 * fy, 0.0],
        [0.0, 200.0 * fy, -200.0 * fz],
    ]
}

/// CIEDE2000 colour difference (Sharma, Wu, Dalal 2005), kL = kC = kH = 1.
pub fn delta_e2000(lab1: Lab, lab2: Lab) -> f64 {
    use std::f64::consts::PI;
    let [l1, a1, b1] = lab1;
    let [l2, a2, b2] = lab2;
    let c1 = a1.hypot(b1);
    let c2 = a2.hypot(b2);
    let c_mean = 0.5 * (c1 + c2);
    let g = 0.5 * (1.0 - (c_mean.powi(7) / (c_mean.powi(7) + 25f64.powi(7))).sqrt());
    let a1p = (1.0 + g) * a1;
    let a2p = (1.0 + g) * a2;
    let c1p = a1p.hypot(b1);
    let c2p = a2p.hypot(b2);
    let hue = |b: f64, a: f64| {
        if a == 0.0 && b == 0.0 {
            0.0
        } else {
            let h = b.atan2(a).to_degrees();
            if h < 0.0 { h + 360.0 } else { h }
        }
    };
    let h1p = hue(b1, a1p);
    let h2p = hue(b2, a2p);
    let dl = l2 - l1;
    let dc = c2p - c1p;
    let dh_angle = if c1p * c2p == 0.0 {
        0.0
    } else {
        let d = h2p - h1p;
        if d > 180.0 {
            d - 360.0
        } else if d < -180.0 {
            d + 360.0
        } else {
            d
        }
    };
    let dh = 2.0 * (c1p * c2p).sqrt() * (dh_angle.to_radians() / 2.0).sin();
    let l_mean = 0.5 * (l1 + l2);
    let cp_mean = 0.5 * (c1p + c2p);
    let hp_mean = if c1p * c2p == 0.0 {
        h1p + h2p
    } else if (h1p - h2p).abs() <= 180.0 {
        0.5 * (h1p + h2p)
    } else if h1p + h2p < 360.0 {
        0.5 * (h1p + h2p + 360.0)
    } else {
        0.5 * (h1p + h2p - 360.0)
    };
    let t = 1.0 - 0.17 * (hp_mean - 30.0).to_radians().cos()
        + 0.24 * (2.0 * hp_mean).to_radians().cos()
        + 0.32 * (3.0 * hp_mean + 6.0).to_radians().cos()
        - 0.20 * (4.0 * hp_mean - 63.0).to_radians().cos();
    let d_theta = 30.0 * (-((hp_mean - 275.0) / 25.0).powi(2)).exp();
    let rc = 2.0 * (cp_mean.powi(7) / (cp_mean.powi(7) + 25f64.powi(7))).sqrt();
    let sl = 1.0 + 0.015 * (l_mean - 50.0).powi(2) / (20.0 + (l_mean - 50.0).powi(2)).sqrt();
    let sc = 1.0 + 0.045 * cp_mean;
    let sh = 1.0 + 0.015 * cp_mean * t;
    let rt = -(2.0 * d_theta * PI / 180.0).sin() * rc;
    ((dl / sl).powi(2) + (dc / sc).powi(2) + (dh / sh).powi(2) + rt * (dc / sc) * (dh / sh)).sqrt()
}

/// Bradford chromatic adaptation of `xyz` seen under `from_white` to `to_white`, so that
/// patches under different lights can be shown side by side as a viewer adapted to each
/// light would see them.
pub fn adapt_bradford(xyz: Xyz, from_white: Xyz, to_white: Xyz) -> Xyz {
    const M: [[f64; 3]; 3] = [
        [0.8951, 0.2664, -0.1614],
        [-0.7502, 1.7135, 0.0367],
        [0.0389, -0.0685, 1.0296],
    ];
    const M_INV: [[f64; 3]; 3] = [
        [0.9869929, -0.1470543, 0.1599627],
        [0.4323053, 0.5183603, 0.0492912],
        [-0.0085287, 0.0400428, 0.9684867],
    ];
    let mul = |m: &[[f64; 3]; 3], v: Xyz| -> Xyz {
        [
            m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
            m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
            m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
        ]
    };
    let src = mul(&M, from_white);
    let dst = mul(&M, to_white);
    let cone = mul(&M, xyz);
    mul(
        &M_INV,
        [
            cone[0] * dst[0] / src[0],
            cone[1] * dst[1] / src[1],
            cone[2] * dst[2] / src[2],
        ],
    )
}

/// The D65 white point with Y = 1.
pub const D65_WHITE: Xyz = [0.95047, 1.0, 1.08883];

/// XYZ (D65 white, Y = 1 for white) → linear sRGB (may fall outside [0, 1]).
pub fn xyz_to_linear_srgb(xyz: Xyz) -> [f64; 3] {
    [
        3.2404542 * xyz[0] - 1.5371385 * xyz[1] - 0.4985314 * xyz[2],
        -0.9692660 * xyz[0] + 1.8760108 * xyz[1] + 0.0415560 * xyz[2],
        0.0556434 * xyz[0] - 0.2040259 * xyz[1] + 1.0572252 * xyz[2],
    ]
}

/// Luminance weights of linear sRGB: the Y row of its matrix to XYZ as IEC 61966-2-1
/// publishes it (four decimals, the Rec. 709 primaries), so Y = w · rgb.
pub const SRGB_LUMINANCE: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Linear sRGB component → 8-bit sRGB, clipped to [0, 1] first.
pub fn srgb_encode(linear: f64) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let v = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0).round() as u8
}

/// XYZ with the white at Y = 1 under D65 → 8-bit sRGB.
pub fn xyz_to_srgb8(xyz: Xyz) -> [u8; 3] {
    let rgb = xyz_to_linear_srgb(xyz);
    [
        srgb_encode(rgb[0]),
        srgb_encode(rgb[1]),
        srgb_encode(rgb[2]),
    ]
}

/// XYZ of a flat patch of `material` under `light`, integrated at 1 nm over the observer's
/// range, with the non-fluorescent perfect white over the same range as reference
/// (returned second, Y = 100).
pub fn material_xyz(material: &Material, light: &Light) -> (Xyz, Xyz) {
    let observer = cie1931();
    let (grid, widths) = colour_grid();
    let mut xyz = [0.0; 3];
    let mut white = [0.0; 3];
    for (l, w) in grid.iter().zip(&widths) {
        let cmf = observer.at(*l);
        let p = light.power(*l) * w;
        let d = material.diagonal(*l);
        for c in 0..3 {
            xyz[c] += p * d * cmf[c];
            white[c] += p * cmf[c];
        }
    }
    for (f, reemitted) in material
        .fluorophores
        .iter()
        .zip(reemitted_energy(material, light))
    {
        for (l, w) in grid.iter().zip(&widths) {
            let cmf = observer.at(*l);
            let e = f.emission.eval_zero_outside(*l) * w;
            for c in 0..3 {
                xyz[c] += reemitted * e * cmf[c];
            }
        }
    }
    let scale = 100.0 / white[1];
    (xyz.map(|v| v * scale), white.map(|v| v * scale))
}

/// The grid colour integrates on: 300–830 nm every 1 nm, with its trapezoid bin widths.
pub fn colour_grid() -> (Vec<f64>, Vec<f64>) {
    let grid = uniform_grid(300.0, 830.0, 1.0);
    let widths = crate::spectrum::bin_widths(&grid);
    (grid, widths)
}

/// Energy each fluorophore of `material` re-emits under `light`, ∫ L(λ)·c·Q(λ)·a(λ) dλ on
/// [`colour_grid`] (the row factor c·Q(λ)·a of either yield form; Q(λ) = Φ·λ/λ̄e in the
/// photon form), in the light's units times nm.
pub fn reemitted_energy(material: &Material, light: &Light) -> Vec<f64> {
    let (grid, widths) = colour_grid();
    material
        .fluorophores
        .iter()
        .map(|f| {
            let mean = f.emission_mean_nm();
            grid.iter()
                .zip(&widths)
                .map(|(l, w)| light.power(*l) * f.reradiated_with_mean(*l, mean) * w)
                .sum()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ciede2000_matches_sharma_test_data() {
        // Pairs from Sharma, Wu & Dalal (2005), Table 1.
        let cases = [
            ([50.0, 2.6772, -79.7751], [50.0, 0.0, -82.7485], 2.0425),
            ([50.0, 0.0, 0.0], [50.0, -1.0, 2.0], 2.3669),
            ([50.0, 2.5, 0.0], [73.0, 25.0, -18.0], 27.1492),
            (
                [60.2574, -34.0099, 36.2677],
                [60.4626, -34.1751, 39.4387],
                1.2644,
            ),
            (
                [22.7233, 20.0904, -46.6940],
                [23.0331, 14.9730, -42.5619],
                2.0373,
            ),
            (
                [2.0776, 0.0795, -1.1350],
                [0.9033, -0.0636, -0.5514],
                0.9082,
            ),
        ];
        for (a, b, expected) in cases {
            let de = delta_e2000(a, b);
            assert!(
                (de - expected).abs() < 1e-4,
                "{a:?} {b:?}: {de} vs {expected}"
            );
            assert!((delta_e2000(b, a) - expected).abs() < 1e-4);
        }
    }

    #[test]
    fn srgb_luminance_weights_give_back_y() {
        // Through the XYZ → linear sRGB matrix and back along the published Y row: the
        // four-decimal weights agree with the matrix to its rounding.
        for xyz in [
            D65_WHITE,
            [0.4124, 0.2126, 0.0193],
            [0.2, 0.3, 0.9],
            [0.05, 0.02, 0.4],
        ] {
            let rgb = xyz_to_linear_srgb(xyz);
            let y: f64 = rgb.iter().zip(SRGB_LUMINANCE).map(|(c, w)| c * w).sum();
            // Each weight is within 8e-5 of the exact inverse's.
            let bound = 8e-5 * rgb.iter().map(|c| c.abs()).sum::<f64>();
            assert!((y - xyz[1]).abs() <= bound, "{xyz:?}: {y}");
        }
    }

    #[test]
    fn d65_white_point_and_srgb_white() {
        let d65 = Light::builtin("d65").unwrap();
        let obs = cie1931();
        let grid = uniform_grid(360.0, 830.0, 1.0);
        let mut xyz = [0.0; 3];
        for l in &grid {
            let c = obs.at(*l);
            for k in 0..3 {
                xyz[k] += d65.power(*l) * c[k];
            }
        }
        // D65 tabulated to 780 nm only; chromaticity matches (0.3127, 0.3290) closely.
        let sum: f64 = xyz.iter().sum();
        assert!((xyz[0] / sum - 0.3127).abs() < 5e-4, "x = {}", xyz[0] / sum);
        assert!((xyz[1] / sum - 0.3290).abs() < 5e-4, "y = {}", xyz[1] / sum);
        assert_eq!(xyz_to_srgb8(D65_WHITE), [255, 255, 255]);
    }

    #[test]
    fn uv_light_adds_equal_power_at_365() {
        let d65 = Light::builtin("d65").unwrap();
        let uv = Light::builtin("uv").unwrap();
        let d = d65.spectrum.integral();
        let u = uv.spectrum.integral();
        assert!((u / d - 2.0).abs() < 1e-3, "{u} vs 2×{d}");
        assert!(uv.power(365.0) > 5.0 * d65.power(365.0));
    }

    #[test]
    fn perfect_white_patch_has_l_100() {
        let grid = uniform_grid(380.0, 780.0, 10.0);
        let ex = uniform_grid(300.0, 780.0, 10.0);
        for light in Light::standard() {
            let pc = PatchColorimeter::new(&light, &ex, &grid);
            let lab = xyz_to_lab(pc.xyz_from(&vec![1.0; grid.len()], |_, _| 0.0), pc.white);
            assert!((lab[0] - 100.0).abs() < 1e-9 && lab[1].abs() < 1e-9 && lab[2].abs() < 1e-9);
        }
    }
}
