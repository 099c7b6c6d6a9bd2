//! The outputs of an image fit, pixel by pixel and band by band: each output's values of
//! a pixel (the same functions whoever writes the file), and [`write_band`], which
//! writes a band of tile rows of every uncompressed EXR output into files laid out
//! beforehand ([`crate::image::sink::TiledFile`]) and returns the band's PNG rows: what a
//! worker of a cluster does with its share of the records, while the process that ran
//! the fit encodes the PNGs and writes the material map.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::colour::{D65_WHITE, adapt_bradford, xyz_to_srgb8};
use crate::error::{Error, Result};
use crate::image::layout::Layout;
use crate::image::map::concentration_channel;
use crate::image::sink::{ImageSpec, TILE, TiledFile};

use super::pixel::{PixelColours, PixelFit, PixelModel};
use super::shared::Shared;

/// The top of the ΔE2000 false-colour scale, in multiples of the bound.
pub const DELTA_E_SCALE: f64 = 2.0;
/// Columns between the measured and the fitted image in the light PNGs.
pub const GAP: usize = 8;

/// The EXR outputs' names, in the order [`exr_specs`] gives them.
pub const EXR_OUTPUTS: [&str; 4] = [
    "concentration.exr",
    "reflectance.exr",
    "fitted.exr",
    "delta-e.exr",
];

/// A light's name as a file-name part (the channels of `delta-e.exr`, the PNGs' names).
pub fn file_part(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c.to_ascii_lowercase()
            } else {
                '_'
            }
        })
        .collect()
}

/// What the EXR outputs of a fit of `k` fluorophores on an image of `width` × `height`
/// pixels hold, in [`EXR_OUTPUTS`]' order:
/// concentration (c1..ck), reflectance (the layout's diagonal channels), the fitted image
/// (the input's layout, `half` as the input), ΔE2000 per light.
pub fn exr_specs(
    (width, height): (usize, usize),
    layout: &Layout,
    k: usize,
    lights: &[String],
    half: bool,
    zip: bool,
    attributes: &[(String, String)],
) -> [ImageSpec; 4] {
    let spec = |channels: Vec<String>, half: bool| ImageSpec {
        width,
        height,
        channels,
        half,
        zip,
        attributes: attributes.to_vec(),
    };
    let nd = layout.diagonal_count;
    [
        spec((0..k).map(concentration_channel).collect(), false),
        spec(layout.channel_names()[..nd].to_vec(), false),
        spec(layout.channel_names(), half),
        spec(lights.iter().map(|l| file_part(l)).collect(), false),
    ]
}

/// A pixel's values in `concentration.exr`.
pub fn concentration_values(f: &PixelFit, k: usize, out: &mut Vec<f32>) {
    out.extend(f.concentration[..k].iter().map(|&c| c as f32));
}

/// A pixel's values in `reflectance.exr`.
pub fn reflectance_values(f: &PixelFit, out: &mut Vec<f32>) {
    out.extend(f.reflectance.iter().map(|&r| r as f32));
}

/// A pixel's values in `fitted.exr`: the fitted diagonal, then each reradiation cell
/// Σk scores_k·vectors_k (NaN where the pixel is masked).
pub fn fitted_values(f: &PixelFit, vectors: &[Vec<f64>], out: &mut Vec<f32>) {
    out.extend(f.fitted_diagonal.iter().map(|&d| d as f32));
    let cells = vectors.first().map_or(0, Vec::len);
    for j in 0..cells {
        let value: f64 = if f.masked {
            f64::NAN
        } else {
            vectors
                .iter()
                .enumerate()
                .map(|(c, v)| f.scores[c] * v[j])
                .sum()
        };
        out.push(value as f32);
    }
}

/// A pixel's values in `delta-e.exr`.
pub fn delta_e_values(colours: &PixelColours, out: &mut Vec<f32>) {
    out.extend(colours.delta_e.iter().map(|&d| d as f32));
}

