//! The seed files the mutator starts from: every format fluorite reads, from the shipped
//! examples, `../shared/data`, and files fluorite itself writes.

use std::path::{Path, PathBuf};

use fluorite::Material;
use fluorite::export::{ExportFormat, ExportOptions, export};
use fluorite::formats::{ReadOptions, read, write_bfc, write_long_csv};

/// What a seed is, and so which library path its mutants go through.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A reradiation matrix: read → prepare (units, scatter) → fit.
    Matrix,
    /// A material JSON: load → check → render (tiny).
    Material,
    /// A spectra CSV (`wavelength_nm,excitation,emission`): import-spectra (builds and
    /// checks a material).
    Spectra,
    /// An absorbance spectrum: read → inner-filter correction of a staRdom EEM → fit.
    Absorbance,
}

/// One seed file.
#[derive(Debug, Clone)]
pub struct Seed {
    /// Where it came from (a path relative to the project, `../shared/data/…`, or
    /// `generated:…` for what the harness wrote).
    pub origin: String,
    /// The file name mutants are written under (keeps the extension).
    pub file_name: String,
    /// Which path its mutants go through.
    pub kind: Kind,
    /// Its bytes.
    pub bytes: Vec<u8>,
    /// Binary (EXR): no line or number mutations of the text kind.
    pub binary: bool,
}

/// The project root (this crate's manifest folder).
pub fn project_root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `../shared/data`, if present.
pub fn shared_data() -> Option<PathBuf> {
    let p = project_root().join("../shared/data");
    p.is_dir().then_some(p)
}

fn sorted_files(dir: &Path, keep: impl Fn(&str) -> bool) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut v: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .filter(|p| keep(&p.file_name().unwrap_or_default().to_string_lossy()))
        .collect();
    v.sort();
    v
}

fn seed_from(path: &Path, origin: String, kind: Kind) -> Seed {
    Seed {
        origin,
        file_name: path.file_name().unwrap().to_string_lossy().into_owned(),
        kind,
        bytes: std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())),
        binary: false,
    }
}

fn ends(name: &str, ext: &str) -> bool {
    name.to_ascii_lowercase().ends_with(ext)
}

/// A folder of `../shared/data`, which of its files to take, their kind, and at most how
/// many.
type SharedSource = (&'static str, fn(&str) -> bool, Kind, usize);

/// Every seed, in a fixed order (so a seed and index name a mutant), and the sources
/// left out with why (no `../shared/data`).
pub fn corpus() -> (Vec<Seed>, Vec<String>) {
    let root = project_root();
    let mut seeds = Vec::new();
    let mut skipped = Vec::new();
    for p in sorted_files(&root.join("data"), |n| ends(n, ".csv")) {
        let origin = format!("data/{}", p.file_name().unwrap().to_string_lossy());
        seeds.push(seed_from(&p, origin, Kind::Matrix));
    }
    for sub in ["fits", "fits/measured"] {
        for p in sorted_files(&root.join(sub), |n| ends(n, ".json")) {
            let origin = format!("{sub}/{}", p.file_name().unwrap().to_string_lossy());
            seeds.push(seed_from(&p, origin, Kind::Material));
        }
    }
    seeds.extend(written_by_fluorite(&root));
    let Some(shared) = shared_data() else {
        skipped.push("../shared/data is absent: only the shipped examples are mutated".into());
        return (seeds, skipped);
    };
    let shared_seeds: [SharedSource; 6] = [
        (
            "measured",
            |n| (ends(n, ".bfc") || ends(n, ".csv")) && !n.contains("_meta"),
            Kind::Matrix,
            usize::MAX,
        ),
        ("eem", |n| ends(n, ".txt"), Kind::Matrix, usize::MAX),
        (
            "eem-instrument",
            |n| ends(n, ".csv") && !n.contains("absorbance"),
            Kind::Matrix,
            usize::MAX,
        ),
        (
            "eem-instrument",
            |n| ends(n, "_absorbance.csv"),
            Kind::Absorbance,
            usize::MAX,
        ),
        // Two of the 27 Dorrit samples: the layout is the same in all.
        (
            "eem-instrument/dorrit",
            |n| ends(n, ".csv") && n != "concentrations.csv",
            Kind::Matrix,
            2,
        ),
        ("spectra", |n| ends(n, ".csv"), Kind::Spectra, usize::MAX),
    ];
    for (sub, keep, kind, most) in shared_seeds {
        for p in sorted_files(&shared.join(sub), keep).into_iter().take(most) {
            let origin = format!(
                "../shared/data/{sub}/{}",
                p.file_name().unwrap().to_string_lossy()
            );
            seeds.push(seed_from(&p, origin, kind));
        }
    }
    (seeds, skipped)
}

/// Files fluorite writes and reads back: a bispectral EXR exported from a fitted material,
/// a long CSV and a BFC-450 file written from a shipped example.
fn written_by_fluorite(root: &Path) -> Vec<Seed> {
    let mut seeds = Vec::new();
    let material = Material::load(&root.join("fits/two-dyes.json")).expect("fits/two-dyes.json");
    // On the 10 nm grid of the shipped examples and of a BFC-450 (300–780 nm), as a
    // bispectral measurement holds it: the material's own 1 nm tabulation would make a
    // 481 × 481 matrix whose fit alone takes seconds.
    let mut options = ExportOptions::new(ExportFormat::Exr);
    let grid = fluorite::spectrum::uniform_grid(300.0, 780.0, 10.0);
    options.excitation_nm = Some(grid.clone());
    options.emission_nm = Some(grid);
    let files = export(&material, &options).expect("exr export");
    for f in files {
        seeds.push(Seed {
            origin: format!(
                "generated:export --to exr --grid 300:780:10 of fits/two-dyes.json ({})",
                f.name
            ),
            file_name: "two-dyes.exr".into(),
            kind: Kind::Matrix,
            bytes: f.contents,
            binary: true,
        });
    }
    let example = root.join("data/green-dye.csv");
    let m = read(&example, &ReadOptions::default()).expect("data/green-dye.csv");
    seeds.push(Seed {
        origin: "generated:formats::write_long_csv of data/green-dye.csv".into(),
        file_name: "green-dye-long.csv".into(),
        kind: Kind::Matrix,
        bytes: write_long_csv(&m).into_bytes(),
        binary: false,
    });
    seeds.push(Seed {
        origin: "generated:formats::write_bfc of data/green-dye.csv".into(),
        file_name: "green-dye.BFC".into(),
        kind: Kind::Matrix,
        bytes: write_bfc(&m).expect("write_bfc").into_bytes(),
        binary: false,
    });
    seeds
}
