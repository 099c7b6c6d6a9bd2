//! Renderer exports read back with readers written from the targets' own sources, and
//! the baked total radiance factor checked against an independent computation.
//!
//! - pbrt-v4 (mmp/pbrt-v4): `src/pbrt/util/file.cpp` `ReadFloatFile` (a 32-character
//!   number buffer, `#` comments, `std::stof`) and `PiecewiseLinearSpectrum::Read`.
//! - Mitsuba 3 (mitsuba-renderer/mitsuba3, `src/core/parser.cpp`,
//!   `src/core/properties.cpp`): the root's `version`, the tags it knows, `<spectrum>`
//!   with exactly one of `value`/`filename`, `value` as `λ:v` pairs; the plugin and
//!   parameter names of the stock plugins used and of the fork's `diffusefluoro`
//!   (blzq/mitsuba3, branch fluorescence, `src/bsdfs/diffuse_fluoro.cpp`).
//! - PearRay (PearCoding/PearRay): `src/base/container/CSV.cpp` (no comments, `,` or `;`
//!   separators, a header row when a first-row field is not a number, `std::stof`),
//!   `src/plugins/main/node/SPDFileNode.cpp` (equidistant rows, values clamped at 0), and
//!   the `fluorescent` material's parameters (`fluorescent_diffuse.cpp`).
//! - ART (BUG-Association/ART): `Source/ClassLibraries/Parser/ArfMeasurementArchive.m`.
//!
//! The truth for every value is computed here from the material's spectra with plain
//! sums (linear interpolation, 1 nm trapezoid weights over 300–830 nm), not by the code
//! under test.

use std::path::Path;

use fluorite::colour::{Light, cie1931};
use fluorite::export::{ExportFormat, ExportOptions};
use fluorite::material::{Material, YieldForm};
use fluorite::synth::SynthSpec;

use crate::common;

// ---- the truth, computed independently ------------------------------------------

/// Linear interpolation of samples; `zero_outside` false holds the end values.
fn interp(xs: &[f64], ys: &[f64], x: f64, zero_outside: bool) -> f64 {
    let n = xs.len();
    if x < xs[0] || x > xs[n - 1] {
        return if zero_outside {
            0.0
        } else if x < xs[0] {
            ys[0]
        } else {
            ys[n - 1]
        };
    }
    let k = xs.partition_point(|&v| v <= x).clamp(1, n - 1);
    let t = (x - xs[k - 1]) / (xs[k] - xs[k - 1]);
    ys[k - 1] + t * (ys[k] - ys[k - 1])
}

/// Trapezoid weights of a grid.
fn trapezoid(grid: &[f64]) -> Vec<f64> {
    let n = grid.len();
    (0..n)
        .map(|i| 0.5 * (grid[(i + 1).min(n - 1)] - grid[i.saturating_sub(1)]))
        .collect()
}

/// The 1 nm grid 300–830 nm and its trapezoid weights.
fn grid() -> (Vec<f64>, Vec<f64>) {
    let g: Vec<f64> = (300..=830).map(f64::from).collect();
    let w = trapezoid(&g);
    (g, w)
}

fn light_power(light: &Light, l: f64) -> f64 {
    interp(
        &light.spectrum.wavelength_nm,
        &light.spectrum.value,
        l,
        true,
    )
}

/// The model's pieces for one material, from its samples.
struct Truth<'a> {
    m: &'a Material,
    /// λ̄e per fluorophore (trapezoid on the emission's own samples).
    means: Vec<f64>,
}

impl<'a> Truth<'a> {
    fn new(m: &'a Material) -> Self {
        let means = m
            .fluorophores
            .iter()
            .map(|f| {
                let w = trapezoid(&f.emission.wavelength_nm);
                let (mut num, mut den) = (0.0, 0.0);
                for ((l, e), w) in f
                    .emission
                    .wavelength_nm
                    .iter()
                    .zip(&f.emission.value)
                    .zip(&w)
                {
                    num += l * e * w;
                    den += e * w;
                }
                num / den
            })
            .collect();
        Truth { m, means }
    }
    fn a(&self, k: usize, l: f64) -> f64 {
        let f = &self.m.fluorophores[k];
        interp(&f.absorption.wavelength_nm, &f.absorption.value, l, true)
    }
    fn e(&self, k: usize, l: f64) -> f64 {
        let f = &self.m.fluorophores[k];
        interp(&f.emission.wavelength_nm, &f.emission.value, l, true)
    }
    fn r(&self, l: f64) -> f64 {
        let r = &self.m.reflectance;
        interp(&r.wavelength_nm, &r.value, l, false)
    }
    /// d = (1 − Σc·a)·r.
    fn d(&self, l: f64) -> f64 {
        let absorbed: f64 = (0..self.m.fluorophores.len())
            .map(|k| self.m.fluorophores[k].concentration * self.a(k, l))
            .sum();
        (1.0 - absorbed) * self.r(l)
    }
    /// X = c·Q(λ)·a(λ), Q(λ) = Φ·λ/λ̄e in the photon form.
    fn x(&self, k: usize, l: f64) -> f64 {
        let f = &self.m.fluorophores[k];
        let q = match f.yield_form {
            YieldForm::Energy => f.quantum_yield,
            YieldForm::Photon => f.quantum_yield * l / self.means[k],
        };
        f.concentration * q * self.a(k, l)
    }
    /// ∫ X_k·L dλ per fluorophore.
    fn reemitted(&self, light: &Light) -> Vec<f64> {
        let (g, w) = grid();
        (0..self.m.fluorophores.len())
            .map(|k| {
                g.iter()
                    .zip(&w)
                    .map(|(&l, w)| self.x(k, l) * light_power(light, l) * w)
                    .sum()
            })
            .collect()
    }
    /// βT(λ) = d + Σ e_k·∫X_k·L / L on the 1 nm grid (d where L = 0).
    fn beta_t(&self, light: &Light) -> Vec<(f64, f64)> {
        let r = self.reemitted(light);
        grid()
            .0
            .into_iter()
            .map(|l| {
                let p = light_power(light, l);
                let fl: f64 = (0..r.len()).map(|k| r[k] * self.e(k, l)).sum();
                (
                    l,
                    if p > 0.0 {
                        self.d(l) + fl / p
                    } else {
                        self.d(l)
                    },
                )
            })
            .collect()
    }
    /// XYZ of the full bispectral model under `light` (the patch's radiance integrated
    /// against the observer), on the 1 nm grid.
    fn xyz_bispectral(&self, light: &Light) -> [f64; 3] {
        let (g, w) = grid();
        let r = self.reemitted(light);
        let mut xyz = [0.0; 3];
        for (&l, w) in g.iter().zip(&w) {
            let radiance = self.d(l) * light_power(light, l)
                + (0..r.len()).map(|k| r[k] * self.e(k, l)).sum::<f64>();
            let cmf = cie1931().at(l);
            for c in 0..3 {
                xyz[c] += radiance * cmf[c] * w;
            }
        }
        xyz
    }
}

