//! A material map (`fluorite-material-map/1`, [`crate::image::map`]) as the renderer reads
//! it: the shared fluorophores, and per texel the concentrations c_k and the reflectance
//! r(λ), checked once when loaded and looked up at a surface point's (u, v).
//!
//! Lookups are bilinear between the four texels nearest to (u, v) (texel centres at
//! ((x + ½)/W, (y + ½)/H), row 0 at v = 0): c_k and r(λ) are interpolated separately and
//! the BBRRDF is that of the interpolated parameters, so a map renders without blocks
//! when the texture is magnified, and a texel seen from afar is still its own material.
//! Coordinates wrap around where the shape is periodic (a sphere's longitude) and hold
//! the edge texel elsewhere.
//!
//! A masked texel (any non-finite concentration or reflectance: its measurement held
//! non-finite cells) renders as a neutral middle grey without fluorescence, reflectance
//! [`MASKED_REFLECTANCE`], so that holes in a map stay visible but do not shout. Slightly
//! negative concentrations (fit noise) count as 0 and reflectances are clamped to
//! [0, 1], as [`MaterialMap::material_at`] does; concentrations above 1 are an error.

use std::path::Path;
use std::sync::Arc;

use glam::Vec4;

use crate::error::{Error, Result};
use crate::image::map::{LoadedTextures, MaterialMap, SCHEMA, concentration_channel};
use crate::material::{Fluorophore, Material};
use crate::spectrum::Spectrum;

/// Reflectance of a masked texel: a neutral middle grey (CIELAB L* ≈ 50), no fluorescence.
pub const MASKED_REFLECTANCE: f32 = 0.18;

/// How far above 1 a texel's concentration may lie (f32 rounding of a fit at the bound)
/// before the map is refused; values up to it count as 1.
pub const CONCENTRATION_TOLERANCE: f32 = 1e-4;

/// File name that marks a material map whatever its content says.
pub const MAP_FILE_NAME: &str = "material-map.json";

/// True when `path` is a material map: its name is [`MAP_FILE_NAME`] or its JSON's
/// `schema` is `fluorite-material-map/1`. An unreadable file is not one (the material
/// reader then says why it cannot read it).
pub fn is_material_map(path: &Path) -> bool {
    if path.file_name().is_some_and(|n| n == MAP_FILE_NAME) {
        return true;
    }
    #[derive(serde::Deserialize)]
    struct Schema {
        schema: Option<String>,
    }
    std::fs::read_to_string(path)
        .ok()
        .and_then(|text| serde_json::from_str::<Schema>(&text).ok())
        .and_then(|s| s.schema)
        .is_some_and(|s| s == SCHEMA)
}

/// The four texels around a point of a [`MaterialTexture`] and their bilinear weights
/// (summing to 1), from [`MaterialTexture::footprint`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Texel indices (row-major).
    texel: [usize; 4],
    /// Their weights.
    weight: [f32; 4],
}

/// A material map ready to render: checked, masked texels replaced, values in range.
/// Cloning is cheap (the texels are shared).
#[derive(Debug, Clone)]
pub struct MaterialTexture {
    /// The map's name.
    pub name: String,
    /// Texels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// The fluorophores every texel shares (each one's `concentration` is the map's
    /// largest; the texels hold their own).
    pub fluorophores: Vec<Fluorophore>,
    /// The reflectance's wavelengths (nm, ascending).
    wavelengths: Arc<[f32]>,
    /// `concentration[p·K + k]`, in [0, 1].
    concentration: Arc<[f32]>,
    /// `reflectance[p·n + i]`, in [0, 1].
    reflectance: Arc<[f32]>,
    /// Texels that were masked.
    masked: usize,
    /// Mean over texels of r at each wavelength, then of c_k·r (k-major), and of each c_k:
    /// what the map sends on average, to guide the camera's wavelengths.
    mean_reflectance: Arc<[f32]>,
    mean_absorbing_reflectance: Arc<[f32]>,
    mean_concentration: Vec<f32>,
}

