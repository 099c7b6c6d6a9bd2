//! What a run has finished, kept in the work folder so that the same command started
//! again resumes after its last finished stage. A stage's result is written (atomically)
//! before it is recorded as done; a different input file (path, size or modification
//! time) or different options start afresh.

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
}

impl State {
    /// The state of a run of `key` on `image` in `folder`: resumed when an earlier run of
    /// the same command left one, fresh otherwise.
    pub fn open(folder: &Path, image: PixelSource<'_>, key: &str) -> Result<State> {
        let input = image.identity()?;
        let path = folder.join("state.json");
        if let Ok(text) = std::fs::read_to_string(&path)
            && let Ok(record) = serde_json::from_str::<Record>(&text)
            && record.key == key
            && record.input == input
        {
            return Ok(State {
                folder: folder.to_path_buf(),
                record,
            });
        }
        if folder.exists() {
            std::fs::remove_dir_all(folder).map_err(|e| Error::io(folder, e))?;
        }
        std::fs::create_dir_all(folder).map_err(|e| Error::io(folder, e))?;
        let state = State {
            folder: folder.to_path_buf(),
            record: Record {
                key: key.to_string(),
                input,
                ..Record::default()
            },
        };
        state.save()?;
        Ok(state)
    }

    fn save(&self) -> Result<()> {
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
        write_atomic(&self.folder.join(format!("{stage}.json")), text.as_bytes())?;
        self.mark(&stage)
    }

    /// The run is complete: the work folder goes.
    pub fn finish(self) -> Result<()> {
        std::fs::remove_dir_all(&self.folder).map_err(|e| Error::io(&self.folder, e))
    }
}
