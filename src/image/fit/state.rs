//! What a run has finished, kept in the work folder so that the same command started
//! again resumes after its last finished stage. A stage's result is written (atomically)
//! before it is recorded as done. A work folder of different options or another fluorite
//! version, of a different input (path, size, modification or status-change time, or the
//! bytes at either end of the file), or one whose recorded stages' files are missing or
//! damaged, is not resumed: the run starts afresh, and replaces that folder only when it
//! first has something to keep (after the first pass has read the whole input), so a run
//! refused for bad input leaves an earlier run's work folder as it was.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::files::write_atomic;
use crate::image::array::PixelSource;

use super::Trial;
use super::passes::Census;

/// The record of finished stages.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
struct Record {
    key: String,
    input: String,
    done: Vec<String>,
    masked_pixels: usize,
    non_finite_cells: usize,
}

/// A run's state in its work folder.
#[derive(Debug)]
pub struct State {
    folder: PathBuf,
    record: Record,
    /// Nothing of this run is on disk yet: the first save replaces the folder.
    fresh: bool,
}

/// The sizes a resumable work folder's files must have.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Expected {
    /// Bytes of each basis file.
    pub basis_bytes: u64,
    /// Bytes of the scratch file.
    pub scratch_bytes: u64,
}

impl State {
    /// The state of a run of `key` on `image` in `folder`: resumed when an earlier run of
    /// the same command left one whose files are whole, fresh otherwise (the folder is
    /// left as it is until the first save).
    pub fn open(
        folder: &Path,
        image: PixelSource<'_>,
        key: &str,
        expected: Expected,
    ) -> Result<State> {
        let input = image.identity()?;
        if let Some(record) = resumable(folder, key, &input, expected) {
            return Ok(State {
                folder: folder.to_path_buf(),
                record,
                fresh: false,
            });
        }
        Ok(State {
            folder: folder.to_path_buf(),
            record: Record {
                key: key.to_string(),
                input,
                ..Record::default()
            },
            fresh: true,
        })
    }

    /// A fresh run's first save: the folder an earlier run left goes.
    fn prepare(&mut self) -> Result<()> {
        if self.fresh {
            if self.folder.exists() {
                std::fs::remove_dir_all(&self.folder).map_err(|e| Error::io(&self.folder, e))?;
            }
            std::fs::create_dir_all(&self.folder).map_err(|e| Error::io(&self.folder, e))?;
            self.fresh = false;
        }
        Ok(())
    }

    fn save(&mut self) -> Result<()> {
        self.prepare()?;
        let text = serde_json::to_string_pretty(&self.record).expect("state serialises");
        write_atomic(&self.folder.join("state.json"), text.as_bytes())
    }

    /// Whether `stage` is done.
    pub fn done(&self, stage: &str) -> bool {
        self.record.done.iter().any(|d| d == stage)
    }

    /// Records `stage` as done.
    pub fn mark(&mut self, stage: &str) -> Result<()> {
        if !self.done(stage) {
            self.record.done.push(stage.to_string());
        }
        self.save()
    }

    /// The basis after `step` power steps (0: the sketch's), and the census.
    pub fn basis(&self, step: usize) -> Result<Option<(Vec<f64>, Census)>> {
        let stage = format!("basis-{step}");
        if !self.done(&stage) {
            return Ok(None);
        }
        let path = self.folder.join(format!("{stage}.f64"));
        let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
        let basis = bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        Ok(Some((
            basis,
            Census {
                masked_pixels: self.record.masked_pixels,
                non_finite_cells: self.record.non_finite_cells,
            },
        )))
    }

    /// Keeps the basis after `step` power steps.
    pub fn save_basis(&mut self, step: usize, basis: &[f64], census: &Census) -> Result<()> {
        let stage = format!("basis-{step}");
        let bytes: Vec<u8> = basis.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.prepare()?;
        write_atomic(&self.folder.join(format!("{stage}.f64")), &bytes)?;
        self.record.masked_pixels = census.masked_pixels;
        self.record.non_finite_cells = census.non_finite_cells;
        self.mark(&stage)
    }

    /// The trial of K fluorophores, if finished.
    pub fn trial(&self, k: usize) -> Result<Option<Trial>> {
        let stage = format!("trial-{k}");
        if !self.done(&stage) {
            return Ok(None);
        }
        let path = self.folder.join(format!("{stage}.json"));
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        serde_json::from_str(&text)
            .map(Some)
            .map_err(|e| Error::parse(&path, e.line(), e.column(), e.to_string()))
    }

    /// Keeps a finished trial.
    pub fn save_trial(&mut self, trial: &Trial) -> Result<()> {
        let stage = format!("trial-{}", trial.components);
        let text = serde_json::to_string(trial).expect("a trial serialises");
        self.prepare()?;
        write_atomic(&self.folder.join(format!("{stage}.json")), text.as_bytes())?;
        self.mark(&stage)
    }

    /// The work folder, created (and an earlier run's replaced) if this run had not yet.
    pub fn folder(&mut self) -> Result<&Path> {
        self.prepare()?;
        Ok(&self.folder)
    }

    /// The run is complete: the work folder goes.
    pub fn finish(self) -> Result<()> {
        if self.fresh && !self.folder.exists() {
            return Ok(());
        }
        std::fs::remove_dir_all(&self.folder).map_err(|e| Error::io(&self.folder, e))
    }
}

/// The record in `folder` if it is of this command (`key`) on this input and every stage
/// it records as done left its file whole.
fn resumable(folder: &Path, key: &str, input: &str, expected: Expected) -> Option<Record> {
    let text = std::fs::read_to_string(folder.join("state.json")).ok()?;
    let record = serde_json::from_str::<Record>(&text).ok()?;
    if record.key != key || record.input != input {
        return None;
    }
    let size = |name: &str| std::fs::metadata(folder.join(name)).ok().map(|m| m.len());
    let whole = record.done.iter().all(|stage| {
        if stage.starts_with("basis-") {
            size(&format!("{stage}.f64")) == Some(expected.basis_bytes)
        } else if let Some(k) = stage.strip_prefix("trial-") {
            std::fs::read_to_string(folder.join(format!("{stage}.json")))
                .ok()
                .and_then(|t| serde_json::from_str::<Trial>(&t).ok())
                .is_some_and(|t| k.parse() == Ok(t.components))
        } else if stage == "projection" {
            size("scratch.f32") == Some(expected.scratch_bytes)
        } else {
            stage == "outputs"
        }
    });
    whole.then_some(record)
}
