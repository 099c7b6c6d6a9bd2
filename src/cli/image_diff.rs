//! `fluorite image-diff`: two bispectral images compared pixel by pixel (a fit against
//! its truth).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use fluorite::colour::Light;
use fluorite::image::ExrImage;
use fluorite::image::diff::{ImageDiff, MapComparison, compare_maps, diff_images};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Arguments of `fluorite image-diff`.
#[derive(clap::Args, Debug)]
pub struct ImageDiffArgs {
    /// The first bispectral OpenEXR image (e.g. a fit's fitted.exr).
    pub a: PathBuf,
    /// The second, with the same size and channels (e.g. `synth --image`'s NAME.truth.exr).
    pub b: PathBuf,
    /// Lights: built-in names (d65, a, f11, uv) or CSV files.
    #[arg(long, value_delimiter = ',', default_value = "d65,a,f11,uv")]
    pub lights: Vec<String>,
    /// The images' material maps (A's, then B's): the correlation of each fluorophore's
    /// concentration map in A with its best match in B (greedy one to one).
    #[arg(long, num_args = 2, value_names = ["A_MAP", "B_MAP"])]
    pub maps: Vec<PathBuf>,
    /// Print the result as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Runs `fluorite image-diff`.
pub fn run(args: ImageDiffArgs) -> anyhow::Result<ExitCode> {
    let lights = args
        .lights
        .iter()
        .map(|l| Light::parse(l))
        .collect::<Result<Vec<_>, _>>()
        .context("--lights")?;
    let a = ExrImage::open(&args.a)?;
    let b = ExrImage::open(&args.b)?;
    fluorite::image::diff::check_compatible(&a, &b)?;
    let maps = match args.maps.as_slice() {
        [ma, mb] => Some(compare_maps(ma, mb)?),
        _ => None,
    };
    let target = if args.quiet {
        ProgressDrawTarget::hidden()
    } else {
        ProgressDrawTarget::stderr()
    };
    let bar = ProgressBar::with_draw_target(Some((a.blocks() + b.blocks()) as u64), target);
    if let Ok(style) = ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} · {elapsed}") {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_message("reading blocks");
    bar.enable_steady_tick(Duration::from_millis(200));
    let diff = diff_images(&a, &b, &lights, |done, _| bar.set_position(done as u64));
    bar.finish_and_clear();
    let diff = diff?;
    if args.json {
        let mut value = serde_json::to_value(&diff)?;
        if let Some(m) = &maps {
            value["maps"] = serde_json::to_value(m)?;
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        print_text(&diff, maps.as_ref());
    }
    Ok(ExitCode::SUCCESS)
}

fn print_text(diff: &ImageDiff, maps: Option<&MapComparison>) {
    println!(
        "{} against {}: {}×{} pixels, {} cells each; {} compared, {} skipped (non-finite cells: {} pixel(s) in the first, {} in the second)",
        diff.a.display(),
        diff.b.display(),
        diff.width,
        diff.height,
        diff.cells,
        diff.compared,
        diff.skipped,
        diff.non_finite_a,
        diff.non_finite_b
    );
    println!(
        "  {:<8} {:>9} {:>9} {:>9} {:>9}",
        "ΔE2000", "median", "90th", "99th", "max"
    );
    for l in &diff.lights {
        println!(
            "  {:<8} {:>9.4} {:>9.4} {:>9.4} {:>9.4}",
            l.light, l.median, l.p90, l.p99, l.max
        );
    }
    if let Some(m) = maps {
        println!(
            "  fluorophores: {} in the first map, {} in the second",
            m.fluorophores_a, m.fluorophores_b
        );
        for pair in &m.matches {
            println!(
                "  c{} ↔ c{}: concentration maps correlate {:.4}",
                pair.a, pair.b, pair.correlation
            );
        }
        for k in &m.unmatched_a {
            println!("  c{k} of the first map: no match");
        }
        for k in &m.unmatched_b {
            println!("  c{k} of the second map: no match");
        }
    }
}
