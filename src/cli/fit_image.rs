//! `fluorite fit-image`: a bispectral image into a material map.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Mutex;
use std::time::Duration;

use anyhow::Context;
use fluorite::colour::Light;
use fluorite::fit::FitOptions;
use fluorite::image::ExrImage;
use fluorite::image::fit::{ImageFitOptions, Step, YieldPreference, fit_image};
use fluorite::image::per_pixel::{PerPixelOptions, fit_per_pixel};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// The yield form of the image's fluorophores.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum YieldArg {
    /// Constant energy yield Q.
    Energy,
    /// Constant photon yield Φ.
    Photon,
    /// Energy unless it would need a concentration above 1.
    Auto,
}

/// Arguments of `fluorite fit-image`.
#[derive(clap::Args, Debug)]
pub struct FitImageArgs {
    /// A bispectral OpenEXR image (the spectral layout's `T.<λ>nm` and
    /// `T.<λi>nm.<λo>nm` channels; scanline or tiled, half or float).
    pub image: PathBuf,
    /// Output folder (created if missing): material-map.json, concentration.exr,
    /// reflectance.exr, fitted.exr, delta-e.exr, delta-e-<light>.png, under-<light>.png.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Number of shared fluorophores (default: the smallest meeting --max-delta-e on
    /// --share of the pixels, up to --max-components).
    #[arg(long)]
    pub components: Option<usize>,
    /// Largest number of fluorophores tried.
    #[arg(long, default_value_t = 4)]
    pub max_components: usize,
    /// ΔE2000 bound per pixel, fitted against measured, under every light of --lights.
    #[arg(long, default_value_t = 1.0)]
    pub max_delta_e: f64,
    /// Share of the (unmasked) pixels that must meet the bound.
    #[arg(long, default_value_t = 0.99)]
    pub share: f64,
    /// Lights of the bound and the images: built-in names (d65, a, f11, uv) or CSV files.
    #[arg(long, value_delimiter = ',', default_value = "d65,a,f11,uv")]
    pub lights: Vec<String>,
    /// Yield form of the fluorophores.
    #[arg(long = "yield", value_enum, default_value_t = YieldArg::Auto)]
    pub yield_form: YieldArg,
    /// Width of the random sketch (basis vectors of the compressed image).
    #[arg(long, default_value_t = 24)]
    pub rank: usize,
    /// Power steps sharpening the basis (each is one more pass over the image).
    #[arg(long, default_value_t = 1)]
    pub power_steps: usize,
    /// Iteration limit of the shared fit over all pixels.
    #[arg(long, default_value_t = 200)]
    pub max_iterations: usize,
    /// ZIP-compress the EXR outputs (smaller, slower).
    #[arg(long)]
    pub zip: bool,
    /// The per-pixel baseline instead: fit every pixel on its own with the default
    /// single-matrix fit (as `fluorite fit` fits one matrix) and write fitted.exr and
    /// delta-e.exr only; no material map (each pixel has fluorophores of its own). Uses
    /// --lights and --zip.
    #[arg(long, conflicts_with_all = ["components", "max_components", "max_delta_e", "share", "yield_form", "rank", "power_steps", "max_iterations"])]
    pub per_pixel: bool,
    /// Print nothing but errors.
    #[arg(short, long)]
    pub quiet: bool,
}

/// A progress bar per stage, with an ETA; hidden when quiet or not on a terminal.
struct Bars {
    quiet: bool,
    bar: Mutex<Option<ProgressBar>>,
    /// Each stage and when it started, for the timing lines of the report.
    stages: Mutex<Vec<(String, std::time::Instant)>>,
}

impl Bars {
    fn step(&self, step: Step) {
        let mut bar = self.bar.lock().unwrap_or_else(|p| p.into_inner());
        match step {
            Step::Stage { what, total } => {
                self.stages
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .push((what.clone(), std::time::Instant::now()));
                if let Some(b) = bar.take() {
                    b.finish_and_clear();
                }
                let target = if self.quiet {
                    ProgressDrawTarget::hidden()
                } else {
                    ProgressDrawTarget::stderr()
                };
                let b = ProgressBar::with_draw_target(Some(total as u64), target);
                if let Ok(style) = ProgressStyle::with_template(
                    "{msg} [{bar:30}] {pos}/{len} · {elapsed} · ETA {eta}",
                ) {
                    b.set_style(style.progress_chars("=> "));
                }
                b.set_message(what);
                b.enable_steady_tick(Duration::from_millis(200));
                *bar = Some(b);
            }
            Step::Done(d) => {
                if let Some(b) = bar.as_ref() {
                    b.set_position(d as u64);
                }
            }
            Step::Resumed(what) => {
                if !self.quiet {
                    eprintln!("resumed: {what} (finished by an earlier run)");
                }
            }
        }
    }

    fn finish(&self) {
        if let Some(b) = self.bar.lock().unwrap_or_else(|p| p.into_inner()).take() {
            b.finish_and_clear();
        }
    }
}

