//! Fitting samples one by one: a prepared sample, a file, or many in parallel; where the
//! results of a run go.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::fit::{FitOptions, FitOutcome, fit};
use crate::measurement::Measurement;

use super::input::{InputOptions, Prepared, read_input};

/// A file's sample and its fit.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The matrix as fitted (prepared).
    pub measurement: Measurement,
    /// The fit.
    pub outcome: FitOutcome,
}

/// Fits a prepared sample and records in the report what preparing it did.
pub fn fit_prepared(prepared: &Prepared, options: &FitOptions) -> Result<FitOutcome> {
    let mut outcome = fit(&prepared.measurement, options)?;
    if let Some(preprocessing) = &prepared.preprocessing {
        outcome.record_preprocessing(preprocessing.clone());
    }
    Ok(outcome)
}

/// Fits `prepared` `runs` times (at least once) and reports the median time; the fit
/// kept is the first (fits are deterministic).
pub fn fit_timed(prepared: &Prepared, options: &FitOptions, runs: usize) -> Result<FitOutcome> {
    crate::limits::check_runs(runs, "--timing-runs")?;
    let mut outcome = fit_prepared(prepared, options)?;
    if runs > 1 {
        let mut times = vec![outcome.report().seconds];
        for _ in 1..runs {
            times.push(fit(&prepared.measurement, options)?.report().seconds);
        }
        outcome.set_seconds(crate::numeric::median(&times));
    }
    Ok(outcome)
}

/// Reads input `index` of `count` (`path`), prepares it and fits it.
pub fn fit_file(
    path: &Path,
    index: usize,
    count: usize,
    input: &InputOptions,
    options: &FitOptions,
) -> Result<Fitted> {
    fit_file_timed(path, index, count, input, options, 1)
}

/// [`fit_file`] timed over `runs` fits ([`fit_timed`]).
pub fn fit_file_timed(
    path: &Path,
    index: usize,
    count: usize,
    input: &InputOptions,
    options: &FitOptions,
    runs: usize,
) -> Result<Fitted> {
    let prepared = read_input(path, index, count, input)?;
    let outcome = fit_timed(&prepared, options, runs)?;
    Ok(Fitted {
        measurement: prepared.measurement,
        outcome,
    })
}

/// Fits every sample in parallel, on `threads` threads (`None`: one per core), results in
/// input order.
pub fn fit_many(
    samples: &[Prepared],
    options: &FitOptions,
    threads: Option<usize>,
) -> Result<Vec<Result<FitOutcome>>> {
    let fit_all = || -> Vec<Result<FitOutcome>> {
        samples
            .par_iter()
            .map(|s| fit_prepared(s, options))
            .collect()
    };
    match threads {
        None => Ok(fit_all()),
        Some(n) => {
            if n == 0 || n > crate::limits::MAX_THREADS {
                return Err(Error::invalid(
                    "threads",
                    format!(
                        "{n} threads; give 1 to {} (or none: one per core)",
                        crate::limits::MAX_THREADS
                    ),
                ));
            }
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| Error::invalid("threads", format!("cannot start {n} threads: {e}")))?;
            Ok(pool.install(fit_all))
        }
    }
}

/// Where the results of fitting `inputs` go: `output` as the file for a single input, or
/// as a folder (an existing one, or a path ending in `/`) for any number; by default
/// `fits/<input stem>.json`. Two inputs writing one file is an error.
pub fn output_paths(inputs: &[PathBuf], output: Option<&Path>) -> Result<Vec<PathBuf>> {
    let stem = |p: &Path| {
        p.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "material".into())
    };
    let into_folder = |dir: &Path| -> Vec<PathBuf> {
        inputs
            .iter()
            .map(|p| dir.join(format!("{}.json", stem(p))))
            .collect()
    };
    let paths = match output {
        None => into_folder(Path::new("fits")),
        Some(out) => {
            let is_folder = out.is_dir() || out.as_os_str().to_string_lossy().ends_with('/');
            if is_folder {
                into_folder(out)
            } else if inputs.len() == 1 {
                vec![out.to_path_buf()]
            } else {
                return Err(Error::invalid(
                    format!("-o {}", out.display()),
                    "several inputs need an output folder (an existing one, or a path ending in '/')",
                ));
            }
        }
    };
    let mut seen = std::collections::HashSet::new();
    for (p, input) in paths.iter().zip(inputs) {
        if !seen.insert(p.clone()) {
            return Err(Error::invalid(
                "-o",
                format!(
                    "two inputs would write {} (second: {}); rename one or fit them separately",
                    p.display(),
                    input.display()
                ),
            ));
        }
    }
    Ok(paths)
}

/// Creates the folders `paths` go into.
pub fn create_folders(paths: &[PathBuf]) -> Result<()> {
    for out in paths {
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| Error::Io {
                path: dir.to_path_buf(),
                message: format!("cannot create the output folder: {e}"),
            })?;
        }
    }
    Ok(())
}

/// Writes a fit's JSON to `path`, atomically.
pub fn write_outcome(path: &Path, outcome: &FitOutcome) -> Result<()> {
    crate::files::write_atomic(path, outcome.to_json().as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_are_named_after_the_inputs_and_never_collide() {
        let inputs: Vec<PathBuf> = vec!["a/x.csv".into(), "b/y.BFC".into()];
        assert_eq!(
            output_paths(&inputs, None).unwrap(),
            [PathBuf::from("fits/x.json"), PathBuf::from("fits/y.json")]
        );
        assert_eq!(
            output_paths(&inputs, Some(Path::new("out/"))).unwrap(),
            [PathBuf::from("out/x.json"), PathBuf::from("out/y.json")]
        );
        assert_eq!(
            output_paths(&inputs[..1], Some(Path::new("m.json"))).unwrap(),
            [PathBuf::from("m.json")]
        );
        assert!(output_paths(&inputs, Some(Path::new("m.json"))).is_err());
        let twins: Vec<PathBuf> = vec!["a/x.csv".into(), "b/x.csv".into()];
        let message = output_paths(&twins, None).unwrap_err().to_string();
        assert!(
            message.contains("two inputs would write fits/x.json"),
            "{message}"
        );
    }

    #[test]
    fn thread_counts_are_bounded() {
        for threads in [0, crate::limits::MAX_THREADS + 1] {
            let message = fit_many(&[], &FitOptions::default(), Some(threads))
                .unwrap_err()
                .to_string();
            assert!(message.starts_with("threads:"), "{message}");
        }
        assert!(
            fit_many(&[], &FitOptions::default(), Some(2))
                .unwrap()
                .is_empty()
        );
    }
}
