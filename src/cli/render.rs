//! `fluorite render`: preview a material, or a material map, in the built-in spectral path
//! tracer.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use fluorite::Material;
use fluorite::colour::Light;
use fluorite::error::Error;
use fluorite::render::image::check_exposure;
use fluorite::render::picture::{Picture, Rendered, render_picture};
use fluorite::render::report::furnace_noise;
use fluorite::render::{MaterialSource, MaterialTexture, is_material_map};

use crate::cli::printer;
use fluorite::render::{RenderSettings, SceneKind, SpectralSampling};

/// The built-in scene to render.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum SceneArg {
    /// The material on a sphere on a grey ground, an area light and a dim environment.
    Preview,
    /// The material on a sphere alone in a uniform environment of the light (for checks).
    Furnace,
    /// The material on a rectangle facing the camera in a uniform environment of the light:
    /// each point shows its flat-patch colour; a material map spans it once, upright.
    Plane,
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
    /// Material JSON to render (fluorite-material/1), or a material map
    /// (fluorite-material-map/1: `material-map.json` or any JSON of that schema, its
    /// textures beside it), shown textured; with `--report`, one or more materials.
    #[arg(required = true, num_args = 1..)]
    pub materials: Vec<PathBuf>,
    /// Output PNG [default: the material's path with the extension .png].
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Light: d65, a, f11, uv (D65 plus a 365 nm LED), or a two-column CSV file
    /// (wavelength_nm,power).
    #[arg(long, default_value = "d65")]
    pub light: String,
    /// Place a twin sphere (rectangle with `--scene plane`) with the same reflectance r and
    /// no fluorescence (c = 0) to the right of the material's.
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
            SceneArg::Plane => SceneKind::Plane,
        },
        compare: args.compare,
        sampling: args.sampling.into(),
        exposure_ev: args.exposure,
        adapt: !args.no_adapt,
        exr: args.exr,
    };
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| material_path.with_extension("png"));
    if is_material_map(material_path) {
        let texture = MaterialTexture::load(material_path)?;
        render_to(
            MaterialSource::Map(&texture),
            material_path,
            &picture,
            &output,
            args.quiet,
        )?;
        if texture.masked() > 0 && !args.quiet {
            eprintln!(
                "note: {} of {} texels of {} are masked (non-finite values); they show as a neutral grey of reflectance {}",
                texture.masked(),
                texture.width * texture.height,
                material_path.display(),
                fluorite::render::texture::MASKED_REFLECTANCE
            );
        }
    } else {
        let material = Material::load(material_path)?;
        render_to(
            MaterialSource::Uniform(&material),
            material_path,
            &picture,
            &output,
            args.quiet,
        )?;
    }
    Ok(ExitCode::SUCCESS)
}

/// Renders `material` (a material or a map, read from or written to `material_path`, for
/// messages) into `output` (display-referred PNG) and, with [`Picture::exr`], a
/// scene-referred EXR beside it; shows progress and a summary line unless `quiet`.
fn render_to(
    material: MaterialSource,
    material_path: &Path,
    picture: &Picture,
    output: &Path,
    quiet: bool,
) -> anyhow::Result<()> {
    picture.settings.validate()?;
    if let Some(ev) = picture.exposure_ev {
        check_exposure(ev)?;
    }
    check_output_folder(output)?;
    let progress = (!quiet && std::io::stderr().is_terminal()).then(|| {
        let bar = indicatif::ProgressBar::new(picture.settings.height as u64);
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "rendering {bar:40.cyan/blue} {pos}/{len} rows, {elapsed} (eta {eta})",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        bar
    });
    let rendered = render_picture(material, picture, &|| {
        if let Some(bar) = &progress {
            bar.inc(1);
        }
    })
    .with_context(|| format!("cannot render {}", material_path.display()))?;
    if let Some(bar) = &progress {
        bar.finish_and_clear();
    }
    let exr = rendered
        .exr
        .as_ref()
        .map(|bytes| (output.with_extension("exr"), bytes.clone()));
    let mut files = vec![(output.to_path_buf(), rendered.png.clone())];
    files.extend(exr.iter().cloned());
    fluorite::files::write_files(&files)?;
    if !quiet {
        print_rendered(
            output,
            exr.as_ref().map(|(p, _)| p.as_path()),
            picture,
            &rendered,
        );
    }
    Ok(())
}

/// The summary line of a render written to `output` (and `exr`).
fn print_rendered(output: &Path, exr: Option<&Path>, picture: &Picture, rendered: &Rendered) {
    let settings = &picture.settings;
    eprintln!(
        "wrote {}{} ({}×{}, {} spp, light {}): {:.2} s, {:.2} M paths/s",
        output.display(),
        exr.map(|p| format!(" and {}", p.display()))
            .unwrap_or_default(),
        settings.width,
        settings.height,
        settings.samples_per_pixel,
        picture.light.name,
        rendered.seconds,
        settings.paths() as f64 / rendered.seconds / 1e6
    );
}

/// Renders the default preview of a material just fitted, handed over in memory (`fit
/// --render`): `<stem>.png` next to the material JSON, daylight (D65), default size and
/// samples; `quiet` (`fit -q`) prints nothing.
pub fn preview(material: &Material, material_path: &Path, quiet: bool) -> anyhow::Result<()> {
    let (output, picture, rendered) =
        fluorite::pipeline::beside::preview(material, material_path, &|| {})?;
    if !quiet {
        print_rendered(&output, None, &picture, &rendered);
    }
    Ok(())
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
    if let Some(map) = args.materials.iter().find(|p| is_material_map(p)) {
        return Err(Error::invalid(
            "--report",
            format!(
                "{} is a material map; the furnace report measures single materials: render the map without --report",
                map.display()
            ),
        )
        .into());
    }
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
