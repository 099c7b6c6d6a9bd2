//! The material map: what an image fit hands to everything downstream, as the material
//! is for a single matrix. Serialised as `fluorite-material-map/1` JSON beside its
//! textures: K fluorophores shared by every pixel, a concentration per fluorophore and
//! pixel (`concentration.exr`), a reflectance spectrum per pixel (`reflectance.exr`, the
//! spectral OpenEXR layout's reflective channels `T.<λ>nm`).
//!
//! The material of pixel p is the shared fluorophores with concentrations c_k(p) and the
//! reflectance r(p, λ); [`MaterialMap::material_at`] builds it.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::material::{Fluorophore, Material};
use crate::spectrum::Spectrum;

/// Schema tag of a material map.
pub const SCHEMA: &str = "fluorite-material-map/1";

/// Shared fluorophores and the textures that vary them over an image.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MaterialMap {
    /// Always [`SCHEMA`].
    pub schema: String,
    /// A short name (the image's file stem).
    pub name: String,
    /// Pixels per row of the textures.
    pub width: usize,
    /// Rows of the textures.
    pub height: usize,
    /// The fluorophores every pixel shares. Each one's `concentration` is the largest
    /// c_k(p) over the image (its texture holds the per-pixel values); its yield is the
    /// one the gauge chose for the whole image.
    pub fluorophores: Vec<Fluorophore>,
    /// How the yield of each fluorophore (hence the scale of its concentrations) was
    /// chosen: the matrix fixes only c_k(p)·Q_k.
    pub gauge: String,
    /// The texture files, relative to the JSON file's folder.
    pub textures: Textures,
    /// How the fit went (absent for hand-written maps).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<serde_json::Value>,
}

/// The texture files of a material map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Textures {
    /// The concentrations: one channel per fluorophore, in order.
    pub concentration: String,
    /// The channel of each fluorophore's concentration in `concentration`.
    pub concentration_channels: Vec<String>,
    /// The reflectance r(p, λ): reflective spectral channels `T.<λ>nm`.
    pub reflectance: String,
}

/// The channel holding fluorophore `k`'s concentration (k from 0): `c1`, `c2`, …
pub fn concentration_channel(k: usize) -> String {
    format!("c{}", k + 1)
}

/// A material map's textures, read whole.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadedTextures {
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `concentration[p·K + k]`: c_k at pixel p (row-major).
    pub concentration: Vec<f32>,
    /// The reflectance's wavelengths (nm).
    pub wavelengths: Vec<f64>,
    /// `reflectance[p·n + i]`: r at pixel p and wavelength i.
    pub reflectance: Vec<f32>,
}

