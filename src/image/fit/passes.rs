//! The passes over the image file: the three times the measurement is read.
//!
//! 1. Sketch: Z = Σ_p x_p·ω_pᵀ, the reradiation cells of every pixel times a random sign
//!    vector drawn from the pixel's index (so the sketch does not depend on the block
//!    order or the number of threads). Its range holds the image's fluorescence
//!    (randomised range finder, Halko, Martinsson and Tropp 2011).
//! 2. Power step: Z' = Σ_p x_p·(x_pᵀ·Q₁) with Q₁ = orth(Z): sharpens the basis against
//!    the noise floor.
//! 3. Projection: every pixel's reradiation cells as coordinates y = Qᵀx in the basis,
//!    with its energy, its diagonal cells and the colour of its reradiation under each
//!    light, into the scratch file. Everything after reads only the scratch file.

use crate::error::Result;
use crate::numeric::SplitMix64;

use super::colour::CellColours;
use super::scratch::Scratch;
use crate::image::array::PixelSource;
use crate::image::source::PixelBlock;

/// What the sketch pass found besides the sketch.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Census {
    /// Pixels with at least one non-finite cell (masked).
    pub masked_pixels: usize,
    /// Non-finite cells in all.
    pub non_finite_cells: usize,
}

/// Random signs for pixel `p` (±1), `rank` of them.
fn signs(seed: u64, p: usize, rank: usize, out: &mut [f64]) {
    let mut rng = SplitMix64::new(seed ^ (p as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let mut bits = 0u64;
    for (a, o) in out.iter_mut().take(rank).enumerate() {
        if a % 64 == 0 {
            bits = rng.next_u64();
        }
        *o = if bits >> (a % 64) & 1 == 1 { 1.0 } else { -1.0 };
    }
}

/// Whether every cell of a pixel is finite.
fn finite(pixel: &[f32]) -> bool {
    pixel.iter().all(|v| v.is_finite())
}

/// Pass 1: the sketch (m × rank, row-major) and the census of non-finite cells.
pub fn sketch(
    image: PixelSource<'_>,
    rank: usize,
    seed: u64,
    progress: impl FnMut(usize),
) -> Result<(Vec<f64>, Census)> {
    let first = image.layout().diagonal_count;
    let m = image.layout().len() - first;
    let width = image.width();
    let mut z = vec![0.0; m * rank];
    let mut census = Census::default();
    image.pass(
        |block: &PixelBlock| {
            let mut local = vec![0.0; m * rank];
            let mut omega = vec![0.0; rank];
            let mut census = Census::default();
            for q in 0..block.pixel_count() {
                let pixel = block.pixel(q);
                if !finite(pixel) {
                    census.masked_pixels += 1;
                    census.non_finite_cells += pixel.iter().filter(|v| !v.is_finite()).count();
                    continue;
                }
                signs(seed, block.image_index(q, width), rank, &mut omega);
                for (j, &x) in pixel[first..].iter().enumerate() {
                    let x = f64::from(x);
                    if x != 0.0 {
                        let row = &mut local[j * rank..(j + 1) * rank];
                        for (r, w) in row.iter_mut().zip(&omega) {
                            *r += x * w;
                        }
                    }
                }
            }
            Ok((local, census))
        },
        |(local, c)| {
            for (a, b) in z.iter_mut().zip(&local) {
                *a += b;
            }
            census.masked_pixels += c.masked_pixels;
            census.non_finite_cells += c.non_finite_cells;
            Ok(())
        },
        progress,
    )?;
    Ok((z, census))
}

/// Pass 2: Σ_p x_p·(x_pᵀ·basis) for an orthonormal `basis` (m × rank, row-major).
pub fn power(
    image: PixelSource<'_>,
    basis: &[f64],
    rank: usize,
    progress: impl FnMut(usize),
) -> Result<Vec<f64>> {
    let first = image.layout().diagonal_count;
    let m = image.layout().len() - first;
    let mut z = vec![0.0; m * rank];
    image.pass(
        |block: &PixelBlock| {
            let mut local = vec![0.0; m * rank];
            let mut t = vec![0.0; rank];
            for q in 0..block.pixel_count() {
                let pixel = block.pixel(q);
                if !finite(pixel) {
                    continue;
                }
                project(&pixel[first..], basis, rank, &mut t);
                for (j, &x) in pixel[first..].iter().enumerate() {
                    let x = f64::from(x);
                    if x != 0.0 {
                        let row = &mut local[j * rank..(j + 1) * rank];
                        for (r, w) in row.iter_mut().zip(&t) {
                            *r += x * w;
                        }
                    }
                }
            }
            Ok(local)
        },
        |local| {
            for (a, b) in z.iter_mut().zip(&local) {
                *a += b;
            }
            Ok(())
        },
        progress,
    )?;
    Ok(z)
}

/// y = basisᵀ·x.
pub fn project(x: &[f32], basis: &[f64], rank: usize, y: &mut [f64]) {
    y.iter_mut().for_each(|v| *v = 0.0);
    for (j, &v) in x.iter().enumerate() {
        let v = f64::from(v);
        if v != 0.0 {
            for (o, b) in y.iter_mut().zip(&basis[j * rank..(j + 1) * rank]) {
                *o += v * b;
            }
        }
    }
}

/// Pass 3: every pixel's record into `scratch`.
pub fn projection(
    image: PixelSource<'_>,
    basis: &[f64],
    colours: &CellColours,
    scratch: &Scratch,
    progress: impl FnMut(usize),
) -> Result<()> {
    let first = image.layout().diagonal_count;
    let rank = scratch.layout.rank;
    let record = scratch.layout;
    let width = image.width();
    image.pass(
        |block: &PixelBlock| {
            let mut y = vec![0.0; rank];
            let mut row = Vec::with_capacity(block.width * record.len());
            for by in 0..block.height {
                row.clear();
                for bx in 0..block.width {
                    let q = by * block.width + bx;
                    let pixel = block.pixel(q);
                    let start = row.len();
                    row.resize(start + record.len(), 0.0);
                    let out = &mut row[start..];
                    if !finite(pixel) {
                        out[0] = 1.0;
                        continue;
                    }
                    let x = &pixel[first..];
                    project(x, basis, rank, &mut y);
                    out[1] = x.iter().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>() as f32;
                    for (o, v) in out[record.y()].iter_mut().zip(&y) {
                        *o = *v as f32;
                    }
                    out[record.diagonal()].copy_from_slice(&pixel[..first]);
                    for l in 0..record.lights {
                        let xyz = colours.xyz(l, first, x);
                        for (o, v) in out[record.xyz(l)].iter_mut().zip(xyz) {
                            *o = v as f32;
                        }
                    }
                }
                scratch.write(block.image_index(by * block.width, width), &row)?;
            }
            Ok(())
        },
        |()| Ok(()),
        progress,
    )
}

/// An orthonormal basis of the range of `z` (m × rank, row-major), same shape.
pub fn orthonormal(z: &[f64], m: usize, rank: usize) -> Vec<f64> {
    let matrix = nalgebra::DMatrix::from_row_slice(m, rank, z);
    let q = matrix.qr().q();
    let mut out = vec![0.0; m * rank];
    for j in 0..m {
        for a in 0..rank.min(q.ncols()) {
            out[j * rank + a] = q[(j, a)];
        }
    }
    out
}