/// XYZ of a reflectance spectrum (samples, linear between) under `light`, on the grid.
fn xyz_reflectance(samples: &[(f64, f64)], light: &Light) -> [f64; 3] {
    let xs: Vec<f64> = samples.iter().map(|s| s.0).collect();
    let ys: Vec<f64> = samples.iter().map(|s| s.1).collect();
    let (g, w) = grid();
    let mut xyz = [0.0; 3];
    for (&l, w) in g.iter().zip(&w) {
        let radiance = interp(&xs, &ys, l, true) * light_power(light, l);
        let cmf = cie1931().at(l);
        for c in 0..3 {
            xyz[c] += radiance * cmf[c] * w;
        }
    }
    xyz
}

/// Within f32 rounding of the shortest round-trip text: 2^-23 relative, plus an
/// absolute floor for values near 0.
fn f32_close(got: f64, want: f64, floor: f64) -> bool {
    (got - want).abs() <= 2.4e-7 * want.abs() + floor
}

// ---- materials -----------------------------------------------------------------

fn materials() -> Vec<Material> {
    let mut out: Vec<Material> = ["green-dye", "two-dyes", "brightener"]
        .iter()
        .map(|p| SynthSpec::preset(p).unwrap().truth().unwrap())
        .collect();
    let mut photon = out[0].clone();
    photon.name = "green-photon".into();
    photon.fluorophores[0].yield_form = YieldForm::Photon;
    photon.fluorophores[0].quantum_yield = 0.8;
    photon.validate().unwrap();
    out.push(photon);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fits/measured");
    for name in ["HERPICER", "CIBA12", "postit_pink"] {
        out.push(Material::load(&dir.join(format!("{name}.json"))).unwrap());
    }
    out
}

fn lights() -> Vec<Light> {
    ["d65", "a"]
        .iter()
        .map(|n| Light::builtin(n).unwrap())
        .collect()
}

/// The files of `m` in `format`, under D65 and A for the formats that use lights (the
/// others refuse lights).
fn render(m: &Material, format: ExportFormat) -> Vec<(String, String)> {
    let options = ExportOptions {
        lights: if format.uses_lights() {
            lights()
        } else {
            Vec::new()
        },
        ..ExportOptions::new(format)
    };
    common::exported(m, &options)
}

fn file<'a>(files: &'a [(String, String)], name: &str) -> &'a str {
    common::named(files, name)
}

// ---- pbrt-v4 -------------------------------------------------------------------

/// `ReadFloatFile` of pbrt-v4: numbers are runs of digits, `.`, `e`, `E`, `-`, `+`
/// (starting with a digit, `.`, `-` or `+`) gathered into `char curNumber[32]`, which
/// overflows (LOG_FATAL) at 32 characters, so a number has at most 31; any other
/// character ends a number, `#` outside a number skips to the end of the line, and any
/// other non-space character outside a number is an error. A number still open at the
/// end of the file is dropped. Each number goes through `std::stof`, which throws (an
/// error) on text that is not a float and on values out of float range: overflow, and
/// underflow below the normal minimum 1.18e-38 (ERANGE).
fn pbrt_read_float_file(text: &str) -> Result<Vec<f32>, String> {
    let stof = |s: &str| -> Result<f32, String> {
        let v: f32 = s.parse().map_err(|_| format!("unable to parse \"{s}\""))?;
        if v.is_infinite() || (v != 0.0 && v.abs() < f32::MIN_POSITIVE) {
            return Err(format!("\"{s}\" out of float range"));
        }
        Ok(v)
    };
    let mut values = Vec::new();
    let mut number: Option<String> = None;
    let mut chars = text.chars();
    let mut line = 1;
    while let Some(c) = chars.next() {
        if c == '\n' {
            line += 1;
        }
        if let Some(n) = number.as_mut() {
            if n.len() >= 32 {
                return Err(format!("line {line}: overflowed buffer for parsing number"));
            }
            if c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+') {
                n.push(c);
            } else {
                values.push(stof(n)?);
                number = None;
            }
        } else if c.is_ascii_digit() || matches!(c, '.' | '-' | '+') {
            number = Some(c.to_string());
        } else if c == '#' {
            for c in chars.by_ref() {
                if c == '\n' {
                    break;
                }
            }
            line += 1;
        } else if !c.is_ascii_whitespace() {
            return Err(format!("unexpected character \"{c}\" at line {line}"));
        }
    }
    Ok(values)
}

