//! Running mutants through the library: one mutant ([`Harness::run`]) and a parallel
//! campaign with a watchdog, panic capture and allocation accounting ([`campaign`]).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use fluorite::check::check_material;
use fluorite::colour::Light;
use fluorite::eem::correct::Absorbance;
use fluorite::eem::{EemOptions, prepare};
use fluorite::fit::{FitOptions, FitOutcome, fit};
use fluorite::formats::{ReadOptions, read_bytes};
use fluorite::import::{ImportOptions, ReflectanceSource, SpectrumSource, import_spectra};
use fluorite::numeric::SplitMix64;
use fluorite::render::{RenderSettings, Scene, SceneKind, render};
use fluorite::{Material, Measurement, YieldForm};

use super::alloc;
use super::corpus::{Kind, Seed, corpus, shared_data};
use super::mutate::{Mutant, mutate};

/// Iteration limit of the fits: the default solver and start, refined briefly (a full
/// fit of a shipped example takes 20–40 iterations; mutants are about reaching the
/// solver with odd data, not about converging).
pub const FIT_ITERATIONS: u64 = 25;

/// Everything a mutant needs besides its bytes.
pub struct Harness {
    /// The seeds, in order.
    pub seeds: Vec<Seed>,
    /// Sources left out, with why.
    pub skipped: Vec<String>,
    fit_options: FitOptions,
    render_light: Light,
    /// The EEM an absorbance mutant corrects (staRdom d433sf), when `../shared` is here.
    inner_filter_sample: Option<Measurement>,
}

/// How a mutant ended, when it ended normally.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Ending {
    /// Read (and fitted, checked, rendered) without error.
    Accepted,
    /// Refused with this error message.
    Refused(String),
    /// Accepted, but the material the fit returned breaks its own laws (a defect, not a
    /// refusal: `fit` would write a file `check` rejects), with the law it breaks.
    Invalid(String),
}

impl Default for Harness {
    fn default() -> Self {
        Harness::new()
    }
}

impl Harness {
    /// Loads the corpus and the fixed inputs.
    pub fn new() -> Harness {
        let (seeds, skipped) = corpus();
        let inner_filter_sample = shared_data().map(|d| {
            let path = d.join("eem-instrument/stardom_d433sf.csv");
            fluorite::formats::read(&path, &ReadOptions::default()).expect("stardom_d433sf")
        });
        Harness {
            seeds,
            skipped,
            fit_options: FitOptions {
                max_iterations: FIT_ITERATIONS,
                ..FitOptions::default()
            },
            render_light: Light::parse("d65").expect("built-in light"),
            inner_filter_sample,
        }
    }

    /// The mutant `index` of `seed`'s campaign: which seed file and which edits.
    pub fn mutant(&self, campaign_seed: u64, index: u64) -> (usize, Mutant) {
        let which = (index % self.seeds.len() as u64) as usize;
        let mut rng = SplitMix64::new(
            campaign_seed ^ index.wrapping_mul(0x9e37_79b9_7f4a_7c15).rotate_left(17),
        );
        (which, mutate(&self.seeds[which], &self.seeds, &mut rng))
    }

    /// Runs `bytes` as a file of `seed`'s kind through the library. Kinds read from a
    /// path (material, spectra, absorbance) are written to `scratch` first.
    pub fn run(&self, seed: &Seed, bytes: &[u8], scratch: &Path) -> Ending {
        match self.run_result(seed, bytes, scratch) {
            Ok(None) => Ending::Accepted,
            Ok(Some(broken)) => Ending::Invalid(broken),
            Err(e) => Ending::Refused(e.to_string()),
        }
    }

