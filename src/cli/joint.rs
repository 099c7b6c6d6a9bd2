//! `fluorite fit FILES... --joint --components K`: one joint fit of a sample set.
//! EEMs (uncalibrated solution matrices) get a non-negative PARAFAC
//! ([`fluorite::fit::joint`]); radiance-factor surface matrices of one material at
//! several concentrations go to [`run_surface_series`].

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use fluorite::files::write_files;
use fluorite::fit::joint::diagnostics::r_squared;
use fluorite::fit::joint::parafac::ParafacOptions;
use fluorite::fit::joint::{JointFit, JointOptions, fit_joint};
use fluorite::formats::ReadOptions;
use fluorite::measurement::Measurement;
use fluorite::plot::ImageFormat;

use crate::cli::fit::FitArgs;

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

/// Component counts to fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ComponentList(pub Vec<usize>);

/// A wavelength range in nm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NmRange(pub f64, pub f64);

fn parse_components(text: &str) -> Result<ComponentList, String> {
    let bad = || format!("{text:?}: give a count (4), a list (2,3,4,5) or a range (1..6)");
    let list: Vec<usize> = if let Some((lo, hi)) = text.split_once("..") {
        let lo: usize = lo.trim().parse().map_err(|_| bad())?;
        let hi: usize = hi
            .trim()
            .trim_start_matches('=')
            .parse()
            .map_err(|_| bad())?;
        (lo..=hi).collect()
    } else {
        text.split(',')
            .map(|c| c.trim().parse::<usize>().map_err(|_| bad()))
            .collect::<Result<_, _>>()?
    };
    let max = fluorite::fit::joint::parafac::MAX_COMPONENTS;
    if list.is_empty() || list.iter().any(|&k| k == 0 || k > max) {
        return Err(format!("{text:?}: components must be 1 to {max}"));
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
pub fn run(args: &FitArgs, read_options: &ReadOptions) -> anyhow::Result<ExitCode> {
    let joint = &args.joint;
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
pub fn run_surface_series(args: &FitArgs, surfaces: &[Measurement]) -> anyhow::Result<ExitCode> {
    let lights = args.parsed_lights()?;
    let options = fluorite::fit::series::SeriesOptions {
        yield_choice: args.yield_choice,
        guard_nm: args.guard,
        lights,
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
fn run_eem_set(args: &FitArgs, eems: &[Measurement]) -> anyhow::Result<ExitCode> {
    let joint = &args.joint;
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
        .map(|p| read_reference(p))
        .transpose()?;
    if !args.quiet {
        println!(
            "joint fit of {} EEMs ({}), scatter masked and units inferred per file as `fit` does",
            eems.len(),
            eems.iter()
                .map(|m| m.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
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
            times.sort_by(f64::total_cmp);
            fit.seconds = times[times.len() / 2];
        }
        let dir = if ks.len() > 1 {
            out.join(format!("k{k}"))
        } else {
            out.clone()
        };
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create output folder {}", dir.display()))?;
        let mut files = vec![
            (dir.join("model.json"), fit.to_json().into_bytes()),
            (dir.join("scores.csv"), fit.scores_csv().into_bytes()),
        ];
        for c in 0..k {
            files.push((
                dir.join(format!("component-{}.json", c + 1)),
                fit.fluorophore(c).to_json().into_bytes(),
            ));
        }
        let format = ImageFormat::Png;
        let figure = fluorite::plot::joint::components(&fit, format)?;
        files.push((dir.join("components.png"), figure));
        write_files(&files)?;
        let matches = reference.as_ref().map(|r| match_reference(&fit, r));
        if !args.quiet {
            let names = reference.as_ref().map(|r| r.analytes.as_slice());
            print!("{}", summary(&fit, &dir, matches.as_deref(), names));
        }
        rows.push(sweep_row(&fit, matches.as_deref()));
    }
    if ks.len() > 1 || args.table {
        let table = sweep_table(&rows, reference.as_ref());
        print!("{table}");
        std::fs::create_dir_all(&out)?;
        fluorite::files::write_atomic(&out.join("sweep.md"), table.as_bytes())?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Known concentrations: analyte names and, per sample, one value per analyte.
struct Reference {
    analytes: Vec<String>,
    samples: Vec<(String, Vec<f64>)>,
}

fn read_reference(path: &Path) -> anyhow::Result<Reference> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("--reference {}", path.display()))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header = lines
        .next()
        .with_context(|| format!("--reference {}: empty file", path.display()))?;
    let analytes: Vec<String> = header.split(',').skip(1).map(|s| s.trim().into()).collect();
    let mut samples = Vec::new();
    for (n, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let values = cells[1..]
            .iter()
            .map(|c| c.parse::<f64>())
            .collect::<Result<Vec<f64>, _>>()
            .map_err(|_| {
                anyhow::anyhow!(
                    "{}:{}: expected a sample name and {} numbers (one per analyte of the header)",
                    path.display(),
                    n + 2,
                    analytes.len()
                )
            })?;
        if values.len() != analytes.len() {
            anyhow::bail!(
                "{}:{}: {} values for {} analytes",
                path.display(),
                n + 2,
                values.len(),
                analytes.len()
            );
        }
        samples.push((cells[0].to_string(), values));
    }
    Ok(Reference { analytes, samples })
}

/// Per analyte: the best-matching component (1-based) and its R², over the samples in
/// both the fit and the reference.
fn match_reference(fit: &JointFit, r: &Reference) -> Vec<(usize, f64)> {
    (0..r.analytes.len())
        .map(|a| {
            let pairs: Vec<(usize, f64)> = fit
                .samples
                .iter()
                .enumerate()
                .filter_map(|(s, name)| {
                    r.samples
                        .iter()
                        .find(|(n, _)| n.eq_ignore_ascii_case(name))
                        .map(|(_, v)| (s, v[a]))
                })
                .collect();
            let truth: Vec<f64> = pairs.iter().map(|p| p.1).collect();
            (0..fit.components.len())
                .map(|c| {
                    let scores: Vec<f64> = pairs.iter().map(|p| fit.scores[p.0][c]).collect();
                    (c + 1, r_squared(&scores, &truth))
                })
                .filter(|p| p.1.is_finite())
                .max_by(|x, y| x.1.total_cmp(&y.1))
                .unwrap_or((0, f64::NAN))
        })
        .collect()
}

fn split_text(fit: &JointFit) -> String {
    match &fit.split_half {
        Some(s) => format!(
            "min Tucker congruence {:.3} ({})",
            s.min_congruence,
            if s.validated {
                "validated, ≥ 0.95"
            } else {
                "NOT validated, < 0.95"
            }
        ),
        None if fit.samples.len() < 4 => "not run (it needs at least 4 samples)".into(),
        None => "skipped (--no-split-half)".into(),
    }
}

fn summary(
    fit: &JointFit,
    dir: &Path,
    matches: Option<&[(usize, f64)]>,
    analytes: Option<&[String]>,
) -> String {
    let k = fit.components.len();
    let mut out = format!(
        "K = {k} → {}/ (model.json, scores.csv, component-*.json, components.png)\n  explained variance {:.4} %, core consistency {:.1} %, split-half {}\n  {} sweeps ({}), fit {:.1} ms (+ {:.1} ms diagnostics); {} cells fitted, {} missing or masked\n",
        dir.display().to_string().trim_end_matches('/'),
        100.0 * fit.explained_variance,
        fit.core_consistency,
        split_text(fit),
        fit.iterations,
        if fit.converged {
            "converged"
        } else {
            "NOT converged: raise --max-iterations"
        },
        1e3 * fit.seconds,
        1e3 * fit.diagnostics_seconds,
        fit.measured_cells,
        fit.missing_cells
    );
    for (c, comp) in fit.components.iter().enumerate() {
        out.push_str(&format!(
            "  component {}: excitation max {} nm, emission max {} nm, {:.1} % of the model\n",
            c + 1,
            comp.peak_excitation_nm,
            comp.peak_emission_nm,
            100.0 * comp.share
        ));
    }
    if let Some((worst, r)) = fit
        .samples
        .iter()
        .zip(&fit.residual_per_sample)
        .max_by(|a, b| a.1.total_cmp(b.1))
    {
        out.push_str(&format!(
            "  residual per sample (RMS relative): worst {worst} {:.2} %, median {:.2} % (scores.csv lists all)\n",
            100.0 * r,
            100.0 * fluorite::numeric::median(&fit.residual_per_sample)
        ));
    }
    if let (Some(m), Some(names)) = (matches, analytes) {
        for ((c, r2), name) in m.iter().zip(names) {
            out.push_str(&format!(
                "  {name}: best component {c}, R² {r2:.4} (squared Pearson correlation of scores and reference)\n"
            ));
        }
    }
    out
}

fn sweep_row(fit: &JointFit, matches: Option<&[(usize, f64)]>) -> Vec<String> {
    let mut row = vec![
        fit.components.len().to_string(),
        format!("{:.3}", 100.0 * fit.explained_variance),
        format!("{:.1}", fit.core_consistency),
        fit.split_half
            .as_ref()
            .map(|s| format!("{:.3}", s.min_congruence))
            .unwrap_or_else(|| "–".into()),
        format!(
            "{:.2}",
            100.0 * fluorite::numeric::median(&fit.residual_per_sample)
        ),
        fit.iterations.to_string(),
        format!("{:.1}", 1e3 * fit.seconds),
    ];
    if let Some(m) = matches {
        row.extend(m.iter().map(|(c, r2)| format!("{r2:.3} (C{c})")));
    }
    row
}

fn sweep_table(rows: &[Vec<String>], reference: Option<&Reference>) -> String {
    let mut header = vec![
        "K",
        "explained %",
        "core consistency %",
        "split-half min congruence",
        "median residual %",
        "sweeps",
        "fit ms",
    ]
    .into_iter()
    .map(String::from)
    .collect::<Vec<_>>();
    if let Some(r) = reference {
        header.extend(r.analytes.iter().map(|a| format!("R² {a}")));
    }
    let mut out = format!("| {} |\n", header.join(" | "));
    out.push_str(&format!("|{}\n", "---|".repeat(header.len())));
    for row in rows {
        out.push_str(&format!("| {} |\n", row.join(" | ")));
    }
    out
}
