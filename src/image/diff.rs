//! Comparing two bispectral images pixel by pixel (`fluorite image-diff`): the ΔE2000
//! between their matrices under each light, and, given their material maps, how well the
//! concentration maps of one match the other's.
//!
//! This is the yardstick for a fit against its truth, so it uses nothing from a fit:
//! each pixel's colour is that of its matrix (its cells on the layout's one grid, cells
//! the layout lacks counted as zero) through [`PatchColorimeter`], the colorimeter
//! `fluorite fit` judges a matrix by and that `../shared/tools/evaluate.py` checks
//! (model.md §7); the image fit's own per-cell weights are not used. Pixels holding a
//! non-finite cell in either image are skipped and counted.
//!
//! Memory: the images are streamed block by block, one after the other (their block
//! layouts may differ), keeping per pixel only the first image's XYZ under each light
//! (3 numbers per light, as 32-bit floats: both images' XYZ are rounded alike, which
//! moves a ΔE2000 by about 1e-5) and then the ΔE2000 per light: a few dozen bytes per
//! pixel where the image holds kilobytes.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::colour::{Light, PatchColorimeter, Xyz, delta_e2000, xyz_to_lab};
use crate::error::{Error, Result};
use crate::image::layout::{Cell, Layout};
use crate::image::map::{MaterialMap, read_whole};
use crate::image::source::{ExrImage, PixelBlock};

/// The ΔE2000 distribution over the compared pixels under one light.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LightDelta {
    /// The light's name.
    pub light: String,
    /// Median over the compared pixels (NaN when none was compared).
    pub median: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest value.
    pub max: f64,
}

/// What [`diff_images`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageDiff {
    /// The first image.
    pub a: PathBuf,
    /// The second image.
    pub b: PathBuf,
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Cells per pixel (the shared layout's).
    pub cells: usize,
    /// Pixels compared (finite in both images).
    pub compared: usize,
    /// Pixels skipped: a non-finite cell in either image.
    pub skipped: usize,
    /// Pixels of the first image holding a non-finite cell.
    pub non_finite_a: usize,
    /// Pixels of the second image holding a non-finite cell.
    pub non_finite_b: usize,
    /// Per light, in the order asked for.
    pub lights: Vec<LightDelta>,
}

/// Checks that two opened images can be compared pixel by pixel: the same size and the
/// same cells on the same grid. The error names both files.
pub fn check_compatible(a: &ExrImage, b: &ExrImage) -> Result<()> {
    let both = format!("{} and {}", a.path.display(), b.path.display());
    if (a.width, a.height) != (b.width, b.height) {
        return Err(Error::invalid(
            both,
            format!(
                "the images differ in size ({}×{} and {}×{} pixels); compare images of one size",
                a.width, a.height, b.width, b.height
            ),
        ));
    }
    let grid = |l: &crate::image::Layout| {
        format!(
            "{} wavelengths {}–{} nm",
            l.wavelengths.len(),
            l.wavelengths.first().copied().unwrap_or(f64::NAN),
            l.wavelengths.last().copied().unwrap_or(f64::NAN)
        )
    };
    let same_grid = a.layout.wavelengths.len() == b.layout.wavelengths.len()
        && a.layout
            .wavelengths
            .iter()
            .zip(&b.layout.wavelengths)
            .all(|(x, y)| (x - y).abs() <= 1e-6);
    if !same_grid || a.layout.cells != b.layout.cells {
        return Err(Error::invalid(
            both,
            format!(
                "the images have different layouts ({} cells on {} against {} cells on {}); compare images with the same channels",
                a.layout.len(),
                grid(&a.layout),
                b.layout.len(),
                grid(&b.layout)
            ),
        ));
    }
    Ok(())
}

/// The colour of a pixel's matrix under each light: the matrix rebuilt on the layout's
/// grid (excitation × emission, per bin) and measured with [`PatchColorimeter`].
struct Yardstick {
    /// Light names, in order.
    lights: Vec<String>,
    /// One colorimeter per light on the layout's grid (both axes).
    colorimeters: Vec<PatchColorimeter>,
    /// The layout's cells: (excitation, emission) grid indices, equal on the diagonal.
    cells: Vec<(usize, usize)>,
    /// Grid samples.
    n: usize,
}

