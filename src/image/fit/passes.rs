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
use crate::image::source::PlanarBlock;

use super::gemm::{View, multiply};

/// What the sketch pass found besides the sketch.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Census {
    /// Pixels with at least one non-finite cell (masked).
    pub masked_pixels: usize,
    /// Non-finite cells in all.
    pub non_finite_cells: usize,
}

/// Random signs for pixel `p` (±1), `rank` of them.
fn signs(seed: u64, p: usize, rank: usize, out: &mut [f32]) {
    let mut rng = SplitMix64::new(seed ^ (p as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let mut bits = 0u64;
    for (a, o) in out.iter_mut().take(rank).enumerate() {
        if a % 64 == 0 {
            bits = rng.next_u64();
        }
        *o = if bits >> (a % 64) & 1 == 1 { 1.0 } else { -1.0 };
    }
}

/// Masks the block's pixels holding a non-finite cell: their cells become zero (so the
/// products skip them); returns each pixel's count of non-finite cells (0: not masked).
fn mask(block: &mut PlanarBlock) -> Vec<usize> {
    let n = block.pixel_count();
    let mut bad = vec![0usize; n];
    for plane in block.planes.chunks_exact(n) {
        for (m, v) in bad.iter_mut().zip(plane) {
            *m += usize::from(!v.is_finite());
        }
    }
    if bad.iter().any(|&m| m > 0) {
        for plane in block.planes.chunks_exact_mut(n) {
            for (v, &m) in plane.iter_mut().zip(&bad) {
                if m > 0 {
                    *v = 0.0;
                }
            }
        }
    }
    bad
}

/// The block's reradiation cells as a pixels × cells matrix (column-major, no copy).
fn reradiation(block: &PlanarBlock, first: usize) -> View<'_> {
    let n = block.pixel_count();
    View::column_major(&block.planes[first * n..], n, block.cells - first)
}

/// A row-major m × r f64 matrix in f32.
fn as_f32(values: &[f64]) -> Vec<f32> {
    values.iter().map(|&v| v as f32).collect()
}

/// Adds an f32 product into an f64 accumulator.
fn accumulate(total: &mut [f64], part: &[f32]) {
    for (t, p) in total.iter_mut().zip(part) {
        *t += f64::from(*p);
    }
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
    image.pass_planar(
        |mut block: PlanarBlock| {
            let n = block.pixel_count();
            let mut census = Census::default();
            let bad = mask(&mut block);
            let mut omega = vec![0f32; n * rank];
            for q in 0..n {
                if bad[q] > 0 {
                    census.masked_pixels += 1;
                    census.non_finite_cells += bad[q];
                    continue;
                }
                signs(
                    seed,
                    block.image_index(q, width),
                    rank,
                    &mut omega[q * rank..(q + 1) * rank],
                );
            }
            let local = multiply(
                reradiation(&block, first).t(),
                View::row_major(&omega, n, rank),
            );
            Ok((local, census))
        },
        |(local, c)| {
            accumulate(&mut z, &local);
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
    let q = as_f32(basis);
    let mut z = vec![0.0; m * rank];
    image.pass_planar(
        |mut block: PlanarBlock| {
            mask(&mut block);
            let n = block.pixel_count();
            let x = reradiation(&block, first);
            let t = multiply(x, View::row_major(&q, m, rank));
            Ok(multiply(x.t(), View::row_major(&t, n, rank)))
        },
        |local| {
            accumulate(&mut z, &local);
            Ok(())
        },
        progress,
    )?;
    Ok(z)
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
    let m = image.layout().len() - first;
    let rank = scratch.layout.rank;
    let record = scratch.layout;
    let width = image.width();
    let lights = record.lights;
    // [basis | the reradiation cells' XYZ weights per light], row-major: one product
    // gives both.
    let columns = rank + 3 * lights;
    let mut both = vec![0f32; m * columns];
    for j in 0..m {
        for a in 0..rank {
            both[j * columns + a] = basis[j * rank + a] as f32;
        }
        for l in 0..lights {
            for t in 0..3 {
                both[j * columns + rank + 3 * l + t] = colours.weights[l][first + j][t] as f32;
            }
        }
    }
    image.pass_planar(
        |mut block: PlanarBlock| {
            let masked = mask(&mut block);
            let n = block.pixel_count();
            let product = multiply(
                reradiation(&block, first),
                View::row_major(&both, m, columns),
            );
            let mut energy = vec![0f64; n];
            for plane in block.planes[first * n..].chunks_exact(n) {
                for (e, &v) in energy.iter_mut().zip(plane) {
                    *e += f64::from(v) * f64::from(v);
                }
            }
            let mut row = Vec::with_capacity(block.width * record.len());
            for by in 0..block.height {
                row.clear();
                for bx in 0..block.width {
                    let q = by * block.width + bx;
                    let start = row.len();
                    row.resize(start + record.len(), 0.0);
                    let out = &mut row[start..];
                    if masked[q] > 0 {
                        out[0] = 1.0;
                        continue;
                    }
                    out[1] = energy[q] as f32;
                    out[record.y()].copy_from_slice(&product[q * columns..q * columns + rank]);
                    for (d, o) in out[record.diagonal()].iter_mut().enumerate() {
                        *o = block.planes[d * n + q];
                    }
                    out[2 + rank + first..]
                        .copy_from_slice(&product[q * columns + rank..(q + 1) * columns]);
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
