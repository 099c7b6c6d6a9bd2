//! A joint fit of a sample set: which files are samples, and the dispatch to the
//! non-negative PARAFAC of instrument EEMs (one fit per component count) or to the
//! concentration series of radiance-factor surface matrices.

use std::path::{Path, PathBuf};

use crate::colour::Light;
use crate::eem::Preprocessing;
use crate::eem::scatter::{MaskedBand, ScatterOptions, plan};
use crate::error::{Error, Result};
use crate::files::write_files;
use crate::fit::YieldChoice;
use crate::fit::joint::parafac::ParafacOptions;
use crate::fit::joint::reference::{AnalyteMatch, Reference};
use crate::fit::joint::scatter::set_bands;
use crate::fit::joint::{JointFit, JointOptions, fit_joint};
use crate::fit::series::{SeriesFit, SeriesOptions, fit_concentration_series};
use crate::plot::ImageFormat;

use super::input::{InputOptions, Prepared, read_input};

/// What a joint fit is asked for.
#[derive(Debug, Clone)]
pub struct JointRequest {
    /// Component counts of an EEM set, one fit each (empty: [`ParafacOptions`]' default).
    pub components: Vec<usize>,
    /// Emission range kept, nm inclusive (`None`: all).
    pub em_range: Option<(f64, f64)>,
    /// Excitation range kept, nm inclusive (`None`: all).
    pub ex_range: Option<(f64, f64)>,
    /// Skip split-half validation.
    pub no_split_half: bool,
    /// PARAFAC sweeps, or the series' Gauss-Newton iterations.
    pub max_iterations: u64,
    /// Yield form (series of surfaces).
    pub yield_choice: YieldChoice,
    /// Guard around the diagonal in nm (series of surfaces).
    pub guard_nm: Option<f64>,
    /// Lights of the per-file ΔE2000 (series of surfaces).
    pub lights: Vec<Light>,
    /// Time each PARAFAC fit this many times and report the median.
    pub timing_runs: usize,
    /// Known concentrations to match the components with.
    pub reference: Option<Reference>,
    /// Whether an EEM set's fit models the grating's second-order image.
    pub second_order: SecondOrderChoice,
}

/// Whether a joint EEM fit models the grating's second-order image of the emission
/// ([`JointOptions::second_order`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SecondOrderChoice {
    /// When the data hold second-order light: the second-order Rayleigh line stood out
    /// (its width was measured) in at least one sample.
    #[default]
    Auto,
    /// Always (where the emission grid holds an image).
    On,
    /// Never: the effective emission is reported as the component's.
    Off,
}

impl SecondOrderChoice {
    /// The choice for a set whose samples were masked with `reports`' bands: `Auto` is on
    /// when any sample's second-order Rayleigh line stood out in at least 3 excitation
    /// rows (the rows that measure a band's width), i.e. the instrument passes the
    /// grating's second order.
    pub fn resolve<'a>(self, reports: impl IntoIterator<Item = &'a [MaskedBand]>) -> bool {
        match self {
            SecondOrderChoice::On => true,
            SecondOrderChoice::Off => false,
            SecondOrderChoice::Auto => reports.into_iter().flatten().any(|b| {
                b.line == crate::eem::scatter::ScatterLine::Rayleigh2 && b.rows_measured >= 3
            }),
        }
    }
}

impl Default for JointRequest {
    fn default() -> Self {
        JointRequest {
            components: Vec::new(),
            em_range: None,
            ex_range: None,
            no_split_half: false,
            max_iterations: 500,
            yield_choice: YieldChoice::Auto,
            guard_nm: None,
            lights: Light::standard(),
            timing_runs: 1,
            reference: None,
            second_order: SecondOrderChoice::Auto,
        }
    }
}

impl JointRequest {
    /// The component counts fitted.
    pub fn component_counts(&self) -> Vec<usize> {
        if self.components.is_empty() {
            vec![ParafacOptions::default().components]
        } else {
            self.components.clone()
        }
    }
}

/// One PARAFAC fit of an EEM set and, with a reference, each analyte's best component.
#[derive(Debug, Clone)]
pub struct EemFit {
    /// The fit.
    pub fit: JointFit,
    /// Each analyte's best-matching component (with a reference).
    pub matches: Option<Vec<AnalyteMatch>>,
}

