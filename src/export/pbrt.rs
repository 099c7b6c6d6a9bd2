//! pbrt-v4: spectrum files (`.spd`) and a material file to `Include`.
//!
//! Stock pbrt-v4 has no fluorescent material. `NAME.pbrt` defines, per light, a named
//! `diffuse` material whose reflectance is the baked total radiance factor βT for that
//! light (`NAME_baked_<light>.spd`, [`super::baked`]), and `NAME_albedo` with the plain
//! d = (1 − Σc·a)·r (no fluorescence). pbrt-v4's `DiffuseMaterial::GetBxDF` clamps the
//! reflectance to [0, 1] (`materials.h`): βT above 1 is cut to 1, which loses that part
//! of the fluorescence; each file says how much luminance the cut costs under its light.
//! The excitation and emission of every fluorophore and the full reradiation matrix are
//! written too, for renderers that take them.
//!
//! Numbers are written as `ReadFloatFile` (`util/file.cpp`) reads them: at most 31
//! characters each (its buffer holds 32 with the terminator), parsed by `std::stof`, so
//! f32 values in shortest form and 0 below f32's normal range
//! ([`super::spectra::number`]). pbrt-v4 resolves a relative file name against the
//! directory of the scene file given on its command line (`SetSearchDirectory`), not
//! against the file that names it, so `NAME.pbrt` names no file: its materials carry
//! their spectra inline, as the (λ, value) pairs a `"spectrum"` parameter takes
//! (`ParameterDictionary::extractSpectrumArray`: an even count, wavelengths strictly
//! increasing), and it works wherever the scene that `Include`s it sits. The `.spd` files
//! hold the same spectra for other uses.

use crate::colour::{Light, cie1931, colour_grid};
use crate::material::{Material, YieldForm};

use super::baked::{BakedSpectrum, total_radiance_factor};
use super::spectra::{excitation_grid, number, two_column, union_grid};
use super::{VERSION, one_line};

/// A spectrum file to write: file name, header lines, (wavelength, value) samples.
type SpectrumFile = (String, Vec<String>, Vec<(f64, f64)>);

/// The model's spectra as `.spd` files: d, r, and each fluorophore's excitation and emission.
fn spectra(material: &Material, stem: &str) -> Vec<SpectrumFile> {
    let name = one_line(&material.name);
    let produced = format!("fluorite {VERSION} export of material \"{name}\"");
    let grid = union_grid(material);
    let n = material.fluorophores.len();
    let albedo = if n > 1 {
        format!(
            "quantity: non-fluorescent albedo (1 - Σ c_k*a_k(λ))*r(λ) over the {n} fluorophores, dimensionless (diagonal reflectance)"
        )
    } else {
        "quantity: non-fluorescent albedo (1 - c*a(λ))*r(λ), dimensionless (diagonal reflectance)"
            .to_string()
    };
    let mut out = vec![
        (
            format!("{stem}_albedo.spd"),
            vec![
                produced.clone(),
                albedo,
                "columns: wavelength (nm), value".into(),
            ],
            grid.iter().map(|&l| (l, material.diagonal(l))).collect(),
        ),
        (
            format!("{stem}_reflectance.spd"),
            vec![
                produced.clone(),
                "quantity: reflectance r(λ) of the non-fluorescent part, dimensionless".into(),
                "columns: wavelength (nm), value".into(),
            ],
            grid.iter()
                .map(|&l| (l, material.reflectance.eval_clamped(l)))
                .collect(),
        ),
    ];
    for (i, f) in material.fluorophores.iter().enumerate() {
        let s = if n > 1 {
            format!("_{i}")
        } else {
            String::new()
        };
        let quantity = match f.yield_form {
            YieldForm::Energy => format!(
                "quantity: fluorescent excitation c*Q*a(λ), dimensionless (fraction of incident energy at λ re-emitted), c = {}, Q = {}",
                f.concentration, f.quantum_yield
            ),
            YieldForm::Photon => format!(
                "quantity: fluorescent excitation c*Q(λ)*a(λ) with the energy yield Q(λ) = Φ*λ/λ̄e (photon form: constant photon yield), dimensionless (fraction of incident energy at λ re-emitted), c = {}, Φ = {}, λ̄e = {} nm; sampled at most 1 nm apart (λ*a is quadratic between the absorption samples)",
                f.concentration,
                f.quantum_yield,
                f.emission_mean_nm()
            ),
        };
        let mean = f.emission_mean_nm();
        out.push((
            format!("{stem}_excitation{s}.spd"),
            vec![
                produced.clone(),
                quantity,
                "columns: wavelength (nm), value".into(),
            ],
            excitation_grid(f)
                .into_iter()
                .map(|l| (l, f.reradiated_with_mean(l, mean)))
                .collect(),
        ));
        out.push((
            format!("{stem}_emission{s}.spd"),
            vec![
                produced.clone(),
                "quantity: normalised emission spectrum e(λ) in 1/nm (integral over nm = 1)".into(),
                "columns: wavelength (nm), value".into(),
            ],
            f.emission
                .wavelength_nm
                .iter()
                .zip(&f.emission.value)
                .map(|(&l, &e)| (l, e))
                .collect(),
        ));
    }
    if let Some(forms) = &material.forms {
        let note = format!(
            "spectra: samples of the continuous forms of model {} (parameters in the material's JSON forms block)",
            one_line(&forms.model)
        );
        for (_, header, _) in &mut out {
            header.insert(1, note.clone());
        }
    }
    out
}

