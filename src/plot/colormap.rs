//! Colour maps for heat maps: a sequential map (viridis) for values and a diverging map
//! (blue–white–red) centred on zero for residuals, plus the fixed colours that mark cells
//! which are not colour-mapped (diagonal, missing) and the fade of guard-band cells.
//!
//! Both maps interpolate linearly in 8-bit sRGB between evenly spaced stops, so the colour
//! of any value is reproducible exactly (tests probe rendered pixels against these
//! functions).

use plotters::style::RGBColor;

/// Viridis (van der Walt and Smith, matplotlib's default) at nine evenly spaced stops,
/// as 0xRRGGBB.
const VIRIDIS_STOPS: [u32; 9] = [
    0x440154, 0x472d7b, 0x3b528b, 0x2c728e, 0x21908c, 0x27ad81, 0x5dc863, 0xaadc32, 0xfde725,
];

/// ColorBrewer RdBu (11 classes) as published, 0xRRGGBB, ordered from blue (negative) to
/// red (positive), with the neutral near-white in the middle.
const DIVERGING_STOPS: [u32; 11] = [
    0x053061, 0x2166ac, 0x4393c3, 0x92c5de, 0xd1e5f0, 0xf7f7f7, 0xfddbc7, 0xf4a582, 0xd6604d,
    0xb2182b, 0x67001f,
];

/// Colour of a diagonal cell (λo = λi): the reflectance, shown in black on every panel
/// because its scale (up to 1) would swamp the fluorescence.
pub const DIAGONAL: RGBColor = RGBColor(0, 0, 0);
/// Colour of a missing (unmeasured) cell.
pub const MISSING: RGBColor = RGBColor(160, 160, 160);
/// Background of a cell removed by scatter masking…
pub const MASKED: RGBColor = RGBColor(228, 228, 228);
/// …and its hatch lines.
pub const HATCH: RGBColor = RGBColor(96, 96, 96);

fn interpolate(stops: &[u32], t: f64) -> RGBColor {
    // NaN maps to the low end rather than panicking on a bad index.
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let position = t * (stops.len() - 1) as f64;
    let lower = (position.floor() as usize).min(stops.len() - 2);
    let frac = position - lower as f64;
    let (a, b) = (stops[lower], stops[lower + 1]);
    // The channel at bit `shift` of each stop, mixed.
    let mix = |shift: u32| {
        let (x, y) = (((a >> shift) & 0xff) as f64, ((b >> shift) & 0xff) as f64);
        (x + frac * (y - x)).round() as u8
    };
    RGBColor(mix(16), mix(8), mix(0))
}

/// The sequential map: `t` in [0, 1] (clamped; NaN counts as 0) from dark purple to yellow.
pub fn viridis(t: f64) -> RGBColor {
    interpolate(&VIRIDIS_STOPS, t)
}

/// The diverging map: `t` in [0, 1] (clamped; NaN counts as 0) from dark blue through
/// near-white at `t` = 0.5 to dark red.
pub fn diverging(t: f64) -> RGBColor {
    interpolate(&DIVERGING_STOPS, t)
}

/// Which colour map a scale uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColourMap {
    /// [`viridis`], for values.
    Viridis,
    /// [`diverging`], for signed residuals.
    Diverging,
}

impl ColourMap {
    /// The map's colour at `t` in [0, 1].
    pub fn at(self, t: f64) -> RGBColor {
        match self {
            ColourMap::Viridis => viridis(t),
            ColourMap::Diverging => diverging(t),
        }
    }
}

/// A colour map stretched over a value range: `min` maps to the map's start, `max` to its
/// end, values outside are clamped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColourScale {
    /// The map.
    pub map: ColourMap,
    /// Value at the start of the map.
    pub min: f64,
    /// Value at the end of the map.
    pub max: f64,
}

impl ColourScale {
    /// A sequential scale over [`min`, `max`]. A degenerate or non-finite range is widened
    /// so every value still gets a colour.
    pub fn sequential(min: f64, max: f64) -> Self {
        let (min, max) = sane_range(min, max);
        ColourScale {
            map: ColourMap::Viridis,
            min,
            max,
        }
    }

    /// A diverging scale over [−`limit`, `limit`], so zero sits at the neutral centre.
    pub fn diverging(limit: f64) -> Self {
        let limit = if limit.is_finite() && limit > 0.0 {
            limit
        } else {
            1e-12
        };
        ColourScale {
            map: ColourMap::Diverging,
            min: -limit,
            max: limit,
        }
    }

    /// Position of `value` along the map, in [0, 1].
    pub fn position(&self, value: f64) -> f64 {
        ((value - self.min) / (self.max - self.min)).clamp(0.0, 1.0)
    }

    /// The colour of `value`.
    pub fn colour(&self, value: f64) -> RGBColor {
        self.map.at(self.position(value))
    }
}

fn sane_range(min: f64, max: f64) -> (f64, f64) {
    let (min, max) = match (min.is_finite(), max.is_finite()) {
        (true, true) => (min.min(max), min.max(max)),
        (true, false) => (min, min + 1.0),
        (false, true) => (max - 1.0, max),
        (false, false) => (0.0, 1.0),
    };
    if max - min > 1e-300 {
        (min, max)
    } else {
        (min, min + min.abs().max(1e-12))
    }
}

/// Mixes `colour` with `other`: `amount` = 0 keeps `colour`, 1 gives `other`.
pub fn mix(colour: RGBColor, other: RGBColor, amount: f64) -> RGBColor {
    let m = |a: u8, b: u8| (a as f64 + amount * (b as f64 - a as f64)).round() as u8;
    RGBColor(
        m(colour.0, other.0),
        m(colour.1, other.1),
        m(colour.2, other.2),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_hit_their_stops_and_centre() {
        assert_eq!(viridis(0.0), RGBColor(68, 1, 84));
        assert_eq!(viridis(1.0), RGBColor(253, 231, 37));
        assert_eq!(diverging(0.5), RGBColor(247, 247, 247));
        assert_eq!(
            ColourScale::diverging(0.01).colour(0.0),
            RGBColor(247, 247, 247)
        );
        assert_eq!(viridis(f64::NAN), viridis(0.0));
        assert_eq!(viridis(7.0), viridis(1.0));
    }

    #[test]
    fn degenerate_ranges_still_map() {
        let s = ColourScale::sequential(0.5, 0.5);
        assert!(s.max > s.min);
        let s = ColourScale::sequential(f64::NAN, f64::INFINITY);
        assert_eq!((s.min, s.max), (0.0, 1.0));
    }
}