    /// `Ok(Some(law))` when a fit returned a material that breaks `law`.
    fn run_result(
        &self,
        seed: &Seed,
        bytes: &[u8],
        scratch: &Path,
    ) -> fluorite::Result<Option<String>> {
        let path = scratch.join(&seed.file_name);
        match seed.kind {
            Kind::Matrix => {
                let m = read_bytes(bytes, &path, &ReadOptions::default())?;
                self.prepare_and_fit(m, &EemOptions::default())
            }
            Kind::Material => {
                write(&path, bytes)?;
                let material = Material::load(&path)?;
                let _report = check_material(&material);
                let settings = RenderSettings {
                    width: 8,
                    height: 8,
                    samples_per_pixel: 2,
                    seed: 1,
                };
                let scene = Scene::build(
                    SceneKind::Preview,
                    &material,
                    &self.render_light,
                    true,
                    settings.aspect(),
                )?;
                render(&scene, &settings, &|| {})?;
                Ok(None)
            }
            Kind::Spectra => {
                write(&path, bytes)?;
                let source = |column: &str| SpectrumSource {
                    path: path.clone(),
                    column: Some(column.into()),
                };
                import_spectra(&ImportOptions {
                    name: "fuzz".into(),
                    absorption: source("excitation"),
                    emission: source("emission"),
                    reflectance: ReflectanceSource::Constant(0.5),
                    concentration: 0.5,
                    quantum_yield: 0.5,
                    yield_form: YieldForm::Photon,
                })?;
                Ok(None)
            }
            Kind::Absorbance => {
                write(&path, bytes)?;
                let absorbance = Absorbance::read(&path)?;
                let Some(sample) = &self.inner_filter_sample else {
                    return Ok(None);
                };
                let options = EemOptions {
                    absorbance: Some((absorbance, path)),
                    ..EemOptions::default()
                };
                self.prepare_and_fit(sample.clone(), &options)
            }
        }
    }

    fn prepare_and_fit(
        &self,
        m: Measurement,
        options: &EemOptions,
    ) -> fluorite::Result<Option<String>> {
        let (m, _) = prepare(m, options)?;
        Ok(match fit(&m, &self.fit_options)? {
            // What the fit returns must be a material its own loader accepts; one that is
            // not was counted as a refusal until a dye-free matrix without a measured
            // diagonal came back as a reflector of no sample (seed 20261204 mutant 8322).
            FitOutcome::Material(material) => material.validate().err().map(|e| e.to_string()),
            FitOutcome::Shapes(_) => None,
        })
    }
}

fn write(path: &Path, bytes: &[u8]) -> fluorite::Result<()> {
    std::fs::write(path, bytes).map_err(|e| fluorite::Error::io(path, e))
}

/// A campaign: which mutants, on how many workers, within which budget.
#[derive(Debug, Clone)]
pub struct Campaign {
    /// Seed of the mutator.
    pub seed: u64,
    /// First mutant index.
    pub first: u64,
    /// Number of mutants.
    pub count: u64,
    /// Worker threads.
    pub workers: usize,
    /// Time a mutant may take (read + fit, or load + check + render).
    pub budget: Duration,
    /// Where failing mutants are written.
    pub failures_dir: PathBuf,
    /// Stop after this many failures.
    pub max_failures: usize,
    /// Print progress every this many mutants (0: never).
    pub progress_every: u64,
}

/// What went wrong with a mutant.
#[derive(Debug, Clone)]
pub struct Failure {
    /// The mutation recipe: seed, index, file, edits.
    pub recipe: String,
    /// Panic, hang, over budget, over the allocation bound, or a multi-line error.
    pub what: String,
    /// The mutant, written for replay.
    pub written: PathBuf,
    /// The CLI command that replays it.
    pub replay: String,
}

/// A campaign's figures.
#[derive(Debug, Default)]
pub struct Report {
    /// Mutants run.
    pub mutants: u64,
    /// Accepted (read and fitted).
    pub accepted: u64,
    /// Refused with an error.
    pub refused: u64,
    /// Failures.
    pub failures: Vec<Failure>,
    /// Largest peak of live bytes of one mutant, and its recipe.
    pub peak_bytes: (i64, String),
    /// Slowest mutant: seconds and recipe.
    pub slowest: (f64, String),
    /// Wall time of the campaign, seconds.
    pub seconds: f64,
    /// Refusals whose message does not name the file (examples).
    pub unnamed_errors: Vec<String>,
    /// How many refusals do not name the file.
    pub unnamed_error_count: u64,
    /// Mutants and their summed seconds per kind of seed.
    pub per_kind: Vec<(Kind, u64, f64)>,
}

/// What a mutant's worker thread hands back.
struct Done {
    ending: std::result::Result<Ending, String>,
    seconds: f64,
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(non-string panic payload)".into())
}

fn next_slot() -> Option<usize> {
    static NEXT: AtomicUsize = AtomicUsize::new(1);
    let slot = NEXT.fetch_add(1, Ordering::Relaxed);
    (slot < alloc::MAX_SLOTS).then_some(slot)
}

