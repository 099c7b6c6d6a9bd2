//! `fluorite render`: preview a material in the built-in spectral path tracer.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use fluorite::Material;
use fluorite::colour::Light;
use fluorite::error::Error;
use fluorite::render::compare::develop_compare;
use fluorite::render::image::{Develop, check_exposure, develop};
use fluorite::render::report::furnace_noise;

use crate::cli::printer;
use fluorite::render::{
    DEFAULT_EXPOSURE_EV, RenderSettings, Scene, SceneKind, SpectralSampling, render,
};

/// The built-in scene to render.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum SceneArg {
    /// The material on a sphere on a grey ground, an area light and a dim environment.
    Preview,
    /// The material on a sphere alone in a uniform environment of the light (for checks).
    Furnace,
}

/// How paths draw wavelengths.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum SamplingArg {
    /// Light-aware: excitation by multiple importance sampling of a(λ) and a(λ)·L(λ) (L
    /// the scene's light), camera wavelengths guided by L and the surfaces' radiance.
    Light,
    /// The paper's rules: λi ∝ a(λ) (× λ/λ̄e in the photon form), observer wavelengths.
    Paper,
}

impl From<SamplingArg> for SpectralSampling {
    fn from(arg: SamplingArg) -> SpectralSampling {
        match arg {
            SamplingArg::Light => SpectralSampling::LightAware,
            SamplingArg::Paper => SpectralSampling::Paper,
        }
    }
}

