//! Every shell example in README.md and docs/*.md runs against the built binary.
//!
//! Conventions (docs/README.md, "Examples are tested"):
//! - ```` ```sh ````, ```` ```bash ```` and ```` ```console ```` blocks are run; other
//!   fences (json, text, none) are not.
//! - A block is skipped when its info string says `no-run` (```` ```sh no-run: reason ````)
//!   or the line before the fence is `<!-- no-run: reason -->`; the reason is mandatory
//!   and the test prints every skipped block with it.
//! - In sh/bash blocks every logical line (`\` continues it) is one command, run by bash
//!   from a scratch copy of the repository's `data/` and `fits/` with `../shared` beside
//!   it; `fluorite` and `cargo run --release --` are the binary under test. `NAME=value`
//!   lines set a variable for the rest of the block. Comment lines after a command:
//!   `# expect: TEXT` (TEXT must appear in its stdout or stderr), `# exit: N` (the exit
//!   code it must end with; 0 otherwise).
//! - In console blocks, `$ command` lines are commands and the lines after one are
//!   substrings its output must contain.
//! - `cargo test`, `cargo bench`, `cargo install`, `cargo build` and scripts under
//!   `scripts/` or `.ci/` are not run (they build or run the whole project); the test
//!   lists them as skipped.
//!
//! Commands write only into the scratch copy, so the repository is unchanged by
//! construction; the test also compares `git status --porcelain` before and after.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Longest any single documented command may take in the test profile.
const COMMAND_TIMEOUT: Duration = Duration::from_secs(240);

/// One command taken from a doc page, with what it must produce.
#[derive(Debug, Clone)]
struct Example {
    /// `file:line` of the command, for messages.
    place: String,
    /// Variable assignments of the block that precede the command.
    prelude: Vec<String>,
    /// The command as bash runs it.
    command: String,
    /// Substrings the combined stdout and stderr must contain.
    expect: Vec<String>,
    /// The exit code the command must end with.
    exit: i32,
}

/// A block or command the test does not run, and why.
#[derive(Debug, Clone)]
struct Skipped {
    place: String,
    reason: String,
}

/// What one page yields: the commands to run, in order, and what was skipped.
#[derive(Debug, Default)]
struct Page {
    examples: Vec<Example>,
    skipped: Vec<Skipped>,
}

/// The reason in `no-run: reason` (or `no-run reason`), if `text` holds the marker.
fn no_run_reason(text: &str) -> Option<String> {
    let at = text.find("no-run")?;
    let reason = text[at + "no-run".len()..]
        .trim_start_matches(':')
        .trim()
        .trim_end_matches("-->")
        .trim();
    Some(reason.to_string())
}

/// Why a command is not run, if it is one of the project-wide ones.
fn project_command_reason(command: &str) -> Option<&'static str> {
    let c = command.trim();
    if c.starts_with("cargo test") {
        Some("runs the test suite (this test is part of it)")
    } else if c.starts_with("cargo bench") {
        Some("benchmarks take minutes; timings are not asserted")
    } else if c.starts_with("cargo install") || c.starts_with("cargo build") {
        Some("builds or installs the project")
    } else if c.starts_with("scripts/") || c.starts_with(".ci/") {
        Some("a project script (regenerates fits/ or installs external renderers)")
    } else {
        None
    }
}

/// Maps `cargo run --release --` to the binary under test (found on PATH as `fluorite`).
fn map_binary(command: &str) -> String {
    command.replace("cargo run --release --", "fluorite")
}

fn is_assignment(line: &str) -> bool {
    let Some((name, value)) = line.split_once('=') else {
        return false;
    };
    !name.is_empty()
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        && !name.starts_with(|c: char| c.is_ascii_digit())
        && !value.contains(char::is_whitespace)
}

/// Joins `\`-continued lines; each result keeps the number of its first line.
fn logical_lines(lines: &[(usize, &str)]) -> Vec<(usize, String)> {
    let mut out: Vec<(usize, String)> = Vec::new();
    let mut pending: Option<(usize, String)> = None;
    for &(number, line) in lines {
        let (start, mut text) = pending.take().unwrap_or((number, String::new()));
        if let Some(body) = line.trim_end().strip_suffix('\\') {
            text.push_str(body);
            text.push(' ');
            pending = Some((start, text));
        } else {
            text.push_str(line);
            out.push((start, text));
        }
    }
    out.extend(pending);
    out
}