/// A one-thread rayon pool whose thread counts its allocations against `slot`, so the
/// library's own parallel loops stay on it (and in its accounting).
fn worker_pool(slot: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .thread_name(move |_| format!("fuzz-slot-{slot}"))
        .start_handler(move |_| alloc::enter_slot(slot))
        .build()
        .expect("a fuzz worker thread")
}

/// The CLI command that replays a mutant written at `path`.
pub fn replay_command(kind: Kind, path: &Path) -> String {
    let p = path.display();
    match kind {
        Kind::Matrix => format!("fluorite fit {p} -o /tmp/fuzz-replay.json"),
        Kind::Material => {
            format!(
                "fluorite check {p} && fluorite render {p} --size 8x8 --spp 2 -o /tmp/fuzz-replay.png"
            )
        }
        Kind::Spectra => format!(
            "fluorite import-spectra --absorption {p} --absorption-column excitation --emission-column emission --reflectance 0.5 -c 0.5 --photon-yield 0.5 -o /tmp/fuzz-replay.json"
        ),
        Kind::Absorbance => format!(
            "fluorite fit ../shared/data/eem-instrument/stardom_d433sf.csv --absorbance {p} -o /tmp/fuzz-replay.json"
        ),
    }
}

/// Runs a campaign: mutants `first..first+count`, spread over worker threads, each timed
/// and watched, panics caught, allocations bounded. Failures are written to
/// `failures_dir` with their recipe.
pub fn campaign(harness: &Arc<Harness>, c: &Campaign) -> Report {
    let started = Instant::now();
    let next = AtomicU64::new(c.first);
    let end = c.first + c.count;
    let report = Mutex::new(Report::default());
    let stop = AtomicBool::new(false);
    std::fs::create_dir_all(&c.failures_dir).expect("failures folder");
    std::thread::scope(|scope| {
        for worker in 0..c.workers {
            let (next, report, stop, harness) = (&next, &report, &stop, harness);
            scope.spawn(move || {
                let scratch = c.failures_dir.join(format!("scratch-{worker}"));
                std::fs::create_dir_all(&scratch).expect("scratch folder");
                let Some(mut slot) = next_slot() else { return };
                let mut pool = worker_pool(slot);
                while !stop.load(Ordering::Relaxed) {
                    let index = next.fetch_add(1, Ordering::Relaxed);
                    if index >= end {
                        break;
                    }
                    let (which, mutant) = harness.mutant(c.seed, index);
                    let seed = &harness.seeds[which];
                    let recipe = format!(
                        "seed {} mutant {index}: {} [{:?}]: {}",
                        c.seed,
                        seed.origin,
                        seed.kind,
                        mutant.edits.join("; ")
                    );
                    alloc::begin(slot, recipe.clone());
                    let (tx, rx) = mpsc::channel();
                    let bytes = Arc::new(mutant.bytes);
                    {
                        let (harness, bytes, scratch) =
                            (Arc::clone(harness), Arc::clone(&bytes), scratch.clone());
                        pool.spawn(move || {
                            let t = Instant::now();
                            let ending = catch_unwind(AssertUnwindSafe(|| {
                                harness.run(&harness.seeds[which], &bytes, &scratch)
                            }))
                            .map_err(|p| panic_message(&*p));
                            let _ = tx.send(Done {
                                ending,
                                seconds: t.elapsed().as_secs_f64(),
                            });
                        });
                    }
                    let outcome = rx.recv_timeout(c.budget);
                    let mut failure = None;
                    let mut r = report.lock().unwrap();
                    r.mutants += 1;
                    match outcome {
                        Err(_) => {
                            failure = Some(format!(
                                "HANG: no answer within {:.1} s (the worker thread is abandoned)",
                                c.budget.as_secs_f64()
                            ));
                            // The stuck thread keeps its slot; carry on with a fresh one.
                            match next_slot() {
                                Some(s) => {
                                    slot = s;
                                    pool = worker_pool(slot);
                                }
                                None => stop.store(true, Ordering::Relaxed),
                            }
                        }
                        Ok(done) => {
                            let (peak, refused) = alloc::peak(slot);
                            if peak > r.peak_bytes.0 {
                                r.peak_bytes = (peak, recipe.clone());
                            }
                            match r.per_kind.iter_mut().find(|k| k.0 == seed.kind) {
                                Some(k) => {
                                    k.1 += 1;
                                    k.2 += done.seconds;
                                }
                                None => r.per_kind.push((seed.kind, 1, done.seconds)),
                            }
                            if done.seconds > r.slowest.0 {
                                r.slowest = (done.seconds, recipe.clone());
                            }
                            if refused || peak > alloc::BOUND_BYTES {
                                failure = Some(format!(
                                    "OVER-ALLOCATION: asked for more than {} bytes live",
                                    alloc::BOUND_BYTES
                                ));
                            } else if done.seconds > c.budget.as_secs_f64() {
                                failure = Some(format!(
                                    "SLOW: {:.2} s, over the {:.1} s budget",
                                    done.seconds,
                                    c.budget.as_secs_f64()
                                ));
                            }
                            match done.ending {
                                Err(panic) => failure = Some(format!("PANIC: {panic}")),
                                Ok(Ending::Accepted) => r.accepted += 1,
                                Ok(Ending::Invalid(law)) => {
                                    failure = Some(format!(
                                        "INVALID OUTPUT: accepted, but the material returned breaks its own laws: {law}"
                                    ))
                                }
                                Ok(Ending::Refused(message)) => {
                                    r.refused += 1;
                                    if message.trim().is_empty() || message.contains('\n') {
                                        failure = Some(format!(
                                            "ERROR NOT ONE LINE: {message:?}"
                                        ));
                                    } else if !names_file(&message, seed) {
                                        r.unnamed_error_count += 1;
                                        if r.unnamed_errors.len() < 8 {
                                            r.unnamed_errors.push(format!("{recipe} → {message}"));
                                        }
                                    }
                                }
                            }
                        }
                    }
                    if let Some(what) = failure {
                        let written = c.failures_dir.join(format!(
                            "seed{}-mutant{index}-{}",
                            c.seed, seed.file_name
                        ));
                        let _ = std::fs::write(&written, &*bytes);
                        let replay = replay_command(seed.kind, &written);
                        eprintln!("fuzz: FAILURE: {recipe}\n  {what}\n  written to {}\n  replay: {replay}", written.display());
                        r.failures.push(Failure {
                            recipe,
                            what,
                            written,
                            replay,
                        });
                        if r.failures.len() >= c.max_failures {
                            stop.store(true, Ordering::Relaxed);
                        }
                    }
                    if c.progress_every > 0 && r.mutants % c.progress_every == 0 {
                        eprintln!(
                            "fuzz: {} mutants, {} accepted, {} refused, {} failures, {:.0} s",
                            r.mutants,
                            r.accepted,
                            r.refused,
                            r.failures.len(),
                            started.elapsed().as_secs_f64()
                        );
                    }
                }
            });
        }
    });
    let mut r = report.into_inner().unwrap();
    r.seconds = started.elapsed().as_secs_f64();
    r
}