impl Yardstick {
    fn new(layout: &Layout, lights: &[Light]) -> Yardstick {
        let grid = &layout.wavelengths;
        Yardstick {
            lights: lights.iter().map(|l| l.name.clone()).collect(),
            colorimeters: lights
                .iter()
                .map(|l| PatchColorimeter::new(l, grid, grid))
                .collect(),
            cells: layout
                .cells
                .iter()
                .map(|c| match *c {
                    Cell::Diagonal(i) => (i, i),
                    Cell::Reradiation(i, o) => (i, o),
                })
                .collect(),
            n: grid.len(),
        }
    }

    /// XYZ under every light (`3 × lights`, light-major) of a pixel's cells.
    fn xyz(&self, cells: &[f32]) -> Vec<f64> {
        let n = self.n;
        let mut diagonal = vec![0.0; n];
        let mut reradiation = vec![0.0; n * n];
        for (&(i, o), &v) in self.cells.iter().zip(cells) {
            if i == o {
                diagonal[i] = f64::from(v);
            } else {
                reradiation[i * n + o] = f64::from(v);
            }
        }
        self.colorimeters
            .iter()
            .flat_map(|c| c.xyz_from(&diagonal, |i, o| reradiation[i * n + o]))
            .collect()
    }

    /// ΔE2000 between two XYZ under light `l`.
    fn delta_e(&self, l: usize, a: Xyz, b: Xyz) -> f64 {
        let white = self.colorimeters[l].white;
        delta_e2000(xyz_to_lab(a, white), xyz_to_lab(b, white))
    }
}

/// Per pixel of a block: its XYZ under every light (`3 × lights` numbers, light-major),
/// or None when a cell is non-finite.
fn block_xyz(block: &PixelBlock, colours: &Yardstick) -> Vec<Option<Vec<f64>>> {
    (0..block.pixel_count())
        .map(|q| {
            let cells = block.pixel(q);
            if cells.iter().any(|v| !v.is_finite()) {
                return None;
            }
            Some(colours.xyz(cells))
        })
        .collect()
}

/// The `q`-quantile of sorted values, interpolated linearly between ranks (as
/// [`crate::numeric::quantile`]); NaN when empty.
fn sorted_quantile(sorted: &[f32], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let pos = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    let (a, b) = (f64::from(sorted[lo]), f64::from(sorted[hi]));
    a + (b - a) * (pos - lo as f64)
}

/// ΔE2000 per pixel between `a` and `b` (same size and layout) under `lights`: the
/// median, 90th and 99th percentile and largest value per light. `progress` gets the
/// blocks read so far and the total (both images' blocks).
pub fn diff_images(
    a: &ExrImage,
    b: &ExrImage,
    lights: &[Light],
    mut progress: impl FnMut(usize, usize),
) -> Result<ImageDiff> {
    check_compatible(a, b)?;
    if lights.is_empty() {
        return Err(Error::invalid("--lights", "give at least one light"));
    }
    let colours = Yardstick::new(&a.layout, lights);
    let nl = lights.len();
    let width = a.width;
    let pixels = a.pixels();
    let total = a.blocks() + b.blocks();

    // Pass over A: XYZ per pixel and light (NaN for a pixel with a non-finite cell).
    let mut xyz_a = vec![f32::NAN; pixels * 3 * nl];
    let mut non_finite_a = 0;
    a.pass(
        |block| {
            let pixels: Vec<usize> = (0..block.pixel_count())
                .map(|q| block.image_index(q, width))
                .collect();
            Ok((pixels, block_xyz(block, &colours)))
        },
        |(pixels, values)| {
            for (p, v) in pixels.into_iter().zip(values) {
                match v {
                    Some(v) => {
                        for (out, x) in xyz_a[p * 3 * nl..(p + 1) * 3 * nl].iter_mut().zip(v) {
                            *out = x as f32;
                        }
                    }
                    None => non_finite_a += 1,
                }
            }
            Ok(())
        },
        |d| progress(d, total),
    )?;

    // Pass over B: ΔE2000 per pixel and light against A's colour.
    let mut delta = vec![f32::NAN; pixels * nl];
    let mut non_finite_b = 0;
    let done_a = a.blocks();
    pass_b(b, &colours, &xyz_a, &mut delta, &mut non_finite_b, |d| {
        progress(done_a + d, total)
    })?;
    drop(xyz_a);

    let mut stats = Vec::with_capacity(nl);
    let mut compared = 0;
    for (l, light) in lights.iter().enumerate() {
        let mut values: Vec<f32> = (0..pixels)
            .map(|p| delta[p * nl + l])
            .filter(|v| v.is_finite())
            .collect();
        values.sort_by(f32::total_cmp);
        compared = values.len();
        stats.push(LightDelta {
            light: light.name.clone(),
            median: sorted_quantile(&values, 0.5),
            p90: sorted_quantile(&values, 0.9),
            p99: sorted_quantile(&values, 0.99),
            max: values.last().map_or(f64::NAN, |&v| f64::from(v)),
        });
    }
    Ok(ImageDiff {
        a: a.path.clone(),
        b: b.path.clone(),
        width,
        height: a.height,
        cells: a.layout.len(),
        compared,
        skipped: pixels - compared,
        non_finite_a,
        non_finite_b,
        lights: stats,
    })
}