/// `PiecewiseLinearSpectrum::Read`: an even count of numbers, increasing wavelengths.
fn pbrt_spectrum(text: &str) -> Vec<(f64, f64)> {
    let v = pbrt_read_float_file(text).unwrap();
    assert!(
        !v.is_empty() && v.len().is_multiple_of(2),
        "{} values",
        v.len()
    );
    let pairs: Vec<(f64, f64)> = v
        .chunks(2)
        .map(|p| (f64::from(p[0]), f64::from(p[1])))
        .collect();
    assert!(pairs.windows(2).all(|w| w[1].0 > w[0].0));
    pairs
}

#[test]
fn pbrt_reader_enforces_the_buffer_and_stof() {
    assert_eq!(
        pbrt_read_float_file("# c\n300 0.5\n301 1e-3\n").unwrap(),
        vec![300.0, 0.5, 301.0, 1e-3]
    );
    let long = format!("300 0.{}\n", "1".repeat(31));
    assert!(
        pbrt_read_float_file(&long)
            .unwrap_err()
            .contains("overflowed")
    );
    assert!(pbrt_read_float_file("300 1e-39\n").is_err());
    assert!(pbrt_read_float_file("300 x\n").is_err());
}

/// pbrt-v4's `"spectrum"` parameter given inline, as `ParameterDictionary::
/// extractSpectrumArray` takes it: numbers between `[` and `]`, an even count of them,
/// read as (λ, value) pairs with λ strictly increasing; `None` when the parameter names a
/// file or a named spectrum instead.
fn pbrt_inline_spectrum(scene: &str, material: &str, parameter: &str) -> Option<Vec<(f64, f64)>> {
    let start = scene.find(&format!("MakeNamedMaterial \"{material}\""))?;
    let rest = &scene[start..];
    let key = format!("\"spectrum {parameter}\"");
    let after = rest[rest.find(&key)? + key.len()..].trim_start();
    let body = after.strip_prefix('[')?;
    let body = &body[..body.find(']').expect("the array is closed")];
    let numbers: Vec<f64> = body
        .split_whitespace()
        .map(|t| t.parse().expect("pbrt reads every token as a number"))
        .collect();
    assert!(
        numbers.len().is_multiple_of(2),
        "Found odd number of values"
    );
    let pairs: Vec<(f64, f64)> = numbers.chunks(2).map(|p| (p[0], p[1])).collect();
    for w in pairs.windows(2) {
        assert!(
            w[1].0 > w[0].0,
            "Spectrum description invalid: wavelengths not increasing"
        );
    }
    Some(pairs)
}

/// Every pbrt-v4 file parses with pbrt's readers; the named materials carry the baked βT
/// inline (no file for pbrt to resolve against the main scene's folder) and match the
/// truth, as do the `.spd` files beside them.
#[test]
fn pbrt_files_parse_and_hold_the_baked_factor() {
    for m in materials() {
        let truth = Truth::new(&m);
        let files = render(&m, ExportFormat::Pbrt);
        for (name, text) in &files {
            if name.ends_with(".spd") {
                pbrt_spectrum(text);
                assert!(text.lines().next().unwrap().starts_with("# fluorite"));
                assert!(text.contains("wavelength (nm)"), "{name}");
            }
        }
        let scene = file(&files, &format!("{}.pbrt", m.name));
        for light in lights() {
            let want = truth.beta_t(&light);
            let material = format!("{}_{}", m.name, light.name);
            let inline = pbrt_inline_spectrum(scene, &material, "reflectance")
                .unwrap_or_else(|| panic!("{material}: no inline reflectance"));
            let baked = pbrt_spectrum(file(
                &files,
                &format!("{}_baked_{}.spd", m.name, light.name),
            ));
            for spectrum in [&inline, &baked] {
                assert_eq!(spectrum.len(), want.len());
                for ((l, v), (wl, wv)) in spectrum.iter().zip(&want) {
                    assert_eq!(l, wl);
                    assert!(
                        f32_close(*v, *wv, 1e-12),
                        "{} {} {l}: {v} vs {wv}",
                        m.name,
                        light.name
                    );
                }
            }
        }
        let albedo = pbrt_inline_spectrum(scene, &format!("{}_albedo", m.name), "reflectance")
            .expect("the albedo material's reflectance is inline");
        // Both as pbrt holds them, in f32.
        let single = |s: &[(f64, f64)]| -> Vec<(f32, f32)> {
            s.iter().map(|(l, v)| (*l as f32, *v as f32)).collect()
        };
        assert_eq!(
            single(&albedo),
            single(&pbrt_spectrum(file(
                &files,
                &format!("{}_albedo.spd", m.name)
            )))
        );
        assert!(scene.contains("clamps its reflectance to [0, 1]"));
        // No parameter of the snippet names a file.
        assert!(
            !scene
                .lines()
                .any(|l| !l.starts_with('#') && l.contains(".spd"))
        );
    }
}

// ---- Mitsuba 3 -------------------------------------------------------------------

/// An XML element: tag, attributes, children.
#[derive(Debug)]
struct Element {
    tag: String,
    attributes: Vec<(String, String)>,
    children: Vec<Element>,
}

