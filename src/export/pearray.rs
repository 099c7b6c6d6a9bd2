//! PearRay: its `fluorescent` material (`src/plugins/main/materials/fluorescent_diffuse.cpp`,
//! Jung et al. 2018 exactly) in a `.prc` file to include, and the spectra as a CSV.
//!
//! The material evaluates c·Q·a(λi)·e(λo)/π + δ·(1 − c·a)·r/π with `absorption` a,
//! `emission` e (normalised by PearRay), `albedo` r, `aefactor` Q and `concentration` c,
//! all for one fluorophore with a constant energy yield. A photon-form fluorophore
//! (Q(λi) = Φ·λi/λ̄e) is written exactly as the same product with Q = 1: `absorption`
//! X/max X with X = c·Φ·(λi/λ̄e)·a, `concentration` max X, and `albedo` d/(1 − X), which
//! gives back the model's diagonal d. With several fluorophores the one re-emitting the
//! most under the first light is kept, and the albedo d/(1 − c·a) keeps every
//! fluorophore's absorption; the others' re-emission is dropped (the `.prc` says how
//! much).
//!
//! Rendered in PearRay 95f065ad (`scripts/verify-renderers.sh`), the material does not show
//! the model (its non-fluorescent term vanishes on the diagonal; docs/renderers.md), so the
//! `.prc` says it is checked against PearRay's formats only.
//!
//! The CSV follows what PearRay's readers accept: `src/base/container/CSV.cpp` has no
//! comment lines (a header row of names, then numbers parsed by `std::stof`), and the
//! `spd` node (`src/plugins/main/node/SPDFileNode.cpp`) places the rows on an
//! equidistant grid from the first two wavelengths, so the CSV has one row per nm.

use crate::colour::Light;
use crate::material::{Material, YieldForm};

use super::baked::strongest_fluorophore;
use super::spectra::{number, union_grid};
use super::{VERSION, one_line};

/// What this export has been checked against, for its header: PearRay 95f065ad renders
/// the file but its `fluorescent` material does not show the model (docs/renderers.md).
const PEARRAY_CHECKED: &str = "\
; CHECKED AGAINST PEARRAY'S FORMATS ONLY (its CSV reader and spd node), not against a render: PearRay\n\
; 95f065ad loads and renders this file, but its `fluorescent` material with the `direct` integrator does not\n\
; show the model (docs/renderers.md): it weights the non-fluorescent term by |λ - λ'| (nonFlourescency), 0\n\
; on the diagonal, so even concentration 0 renders black, and the re-emission comes out far too dark.\n";

/// The whole-nanometre grid the CSV holds: the material's samples and 300–830 nm.
fn csv_grid(material: &Material) -> Vec<f64> {
    let samples = union_grid(material);
    let first = samples.first().map_or(300.0, |l| l.floor().min(300.0));
    let last = samples.last().map_or(830.0, |l| l.ceil().max(830.0));
    (0..=(last - first) as usize)
        .map(|i| first + i as f64)
        .collect()
}

