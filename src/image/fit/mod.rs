//! `fluorite fit-image`: a bispectral image into a material map (model.md §8).
//!
//! Three passes read the image (sketch, power step, projection into a scratch file);
//! everything after reads the scratch file: the shared fluorophores for K = 1, 2, … (the
//! smallest K whose fit meets the colour bound on the asked share of pixels, the search's
//! monotone rule), the gauge, and the outputs, each written tile by tile. Every stage's
//! result is kept in the output folder's work folder as it finishes, so a run killed and
//! started again with the same command resumes after its last finished stage and ends
//! with the same files.

// The kernels index several parallel arrays (cells, components, lights) by one index;
// iterator chains over four zipped slices would hide the algebra they follow.
#![allow(clippy::needless_range_loop)]

pub mod band;
pub mod colour;
pub mod gauge;
pub mod gemm;
pub mod nnls;
pub mod outputs;
pub mod passes;
pub mod pixel;
pub mod records;
pub mod scratch;
pub mod shared;
pub mod sketch;
pub mod stages;
pub mod state;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::colour::Light;
use crate::error::{Error, Result};
use crate::image::array::PixelSource;
use crate::image::layout::{Cell, Layout};

pub use gauge::YieldPreference;

use colour::CellColours;
use scratch::{RecordLayout, Scratch};
use shared::{Cells, Shared};
use state::State;

/// Most fluorophores an image fit looks for.
pub const MAX_COMPONENTS: usize = 6;

/// How to fit an image.
#[derive(Debug, Clone)]
pub struct ImageFitOptions {
    /// A fixed number of fluorophores; None chooses the smallest that meets the bound.
    pub components: Option<usize>,
    /// Largest K tried when choosing.
    pub max_components: usize,
    /// ΔE2000 bound per pixel (fitted against measured, every light).
    pub max_delta_e: f64,
    /// Share of (unmasked) pixels that must meet the bound.
    pub share: f64,
    /// Lights the bound is judged under.
    pub lights: Vec<Light>,
    /// Yield form of the fluorophores.
    pub yield_preference: YieldPreference,
    /// Width of the random sketch (basis vectors).
    pub rank: usize,
    /// Power steps sharpening the basis (each one more pass over the image).
    pub power_steps: usize,
    /// Iteration limit of the shared fit over all pixels.
    pub max_iterations: usize,
    /// Relative loss change (of the pixels' energy) at which the shared fit stops.
    pub tolerance: f64,
    /// Pixels the start of each K is fitted on (the extreme ones, then a regular grid).
    pub start_pixels: usize,
    /// Seed of the sketch's random signs.
    pub seed: u64,
    /// ZIP-compress the EXR outputs.
    pub zip: bool,
}

impl Default for ImageFitOptions {
    fn default() -> Self {
        ImageFitOptions {
            components: None,
            max_components: 4,
            max_delta_e: 1.0,
            share: 0.99,
            lights: Light::standard(),
            yield_preference: YieldPreference::Auto,
            rank: 24,
            power_steps: 1,
            max_iterations: 200,
            tolerance: 1e-8,
            start_pixels: 96,
            seed: 1,
            zip: false,
        }
    }
}

impl ImageFitOptions {
    /// Checks the options, naming the flag at fault.
    pub fn validate(&self) -> Result<()> {
        if let Some(k) = self.components
            && !(1..=MAX_COMPONENTS).contains(&k)
        {
            return Err(Error::invalid(
                "--components",
                format!("{k}: give 1 to {MAX_COMPONENTS}"),
            ));
        }
        if !(1..=MAX_COMPONENTS).contains(&self.max_components) {
            return Err(Error::invalid(
                "--max-components",
                format!("{}: give 1 to {MAX_COMPONENTS}", self.max_components),
            ));
        }
        if !(self.max_delta_e.is_finite() && self.max_delta_e > 0.0) {
            return Err(Error::invalid("--max-delta-e", "give a positive ΔE2000"));
        }
        if !(self.share > 0.0 && self.share <= 1.0) {
            return Err(Error::invalid("--share", "give a share in (0, 1]"));
        }
        if self.lights.is_empty() {
            return Err(Error::invalid("--lights", "give at least one light"));
        }
        if self.rank < MAX_COMPONENTS + 2 || self.rank > 256 {
            return Err(Error::invalid(
                "--rank",
                format!("give {} to 256", MAX_COMPONENTS + 2),
            ));
        }
        if self.max_iterations == 0 || self.max_iterations > 100_000 {
            return Err(Error::invalid("--max-iterations", "give 1 to 100000"));
        }
        Ok(())
    }