impl Element {
    fn attribute(&self, name: &str) -> Option<&str> {
        self.attributes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
    fn walk<'a>(&'a self, out: &mut Vec<&'a Element>) {
        out.push(self);
        for c in &self.children {
            c.walk(out);
        }
    }
}

/// A strict reader of the XML subset the exports use (pugixml accepts it): a prolog,
/// comments without `--`, elements with double-quoted attributes, no text content.
fn parse_xml(text: &str) -> Result<Element, String> {
    let mut rest = text.trim_start();
    if let Some(after) = rest.strip_prefix("<?xml") {
        let end = after.find("?>").ok_or("unterminated prolog")?;
        rest = &after[end + 2..];
    }
    let mut stack: Vec<Element> = Vec::new();
    let mut root = None;
    loop {
        rest = rest.trim_start();
        if rest.is_empty() {
            break;
        }
        if let Some(after) = rest.strip_prefix("<!--") {
            let end = after.find("-->").ok_or("unterminated comment")?;
            if after[..end].contains("--") {
                return Err("\"--\" inside a comment".into());
            }
            rest = &after[end + 3..];
            continue;
        }
        if let Some(after) = rest.strip_prefix("</") {
            let end = after.find('>').ok_or("unterminated end tag")?;
            let element = stack.pop().ok_or("end tag without start")?;
            if after[..end].trim() != element.tag {
                return Err(format!("</{}> closes <{}>", &after[..end], element.tag));
            }
            rest = &after[end + 1..];
            match stack.last_mut() {
                Some(parent) => parent.children.push(element),
                None => root = Some(element),
            }
            continue;
        }
        let after = rest
            .strip_prefix('<')
            .ok_or(format!("text content: {:.40}", rest))?;
        let name_end = after
            .find(|c: char| c.is_whitespace() || c == '>' || c == '/')
            .ok_or("unterminated tag")?;
        let mut element = Element {
            tag: after[..name_end].to_string(),
            attributes: Vec::new(),
            children: Vec::new(),
        };
        let mut inner = &after[name_end..];
        loop {
            inner = inner.trim_start();
            if let Some(r) = inner.strip_prefix("/>") {
                rest = r;
                match stack.last_mut() {
                    Some(parent) => parent.children.push(element),
                    None => root = Some(element),
                }
                break;
            }
            if let Some(r) = inner.strip_prefix('>') {
                rest = r;
                stack.push(element);
                break;
            }
            let eq = inner.find('=').ok_or("attribute without value")?;
            let name = inner[..eq].trim().to_string();
            let value = inner[eq + 1..]
                .strip_prefix('"')
                .ok_or("unquoted attribute")?;
            let close = value.find('"').ok_or("unterminated attribute")?;
            if value[..close].contains(['<', '&']) {
                return Err(format!("unescaped character in {name}"));
            }
            element.attributes.push((name, value[..close].to_string()));
            inner = &value[close + 1..];
        }
    }
    if !stack.is_empty() {
        return Err("unclosed elements".into());
    }
    root.ok_or_else(|| "no root element".into())
}

/// `Properties::Spectrum(std::string_view)`: tokens split at `,` and ` `, each a
/// `wavelength:value` pair parsed with `string::stof`; at least two entries, wavelengths
/// strictly increasing.
fn mitsuba_spectrum(value: &str) -> Vec<(f64, f64)> {
    let pairs: Vec<(f64, f64)> = value
        .split([',', ' '])
        .filter(|t| !t.is_empty())
        .map(|t| {
            let (l, v) = t.split_once(':').unwrap_or_else(|| panic!("token {t}"));
            assert!(!v.contains(':'), "{t}");
            (l.parse().unwrap(), v.parse().unwrap())
        })
        .collect();
    assert!(pairs.len() >= 2);
    assert!(pairs.windows(2).all(|w| w[1].0 > w[0].0));
    pairs
}

/// Tags Mitsuba's parser knows (`tag_type` in parser.cpp) among those used, the plugin
/// type each object may have, and the named parameters each plugin reads.
const MITSUBA_TAGS: [&str; 14] = [
    "scene",
    "integrator",
    "sensor",
    "film",
    "rfilter",
    "sampler",
    "emitter",
    "bsdf",
    "shape",
    "transform",
    "lookat",
    "float",
    "integer",
    "spectrum",
];

/// Checks one scene file, returns (integrator, bsdf type, the bsdf's spectra by name,
/// the emitter's spectrum).
fn check_mitsuba_scene(text: &str) -> (String, Element, Vec<(f64, f64)>) {
    let root = parse_xml(text).unwrap();
    assert_eq!(root.tag, "scene");
    let version = root.attribute("version").expect("version attribute");
    let parts: Vec<u32> = version.split('.').map(|p| p.parse().unwrap()).collect();
    assert_eq!(parts.len(), 3);
    assert!(
        parts[0] >= 2,
        "version {version} is upgraded as Mitsuba 0.x"
    );
    let mut all = Vec::new();
    root.walk(&mut all);
    for e in &all {
        assert!(
            MITSUBA_TAGS.contains(&e.tag.as_str()) || e.tag == "ref",
            "<{}>",
            e.tag
        );
        if e.tag == "spectrum" {
            assert!(e.attribute("name").is_some());
            assert!(
                e.attribute("value").is_some() != e.attribute("filename").is_some(),
                "a <spectrum> needs value or filename, not both"
            );
        }
    }
    let of =
        |tag: &str| -> Vec<&Element> { all.iter().copied().filter(|e| e.tag == tag).collect() };
    let integrator = of("integrator")[0].attribute("type").unwrap().to_string();
    assert_eq!(of("sensor")[0].attribute("type"), Some("perspective"));
    assert_eq!(of("film")[0].attribute("type"), Some("hdrfilm"));
    let emitter = of("emitter")[0];
    assert_eq!(emitter.attribute("type"), Some("constant"));
    assert_eq!(emitter.children[0].attribute("name"), Some("radiance"));
    let radiance = mitsuba_spectrum(emitter.children[0].attribute("value").unwrap());
    let bsdfs = of("bsdf");
    assert_eq!(bsdfs.len(), 1);
    let bsdf = bsdfs[0];
    let id = bsdf.attribute("id").unwrap();
    let shape = of("shape")[0];
    assert_eq!(shape.attribute("type"), Some("sphere"));
    assert_eq!(shape.children[0].tag, "ref");
    assert_eq!(shape.children[0].attribute("id"), Some(id));
    let bsdf = Element {
        tag: bsdf.attribute("type").unwrap().to_string(),
        attributes: bsdf.attributes.clone(),
        children: bsdf
            .children
            .iter()
            .map(|c| Element {
                tag: c.tag.clone(),
                attributes: c.attributes.clone(),
                children: Vec::new(),
            })
            .collect(),
    };
    (integrator, bsdf, radiance)
}

