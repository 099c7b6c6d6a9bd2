//! Writing small material maps (`fluorite-material-map/1`): the JSON and its two textures
//! (`concentration.exr`, channels c1..cK; `reflectance.exr`, channels `T.<λ>nm`) in one
//! folder. The render tests build their maps with it, and `examples/material_map.rs`
//! (which includes this file) writes the example map under `fits/maps/`.

use std::path::Path;

use fluorite::Fluorophore;
use fluorite::formats::exr::diagonal_channel;
use fluorite::image::map::{MaterialMap, SCHEMA, Textures, concentration_channel};
use fluorite::image::sink::{ImageSpec, write_image};

/// File name of a written map's concentration texture.
pub const CONCENTRATION_FILE: &str = "concentration.exr";
/// File name of a written map's reflectance texture.
pub const REFLECTANCE_FILE: &str = "reflectance.exr";

/// Writes an OpenEXR image of `width` × `height` pixels with `channels`, pixel (x, y)
/// holding `pixel(x, y)` (one value per channel, in order).
pub fn write_exr(
    path: &Path,
    (width, height): (usize, usize),
    channels: &[String],
    pixel: &(dyn Fn(usize, usize) -> Vec<f32> + Sync),
) -> fluorite::Result<()> {
    let spec = ImageSpec {
        width,
        height,
        channels: channels.to_vec(),
        half: false,
        zip: true,
        attributes: Vec::new(),
    };
    write_image(
        path,
        &spec,
        |rect| {
            let mut values = Vec::with_capacity(rect.width * rect.height * channels.len());
            for y in rect.y..rect.y + rect.height {
                for x in rect.x..rect.x + rect.width {
                    let v = pixel(x, y);
                    assert_eq!(v.len(), channels.len(), "pixel ({x}, {y})");
                    values.extend(v);
                }
            }
            Ok(values)
        },
        |_, _| {},
    )
}

/// Writes the material map `json` (its textures beside it): the shared `fluorophores`,
/// `size` = (width, height) texels, texel (x, y) holding the concentrations
/// `concentration(x, y)` (one per fluorophore) and the reflectance `reflectance(x, y)` at
/// `wavelengths`. Each fluorophore's `concentration` in the JSON becomes the largest of
/// its texels. Returns the map as written.
pub fn write_map(
    json: &Path,
    name: &str,
    size: (usize, usize),
    fluorophores: &[Fluorophore],
    wavelengths: &[f64],
    concentration: &(dyn Fn(usize, usize) -> Vec<f32> + Sync),
    reflectance: &(dyn Fn(usize, usize) -> Vec<f32> + Sync),
) -> fluorite::Result<MaterialMap> {
    let dir = json.parent().unwrap_or(Path::new("."));
    let k = fluorophores.len();
    let (width, height) = size;
    let mut largest = vec![0f64; k];
    for y in 0..height {
        for x in 0..width {
            for (m, c) in largest.iter_mut().zip(concentration(x, y)) {
                if c.is_finite() {
                    *m = m.max(c as f64);
                }
            }
        }
    }
    let channels: Vec<String> = (0..k).map(concentration_channel).collect();
    if k == 0 {
        // An image needs a channel: a map without fluorophores stores an unused one.
        write_exr(
            &dir.join(CONCENTRATION_FILE),
            size,
            &["unused".to_string()],
            &|_, _| vec![0.0],
        )?;
    } else {
        write_exr(
            &dir.join(CONCENTRATION_FILE),
            size,
            &channels,
            concentration,
        )?;
    }
    let spectral: Vec<String> = wavelengths.iter().map(|&l| diagonal_channel(l)).collect();
    write_exr(&dir.join(REFLECTANCE_FILE), size, &spectral, reflectance)?;
    let map = MaterialMap {
        schema: SCHEMA.to_string(),
        name: name.to_string(),
        width,
        height,
        fluorophores: fluorophores
            .iter()
            .zip(&largest)
            .map(|(f, &c)| Fluorophore {
                concentration: c,
                ..f.clone()
            })
            .collect(),
        gauge: "written by hand: each fluorophore's yield as given".to_string(),
        textures: Textures {
            concentration: CONCENTRATION_FILE.to_string(),
            concentration_channels: channels,
            reflectance: REFLECTANCE_FILE.to_string(),
        },
        fit: None,
    };
    std::fs::write(json, map.to_json()).map_err(|e| fluorite::Error::io(json, e))?;
    Ok(map)
}