    /// The options that change results, as text (the resume key).
    fn key(&self) -> String {
        format!(
            "fluorite {} components={:?} max={} bound={} share={} lights={} yield={:?} rank={} power={} iterations={} tolerance={} start={} seed={} zip={}",
            env!("CARGO_PKG_VERSION"),
            self.components,
            self.max_components,
            self.max_delta_e,
            self.share,
            self.lights
                .iter()
                .map(|l| l.name.as_str())
                .collect::<Vec<_>>()
                .join(","),
            self.yield_preference,
            self.rank,
            self.power_steps,
            self.max_iterations,
            self.tolerance,
            self.start_pixels,
            self.seed,
            self.zip
        )
    }
}

/// What a run reports as it goes.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// A stage starts with `total` units of work.
    Stage {
        /// What it does.
        what: String,
        /// Units of work.
        total: usize,
    },
    /// Units done in the current stage.
    Done(usize),
    /// A stage was found finished by an earlier run.
    Resumed(String),
}

/// How one K did against the bound.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trial {
    /// Fluorophores.
    pub components: usize,
    /// Share of unmasked pixels within the bound under every light.
    pub share_within: f64,
    /// Median ΔE2000 per light (fitted against measured), from a sketch of the pixels'
    /// values: within 0.05 % ([`sketch::QuantileSketch`]).
    pub median_delta_e: Vec<f64>,
    /// 99th percentile per light (from the sketch, as the median).
    pub p99_delta_e: Vec<f64>,
    /// Largest per light.
    pub max_delta_e: Vec<f64>,
    /// Residual energy share of the reradiation cells (loss / energy).
    pub residual_share: f64,
    /// Iterations of the shared fit.
    pub iterations: usize,
    /// Whether it converged.
    pub converged: bool,
    /// The shared spectra.
    pub shared: Shared,
}

/// The outcome of an image fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageFit {
    /// The material map written (`material-map.json`).
    pub map_path: PathBuf,
    /// Every file written.
    pub files: Vec<PathBuf>,
    /// Each K tried, in order.
    pub trials: Vec<Trial>,
    /// The K chosen.
    pub components: usize,
    /// Pixels masked for non-finite cells, and those cells.
    pub masked_pixels: usize,
    /// See `masked_pixels`.
    pub non_finite_cells: usize,
    /// Pixels whose material needed clamping.
    pub clamped_pixels: usize,
    /// Lines for the report.
    pub notes: Vec<String>,
    /// Stages an earlier run had finished.
    pub resumed: Vec<String>,
    /// The cell noise σ measured from the image (the energy outside the basis).
    pub noise_sigma: f64,
}

/// The reradiation cells of `layout` as excitation and emission indices.
pub fn cells_of(layout: &Layout) -> Cells {
    let ex = layout.excitation_wavelengths();
    let em = layout.emission_wavelengths();
    let mut excitation = Vec::new();
    let mut emission = Vec::new();
    for c in layout.reradiation() {
        if let Cell::Reradiation(i, o) = *c {
            excitation.push(ex.binary_search(&i).unwrap_or(0));
            emission.push(em.binary_search(&o).unwrap_or(0));
        }
    }
    Cells {
        excitation,
        emission,
        excitation_nm: ex.iter().map(|&i| layout.wavelengths[i]).collect(),
        emission_nm: em.iter().map(|&o| layout.wavelengths[o]).collect(),
    }
}