impl MaterialMap {
    /// Reads a material map's JSON.
    pub fn load(path: &Path) -> Result<MaterialMap> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        let map: MaterialMap = serde_json::from_str(&text).map_err(|e| {
            Error::parse(
                path,
                e.line(),
                e.column(),
                format!("not a {SCHEMA} file: {e}"),
            )
        })?;
        if map.schema != SCHEMA {
            return Err(Error::parse(
                path,
                1,
                1,
                format!("schema {:?}, expected {SCHEMA:?}", map.schema),
            ));
        }
        if map.textures.concentration_channels.len() != map.fluorophores.len() {
            return Err(Error::parse(
                path,
                1,
                1,
                format!(
                    "{} concentration channels for {} fluorophores",
                    map.textures.concentration_channels.len(),
                    map.fluorophores.len()
                ),
            ));
        }
        Ok(map)
    }

    /// The JSON text.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a material map serialises") + "\n"
    }

    /// The texture paths, resolved against the folder of the JSON file at `json`.
    pub fn texture_paths(&self, json: &Path) -> (PathBuf, PathBuf) {
        let dir = json.parent().unwrap_or(Path::new("."));
        (
            dir.join(&self.textures.concentration),
            dir.join(&self.textures.reflectance),
        )
    }

    /// Reads the textures of the map whose JSON is at `json`.
    pub fn load_textures(&self, json: &Path) -> Result<LoadedTextures> {
        let (c_path, r_path) = self.texture_paths(json);
        let (cw, ch, names, c_values) = read_whole(&c_path)?;
        let k = self.fluorophores.len();
        let mut concentration = vec![0f32; cw * ch * k];
        for (j, wanted) in self.textures.concentration_channels.iter().enumerate() {
            let Some(index) = names.iter().position(|n| n == wanted) else {
                return Err(Error::parse(
                    &c_path,
                    0,
                    0,
                    format!(
                        "no channel {wanted} (the map names it for fluorophore {})",
                        j + 1
                    ),
                ));
            };
            for p in 0..cw * ch {
                concentration[p * k + j] = c_values[index][p];
            }
        }
        let (rw, rh, r_names, r_values) = read_whole(&r_path)?;
        if (rw, rh) != (cw, ch) {
            return Err(Error::parse(
                &r_path,
                0,
                0,
                format!("{rw}×{rh} pixels, while the concentrations have {cw}×{ch}"),
            ));
        }
        let mut spectral: Vec<(f64, usize)> = r_names
            .iter()
            .enumerate()
            .filter_map(|(i, n)| match crate::formats::exr::parse_channel(n) {
                Some(crate::formats::exr::Channel::Diagonal(l)) => Some((l, i)),
                _ => None,
            })
            .collect();
        spectral.sort_by(|a, b| a.0.total_cmp(&b.0));
        if spectral.is_empty() {
            return Err(Error::parse(
                &r_path,
                0,
                0,
                "no reflective spectral channel T.<λ>nm".to_string(),
            ));
        }
        let n = spectral.len();
        let mut reflectance = vec![0f32; rw * rh * n];
        for (i, &(_, channel)) in spectral.iter().enumerate() {
            for p in 0..rw * rh {
                reflectance[p * n + i] = r_values[channel][p];
            }
        }
        Ok(LoadedTextures {
            width: cw,
            height: ch,
            concentration,
            wavelengths: spectral.iter().map(|s| s.0).collect(),
            reflectance,
        })
    }

    /// The material of one pixel: the shared fluorophores at concentrations `c` and the
    /// reflectance `r` on `wavelengths`. Non-finite values (masked pixels) are an error.
    pub fn material_at(&self, c: &[f32], wavelengths: &[f64], r: &[f32]) -> Result<Material> {
        if c.iter().chain(r).any(|v| !v.is_finite()) {
            return Err(Error::invalid(
                "pixel",
                "the pixel is masked (its measurement held non-finite cells)",
            ));
        }
        let reflectance = Spectrum::new(
            wavelengths.to_vec(),
            r.iter().map(|&v| f64::from(v).clamp(0.0, 1.0)).collect(),
            "reflectance",
        )?;
        let fluorophores = self
            .fluorophores
            .iter()
            .zip(c)
            .map(|(f, &c)| Fluorophore {
                concentration: f64::from(c).max(0.0),
                concentration_range: None,
                ..f.clone()
            })
            .collect();
        Ok(Material {
            schema: crate::material::SCHEMA.into(),
            name: self.name.clone(),
            reflectance,
            fluorophores,
            fit: None,
            conservation: None,
            forms: None,
        })
    }
}

/// Every channel of the first part of a (small) EXR, read whole: width, height, channel
/// names, and each channel's samples row-major.
#[allow(clippy::type_complexity)] // four parts, destructured where it is called
pub fn read_whole(path: &Path) -> Result<(usize, usize, Vec<String>, Vec<Vec<f32>>)> {
    use exr::prelude::{ReadChannels, ReadLayers, read};
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| Error::parse(path, 0, 0, format!("not a readable OpenEXR file: {e}")))?;
    let layer = image.layer_data;
    let size = layer.size;
    let mut names = Vec::new();
    let mut values = Vec::new();
    for c in &layer.channel_data.list {
        names.push(c.name.to_string());
        values.push(c.sample_data.values_as_f32().collect());
    }
    Ok((size.x(), size.y(), names, values))
}