impl MaterialTexture {
    /// Reads the material map whose JSON is at `json` and its two textures (paths
    /// relative to the JSON's folder), and checks them; every error names the file at
    /// fault.
    pub fn load(json: &Path) -> Result<MaterialTexture> {
        let map = MaterialMap::load(json)?;
        let (c_path, r_path) = map.texture_paths(json);
        for (path, field) in [
            (&c_path, "textures.concentration"),
            (&r_path, "textures.reflectance"),
        ] {
            if !path.is_file() {
                return Err(Error::Io {
                    path: path.clone(),
                    message: format!(
                        "no such texture file; {} names it in `{field}` (relative to the JSON's folder): put the file there or correct the name",
                        json.display()
                    ),
                });
            }
        }
        let textures = map.load_textures(json)?;
        if (textures.width, textures.height) != (map.width, map.height) {
            return Err(Error::parse(
                &c_path,
                0,
                0,
                format!(
                    "{}×{} pixels, while {} says width {} and height {}; write the textures at the map's size or correct the JSON",
                    textures.width,
                    textures.height,
                    json.display(),
                    map.width,
                    map.height
                ),
            ));
        }
        let c_name = c_path.display().to_string();
        let json_name = json.display().to_string();
        MaterialTexture::build(&map, textures, &c_name, &json_name)
    }

    /// A texture from a map and its textures read in memory (messages call them "the
    /// concentration texture" and "the material map").
    pub fn new(map: &MaterialMap, textures: LoadedTextures) -> Result<MaterialTexture> {
        MaterialTexture::build(
            map,
            textures,
            "the concentration texture",
            &format!("material map {}", map.name),
        )
    }

    fn build(
        map: &MaterialMap,
        textures: LoadedTextures,
        c_name: &str,
        json_name: &str,
    ) -> Result<MaterialTexture> {
        let k = map.fluorophores.len();
        let (width, height) = (textures.width, textures.height);
        let pixels = width.checked_mul(height).unwrap_or(0);
        let n = textures.wavelengths.len();
        if pixels == 0 || (width, height) != (map.width, map.height) {
            return Err(Error::invalid(
                json_name,
                format!(
                    "the textures hold {width}×{height} pixels and the map says {}×{}; a map needs at least one pixel and textures of its size",
                    map.width, map.height
                ),
            ));
        }
        if n == 0
            || Some(textures.reflectance.len()) != pixels.checked_mul(n)
            || Some(textures.concentration.len()) != pixels.checked_mul(k)
        {
            return Err(Error::invalid(
                json_name,
                format!(
                    "the textures hold {} concentrations and {} reflectances for {pixels} pixels, {k} fluorophores and {n} wavelengths",
                    textures.concentration.len(),
                    textures.reflectance.len()
                ),
            ));
        }
        let wavelengths = &textures.wavelengths;
        if wavelengths.iter().any(|l| !l.is_finite())
            || wavelengths.windows(2).any(|w| w[1] <= w[0])
        {
            return Err(Error::invalid(
                json_name,
                format!(
                    "the reflectance's wavelengths {wavelengths:?} are not finite and increasing; name each spectral channel once, T.<λ>nm"
                ),
            ));
        }
        for (i, f) in map.fluorophores.iter().enumerate() {
            let zero = Spectrum::new(vec![300.0, 780.0], vec![0.0, 0.0], "reflectance")?;
            Material::new(map.name.clone(), zero, vec![f.clone()])
                .validate()
                .map_err(|e| e.context(format!("{json_name}: fluorophores[{i}]")))?;
        }
        let mut concentration = textures.concentration;
        let mut reflectance = textures.reflectance;
        let mut masked = 0;
        for p in 0..pixels {
            let c = &mut concentration[p * k..(p + 1) * k];
            let r = &mut reflectance[p * n..(p + 1) * n];
            if c.iter().chain(r.iter()).any(|v| !v.is_finite()) {
                masked += 1;
                c.fill(0.0);
                r.fill(MASKED_REFLECTANCE);
                continue;
            }
            for (j, value) in c.iter_mut().enumerate() {
                if *value > 1.0 + CONCENTRATION_TOLERANCE {
                    return Err(Error::invalid(
                        c_name,
                        format!(
                            "pixel ({}, {}) holds {} = {value}; a concentration is a fraction of the light absorbed at the absorption peak, from 0 to 1: rescale the fluorophore's yield instead",
                            p % width,
                            p / width,
                            map.textures
                                .concentration_channels
                                .get(j)
                                .cloned()
                                .unwrap_or_else(|| concentration_channel(j))
                        ),
                    ));
                }
                *value = value.clamp(0.0, 1.0);
            }
            for value in r.iter_mut() {
                *value = value.clamp(0.0, 1.0);
            }
        }
        let mut mean_reflectance = vec![0f64; n];
        let mut mean_absorbing = vec![0f64; n * k];
        let mut mean_concentration = vec![0f64; k];
        for p in 0..pixels {
            let r = &reflectance[p * n..(p + 1) * n];
            for (i, &v) in r.iter().enumerate() {
                mean_reflectance[i] += v as f64;
            }
            for j in 0..k {
                let c = concentration[p * k + j] as f64;
                mean_concentration[j] += c;
                if c > 0.0 {
                    for (i, &v) in r.iter().enumerate() {
                        mean_absorbing[j * n + i] += c * v as f64;
                    }
                }
            }
        }
        let mean =
            |v: Vec<f64>| -> Arc<[f32]> { v.iter().map(|s| (s / pixels as f64) as f32).collect() };
        Ok(MaterialTexture {
            name: map.name.clone(),
            width,
            height,
            fluorophores: map.fluorophores.clone(),
            wavelengths: textures.wavelengths.iter().map(|&l| l as f32).collect(),
            concentration: concentration.into(),
            reflectance: reflectance.into(),
            masked,
            mean_reflectance: mean(mean_reflectance),
            mean_absorbing_reflectance: mean(mean_absorbing),
            mean_concentration: mean_concentration
                .iter()
                .map(|s| (s / pixels as f64) as f32)
                .collect(),
        })
    }