/// The per-pixel record of a fit with a sketch of `rank` vectors, and the sizes of the
/// work files it keeps (the basis, the scratch file): what a resumed run checks.
fn work_sizes(
    image: PixelSource<'_>,
    options: &ImageFitOptions,
    rank: usize,
) -> (RecordLayout, state::Expected) {
    let layout = image.layout();
    let m = layout.len() - layout.diagonal_count;
    let record = RecordLayout {
        rank,
        diagonal: layout.diagonal_count,
        lights: options.lights.len(),
    };
    let expected = state::Expected {
        basis_bytes: (m * rank * 8) as u64,
        scratch_bytes: (image.pixels() * record.len() * 4) as u64,
    };
    (record, expected)
}

/// The work folder of an output folder.
pub fn work_folder(out: &Path) -> PathBuf {
    out.join(".fluorite-work")
}

/// Fits `image` into a material map in `out` (created if missing).
pub fn fit_image(
    image: PixelSource<'_>,
    out: &Path,
    options: &ImageFitOptions,
    report: &(dyn Fn(Step) + Sync),
) -> Result<ImageFit> {
    options.validate()?;
    if image.layout().diagonal_count == 0 {
        return Err(Error::invalid(
            image.describe(),
            "the image holds reradiation cells only, no diagonal (T.<λ>nm): a material map needs each pixel's reflectance, which only the diagonal measures; include the diagonal channels",
        ));
    }
    if out.is_file() {
        return Err(Error::invalid(
            "-o",
            format!("{} is a file; give a folder", out.display()),
        ));
    }
    let created_out = !out.exists();
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let work = work_folder(out);
    let work_existed = work.exists();
    let result = run(image, out, &work, options, report);
    if let Err(e) = &result {
        // Bad input writes nothing: the work folder is made only once the first pass has
        // read the whole input; one a later pass made for input it then refused goes (an
        // earlier run's folder this run never replaced stays), and so does the output
        // folder this run created, if that leaves it empty.
        if matches!(e, Error::Parse { .. } | Error::Invalid { .. }) && !work_existed {
            let _ = std::fs::remove_dir_all(&work);
        }
        if created_out {
            let _ = std::fs::remove_dir(out);
        }
    }
    result
}

fn run(
    image: PixelSource<'_>,
    out: &Path,
    work: &Path,
    options: &ImageFitOptions,
    report: &(dyn Fn(Step) + Sync),
) -> Result<ImageFit> {
    let layout = &image.layout();
    let m = layout.len() - layout.diagonal_count;
    let rank = options.rank.min(m);
    let colours = CellColours::new(layout, &options.lights);
    let (record, expected) = work_sizes(image, options, rank);
    let mut state = State::open(work, image, &options.key(), expected)?;
    let mut resumed = Vec::new();
    let blocks = image.blocks();

    // Pass 1: the sketch.
    let (mut basis, census) = match state.basis(0)? {
        Some(found) => {
            resumed.push("sketch".to_string());
            report(Step::Resumed("sketch".into()));
            found
        }
        None => {
            report(Step::Stage {
                what: "pass 1 (sketch)".into(),
                total: blocks,
            });
            let (z, census) = passes::sketch(image, rank, options.seed, |d| report(Step::Done(d)))?;
            refuse_all_masked(image, &census)?;
            let basis = passes::orthonormal(&z, m, rank);
            state.save_basis(0, &basis, &census)?;
            (basis, census)
        }
    };
    for step in 1..=options.power_steps {
        basis = match state.basis(step)? {
            Some((b, _)) => {
                resumed.push(format!("power step {step}"));
                report(Step::Resumed(format!("power step {step}")));
                b
            }
            None => {
                report(Step::Stage {
                    what: format!("pass {} (power step)", step + 1),
                    total: blocks,
                });
                let z = passes::power(image, &basis, rank, |d| report(Step::Done(d)))?;
                let b = passes::orthonormal(&z, m, rank);
                state.save_basis(step, &b, &census)?;
                b
            }
        };
    }
    refuse_all_masked(image, &census)?;
    // Pass 3: the projection into the scratch file.
    let scratch_path = state.folder()?.join("scratch.f32");
    let scratch = if state.done("projection") {
        resumed.push("projection".into());
        report(Step::Resumed("projection".into()));
        Scratch::open(&scratch_path, record, image.pixels())?
    } else {
        report(Step::Stage {
            what: format!("pass {} (projection)", options.power_steps + 2),
            total: blocks,
        });
        let scratch = Scratch::create(&scratch_path, record, image.pixels())?;
        passes::projection(image, &basis, &colours, &scratch, |d| report(Step::Done(d)))?;
        scratch.sync()?;
        state.mark("projection")?;
        scratch
    };
    let fit = conclude(
        image, out, options, report, &mut state, &basis, &census, &scratch, None, None, resumed,
    )?;
    state.finish()?;
    Ok(fit)
}