/// The pass over the second image: fills `delta[pixel · lights + light]` with the
/// ΔE2000 against the first image's XYZ `xyz_a` (left NaN where either is non-finite).
fn pass_b(
    b: &ExrImage,
    colours: &Yardstick,
    xyz_a: &[f32],
    delta: &mut [f32],
    non_finite_b: &mut usize,
    progress: impl FnMut(usize),
) -> Result<()> {
    let nl = colours.lights.len();
    let width = b.width;
    b.pass(
        |block| {
            let pixels: Vec<usize> = (0..block.pixel_count())
                .map(|q| block.image_index(q, width))
                .collect();
            let xyz = block_xyz(block, colours);
            let values: Vec<Option<Vec<f32>>> = xyz
                .into_iter()
                .zip(&pixels)
                .map(|(v, &p)| {
                    let theirs = &xyz_a[p * 3 * nl..(p + 1) * 3 * nl];
                    v.map(|mine| {
                        (0..nl)
                            .map(|l| {
                                if theirs[3 * l..3 * l + 3].iter().any(|x| !x.is_finite()) {
                                    return f32::NAN;
                                }
                                let a = [0, 1, 2].map(|k| f64::from(theirs[3 * l + k]));
                                // Rounded as the first image's XYZ were when kept, so
                                // equal pixels differ by exactly 0.
                                let b = [0, 1, 2].map(|k| f64::from(mine[3 * l + k] as f32));
                                colours.delta_e(l, a, b) as f32
                            })
                            .collect()
                    })
                })
                .collect();
            Ok((pixels, values))
        },
        |(pixels, values)| {
            for (p, v) in pixels.into_iter().zip(values) {
                match v {
                    Some(v) => delta[p * nl..(p + 1) * nl].copy_from_slice(&v),
                    None => *non_finite_b += 1,
                }
            }
            Ok(())
        },
        progress,
    )
}

/// A fluorophore of the first map and its match in the second.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapMatch {
    /// Fluorophore of the first map (1-based, as the map's channels `c1`…).
    pub a: usize,
    /// Its match in the second map (1-based).
    pub b: usize,
    /// Pearson correlation of the two concentration maps over the pixels finite in both
    /// (NaN when either map is constant there).
    pub correlation: f64,
}

/// What [`compare_maps`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapComparison {
    /// Fluorophores of the first map.
    pub fluorophores_a: usize,
    /// Fluorophores of the second map.
    pub fluorophores_b: usize,
    /// Matched pairs, by decreasing correlation (greedy one-to-one: the best pair first,
    /// then the best among the rest).
    pub matches: Vec<MapMatch>,
    /// Fluorophores of the first map left without a match (1-based).
    pub unmatched_a: Vec<usize>,
    /// Fluorophores of the second map left without a match (1-based).
    pub unmatched_b: Vec<usize>,
}