    /// Texels that were masked (rendered as [`MASKED_REFLECTANCE`] grey).
    pub fn masked(&self) -> usize {
        self.masked
    }

    /// Width / height of the texture.
    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }

    /// The four texels around texture coordinates (u, v) ∈ [0, 1]² and their bilinear
    /// weights; `wraps` says, for u and for v, whether the coordinate is periodic (the
    /// texel before the first is the last) or held at the edge.
    #[inline]
    pub fn footprint(&self, u: f32, v: f32, wraps: [bool; 2]) -> Footprint {
        let axis = |t: f32, size: usize, wrap: bool| -> ([usize; 2], f32) {
            let x = if t.is_finite() { t } else { 0.5 } * size as f32 - 0.5;
            let floor = x.floor();
            let frac = x - floor;
            let i = floor as i64;
            let size = size as i64;
            let index = |i: i64| {
                if wrap {
                    i.rem_euclid(size) as usize
                } else {
                    i.clamp(0, size - 1) as usize
                }
            };
            ([index(i), index(i + 1)], frac)
        };
        let ([x0, x1], fx) = axis(u, self.width, wraps[0]);
        let ([y0, y1], fy) = axis(v, self.height, wraps[1]);
        let w = self.width;
        Footprint {
            texel: [y0 * w + x0, y0 * w + x1, y1 * w + x0, y1 * w + x1],
            weight: [
                (1.0 - fx) * (1.0 - fy),
                fx * (1.0 - fy),
                (1.0 - fx) * fy,
                fx * fy,
            ],
        }
    }

    /// Concentration of fluorophore `k` (from 0) interpolated over `footprint` (of this
    /// texture); 0 for a fluorophore the map does not have.
    #[inline]
    pub fn concentration(&self, footprint: &Footprint, k: usize) -> f32 {
        let stride = self.fluorophores.len();
        if k >= stride {
            return 0.0;
        }
        let mut sum = 0.0;
        for (&texel, &w) in footprint.texel.iter().zip(&footprint.weight) {
            sum += w * self.concentration[texel * stride + k];
        }
        sum
    }

    /// The reflectance at four wavelengths `nm`, interpolated over `footprint` (of this
    /// texture; linear between the texture's wavelengths, holding the end values outside
    /// them).
    #[inline]
    pub fn reflectance(&self, footprint: &Footprint, nm: Vec4) -> Vec4 {
        let n = self.wavelengths.len();
        let positions = nm.to_array().map(|l| self.locate(l));
        let mut out = [0.0f32; 4];
        for (&texel, &w) in footprint.texel.iter().zip(&footprint.weight) {
            if w == 0.0 {
                continue;
            }
            let r = &self.reflectance[texel * n..(texel + 1) * n];
            for (o, &(i, t)) in out.iter_mut().zip(&positions) {
                let low = r[i];
                let high = r[(i + 1).min(n - 1)];
                *o += w * (low + t * (high - low));
            }
        }
        Vec4::from_array(out)
    }

    /// Where `nm` falls among the texture's wavelengths: the interval's first sample and
    /// the fraction into it (0 before the first sample, 1 at and after the last).
    #[inline]
    fn locate(&self, nm: f32) -> (usize, f32) {
        let w = &self.wavelengths;
        let n = w.len();
        if n == 1 || nm <= w[0] {
            return (0, 0.0);
        }
        if nm >= w[n - 1] {
            return (n - 2, 1.0);
        }
        let hi = w.partition_point(|&s| s <= nm).clamp(1, n - 1);
        let (a, b) = (w[hi - 1], w[hi]);
        (hi - 1, if b > a { (nm - a) / (b - a) } else { 0.0 })
    }

    /// The map's mean reflectance r̄(λ) and mean c_k·r (for fluorophore `k`) at `nm`, and
    /// the mean c_k: what the map's diagonal is on average, d̄ = r̄ − Σ a_k·(c_k·r)‾.
    pub fn mean_at(&self, nm: f32) -> (f32, Vec<f32>) {
        let n = self.wavelengths.len();
        let (i, t) = self.locate(nm);
        let lerp = |v: &[f32]| v[i] + t * (v[(i + 1).min(n - 1)] - v[i]);
        let absorbing = (0..self.fluorophores.len())
            .map(|k| lerp(&self.mean_absorbing_reflectance[k * n..(k + 1) * n]))
            .collect();
        (lerp(&self.mean_reflectance), absorbing)
    }

    /// The mean concentration of fluorophore `k` over the map.
    pub fn mean_concentration(&self, k: usize) -> f32 {
        self.mean_concentration[k]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `width` × `height` texture without fluorophores whose texel p reflects p / 100 at
    /// 400 nm and twice that at 600 nm.
    fn numbered(width: usize, height: usize) -> MaterialTexture {
        let map = MaterialMap {
            schema: SCHEMA.into(),
            name: "numbered".into(),
            width,
            height,
            fluorophores: Vec::new(),
            gauge: String::new(),
            textures: crate::image::map::Textures {
                concentration: "c.exr".into(),
                concentration_channels: Vec::new(),
                reflectance: "r.exr".into(),
            },
            fit: None,
        };
        let reflectance = (0..width * height)
            .flat_map(|p| [p as f32 / 100.0, p as f32 / 50.0])
            .collect();
        let textures = LoadedTextures {
            width,
            height,
            concentration: Vec::new(),
            wavelengths: vec![400.0, 600.0],
            reflectance,
        };
        MaterialTexture::new(&map, textures).unwrap()
    }

    #[test]
    fn a_texel_centre_reads_that_texel_alone() {
        let t = numbered(4, 2);
        // Texel (2, 1) is p = 6, centred at u = 2.5/4, v = 1.5/2.
        let f = t.footprint(2.5 / 4.0, 1.5 / 2.0, [false, false]);
        let r = t.reflectance(&f, Vec4::new(400.0, 500.0, 600.0, 700.0));
        for (got, want) in r.to_array().iter().zip([0.06, 0.09, 0.12, 0.12]) {
            assert!((got - want).abs() < 1e-6, "{r}");
        }
        assert_eq!(t.reflectance(&f, Vec4::splat(300.0)).x, 0.06);
    }

    #[test]
    fn between_texels_is_bilinear_and_wraps_where_asked() {
        let t = numbered(4, 2);
        // Halfway between texels 0 and 1 of row 0, a quarter of the way to row 1.
        let f = t.footprint(1.0 / 4.0, 0.25 / 2.0 + 0.25, [false, false]);
        let want = 0.75 * 0.5 * (0.00 + 0.01) + 0.25 * 0.5 * (0.04 + 0.05);
        assert!((t.reflectance(&f, Vec4::splat(400.0)).x - want).abs() < 1e-6);
        // u = 0: half the first texel, half the last when wrapping; the first alone when
        // held at the edge.
        let wrapped = t.footprint(0.0, 0.25, [true, false]);
        assert!((t.reflectance(&wrapped, Vec4::splat(400.0)).x - 0.015).abs() < 1e-6);
        let held = t.footprint(0.0, 0.25, [false, false]);
        assert!(t.reflectance(&held, Vec4::splat(400.0)).x.abs() < 1e-6);
        let sum: f32 = wrapped.weight.iter().sum();
        assert!((sum - 1.0).abs() < 1e-6);
    }
}
