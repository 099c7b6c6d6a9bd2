//! The per-block work of the passes over an image, shared by `fit-image`'s own passes
//! ([`super::passes`], a rayon loop over the image's blocks) and by a distributed run
//! (the Python package's `fluorite.dask`, which maps the same functions over chunks of
//! blocks on a Dask cluster and sums their contributions in block order).
//!
//! A block is a [`PlanarBlock`]: its pixels' cells stored plane by plane (f32), the
//! image's canonical blocks being the file's chunks for a bispectral EXR and bands of
//! [`ROWS_PER_BLOCK`] rows for an image in memory. Each function takes one block and
//! returns its contribution; summing the contributions in block order into f64 (as
//! [`accumulate`] does) gives the pass's result, whatever process computed each block.

use crate::numeric::SplitMix64;

use super::colour::CellColours;
use super::gauge;
use super::gemm::{View, multiply};
use super::pixel::PixelModel;
use super::scratch::RecordLayout;
use super::shared::Shared;
use super::{ImageFitOptions, cells_of};
use crate::image::layout::Layout;
use crate::image::source::PlanarBlock;

pub use crate::image::array::ROWS_PER_BLOCK;

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
pub fn mask(block: &mut PlanarBlock) -> Vec<usize> {
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

/// The block's reradiation cells (those after the `first` diagonal ones) as a pixels ×
/// cells matrix (column-major, no copy).
fn reradiation(block: &PlanarBlock, first: usize) -> View<'_> {
    let n = block.pixel_count();
    View::column_major(&block.planes[first * n..], n, block.cells - first)
}

/// A row-major m × r f64 matrix in f32.
pub fn as_f32(values: &[f64]) -> Vec<f32> {
    values.iter().map(|&v| v as f32).collect()
}

/// Adds a block's f32 contribution into the pass's f64 sum (in block order).
pub fn accumulate(total: &mut [f64], part: &[f32]) {
    for (t, p) in total.iter_mut().zip(part) {
        *t += f64::from(*p);
    }
}

/// Pass 1 on one block: Σ_p x_p·ω_pᵀ over its unmasked pixels (m × `rank`, row-major,
/// m the reradiation cells after the `first` diagonal ones), and its census of
/// non-finite cells. `image_width` places the block's pixels in the image (their signs
/// are drawn from their index there).
pub fn sketch_block(
    mut block: PlanarBlock,
    first: usize,
    rank: usize,
    seed: u64,
    image_width: usize,
) -> (Vec<f32>, Census) {
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
            block.image_index(q, image_width),
            rank,
            &mut omega[q * rank..(q + 1) * rank],
        );
    }
    let local = multiply(
        reradiation(&block, first).t(),
        View::row_major(&omega, n, rank),
    );
    (local, census)
}

/// Pass 2 on one block: Σ_p x_p·(x_pᵀ·Q) for `q` the basis in f32 ([`as_f32`]; m ×
/// `rank`, row-major).
pub fn power_block(mut block: PlanarBlock, first: usize, q: &[f32], rank: usize) -> Vec<f32> {
    mask(&mut block);
    let n = block.pixel_count();
    let m = block.cells - first;
    let x = reradiation(&block, first);
    let t = multiply(x, View::row_major(q, m, rank));
    multiply(x.t(), View::row_major(&t, n, rank))
}

/// The matrix pass 3 multiplies every block by: [basis | the reradiation cells' XYZ
/// weights per light], m × (rank + 3·lights), row-major, so one product gives both.
pub fn projection_matrix(
    basis: &[f64],
    colours: &CellColours,
    first: usize,
    m: usize,
    rank: usize,
) -> Vec<f32> {
    let lights = colours.weights.len();
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
    both
}

/// Pass 3 on one block: its pixels' records ([`RecordLayout`]), pixel after pixel in
/// the block's row-major order, for `both` the [`projection_matrix`].
pub fn projection_block(
    mut block: PlanarBlock,
    first: usize,
    both: &[f32],
    record: RecordLayout,
) -> Vec<f32> {
    let masked = mask(&mut block);
    let n = block.pixel_count();
    let m = block.cells - first;
    let rank = record.rank;
    let columns = rank + 3 * record.lights;
    let product = multiply(
        reradiation(&block, first),
        View::row_major(both, m, columns),
    );
    let mut energy = vec![0f64; n];
    for plane in block.planes[first * n..].chunks_exact(n) {
        for (e, &v) in energy.iter_mut().zip(plane) {
            *e += f64::from(v) * f64::from(v);
        }
    }
    let len = record.len();
    let mut records = vec![0f32; n * len];
    for (q, out) in records.chunks_exact_mut(len).enumerate() {
        if masked[q] > 0 {
            out[0] = 1.0;
            continue;
        }
        out[1] = energy[q] as f32;
        out[record.y()].copy_from_slice(&product[q * columns..q * columns + rank]);
        for (d, o) in out[record.diagonal()].iter_mut().enumerate() {
            *o = block.planes[d * n + q];
        }
        out[2 + rank + first..].copy_from_slice(&product[q * columns + rank..(q + 1) * columns]);
    }
    records
}

/// Rows `y..y + values.len() / (width · cells)` of an image in memory (pixel-major, the
/// layout's canonical cell order) as the blocks a pass over the whole image reads there:
/// bands of [`ROWS_PER_BLOCK`] rows, `y` a multiple of it.
pub fn row_blocks(values: &[f32], y: usize, width: usize, cells: usize) -> Vec<PlanarBlock> {
    let rows = values.len() / (width * cells).max(1);
    (0..rows.div_ceil(ROWS_PER_BLOCK))
        .map(|b| {
            let top = b * ROWS_PER_BLOCK;
            let height = ROWS_PER_BLOCK.min(rows - top);
            let n = width * height;
            let pixels = &values[top * width * cells..(top + height) * width * cells];
            let mut planes = vec![0f32; n * cells];
            for q in 0..n {
                for (c, &v) in pixels[q * cells..(q + 1) * cells].iter().enumerate() {
                    planes[c * n + q] = v;
                }
            }
            PlanarBlock {
                x: 0,
                y: y + top,
                width,
                height,
                cells,
                planes,
            }
        })
        .collect()
}

/// The model every pixel of a fit is evaluated with (its material, its colours), as
/// `fit-image` makes it for its outputs: the shared spectra of the chosen K under the
/// gauge `options` ask for, on `basis` (m × rank) at cell noise `sigma`.
pub fn pixel_model(
    layout: &Layout,
    options: &ImageFitOptions,
    shared: &Shared,
    basis: &[f64],
    record: RecordLayout,
    sigma: f64,
) -> PixelModel {
    let cells = cells_of(layout);
    let gauge = gauge::choose(shared, &cells, options.yield_preference);
    let colours = CellColours::new(layout, &options.lights);
    PixelModel::new(
        shared, &gauge, &cells, layout, basis, record, colours, sigma,
    )
}
