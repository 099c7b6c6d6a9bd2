//! `fluorite synth`: write synthetic matrices with their ground truth, or (`--image`) a
//! bispectral image with its truth and material map.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use fluorite::Material;
use fluorite::export::parse_grid;
use fluorite::files::write_files;
use fluorite::formats::{RowsAre, write_wide_csv};
use fluorite::image::synth::colour::NOISE_LIGHTS;
use fluorite::image::synth::{
    DEFAULT_MATERIALS, ImageSynth, ImageSynthOptions, Source, parse_size,
};
use fluorite::synth::{PRESETS, SynthSpec};

use super::progress::Progress;

/// Arguments of `fluorite synth`.
#[derive(clap::Args, Debug)]
#[command(
    after_help = "The shipped examples (data/) are exactly\n  fluorite synth --out data/ --preset green-dye,red-pigment,brightener,two-dyes,plain --missing 0.02 --seed 1\n(scripts/regenerate.sh; without --missing 0.02 no cell is missing and every file differs)."
)]
pub struct SynthArgs {
    /// Output folder (created if missing). Writes `<preset>.csv` (wide CSV, rows =
    /// excitation), `<preset>.truth.json` (the ground-truth material) and
    /// `<preset>.synth.json` (the generating parameters); with --image, the files that
    /// flag lists.
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
    /// Write a bispectral OpenEXR image with known truth instead of matrices: `NAME.exr`
    /// (the model's matrix per pixel plus noise σ per cell), `NAME.truth.exr` (without
    /// noise), `NAME.truth/` (the truth as a material map: material-map.json,
    /// concentration.exr, reflectance.exr) and `NAME.synth.json` (the parameters). The
    /// fluorophores of the --material files in soft-edged regions with concentration
    /// gradients, a strip without fluorescence, a blend of their reflectances.
    #[arg(long, conflicts_with_all = ["preset", "crosstalk", "missing", "concentrations"])]
    pub image: bool,
    /// With --image: the size, `512` (square) or `640x480` (default 256).
    #[arg(long, requires = "image")]
    pub size: Option<String>,
    /// With --image: fitted materials (comma-separated) whose fluorophores (all of them,
    /// shared by every pixel) and reflectances make the image (default:
    /// fits/measured/grid/CIBA12.json,fits/measured/grid/TEXTYELL.json,
    /// fits/measured/grid/postit_pink.json, one-fluorophore grid fits, from the repository's
    /// root).
    #[arg(long, value_delimiter = ',', requires = "image")]
    pub material: Vec<PathBuf>,
    /// With --image: the file stem of the outputs (default `image`).
    #[arg(long, requires = "image")]
    pub name: Option<String>,
    /// With --image: 16-bit float images (half the size; values just below 1 round by up
    /// to 0.00024, less than σ) instead of 32-bit.
    #[arg(long, requires = "image")]
    pub half: bool,
    /// With --image: ZIP-compressed images (lossless; smaller, slower to write and read).
    #[arg(long, requires = "image")]
    pub zip: bool,
    /// With --image: the excitation grid, start:end:step in nm or comma-separated
    /// wavelengths (default 300:780:10, the BFC-450's).
    #[arg(long, requires = "image")]
    pub excitation_grid: Option<String>,
    /// With --image: the emission grid (default 380:780:10, the BFC-450's).
    #[arg(long, requires = "image")]
    pub emission_grid: Option<String>,
    /// With --image: width of the regions' soft edges in pixels (default 4).
    #[arg(long, requires = "image")]
    pub falloff: Option<f64>,
    /// With --image: no progress line on the terminal.
    #[arg(short, long, requires = "image")]
    pub quiet: bool,
}