/// The result of a joint fit.
#[derive(Debug, Clone)]
pub enum JointOutcome {
    /// Surface matrices of one material at several concentrations.
    Series(Box<SeriesFit>),
    /// Instrument EEMs: one PARAFAC fit per component count, in the order asked.
    Eem(Vec<EemFit>),
}

/// The file stem of `p`, the sample's name.
pub fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The samples among `inputs`: without the files `exclude` names (by stem, any case; each
/// must name one) and without the `reference` file, which a glob may have brought in.
pub fn select_samples(
    inputs: &[PathBuf],
    exclude: &[String],
    reference: Option<&Path>,
) -> Result<Vec<PathBuf>> {
    for name in exclude {
        if !inputs.iter().any(|p| stem(p).eq_ignore_ascii_case(name)) {
            return Err(Error::invalid(
                format!("--exclude {name}"),
                format!(
                    "no input file is named {name} (the names are the file stems, e.g. QAB for QAB.csv)"
                ),
            ));
        }
    }
    let reference = reference.and_then(|r| r.canonicalize().ok());
    Ok(inputs
        .iter()
        .filter(|p| !exclude.iter().any(|n| stem(p).eq_ignore_ascii_case(n)))
        .filter(|p| reference.is_none() || p.canonicalize().ok() != reference)
        .cloned()
        .collect())
}

/// Reads and prepares every sample, as a single fit would.
pub fn read_samples(paths: &[PathBuf], input: &InputOptions) -> Result<Vec<Prepared>> {
    paths
        .iter()
        .enumerate()
        .map(|(index, path)| {
            read_input(path, index, paths.len(), input).map_err(|e| {
                e.context(format!(
                    "joint fit: sample {} (a file that is not a sample can be left out with --exclude {})",
                    path.display(),
                    stem(path)
                ))
            })
        })
        .collect()
}

/// Fits a sample set jointly: instrument EEMs by PARAFAC, surfaces as a concentration
/// series. The samples must all be of one kind.
pub fn fit_samples(samples: &[Prepared], request: &JointRequest) -> Result<JointOutcome> {
    crate::limits::check_runs(request.timing_runs, "--timing-runs")?;
    if samples.is_empty() {
        return Err(Error::invalid(
            "samples",
            "a joint fit needs at least one sample; give the files of the set",
        ));
    }
    let eem = samples.iter().find(|s| s.is_eem());
    let surface = samples.iter().find(|s| !s.is_eem());
    match (eem, surface) {
        (Some(e), Some(s)) => Err(Error::invalid(
            "samples",
            format!(
                "a joint fit needs one kind of matrix: {} is an uncalibrated EEM, {} a radiance-factor surface matrix; fit them separately (or set --units)",
                e.measurement.name, s.measurement.name
            ),
        )),
        (None, _) => fit_series(samples, request).map(|f| JointOutcome::Series(Box::new(f))),
        (Some(_), None) => fit_eem_set(samples, request).map(JointOutcome::Eem),
    }
}

fn fit_series(samples: &[Prepared], request: &JointRequest) -> Result<SeriesFit> {
    let options = SeriesOptions {
        yield_choice: request.yield_choice,
        guard_nm: request.guard_nm,
        max_iterations: request.max_iterations,
        lights: request.lights.clone(),
        ..SeriesOptions::default()
    };
    let surfaces: Vec<_> = samples.iter().map(|s| s.measurement.clone()).collect();
    fit_concentration_series(&surfaces, &options)
}

fn fit_eem_set(samples: &[Prepared], request: &JointRequest) -> Result<Vec<EemFit>> {
    let eems: Vec<_> = samples.iter().map(|s| s.measurement.clone()).collect();
    let max_iterations = usize::try_from(request.max_iterations.max(1)).unwrap_or(usize::MAX);
    let (bands, shift) = set_scatter_bands(samples);
    let second_order = request.second_order.resolve(
        samples
            .iter()
            .filter_map(|s| s.preprocessing.as_ref())
            .map(|p| p.scatter.as_slice()),
    );
    request
        .component_counts()
        .into_iter()
        .map(|k| {
            let mut options = JointOptions {
                parafac: ParafacOptions {
                    components: k,
                    max_iterations,
                    ..ParafacOptions::default()
                },
                em_range: request.em_range,
                ex_range: request.ex_range,
                no_split_half: request.no_split_half,
                second_order,
            };
            let mut fit = fit_joint(&eems, &options)?;
            if request.second_order == SecondOrderChoice::Auto
                && let Some(note) = image_found_nothing(&fit)
            {
                options.second_order = false;
                fit = fit_joint(&eems, &options)?;
                fit.second_order_note = Some(note);
            }
            if request.timing_runs > 1 {
                let quick = JointOptions {
                    no_split_half: true,
                    ..options.clone()
                };
                let mut times = vec![fit.seconds];
                for _ in 1..request.timing_runs {
                    times.push(fit_joint(&eems, &quick)?.seconds);
                }
                fit.seconds = crate::numeric::median(&times);
            }
            fit.check_scatter(&bands, shift);
            let matches = request.reference.as_ref().map(|r| r.best_matches(&fit));
            Ok(EemFit { fit, matches })
        })
        .collect()
}

/// The largest share of a component's signal its second-order image may carry for
/// `--second-order auto` to keep the image: below it, the image explains nothing the
/// plain PARAFAC does not (the line that turned it on was the set's own fluorescence).
pub const AUTO_IMAGE_MIN_SHARE: f64 = 0.02;

/// With the image fitted, why to fit without it: every component's image at most
/// [`AUTO_IMAGE_MIN_SHARE`] of its signal.
fn image_found_nothing(fit: &JointFit) -> Option<String> {
    let image = fit.second_order.as_ref()?;
    let largest = fit
        .components
        .iter()
        .map(|c| c.image_share.unwrap_or(0.0))
        .fold(0.0, f64::max);
    (largest <= AUTO_IMAGE_MIN_SHARE).then(|| {
        format!(
            "--second-order auto: a second-order line stood out, but the fitted image carried at most {:.1} % of any component's signal (largest G {:.3}); fitted without it",
            100.0 * largest,
            image.gain.iter().copied().fold(0.0, f64::max)
        )
    })
}

/// The set's scatter bands (per line the widest any sample was masked with) and Raman
/// shift, to check the components against. With scatter kept, the bands a default
/// masking would have planned on each sample.
fn set_scatter_bands(samples: &[Prepared]) -> (Vec<MaskedBand>, Option<f64>) {
    let reports: Vec<&Preprocessing> = samples
        .iter()
        .filter_map(|s| s.preprocessing.as_ref())
        .collect();
    let shift = reports.iter().find_map(|p| p.raman_shift_cm);
    let masked = set_bands(reports.iter().map(|p| p.scatter.as_slice()));
    if !masked.is_empty() {
        return (masked, shift);
    }
    let planned: Vec<Vec<MaskedBand>> = samples
        .iter()
        .map(|s| plan(&s.measurement, &ScatterOptions::default()))
        .collect();
    (set_bands(planned.iter().map(Vec::as_slice)), shift)
}

impl JointOutcome {
    /// Where the results go when no folder is given: `fits/series` or `fits/joint`.
    pub fn default_output(&self) -> PathBuf {
        match self {
            JointOutcome::Series(_) => PathBuf::from("fits/series"),
            JointOutcome::Eem(_) => PathBuf::from("fits/joint"),
        }
    }

    /// The folder of fit `index` of an EEM set written to `out`: `out` itself for a single
    /// component count, `out/k<K>` for a sweep.
    pub fn folder(&self, out: &Path, components: usize) -> PathBuf {
        match self {
            JointOutcome::Eem(fits) if fits.len() > 1 => out.join(format!("k{components}")),
            _ => out.to_path_buf(),
        }
    }

    /// Writes the results into `out` (created if missing): a series' `series.json` and
    /// one material per file; per EEM fit its model, scores, components and figure.
    /// Returns the written paths.
    pub fn write(&self, out: &Path) -> Result<Vec<PathBuf>> {
        match self {
            JointOutcome::Series(fit) => fit.write(out, "series"),
            JointOutcome::Eem(fits) => {
                let mut written = Vec::new();
                for f in fits {
                    let dir = self.folder(out, f.fit.components.len());
                    std::fs::create_dir_all(&dir).map_err(|e| Error::Io {
                        path: dir.clone(),
                        message: format!("cannot create the output folder: {e}"),
                    })?;
                    let mut files = f.fit.files(&dir);
                    let figure = crate::plot::joint::components(&f.fit, ImageFormat::Png)?;
                    files.push((dir.join("components.png"), figure));
                    write_files(&files)?;
                    written.extend(files.into_iter().map(|(p, _)| p));
                }
                Ok(written)
            }
        }
    }
}