fn spectrum_param(bsdf: &Element, name: &str) -> Vec<(f64, f64)> {
    let e = bsdf
        .children
        .iter()
        .find(|c| c.attribute("name") == Some(name))
        .unwrap_or_else(|| panic!("no {name}"));
    assert_eq!(e.tag, "spectrum");
    mitsuba_spectrum(e.attribute("value").unwrap())
}

/// Stock scenes: plugin `diffuse` with `reflectance` = βT for that light (the truth to
/// f32), the emitter proportional to the light; the fork's scene: `diffusefluoro` with
/// reflectance d, fluorescence e and excitation X of the strongest fluorophore.
#[test]
fn mitsuba_scenes_use_real_plugins_and_hold_the_baked_factor() {
    for m in materials() {
        let truth = Truth::new(&m);
        let files = render(&m, ExportFormat::Mitsuba);
        for light in lights() {
            let text = file(&files, &format!("{}_{}.xml", m.name, light.name));
            assert!(text.contains(&format!("VALID UNDER LIGHT \"{}\" ONLY", light.name)));
            let (integrator, bsdf, radiance) = check_mitsuba_scene(text);
            assert_eq!(integrator, "path");
            assert_eq!(bsdf.tag, "diffuse");
            assert_eq!(bsdf.children.len(), 1);
            let baked = spectrum_param(&bsdf, "reflectance");
            let want = truth.beta_t(&light);
            assert_eq!(baked.len(), want.len());
            for ((l, v), (wl, wv)) in baked.iter().zip(&want) {
                assert_eq!(l, wl);
                assert!(f32_close(*v, *wv, 1e-12), "{} {l}: {v} vs {wv}", m.name);
            }
            let ratio = radiance[0].1 / light.spectrum.value[0];
            for ((l, p), (wl, wp)) in radiance.iter().zip(
                light
                    .spectrum
                    .wavelength_nm
                    .iter()
                    .zip(&light.spectrum.value),
            ) {
                assert_eq!(l, wl);
                // The first value fixed the ratio: two f32 roundings apart.
                assert!((p - wp * ratio).abs() <= 5e-7 * wp * ratio + 1e-9, "{l}");
            }
        }
        let fork = format!("{}_fluoro.xml", m.name);
        let (integrator, bsdf, _) = check_mitsuba_scene(file(&files, &fork));
        assert_eq!(integrator, "pathfluoro");
        assert_eq!(bsdf.tag, "diffusefluoro");
        let mut names: Vec<&str> = bsdf
            .children
            .iter()
            .filter_map(|c| c.attribute("name"))
            .collect();
        names.sort();
        assert_eq!(names, ["excitation", "fluorescence", "reflectance"]);
        // The strongest fluorophore under D65 (the first light), found here by brute force.
        let reemitted = truth.reemitted(&lights()[0]);
        let k = (0..reemitted.len())
            .max_by(|&a, &b| reemitted[a].total_cmp(&reemitted[b]))
            .unwrap();
        for (l, v) in spectrum_param(&bsdf, "reflectance") {
            assert!(f32_close(v, truth.d(l), 1e-12), "d at {l}");
        }
        for (l, v) in spectrum_param(&bsdf, "fluorescence") {
            assert!(f32_close(v, truth.e(k, l), 1e-12), "e at {l}");
        }
        for (l, v) in spectrum_param(&bsdf, "excitation") {
            assert!(f32_close(v, truth.x(k, l), 1e-12), "X at {l}");
        }
        let n = m.fluorophores.len();
        assert_eq!(
            file(&files, &fork).contains(&format!("This material has {n} fluorophores")),
            n > 1
        );
    }
}