/// Whether an error message names the file: its name, or the measurement or material
/// name it gives (the file stem).
fn names_file(message: &str, seed: &Seed) -> bool {
    let stem = Path::new(&seed.file_name)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    message.contains(&seed.file_name) || (!stem.is_empty() && message.contains(&stem))
}

/// The report as text: counts, time, peak, slowest, failures with recipes.
pub fn summary(r: &Report) -> String {
    let mut s = format!(
        "{} mutants in {:.1} s: {} accepted, {} refused, {} failures\npeak live bytes of one mutant: {:.1} MiB ({})\nslowest mutant: {:.3} s ({})\nrefusals not naming the file: {}\n",
        r.mutants,
        r.seconds,
        r.accepted,
        r.refused,
        r.failures.len(),
        r.peak_bytes.0 as f64 / (1024.0 * 1024.0),
        r.peak_bytes.1,
        r.slowest.0,
        r.slowest.1,
        r.unnamed_error_count,
    );
    for (kind, n, seconds) in &r.per_kind {
        s.push_str(&format!(
            "  {kind:?}: {n} mutants, mean {:.1} ms\n",
            1000.0 * seconds / *n as f64
        ));
    }
    for e in &r.unnamed_errors {
        s.push_str(&format!("  e.g. {e}\n"));
    }
    for f in &r.failures {
        s.push_str(&format!(
            "FAILURE {}\n  {}\n  written to {}\n  replay: {}\n",
            f.recipe,
            f.what,
            f.written.display(),
            f.replay
        ));
    }
    s
}
