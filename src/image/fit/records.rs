//! Passes over the per-pixel records: after the projection, the shared fit reads every
//! record dozens of times (each iteration of every K, the start's extreme pixels, the
//! judge of every K, the noise). Each such pass is a [`RecordKernel`] run on every chunk
//! of [`RECORD_CHUNK`] records, whose results come back in chunk order and are folded
//! here. Who runs the chunks does not change the result: the threads of this process
//! over the scratch file, or the workers of a cluster over their copy of the records
//! ([`ChunkMapper`], `fluorite.dask`), each running [`RecordContext::run`] on the same records.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::image::layout::Layout;

use super::ImageFitOptions;
use super::colour::CellColours;
use super::pixel::PixelModel;
use super::scratch::{RecordLayout, Scratch};
use super::shared::{Cells, Projected, Shared, Sums};
use super::sketch::QuantileSketch;

/// Records per chunk of a pass: the unit whose results are folded in order.
pub const RECORD_CHUNK: usize = 4096;

/// The work of one pass, on every chunk of records.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum RecordKernel {
    /// Every unmasked pixel's scores under `shared` and their sums (one iteration of the
    /// shared fit).
    Scores {
        /// The shared spectra.
        shared: Shared,
    },
    /// ΔE2000 per light of the fit of `shared` against each unmasked pixel, and whether the
    /// pixel meets its bound (the judge of a K), at cell noise `sigma`.
    Judge {
        /// The shared spectra.
        shared: Shared,
        /// The cell noise σ.
        sigma: f64,
    },
    /// The unmasked pixel farthest from the span of `directions` (orthonormal, rank each):
    /// one step of the start's extreme pixels.
    Farthest {
        /// The directions picked so far.
        directions: Vec<Vec<f64>>,
    },
    /// The energy of the unmasked pixels outside the basis (the cell noise).
    Outside,
}

/// One chunk's result of a [`RecordKernel`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ChunkResult {
    /// Of [`RecordKernel::Scores`].
    Sums(Sums),
    /// Of [`RecordKernel::Judge`]: per light, a sketch of the unmasked pixels' ΔE2000;
    /// how many of them meet their bound. Its counts add exactly, so results of
    /// consecutive chunks may come folded into the first ([`fold_exact`]).
    Judged {
        /// Per light, the sketch of the pixels' ΔE2000.
        delta_e: Vec<QuantileSketch>,
        /// Unmasked pixels within their bound under every light.
        within: usize,
        /// Unmasked pixels judged.
        judged: usize,
    },
    /// Of [`RecordKernel::Farthest`]: the farthest pixel's squared distance and image
    /// index, none when the chunk has no unmasked pixel.
    Farthest(Option<(f64, usize)>),
    /// Of [`RecordKernel::Outside`]: energy outside the basis and unmasked pixels.
    Outside {
        /// Σ energy outside the basis.
        outside: f64,
        /// Unmasked pixels.
        pixels: usize,
    },
}

/// What every kernel needs beside the records: the same wherever it runs.
pub struct RecordContext<'a> {
    /// The image's cells.
    pub layout: &'a Layout,
    /// Its reradiation cells by excitation and emission.
    pub cells: Cells,
    /// The basis (m × rank, row-major).
    pub basis: &'a [f64],
    /// The records' layout.
    pub record: RecordLayout,
    /// The fit's options (lights, bound, yield preference).
    pub options: &'a ImageFitOptions,
}