/// Copies every pixel's record into the scratch file it is given.
pub type FillRecords<'a> = Box<dyn FnOnce(&Scratch) -> Result<()> + Send + 'a>;

/// Where [`fit_image_from_records`] finds the pixels' records.
pub enum RecordSource<'a> {
    /// Copied into the run's scratch file by the closure, given the file.
    Fill(FillRecords<'a>),
    /// Kept elsewhere and read when needed: with the passes over the records and the
    /// outputs run elsewhere too, only the start's few pixels are read.
    Fetch(scratch::FetchRecords),
}

/// Fits an image whose passes another process ran (a Dask cluster, `fluorite.dask`):
/// `basis` is the basis after the power steps, `census` the sketch's count of masked
/// pixels, and `records` gives every pixel's record (pass 3's,
/// [`stages::projection_block`]): copied into a scratch file, or fetched when read. The rest is `fit_image`'s: the shared fluorophores
/// for K = 1, 2, …, the gauge and the outputs, written into `out` from the scratch file
/// (kept in `out`'s work folder while it runs). With `mapper`, the passes over the records
/// of the shared fit (its iterations, start and judge of every K, the noise) run there,
/// on the cluster's copy of the same records, with the same results; with `bands` (and
/// uncompressed outputs), the EXR outputs' tiles are written there too
/// ([`band::write_band`]), the PNGs encoded here from the rows it returns. Only `image`'s size,
/// layout and names are used, never its pixels. An earlier run's work folder in `out` is replaced: this run
/// resumes nothing.
#[allow(clippy::too_many_arguments)]
pub fn fit_image_from_records(
    image: PixelSource<'_>,
    out: &Path,
    options: &ImageFitOptions,
    basis: &[f64],
    census: &passes::Census,
    records: RecordSource<'_>,
    mapper: Option<&dyn records::ChunkMapper>,
    bands: Option<&dyn outputs::BandMapper>,
    report: &(dyn Fn(Step) + Sync),
) -> Result<ImageFit> {
    options.validate()?;
    let layout = image.layout();
    let m = layout.len() - layout.diagonal_count;
    let rank = options.rank.min(m);
    if basis.len() != m * rank {
        return Err(Error::invalid(
            "basis",
            format!(
                "{} values for {m} cells × rank {rank} ({} expected)",
                basis.len(),
                m * rank
            ),
        ));
    }
    refuse_all_masked(image, census)?;
    if out.is_file() {
        return Err(Error::invalid(
            "-o",
            format!("{} is a file; give a folder", out.display()),
        ));
    }
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let work = work_folder(out);
    if work.exists() {
        std::fs::remove_dir_all(&work).map_err(|e| Error::io(&work, e))?;
    }
    let (record, expected) = work_sizes(image, options, rank);
    let mut state = State::open(&work, image, &options.key(), expected)?;
    let scratch = match records {
        RecordSource::Fill(fill) => {
            let scratch_path = state.folder()?.join("scratch.f32");
            let scratch = Scratch::create(&scratch_path, record, image.pixels())?;
            fill(&scratch)?;
            scratch
        }
        RecordSource::Fetch(fetch) => Scratch::fetched("records", record, image.pixels(), fetch),
    };
    let fit = conclude(
        image,
        out,
        options,
        report,
        &mut state,
        basis,
        census,
        &scratch,
        mapper,
        bands,
        Vec::new(),
    )?;
    state.finish()?;
    Ok(fit)
}