/// Comment lines (each starting with `prefix`) for the photon-form fluorophores: the
/// excitation file holds c·Q(λi)·a with Q(λi) = Φ·λi/λ̄e, which a plugin taking a constant
/// quantum yield cannot express. Empty when every fluorophore is in the energy form.
fn photon_note(material: &Material, prefix: &str) -> String {
    let mut out = String::new();
    for (i, f) in material.fluorophores.iter().enumerate() {
        if f.yield_form != YieldForm::Photon {
            continue;
        }
        let s = lobe_suffix(material, i);
        out.push_str(&format!(
            "{prefix}Lobe{s} has a constant PHOTON yield Φ = {} (yield_form photon), not a constant energy yield:\n\
{prefix}its energy yield is Q(λi) = Φ·λi/λ̄e (λ̄e = {} nm), already in excitation{s}. A plugin that\n\
{prefix}takes a constant quantum_yield and an absorption cannot express this form: give it the\n\
{prefix}excitation spectrum (with quantum_yield 1 and concentration 1) or use the reradiation matrix.\n",
            f.quantum_yield,
            f.emission_mean_nm()
        ));
    }
    out
}

/// The suffix of fluorophore `i`'s files: none for a single fluorophore, `_i` otherwise.
fn lobe_suffix(material: &Material, i: usize) -> String {
    if material.fluorophores.len() > 1 {
        format!("_{i}")
    } else {
        String::new()
    }
}

/// A `"spectrum"` parameter's value inline: `[ λ v λ v … ]`, eight pairs a line.
fn inline_spectrum(samples: impl Iterator<Item = (f64, f64)>) -> String {
    let pairs: Vec<String> = samples
        .map(|(l, v)| format!("{} {}", number(l), number(v)))
        .collect();
    let lines: Vec<String> = pairs.chunks(8).map(|c| c.join(" ")).collect();
    format!("[\n        {}\n    ]", lines.join("\n        "))
}

/// Luminance under `light` of βT clamped to [0, 1] (what pbrt-v4's diffuse renders),
/// relative to βT's own.
fn clamped_luminance(baked: &BakedSpectrum, light: &Light) -> f64 {
    let (grid, widths) = colour_grid();
    let observer = cie1931();
    let (mut clamped, mut full) = (0.0, 0.0);
    for ((l, w), v) in grid.iter().zip(&widths).zip(&baked.value) {
        let weight = light.power(*l) * observer.at(*l)[1] * w;
        clamped += weight * v.clamp(0.0, 1.0);
        full += weight * v;
    }
    if full > 0.0 { clamped / full } else { 1.0 }
}

