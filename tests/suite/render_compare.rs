//! `render --compare`: the fluorescent sphere keeps its colour under daylight and UV
//! (few clipped pixels on the spheres at the automatic exposure, many at the old fixed
//! one), and a label strip under the render says which sphere is which.

use crate::common;

use std::path::{Path, PathBuf};

use fluorite::colour::Light;
use fluorite::render::compare::{object_pixels, strip_height};
use fluorite::render::{RenderSettings, Scene, SceneKind};
use fluorite::synth::SynthSpec;

const WIDTH: u32 = 160;
const HEIGHT: u32 = 80;

use crate::common::fluorite;

/// 8-bit RGB pixels, width and height of a PNG.
fn read_png(path: &Path) -> (Vec<u8>, u32, u32) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buffer).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buffer.truncate(info.buffer_size());
    (buffer, info.width, info.height)
}

fn render_compare(material: &Path, light: &str, exposure: Option<&str>, out: &Path) -> PathBuf {
    let png = out.join(format!(
        "compare-{light}-{}.png",
        exposure.unwrap_or("auto")
    ));
    let mut command = fluorite();
    command
        .args([
            "render",
            material.to_str().unwrap(),
            "--compare",
            "--light",
            light,
        ])
        .args(["--size", &format!("{WIDTH}x{HEIGHT}"), "--spp", "16", "-q"]);
    if let Some(ev) = exposure {
        command.args(["--exposure", ev]);
    }
    common::succeed(command.arg("-o").arg(&png));
    png
}

/// Share of the pixels of both spheres that are flat white (all channels 255).
fn clipped_share(rgb: &[u8], spheres: &[usize]) -> f64 {
    let clipped = spheres
        .iter()
        .filter(|&&i| rgb[3 * i..3 * i + 3].iter().all(|&c| c == 255))
        .count();
    clipped as f64 / spheres.len() as f64
}

#[test]
fn compare_keeps_the_fluorescent_colour_and_labels_both_spheres() {
    let out = common::temp_dir("compare");
    // The green dye's lit side is far brighter than white under UV: at the old fixed
    // exposure (-0.5 EV) it is flat white.
    let material = SynthSpec::preset("green-dye").unwrap().truth().unwrap();
    let path = out.join("green-dye.json");
    material.save(&path).unwrap();
    let settings = RenderSettings {
        width: WIDTH,
        height: HEIGHT,
        samples_per_pixel: 1,
        seed: 1,
    };
    let mut fixed_clipped = Vec::new();
    for light in ["d65", "uv"] {
        let scene = Scene::build(
            SceneKind::Preview,
            &material,
            &Light::parse(light).unwrap(),
            true,
            settings.aspect(),
        )
        .unwrap();
        let fluorescent = object_pixels(&scene, &settings, 0);
        let twin = object_pixels(&scene, &settings, 1);
        assert!(fluorescent.len() > 500 && twin.len() > 500);
        // The fluorescent sphere is on the left, its twin on the right.
        let column = |pixels: &[usize]| {
            pixels.iter().map(|i| i % WIDTH as usize).sum::<usize>() / pixels.len()
        };
        assert!(column(&fluorescent) < WIDTH as usize / 2 && column(&twin) > WIDTH as usize / 2);
        let spheres: Vec<usize> = fluorescent.iter().chain(&twin).copied().collect();

        let (rgb, width, height) = read_png(&render_compare(&path, light, None, &out));
        assert_eq!(width, WIDTH);
        assert_eq!(
            height,
            HEIGHT + strip_height(WIDTH),
            "the label strip is below"
        );
        let share = clipped_share(&rgb, &spheres);
        assert!(
            share < 0.02,
            "{light}: {:.1} % of the spheres clip",
            100.0 * share
        );
        // The fluorescent sphere keeps a hue rather than turning white or grey: its mean
        // channels stay well apart (a yellow-green under D65, green under UV).
        let mean = |c: usize| {
            fluorescent
                .iter()
                .map(|&i| rgb[3 * i + c] as f64)
                .sum::<f64>()
                / fluorescent.len() as f64
        };
        let means = [mean(0), mean(1), mean(2)];
        let spread = means.iter().fold(f64::MIN, |a, &b| a.max(b))
            - means.iter().fold(f64::MAX, |a, &b| a.min(b));
        assert!(
            spread > 40.0 && means[1] >= means[0] && means[1] > means[2],
            "{light}: mean sRGB {means:?}"
        );

        // Dark text in the strip, under each sphere's half of the picture.
        let dark = |x0: u32, x1: u32| {
            (HEIGHT..height)
                .flat_map(|y| (x0..x1).map(move |x| (y * width + x) as usize))
                .filter(|&i| rgb[3 * i..3 * i + 3].iter().all(|&c| c < 110))
                .count()
        };
        assert!(
            dark(0, WIDTH / 2) > 30,
            "{light}: no label under the left sphere"
        );
        assert!(
            dark(WIDTH / 2, WIDTH) > 30,
            "{light}: no label under the right sphere"
        );
        // Above the strip the render is as rendered: no text drawn over it.
        let strip_top = &rgb[3 * (HEIGHT * width) as usize..3 * ((HEIGHT + 1) * width) as usize];
        assert!(
            strip_top.iter().all(|&c| c == 255),
            "{light}: the strip starts white"
        );

        let (fixed, _, _) = read_png(&render_compare(&path, light, Some("-0.5"), &out));
        fixed_clipped.push(clipped_share(&fixed, &spheres));
    }
    // The scene is a hard one: the old fixed exposure clipped under UV.
    assert!(
        fixed_clipped[1] > 0.05,
        "at -0.5 EV under uv only {:.1} % clip",
        100.0 * fixed_clipped[1]
    );
    std::fs::remove_dir_all(&out).unwrap();
}
