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

use super::colour::CellColours;
use super::scratch::Scratch;
pub use super::stages::Census;
use super::stages::{
    accumulate, as_f32, power_block, projection_block, projection_matrix, sketch_block,
};
use crate::image::array::PixelSource;
use crate::image::source::PlanarBlock;

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
        |block: PlanarBlock| Ok(sketch_block(block, first, rank, seed, width)),
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
        |block: PlanarBlock| Ok(power_block(block, first, &q, rank)),
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
    let both = projection_matrix(basis, colours, first, m, rank);
    let len = record.len();
    image.pass_planar(
        |block: PlanarBlock| {
            let (x, y, w, h) = (block.x, block.y, block.width, block.height);
            let records = projection_block(block, first, &both, record);
            for (by, row) in records.chunks_exact(w * len).enumerate().take(h) {
                scratch.write((y + by) * width + x, row)?;
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
