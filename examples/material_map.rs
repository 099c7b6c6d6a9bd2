//! Writes a small example material map (`fluorite-material-map/1`) from a material with
//! two fluorophores, for trying `fluorite render` on a textured material before an image
//! fit has made one (scripts/regenerate.sh writes `fits/maps/two-dyes/` with it):
//!
//! ```text
//! cargo run --example material_map -- data/two-dyes.truth.json fits/maps/two-dyes
//! ```
//!
//! The map is 32 × 16 texels over the material's reflectance: the left half holds the
//! first fluorophore, the right half the second, each at the material's concentration in
//! the top row fading linearly to a quarter of it in the bottom row; the 4 × 4 texels of
//! the bottom-right corner are masked (NaN), as a fit leaves pixels it could not read.

#[allow(dead_code)]
#[path = "../tests/suite/common/map.rs"]
mod map;

use std::path::PathBuf;
use std::process::ExitCode;

use fluorite::Material;

const WIDTH: usize = 32;
const HEIGHT: usize = 16;
const MASKED: usize = 4;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [material, folder] = args.as_slice() else {
        eprintln!("usage: material_map MATERIAL.json FOLDER (a material with two fluorophores)");
        return ExitCode::from(2);
    };
    match write(&PathBuf::from(material), &PathBuf::from(folder)) {
        Ok(json) => {
            eprintln!("wrote {}", json.display());
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("material_map: {e}");
            ExitCode::FAILURE
        }
    }
}

fn write(material: &std::path::Path, folder: &std::path::Path) -> fluorite::Result<PathBuf> {
    let material = Material::load(material)?;
    let [first, second] = material.fluorophores.as_slice() else {
        return Err(fluorite::Error::invalid(
            "MATERIAL",
            format!(
                "{} has {} fluorophores; give one with two",
                material.name,
                material.fluorophores.len()
            ),
        ));
    };
    std::fs::create_dir_all(folder).map_err(|e| fluorite::Error::io(folder, e))?;
    let json = folder.join("material-map.json");
    let wavelengths = material.reflectance.wavelength_nm.clone();
    let reflectance: Vec<f32> = material
        .reflectance
        .value
        .iter()
        .map(|&v| v as f32)
        .collect();
    let masked = |x: usize, y: usize| x >= WIDTH - MASKED && y >= HEIGHT - MASKED;
    let (c1, c2) = (first.concentration as f32, second.concentration as f32);
    map::write_map(
        &json,
        &format!("{}-halves", material.name),
        (WIDTH, HEIGHT),
        &material.fluorophores,
        &wavelengths,
        &|x, y| {
            if masked(x, y) {
                return vec![f32::NAN, f32::NAN];
            }
            let fade = 1.0 - 0.75 * y as f32 / (HEIGHT - 1) as f32;
            if x < WIDTH / 2 {
                vec![c1 * fade, 0.0]
            } else {
                vec![0.0, c2 * fade]
            }
        },
        &|_, _| reflectance.clone(),
    )?;
    Ok(json)
}
