//! The `--compare` picture (the paper's first figure): the material's sphere beside its
//! twin without fluorescence, an exposure that keeps the fluorescent sphere's colour, and
//! a strip below the render that says which sphere is which and what exposure was used.
//!
//! Automatic exposure: under UV, or for a bright dye under D65, the fluorescent sphere's lit
//! side is far brighter than white and the default exposure turns it into flat white. The
//! automatic rule lowers the exposure until the [`AUTO_PERCENTILE`] percentile of the
//! largest linear sRGB channel over both spheres' pixels sits at [`AUTO_TARGET`]; it never
//! raises it above [`DEFAULT_EXPOSURE_EV`], so a compare image that does not clip is
//! exposed like every other preview.

use crate::error::Result;
use crate::plot::{Caption, draw_captions};

use super::image::{
    DEFAULT_EXPOSURE_EV, Develop, MAX_EXPOSURE_EV, check_exposure, encode_exr, encode_png,
    film_to_linear_srgb, to_srgb8, xyz_to_srgb_matrix,
};
use super::{Film, RenderSettings, Scene};

/// Share of the spheres' pixels allowed above [`AUTO_TARGET`] by the automatic exposure.
pub const AUTO_PERCENTILE: f64 = 0.99;
/// Where the automatic exposure puts that percentile's largest channel: a little below 1,
/// so that the brightest pixels keep their hue.
pub const AUTO_TARGET: f64 = 0.9;

/// Narrowest picture (pixels) whose labels name the material and spell out the twin.
pub const WIDE_LABELS: u32 = 400;

/// Indices (row-major) of the pixels whose centre sees object `object` first.
pub fn object_pixels(scene: &Scene, settings: &RenderSettings, object: usize) -> Vec<usize> {
    let (w, h) = (settings.width, settings.height);
    let camera = scene.camera();
    let mut pixels = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let ray = camera.ray((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            if scene
                .intersect(&ray, f32::INFINITY)
                .is_some_and(|hit| hit.object == object)
            {
                pixels.push((y * w + x) as usize);
            }
        }
    }
    pixels
}

/// The automatic exposure (stops) for linear sRGB `linear`, judged on `pixels`: the
/// [`AUTO_PERCENTILE`] percentile of each pixel's largest channel maps to
/// [`AUTO_TARGET`], but never brighter than [`DEFAULT_EXPOSURE_EV`] (nor beyond
/// ±[`MAX_EXPOSURE_EV`]). With no lit pixel it is the default.
pub fn auto_exposure_ev(linear: &[[f32; 3]], pixels: &[usize]) -> f64 {
    let mut brightest: Vec<f64> = pixels
        .iter()
        .filter_map(|&i| linear.get(i))
        .map(|rgb| rgb.iter().fold(0.0f64, |m, c| m.max(*c as f64)))
        .filter(|v| v.is_finite())
        .collect();
    if brightest.is_empty() {
        return DEFAULT_EXPOSURE_EV;
    }
    brightest.sort_by(f64::total_cmp);
    let rank = ((brightest.len() - 1) as f64 * AUTO_PERCENTILE).round() as usize;
    let high = brightest[rank];
    if high <= 0.0 {
        return DEFAULT_EXPOSURE_EV;
    }
    (AUTO_TARGET / high)
        .log2()
        .clamp(-MAX_EXPOSURE_EV, MAX_EXPOSURE_EV)
        .min(DEFAULT_EXPOSURE_EV)
}

/// The exposure of a picture: stops, and whether the automatic rule chose them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exposure {
    /// Exposure in stops (the picture is multiplied by 2^ev).
    pub ev: f64,
    /// Chosen by [`auto_exposure_ev`] rather than given.
    pub auto: bool,
}

impl Exposure {
    /// "exposure ×0.42 (−1.25 EV, auto)".
    pub fn legend(&self) -> String {
        format!(
            "exposure ×{:.2} ({:+.2} EV, {})",
            2f64.powf(self.ev),
            self.ev,
            if self.auto { "auto" } else { "set" }
        )
        .replace('-', "−")
    }
}

/// Height in pixels of the label strip under a compare render `width` pixels wide: two
/// lines of text.
pub fn strip_height(width: u32) -> u32 {
    let size = caption_size(width);
    (2.0 * 1.45 * size + 6.0).round() as u32
}

/// Mean advance of a bold DejaVu Sans character in ems (a generous estimate, so that a
/// label said to fit does).
const BOLD_EM_PER_CHARACTER: f64 = 0.68;
/// Smallest caption size (pixels): below it no text is legible anyway.
const MIN_CAPTION_SIZE: f64 = 6.0;

/// Caption size for a picture `width` pixels wide: 1/42 of it, from 9 to 18 pixels.
fn caption_size(width: u32) -> f64 {
    (width as f64 / 42.0).clamp(9.0, 18.0)
}

/// What the label strip says.
#[derive(Debug, Clone, PartialEq)]
pub struct CompareLabels {
    /// Under the fluorescent sphere.
    pub left: String,
    /// Under the twin.
    pub right: String,
    /// The second line: light and exposure.
    pub legend: String,
}

