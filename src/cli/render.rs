//! `fluorite render`: preview a material in the built-in spectral path tracer.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Context;
use fluorite::Material;
use fluorite::colour::Light;
use fluorite::error::Error;
use fluorite::export::write_atomic;
use fluorite::render::image::{
    check_exposure, encode_exr, encode_png, film_to_linear_srgb, to_srgb8, xyz_to_srgb_matrix,
};
use fluorite::render::{DEFAULT_EXPOSURE_EV, RenderSettings, Scene, SceneKind, render};

/// The built-in scene to render.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum SceneArg {
    /// The material on a sphere on a grey ground, an area light and a dim environment.
    Preview,
    /// The material on a sphere alone in a uniform environment of the light (for checks).
    Furnace,
}

/// Arguments of `fluorite render`.
#[derive(clap::Args)]
pub struct RenderArgs {
    /// Material JSON to render (fluorite-material/1).
    pub material: PathBuf,
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
    /// Image size WIDTHxHEIGHT in pixels (each 1 to 16384).
    #[arg(long, default_value = "640x400")]
    pub size: String,
    /// Random seed: the same seed, settings and material give the same image.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Exposure in stops. At 0 a white diffuser facing up on top of the sphere is sRGB
    /// white; the default leaves half a stop for fluorescence brighter than white.
    #[arg(long, default_value_t = DEFAULT_EXPOSURE_EV, allow_negative_numbers = true)]
    pub exposure: f64,
    /// Also write linear sRGB (no exposure, no clipping) as OpenEXR beside the PNG.
    #[arg(long)]
    pub exr: bool,
    /// Show the light's own colour instead of adapting its white to D65.
    #[arg(long)]
    pub no_adapt: bool,
    /// No progress bar or summary line.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Runs `fluorite render`.
pub fn run(args: RenderArgs) -> anyhow::Result<ExitCode> {
    let material = Material::load(&args.material)?;
    let light = Light::parse(&args.light)?;
    let (width, height) = parse_size(&args.size)?;
    let settings = RenderSettings {
        width,
        height,
        samples_per_pixel: args.spp,
        seed: args.seed,
    };
    settings.validate()?;
    check_exposure(args.exposure)?;
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| args.material.with_extension("png"));
    check_output_folder(&output)?;
    let kind = match args.scene {
        SceneArg::Preview => SceneKind::Preview,
        SceneArg::Furnace => SceneKind::Furnace,
    };
    let scene = Scene::build(kind, &material, &light, args.compare, settings.aspect())
        .with_context(|| format!("cannot render {}", args.material.display()))?;

    let progress = (!args.quiet && std::io::stderr().is_terminal()).then(|| {
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
    let film = render(&scene, &settings, &|| {
        if let Some(bar) = &progress {
            bar.inc(1);
        }
    })?;
    let seconds = started.elapsed().as_secs_f64();
    if let Some(bar) = &progress {
        bar.finish_and_clear();
    }

    let matrix = xyz_to_srgb_matrix(scene.light(), !args.no_adapt);
    let linear = film_to_linear_srgb(&film, &matrix);
    let description = format!(
        "{} under {}{}, scene {:?}, {} spp, seed {}, exposure {:+} EV{}",
        material.name,
        light.name,
        if args.compare {
            " (right: same reflectance without fluorescence)"
        } else {
            ""
        },
        kind,
        settings.samples_per_pixel,
        settings.seed,
        args.exposure,
        if args.no_adapt {
            ", not adapted"
        } else {
            ", adapted to D65"
        }
    );
    let png = encode_png(
        width,
        height,
        &to_srgb8(&linear, args.exposure),
        &description,
    )?;
    let exr = if args.exr {
        Some((
            output.with_extension("exr"),
            encode_exr(width, height, &linear)?,
        ))
    } else {
        None
    };
    write_atomic(&output, &png)?;
    if let Some((path, bytes)) = &exr {
        write_atomic(path, bytes)?;
    }
    if !args.quiet {
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
    Ok(ExitCode::SUCCESS)
}

/// Renders the default preview of a freshly fitted material (used by `fit --render`):
/// `<stem>.png` next to the material JSON, daylight (D65), default size and samples.
pub fn preview(material_path: &Path) -> anyhow::Result<()> {
    let args = RenderArgs {
        material: material_path.to_path_buf(),
        output: None,
        light: "d65".to_string(),
        compare: false,
        scene: SceneArg::Preview,
        spp: RenderSettings::default().samples_per_pixel,
        size: {
            let s = RenderSettings::default();
            format!("{}x{}", s.width, s.height)
        },
        seed: RenderSettings::default().seed,
        exposure: DEFAULT_EXPOSURE_EV,
        exr: false,
        no_adapt: false,
        quiet: false,
    };
    run(args).map(|_| ())
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
