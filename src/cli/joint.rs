//! `fluorite fit FILES... --joint --components K`: one joint fit of a sample set.
//! EEMs (uncalibrated solution matrices) get a non-negative PARAFAC
//! ([`fluorite::fit::joint`]); radiance-factor surface matrices of one material at
//! several concentrations go to [`run_surface_series`].

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use fluorite::eem::UnitsChoice;
use fluorite::files::write_files;
use fluorite::fit::joint::parafac::ParafacOptions;
use fluorite::fit::joint::reference::Reference;
use fluorite::fit::joint::{JointOptions, fit_joint};
use fluorite::formats::ReadOptions;
use fluorite::measurement::Measurement;
use fluorite::plot::ImageFormat;

use crate::cli::eem::EemArgs;
use crate::cli::printer;

/// The joint-fit options of `fluorite fit`.
#[derive(clap::Args, Debug, Clone)]
pub struct JointArgs {
    /// Fit all inputs jointly: shapes shared by every file, one score per file and
    /// component (EEMs: non-negative PARAFAC). Writes a folder (-o, default fits/joint/).
    #[arg(long)]
    pub joint: bool,
    /// Components of a joint fit: `4` (the default), a list `2,3,4,5` or a range `1..6`
    /// (a sweep reports explained variance, core consistency and split-half per K).
    #[arg(long, value_parser = parse_components, requires = "joint")]
    pub components: Option<ComponentList>,
    /// Emission range of a joint fit, `LO:HI` nm (inclusive).
    #[arg(long, value_parser = parse_range, requires = "joint")]
    pub em_range: Option<NmRange>,
    /// Excitation range of a joint fit, `LO:HI` nm (inclusive).
    #[arg(long, value_parser = parse_range, requires = "joint")]
    pub ex_range: Option<NmRange>,
    /// Samples (file stems) to leave out of a joint fit, comma-separated.
    #[arg(long, value_delimiter = ',', requires = "joint")]
    pub exclude: Vec<String>,
    /// Known concentrations (CSV: sample name, then one column per analyte): print each
    /// analyte's best-matching component and its R² (squared Pearson correlation). The
    /// file is left out of the inputs if a glob brought it in.
    #[arg(long, requires = "joint")]
    pub reference: Option<PathBuf>,
    /// Skip split-half validation in a joint fit.
    #[arg(long, requires = "joint")]
    pub no_split_half: bool,
}

/// What a joint fit takes from `fit`'s arguments (`fit` builds it, so this file needs
/// nothing of `fit`'s).
pub struct JointRun<'a> {
    /// The sample files.
    pub inputs: &'a [PathBuf],
    /// `-o`: the output folder.
    pub output: Option<PathBuf>,
    /// The joint-fit flags.
    pub joint: &'a JointArgs,
    /// The raw-EEM flags, applied per file as `fit` does.
    pub eem: &'a EemArgs,
    /// `--yield` (series of surfaces).
    pub yield_choice: fluorite::fit::YieldChoice,
    /// `--guard` (series of surfaces).
    pub guard_nm: Option<f64>,
    /// `--max-iterations`: PARAFAC sweeps, or the series' Gauss-Newton.
    pub max_iterations: u64,
    /// `--lights` (series of surfaces).
    pub lights: Vec<fluorite::colour::Light>,
    /// `--timing-runs`.
    pub timing_runs: usize,
    /// `--table`.
    pub table: bool,
    /// `-q`.
    pub quiet: bool,
}

/// Component counts to fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentList(pub Vec<usize>);

/// A wavelength range in nm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NmRange(pub f64, pub f64);

fn parse_components(text: &str) -> Result<ComponentList, String> {
    let bad = || format!("{text:?}: give a count (4), a list (2,3,4,5) or a range (1..6)");
    let max = fluorite::fit::joint::parafac::MAX_COMPONENTS;
    let out_of_range = || format!("{text:?}: components must be 1 to {max}");
    let within = |k: usize| (1..=max).contains(&k);
    let list: Vec<usize> = if let Some((lo, hi)) = text.split_once("..") {
        let lo: usize = lo.trim().parse().map_err(|_| bad())?;
        let hi: usize = hi
            .trim()
            .trim_start_matches('=')
            .parse()
            .map_err(|_| bad())?;
        // Checked before the range is built: `1..4000000000` must not allocate.
        if !(within(lo) && within(hi)) {
            return Err(out_of_range());
        }
        (lo..=hi).collect()
    } else {
        text.split(',')
            .map(|c| c.trim().parse::<usize>().map_err(|_| bad()))
            .collect::<Result<_, _>>()?
    };
    if list.is_empty() || !list.iter().all(|&k| within(k)) {
        return Err(out_of_range());
    }
    Ok(ComponentList(list))
}

fn parse_range(text: &str) -> Result<NmRange, String> {
    let (lo, hi) = text
        .split_once(':')
        .ok_or_else(|| format!("{text:?}: give LO:HI in nm, e.g. 250:681"))?;
    let lo: f64 = lo
        .trim()
        .parse()
        .map_err(|_| format!("{text:?}: LO is not a number"))?;
    let hi: f64 = hi
        .trim()
        .parse()
        .map_err(|_| format!("{text:?}: HI is not a number"))?;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return Err(format!("{text:?}: LO must be below HI"));
    }
    Ok(NmRange(lo, hi))
}