/// `rgb8` (the render, `width` × `height`) with a white strip of [`strip_height`] added
/// below it, holding `labels` centred under the spheres' columns (`left_x`, `right_x`,
/// pixels) and the legend under both. Returns the new height with the bytes.
pub fn add_label_strip(
    rgb8: &[u8],
    width: u32,
    height: u32,
    (left_x, right_x): (i32, i32),
    labels: &CompareLabels,
) -> Result<(Vec<u8>, u32)> {
    let strip = strip_height(width);
    let total = height + strip;
    let mut picture = rgb8.to_vec();
    picture.resize(width as usize * total as usize * 3, 255);
    // The strip's height follows the width; the text shrinks, if need be, so that each
    // label fits its half of the picture and the legend the whole width.
    let line = 1.45 * caption_size(width);
    let size = [
        (labels.left.as_str(), 0.48),
        (labels.right.as_str(), 0.48),
        (labels.legend.as_str(), 0.96),
    ]
    .iter()
    .map(|(text, share)| {
        share * width as f64 / (BOLD_EM_PER_CHARACTER * text.chars().count() as f64)
    })
    .fold(caption_size(width), f64::min)
    .max(MIN_CAPTION_SIZE);
    let top = height as f64 + 3.0;
    let caption = |text: &str, x: i32, row: f64, bold: bool| Caption {
        text: text.to_string(),
        centre: (x, (top + line * (row + 0.5)).round() as i32),
        size,
        bold,
    };
    draw_captions(
        &mut picture,
        (width, total),
        &[
            caption(&labels.left, left_x, 0.0, true),
            caption(&labels.right, right_x, 0.0, true),
            caption(&labels.legend, width as i32 / 2, 1.0, false),
        ],
    )?;
    Ok((picture, total))
}

/// A developed compare picture.
#[derive(Debug, Clone)]
pub struct ComparePicture {
    /// The PNG: the render with the label strip below it.
    pub png: Vec<u8>,
    /// With [`Develop::exr`], the scene-referred EXR of the render alone (no strip).
    pub exr: Option<Vec<u8>>,
    /// The exposure used.
    pub exposure: Exposure,
}

/// Develops a compare render of `scene` (built with `compare`: object 0 the material's
/// sphere, object 1 its twin) made with `settings`: exposure `develop.exposure_ev`, or
/// with `auto` the [`auto_exposure_ev`] of both spheres; then the label strip, naming
/// the material (`name`) and the light (`light_name`). The exposure legend is appended
/// to `develop.description` in the PNG.
pub fn develop_compare(
    film: &Film,
    scene: &Scene,
    settings: &RenderSettings,
    develop: &Develop,
    auto: bool,
    (name, light_name): (&str, &str),
) -> Result<ComparePicture> {
    let (width, height) = (film.width, film.height);
    let linear = film_to_linear_srgb(film, &xyz_to_srgb_matrix(scene.light(), develop.adapt));
    let left = object_pixels(scene, settings, 0);
    let right = object_pixels(scene, settings, 1);
    let ev = if auto {
        let spheres: Vec<usize> = left.iter().chain(&right).copied().collect();
        auto_exposure_ev(&linear, &spheres)
    } else {
        develop.exposure_ev
    };
    check_exposure(ev)?;
    let exposure = Exposure { ev, auto };
    let quarter = width as i32 / 4;
    // Narrow pictures get the short labels.
    let labels = if width >= WIDE_LABELS {
        CompareLabels {
            left: format!("{name}: fluorescent"),
            right: "same reflectance, no fluorescence".to_string(),
            legend: format!("under {light_name}, {}", exposure.legend()),
        }
    } else {
        CompareLabels {
            left: "fluorescent".to_string(),
            right: "not fluorescent".to_string(),
            legend: format!("{light_name}, {}", exposure.legend()),
        }
    };
    let (picture, total) = add_label_strip(
        &to_srgb8(&linear, ev),
        width,
        height,
        (
            mean_column(&left, width, quarter),
            mean_column(&right, width, 3 * quarter),
        ),
        &labels,
    )?;
    // PNG text chunks are ISO 8859-1, which has × but not the minus sign.
    let description = format!(
        "{}, {}",
        develop.description,
        exposure.legend().replace('−', "-")
    );
    let png = encode_png(width, total, &picture, &description)?;
    let exr = if develop.exr {
        let scene_referred = film_to_linear_srgb(film, &xyz_to_srgb_matrix(scene.light(), false));
        Some(encode_exr(width, height, &scene_referred)?)
    } else {
        None
    };
    Ok(ComparePicture { png, exr, exposure })
}

/// Mean column of `pixels` (row-major in an image `width` wide), or `fallback` for none.
pub fn mean_column(pixels: &[usize], width: u32, fallback: i32) -> i32 {
    if pixels.is_empty() || width == 0 {
        return fallback;
    }
    let sum: usize = pixels.iter().map(|i| i % width as usize).sum();
    (sum as f64 / pixels.len() as f64).round() as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_exposure_puts_the_high_percentile_at_the_target_and_never_brightens() {
        // 100 pixels: largest channels 0.04, 0.08, …, 4.0; the 99th percentile is 3.96.
        let linear: Vec<[f32; 3]> = (1..=100).map(|i| [0.04 * i as f32, 0.01, 0.02]).collect();
        let all: Vec<usize> = (0..100).collect();
        let ev = auto_exposure_ev(&linear, &all);
        let expected = (AUTO_TARGET / 3.96).log2();
        assert!((ev - expected).abs() < 1e-5, "{ev} vs {expected}");
        // A dim picture keeps the default exposure; an empty selection too.
        let dim: Vec<[f32; 3]> = vec![[0.2, 0.3, 0.1]; 10];
        assert_eq!(auto_exposure_ev(&dim, &[0, 1, 2]), DEFAULT_EXPOSURE_EV);
        assert_eq!(auto_exposure_ev(&linear, &[]), DEFAULT_EXPOSURE_EV);
    }

    #[test]
    fn the_legend_states_factor_and_stops() {
        let legend = Exposure {
            ev: -1.25,
            auto: true,
        }
        .legend();
        assert_eq!(legend, "exposure ×0.42 (−1.25 EV, auto)");
    }
}