/// The furnace identity: βT read from the export, lit by L and seen by the CIE observer,
/// gives the XYZ of the full bispectral model under L (to f32 rounding of the file).
#[test]
fn baked_factor_reproduces_the_bispectral_colour_under_its_light() {
    for m in materials() {
        let truth = Truth::new(&m);
        let files = render(&m, ExportFormat::Mitsuba);
        for light in lights() {
            let (_, bsdf, _) =
                check_mitsuba_scene(file(&files, &format!("{}_{}.xml", m.name, light.name)));
            let baked = spectrum_param(&bsdf, "reflectance");
            let got = xyz_reflectance(&baked, &light);
            let want = truth.xyz_bispectral(&light);
            let worst = (0..3)
                .map(|c| (got[c] - want[c]).abs() / want[c])
                .fold(0.0, f64::max);
            println!(
                "{} under {}: XYZ of the baked factor within {worst:.1e} of the bispectral model",
                m.name, light.name
            );
            for c in 0..3 {
                let rel = (got[c] - want[c]).abs() / want[c];
                assert!(
                    rel < 1e-6,
                    "{} {} XYZ[{c}]: {} vs {} ({rel:e})",
                    m.name,
                    light.name,
                    got[c],
                    want[c]
                );
            }
            // And under the other light the baked factor is wrong whenever the material
            // fluoresces: it is valid for its own light only.
            let other = lights().into_iter().find(|l| l.name != light.name).unwrap();
            let off = xyz_reflectance(&baked, &other);
            let right = truth.xyz_bispectral(&other);
            if !m.fluorophores.is_empty() {
                assert!((off[1] - right[1]).abs() / right[1] > 1e-4, "{}", m.name);
            }
        }
    }
}

// ---- PearRay -------------------------------------------------------------------

/// `CSV::read` of PearRay: the first line sets the column count (fields split at `,` or
/// `;`, empty fields skipped) and is a header when one field is not a number
/// (`std::stof` throws); every other line must have that many fields, each converted
/// completely by `std::stof` (PearRay logs an error otherwise); out-of-range values
/// become 0. Returns (header, rows).
fn pearray_csv(text: &str) -> (Vec<String>, Vec<Vec<f32>>) {
    let split = |line: &str| -> Vec<String> {
        line.split([',', ';'])
            .filter(|f| !f.is_empty())
            .map(String::from)
            .collect()
    };
    let stof = |s: &str| -> Option<f32> {
        let v: f32 = s.parse().ok()?;
        Some(
            if v.is_infinite() || (v != 0.0 && v.abs() < f32::MIN_POSITIVE) {
                0.0
            } else {
                v
            },
        )
    };
    let mut lines = text.split('\n');
    let first = split(lines.next().unwrap());
    let header = first.iter().any(|f| stof(f).is_none());
    assert!(header, "no header row");
    let mut rows = Vec::new();
    for line in lines.filter(|l| !l.is_empty()) {
        let fields = split(line);
        assert_eq!(fields.len(), first.len(), "malformed line {line:?}");
        rows.push(
            fields
                .iter()
                .map(|f| stof(f).unwrap_or_else(|| panic!("invalid entry {f:?} in {line:?}")))
                .collect(),
        );
    }
    (first, rows)
}

/// The PearRay export reads back to the model: an `add` of a `diffuse` of 2·d and a
/// `fluorescent` with albedo 0 whose c'·Q'·a'(λi)·e(λo) is the kept fluorophore's
/// X(λi)·e(λo), with `scale` twice span·Σ400 e (what PearRay's material divides by), from
/// a CSV PearRay's reader and spd node take (equidistant rows, no comments, no negative
/// values).
#[test]
fn pearray_material_reads_back_to_the_model() {
    for m in materials() {
        let truth = Truth::new(&m);
        let files = render(&m, ExportFormat::Pearray);
        let prc = file(&files, &format!("{}.prc", m.name));
        let csv_name = format!("{}_pearray.csv", m.name);
        let number = |key: &str| -> f64 {
            let line = prc
                .lines()
                .find(|l| l.trim_start().starts_with(&format!(":{key} ")))
                .unwrap_or_else(|| panic!(":{key} missing"));
            line.trim_start()[key.len() + 2..].trim().parse().unwrap()
        };
        let reemitted = truth.reemitted(&lights()[0]);
        let k = (0..reemitted.len()).max_by(|&a, &b| reemitted[a].total_cmp(&reemitted[b]));
        if k.is_none() {
            continue; // a_plain_material_exports_as_plain_diffuse
        }
        let name = &m.name;
        for block in [
            format!(
                "(material\n\t:name '{name}_reflectance'\n\t:type 'diffuse'\n\t:albedo (spd '{csv_name}' 3)\n)\n"
            ),
            format!(
                "(material\n\t:name '{name}_fluorescence'\n\t:type 'fluorescent'\n\t:absorption (spd '{csv_name}' 1)\n\t:emission (spd '{csv_name}' 2)\n\t:albedo 0\n"
            ),
            format!(
                "(material\n\t:name '{name}'\n\t:type 'add'\n\t:material1 '{name}_reflectance'\n\t:material2 '{name}_fluorescence'\n)\n"
            ),
        ] {
            assert!(prc.contains(&block), "{block}\n{prc}");
        }
        for line in prc.lines().filter(|l| !l.starts_with(';')) {
            assert!(!line.contains(';'), "{line}");
        }
        let (q, c, scale) = (number("aefactor"), number("concentration"), number("scale"));
        assert!(
            (0.0..=1.0).contains(&q) && (0.0..=1.0).contains(&c),
            "Number01"
        );
        let (header, rows) = pearray_csv(file(&files, &csv_name));
        assert_eq!(
            header,
            ["wavelength", "absorption", "emission", "reflectance_x2"]
        );
        let start = rows[0][0];
        let delta = rows[1][0] - rows[0][0];
        assert!(delta > 0.0);
        for (i, row) in rows.iter().enumerate() {
            assert_eq!(row[0], i as f32 * delta + start, "not equidistant");
            assert!(row[1..].iter().all(|v| *v >= 0.0));
            assert!(row[2] > 0.0, "the emission's floor");
            let l = f64::from(row[0]);
            let (a, e, d2) = (f64::from(row[1]), f64::from(row[2]), f64::from(row[3]));
            let tolerance = 1e-6;
            assert!((d2 / 2.0 - truth.d(l)).abs() <= tolerance, "d at {l}");
            let k = k.unwrap();
            assert!(
                (c * q * a - truth.x(k, l)).abs() <= tolerance * (1.0 + truth.x(k, l)),
                "X at {l}"
            );
            assert!(
                (e - truth.e(k, l)).abs() <= tolerance * (1.0 + truth.e(k, l)),
                "e at {l}"
            );
        }
        // PearRay's normalisation (fluorescent_diffuse.cpp, buildEmissionDistribution):
        // Σ over 400 bins of e at start + span·i/400, linear between the rows.
        let span = f64::from(rows[rows.len() - 1][0] - start);
        let sum: f64 = (0..400)
            .map(|i| {
                let x = span * f64::from(i) / 400.0 / f64::from(delta);
                let j = (x.floor() as usize).min(rows.len() - 2);
                let t = x - j as f64;
                f64::from(rows[j][2]) * (1.0 - t) + f64::from(rows[j + 1][2]) * t
            })
            .sum();
        assert!(
            (scale / (2.0 * span * sum) - 1.0).abs() < 1e-5,
            "scale {scale}"
        );
        // e integrates to 1 per nm, so the scale is about twice 400.
        assert!((scale / 800.0 - 1.0).abs() < 0.01, "scale {scale}");
        let n = m.fluorophores.len();
        assert_eq!(
            prc.contains(&format!("This material has {n} fluorophores")),
            n > 1
        );
    }
}

