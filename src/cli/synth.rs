//! `fluorite synth`: write synthetic matrices with their ground truth.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use fluorite::files::write_files;
use fluorite::formats::{RowsAre, write_wide_csv};
use fluorite::synth::{PRESETS, SynthSpec};

/// Arguments of `fluorite synth`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "The shipped examples (data/) are exactly\n  fluorite synth --out data/ --preset green-dye,red-pigment,brightener,two-dyes,plain --missing 0.02 --seed 1\n(scripts/regenerate.sh; without --missing 0.02 no cell is missing and every file differs)."
)]
pub struct SynthArgs {
    /// Output folder (created if missing). Writes `<preset>.csv` (wide CSV, rows =
    /// excitation), `<preset>.truth.json` (the ground-truth material) and
    /// `<preset>.synth.json` (the generating parameters).
    #[arg(long)]
    pub out: PathBuf,
    /// Presets to write, comma-separated (default: all of green-dye, red-pigment,
    /// brightener, two-dyes, plain).
    #[arg(long, value_delimiter = ',')]
    pub preset: Vec<String>,
    /// Gaussian noise σ per cell (radiance-factor units). Default: 0.0006, what the real BFC-450 files show.
    #[arg(long)]
    pub noise: Option<f64>,
    /// Crosstalk: fraction of the diagonal a monochromator offset moves from the cell one
    /// step above the diagonal to the cell one step below (default 0.001, as most real
    /// files show; POLGREE and TEXTYELL show 0.04).
    #[arg(long)]
    pub crosstalk: Option<f64>,
    /// Fraction of off-diagonal cells left missing (default 0). The shipped examples in
    /// data/ have 2 %: `fluorite synth --out data/ --preset
    /// green-dye,red-pigment,brightener,two-dyes,plain --missing 0.02 --seed 1` rewrites
    /// them byte for byte (scripts/regenerate.sh).
    #[arg(long)]
    pub missing: Option<f64>,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Suffix appended to each file stem (e.g. `-noisefree`).
    #[arg(long, default_value = "")]
    pub suffix: String,
    /// Write a concentration series instead of one matrix per preset: one matrix per
    /// concentration (comma-separated, e.g. 0.2,0.5,1.0), named `<preset>-c<c>`, with the
    /// preset's spectra, reflectance and yield shared and a noise draw each (seed, seed + 1,
    /// …). Input for the joint series fit, which separates c from Q.
    #[arg(long, value_delimiter = ',')]
    pub concentrations: Vec<f64>,
}

/// Runs `fluorite synth`.
pub fn run(args: SynthArgs) -> anyhow::Result<ExitCode> {
    let presets: Vec<String> = if args.preset.is_empty() {
        PRESETS.iter().map(|s| s.to_string()).collect()
    } else {
        args.preset.clone()
    };
    // Build everything first so a bad preset writes nothing.
    let mut outputs = Vec::new();
    for preset in &presets {
        let mut spec = SynthSpec::preset(preset)?;
        spec.name = format!("{preset}{}", args.suffix);
        spec.seed = args.seed;
        if let Some(v) = args.noise {
            spec.noise_sigma = v;
        }
        if let Some(v) = args.crosstalk {
            spec.crosstalk = v;
        }
        if let Some(v) = args.missing {
            spec.missing_fraction = v;
        }
        if args.concentrations.is_empty() {
            let (m, truth) = spec.generate()?;
            outputs.push((spec, m, truth));
        } else {
            outputs.extend(spec.concentration_series(&args.concentrations)?);
        }
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    // Every preset's three files, written all-or-nothing.
    let mut files = Vec::with_capacity(3 * outputs.len());
    for (spec, m, truth) in &outputs {
        // Appended, not `with_extension`: series names hold a dot (`green-dye-c0.5`).
        let file = |extension: &str| args.out.join(format!("{}.{extension}", spec.name));
        let spec_json = serde_json::to_string_pretty(spec)? + "\n";
        files.push((
            file("csv"),
            write_wide_csv(m, RowsAre::Excitation).into_bytes(),
        ));
        files.push((file("truth.json"), truth.to_json().into_bytes()));
        files.push((file("synth.json"), spec_json.into_bytes()));
    }
    write_files(&files)?;
    // The CSV is the first of each output's three files.
    for ((spec, m, _), (csv, _)) in outputs.iter().zip(files.iter().step_by(3)) {
        println!(
            "{}: {} × {} cells, noise σ = {}, crosstalk {}, missing {:.0} %, seed {}",
            csv.display(),
            m.n_excitation(),
            m.n_emission(),
            spec.noise_sigma,
            spec.crosstalk,
            100.0 * spec.missing_fraction,
            spec.seed
        );
    }
    Ok(ExitCode::SUCCESS)
}