/// How the PNGs show a pixel: each light's white (for the adaptation to D65) and the
/// bound (the ΔE false colour's scale).
pub struct PngStyle {
    whites: Vec<[f64; 3]>,
    bound: f64,
}

impl PngStyle {
    /// The style of `model`'s PNGs under the bound `bound`.
    pub fn new(model: &PixelModel, bound: f64) -> PngStyle {
        PngStyle {
            whites: (0..model.lights().len()).map(|l| model.white(l)).collect(),
            bound,
        }
    }

    /// Lights.
    pub fn lights(&self) -> usize {
        self.whites.len()
    }

    /// Bytes of one image row of every PNG: per light, the ΔE map's row (RGB) and the
    /// light image's (measured, a gap, fitted).
    pub fn row_bytes(&self, width: usize) -> usize {
        self.lights() * 3 * (width + 2 * width + GAP)
    }

    /// A new row of every PNG (the gap white), as [`PngStyle::row_bytes`] lays it out.
    pub fn blank_row(&self, width: usize) -> Vec<u8> {
        vec![255u8; self.row_bytes(width)]
    }

    /// Pixel `x`'s colours into `row` (of [`PngStyle::blank_row`]).
    pub fn fill(
        &self,
        row: &mut [u8],
        width: usize,
        x: usize,
        f: &PixelFit,
        colours: &PixelColours,
    ) {
        let per_light = 3 * (3 * width + GAP);
        for l in 0..self.lights() {
            let base = l * per_light;
            let (delta, under) = row[base..base + per_light].split_at_mut(3 * width);
            let fitted_at = (width + GAP + x) * 3;
            if f.masked {
                let grey = [128, 128, 128];
                delta[x * 3..x * 3 + 3].copy_from_slice(&grey);
                under[x * 3..x * 3 + 3].copy_from_slice(&grey);
                under[fitted_at..fitted_at + 3].copy_from_slice(&grey);
                continue;
            }
            let c =
                crate::plot::colormap::viridis(colours.delta_e[l] / (DELTA_E_SCALE * self.bound));
            delta[x * 3..x * 3 + 3].copy_from_slice(&[c.0, c.1, c.2]);
            let show = |xyz: [f64; 3]| {
                let adapted = adapt_bradford(xyz, self.whites[l], D65_WHITE.map(|v| v * 100.0));
                xyz_to_srgb8(adapted.map(|v| v / 100.0))
            };
            under[x * 3..x * 3 + 3].copy_from_slice(&show(colours.measured_xyz[l]));
            under[fitted_at..fitted_at + 3].copy_from_slice(&show(colours.fitted_xyz[l]));
        }
    }

    /// Light `l`'s ΔE row and light-image row within a row of every PNG.
    pub fn split<'r>(&self, row: &'r [u8], width: usize, l: usize) -> (&'r [u8], &'r [u8]) {
        let per_light = 3 * (3 * width + GAP);
        row[l * per_light..(l + 1) * per_light].split_at(3 * width)
    }
}

/// What a worker needs to write its bands of a fit's outputs (sent as JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputJob {
    /// The chosen K's shared spectra.
    pub shared: Shared,
    /// The cell noise σ.
    pub sigma: f64,
    /// The EXR outputs' staged files, made by [`TiledFile::create`], in
    /// [`EXR_OUTPUTS`]' order.
    pub staged: Vec<PathBuf>,
    /// The images' header attributes.
    pub attributes: Vec<(String, String)>,
    /// Whether the fitted image is written in 16-bit floats (as its input).
    pub half: bool,
}

/// What [`write_band`] returns to the process encoding the PNGs.
#[derive(Debug, Clone, PartialEq)]
pub struct BandOutputs {
    /// Pixels of the band whose material needed clamping.
    pub clamped: usize,
    /// The band's rows of every PNG, row after row ([`PngStyle::row_bytes`] each).
    pub png: Vec<u8>,
}

