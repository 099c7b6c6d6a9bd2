//! Mitsuba 3: complete scenes that load as they are.
//!
//! - `NAME_<light>.xml`, one per light, for stock Mitsuba 3 (3.x, a spectral variant such
//!   as `scalar_spectral`): the material as a `diffuse` BSDF whose reflectance is the
//!   baked total radiance factor βT for that light ([`super::baked`]), on a sphere in a
//!   uniform environment of the light, with a camera and the `path` integrator. Stock
//!   Mitsuba has no fluorescence; βT shows the fluorescent colour exactly under that
//!   light and wrongly under any other.
//! - `NAME_fluoro.xml` for the fluorescence fork (blzq/mitsuba3, branch `fluorescence`):
//!   its `diffusefluoro` BSDF (`reflectance` = d, `fluorescence` = e, normalised by the
//!   plugin, `excitation` = c·Q(λi)·a, the energy fraction re-emitted) with its
//!   `pathfluoro` integrator. It holds one fluorophore. Rendered in the fork
//!   (`scripts/verify-renderers.sh`), it matches the exact furnace colour once the fork's
//!   lobe weighting is corrected; as released the fork renders it too dark, which the
//!   scene's comment says (docs/renderers.md).
//!
//! Every spectrum is written inline (`value="λ:v, λ:v, …"`, parsed by
//! `Properties::Spectrum(std::string_view)`), so a scene needs no other file and a
//! `<bsdf>` can be copied into any scene. Mitsuba requires the root's `version` attribute.

use crate::colour::{Light, cie1931, colour_grid};
use crate::material::Material;

use super::baked::{strongest_fluorophore, total_radiance_factor};
use super::spectra::{excitation_grid, number};
use super::{VERSION, one_line};

