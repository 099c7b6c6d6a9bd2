//! Outputs that are not regular files: a device such as `/dev/null` or `/dev/stdout`, or a
//! FIFO another program reads. Every write is atomic (a temporary file renamed over the
//! target), and a rename over a device replaces it: `fluorite class --report /dev/null`,
//! run as root, turned `/dev/null` into a file holding the report, and the next program
//! that read `/dev/null` (rustc, under cargo) read the report. Such targets are written in
//! place. Tested on FIFOs in a temporary folder, which a broken writer cannot harm: each
//! must still be a FIFO afterwards, and its reader must have received the bytes.
#![cfg(unix)]

use std::io::Read;
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::thread::JoinHandle;

use crate::common;

/// A FIFO at `path` and a thread that reads it to its end (it blocks until a writer opens
/// the FIFO).
fn fifo_with_reader(path: &Path) -> JoinHandle<Vec<u8>> {
    common::succeed(Command::new("mkfifo").arg(path));
    let path = path.to_path_buf();
    std::thread::spawn(move || {
        let mut bytes = Vec::new();
        std::fs::File::open(&path)
            .and_then(|mut f| f.read_to_end(&mut bytes))
            .unwrap();
        bytes
    })
}

/// Still a FIFO, and its reader got `expected`. A reader whose FIFO was replaced stays
/// blocked; it is left, not joined, so the failure is an assertion, not a hang.
fn assert_received(path: &Path, reader: JoinHandle<Vec<u8>>, expected: &[u8]) {
    let kind = std::fs::symlink_metadata(path).unwrap().file_type();
    assert!(
        kind.is_fifo(),
        "{} is no longer a FIFO: {kind:?}",
        path.display()
    );
    assert_eq!(reader.join().unwrap(), expected);
}

#[test]
fn devices_and_fifos_are_written_in_place_not_replaced() {
    let dir = common::temp_dir("special-outputs");
    let fifo = |name: &str| -> PathBuf { dir.join(name) };

    let one = fifo("one");
    let reader = fifo_with_reader(&one);
    fluorite::files::write_atomic(&one, b"a report\n").unwrap();
    assert_received(&one, reader, b"a report\n");

    // A set of files with a FIFO among them: the regular one lands as usual.
    let (two, plain) = (fifo("two"), dir.join("plain.txt"));
    let reader = fifo_with_reader(&two);
    fluorite::files::write_files(&[
        (plain.clone(), b"plain".to_vec()),
        (two.clone(), b"set".to_vec()),
    ])
    .unwrap();
    assert_received(&two, reader, b"set");
    assert_eq!(std::fs::read(&plain).unwrap(), b"plain");

    // A file written piece by piece beside its target, then moved into place.
    let three = fifo("three");
    let reader = fifo_with_reader(&three);
    let staged = fluorite::files::stage_beside(&three).unwrap();
    std::fs::write(&staged, b"staged image").unwrap();
    fluorite::files::persist_staged(&staged, &three).unwrap();
    assert_received(&three, reader, b"staged image");
    assert!(!staged.exists(), "the staged copy is removed");
}

/// The command that did it: `fluorite class --report` into a FIFO (one case, so it is quick).
#[test]
fn a_class_report_into_a_fifo_leaves_the_fifo() {
    let dir = common::temp_dir("special-outputs-cli");
    let report = dir.join("report.md");
    let reader = fifo_with_reader(&report);
    common::succeed(
        Command::new(env!("CARGO_BIN_EXE_fluorite"))
            .args(["class", "--case", "case000", "-q", "--report"])
            .arg(&report),
    );
    let kind = std::fs::symlink_metadata(&report).unwrap().file_type();
    assert!(kind.is_fifo(), "{kind:?}");
    let text = String::from_utf8(reader.join().unwrap()).unwrap();
    assert!(
        text.contains("Accuracy on a randomized class of materials"),
        "{text}"
    );
}
