//! From the film's CIE XYZ to pictures: the exposure rule, sRGB PNG and linear EXR.
//!
//! Exposure rule (so that renders are comparable): every light is normalised to unit
//! luminance; in the preview the area light alone gives a white diffuser facing up at
//! the top of the sphere Y = 0.85 and the environment adds up to 0.15 (less the part the
//! light's back hides), so that white reads Y ≈ 1; in the furnace, white reads Y = 1.
//! The picture is that XYZ, adapted from the light's
//! white to D65 (Bradford, unless adaptation is off: a viewer adapted to each light),
//! converted to linear sRGB and multiplied by 2^EV, EV = [`DEFAULT_EXPOSURE_EV`] unless
//! `--exposure` says otherwise; then brought into the display's gamut by [`gamut_map`]
//! and sRGB encoded. The default leaves half a stop of headroom for fluorescent surfaces
//! brighter than white.

use std::io::Cursor;

use crate::colour::{D65_WHITE, SRGB_LUMINANCE, adapt_bradford, srgb_encode, xyz_to_linear_srgb};
use crate::error::{Error, Result};

use super::Film;
use super::spectra::{LightNormalisation, LightSpectrum};

/// Default exposure in stops: a white diffuser at Y = 1 becomes linear 0.71.
pub const DEFAULT_EXPOSURE_EV: f64 = -0.5;
/// Largest exposure magnitude accepted (stops).
pub const MAX_EXPOSURE_EV: f64 = 30.0;

/// The 3×3 matrix from film XYZ to linear sRGB (D65), optionally adapting the light's
/// white to D65 first. A light without visible power is never adapted.
pub fn xyz_to_srgb_matrix(light: &LightSpectrum, adapt: bool) -> [[f64; 3]; 3] {
    let adapt = adapt
        && light.normalisation == LightNormalisation::Luminance
        && light.white_xyz.iter().all(|v| *v > 0.0);
    let mut m = [[0.0; 3]; 3];
    for col in 0..3 {
        let mut basis = [0.0; 3];
        basis[col] = 1.0;
        let xyz = if adapt {
            adapt_bradford(basis, light.white_xyz, D65_WHITE)
        } else {
            basis
        };
        let rgb = xyz_to_linear_srgb(xyz);
        for (row, v) in rgb.iter().enumerate() {
            m[row][col] = *v;
        }
    }
    m
}

/// Linear sRGB of every pixel (before exposure), row by row.
pub fn film_to_linear_srgb(film: &Film, matrix: &[[f64; 3]; 3]) -> Vec<[f32; 3]> {
    film.xyz
        .iter()
        .map(|xyz| {
            let mut rgb = [0.0f32; 3];
            for (row, out) in rgb.iter_mut().enumerate() {
                *out = (0..3).map(|c| matrix[row][c] * xyz[c] as f64).sum::<f64>() as f32;
            }
            rgb
        })
        .collect()
}

/// Checks an exposure value.
pub fn check_exposure(ev: f64) -> Result<()> {
    if !ev.is_finite() || ev.abs() > MAX_EXPOSURE_EV {
        return Err(Error::invalid(
            "--exposure",
            format!(
                "is {ev}; give a number of stops between -{MAX_EXPOSURE_EV} and {MAX_EXPOSURE_EV}"
            ),
        ));
    }
    Ok(())
}

/// Brings a linear sRGB colour into [0, 1]³ keeping its luminance and hue: a colour out
/// of range moves straight towards the grey of the same luminance, just as far as needed
/// (white when its luminance is above 1, black when at or below 0); colours in range are
/// unchanged. Fluorescent colours are often brighter and purer than sRGB holds: clipping
/// each channel instead shifts their hue and, once the strong channel clips, shows the
/// Monte Carlo colour noise of the weak channels as dark grain (a saturated red at
/// preview sample counts), while the luminance, which this keeps, is as clean as a plain
/// reflector's.
pub fn gamut_map(rgb: [f64; 3]) -> [f64; 3] {
    if rgb.iter().all(|c| (0.0..=1.0).contains(c)) {
        return rgb;
    }
    let luminance: f64 = rgb.iter().zip(SRGB_LUMINANCE).map(|(c, w)| c * w).sum();
    if !luminance.is_finite() || luminance <= 0.0 {
        return [0.0; 3];
    }
    if luminance >= 1.0 {
        return [1.0; 3];
    }
    // The largest s in [0, 1] with luminance + s·(c − luminance) in [0, 1] per channel.
    let mut s = 1.0f64;
    for &c in &rgb {
        let offset = c - luminance;
        if c > 1.0 {
            s = s.min((1.0 - luminance) / offset);
        } else if c < 0.0 {
            s = s.min(luminance / -offset);
        }
    }
    rgb.map(|c| (luminance + s * (c - luminance)).clamp(0.0, 1.0))
}

/// 8-bit sRGB bytes (RGB, row by row) of linear sRGB pixels at exposure `ev` stops,
/// gamut-mapped by [`gamut_map`].
pub fn to_srgb8(linear: &[[f32; 3]], ev: f64) -> Vec<u8> {
    let gain = 2f64.powf(ev);
    linear
        .iter()
        .flat_map(|rgb| gamut_map(rgb.map(|c| c as f64 * gain)).map(srgb_encode))
        .collect()
}

