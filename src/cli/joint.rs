//! `fluorite fit FILES... --joint --components K`: one joint fit of a sample set, run by
//! [`fluorite::pipeline::joint`] (EEMs: non-negative PARAFAC; radiance-factor surface
//! matrices of one material at several concentrations: the concentration series); this
//! file parses the flags and prints.

use std::path::PathBuf;
use std::process::ExitCode;

use fluorite::fit::joint::reference::Reference;
use fluorite::pipeline::InputOptions;
use fluorite::pipeline::joint::{
    JointOutcome, JointRequest, SecondOrderChoice, fit_samples, read_samples, select_samples,
};

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
    /// Model the grating's second-order image of the emission in a joint EEM fit (each
    /// component seen as e(λo) + G(λo)·e(λo/2), G fitted and shared): `auto` (when the
    /// second-order Rayleigh line stands out in the data), `on` or `off`.
    #[arg(long, value_parser = parse_second_order, default_value = "auto", requires = "joint")]
    pub second_order: SecondOrderChoice,
}

fn parse_second_order(text: &str) -> Result<SecondOrderChoice, String> {
    match text {
        "auto" => Ok(SecondOrderChoice::Auto),
        "on" => Ok(SecondOrderChoice::On),
        "off" => Ok(SecondOrderChoice::Off),
        _ => Err(format!("{text:?}: give auto, on or off")),
    }
}

/// A joint fit as `fit` hands it over: its inputs, how to read them, the request (`fit`'s
/// flags that apply, and these), and how to report.
pub struct JointRun<'a> {
    /// The sample files.
    pub inputs: &'a [PathBuf],
    /// `-o`: the output folder.
    pub output: Option<PathBuf>,
    /// How the samples are read and prepared, as single fits are.
    pub input: InputOptions,
    /// The fit asked for.
    pub request: JointRequest,
    /// `--table`.
    pub table: bool,
    /// `-q`.
    pub quiet: bool,
}

impl JointArgs {
    /// Completes `request` (built from `fit`'s flags) with the joint flags; reads the
    /// reference file.
    pub fn request(&self, request: JointRequest) -> fluorite::Result<JointRequest> {
        Ok(JointRequest {
            components: self.components.clone().map(|c| c.0).unwrap_or_default(),
            em_range: self.em_range.map(|r| (r.0, r.1)),
            ex_range: self.ex_range.map(|r| (r.0, r.1)),
            no_split_half: self.no_split_half,
            second_order: self.second_order,
            reference: self.reference.as_deref().map(Reference::read).transpose()?,
            ..request
        })
    }
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

/// Runs a joint fit (`fit --joint`) of the samples among `run.inputs` (without the files
/// `--exclude` names and the `--reference` file) and prints its summary.
pub fn run(run: &JointRun, joint: &JointArgs) -> anyhow::Result<ExitCode> {
    let paths = select_samples(run.inputs, &joint.exclude, joint.reference.as_deref())?;
    let samples = read_samples(&paths, &run.input)?;
    let outcome = fit_samples(&samples, &run.request)?;
    let out = run
        .output
        .clone()
        .unwrap_or_else(|| outcome.default_output());
    let written = outcome.write(&out)?;
    let fits = match &outcome {
        JointOutcome::Series(fit) => {
            if !run.quiet {
                print!("{}", printer::series_summary(fit));
                for path in &written {
                    println!("wrote {}", path.display());
                }
            }
            return Ok(ExitCode::SUCCESS);
        }
        JointOutcome::Eem(fits) => fits,
    };
    if !run.quiet {
        println!(
            "joint fit of {} EEMs ({}), {} and units {} per file as `fit` does",
            samples.len(),
            samples
                .iter()
                .map(|s| s.measurement.name.as_str())
                .collect::<Vec<_>>()
                .join(", "),
            if run.input.eem.keep_scatter {
                "scatter kept"
            } else {
                "scatter masked"
            },
            match run.input.eem.units {
                fluorite::eem::UnitsChoice::Auto => "inferred",
                _ => "as --units says",
            }
        );
    }
    let mut rows = Vec::new();
    for f in fits {
        let dir = outcome.folder(&out, f.fit.components.len());
        if !run.quiet {
            print!(
                "{}",
                printer::joint_summary(&f.fit, &dir, f.matches.as_deref())
            );
        }
        rows.push(printer::joint_sweep_row(&f.fit, f.matches.as_deref()));
    }
    if fits.len() > 1 || run.table {
        let table = printer::joint_sweep_table(&rows, run.request.reference.as_ref());
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
