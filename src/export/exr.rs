//! `--to exr`: the material's reradiation matrix as a uniform bispectral spectral OpenEXR
//! (the layout of Fichet, Mercier and Wilkie, JCGT 2021, as afichet/spectral-exr writes
//! and reads it; channel names in [`crate::formats::exr`]).
//!
//! Every pixel holds the whole matrix: `T.<λ>nm` the diagonal d = (1 − Σc·a)·r plus the
//! fluorescence emitted at λ itself, `T.<λi>nm.<λo>nm` the reradiation per emission bin
//! for λo > λi (dimensionless, like a BFC-450 cell; the reference's own Labsphere
//! example stores those cells as they are). The layout has one wavelength grid for both
//! axes, so the excitation and emission grids are merged, and it has no channel for
//! anti-Stokes cells (λo < λi): the export reports how much of the matrix's
//! off-diagonal energy that drops, and the file's header says it too. `R`, `G`, `B`
//! channels give viewers the patch's linear sRGB under D65 (white = 1).

use std::collections::HashMap;

use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, Layer, LayerAttributes,
    WritableImage,
};

use crate::colour::{Light, material_xyz, xyz_to_linear_srgb};
use crate::error::{Error, Result};
use crate::formats::exr::{
    VERSION, VERSION_ATTRIBUTE, diagonal_channel, header_text as text, reradiation_channel,
};
use crate::material::Material;
use crate::measurement::{Measurement, Units};

use super::matrix::matrix;
use super::{VERSION as FLUORITE_VERSION, one_line};

/// Pixels per side of the (uniform) image: small, yet visible in a viewer.
const SIDE: usize = 4;

/// The layout's single wavelength grid: the excitation and emission grids merged.
pub fn layout_grid(excitation_nm: &[f64], emission_nm: &[f64]) -> Vec<f64> {
    let mut grid: Vec<f64> = excitation_nm.iter().chain(emission_nm).copied().collect();
    grid.sort_by(f64::total_cmp);
    grid.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    grid
}

/// The share of the off-diagonal energy of `m` (a square per-bin matrix) in anti-Stokes
/// cells (λo < λi), rows weighted by their excitation bin widths so that the sums
/// approximate ∫∫ over both wavelengths; 0 for a matrix without fluorescence.
fn anti_stokes_share_of(m: &Measurement) -> f64 {
    let widths = crate::spectrum::bin_widths(&m.excitation_nm);
    let (mut anti, mut total) = (0.0, 0.0);
    for (i, w) in widths.iter().enumerate() {
        for j in (0..m.n_emission()).filter(|&j| j != i) {
            let v = w * m.get(i, j);
            total += v;
            if j < i {
                anti += v;
            }
        }
    }
    if total > 0.0 { anti / total } else { 0.0 }
}

/// The uniform bispectral EXR of `material` on `grid` (sorted, in nm), and the share of
/// the matrix's off-diagonal (fluorescent) energy in the anti-Stokes cells (λo < λi) the
/// layout cannot hold.
pub(super) fn exr(material: &Material, grid: &[f64]) -> Result<(Vec<u8>, f64)> {
    let m = matrix(material, grid, grid, Units::PerBin)?;
    let n = grid.len();
    let uniform = |v: f64| FlatSamples::F32(vec![v as f32; SIDE * SIDE]);
    let mut channels = Vec::with_capacity(n * (n + 1) / 2 + 3);
    for i in 0..n {
        channels.push(AnyChannel::new(
            diagonal_channel(grid[i]).as_str(),
            uniform(m.get(i, i)),
        ));
        for j in i + 1..n {
            channels.push(AnyChannel::new(
                reradiation_channel(grid[i], grid[j]).as_str(),
                uniform(m.get(i, j)),
            ));
        }
    }
    let d65 = Light::builtin("d65").expect("d65 is built in");
    let (xyz, _) = material_xyz(material, &d65);
    let rgb = xyz_to_linear_srgb(xyz.map(|v| v / 100.0));
    for (name, v) in ["R", "G", "B"].iter().zip(rgb) {
        channels.push(AnyChannel::new(*name, uniform(v)));
    }
    let share = anti_stokes_share_of(&m);
    let mut attributes = LayerAttributes {
        software_name: Some(text(&format!("fluorite {FLUORITE_VERSION}"))),
        comments: Some(text(&format!(
            "Bispectral reflective image of material \"{}\" (Jung et al. 2018 model), uniform. \
             T.<l>nm: diagonal, reflectance factor (1 - sum c*a)*r plus the fluorescence emitted at l (dimensionless). \
             T.<li>nm.<lo>nm: reradiation from li to lo > li per emission bin (dimensionless, trapezoid bin widths). \
             The layout has no anti-Stokes channel (lo < li): {:.4} % of this matrix's off-diagonal energy is not stored. \
             R, G, B: linear sRGB of the patch under D65 (perfect white = 1). \
             fluoriteAntiStokesShareDropped: {}",
            one_line(&material.name),
            100.0 * share,
            share as f32
        ))),
        ..LayerAttributes::default()
    };
    // The exr crate keeps custom attributes in hash maps and writes each map in random
    // order: one custom attribute per map (the layer's and the image's) keeps the file
    // byte-reproducible; the rest is in `comments`.
    attributes.other =
        HashMap::from([(text(VERSION_ATTRIBUTE), AttributeValue::Text(text(VERSION)))]);
    let layer = Layer::new(
        (SIDE, SIDE),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let mut image = Image::from_layer(layer);
    // The reference writer always stores an exposure compensation (`EV`, float).
    image.attributes.other = HashMap::from([(text("EV"), AttributeValue::F32(0.0))]);
    let mut cursor = std::io::Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut cursor)
        .map_err(|e| Error::invalid("exr", format!("could not encode the image: {e}")))?;
    Ok((cursor.into_inner(), share))
}