// ---- ART -------------------------------------------------------------------------

/// A cursor over an `.ark` with the `scanf` conversions `ArfMeasurementArchive.m` uses:
/// white space in a format matches any run of white space (also none), `%lf` a double after
/// optional white space, `%[^\n]` a non-empty rest of line.
struct Scan<'a>(&'a str);

impl<'a> Scan<'a> {
    fn literal(&mut self, format: &str) {
        for part in format.split(char::is_whitespace) {
            self.0 = self.0.trim_start();
            if part.is_empty() {
                continue;
            }
            self.0 = self
                .0
                .strip_prefix(part)
                .unwrap_or_else(|| panic!("expected {part:?} at {:.60?}", self.0));
        }
    }
    fn exact(&mut self, text: &str) {
        self.0 = self
            .0
            .strip_prefix(text)
            .unwrap_or_else(|| panic!("expected {text:?} at {:.60?}", self.0));
    }
    fn double(&mut self) -> f64 {
        self.0 = self.0.trim_start();
        let end = self
            .0
            .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '-' | '+')))
            .unwrap_or(self.0.len());
        let v = self.0[..end]
            .parse()
            .unwrap_or_else(|_| panic!("%lf at {:.40?}", self.0));
        self.0 = &self.0[end..];
        v
    }
    fn rest_of_line(&mut self) -> &'a str {
        let end = self.0.find('\n').unwrap();
        assert!(end > 0, "%[^\\n] matches no character");
        let s = &self.0[..end];
        self.0 = &self.0[end..];
        s
    }
    fn getc(&mut self) -> char {
        let c = self.0.chars().next().unwrap();
        self.0 = &self.0[c.len_utf8()..];
        c
    }
    fn spaces(&mut self) {
        self.0 = self.0.trim_start_matches(' ');
    }
    /// `STREAM_SCANSTRING`: the label, spaces, then the rest of the line if any.
    fn field(&mut self, label: &str) -> &'a str {
        self.literal(label);
        self.spaces();
        if self.0.starts_with('\n') {
            self.literal(" ");
            ""
        } else {
            let s = self.rest_of_line();
            self.literal(" ");
            s
        }
    }
}

/// Parses one bispectral archive entry as ART does; returns (emission start, step,
/// excitation start, step, maximum value, series).
fn art_entry(text: &str) -> (f64, f64, f64, f64, f64, Vec<Vec<f64>>) {
    let mut s = Scan(text);
    s.literal("ART measurement archive version ");
    let version = s.double();
    assert!((1.0..=1.1).contains(&version));
    s.literal(" Archive content: ");
    s.rest_of_line();
    s.literal(" ");
    assert!(
        !s.0.starts_with('A'),
        "copyright lines are optional; none written"
    );
    assert!(s.0.starts_with('E'));
    s.exact("Entry ID:   ");
    let id = s.rest_of_line();
    assert!(!id.contains(char::is_whitespace));
    s.exact("\n---------------------------------------------------------------------------\n");
    s.field("Description           :");
    assert!(!s.0.starts_with('A'));
    s.literal("Type                  :  ");
    assert_eq!(s.rest_of_line(), "reflectance spectrum");
    s.literal(" Fluorescence data     :  ");
    assert_eq!(s.rest_of_line(), "yes");
    s.literal(" ");
    s.field("Measurement device    :");
    s.field("Measured by           :");
    s.field("Measurement date      :");
    s.literal("Sampling information\n--------------------\n");
    s.literal("Type                  :  ");
    assert_eq!(s.rest_of_line(), "regular");
    let mut value = |label: &str| {
        s.literal(label);
        let v = s.double();
        s.literal(" nm \n");
        v
    };
    let em_start = value(" Reflectance start     :  ");
    let em_step = value("Reflectance increment :  ");
    let ex_start = value("Illumination start    :  ");
    let ex_step = value("Illumination increment:  ");
    s.literal("Maximum sample value  :  ");
    let max = s.double();
    s.literal(" \n");
    s.literal("ASCII sample data \n----------------- \n ");
    // _parse2DSampleArray / _parseSampleArray.
    assert_eq!(s.getc(), '{');
    s.spaces();
    let mut series = Vec::new();
    while s.0.starts_with('{') {
        s.getc();
        let mut row = Vec::new();
        loop {
            row.push(s.double());
            if s.getc() != ',' {
                break;
            }
        }
        series.push(row);
        s.spaces();
        if s.getc() != ',' {
            break;
        }
        s.spaces();
    }
    s.literal(" ");
    assert!(s.0.is_empty(), "text after the entry: {:.40?}", s.0);
    (em_start, em_step, ex_start, ex_step, max, series)
}