impl<'a> RecordContext<'a> {
    /// The context of a fit of an image of `layout`.
    pub fn new(
        layout: &'a Layout,
        basis: &'a [f64],
        record: RecordLayout,
        options: &'a ImageFitOptions,
    ) -> RecordContext<'a> {
        RecordContext {
            layout,
            cells: super::cells_of(layout),
            basis,
            record,
            options,
        }
    }

    /// `kernel` made ready to run on chunks (its models built once).
    pub fn prepare<'k>(&self, kernel: &'k RecordKernel) -> Prepared<'k> {
        match kernel {
            RecordKernel::Scores { shared } => Prepared::Scores(Projected::new(
                shared,
                &self.cells,
                self.basis,
                self.record.rank,
            )),
            RecordKernel::Judge { shared, sigma } => {
                let gauge =
                    super::gauge::choose(shared, &self.cells, self.options.yield_preference);
                Prepared::Judge(Box::new(PixelModel::new(
                    shared,
                    &gauge,
                    &self.cells,
                    self.layout,
                    self.basis,
                    self.record,
                    CellColours::new(self.layout, &self.options.lights),
                    *sigma,
                )))
            }
            RecordKernel::Farthest { directions } => Prepared::Farthest(directions),
            RecordKernel::Outside => Prepared::Outside,
        }
    }

    /// Runs a prepared kernel on the records of pixels `first..` (whole records).
    pub fn run(
        &self,
        prepared: &Prepared<'_>,
        first: usize,
        records: &[f32],
    ) -> Result<ChunkResult> {
        let record = self.record;
        let len = record.len();
        if !records.len().is_multiple_of(len) {
            return Err(Error::invalid(
                "records",
                format!("{} values are not whole records of {len}", records.len()),
            ));
        }
        let unmasked = records
            .chunks_exact(len)
            .enumerate()
            .filter(|(_, r)| r[0] == 0.0);
        Ok(match prepared {
            Prepared::Scores(p) => {
                let (k, rank) = (p.k, record.rank);
                let mut sums = Sums::zero(k, rank);
                for (_, r) in unmasked {
                    let y = &r[record.y()];
                    let s = p.scores(y);
                    let mut gs = 0.0;
                    let mut shs = 0.0;
                    for a in 0..k {
                        sums.max_scores[a] = sums.max_scores[a].max(s[a]);
                        for b in 0..k {
                            sums.sts[a * k + b] += s[a] * s[b];
                            shs += s[a] * p.h[a * k + b] * s[b];
                        }
                        for (t, &v) in y.iter().enumerate() {
                            let v = f64::from(v);
                            sums.sty[a * rank + t] += s[a] * v;
                            gs += s[a] * p.g[t * k + a] * v;
                        }
                    }
                    let energy = f64::from(r[1]);
                    sums.energy += energy;
                    sums.loss += energy - 2.0 * gs + shs;
                }
                ChunkResult::Sums(sums)
            }
            Prepared::Judge(model) => {
                let bound = self.options.max_delta_e;
                let mut delta_e = vec![Vec::new(); self.options.lights.len()];
                let (mut within, mut judged) = (0, 0);
                for (_, r) in unmasked {
                    let fit = model.fit(r);
                    if fit.masked {
                        continue;
                    }
                    let colours = model.colours(r, &fit);
                    for (l, d) in colours.delta_e.iter().enumerate() {
                        delta_e[l].push(*d as f32);
                    }
                    judged += 1;
                    within += usize::from(colours.delta_e.iter().enumerate().all(|(l, d)| {
                        *d <= bound
                            || *d
                                <= crate::fit::assess::NOISE_COVERAGE
                                    * model.noise_delta_e2000(l, colours.measured_xyz[l])
                    }));
                }
                ChunkResult::Judged {
                    delta_e: delta_e.into_iter().map(QuantileSketch::of).collect(),
                    within,
                    judged,
                }
            }
            Prepared::Farthest(directions) => {
                let mut best: Option<(f64, usize)> = None;
                for (q, r) in unmasked {
                    let y = &r[record.y()];
                    let mut norm: f64 = y.iter().map(|&v| f64::from(v).powi(2)).sum();
                    for d in directions.iter() {
                        let dot: f64 = d.iter().zip(y).map(|(a, &b)| a * f64::from(b)).sum();
                        norm -= dot * dot;
                    }
                    if norm > best.map_or(f64::NEG_INFINITY, |(b, _)| b) {
                        best = Some((norm, first + q));
                    }
                }
                ChunkResult::Farthest(best)
            }
            Prepared::Outside => {
                let (mut outside, mut pixels) = (0.0f64, 0usize);
                for (_, r) in unmasked {
                    let inside: f64 = r[record.y()].iter().map(|&v| f64::from(v).powi(2)).sum();
                    outside += (f64::from(r[1]) - inside).max(0.0);
                    pixels += 1;
                }
                ChunkResult::Outside { outside, pixels }
            }
        })
    }
}

/// A kernel made ready ([`RecordContext::prepare`]).
pub enum Prepared<'a> {
    /// Scores.
    Scores(Projected),
    /// Judge.
    Judge(Box<PixelModel>),
    /// Farthest.
    Farthest(&'a [Vec<f64>]),
    /// Outside.
    Outside,
}

/// Runs `kernel` on every chunk of records elsewhere (the workers of a cluster), each
/// chunk with [`RecordContext::run`] on its records, and returns the results in chunk
/// order: `chunks` of them, chunk `i` holding the records of pixels
/// `i·RECORD_CHUNK..(i + 1)·RECORD_CHUNK` (the last fewer).
pub trait ChunkMapper: Sync {
    /// The results of `kernel` on every chunk, in order.
    fn map_chunks(&self, kernel: &RecordKernel, chunks: usize) -> Result<Vec<ChunkResult>>;
}

/// The records of a fit and where their passes run.
pub struct Records<'a> {
    /// The scratch file (read for a few pixels, and by every pass run here).
    pub scratch: &'a Scratch,
    /// What the kernels need.
    pub context: RecordContext<'a>,
    /// Where passes run when not here.
    pub mapper: Option<&'a dyn ChunkMapper>,
}

