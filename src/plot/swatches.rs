//! The colour figure: for each standard light, the colour of a flat patch computed from
//! the measured matrix beside the one from the fitted matrix, as sRGB swatches, with the
//! CIEDE2000 difference under each pair (model.md §7).
//!
//! Patch colours come from [`PatchColorimeter`] on the measurement's grids; missing
//! measured cells are filled from the fitted matrix so both patches integrate the same
//! cells. The swatches are adapted (Bradford) from each light's white to D65 and encoded
//! as sRGB, which shows them as a viewer adapted to that light sees them.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::common::{
    Draw, DrawResult, anchored, bold, draw_text, draw_title, font, format_significant,
};
use super::{Comparison, Layout};
use crate::colour::{
    D65_WHITE, Lab, Light, PatchColorimeter, Xyz, adapt_bradford, delta_e2000, srgb_encode,
    xyz_to_lab, xyz_to_linear_srgb,
};
use crate::material::Material;

/// Size of the colour figure in pixels.
pub const SIZE: (u32, u32) = (1000, 420);

const TITLE_HEIGHT: i32 = 44;
const SWATCH_WIDTH: i32 = 96;
const SWATCH_HEIGHT: i32 = 120;
const SWATCH_TOP: i32 = 130;
const BACKDROP: RGBColor = RGBColor(205, 205, 205);

/// The measured and fitted patch colours under one light.
#[derive(Debug, Clone, PartialEq)]
pub struct SwatchPair {
    /// The light's name (`d65`, `a`, `f11`, `uv`).
    pub light: String,
    /// CIELAB of the measured patch against the perfect white under the light.
    pub measured_lab: Lab,
    /// CIELAB of the fitted patch.
    pub fitted_lab: Lab,
    /// The measured swatch's displayed 8-bit sRGB.
    pub measured_srgb: [u8; 3],
    /// The fitted swatch's displayed 8-bit sRGB.
    pub fitted_srgb: [u8; 3],
    /// CIEDE2000 between the two Lab colours.
    pub delta_e2000: f64,
    /// True when either swatch lies outside the sRGB gamut and was clipped for display.
    pub clipped: bool,
}

/// Where a swatch pair was drawn (pixel rectangles left, top, right, bottom; right and
/// bottom exclusive).
#[derive(Debug, Clone, PartialEq)]
pub struct SwatchPanel {
    /// The colours.
    pub pair: SwatchPair,
    /// The measured swatch.
    pub measured_rect_px: [i32; 4],
    /// The fitted swatch.
    pub fitted_rect_px: [i32; 4],
}

/// Display colour of `xyz` seen under a light whose white is `white` (same units): adapted
/// to D65 and encoded as 8-bit sRGB. The flag is true when the colour had to be clipped.
pub fn display_srgb(xyz: Xyz, white: Xyz) -> ([u8; 3], bool) {
    let y = if white[1] > 0.0 { white[1] } else { 1.0 };
    let adapted = adapt_bradford(xyz.map(|v| v / y), white.map(|v| v / y), D65_WHITE);
    let linear = xyz_to_linear_srgb(adapted);
    let clipped = linear.iter().any(|&c| !(-1e-3..=1.0 + 1e-3).contains(&c));
    (linear.map(srgb_encode), clipped)
}

/// Number of measured cells that are missing (filled from the fit for colour).
pub fn missing_cells(c: &Comparison) -> usize {
    c.measured.values.iter().filter(|v| v.is_nan()).count()
}

/// The measured and fitted patch colours under each standard light.
pub fn swatch_pairs(c: &Comparison) -> Vec<SwatchPair> {
    // The patch the fit's colour is judged on (every measured cell as measured).
    let measured = c.measured.filled_from(&c.fitted).to_per_bin();
    let fitted = c.fitted.to_per_bin();
    Light::standard()
        .iter()
        .map(|light| {
            let pc = PatchColorimeter::new(light, &measured.excitation_nm, &measured.emission_nm);
            let (xm, xf) = (pc.xyz(&measured), pc.xyz(&fitted));
            let (lm, lf) = (xyz_to_lab(xm, pc.white), xyz_to_lab(xf, pc.white));
            let (sm, cm) = display_srgb(xm, pc.white);
            let (sf, cf) = display_srgb(xf, pc.white);
            SwatchPair {
                light: light.name.clone(),
                measured_lab: lm,
                fitted_lab: lf,
                measured_srgb: sm,
                fitted_srgb: sf,
                delta_e2000: delta_e2000(lm, lf),
                clipped: cm || cf,
            }
        })
        .collect()
}

