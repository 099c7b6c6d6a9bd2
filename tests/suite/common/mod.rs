//! Fixtures shared by the integration tests: where `../shared/data` is, and its files.
//! Tests that need it skip with a printed reason when it is absent (CI always has it).
#![allow(dead_code)] // each test crate uses its own subset

use std::path::{Path, PathBuf};

pub mod eem_sim;
pub mod map;

/// `../shared/data/<sub>` (a folder or a file), or None when it is absent: the calling
/// test then skips, and says so — `SKIPPED <test>: <reason>` on the terminal, past the test
/// harness's capture. Under CI (`CI` set and not `false`), which always has `../shared`,
/// an absent folder fails the test instead.
pub fn shared(sub: &str) -> Option<PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(sub);
    if path.exists() {
        return Some(path);
    }
    skipped(&format!("{} is absent", path.display()));
    None
}

/// Says on the terminal that the running test skips (all or part of its work), and why:
/// written to the process's stderr directly, since the harness shows a passing test's
/// `eprintln!` only on failure. Under CI nothing may skip: the test fails instead.
pub fn skipped(reason: &str) {
    use std::io::Write;
    let ci = std::env::var("CI").is_ok_and(|v| !v.is_empty() && v != "false");
    assert!(!ci, "{reason}; CI must have ../shared beside the clone");
    let thread = std::thread::current();
    let test = thread.name().unwrap_or("a test");
    let _ = writeln!(std::io::stderr().lock(), "SKIPPED {test}: {reason}");
}

/// A fresh, empty folder for `tag` of the calling test file, under the system's temporary
/// folder (named after the file, the tag and the process, so parallel tests never meet).
/// Removed when the returned guard drops, unless the test is failing: a failed test's
/// files stay for a look, and its path is printed.
#[track_caller]
pub fn temp_dir(tag: &str) -> TempDir {
    let file = Path::new(std::panic::Location::caller().file())
        .file_stem()
        .map_or_else(|| "test".to_string(), |s| s.to_string_lossy().to_string());
    static SWEPT: std::sync::Once = std::sync::Once::new();
    SWEPT.call_once(remove_stale_temp_dirs);
    let dir =
        std::env::temp_dir().join(format!("fluorite-test-{file}-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    TempDir(dir)
}

/// Removes the scratch folders of test processes that have ended: those a failed test kept
/// and those held in statics (shared fixtures, never dropped). Linux only (`/proc`).
fn remove_stale_temp_dirs() {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(std::env::temp_dir()) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().to_string();
        let Some(pid) = name
            .strip_prefix("fluorite-test-")
            .and_then(|rest| rest.rsplit('-').next())
            .and_then(|pid| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// A test's scratch folder (see [`temp_dir`]); derefs to its path.
#[derive(Debug)]
pub struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for TempDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<std::ffi::OsStr> for TempDir {
    fn as_ref(&self) -> &std::ffi::OsStr {
        self.0.as_os_str()
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("kept the failing test's files in {}", self.0.display());
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// Case `name` (`case000`, ...) of the draws `fluorite class --seed seed` makes (default
/// number of cases).
pub fn class_case(seed: u64, name: &str) -> fluorite::synth::SynthSpec {
    use fluorite::evaluate::class::{ClassConfig, draw};
    draw(&ClassConfig {
        seed,
        ..ClassConfig::default()
    })
    .unwrap()
    .specs
    .into_iter()
    .find(|s| s.name == name)
    .unwrap_or_else(|| panic!("no {name} among seed {seed:#X}'s draws"))
}

/// One file of `../shared/data/measured`.
pub fn measured(name: &str) -> Option<PathBuf> {
    shared(&format!("measured/{name}"))
}

/// The files of `dir` with one of `extensions` (lower case), sorted; metadata files
/// (`*_meta*`) left out.
pub fn files_in(dir: &Path, extensions: &[&str]) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let ext = p
                .extension()
                .map(|e| e.to_string_lossy().to_lowercase())
                .unwrap_or_default();
            extensions.contains(&ext.as_str()) && !p.to_string_lossy().contains("_meta")
        })
        .collect();
    v.sort();
    v
}

/// Every measured matrix of `../shared/data/measured` (the BFC-450 files and the CSVs).
pub fn measured_files() -> Option<Vec<PathBuf>> {
    shared("measured").map(|dir| files_in(&dir, &["bfc", "csv"]))
}

/// The files `fluorite::export::export` renders for `material`, as (name, text).
pub fn exported(
    material: &fluorite::Material,
    options: &fluorite::export::ExportOptions,
) -> Vec<(String, String)> {
    fluorite::export::export(material, options)
        .unwrap()
        .into_iter()
        .map(|f| (f.name, String::from_utf8(f.contents).unwrap()))
        .collect()
}

/// The text of the exported file `name` (panics naming the files there are).
pub fn named<'a>(files: &'a [(String, String)], name: &str) -> &'a str {
    &files
        .iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| {
            panic!(
                "{name} missing among {:?}",
                files.iter().map(|f| &f.0).collect::<Vec<_>>()
            )
        })
        .1
}