/// Everything after the projection: the shared fluorophores for K = 1, 2, … (or the K
/// asked for), the gauge and the outputs, from the scratch file.
#[allow(clippy::too_many_arguments)]
fn conclude(
    image: PixelSource<'_>,
    out: &Path,
    options: &ImageFitOptions,
    report: &(dyn Fn(Step) + Sync),
    state: &mut State,
    basis: &[f64],
    census: &passes::Census,
    scratch: &Scratch,
    mapper: Option<&dyn records::ChunkMapper>,
    bands: Option<&dyn outputs::BandMapper>,
    mut resumed: Vec<String>,
) -> Result<ImageFit> {
    let layout = &image.layout();
    let m = layout.len() - layout.diagonal_count;
    let rank = scratch.layout.rank;
    let record = scratch.layout;
    let cells = cells_of(layout);
    let colours = CellColours::new(layout, &options.lights);
    let records = records::Records {
        scratch,
        context: records::RecordContext::new(layout, basis, record, options),
        mapper,
    };
    let sigma = records.noise_sigma(m)?;

    // The shared fluorophores, K = 1, 2, … (or the K asked for).
    let ks: Vec<usize> = match options.components {
        Some(k) => vec![k],
        None => (1..=options.max_components).collect(),
    };
    let mut trials = Vec::new();
    let mut chosen = None;
    let mut extremes: Option<Vec<usize>> = None;
    for &k in &ks {
        let trial = match state.trial(k)? {
            Some(t) => {
                resumed.push(format!("K = {k}"));
                report(Step::Resumed(format!("K = {k}")));
                t
            }
            None => {
                report(Step::Stage {
                    what: format!("K = {k}: shared fluorophores"),
                    total: options.max_iterations,
                });
                if extremes.is_none() {
                    extremes = Some(shared::extreme_pixels(
                        scratch,
                        shared::START_EXTREMES,
                        |directions| records.farthest(directions),
                    )?);
                }
                let start = shared::start(
                    scratch,
                    &cells,
                    basis,
                    extremes.as_deref().unwrap_or(&[]),
                    image.width(),
                    image.height(),
                    k,
                    options.start_pixels,
                )?;
                let fitted = shared::refine(
                    &cells,
                    basis,
                    rank,
                    start,
                    options.max_iterations,
                    options.tolerance,
                    |s| records.scores(s),
                    |i| report(Step::Done(i)),
                )?;
                let fitted = prune(fitted);
                let t = judge(&records, &fitted, sigma)?;
                state.save_trial(&t)?;
                t
            }
        };
        let meets = trial.share_within >= options.share;
        trials.push(trial);
        if meets || options.components.is_some() {
            chosen = Some(trials.len() - 1);
            break;
        }
    }
    let mut notes = Vec::new();
    let chosen = match chosen {
        Some(c) => c,
        None => {
            // None met the bound: the best share, smallest K on ties.
            let best = (0..trials.len())
                .max_by(|&a, &b| {
                    trials[a]
                        .share_within
                        .total_cmp(&trials[b].share_within)
                        .then(b.cmp(&a))
                })
                .unwrap_or(0);
            notes.push(format!(
                "no K up to {} meets ΔE2000 ≤ {} on {:.1} % of the pixels; kept K = {} ({:.1} % within)",
                options.max_components,
                options.max_delta_e,
                100.0 * options.share,
                trials[best].components,
                100.0 * trials[best].share_within
            ));
            best
        }
    };
    notes.push(format!(
        "cell noise σ = {sigma:.2e} (the energy outside the {rank}-vector basis): a pixel also meets the bound where its ΔE2000 is within {} × the RMS ΔE2000 that noise gives its measured colour",
        crate::fit::assess::NOISE_COVERAGE
    ));
    let trial = trials[chosen].clone();
    let gauge = gauge::choose(&trial.shared, &cells, options.yield_preference);
    notes.extend(gauge.description.iter().cloned());
    let model = pixel::PixelModel::new(
        &trial.shared,
        &gauge,
        &cells,
        layout,
        basis,
        record,
        colours.clone(),
        sigma,
    );
    let written = outputs::write_all(
        out, image, scratch, &model, &gauge, &trial, &trials, census, options, state, report,
        &notes, bands,
    )?;
    if census.masked_pixels > 0 {
        notes.push(format!(
            "{} pixel(s) hold non-finite cells ({} cells): masked from the fit, NaN in every map",
            census.masked_pixels, census.non_finite_cells
        ));
    }
    if written.clamped_pixels > 0 {
        notes.push(format!(
            "{} pixel(s) needed clamping (a concentration above 1, Σ c·a above 1, or a reflectance outside [0, 1] by more than 0.01 and more than 3 × the noise of its estimate, σ / (1 − Σ c·a)): their materials conserve energy, their colour error says what it cost",
            written.clamped_pixels,
        ));
    }
    Ok(ImageFit {
        map_path: written.map_path,
        files: written.files,
        trials,
        components: trial.components,
        masked_pixels: census.masked_pixels,
        non_finite_cells: census.non_finite_cells,
        clamped_pixels: written.clamped_pixels,
        notes,
        resumed,
        noise_sigma: sigma,
    })
}