/// pbrt-v4: `.spd` files and `NAME.pbrt` (the matrix is added by the caller).
pub(super) fn pbrt(material: &Material, stem: &str, lights: &[Light]) -> Vec<(String, String)> {
    let spectrum_files = spectra(material, stem);
    // The albedo material carries d inline too.
    let albedo_file = format!("{stem}_albedo.spd");
    let albedo = spectrum_files
        .iter()
        .find(|(file, _, _)| *file == albedo_file)
        .map(|(_, _, samples)| samples.clone())
        .unwrap_or_default();
    let mut files: Vec<(String, String)> = spectrum_files
        .into_iter()
        .map(|(file, header, samples)| (file, two_column(&header, samples.into_iter())))
        .collect();
    let name = one_line(&material.name);
    let n = material.fluorophores.len();
    let lobes: String = (0..n)
        .map(|i| {
            let s = lobe_suffix(material, i);
            format!("# {stem}_excitation{s}.spd (c·Q(λi)·a{s}, dimensionless), {stem}_emission{s}.spd (e{s}, 1/nm, ∫e dλ = 1),\n")
        })
        .collect();
    let summed = if n > 1 {
        format!(", all {n} fluorophores summed")
    } else {
        String::new()
    };
    let forms = match &material.forms {
        Some(f) => format!(
            "# The spectra are samples of the continuous forms of model {} (see the material JSON).\n",
            one_line(&f.model)
        ),
        None => String::new(),
    };
    let photon = photon_note(material, "# ");
    let mut scene = format!(
        "# fluorite {VERSION} export of material \"{name}\" for pbrt-v4: named materials to Include.\n\
# The spectra are inline ((wavelength nm, value) pairs), so this file names no other file and\n\
# works from wherever the including scene sits; Include it after WorldBegin\n\
# (MakeNamedMaterial is a world-block statement).\n\
# Stock pbrt-v4 has no fluorescent material. Each \"{stem}_<light>\" material below is a diffuse\n\
# material whose reflectance is the baked total radiance factor for that light ONLY,\n\
#   βT(λ) = d(λ) + Σ e(λ)·∫ c·Q(λi)·a(λi)·L(λi) dλi / L(λ),   d = (1 - Σc·a)·r  (dimensionless),\n\
# the fluorescence that light excites folded into a reflectance: under any other light the\n\
# colour is wrong. pbrt-v4's diffuse material clamps its reflectance to [0, 1]\n\
# (DiffuseMaterial::GetBxDF), so βT above 1 is cut to 1 and that part of the fluorescence is lost.\n\
# \"{stem}_albedo\" is the plain d: no fluorescence at all.\n\
# Files beside this one, for other uses: {stem}_baked_<light>.spd (the same βT),\n\
# {stem}_albedo.spd (d), {stem}_reflectance.spd (r),\n\
{lobes}\
# {stem}_reradiation.csv (the full reradiation matrix{summed}, rows excitation, columns emission,\n\
# for matrix-based renderers; see its header for units).\n\
{photon}{forms}"
    );
    for light in lights {
        let baked = total_radiance_factor(material, light);
        let light_stem = super::file_stem(&light.name);
        let file = format!("{stem}_baked_{light_stem}.spd");
        let kept = clamped_luminance(&baked, light);
        let clamp = format!(
            "max βT = {}; pbrt-v4 clamps the reflectance to 1, which keeps {:.2} % of this material's luminance under {}",
            number(baked.max()),
            100.0 * kept,
            one_line(&light.name)
        );
        let mut header = vec![
            format!("fluorite {VERSION} export of material \"{name}\""),
            format!(
                "quantity: total radiance factor βT(λ) = d(λ) + Σ e(λ)·∫c·Q·a·L dλi / L(λ) for light \"{}\" ONLY, dimensionless (may exceed 1)",
                one_line(&light.name)
            ),
            clamp.clone(),
            "columns: wavelength (nm), value".into(),
        ];
        if baked.unlit_share > 0.0 {
            header.push(format!(
                "{:.3} % of the re-emitted energy falls where the light has no power and is not in βT",
                100.0 * baked.unlit_share
            ));
        }
        scene.push_str(&format!(
            "\n# valid under light \"{light}\" only; {clamp}\n\
MakeNamedMaterial \"{stem}_{light_stem}\"\n    \"string type\" \"diffuse\"\n    \"spectrum reflectance\" {}\n",
            inline_spectrum(baked.wavelength_nm.iter().copied().zip(baked.value.iter().copied())),
            light = one_line(&light.name),
        ));
        files.push((
            file,
            two_column(&header, baked.wavelength_nm.into_iter().zip(baked.value)),
        ));
    }
    scene.push_str(&format!(
        "\n# the reflected part only (no fluorescence)\nMakeNamedMaterial \"{stem}_albedo\"\n    \"string type\" \"diffuse\"\n    \"spectrum reflectance\" {}\n",
        inline_spectrum(albedo.into_iter())
    ));
    for (i, f) in material.fluorophores.iter().enumerate() {
        let s = lobe_suffix(material, i);
        let y = match f.yield_form {
            YieldForm::Energy => format!("Q = {}", number(f.quantum_yield)),
            YieldForm::Photon => format!(
                "photon form, Φ = {} (Q(λi) = Φ·λi/λ̄e, λ̄e = {} nm)",
                number(f.quantum_yield),
                number(f.emission_mean_nm())
            ),
        };
        scene.push_str(&format!(
            "# fluorescent lobe{s}: c = {}, {y}, excitation \"{stem}_excitation{s}.spd\", emission \"{stem}_emission{s}.spd\"\n",
            number(f.concentration)
        ));
    }
    files.push((format!("{stem}.pbrt"), scene));
    files
}