/// A PNG figure's width, height and RGB bytes (fluorite writes 8-bit RGB).
pub fn decode_png(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().expect("figure decodes as PNG");
    let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buffer).expect("PNG frame decodes");
    assert_eq!(info.color_type, png::ColorType::Rgb);
    assert_eq!(info.bit_depth, png::BitDepth::Eight);
    buffer.truncate(info.buffer_size());
    (info.width, info.height, buffer)
}

/// Runs `command` and returns its output, failing the test with its stderr unless it
/// exits 0.
pub fn succeed(command: &mut std::process::Command) -> std::process::Output {
    let out = command.output().expect("the command runs");
    assert!(
        out.status.success(),
        "{:?} failed: {}",
        command,
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// Runs `command`, which must fail with a one-line message on stderr (no backtrace);
/// returns its exit code and that message.
pub fn refused(command: &mut std::process::Command) -> (Option<i32>, String) {
    let out = command.output().expect("the command runs");
    let stderr = String::from_utf8_lossy(&out.stderr).trim().to_string();
    assert!(!out.status.success(), "{command:?} succeeded");
    assert_eq!(stderr.lines().count(), 1, "{command:?}: {stderr}");
    (out.status.code(), stderr)
}

/// The samples the classic Dorrit analysis leaves out (the data README).
pub const DORRIT_OUTLIERS: [&str; 4] = ["QAB", "QAC", "QAE", "QAA"];

/// The Dorrit EEMs of the classic analysis, prepared with the default EEM options
/// (scatter masked): (sample name, EEM), sorted by name, [`DORRIT_OUTLIERS`] left out.
/// None with a printed reason when `../shared` is absent.
pub fn dorrit_classic() -> Option<Vec<(String, fluorite::measurement::Measurement)>> {
    use fluorite::eem::{EemOptions, prepare};
    use fluorite::formats::{ReadOptions, read};
    let dir = shared("eem-instrument/dorrit")?;
    Some(
        files_in(&dir, &["csv"])
            .into_iter()
            .filter_map(|path| {
                let name = path.file_stem()?.to_string_lossy().to_string();
                let kept = name != "concentrations" && !DORRIT_OUTLIERS.contains(&name.as_str());
                kept.then_some((name, path))
            })
            .map(|(name, path)| {
                let raw = read(&path, &ReadOptions::default()).unwrap();
                (name, prepare(raw, &EemOptions::default()).unwrap().0)
            })
            .collect(),
    )
}

/// The classic Dorrit joint fit: emission 250–681 nm, excitation 230–315 nm, four
/// components, with or without the split-half diagnostic.
pub fn dorrit_classic_options(split_half: bool) -> fluorite::fit::joint::JointOptions {
    fluorite::fit::joint::JointOptions {
        parafac: fluorite::fit::joint::parafac::ParafacOptions {
            components: 4,
            ..Default::default()
        },
        em_range: Some((250.0, 681.0)),
        ex_range: Some((230.0, 315.0)),
        no_split_half: !split_half,
        second_order: false,
    }
}

/// The repository's root (the crate's manifest folder).
pub fn repository() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The `fluorite` binary under test, as a command to add arguments to.
pub fn fluorite() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_fluorite"))
}

/// Runs the binary with `args` in `dir` and returns its output.
pub fn run_in(args: &[&str], dir: &Path) -> std::process::Output {
    fluorite()
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the binary runs")
}

/// A command's stderr as text.
pub fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// ΔE2000 per named light between the measured patch of `m` (every measured cell as
/// measured, the missing ones from `material`) and `material`'s own patch, on the
/// matrix's grids: the colour check the tests make apart from the fit's report.
pub fn delta_e_to_matrix(
    material: &fluorite::Material,
    m: &fluorite::measurement::Measurement,
    lights: &[&str],
) -> Vec<(String, f64)> {
    use fluorite::colour::{Light, PatchColorimeter, delta_e2000};
    let predicted = fluorite::model::predict(
        material,
        &m.name,
        &m.excitation_nm,
        &m.emission_nm,
        fluorite::measurement::Units::PerBin,
        m.has_diagonal,
    );
    let measured = m.to_per_bin().filled_from(&predicted);
    lights
        .iter()
        .map(|name| {
            let light = Light::builtin(name).unwrap();
            let colorimeter = PatchColorimeter::new(&light, &m.excitation_nm, &m.emission_nm);
            let de = delta_e2000(colorimeter.lab(&measured), colorimeter.lab(&predicted));
            (name.to_string(), de)
        })
        .collect()
}

/// The grid fit of `m` (`fluorite fit --model tabulated`), the material every search
/// starts from.
pub fn grid_fit(m: &fluorite::measurement::Measurement) -> fluorite::Material {
    let options = fluorite::fit::FitOptions {
        model: fluorite::fit::ModelChoice::Tabulated,
        ..Default::default()
    };
    match fluorite::fit::fit(m, &options).expect("the grid fit runs") {
        fluorite::fit::FitOutcome::Material(material) => *material,
        fluorite::fit::FitOutcome::Shapes(_) => panic!("a calibrated matrix"),
    }
}