/// Arguments of `fluorite render`.
#[derive(clap::Args)]
pub struct RenderArgs {
    /// Material JSON to render (fluorite-material/1); with `--report`, one or more.
    #[arg(required = true, num_args = 1..)]
    pub materials: Vec<PathBuf>,
    /// Output PNG [default: the material's path with the extension .png].
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Light: d65, a, f11, uv (D65 plus a 365 nm LED), or a two-column CSV file
    /// (wavelength_nm,power).
    #[arg(long, default_value = "d65")]
    pub light: String,
    /// Place a twin sphere with the same reflectance r and no fluorescence (c = 0) to the
    /// right of the material's sphere.
    #[arg(long)]
    pub compare: bool,
    /// Scene to render.
    #[arg(long, value_enum, default_value = "preview")]
    pub scene: SceneArg,
    /// Camera paths per pixel (1 to 16384); each path carries four wavelengths.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    /// Image size WIDTHxHEIGHT in pixels (each 1 to 16384) [default: 640x400; with
    /// `--report` 128x128].
    #[arg(long)]
    pub size: Option<String>,
    /// Random seed: the same seed, settings and material give the same image.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Exposure in stops. At 0 a white diffuser facing up on top of the sphere is sRGB
    /// white; the default, -0.5, leaves half a stop for fluorescence brighter than white.
    /// With `--compare` the default is automatic: 99 % of both spheres' pixels stay below
    /// 0.9 in every linear sRGB channel (never brighter than -0.5), so a fluorescent sphere
    /// far brighter than white keeps its colour; the image states the exposure used.
    #[arg(long, allow_negative_numbers = true)]
    pub exposure: Option<f64>,
    /// Also write scene-referred linear radiance as OpenEXR beside the PNG: linear sRGB
    /// primaries of the film's XYZ, without chromatic adaptation, exposure or clipping
    /// (the PNG alone gets the display transform).
    #[arg(long)]
    pub exr: bool,
    /// Show the light's own colour in the PNG instead of adapting its white to D65.
    #[arg(long)]
    pub no_adapt: bool,
    /// Instead of a picture, print a Markdown table of furnace noise (relative standard
    /// deviation of Y over the pixels wholly inside the sphere) and median render time
    /// per light, for the paper's excitation sampling and the light-aware one, at the
    /// given --spp and --size; nothing is written.
    #[arg(long)]
    pub report: bool,
    /// Lights of `--report`, comma-separated (names or CSV files).
    #[arg(long, default_value = "d65,a,f11,uv")]
    pub lights: String,
    /// Spectral sampling: `light` (camera wavelengths and excitation wavelengths guided
    /// by the scene's light spectrum) or `paper` (the paper's rules, for comparison).
    #[arg(long, value_enum, default_value = "light")]
    pub sampling: SamplingArg,
    /// No progress bar or summary line.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Runs `fluorite render`.
pub fn run(args: RenderArgs) -> anyhow::Result<ExitCode> {
    if args.report {
        return report(&args);
    }
    let [material_path] = args.materials.as_slice() else {
        return Err(Error::invalid(
            "material",
            format!(
                "{} files given; render takes one (several only with --report)",
                args.materials.len()
            ),
        )
        .into());
    };
    let material = Material::load(material_path)?;
    let (width, height) = parse_size(args.size.as_deref().unwrap_or(DEFAULT_SIZE))?;
    let picture = Picture {
        light: Light::parse(&args.light)?,
        settings: RenderSettings {
            width,
            height,
            samples_per_pixel: args.spp,
            seed: args.seed,
        },
        kind: match args.scene {
            SceneArg::Preview => SceneKind::Preview,
            SceneArg::Furnace => SceneKind::Furnace,
        },
        compare: args.compare,
        sampling: args.sampling,
        exposure: args.exposure,
        exr: args.exr,
        adapt: !args.no_adapt,
        quiet: args.quiet,
        output: args
            .output
            .clone()
            .unwrap_or_else(|| material_path.with_extension("png")),
    };
    render_picture(&material, material_path, &picture)?;
    Ok(ExitCode::SUCCESS)
}

/// One picture to render: everything but the material.
struct Picture {
    light: Light,
    settings: RenderSettings,
    kind: SceneKind,
    compare: bool,
    sampling: SamplingArg,
    /// Given exposure (stops); None: the default, automatic with `compare`.
    exposure: Option<f64>,
    exr: bool,
    adapt: bool,
    quiet: bool,
    output: PathBuf,
}

/// Renders `material` (read from or written to `material_path`, for messages) into the
/// picture's PNG (display-referred) and, with `exr`, a scene-referred EXR beside it.
fn render_picture(
    material: &Material,
    material_path: &Path,
    picture: &Picture,
) -> anyhow::Result<()> {
    let Picture {
        light,
        settings,
        kind,
        compare,
        exposure,
        output,
        ..
    } = picture;
    let (width, height) = (settings.width, settings.height);
    settings.validate()?;
    if let Some(ev) = exposure {
        check_exposure(*ev)?;
    }
    check_output_folder(output)?;
    let mut scene = Scene::build(*kind, material, light, *compare, settings.aspect())
        .with_context(|| format!("cannot render {}", material_path.display()))?;
    scene.set_spectral_sampling(picture.sampling.into());

    let progress = (!picture.quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(height as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "rendering {bar:40.cyan/blue} {pos}/{len} rows, {elapsed} (eta {eta})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let started = Instant::now();
    let film = render(&scene, settings, &|| {
        if let Some(bar) = &progress {
            bar.inc(1);
        }
    })?;
    let seconds = started.elapsed().as_secs_f64();
    if let Some(bar) = &progress {
        bar.finish_and_clear();
    }

    let exposure_ev = exposure.unwrap_or(DEFAULT_EXPOSURE_EV);
    let description = format!(
        "{} under {}{}, scene {:?}, {} spp, seed {}{}{}",
        material.name,
        light.name,
        if *compare {
            " (right: same reflectance without fluorescence)"
        } else {
            ""
        },
        kind,
        settings.samples_per_pixel,
        settings.seed,
        // The compare picture states its exposure itself (it may be automatic).
        if *compare {
            String::new()
        } else {
            format!(", exposure {exposure_ev:+} EV")
        },
        if picture.adapt {
            ", adapted to D65"
        } else {
            ", not adapted"
        }
    );
    let develop_as = Develop {
        adapt: picture.adapt,
        exposure_ev,
        description,
        exr: picture.exr,
    };
    let (png, exr) = if *compare {
        let developed = develop_compare(
            &film,
            &scene,
            settings,
            &develop_as,
            exposure.is_none(),
            (&material.name, &light.name),
        )?;
        (developed.png, developed.exr)
    } else {
        develop(&film, scene.light(), &develop_as)?
    };
    let exr = exr.map(|bytes| (output.with_extension("exr"), bytes));
    let mut files = vec![(output.clone(), png)];
    files.extend(exr.iter().cloned());
    fluorite::files::write_files(&files)?;
    if !picture.quiet {
        let paths = settings.paths();
        eprintln!(
            "wrote {}{} ({width}×{height}, {} spp, light {}): {:.2} s, {:.2} M paths/s",
            output.display(),
            exr.as_ref()
                .map(|(p, _)| format!(" and {}", p.display()))
                .unwrap_or_default(),
            settings.samples_per_pixel,
            light.name,
            seconds,
            paths as f64 / seconds / 1e6
        );
    }
    Ok(())
}

/// Renders the default preview of a material just fitted, handed over in memory (`fit
/// --render`):
/// `<stem>.png` next to the material JSON, daylight (D65), default size and samples;
/// `quiet` (`fit -q`) prints nothing.
pub fn preview(material: &Material, material_path: &Path, quiet: bool) -> anyhow::Result<()> {
    let (width, height) = parse_size(DEFAULT_SIZE)?;
    let picture = Picture {
        light: Light::parse("d65")?,
        settings: RenderSettings {
            width,
            height,
            ..RenderSettings::default()
        },
        kind: SceneKind::Preview,
        compare: false,
        sampling: SamplingArg::Light,
        exposure: None,
        exr: false,
        adapt: true,
        quiet,
        output: material_path.with_extension("png"),
    };
    render_picture(material, material_path, &picture)
}

/// Image size of a picture when `--size` is not given.
const DEFAULT_SIZE: &str = "640x400";
/// Image size of `--report` when `--size` is not given (a furnace patch: small, as noise
/// per pixel is what it measures).
const REPORT_SIZE: &str = "128x128";
/// Renders per rule and light in `--report`; the time is their median.
const REPORT_RUNS: usize = 5;

/// `--report`: furnace noise and time per material, light and excitation sampling rule.
fn report(args: &RenderArgs) -> anyhow::Result<ExitCode> {
    let (width, height) = parse_size(args.size.as_deref().unwrap_or(REPORT_SIZE))?;
    let settings = RenderSettings {
        width,
        height,
        samples_per_pixel: args.spp,
        seed: args.seed,
    };
    settings.validate()?;
    let lights = args
        .lights
        .split(',')
        .map(|l| Light::parse(l.trim()))
        .collect::<fluorite::Result<Vec<_>>>()?;
    let materials = args
        .materials
        .iter()
        .map(|p| Material::load(p).map(|m| (p, m)))
        .collect::<fluorite::Result<Vec<_>>>()?;
    let rules = [SpectralSampling::Paper, SpectralSampling::LightAware];
    print!("{}", printer::furnace_header(&settings, REPORT_RUNS));
    for (path, material) in &materials {
        for light in &lights {
            let r = furnace_noise(material, light, &settings, &rules, REPORT_RUNS)
                .with_context(|| format!("cannot report on {}", path.display()))?;
            print!("{}", printer::furnace_row(material, light, &r[0], &r[1]));
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Parses `WIDTHxHEIGHT`.
fn parse_size(text: &str) -> fluorite::Result<(u32, u32)> {
    let bad = || {
        Error::invalid(
            "--size",
            format!("\"{text}\" is not WIDTHxHEIGHT in pixels, e.g. 800x600"),
        )
    };
    let (w, h) = text.trim().split_once(['x', 'X', '×']).ok_or_else(bad)?;
    let w: u64 = w.trim().parse().map_err(|_| bad())?;
    let h: u64 = h.trim().parse().map_err(|_| bad())?;
    let limit = fluorite::render::MAX_SETTING as u64;
    for (value, what) in [(w, "width"), (h, "height")] {
        if value == 0 || value > limit {
            return Err(Error::invalid(
                "--size",
                format!("{what} is {value}; give a value from 1 to {limit}"),
            ));
        }
    }
    Ok((w as u32, h as u32))
}

/// Fails early, before rendering, when the output's folder does not exist.
fn check_output_folder(output: &Path) -> fluorite::Result<()> {
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(Error::invalid(
            "--output",
            format!(
                "{}: folder {} does not exist; create it first",
                output.display(),
                dir.display()
            ),
        ));
    }
    Ok(())
}