/// The commands of one sh/bash block.
fn shell_block(file: &str, lines: &[(usize, &str)], page: &mut Page) {
    let mut prelude = Vec::new();
    let block_start = page.examples.len();
    for (number, line) in logical_lines(lines) {
        let trimmed = line.trim();
        let place = format!("{file}:{number}");
        if trimmed.is_empty() {
            continue;
        }
        if let Some(comment) = trimmed.strip_prefix('#') {
            let comment = comment.trim();
            let expect = comment.strip_prefix("expect:");
            let exit = comment.strip_prefix("exit:");
            if expect.is_none() && exit.is_none() {
                continue; // a plain comment
            }
            assert!(
                page.examples.len() > block_start,
                "{place}: `# expect:` and `# exit:` follow the command they are about, in its block"
            );
            let last = page.examples.last_mut().expect("checked above");
            if let Some(text) = expect {
                last.expect.push(text.trim().to_string());
            }
            if let Some(code) = exit {
                last.exit = code.trim().parse().expect("`# exit: N` takes a number");
            }
            continue;
        }
        if is_assignment(trimmed) {
            prelude.push(trimmed.to_string());
            continue;
        }
        if let Some(reason) = project_command_reason(trimmed) {
            page.skipped.push(Skipped {
                place: format!("{place} `{trimmed}`"),
                reason: reason.to_string(),
            });
            continue;
        }
        page.examples.push(Example {
            place,
            prelude: prelude.clone(),
            command: map_binary(trimmed),
            expect: Vec::new(),
            exit: 0,
        });
    }
}

/// The commands of one console block: `$ command` lines, then the output they must show.
fn console_block(file: &str, lines: &[(usize, &str)], page: &mut Page) {
    let mut current: Option<Example> = None;
    let mut command_lines: Vec<(usize, &str)> = Vec::new();
    let flush = |current: &mut Option<Example>, page: &mut Page| {
        if let Some(example) = current.take() {
            page.examples.push(example);
        }
    };
    for &(number, line) in lines {
        if let Some(command) = line.strip_prefix("$ ") {
            flush(&mut current, page);
            command_lines.clear();
            command_lines.push((number, command));
            if !command.trim_end().ends_with('\\') {
                let (start, text) = logical_lines(&command_lines).remove(0);
                current = new_console_example(file, start, &text, page);
            }
        } else if !command_lines.is_empty() && current.is_none() {
            command_lines.push((number, line));
            if !line.trim_end().ends_with('\\') {
                let (start, text) = logical_lines(&command_lines).remove(0);
                current = new_console_example(file, start, &text, page);
            }
        } else if let Some(example) = current.as_mut()
            && !line.trim().is_empty()
        {
            example.expect.push(line.trim().to_string());
        }
    }
    flush(&mut current, page);
}

fn new_console_example(file: &str, number: usize, text: &str, page: &mut Page) -> Option<Example> {
    let place = format!("{file}:{number}");
    if let Some(reason) = project_command_reason(text) {
        page.skipped.push(Skipped {
            place: format!("{place} `{}`", text.trim()),
            reason: reason.to_string(),
        });
        return None;
    }
    Some(Example {
        place,
        prelude: Vec::new(),
        command: map_binary(text.trim()),
        expect: Vec::new(),
        exit: 0,
    })
}

/// Every runnable command of a Markdown page, in order, and every skipped block.
fn parse_page(file: &str, markdown: &str) -> Page {
    let mut page = Page::default();
    let lines: Vec<&str> = markdown.lines().collect();
    let mut i = 0;
    let mut previous_text_line = "";
    while i < lines.len() {
        let line = lines[i];
        let Some(info) = line.trim_start().strip_prefix("```") else {
            if !line.trim().is_empty() {
                previous_text_line = line;
            }
            i += 1;
            continue;
        };
        let fence_line = i + 1;
        let mut body: Vec<(usize, &str)> = Vec::new();
        i += 1;
        while i < lines.len() && !lines[i].trim_start().starts_with("```") {
            body.push((i + 1, lines[i]));
            i += 1;
        }
        i += 1; // the closing fence
        let lang = info.split_whitespace().next().unwrap_or("");
        let comment_reason = previous_text_line
            .trim()
            .starts_with("<!--")
            .then(|| no_run_reason(previous_text_line))
            .flatten();
        previous_text_line = "";
        if !matches!(lang, "sh" | "bash" | "console") {
            continue;
        }
        let place = format!("{file}:{fence_line}");
        if let Some(reason) = no_run_reason(info).or(comment_reason) {
            assert!(
                !reason.is_empty(),
                "{place}: a no-run block must say why (`no-run: reason`)"
            );
            page.skipped.push(Skipped { place, reason });
            continue;
        }
        if lang == "console" {
            console_block(file, &body, &mut page);
        } else {
            shell_block(file, &body, &mut page);
        }
    }
    page
}