/// A spectrum as a Mitsuba `value` attribute: `λ:v` pairs separated by `, `.
fn inline(samples: impl Iterator<Item = (f64, f64)>) -> String {
    samples
        .map(|(l, v)| format!("{}:{}", number(l), number(v)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The light scaled so that a white diffuser reads Y = 1 in Mitsuba, which divides
/// ∫ s·ȳ dλ by ∫ ȳ dλ when it converts a spectrum to XYZ.
fn light_scale(light: &Light) -> f64 {
    let (grid, widths) = colour_grid();
    let observer = cie1931();
    let (mut lit, mut flat) = (0.0, 0.0);
    for (l, w) in grid.iter().zip(&widths) {
        let y = observer.at(*l)[1];
        lit += light.power(*l) * y * w;
        flat += y * w;
    }
    if lit > 0.0 { flat / lit } else { 1.0 }
}

/// The scene around a BSDF: integrator, camera, the light as a uniform environment and a
/// unit sphere of the material `id`.
fn scene(comment: &str, integrator: &str, light: &Light, bsdf: &str, id: &str) -> String {
    let scale = light_scale(light);
    let radiance = inline(
        light
            .spectrum
            .wavelength_nm
            .iter()
            .zip(&light.spectrum.value)
            .map(|(&l, &p)| (l, p * scale)),
    );
    let light_name = xml_comment(&light.name);
    let mut lines = vec![
        "<?xml version=\"1.0\" encoding=\"utf-8\"?>".to_string(),
        format!(
            "<!-- {} -->",
            comment.lines().collect::<Vec<_>>().join("\n     ")
        ),
        "<scene version=\"3.0.0\">".into(),
        format!("    <integrator type=\"{integrator}\">"),
    ];
    lines.extend(
        [
            "        <integer name=\"max_depth\" value=\"8\"/>",
            "    </integrator>",
            "    <sensor type=\"perspective\">",
            "        <float name=\"fov\" value=\"30\"/>",
            "        <transform name=\"to_world\">",
            "            <lookat origin=\"0, 0, 5\" target=\"0, 0, 0\" up=\"0, 1, 0\"/>",
            "        </transform>",
            "        <sampler type=\"independent\">",
            "            <integer name=\"sample_count\" value=\"64\"/>",
            "        </sampler>",
            "        <film type=\"hdrfilm\">",
            "            <integer name=\"width\" value=\"128\"/>",
            "            <integer name=\"height\" value=\"128\"/>",
            "            <rfilter type=\"box\"/>",
            "        </film>",
            "    </sensor>",
        ]
        .map(String::from),
    );
    lines.push(format!(
        "    <!-- light \"{light_name}\" (relative spectral power, wavelengths in nm), scaled so that a white diffuser reads Y = 1 -->"
    ));
    lines.push("    <emitter type=\"constant\">".into());
    lines.push(format!(
        "        <spectrum name=\"radiance\" value=\"{radiance}\"/>"
    ));
    lines.push("    </emitter>".into());
    lines.push(bsdf.trim_end().to_string());
    lines.push("    <shape type=\"sphere\">".into());
    lines.push(format!("        <ref id=\"{id}\"/>"));
    lines.push("    </shape>".into());
    lines.push("</scene>\n".into());
    lines.join("\n")
}

/// Text safe inside an XML comment (no `--`).
fn xml_comment(text: &str) -> String {
    let mut out = one_line(text);
    while out.contains("--") {
        out = out.replace("--", "- -");
    }
    out
}

/// Mitsuba 3: one stock scene per light, and the fork's scene when the material
/// fluoresces.
pub(super) fn mitsuba(material: &Material, stem: &str, lights: &[Light]) -> Vec<(String, String)> {
    let name = xml_comment(&material.name);
    let mut files = Vec::new();
    for light in lights {
        let baked = total_radiance_factor(material, light);
        let id = format!("{stem}_{}", super::file_stem(&light.name));
        let unlit = if baked.unlit_share > 0.0 {
            format!(
                "\n     {:.3} % of the re-emitted energy falls where this light has no power; βT cannot carry it (there βT = d).",
                100.0 * baked.unlit_share
            )
        } else {
            String::new()
        };
        let comment = format!(
            "fluorite {VERSION} export of material \"{name}\" for stock Mitsuba 3 (3.x, a spectral variant, e.g. scalar_spectral).\n\
     VALID UNDER LIGHT \"{light}\" ONLY. The diffuse reflectance below is the baked total radiance factor\n\
\x20 βT(λ) = d(λ) + Σ e(λ)·∫ c·Q(λi)·a(λi)·L(λi) dλi / L(λ),   d = (1 - Σc·a)·r,\n\
     dimensionless, wavelengths in nm (1 nm steps, 1 nm trapezoid sums), for L = light \"{light}\": the\n\
     fluorescence this light excites, folded into a reflectance (max βT = {max}; Mitsuba's diffuse takes\n\
     values above 1). Stock Mitsuba 3 has no fluorescent BSDF: under any other light this material shows\n\
     the wrong colour; export once per light you render with (fluorite's light option).{unlit}\n\
     The scene: the material on a unit sphere in a uniform environment of the light (a furnace), a\n\
     perspective camera and a path tracer. Copy the <bsdf> into your own scene: it needs no file.",
            light = xml_comment(&light.name),
            max = number(baked.max()),
        );
        let bsdf = format!(
            "    <bsdf type=\"diffuse\" id=\"{id}\">\n        <spectrum name=\"reflectance\" value=\"{}\"/>\n    </bsdf>\n",
            inline(baked.wavelength_nm.iter().copied().zip(baked.value))
        );
        files.push((
            format!("{id}.xml"),
            scene(&comment, "path", light, &bsdf, &id),
        ));
    }
    if let Some(file) = fork_scene(material, stem, &name, lights) {
        files.push(file);
    }
    files
}

/// The `diffusefluoro` scene for the fluorescence fork (blzq/mitsuba3, branch
/// `fluorescence`, `src/bsdfs/diffuse_fluoro.cpp`), lit by the first light. None for a
/// material that re-emits nothing.
fn fork_scene(
    material: &Material,
    stem: &str,
    name: &str,
    lights: &[Light],
) -> Option<(String, String)> {
    let light = lights.first()?;
    let (kept, share) = strongest_fluorophore(material, light)?;
    let f = &material.fluorophores[kept];
    let n = material.fluorophores.len();
    let several = if n > 1 {
        format!(
            "\nThis material has {n} fluorophores; diffusefluoro holds one. Kept: fluorophore {kept}, which re-emits\n\
     {:.1} % of the fluorescent energy under light \"{}\". The others' absorption stays in the reflectance d\n\
     (their light is absorbed and not re-emitted here); the stock scenes' baked βT keeps every one.",
            100.0 * share,
            xml_comment(&light.name)
        )
    } else {
        String::new()
    };
    let mean = f.emission_mean_nm();
    let excitation: Vec<(f64, f64)> = excitation_grid(f)
        .into_iter()
        .map(|l| (l, f.reradiated_with_mean(l, mean)))
        .collect();
    // The fork samples λi from the excitation: it needs some.
    if excitation.iter().all(|&(_, x)| x <= 0.0) {
        return None;
    }
    let (grid, _) = colour_grid();
    let id = format!("{stem}_fluoro");
    let comment = format!(
        "fluorite {VERSION} export of material \"{name}\" for the Mitsuba 3 fluorescence fork (blzq/mitsuba3,\n\
     branch fluorescence): BSDF diffusefluoro and integrator pathfluoro; stock Mitsuba does not know them.\n\
     The diffuse fluorescent BBRRDF (Jung et al. 2018), f(λi, λo) = [δ(λi - λo)·d(λi) + X(λi)·e(λo)] / π:\n\
\x20 reflectance   d = (1 - Σc·a)·r, dimensionless (1 nm steps)\n\
\x20 fluorescence  e, emission density in 1/nm (∫e dλ = 1; the plugin normalises it anyway)\n\
\x20 excitation    X = c·Q(λi)·a(λi), dimensionless: the fraction of energy arriving at λi re-emitted\n\
\x20               (c = {c}, {q}){several}\n\
     Valid under every light; the environment below is light \"{light}\".\n\
     RENDERED in the fork (61931a78, scalar_spectral; scripts/verify-renderers.sh, docs/renderers.md): as\n\
     released, pathfluoro shows a material with both lobes too dark (furnace ΔE2000 4.6-23.7): when\n\
     diffusefluoro's sample() picks one lobe with probability p, its eval_pdf()/eval_pdf_fluoro() give the\n\
     emitter-sampling term that lobe's value undivided by p and a density of pdf/p instead of sample()'s pdf·p.\n\
     With both corrected (value/p, pdf·p) the scene matches the exact furnace colour within ΔE2000 0.19.",
        c = number(f.concentration),
        q = match f.yield_form {
            crate::material::YieldForm::Energy => format!("Q = {}", number(f.quantum_yield)),
            crate::material::YieldForm::Photon => format!(
                "photon form: Q(λi) = Φ·λi/λ̄e with Φ = {}, λ̄e = {} nm, sampled every 1 nm or finer",
                number(f.quantum_yield),
                number(mean)
            ),
        },
        light = xml_comment(&light.name),
    );
    let bsdf = format!(
        "    <bsdf type=\"diffusefluoro\" id=\"{id}\">\n        <spectrum name=\"reflectance\" value=\"{}\"/>\n        <spectrum name=\"fluorescence\" value=\"{}\"/>\n        <spectrum name=\"excitation\" value=\"{}\"/>\n    </bsdf>\n",
        inline(grid.iter().map(|&l| (l, material.diagonal(l)))),
        inline(
            f.emission
                .wavelength_nm
                .iter()
                .copied()
                .zip(f.emission.value.iter().copied())
        ),
        inline(excitation.into_iter()),
    );
    Some((
        format!("{id}.xml"),
        scene(&comment, "pathfluoro", light, &bsdf, &id),
    ))
}
