//! A bitmap backend that sets text itself. plotters' own `ab_glyph` text path places each
//! glyph by its ink box and ignores side bearings, so periods float and letters drift
//! apart ("0· 3", "m ax"); this wrapper lays glyphs out on a common baseline with their
//! advances, kerning and bearings, and hands everything else to [`BitMapBackend`].
//! The SVG backend writes `<text>` elements and needs no such help.

use ab_glyph::{Font, FontRef, Glyph, PxScale, ScaleFont, point};
use plotters::prelude::BitMapBackend;
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
    FontStyle,
};

use crate::error::{Error, Result};

/// [`BitMapBackend`] with correct text layout in the embedded DejaVu Sans.
pub(crate) struct TextBitmap<'a> {
    inner: BitMapBackend<'a>,
    regular: FontRef<'static>,
    bold: FontRef<'static>,
}

impl<'a> TextBitmap<'a> {
    /// Wraps `inner`.
    pub(crate) fn new(inner: BitMapBackend<'a>) -> Result<Self> {
        let load = |bytes: &'static [u8]| {
            FontRef::try_from_slice(bytes).map_err(|_| {
                Error::invalid(
                    "plot font",
                    "the embedded DejaVu Sans font could not be loaded; the build is broken, reinstall fluorite",
                )
            })
        };
        Ok(TextBitmap {
            inner,
            regular: load(dejavu::sans::regular())?,
            bold: load(dejavu::sans::bold())?,
        })
    }

    fn font_for(&self, style: FontStyle) -> &FontRef<'static> {
        match style {
            FontStyle::Bold => &self.bold,
            _ => &self.regular,
        }
    }
}

/// Glyphs laid out left to right with the baseline at y = ascent (so the box's top is 0).
struct Shaped {
    glyphs: Vec<Glyph>,
    width: f32,
    height: f32,
}

fn shape(font: &FontRef<'static>, size: f64, text: &str) -> Shaped {
    let scale = PxScale::from(size as f32);
    let scaled = font.as_scaled(scale);
    let ascent = scaled.ascent();
    let mut caret = 0.0f32;
    let mut previous = None;
    let mut glyphs = Vec::with_capacity(text.len());
    for ch in text.chars() {
        let id = scaled.glyph_id(ch);
        if let Some(p) = previous {
            caret += scaled.kern(p, id);
        }
        glyphs.push(id.with_scale_and_position(scale, point(caret, ascent)));
        caret += scaled.h_advance(id);
        previous = Some(id);
    }
    Shaped {
        glyphs,
        width: caret,
        height: ascent - scaled.descent(),
    }
}

/// Drawing methods handed to the bitmap backend unchanged (its own are faster than the
/// trait's pixel-by-pixel defaults): one line each instead of a copied body.
macro_rules! pass_to_inner {
    ($(fn $name:ident $(<$($generic:ident: $bound:path),+>)? (&mut self $(, $arg:ident: $ty:ty)*);)+) => {
        $(
            fn $name $(<$($generic: $bound),+>)? (
                &mut self
                $(, $arg: $ty)*
            ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
                self.inner.$name($($arg),*)
            }
        )+
    };
}

impl<'a> DrawingBackend for TextBitmap<'a> {
    type ErrorType = <BitMapBackend<'a> as DrawingBackend>::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }

    pass_to_inner! {
        fn ensure_prepared(&mut self);
        fn present(&mut self);
        fn draw_pixel(&mut self, point: BackendCoord, color: BackendColor);
        fn draw_line<S: BackendStyle>(&mut self, from: BackendCoord, to: BackendCoord, style: &S);
        fn draw_rect<S: BackendStyle>(
            &mut self,
            upper_left: BackendCoord,
            bottom_right: BackendCoord,
            style: &S,
            fill: bool
        );
        fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            path: I,
            style: &S
        );
        fn draw_circle<S: BackendStyle>(
            &mut self,
            center: BackendCoord,
            radius: u32,
            style: &S,
            fill: bool
        );
        fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
            &mut self,
            vert: I,
            style: &S
        );
        fn blit_bitmap(&mut self, pos: BackendCoord, size: (u32, u32), src: &[u8]);
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> std::result::Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
        let shaped = shape(self.font_for(style.style()), style.size(), text);
        Ok((shaped.width.ceil() as u32, shaped.height.ceil() as u32))
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> std::result::Result<(), DrawingErrorKind<Self::ErrorType>> {
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        let font = self.font_for(style.style()).clone();
        let shaped = shape(&font, style.size(), text);
        let anchor = style.anchor();
        let dx = match anchor.h_pos {
            HPos::Left => 0.0,
            HPos::Center => -shaped.width / 2.0,
            HPos::Right => -shaped.width,
        };
        let dy = match anchor.v_pos {
            VPos::Top => 0.0,
            VPos::Center => -shaped.height / 2.0,
            VPos::Bottom => -shaped.height,
        };
        // Whole-pixel offsets: rounding each pixel's fractional position separately would
        // merge or skip rows where the position crosses zero.
        let (dx, dy) = (dx.round() as i32, dy.round() as i32);
        let transform = style.transform();
        let mut pixels = Vec::new();
        for glyph in shaped.glyphs {
            if let Some(outline) = font.outline_glyph(glyph) {
                // px_bounds is whole pixels.
                let bounds = outline.px_bounds();
                outline.draw(|x, y, coverage| {
                    let lx = bounds.min.x as i32 + x as i32 + dx;
                    let ly = bounds.min.y as i32 + y as i32 + dy;
                    pixels.push((transform.transform(lx, ly), coverage.clamp(0.0, 1.0)));
                });
            }
        }
        let (w, h) = self.get_size();
        for ((x, y), coverage) in pixels {
            let (x, y) = (pos.0 + x, pos.1 + y);
            if coverage > 0.0 && x >= 0 && y >= 0 && x < w as i32 && y < h as i32 {
                self.inner.draw_pixel(
                    (x, y),
                    BackendColor {
                        alpha: color.alpha * coverage as f64,
                        rgb: color.rgb,
                    },
                )?;
            }
        }
        Ok(())
    }
}