/// The `.ark` entry parses as ART's parser reads it and holds the model's matrix per
/// emission bin: series per emission wavelength, values per excitation wavelength; the
/// anti-Stokes cells (excitation above emission), which ART zeroes, are 0 and their sum
/// sits on the diagonal of their emission wavelength, which ART keeps.
#[test]
fn art_archive_holds_the_reradiation_matrix() {
    for m in materials() {
        let truth = Truth::new(&m);
        let files = render(&m, ExportFormat::Art);
        let (em0, dem, ex0, dex, max, series) = art_entry(file(&files, &format!("{}.ark", m.name)));
        assert_eq!((dem, dex, max), (10.0, 10.0, 1.0));
        let columns = series[0].len();
        assert!(series.iter().all(|r| r.len() == columns));
        let em: Vec<f64> = (0..series.len()).map(|j| em0 + dem * j as f64).collect();
        let bins = trapezoid(&em);
        let cell = |li: f64, lo: f64, j: usize| -> f64 {
            (0..m.fluorophores.len())
                .map(|k| truth.x(k, li) * truth.e(k, lo) * bins[j])
                .sum()
        };
        for (j, row) in series.iter().enumerate() {
            for (i, v) in row.iter().enumerate() {
                let (li, lo) = (ex0 + dex * i as f64, em[j]);
                let mut want = if li > lo { 0.0 } else { cell(li, lo, j) };
                if li == lo {
                    let folded: f64 = (i + 1..row.len())
                        .map(|k| cell(ex0 + dex * k as f64, lo, j))
                        .sum();
                    want += truth.d(li) + folded;
                }
                assert!(
                    f32_close(*v, want, 1e-12),
                    "{} {li} {lo}: {v} vs {want}",
                    m.name
                );
            }
        }
        let samples = m.sample_wavelengths();
        assert!(ex0 <= samples[0] && em0 + dem * (em.len() - 1) as f64 >= 780.0);
    }
}

/// A material without fluorophores: βT is its reflectance under every light, no fork
/// scene (nothing to re-emit), PearRay's plain `diffuse`, and no fluorescence in ART.
#[test]
fn a_plain_material_exports_as_plain_diffuse() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fits");
    let m = Material::load(&dir.join("plain.json")).unwrap();
    assert!(m.fluorophores.is_empty());
    let truth = Truth::new(&m);
    let files = render(&m, ExportFormat::Mitsuba);
    let mut names: Vec<&str> = files.iter().map(|f| f.0.as_str()).collect();
    names.sort();
    assert_eq!(names, ["plain_a.xml", "plain_d65.xml"]);
    let (_, bsdf, _) = check_mitsuba_scene(file(&files, "plain_a.xml"));
    for (l, v) in spectrum_param(&bsdf, "reflectance") {
        assert!(f32_close(v, truth.r(l), 1e-12), "{l}");
    }
    let files = render(&m, ExportFormat::Pearray);
    let prc = file(&files, "plain.prc");
    assert!(prc.contains("\t:type 'diffuse'\n\t:albedo (spd 'plain_pearray.csv' 3)\n)"));
    let (_, rows) = pearray_csv(file(&files, "plain_pearray.csv"));
    for row in rows {
        assert!(f32_close(
            f64::from(row[3]),
            truth.r(f64::from(row[0])),
            1e-12
        ));
    }
}

/// Each fluorescent export says in its header how it was checked: the fork's scene that it
/// was rendered (and what the released fork gets wrong), PearRay's that it was rendered
/// (with `:nee false` and the CIE 1931 build), ART's that it was rendered (with `-s46e`,
/// Stokes shifts only) (docs/renderers.md).
#[test]
fn fluorescent_exports_say_how_they_were_checked() {
    for m in materials() {
        if m.fluorophores.is_empty() {
            continue;
        }
        let files = render(&m, ExportFormat::Mitsuba);
        let fork = file(&files, &format!("{}_fluoro.xml", m.name));
        assert!(fork.contains("RENDERED in the fork"), "{fork}");
        assert!(fork.contains("value/p, pdf·p"));
        let files = render(&m, ExportFormat::Pearray);
        let prc = file(&files, &format!("{}.prc", m.name));
        assert!(prc.contains("; RENDERED in PearRay 95f065ad"), "{prc}");
        assert!(prc.contains("(integrator :type 'direct' :nee false)"));
        assert!(prc.contains("-DPR_USE_CIE_1931"));
        let files = render(&m, ExportFormat::Art);
        let ark = file(&files, &format!("{}.ark", m.name));
        let description = ark
            .lines()
            .find(|l| l.starts_with("Description"))
            .expect("a description line");
        assert!(
            description.contains("RENDERED in ART 99c65c0"),
            "{description}"
        );
        assert!(description.contains("-s46e"));
        assert!(description.contains("anti-Stokes"));
    }
}