/// An image whose every pixel holds a non-finite cell has nothing to fit.
fn refuse_all_masked(image: PixelSource<'_>, census: &passes::Census) -> Result<()> {
    if census.masked_pixels == image.pixels() {
        return Err(Error::invalid(
            image.describe(),
            format!(
                "every one of its {} pixels holds a non-finite (NaN or infinite) cell: nothing to fit; write finite values",
                image.pixels()
            ),
        ));
    }
    Ok(())
}

/// Drops components the fit left without absorption, emission or any pixel.
fn prune(mut shared: Shared) -> Shared {
    let ni = shared.excitation.len() / shared.k.max(1);
    let no = shared.emission.len() / shared.k.max(1);
    let keep: Vec<usize> = (0..shared.k)
        .filter(|&c| {
            shared.max_scores.get(c).copied().unwrap_or(0.0) > 0.0
                && shared.excitation[c * ni..(c + 1) * ni]
                    .iter()
                    .any(|&v| v > 0.0)
                && shared.emission[c * no..(c + 1) * no]
                    .iter()
                    .any(|&v| v > 0.0)
        })
        .collect();
    if keep.len() == shared.k || keep.is_empty() {
        return shared;
    }
    shared.excitation = keep
        .iter()
        .flat_map(|&c| shared.excitation[c * ni..(c + 1) * ni].to_vec())
        .collect();
    shared.emission = keep
        .iter()
        .flat_map(|&c| shared.emission[c * no..(c + 1) * no].to_vec())
        .collect();
    shared.max_scores = keep.iter().map(|&c| shared.max_scores[c]).collect();
    shared.k = keep.len();
    shared
}

/// Per-pixel ΔE of the fit of `shared` against the measurement: the trial's figures. A
/// pixel meets the bound under a light when its ΔE2000 is within the bound or within
/// what the measured colour's own noise explains (3 × its RMS ΔE76 from cell noise σ, as
/// the single fit's noise-aware bound): fitting beyond that is fitting noise.
fn judge(records: &records::Records<'_>, shared: &Shared, sigma: f64) -> Result<Trial> {
    let (per_light, inside, counted) = records.judge(shared, sigma)?;
    let share_within = inside as f64 / counted.max(1) as f64;
    // From sketches: within 0.05 % of the exact quantiles, the largest exact; memory
    // bounded by the values' range, not by the image (sketch.rs).
    let stat = |q: f64| -> Vec<f64> { per_light.iter().map(|s| s.quantile(q)).collect() };
    Ok(Trial {
        components: shared.k,
        share_within,
        median_delta_e: stat(0.5),
        p99_delta_e: stat(0.99),
        max_delta_e: stat(1.0),
        residual_share: shared.loss / shared.energy.max(f64::MIN_POSITIVE),
        iterations: shared.iterations,
        converged: shared.converged,
        shared: shared.clone(),
    })
}