/// The concentration maps of the material map at `json`: (width, height, one map per
/// fluorophore, row-major).
fn concentrations(json: &Path) -> Result<(usize, usize, Vec<Vec<f32>>)> {
    let map = MaterialMap::load(json)?;
    let (path, _) = map.texture_paths(json);
    let (width, height, names, values) = read_whole(&path)?;
    let maps = map
        .textures
        .concentration_channels
        .iter()
        .take(map.fluorophores.len())
        .enumerate()
        .map(|(j, wanted)| match names.iter().position(|n| n == wanted) {
            Some(i) => Ok(values[i].clone()),
            None => Err(Error::parse(
                &path,
                0,
                0,
                format!(
                    "no channel {wanted} (the map {} names it for fluorophore {})",
                    json.display(),
                    j + 1
                ),
            )),
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((width, height, maps))
}

/// Pearson correlation of `a` and `b` over the indices where both are finite.
pub fn pearson(a: &[f32], b: &[f32]) -> f64 {
    let (mut n, mut sa, mut sb) = (0.0, 0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        if x.is_finite() && y.is_finite() {
            n += 1.0;
            sa += f64::from(x);
            sb += f64::from(y);
        }
    }
    if n < 2.0 {
        return f64::NAN;
    }
    let (ma, mb) = (sa / n, sb / n);
    let (mut cov, mut va, mut vb) = (0.0, 0.0, 0.0);
    for (&x, &y) in a.iter().zip(b) {
        if x.is_finite() && y.is_finite() {
            let (dx, dy) = (f64::from(x) - ma, f64::from(y) - mb);
            cov += dx * dy;
            va += dx * dx;
            vb += dy * dy;
        }
    }
    if va > 0.0 && vb > 0.0 {
        cov / (va * vb).sqrt()
    } else {
        f64::NAN
    }
}

/// Matches the fluorophores of two material maps by their concentration maps: the
/// Pearson correlation of every pair, then greedily one to one (highest first; NaN
/// correlations last). The maps must have the same size.
pub fn compare_maps(a: &Path, b: &Path) -> Result<MapComparison> {
    let (wa, ha, maps_a) = concentrations(a)?;
    let (wb, hb, maps_b) = concentrations(b)?;
    if (wa, ha) != (wb, hb) {
        return Err(Error::invalid(
            format!("{} and {}", a.display(), b.display()),
            format!(
                "the material maps differ in size ({wa}×{ha} and {wb}×{hb} texels); compare maps of one image size"
            ),
        ));
    }
    let mut pairs: Vec<(usize, usize, f64)> = Vec::new();
    for (i, x) in maps_a.iter().enumerate() {
        for (j, y) in maps_b.iter().enumerate() {
            pairs.push((i, j, pearson(x, y)));
        }
    }
    // Highest correlation first, NaN after every number; ties by index.
    pairs.sort_by(|p, q| {
        let key = |c: f64| if c.is_nan() { f64::NEG_INFINITY } else { c };
        key(q.2)
            .total_cmp(&key(p.2))
            .then(p.0.cmp(&q.0))
            .then(p.1.cmp(&q.1))
    });
    let mut used_a = vec![false; maps_a.len()];
    let mut used_b = vec![false; maps_b.len()];
    let mut matches = Vec::new();
    for (i, j, c) in pairs {
        if !used_a[i] && !used_b[j] {
            used_a[i] = true;
            used_b[j] = true;
            matches.push(MapMatch {
                a: i + 1,
                b: j + 1,
                correlation: c,
            });
        }
    }
    let unmatched = |used: &[bool]| -> Vec<usize> {
        used.iter()
            .enumerate()
            .filter(|(_, u)| !**u)
            .map(|(k, _)| k + 1)
            .collect()
    };
    Ok(MapComparison {
        fluorophores_a: maps_a.len(),
        fluorophores_b: maps_b.len(),
        unmatched_a: unmatched(&used_a),
        unmatched_b: unmatched(&used_b),
        matches,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_interpolate_between_ranks() {
        let v: Vec<f32> = (0..=10).map(|i| i as f32).collect();
        assert_eq!(sorted_quantile(&v, 0.5), 5.0);
        assert!((sorted_quantile(&v, 0.99) - 9.9).abs() < 1e-9);
        assert!(sorted_quantile(&[], 0.5).is_nan());
    }

    #[test]
    fn pearson_skips_non_finite_pairs_and_constant_maps() {
        let a = [1.0, 2.0, 3.0, f32::NAN];
        let b = [2.0, 4.0, 6.0, 1.0];
        assert!((pearson(&a, &b) - 1.0).abs() < 1e-12);
        assert!(pearson(&[1.0, 1.0, 1.0], &b[..3]).is_nan());
    }
}