/// The rows of tiles a band starting at row `y` and `rows` rows long covers, checked: a
/// band is whole rows of tiles.
fn band_tiles(
    width: usize,
    height: usize,
    y: usize,
    rows: usize,
) -> Result<std::ops::Range<usize>> {
    let whole = y.is_multiple_of(TILE) && (rows.is_multiple_of(TILE) || y + rows == height);
    if !whole || rows == 0 || y + rows > height {
        return Err(Error::invalid(
            "band",
            format!(
                "rows {y}..{} of an image of {height} rows: a band is whole rows of {TILE}-pixel tiles",
                y + rows
            ),
        ));
    }
    let per_row = width.div_ceil(TILE);
    Ok(y / TILE * per_row..(y + rows).div_ceil(TILE) * per_row)
}

/// Writes rows `y..y + rows` (whole rows of tiles) of every EXR output of `job` into its
/// staged files, from `records` (those rows' records, every column, in pixel order), and
/// returns the band's PNG rows and clamped pixels. Each pixel is evaluated once.
#[allow(clippy::too_many_arguments)]
pub fn write_band(
    job: &OutputJob,
    model: &PixelModel,
    layout: &Layout,
    vectors: &[Vec<f64>],
    style: &PngStyle,
    (width, height): (usize, usize),
    y: usize,
    rows: usize,
    records: &[f32],
    record_len: usize,
) -> Result<BandOutputs> {
    let tiles = band_tiles(width, height, y, rows)?;
    if records.len() != rows * width * record_len {
        return Err(Error::invalid(
            "records",
            format!(
                "{} values for {rows} rows of {width} pixels of {record_len} values",
                records.len()
            ),
        ));
    }
    if job.staged.len() != EXR_OUTPUTS.len() {
        return Err(Error::invalid(
            "job",
            format!(
                "{} staged files for {} outputs",
                job.staged.len(),
                EXR_OUTPUTS.len()
            ),
        ));
    }
    let k = model.components();
    let specs = exr_specs(
        (width, height),
        layout,
        k,
        model.lights(),
        job.half,
        false,
        &job.attributes,
    );
    let files = specs
        .iter()
        .zip(&job.staged)
        .map(|(spec, path)| TiledFile::plan(path, spec))
        .collect::<Result<Vec<_>>>()?;
    let mut writers = files
        .iter()
        .zip(&job.staged)
        .map(|(file, path)| file.writer(path))
        .collect::<Result<Vec<_>>>()?;
    let row_bytes = style.row_bytes(width);
    let mut png: Vec<u8> = (0..rows).flat_map(|_| style.blank_row(width)).collect();
    let mut clamped = 0;
    // Each file's values of one tile, the buffers kept from tile to tile.
    let mut values: [Vec<f32>; 4] = Default::default();
    for tile in tiles {
        let Some(rect) = files[0].rect(tile) else {
            break;
        };
        // The tile's pixels, evaluated once for the four files and the PNGs.
        values.iter_mut().for_each(Vec::clear);
        for py in rect.y..rect.y + rect.height {
            let row = &mut png[(py - y) * row_bytes..(py - y + 1) * row_bytes];
            for px in rect.x..rect.x + rect.width {
                let at = ((py - y) * width + px) * record_len;
                let record = &records[at..at + record_len];
                let f = model.fit(record);
                let colours = model.colours(record, &f);
                clamped += usize::from(f.clamped);
                concentration_values(&f, k, &mut values[0]);
                reflectance_values(&f, &mut values[1]);
                fitted_values(&f, vectors, &mut values[2]);
                delta_e_values(&colours, &mut values[3]);
                style.fill(row, width, px, &f, &colours);
            }
        }
        for (writer, v) in writers.iter_mut().zip(&values) {
            writer.write(tile, v)?;
        }
    }
    Ok(BandOutputs { clamped, png })
}