fn stem(p: &Path) -> String {
    p.file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Runs a joint fit of `args.inputs` (`fit --joint`).
pub fn run(args: &JointRun, read_options: &ReadOptions) -> anyhow::Result<ExitCode> {
    let joint = args.joint;
    for name in &joint.exclude {
        if !args
            .inputs
            .iter()
            .any(|p| stem(p).eq_ignore_ascii_case(name))
        {
            anyhow::bail!(
                "--exclude {name}: no input file is named {name} (the names are the file stems, e.g. QAB for QAB.csv)"
            );
        }
    }
    // `fit dir/*.csv --reference dir/concentrations.csv` must not read the reference as
    // a sample.
    let reference = joint.reference.as_ref().and_then(|r| r.canonicalize().ok());
    let inputs: Vec<&PathBuf> = args
        .inputs
        .iter()
        .filter(|p| {
            !joint
                .exclude
                .iter()
                .any(|n| stem(p).eq_ignore_ascii_case(n))
        })
        .filter(|p| reference.is_none() || p.canonicalize().ok() != reference)
        .collect();
    let mut eems = Vec::new();
    let mut surfaces = Vec::new();
    for (index, input) in inputs.iter().enumerate() {
        let eem = args.eem.options(index, inputs.len(), read_options)?;
        let (m, preprocessing) = crate::cli::eem::read_prepared(input, &eem, read_options)
            .with_context(|| {
                format!(
                    "joint fit: sample {} (a file that is not a sample can be left out with --exclude {})",
                    input.display(),
                    stem(input)
                )
            })?;
        match preprocessing {
            Some(_) => eems.push(m),
            None => surfaces.push(m),
        }
    }
    if !surfaces.is_empty() {
        if let (Some(e), Some(s)) = (eems.first(), surfaces.first()) {
            anyhow::bail!(
                "a joint fit needs one kind of matrix: {} is an uncalibrated EEM, {} a radiance-factor surface matrix; fit them separately (or set --units)",
                e.name,
                s.name
            );
        }
        return run_surface_series(args, &surfaces);
    }
    run_eem_set(args, &eems)
}

/// Joint fit of radiance-factor surface matrices of one material at several
/// concentrations (shared r, a, e and yield; c per file).
pub fn run_surface_series(args: &JointRun, surfaces: &[Measurement]) -> anyhow::Result<ExitCode> {
    let options = fluorite::fit::series::SeriesOptions {
        yield_choice: args.yield_choice,
        guard_nm: args.guard_nm,
        max_iterations: args.max_iterations,
        lights: args.lights.clone(),
        ..Default::default()
    };
    let fit = fluorite::fit::series::fit_concentration_series(surfaces, &options)?;
    let out = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from("fits/series"));
    let written = fit.write(&out, "series")?;
    if !args.quiet {
        print!("{}", crate::cli::printer::series_summary(&fit));
        for path in &written {
            println!("wrote {}", path.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Joint PARAFAC of a set of prepared EEMs, for each requested K.
fn run_eem_set(args: &JointRun, eems: &[Measurement]) -> anyhow::Result<ExitCode> {
    let joint = args.joint;
    let ks = joint
        .components
        .clone()
        .map(|c| c.0)
        .unwrap_or_else(|| vec![ParafacOptions::default().components]);
    let out = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from("fits/joint"));
    let reference = joint
        .reference
        .as_ref()
        .map(|p| Reference::read(p))
        .transpose()?;
    if !args.quiet {
        println!(
            "joint fit of {} EEMs ({}), {} and units {} per file as `fit` does",
            eems.len(),
            eems.iter()
                .map(|m| m.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            if args.eem.keep_scatter {
                "scatter kept"
            } else {
                "scatter masked"
            },
            match args.eem.units {
                UnitsChoice::Auto => "inferred",
                UnitsChoice::RadianceFactor | UnitsChoice::Arbitrary | UnitsChoice::Percent => {
                    "as --units says"
                }
            }
        );
    }
    let mut rows = Vec::new();
    for &k in &ks {
        let options = JointOptions {
            parafac: ParafacOptions {
                components: k,
                max_iterations: args.max_iterations.max(1) as usize,
                ..ParafacOptions::default()
            },
            em_range: joint.em_range.map(|r| (r.0, r.1)),
            ex_range: joint.ex_range.map(|r| (r.0, r.1)),
            no_split_half: joint.no_split_half,
        };
        let mut fit = fit_joint(eems, &options)?;
        if args.timing_runs > 1 {
            let quick = JointOptions {
                no_split_half: true,
                ..options.clone()
            };
            let mut times = vec![fit.seconds];
            for _ in 1..args.timing_runs {
                times.push(fit_joint(eems, &quick)?.seconds);
            }
            fit.seconds = fluorite::numeric::median(&times);
        }
        let dir = if ks.len() > 1 {
            out.join(format!("k{k}"))
        } else {
            out.clone()
        };
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let mut files = fit.files(&dir);
        let figure = fluorite::plot::joint::components(&fit, ImageFormat::Png)?;
        files.push((dir.join("components.png"), figure));
        write_files(&files)?;
        let matches = reference.as_ref().map(|r| r.best_matches(&fit));
        if !args.quiet {
            print!("{}", printer::joint_summary(&fit, &dir, matches.as_deref()));
        }
        rows.push(printer::joint_sweep_row(&fit, matches.as_deref()));
    }
    if ks.len() > 1 || args.table {
        let table = printer::joint_sweep_table(&rows, reference.as_ref());
        print!("{table}");
        std::fs::create_dir_all(&out)?;
        fluorite::files::write_atomic(&out.join("sweep.md"), table.as_bytes())?;
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn component_lists_are_bounded_before_they_are_built() {
        assert_eq!(parse_components("2..4").unwrap().0, [2, 3, 4]);
        assert_eq!(parse_components("1..=2").unwrap().0, [1, 2]);
        assert_eq!(parse_components("3,5").unwrap().0, [3, 5]);
        for text in [
            "1..18446744073709551615",
            "1..4000000000",
            "0..3",
            "4..2",
            "0",
            "",
        ] {
            assert!(parse_components(text).is_err(), "{text}");
        }
    }
}