/// PearRay: `NAME.prc` (the material) and `NAME_pearray.csv` (its spectra).
pub(super) fn pearray(material: &Material, stem: &str, lights: &[Light]) -> Vec<(String, String)> {
    let name = one_line(&material.name);
    let grid = csv_grid(material);
    let csv_name = format!("{stem}_pearray.csv");
    let kept = lights
        .first()
        .and_then(|light| strongest_fluorophore(material, light).map(|k| (k, light)));
    // (absorption, emission) per row, and the scalars, for the kept fluorophore.
    let (absorption, emission, concentration, aefactor, about): (
        Vec<f64>,
        Vec<f64>,
        f64,
        f64,
        String,
    ) = match kept {
        None => (
            vec![0.0; grid.len()],
            vec![0.0; grid.len()],
            0.0,
            0.0,
            "; The material has no fluorophore: PearRay's plain `diffuse` material (lambert.cpp) with the reflectance.\n"
                .into(),
        ),
        Some(((index, share), light)) => {
            let f = &material.fluorophores[index];
            let emission = grid
                .iter()
                .map(|&l| f.emission.eval_zero_outside(l))
                .collect();
            let n = material.fluorophores.len();
            let mut about = if n > 1 {
                format!(
                    "; This material has {n} fluorophores; PearRay's material holds one. Kept: fluorophore {index},\n\
; which re-emits {:.1} % of the fluorescent energy under light \"{}\". The others' absorption stays in\n\
; the albedo (their light is absorbed, not re-emitted).\n",
                    100.0 * share,
                    one_line(&light.name)
                )
            } else {
                String::new()
            };
            match f.yield_form {
                YieldForm::Energy => (
                    grid.iter()
                        .map(|&l| f.absorption.eval_zero_outside(l))
                        .collect(),
                    emission,
                    f.concentration,
                    f.quantum_yield,
                    about,
                ),
                YieldForm::Photon => {
                    let mean = f.emission_mean_nm();
                    let x: Vec<f64> = grid
                        .iter()
                        .map(|&l| f.reradiated_with_mean(l, mean))
                        .collect();
                    let peak = x.iter().copied().fold(0.0, f64::max);
                    about.push_str(&format!(
                            "; The fluorophore has a constant PHOTON yield Φ = {} (energy yield Q(λi) = Φ·λi/λ̄e, λ̄e = {} nm),\n\
; which a constant aefactor cannot hold: written as aefactor 1, concentration max X and absorption\n\
; X/max X with X = c·Φ·(λi/λ̄e)·a, the albedo set so that (1 - X)·albedo is the model's d (exact).\n",
                            number(f.quantum_yield),
                            number(mean)
                        ));
                    let absorption = x
                        .iter()
                        .map(|v| if peak > 0.0 { v / peak } else { 0.0 })
                        .collect();
                    (absorption, emission, peak, 1.0, about)
                }
            }
        }
    };
    let mut csv = String::from("wavelength,absorption,emission,albedo\n");
    for (i, &l) in grid.iter().enumerate() {
        let absorbed = concentration * absorption[i];
        let albedo = if absorbed < 1.0 {
            material.diagonal(l) / (1.0 - absorbed)
        } else {
            material.reflectance.eval_clamped(l)
        };
        csv.push_str(&format!(
            "{},{},{},{}\n",
            number(l),
            number(absorption[i]),
            number(emission[i]),
            number(albedo)
        ));
    }
    // PearRay normalises the emission by its integral: without a fluorophore its plain
    // `diffuse` (lambert.cpp) takes the albedo alone.
    let block = if kept.is_some() {
        format!(
            "(material\n\t:name '{stem}'\n\t:type 'fluorescent'\n\t:absorption (spd '{csv_name}' 1)\n\t:emission (spd '{csv_name}' 2)\n\t:albedo (spd '{csv_name}' 3)\n\t:aefactor {}\n\t:concentration {}\n)\n",
            aefactor as f32, concentration as f32
        )
    } else {
        format!(
            "(material\n\t:name '{stem}'\n\t:type 'diffuse'\n\t:albedo (spd '{csv_name}' 3)\n)\n"
        )
    };
    let prc = format!(
        "; fluorite {VERSION} export of material \"{name}\" for PearRay: its `fluorescent` material, the diffuse\n\
; fluorescent BBRRDF of Jung et al. 2018, f = [c·Q·a(λi)·e(λo) + δ(λi - λo)·(1 - c·a)·albedo] / π.\n\
; Include it inside a (scene ...) with (include \"{stem}.prc\"); keep {csv_name} beside this file.\n\
; {csv_name}: one row per nm (PearRay's spd node needs equidistant rows), no comment lines (its CSV\n\
; reader has none); columns: 0 wavelength (nm), 1 absorption a (dimensionless, max 1), 2 emission e\n\
; (1/nm, integral 1; PearRay normalises it again), 3 albedo (dimensionless reflectance of the\n\
; non-fluorescent part). aefactor is the energy quantum yield Q, concentration c. Valid under every light.\n\
{PEARRAY_CHECKED}\
{about}\
{block}",
    );
    vec![(format!("{stem}.prc"), prc), (csv_name, csv)]
}