impl Records<'_> {
    /// Chunks of a pass.
    pub fn chunks(&self) -> usize {
        self.scratch.pixels.div_ceil(RECORD_CHUNK)
    }

    /// `kernel` on every chunk, the results in chunk order.
    pub fn map(&self, kernel: &RecordKernel) -> Result<Vec<ChunkResult>> {
        let chunks = self.chunks();
        if let Some(mapper) = self.mapper {
            let results = mapper.map_chunks(kernel, chunks)?;
            if results.len() != chunks {
                return Err(Error::invalid(
                    "records",
                    format!(
                        "a pass returned {} chunk results for {chunks} chunks",
                        results.len()
                    ),
                ));
            }
            return Ok(results);
        }
        let prepared = self.context.prepare(kernel);
        let pixels = self.scratch.pixels;
        (0..chunks)
            .into_par_iter()
            .map(|chunk| {
                let first = chunk * RECORD_CHUNK;
                let records = self.scratch.read(first, RECORD_CHUNK.min(pixels - first))?;
                self.context.run(&prepared, first, &records)
            })
            .collect()
    }

    /// The sums of [`RecordKernel::Scores`] over every record.
    pub fn scores(&self, shared: &Shared) -> Result<Sums> {
        let mut total = Sums::zero(shared.k, self.context.record.rank);
        for result in self.map(&RecordKernel::Scores {
            shared: spectra(shared),
        })? {
            match result {
                ChunkResult::Sums(s) => total.add(&s),
                _ => return Err(mismatch("Scores")),
            }
        }
        Ok(total)
    }

    /// The farthest unmasked pixel from the span of `directions`.
    pub fn farthest(&self, directions: &[Vec<f64>]) -> Result<Option<(f64, usize)>> {
        let mut winner: Option<(f64, usize)> = None;
        for result in self.map(&RecordKernel::Farthest {
            directions: directions.to_vec(),
        })? {
            match result {
                ChunkResult::Farthest(Some(b)) => {
                    if b.0 > winner.map_or(f64::NEG_INFINITY, |w| w.0) {
                        winner = Some(b);
                    }
                }
                ChunkResult::Farthest(None) => {}
                _ => return Err(mismatch("Farthest")),
            }
        }
        Ok(winner)
    }

    /// The fit of `shared` judged: per light, the sketch of the unmasked pixels' ΔE2000;
    /// how many pixels meet their bound, and how many were judged.
    pub fn judge(
        &self,
        shared: &Shared,
        sigma: f64,
    ) -> Result<(Vec<QuantileSketch>, usize, usize)> {
        let lights = self.context.options.lights.len();
        let mut per_light = vec![QuantileSketch::default(); lights];
        let (mut inside, mut counted) = (0, 0);
        for result in self.map(&RecordKernel::Judge {
            shared: spectra(shared),
            sigma,
        })? {
            match result {
                ChunkResult::Judged {
                    delta_e,
                    within,
                    judged,
                } if delta_e.len() == lights => {
                    counted += judged;
                    inside += within;
                    for (sketch, chunk) in per_light.iter_mut().zip(&delta_e) {
                        sketch.merge(chunk);
                    }
                }
                _ => return Err(mismatch("Judge")),
            }
        }
        Ok((per_light, inside, counted))
    }

    /// The noise σ per reradiation cell, independent of any model: the energy of the
    /// unmasked pixels outside the basis, per dimension outside it (`cells` reradiation
    /// cells per pixel). The basis holds the fluorescence; what it leaves is noise.
    pub fn noise_sigma(&self, cells: usize) -> Result<f64> {
        let (mut outside, mut pixels) = (0.0f64, 0usize);
        for result in self.map(&RecordKernel::Outside)? {
            match result {
                ChunkResult::Outside {
                    outside: o,
                    pixels: p,
                } => {
                    outside += o;
                    pixels += p;
                }
                _ => return Err(mismatch("Outside")),
            }
        }
        let dimensions = (cells.saturating_sub(self.context.record.rank)).max(1) * pixels.max(1);
        Ok((outside / dimensions as f64).sqrt())
    }
}

/// Folds into the first of `results` (consecutive chunks' results of one kernel) those
/// whose fold is exact, leaving the others empty: the judge's counts and sketches. A
/// worker sends one judge result for all its chunks instead of one per chunk, and the
/// fit's figures are the same. Other kernels' results (sums of floating-point numbers,
/// folded in chunk order) are left as they are.
pub fn fold_exact(results: &mut [ChunkResult]) {
    let Some((first, rest)) = results.split_first_mut() else {
        return;
    };
    let ChunkResult::Judged {
        delta_e,
        within,
        judged,
    } = first
    else {
        return;
    };
    for result in rest {
        if let ChunkResult::Judged {
            delta_e: other,
            within: w,
            judged: j,
        } = result
            && other.len() == delta_e.len()
        {
            for (sketch, chunk) in delta_e.iter_mut().zip(other.iter()) {
                sketch.merge(chunk);
            }
            *within += std::mem::take(w);
            *judged += std::mem::take(j);
            other
                .iter_mut()
                .for_each(|s| *s = QuantileSketch::default());
        }
    }
}

/// What a kernel needs of `shared`: its spectra and largest scores. The fit's figures
/// stay behind (the start's loss is infinite, which a kernel sent as JSON cannot hold).
fn spectra(shared: &Shared) -> Shared {
    Shared {
        loss: 0.0,
        energy: 0.0,
        iterations: 0,
        converged: false,
        ..shared.clone()
    }
}

fn mismatch(kernel: &str) -> Error {
    Error::invalid(
        "records",
        format!("a pass of {kernel} returned another kernel's results"),
    )
}