/// Runs `fluorite fit-image`.
pub fn run(args: FitImageArgs) -> anyhow::Result<ExitCode> {
    let lights = args
        .lights
        .iter()
        .map(|l| Light::parse(l))
        .collect::<Result<Vec<_>, _>>()
        .context("--lights")?;
    let options = ImageFitOptions {
        components: args.components,
        max_components: args.max_components,
        max_delta_e: args.max_delta_e,
        share: args.share,
        lights,
        yield_preference: match args.yield_form {
            YieldArg::Energy => YieldPreference::Energy,
            YieldArg::Photon => YieldPreference::Photon,
            YieldArg::Auto => YieldPreference::Auto,
        },
        rank: args.rank,
        power_steps: args.power_steps,
        max_iterations: args.max_iterations,
        zip: args.zip,
        ..ImageFitOptions::default()
    };
    options.validate()?;
    let image = ExrImage::open(&args.image)?;
    let bars = Bars {
        quiet: args.quiet,
        bar: Mutex::new(None),
        stages: Mutex::new(Vec::new()),
    };
    if args.per_pixel {
        return run_per_pixel(&args, &image, options.lights, &bars);
    }
    let started = std::time::Instant::now();
    let fitted = fit_image(
        fluorite::image::PixelSource::Exr(&image),
        &args.out,
        &options,
        &|s| bars.step(s),
    );
    bars.finish();
    let fitted = fitted?;
    if !args.quiet {
        let lights: Vec<String> = options.lights.iter().map(|l| l.name.clone()).collect();
        println!(
            "{}: {}×{} pixels, {} cells each; {} shared fluorophore(s) in {:.1} s",
            args.image.display(),
            image.width,
            image.height,
            image.layout.len(),
            fitted.components,
            started.elapsed().as_secs_f64()
        );
        for note in image.notes.iter().chain(&fitted.notes) {
            println!("  {note}");
        }
        for t in &fitted.trials {
            println!(
                "  K = {}: {:.2} % of pixels within ΔE2000 {} under {}; median {} · 99th {}; residual {:.3} % of the fluorescence energy; {} iterations{}",
                t.components,
                100.0 * t.share_within,
                options.max_delta_e,
                lights.join(", "),
                per_light(&lights, &t.median_delta_e),
                per_light(&lights, &t.p99_delta_e),
                100.0 * t.residual_share,
                t.iterations,
                if t.converged { "" } else { " (not converged)" }
            );
        }
        let stages = bars.stages.lock().unwrap_or_else(|p| p.into_inner());
        let ends = stages
            .iter()
            .skip(1)
            .map(|(_, t)| *t)
            .chain([std::time::Instant::now()]);
        let timing: Vec<String> = stages
            .iter()
            .zip(ends)
            .map(|((what, start), end)| format!("{what} {:.1} s", (end - *start).as_secs_f64()))
            .collect();
        if !timing.is_empty() {
            println!("  time: {}", timing.join(" · "));
        }
        if !fitted.resumed.is_empty() {
            println!("  resumed after: {}", fitted.resumed.join(", "));
        }
        println!("  wrote {}", fitted.map_path.display());
    }
    Ok(ExitCode::SUCCESS)
}

/// `--per-pixel`: every pixel fitted on its own.
fn run_per_pixel(
    args: &FitImageArgs,
    image: &ExrImage,
    lights: Vec<Light>,
    bars: &Bars,
) -> anyhow::Result<ExitCode> {
    let options = PerPixelOptions {
        fit: FitOptions {
            lights: lights.clone(),
            ..FitOptions::default()
        },
        lights,
        zip: args.zip,
    };
    let started = std::time::Instant::now();
    let fitted = fit_per_pixel(
        fluorite::image::PixelSource::Exr(image),
        &args.out,
        &options,
        &|s| bars.step(s),
    );
    bars.finish();
    let fitted = fitted?;
    if !args.quiet {
        println!(
            "{}: {}×{} pixels, {} cells each; {} fitted one by one in {:.1} s",
            args.image.display(),
            image.width,
            image.height,
            image.layout.len(),
            fitted.fitted,
            started.elapsed().as_secs_f64()
        );
        for note in image.notes.iter().chain(&fitted.notes) {
            println!("  {note}");
        }
        println!(
            "  ΔE2000 fitted against measured: median {} · 99th {} · max {}",
            per_light(&fitted.lights, &fitted.median_delta_e),
            per_light(&fitted.lights, &fitted.p99_delta_e),
            per_light(&fitted.lights, &fitted.max_delta_e)
        );
        for f in &fitted.files {
            println!("  wrote {}", f.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn per_light(lights: &[String], values: &[f64]) -> String {
    lights
        .iter()
        .zip(values)
        .map(|(l, v)| format!("{l} {v:.2}"))
        .collect::<Vec<_>>()
        .join(", ")
}