fn describe_light(name: &str) -> (&str, &str) {
    match name {
        "d65" => ("D65", "daylight"),
        "a" => ("A", "incandescent"),
        "f11" => ("F11", "tri-band fluorescent"),
        "uv" => ("UV", "D65 + 365 nm LED"),
        other => (other, ""),
    }
}

/// The colour figure: measured and fitted patch colours under each light.
pub(crate) struct ColourFigure<'a> {
    pub(crate) material: &'a Material,
    pub(crate) comparison: &'a Comparison,
}

impl Draw for ColourFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<Layout, DB> {
        let (width, height) = SIZE;
        let width = width as i32;
        draw_title(
            root,
            &format!(
                "{}: patch colour under each light, measured | fitted",
                self.material.name
            ),
            (width / 2, TITLE_HEIGHT / 2 + 2),
        )?;
        let pairs = swatch_pairs(self.comparison);
        let column = width / pairs.len().max(1) as i32;
        let centred = |size: f64| anchored(font(size), HPos::Center, VPos::Center);
        let mut panels = Vec::new();
        let mut any_clipped = false;
        for (n, pair) in pairs.into_iter().enumerate() {
            let cx = column * n as i32 + column / 2;
            let (name, what) = describe_light(&pair.light);
            draw_text(
                root,
                name,
                (cx, 78),
                &anchored(bold(19.0), HPos::Center, VPos::Center),
            )?;
            draw_text(root, what, (cx, 102), &centred(15.0))?;
            let measured_rect = [
                cx - SWATCH_WIDTH,
                SWATCH_TOP,
                cx,
                SWATCH_TOP + SWATCH_HEIGHT,
            ];
            let fitted_rect = [
                cx,
                SWATCH_TOP,
                cx + SWATCH_WIDTH,
                SWATCH_TOP + SWATCH_HEIGHT,
            ];
            // A neutral backdrop keeps light swatches visible on the white page.
            root.draw(&Rectangle::new(
                [
                    (measured_rect[0] - 10, measured_rect[1] - 10),
                    (fitted_rect[2] + 10, fitted_rect[3] + 10),
                ],
                BACKDROP.filled(),
            ))?;
            for (rect, rgb) in [
                (measured_rect, pair.measured_srgb),
                (fitted_rect, pair.fitted_srgb),
            ] {
                root.draw(&Rectangle::new(
                    [(rect[0], rect[1]), (rect[2], rect[3])],
                    RGBColor(rgb[0], rgb[1], rgb[2]).filled(),
                ))?;
            }
            let label_y = SWATCH_TOP + SWATCH_HEIGHT + 26;
            draw_text(
                root,
                "measured",
                (cx - SWATCH_WIDTH / 2, label_y),
                &centred(15.0),
            )?;
            draw_text(
                root,
                "fitted",
                (cx + SWATCH_WIDTH / 2, label_y),
                &centred(15.0),
            )?;
            let star = if pair.clipped { " *" } else { "" };
            any_clipped |= pair.clipped;
            draw_text(
                root,
                &format!("ΔE00 = {}{star}", format_delta_e(pair.delta_e2000)),
                (cx, label_y + 36),
                &anchored(bold(20.0), HPos::Center, VPos::Center),
            )?;
            panels.push(SwatchPanel {
                pair,
                measured_rect_px: measured_rect,
                fitted_rect_px: fitted_rect,
            });
        }
        let mut notes = vec![
            "Each pair is shown as seen by a viewer adapted to that light (Bradford to D65, sRGB). ΔE00 below 1 is invisible side by side."
                .to_string(),
        ];
        let missing = missing_cells(self.comparison);
        if missing > 0 || any_clipped {
            let mut n = Vec::new();
            if any_clipped {
                n.push("* outside the sRGB gamut, clipped for display".to_string());
            }
            if missing > 0 {
                n.push(format!(
                    "{missing} missing measured cells filled from the fit"
                ));
            }
            notes.push(n.join("; "));
        }
        let mut y = height as i32 - 22 * notes.len() as i32 - 6;
        for note in notes {
            draw_text(root, &note, (width / 2, y), &centred(14.0))?;
            y += 22;
        }
        Ok(Layout {
            swatches: panels,
            ..Layout::default()
        })
    }
}

fn format_delta_e(de: f64) -> String {
    if de.is_finite() && de < 10.0 {
        format!("{de:.2}")
    } else {
        format_significant(de, 3)
    }
}
