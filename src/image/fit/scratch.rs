//! The compressed image on disk: one fixed-size record of 32-bit floats per pixel,
//! addressed by pixel index, so passes after the projection read it in any order and
//! memory never holds more than the records in use. Page cache, not the process, keeps
//! it close.
//!
//! A record: `[mask, energy, y (rank), diagonal (diagonal cells), off-diagonal XYZ per
//! light (3 each)]`: mask 0 for a pixel whose cells are all finite, energy Σ x² over its
//! reradiation cells, y its reradiation cells' coordinates in the shared basis.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// Where each part of a record lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordLayout {
    /// Basis vectors (length of y).
    pub rank: usize,
    /// Diagonal cells.
    pub diagonal: usize,
    /// Lights.
    pub lights: usize,
}

impl RecordLayout {
    /// Floats per record.
    pub fn len(&self) -> usize {
        2 + self.rank + self.diagonal + 3 * self.lights
    }

    /// Whether a record is empty (never: it always holds the mask and the energy).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The range of y in a record.
    pub fn y(&self) -> std::ops::Range<usize> {
        2..2 + self.rank
    }

    /// The range of the diagonal cells.
    pub fn diagonal(&self) -> std::ops::Range<usize> {
        2 + self.rank..2 + self.rank + self.diagonal
    }

    /// The range of the off-diagonal XYZ of light `l`.
    pub fn xyz(&self, l: usize) -> std::ops::Range<usize> {
        let start = 2 + self.rank + self.diagonal + 3 * l;
        start..start + 3
    }
}

/// Reads the records of pixels `first..first + count` from elsewhere.
pub type FetchRecords = Box<dyn Fn(usize, usize) -> Result<Vec<f32>> + Send + Sync>;

/// The records of `pixels` pixels: a scratch file, or records kept elsewhere (a
/// cluster's Zarr array) and fetched when read ([`Scratch::fetched`]).
pub struct Scratch {
    path: PathBuf,
    store: Store,
    /// The record layout.
    pub layout: RecordLayout,
    /// Number of records.
    pub pixels: usize,
}

enum Store {
    File(File),
    Fetched(FetchRecords),
}

impl std::fmt::Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scratch")
            .field("path", &self.path)
            .field("fetched", &matches!(self.store, Store::Fetched(_)))
            .field("layout", &self.layout)
            .field("pixels", &self.pixels)
            .finish()
    }
}

impl Scratch {
    /// Creates (or truncates) the scratch file.
    pub fn create(path: &Path, layout: RecordLayout, pixels: usize) -> Result<Scratch> {
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        file.set_len((pixels * layout.len() * 4) as u64)
            .map_err(|e| Error::io(path, e))?;
        Ok(Scratch {
            path: path.to_path_buf(),
            store: Store::File(file),
            layout,
            pixels,
        })
    }

    /// Opens an existing scratch file, checking its size.
    pub fn open(path: &Path, layout: RecordLayout, pixels: usize) -> Result<Scratch> {
        let file = File::options()
            .read(true)
            .write(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
        if len != (pixels * layout.len() * 4) as u64 {
            return Err(Error::invalid(
                path.display().to_string(),
                "the scratch file of an earlier run has the wrong size; delete the work folder",
            ));
        }
        Ok(Scratch {
            path: path.to_path_buf(),
            store: Store::File(file),
            layout,
            pixels,
        })
    }

    /// Records kept elsewhere, read through `fetch` (read-only): when the passes over
    /// the records and the outputs run where the records are, the process that runs the
    /// fit reads only a few pixels (the start's), not a copy of every record. `name`
    /// names them in errors.
    pub fn fetched(
        name: &str,
        layout: RecordLayout,
        pixels: usize,
        fetch: FetchRecords,
    ) -> Scratch {
        Scratch {
            path: PathBuf::from(name),
            store: Store::Fetched(fetch),
            layout,
            pixels,
        }
    }

    fn file(&self) -> Result<&File> {
        match &self.store {
            Store::File(file) => Ok(file),
            Store::Fetched(_) => Err(Error::invalid(
                self.path.display().to_string(),
                "records kept elsewhere are read-only",
            )),
        }
    }

    /// Writes the records of pixels `first..first + records.len() / record length`.
    pub fn write(&self, first: usize, records: &[f32]) -> Result<()> {
        let bytes: Vec<u8> = records.iter().flat_map(|v| v.to_le_bytes()).collect();
        self.file()?
            .write_all_at(&bytes, (first * self.layout.len() * 4) as u64)
            .map_err(|e| Error::io(&self.path, e))
    }

    /// Reads the records of pixels `first..first + count`.
    pub fn read(&self, first: usize, count: usize) -> Result<Vec<f32>> {
        let file = match &self.store {
            Store::File(file) => file,
            Store::Fetched(fetch) => {
                let records = fetch(first, count)?;
                if records.len() != count * self.layout.len() {
                    return Err(Error::invalid(
                        self.path.display().to_string(),
                        format!(
                            "{} values fetched for {count} records of {}",
                            records.len(),
                            self.layout.len()
                        ),
                    ));
                }
                return Ok(records);
            }
        };
        let mut bytes = vec![0u8; count * self.layout.len() * 4];
        file.read_exact_at(&mut bytes, (first * self.layout.len() * 4) as u64)
            .map_err(|e| Error::io(&self.path, e))?;
        Ok(bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect())
    }

    /// Flushes to disk (before a stage is recorded as done).
    pub fn sync(&self) -> Result<()> {
        match &self.store {
            Store::File(file) => file.sync_all().map_err(|e| Error::io(&self.path, e)),
            Store::Fetched(_) => Ok(()),
        }
    }
}