/// A PNG file (8-bit RGB, sRGB chunk) of `rgb8` pixels; `description` goes into a text
/// chunk (what was rendered, light, exposure).
pub fn encode_png(width: u32, height: u32, rgb8: &[u8], description: &str) -> Result<Vec<u8>> {
    let fail =
        |e: png::EncodingError| Error::invalid("png", format!("could not encode the image: {e}"));
    let mut bytes = Vec::new();
    {
        let mut encoder = png::Encoder::new(&mut bytes, width, height);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        encoder
            .add_text_chunk("Software".to_string(), "fluorite render".to_string())
            .map_err(fail)?;
        encoder
            .add_text_chunk("Description".to_string(), description.to_string())
            .map_err(fail)?;
        let mut writer = encoder.write_header().map_err(fail)?;
        writer.write_image_data(rgb8).map_err(fail)?;
        writer.finish().map_err(fail)?;
    }
    Ok(bytes)
}

/// An OpenEXR file (32-bit float RGB, linear sRGB primaries, D65) of linear pixels,
/// without exposure: the film's units (white diffuser Y = 1).
pub fn encode_exr(width: u32, height: u32, linear: &[[f32; 3]]) -> Result<Vec<u8>> {
    use exr::prelude::{Image, SpecificChannels, Vec2, WritableImage};
    let w = width as usize;
    let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
        let p = linear[y * w + x];
        (p[0], p[1], p[2])
    });
    let image = Image::from_channels((w, height as usize), channels);
    let mut cursor = Cursor::new(Vec::new());
    image.write().to_buffered(&mut cursor).map_err(|e| {
        crate::error::Error::invalid("exr", format!("could not encode the image: {e}"))
    })?;
    Ok(cursor.into_inner())
}

/// How a rendered film becomes images.
#[derive(Debug, Clone, PartialEq)]
pub struct Develop {
    /// Adapt the light's white to D65 in the display image (Bradford), as an eye adapted
    /// to the light sees it.
    pub adapt: bool,
    /// Exposure of the display image, in stops.
    pub exposure_ev: f64,
    /// What the picture shows, for the PNG's description.
    pub description: String,
    /// Also encode a scene-referred EXR (linear sRGB primaries, never adapted).
    pub exr: bool,
}

/// The display-referred PNG of `film`, rendered under `light`, and with
/// [`Develop::exr`] the scene-referred EXR beside it.
pub fn develop(
    film: &Film,
    light: &LightSpectrum,
    develop: &Develop,
) -> Result<(Vec<u8>, Option<Vec<u8>>)> {
    check_exposure(develop.exposure_ev)?;
    let linear = film_to_linear_srgb(film, &xyz_to_srgb_matrix(light, develop.adapt));
    let png = encode_png(
        film.width,
        film.height,
        &to_srgb8(&linear, develop.exposure_ev),
        &develop.description,
    )?;
    let exr = if develop.exr {
        let scene_referred = film_to_linear_srgb(film, &xyz_to_srgb_matrix(light, false));
        Some(encode_exr(film.width, film.height, &scene_referred)?)
    } else {
        None
    };
    Ok((png, exr))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn luminance(rgb: [f64; 3]) -> f64 {
        0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
    }

    #[test]
    fn colours_in_range_are_unchanged() {
        for rgb in [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.3, 0.7, 0.05]] {
            assert_eq!(gamut_map(rgb), rgb);
        }
    }

    #[test]
    fn out_of_range_colours_keep_luminance_and_hue() {
        // A fluorescent red brighter than white in its red channel, and a green whose
        // red channel is negative (outside the sRGB triangle).
        for rgb in [[2.05, 0.025, 0.085], [-0.2, 0.8, 0.1], [1.4, 0.9, -0.05]] {
            let mapped = gamut_map(rgb);
            let y = luminance(rgb);
            assert!(
                (luminance(mapped) - y).abs() < 1e-12,
                "{rgb:?} → {mapped:?}"
            );
            assert!(mapped.iter().all(|c| (0.0..=1.0).contains(c)));
            // Same direction from the grey of that luminance: (mapped − y) = s·(rgb − y).
            let s = (mapped[0] - y) / (rgb[0] - y);
            assert!(s > 0.0 && s < 1.0);
            for c in 0..3 {
                assert!((mapped[c] - y - s * (rgb[c] - y)).abs() < 1e-12);
            }
            // Just as far as needed: one channel sits on the boundary.
            assert!(mapped.iter().any(|c| *c == 0.0 || (*c - 1.0).abs() < 1e-12));
        }
    }

    #[test]
    fn brighter_than_white_is_white_and_darker_than_black_is_black() {
        assert_eq!(gamut_map([3.0, 1.2, 0.9]), [1.0; 3]);
        assert_eq!(gamut_map([-0.1, -0.3, 0.2]), [0.0; 3]);
    }
}
