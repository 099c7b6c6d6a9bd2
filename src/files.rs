//! Writing files, at the ground floor: every command that writes (materials, exports,
//! figures, renders, tables) goes through here, so an interrupted or failed run never
//! leaves a half-written file.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};

use crate::error::{Error, Result};

/// Set once [`interrupt`] ran: from then on nothing is written.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);

/// The temporary files being written now. Renames into place happen while this lock is
/// held, so [`interrupt`] sees every file either still temporary (and removes it) or
/// wholly in place, and a set of files ([`write_files`]) either wholly in place or not.
static STAGED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn staged() -> MutexGuard<'static, Vec<PathBuf>> {
    // A writer that panicked left a list that is still a plain list of paths.
    STAGED
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// For an interrupt handler (Ctrl-C): from now on every write fails, and the temporary
/// files being written are removed, so what a run leaves is only whole files written
/// before the interrupt. Returns when the file system is in that state; the caller then
/// ends the process.
pub fn interrupt() {
    let mut pending = staged();
    INTERRUPTED.store(true, Ordering::SeqCst);
    for path in pending.drain(..) {
        let _ = std::fs::remove_file(path);
    }
}

/// An error naming `path` once [`interrupt`] ran: long loops call it between steps so that
/// an interrupted run stops promptly.
pub fn check_interrupted(path: &Path) -> Result<()> {
    refuse_if_interrupted(path)
}

/// A temporary path beside `path` for a file written piece by piece (large images), to be
/// moved into place with [`persist_staged`]; [`interrupt`] removes it.
pub fn stage_beside(path: &Path) -> Result<PathBuf> {
    refuse_if_interrupted(path)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = dir.join(format!(".fluorite-{}-{name}", std::process::id()));
    staged().push(tmp.clone());
    Ok(tmp)
}

/// Moves a file written with [`stage_beside`] into place (atomically: a rename), or
/// copies it into a target that is no regular file (a device or a FIFO).
pub fn persist_staged(tmp: &Path, path: &Path) -> Result<()> {
    let mut pending = staged();
    refuse_if_interrupted(path)?;
    pending.retain(|p| p != tmp);
    if is_stream(path) {
        let copied = std::fs::File::open(tmp).and_then(|mut from| {
            let mut to = std::fs::OpenOptions::new().write(true).open(path)?;
            std::io::copy(&mut from, &mut to).map(|_| ())
        });
        let _ = std::fs::remove_file(tmp);
        return copied.map_err(|e| Error::io(path, e));
    }
    std::fs::rename(tmp, path).map_err(|e| Error::io(path, e))
}

/// Whether `path` names something other than a regular file or a folder: a device
/// (`/dev/null`, `/dev/stdout`), a FIFO or a socket. Renaming a temporary file over it
/// would replace it (as root, `/dev/null` itself became a file holding a report, and the
/// next program reading it read the report), so such targets are written in place: they
/// keep no file that a half-finished write could leave behind.
fn is_stream(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir())
}

/// Writes `bytes` into the existing target `path` ([`is_stream`]), as it stands.
fn write_in_place(path: &Path, bytes: &[u8]) -> Result<()> {
    refuse_if_interrupted(path)?;
    std::fs::OpenOptions::new()
        .write(true)
        .open(path)
        .and_then(|mut f| f.write_all(bytes))
        .map_err(|e| Error::io(path, e))
}

/// Removes a file written with [`stage_beside`] that will not be kept.
pub fn discard_staged(tmp: &Path) {
    let mut pending = staged();
    pending.retain(|p| p != tmp);
    let _ = std::fs::remove_file(tmp);
}

fn refuse_if_interrupted(path: &Path) -> Result<()> {
    if INTERRUPTED.load(Ordering::SeqCst) {
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::Interrupted,
                "interrupted before this file was written; nothing was written",
            ),
        ));
    }
    Ok(())
}

/// Writes `bytes` to `path` atomically: into a temporary file in the same folder, then
/// renamed over the target, so an interrupted or failed run never leaves a half-written
/// file. The folder must exist. A device or FIFO (`/dev/null`) is written in place.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    if is_stream(path) {
        return write_in_place(path, bytes);
    }
    let tmp = temporary_beside(path, bytes)?;
    let mut pending = staged();
    refuse_if_interrupted(path)?;
    pending.retain(|p| p != tmp.path());
    tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
    Ok(())
}

/// Writes `bytes` into a temporary file in `path`'s folder (deleted when dropped, and by
/// [`interrupt`]).
fn temporary_beside(path: &Path, bytes: &[u8]) -> Result<tempfile::NamedTempFile> {
    refuse_if_interrupted(path)?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!(
                    "output folder {} does not exist; create it first",
                    dir.display()
                ),
            ),
        ));
    }
    let mut tmp = {
        let mut pending = staged();
        refuse_if_interrupted(path)?;
        let tmp = tempfile::Builder::new()
            .prefix(".fluorite-")
            .tempfile_in(dir)
            .map_err(|e| Error::io(path, e))?;
        pending.push(tmp.path().to_path_buf());
        tmp
    };
    tmp.write_all(bytes).map_err(|e| Error::io(path, e))?;
    tmp.as_file().sync_all().map_err(|e| Error::io(path, e))?;
    // Temporary files are private (0600); results are ordinary files others may read.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        tmp.as_file()
            .set_permissions(std::fs::Permissions::from_mode(0o644))
            .map_err(|e| Error::io(path, e))?;
    }
    Ok(tmp)
}

/// Writes several files all-or-nothing as far as the file system allows: every file is
/// first written to a temporary file beside its target; only when all are written are
/// they renamed into place. A folder in the way of a target is an error before anything
/// is written. Devices and FIFOs among the targets are written in place, after the rest.
pub fn write_files(files: &[(PathBuf, Vec<u8>)]) -> Result<()> {
    for (path, _) in files {
        if path.is_dir() {
            return Err(Error::io(
                path,
                std::io::Error::new(
                    std::io::ErrorKind::AlreadyExists,
                    "a folder of this name is in the way; remove it or choose another output",
                ),
            ));
        }
    }
    let (streams, files): (Vec<_>, Vec<_>) = files.iter().partition(|(p, _)| is_stream(p));
    let mut written = Vec::with_capacity(files.len());
    for (path, bytes) in files {
        written.push((path, temporary_beside(path, bytes)?));
    }
    let mut pending = staged();
    if let Some((path, _)) = written.first() {
        refuse_if_interrupted(path)?;
    }
    for (path, tmp) in written {
        pending.retain(|p| p != tmp.path());
        tmp.persist(path).map_err(|e| Error::io(path, e.error))?;
    }
    drop(pending);
    for (path, bytes) in streams {
        write_in_place(path, bytes)?;
    }
    Ok(())
}