/// README.md and docs/*.md, sorted, relative to the repository.
fn doc_pages(repo: &Path) -> Vec<PathBuf> {
    let mut pages = vec![PathBuf::from("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(repo.join("docs"))
        .map(|entries| {
            entries
                .map(|e| e.unwrap().path())
                .filter(|p| p.extension().is_some_and(|e| e == "md"))
                .map(|p| p.strip_prefix(repo).unwrap().to_path_buf())
                .collect()
        })
        .unwrap_or_default();
    docs.sort();
    pages.extend(docs);
    pages
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

/// A scratch folder laid out like the workspace: `repo/` holds copies of `data/` and
/// `fits/`, `shared` links to the real `../shared` (read only by the examples), `bin/`
/// holds `fluorite`. Returns the scratch folder's guard, the folder the commands run in
/// and the PATH to give them.
#[cfg(unix)]
fn scratch(tag: &str, shared: &Path) -> (common::TempDir, PathBuf, String) {
    let root = common::temp_dir(tag);
    let repo_source = Path::new(env!("CARGO_MANIFEST_DIR"));
    let repo = root.join("repo");
    for dir in ["data", "fits"] {
        copy_dir(&repo_source.join(dir), &repo.join(dir));
    }
    std::os::unix::fs::symlink(shared.parent().unwrap(), root.join("shared")).unwrap();
    let bin = root.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_fluorite"), bin.join("fluorite")).unwrap();
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    (root, repo, path)
}

/// Runs one example; None when it did what the page says, else what went wrong.
fn run_example(example: &Example, dir: &Path, path: &str) -> Option<String> {
    let script = example
        .prelude
        .iter()
        .map(String::as_str)
        .chain([example.command.as_str()])
        .collect::<Vec<_>>()
        .join("\n");
    let started = Instant::now();
    let mut child = Command::new("bash")
        .args(["-c", &script])
        .current_dir(dir)
        .env("PATH", path)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("bash runs the examples");
    // Read both pipes on threads so a chatty command cannot fill one and stall.
    let mut stdout = child.stdout.take().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut stdout, &mut s).ok();
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        std::io::Read::read_to_string(&mut stderr, &mut s).ok();
        s
    });
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if started.elapsed() > COMMAND_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let output = format!("{}{}", out.join().unwrap(), err.join().unwrap());
    let seconds = started.elapsed().as_secs_f64();
    eprintln!(
        "  {:6.2} s  {}  {}",
        seconds, example.place, example.command
    );
    let tail = |s: &str| {
        let lines: Vec<&str> = s.lines().collect();
        lines[lines.len().saturating_sub(15)..].join("\n")
    };
    let Some(status) = status else {
        return Some(format!(
            "{}: `{}` took longer than {:?}",
            example.place, example.command, COMMAND_TIMEOUT
        ));
    };
    let code = status.code().unwrap_or(-1);
    if code != example.exit {
        return Some(format!(
            "{}: `{}` exited with {code}, the page says {}\n{}",
            example.place,
            example.command,
            example.exit,
            tail(&output)
        ));
    }
    let missing: Vec<&String> = example
        .expect
        .iter()
        .filter(|text| !output.contains(text.as_str()))
        .collect();
    (!missing.is_empty()).then(|| {
        format!(
            "{}: `{}` printed none of {missing:?}\n{}",
            example.place,
            example.command,
            tail(&output)
        )
    })
}

/// Runs every example of one page, in order, in its own scratch copy; returns the failures.
#[cfg(unix)]
fn run_page(tag: &str, name: &str, page: &Page, shared: &Path) -> Vec<String> {
    let (_scratch, dir, path) = scratch(tag, shared);
    eprintln!("{name}: {} commands", page.examples.len());
    let failures = page
        .examples
        .iter()
        .filter_map(|example| run_example(example, &dir, &path))
        .collect();
    let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    failures
}

fn git_status(repo: &Path) -> Option<String> {
    let output = Command::new("git")
        .args(["status", "--porcelain"])
        .current_dir(repo)
        .output()
        .ok()?;
    output
        .status
        .success()
        .then(|| String::from_utf8_lossy(&output.stdout).into_owned())
}

