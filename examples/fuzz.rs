//! The long fuzz campaign (issue 21): the mutator and runner of `tests/suite/fuzz.rs` over any
//! number of mutants, in release, through the library and, for a sample, through the
//! `fluorite` binary. scripts/fuzz-campaign.sh drives it.
//!
//! ```text
//! cargo run --release --example fuzz -- [--seed S] [--count N] [--first I] [--workers W]
//!     [--budget-ms MS] [--out DIR] [--cli PATH --cli-every K --cli-timeout-s S]
//!     [--max-failures F] [--replay I]
//! ```
//! Exit 0 when no mutant failed, 1 otherwise. `--replay I` writes mutant I of the seed
//! to `--out` and prints its recipe and the command that replays it.

#[path = "../tests/suite/fuzz/harness/mod.rs"]
mod harness;

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use harness::corpus::Kind;
use harness::run::{Campaign, Harness, campaign, replay_command, summary};

struct Args {
    seed: u64,
    first: u64,
    count: u64,
    workers: usize,
    budget: Duration,
    out: PathBuf,
    cli: Option<PathBuf>,
    cli_every: u64,
    cli_timeout: Duration,
    max_failures: usize,
    replay: Option<u64>,
}

fn parse_args() -> Result<Args, String> {
    let mut a = Args {
        seed: 1,
        first: 0,
        count: 1_000_000,
        workers: std::thread::available_parallelism().map_or(2, |n| n.get()),
        budget: Duration::from_secs(2),
        out: std::env::temp_dir().join("fluorite-fuzz"),
        cli: None,
        cli_every: 1000,
        cli_timeout: Duration::from_secs(20),
        max_failures: 50,
        replay: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        let number = |v: String| {
            v.replace('_', "")
                .parse::<u64>()
                .map_err(|e| format!("{flag} {v}: {e}"))
        };
        match flag.as_str() {
            "--seed" => a.seed = number(value()?)?,
            "--first" => a.first = number(value()?)?,
            "--count" => a.count = number(value()?)?,
            "--workers" => a.workers = number(value()?)?.max(1) as usize,
            "--budget-ms" => a.budget = Duration::from_millis(number(value()?)?),
            "--out" => a.out = PathBuf::from(value()?),
            "--cli" => a.cli = Some(PathBuf::from(value()?)),
            "--cli-every" => a.cli_every = number(value()?)?.max(1),
            "--cli-timeout-s" => a.cli_timeout = Duration::from_secs(number(value()?)?),
            "--max-failures" => a.max_failures = number(value()?)? as usize,
            "--replay" => a.replay = Some(number(value()?)?),
            "--bench" => {} // cargo passes it to examples run as benches
            other => return Err(format!("unknown argument {other}")),
        }
    }
    Ok(a)
}

fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("fuzz: {e}");
            return ExitCode::from(2);
        }
    };
    let harness = Arc::new(Harness::new());
    for note in &harness.skipped {
        eprintln!("fuzz: {note}");
    }
    std::fs::create_dir_all(&args.out).expect("output folder");
    if let Some(index) = args.replay {
        let (which, mutant) = harness.mutant(args.seed, index);
        let seed = &harness.seeds[which];
        let path = args.out.join(format!(
            "seed{}-mutant{index}-{}",
            args.seed, seed.file_name
        ));
        std::fs::write(&path, &mutant.bytes).expect("write the mutant");
        println!(
            "seed {} mutant {index}: {} [{:?}]: {}\nwritten to {}\nreplay: {}",
            args.seed,
            seed.origin,
            seed.kind,
            mutant.edits.join("; "),
            path.display(),
            replay_command(seed.kind, &path)
        );
        return ExitCode::SUCCESS;
    }
    eprintln!(
        "fuzz: seed {}, mutants {}..{}, {} workers, {} ms budget, {} seed files",
        args.seed,
        args.first,
        args.first + args.count,
        args.workers,
        args.budget.as_millis(),
        harness.seeds.len()
    );
    let report = campaign(
        &harness,
        &Campaign {
            seed: args.seed,
            first: args.first,
            count: args.count,
            workers: args.workers,
            budget: args.budget,
            failures_dir: args.out.join("failures"),
            max_failures: args.max_failures,
            progress_every: (args.count / 20).max(1000),
        },
    );
    println!("library: {}", summary(&report));
    let mut failed = !report.failures.is_empty();
    if let Some(cli) = &args.cli {
        let cli_failures = cli_sample(&harness, &args, cli);
        failed |= cli_failures > 0;
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

/// Runs every `cli_every`-th mutant through the binary with a time limit; returns the
/// failures (a timeout, a signal, or an exit code other than 0 and 2, and 1 for check).
fn cli_sample(harness: &Arc<Harness>, args: &Args, cli: &Path) -> u64 {
    let started = Instant::now();
    let dir = args.out.join("cli");
    std::fs::create_dir_all(&dir).expect("cli folder");
    // Offset by k within each step so the sample walks through every seed file (a plain
    // stride sharing a factor with the number of seeds would revisit a few).
    let seeds = harness.seeds.len() as u64;
    let indices: Vec<u64> = (0..args.count.div_ceil(args.cli_every))
        .map(|k| args.first + k * args.cli_every + (k % seeds) % args.cli_every)
        .filter(|&i| i < args.first + args.count)
        .collect();
    let next = AtomicU64::new(0);
    let failures = Mutex::new(Vec::new());
    let runs = AtomicU64::new(0);
    let slowest = Mutex::new((0.0f64, String::new()));
    std::thread::scope(|scope| {
        for worker in 0..args.workers {
            let (next, failures, runs, slowest, indices) =
                (&next, &failures, &runs, &slowest, &indices);
            let dir = dir.join(format!("w{worker}"));
            scope.spawn(move || {
                std::fs::create_dir_all(&dir).expect("worker folder");
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed) as usize;
                    let Some(&index) = indices.get(k) else { break };
                    let (which, mutant) = harness.mutant(args.seed, index);
                    let seed = &harness.seeds[which];
                    let path = dir.join(&seed.file_name);
                    std::fs::write(&path, &mutant.bytes).expect("write the mutant");
                    for (command, allowed) in commands(seed.kind, &path, &dir) {
                        let t = Instant::now();
                        let verdict = run_limited(cli, &command, args.cli_timeout);
                        let seconds = t.elapsed().as_secs_f64();
                        runs.fetch_add(1, Ordering::Relaxed);
                        let recipe = format!(
                            "seed {} mutant {index}: {} [{:?}]: {}",
                            args.seed,
                            seed.origin,
                            seed.kind,
                            mutant.edits.join("; ")
                        );
                        {
                            let mut s = slowest.lock().unwrap();
                            if seconds > s.0 {
                                *s = (seconds, format!("{recipe}: fluorite {}", command.join(" ")));
                            }
                        }
                        let bad = match verdict {
                            Ok(code) if allowed.contains(&code) => None,
                            Ok(code) => Some(format!("exit code {code}")),
                            Err(e) => Some(e),
                        };
                        if let Some(what) = bad {
                            let kept = args.out.join("failures").join(format!(
                                "cli-seed{}-mutant{index}-{}",
                                args.seed, seed.file_name
                            ));
                            let _ = std::fs::create_dir_all(kept.parent().unwrap());
                            let _ = std::fs::write(&kept, &mutant.bytes);
                            let line = format!(
                                "CLI FAILURE {recipe}\n  fluorite {}: {what}\n  written to {}",
                                command.join(" "),
                                kept.display()
                            );
                            eprintln!("fuzz: {line}");
                            failures.lock().unwrap().push(line);
                        }
                    }
                }
            });
        }
    });
    let failures = failures.into_inner().unwrap();
    let slowest = slowest.into_inner().unwrap();
    println!(
        "cli: {} mutants ({} runs of {}) in {:.1} s with a {} s limit: {} failures; slowest {:.2} s ({})",
        indices.len(),
        runs.load(Ordering::Relaxed),
        cli.display(),
        started.elapsed().as_secs_f64(),
        args.cli_timeout.as_secs(),
        failures.len(),
        slowest.0,
        slowest.1
    );
    for f in &failures {
        println!("{f}");
    }
    failures.len() as u64
}

/// The commands a mutant of `kind` at `path` goes through, each with its allowed exit
/// codes: 0 or 2, and 1 for `check` (a material that breaks a law).
fn commands(kind: Kind, path: &Path, dir: &Path) -> Vec<(Vec<String>, Vec<i32>)> {
    let p = path.display().to_string();
    let out = |name: &str| dir.join(name).display().to_string();
    let owned = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    match kind {
        Kind::Matrix => vec![(
            owned(&["fit", &p, "-q", "-o", &out("fit.json")]),
            vec![0, 2],
        )],
        Kind::Material => vec![
            (owned(&["check", &p]), vec![0, 1, 2]),
            (
                owned(&[
                    "render",
                    &p,
                    "--size",
                    "8x8",
                    "--spp",
                    "2",
                    "-o",
                    &out("r.png"),
                ]),
                vec![0, 2],
            ),
        ],
        Kind::Spectra => vec![(
            owned(&[
                "import-spectra",
                "--absorption",
                &p,
                "--absorption-column",
                "excitation",
                "--emission-column",
                "emission",
                "--reflectance",
                "0.5",
                "-c",
                "0.5",
                "--photon-yield",
                "0.5",
                "-o",
                &out("import.json"),
            ]),
            vec![0, 2],
        )],
        Kind::Absorbance => {
            let sample = harness::corpus::shared_data()
                .map(|d| d.join("eem-instrument/stardom_d433sf.csv"))
                .unwrap_or_default()
                .display()
                .to_string();
            vec![(
                owned(&[
                    "fit",
                    &sample,
                    "--absorbance",
                    &p,
                    "-q",
                    "-o",
                    &out("fit.json"),
                ]),
                vec![0, 2],
            )]
        }
    }
}

/// Runs `cli command` with stdout and stderr discarded; its exit code, or why there is
/// none (a signal, or still running after `limit`, when it is killed).
fn run_limited(cli: &Path, command: &[String], limit: Duration) -> Result<i32, String> {
    let mut child = Command::new(cli)
        .args(command)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("cannot start {}: {e}", cli.display()))?;
    let started = Instant::now();
    loop {
        match child.try_wait() {
            Ok(Some(status)) => {
                return status
                    .code()
                    .ok_or_else(|| format!("killed by a signal ({status})"));
            }
            Ok(None) if started.elapsed() > limit => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!(
                    "TIMEOUT: still running after {} s",
                    limit.as_secs()
                ));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(5)),
            Err(e) => return Err(format!("wait failed: {e}")),
        }
    }
}