/// Runs `fluorite synth`.
pub fn run(args: SynthArgs) -> anyhow::Result<ExitCode> {
    if args.image {
        return run_image(args);
    }
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

/// `fluorite synth --image`: a bispectral image, its truth and its material map.
fn run_image(args: SynthArgs) -> anyhow::Result<ExitCode> {
    if !args.suffix.is_empty() {
        anyhow::bail!("--suffix: not used with --image; name the outputs with --name");
    }
    let mut options = ImageSynthOptions::new(args.name.as_deref().unwrap_or("image"));
    if let Some(size) = &args.size {
        (options.width, options.height) = parse_size(size)?;
    }
    if let Some(grid) = &args.excitation_grid {
        options.excitation_nm = parse_grid(grid, "--excitation-grid")?;
    }
    if let Some(grid) = &args.emission_grid {
        options.emission_nm = parse_grid(grid, "--emission-grid")?;
    }
    if let Some(sigma) = args.noise {
        options.noise_sigma = sigma;
    }
    if let Some(falloff) = args.falloff {
        options.falloff_px = falloff;
    }
    options.seed = args.seed;
    options.half = args.half;
    options.zip = args.zip;
    options.validate()?;
    let paths: Vec<PathBuf> = if args.material.is_empty() {
        DEFAULT_MATERIALS.iter().map(PathBuf::from).collect()
    } else {
        args.material.clone()
    };
    let mut sources = Vec::with_capacity(paths.len());
    for path in &paths {
        if args.material.is_empty() && !path.exists() {
            anyhow::bail!(
                "--material: the default source {} is absent (the defaults are fluorite's fits, relative to the repository's root); run from there or give --material FILE,...",
                path.display()
            );
        }
        let material =
            Material::load(path).with_context(|| format!("--material {}", path.display()))?;
        sources.push(Source {
            label: path.display().to_string(),
            material,
        });
    }
    let synth = ImageSynth::new(options, sources)?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let progress = Progress::start("writing tiles", 4 * synth.tiles(), args.quiet);
    let written = synth.write(&args.out, |path, done, _| {
        progress.working_on(path);
        progress.set_done(done);
    });
    progress.finish();
    let written = written?;
    let o = synth.options();
    let layout = synth.layout();
    let names: Vec<&str> = written
        .record
        .fluorophores
        .iter()
        .map(|f| f.material.as_str())
        .collect();
    let size = |p: &PathBuf| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
    let [noisy, truth, concentration, reflectance, map, record] = &written.files[..] else {
        anyhow::bail!("the image writer reported {} files", written.files.len());
    };
    let grid = |g: &[f64]| match (g.first(), g.last()) {
        (Some(a), Some(b)) => format!("{a}–{b} nm"),
        _ => String::new(),
    };
    println!(
        "{}: {} × {} pixels, {} cells (excitation {}, emission {}), {} fluorophore(s) ({}), noise σ = {}, seed {}, {}-bit float, {}",
        noisy.display(),
        o.width,
        o.height,
        layout.len(),
        grid(&o.excitation_nm),
        grid(&o.emission_nm),
        names.len(),
        names.join(", "),
        o.noise_sigma,
        o.seed,
        if o.half { 16 } else { 32 },
        human_bytes(size(noisy))
    );
    let colour: Vec<String> = NOISE_LIGHTS
        .iter()
        .filter_map(|light| {
            let s = written.record.noise_delta_e2000.get(*light)?;
            Some(format!("{light} {:.3} / {:.3}", s.median, s.p99))
        })
        .collect();
    println!(
        "  the noise alone moves a pixel's colour by ΔE2000 (median / 99th percentile): {}",
        colour.join(", ")
    );
    println!(
        "{}: the same without noise, {}",
        truth.display(),
        human_bytes(size(truth))
    );
    println!(
        "{}: the truth as a material map ({}, {}; {} and {})",
        map.display(),
        concentration.display(),
        reflectance.display(),
        human_bytes(size(concentration)),
        human_bytes(size(reflectance))
    );
    println!("{}: the generating parameters", record.display());
    Ok(ExitCode::SUCCESS)
}

/// A byte count for people (kB, MB, GB: powers of 1000).
fn human_bytes(n: u64) -> String {
    let n = n as f64;
    match n {
        n if n >= 1e9 => format!("{:.2} GB", n / 1e9),
        n if n >= 1e6 => format!("{:.1} MB", n / 1e6),
        n if n >= 1e3 => format!("{:.1} kB", n / 1e3),
        n => format!("{n} bytes"),
    }
}