#[cfg(unix)]
#[test]
fn every_shell_example_in_the_docs_runs_as_documented() {
    let Some(shared) = common::shared("") else {
        return;
    };
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let pages: Vec<(String, Page)> = doc_pages(repo)
        .into_iter()
        .map(|page| {
            let name = page.display().to_string();
            let text = std::fs::read_to_string(repo.join(&page)).unwrap();
            let parsed = parse_page(&name, &text);
            (name, parsed)
        })
        .collect();
    assert!(
        pages.len() > 1,
        "docs/ holds the guide; found only {pages:?}"
    );
    let commands: usize = pages.iter().map(|(_, p)| p.examples.len()).sum();
    eprintln!("skipped (not run):");
    for (_, page) in &pages {
        for skipped in &page.skipped {
            eprintln!("  {}: {}", skipped.place, skipped.reason);
        }
    }
    let before = git_status(repo);
    // Two pages at a time: the machine the docs promise has two cores.
    let failures: Vec<String> = std::thread::scope(|scope| {
        let handles: Vec<_> = pages
            .chunks(pages.len().div_ceil(2))
            .enumerate()
            .map(|(half, chunk)| {
                let shared = &shared;
                scope.spawn(move || {
                    chunk
                        .iter()
                        .enumerate()
                        .flat_map(|(index, (name, page))| {
                            run_page(&format!("doc{half}-{index}"), name, page, shared)
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    let after = git_status(repo);
    assert!(
        failures.is_empty(),
        "{} of {commands} documented commands failed:\n\n{}",
        failures.len(),
        failures.join("\n\n")
    );
    assert_eq!(
        before, after,
        "running the doc examples changed the repository (git status --porcelain)"
    );
}

/// The harness itself: a flag the binary does not know fails, an `# expect:` the output
/// lacks fails, and `# exit:` and `no-run` are honoured.
#[cfg(unix)]
#[test]
fn a_wrong_flag_or_a_missing_expected_text_fails_the_doc_test() {
    let Some(shared) = common::shared("") else {
        return;
    };
    let page = "\
Text.

```sh
fluorite check fits/red-pigment.json
# expect: red-pigment
fluorite check fits/red-pigment.json --no-such-flag
fluorite check fits/red-pigment.json
# expect: text the check never prints
fluorite check fits/no-such-material.json
# exit: 2
```

<!-- no-run: shows a placeholder -->
```sh
fluorite fit m.BFC
```

```sh no-run: a placeholder too
fluorite fit m.BFC
```

```console
$ fluorite check \\
    fits/red-pigment.json
red-pigment
```

```sh
cargo test
```
";
    let parsed = parse_page("example.md", page);
    let commands: Vec<&str> = parsed.examples.iter().map(|e| e.command.as_str()).collect();
    assert_eq!(commands.len(), 5, "{commands:?}");
    assert_eq!(parsed.examples[0].expect, ["red-pigment"]);
    assert_eq!(parsed.examples[3].exit, 2);
    assert_eq!(parsed.examples[4].expect, ["red-pigment"]);
    let reasons: Vec<&str> = parsed.skipped.iter().map(|s| s.reason.as_str()).collect();
    assert_eq!(
        reasons,
        [
            "shows a placeholder",
            "a placeholder too",
            "runs the test suite (this test is part of it)"
        ]
    );
    let (_scratch, dir, path) = scratch("harness", &shared);
    let outcomes: Vec<bool> = parsed
        .examples
        .iter()
        .map(|example| run_example(example, &dir, &path).is_none())
        .collect();
    let _ = std::fs::remove_dir_all(dir.parent().unwrap());
    assert_eq!(outcomes, [true, false, false, true, true]);
}

/// Pages the README announces before they exist (linked as "not yet").
const ANNOUNCED_PAGES: &[&str] = &["docs/python.md"];

/// GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of a page's headings (outside code blocks).
fn anchors(markdown: &str) -> Vec<String> {
    let mut in_code = false;
    let mut out = Vec::new();
    for line in markdown.lines() {
        if line.trim_start().starts_with("```") {
            in_code = !in_code;
        } else if !in_code && line.starts_with('#') {
            out.push(anchor(line.trim_start_matches('#')));
        }
    }
    out
}

/// Every relative link of the README and the guide (files, images, and the heading a
/// `#fragment` names) points at something that exists, so moving text between pages
/// cannot leave a dead link behind.
#[test]
fn relative_links_in_the_docs_resolve() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let link = regex::Regex::new(r"\]\(([^)\s#]*)(?:#([^)\s]*))?\)").unwrap();
    let mut dead = Vec::new();
    for page in doc_pages(repo) {
        let text = std::fs::read_to_string(repo.join(&page)).unwrap();
        let folder = page.parent().unwrap_or(Path::new(""));
        for (number, line) in text.lines().enumerate() {
            for captures in link.captures_iter(line) {
                let target = &captures[1];
                if target.contains("://") || target.starts_with("mailto:") {
                    continue;
                }
                let place = format!("{}:{}: {}", page.display(), number + 1, &captures[0]);
                let path = if target.is_empty() {
                    page.clone()
                } else {
                    folder.join(target)
                };
                let normalised = path.to_string_lossy().replace("docs/../", "");
                if !repo.join(&path).exists() {
                    if !ANNOUNCED_PAGES.contains(&normalised.as_str()) {
                        dead.push(place);
                    }
                    continue;
                }
                if let Some(fragment) = captures.get(2) {
                    let linked = std::fs::read_to_string(repo.join(&path)).unwrap_or_default();
                    if !anchors(&linked).iter().any(|a| a == fragment.as_str()) {
                        dead.push(format!("{place} (no such heading)"));
                    }
                }
            }
        }
    }
    assert!(dead.is_empty(), "dead links:\n{}", dead.join("\n"));
}
