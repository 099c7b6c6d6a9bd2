//! Progress of long runs on stderr: nothing for runs that end within a second, then a line
//! with the files done, the elapsed time and the file being fitted. Drawn only on a
//! terminal (indicatif hides it otherwise), so pipes and logs stay clean.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How long a run goes before it shows progress.
const SHOW_AFTER: Duration = Duration::from_secs(1);

/// A progress line over `total` items that appears once the run has taken [`SHOW_AFTER`].
pub struct Progress {
    bar: ProgressBar,
    finished: Arc<AtomicBool>,
}

impl Progress {
    /// Starts counting `total` items of `what` (e.g. "fitting"); `quiet` shows nothing.
    pub fn start(what: &str, total: usize, quiet: bool) -> Progress {
        let bar = ProgressBar::with_draw_target(Some(total as u64), ProgressDrawTarget::hidden());
        let template = format!("{what} {{pos}}/{{len}} · {{elapsed}} · {{msg}}");
        if let Ok(style) = ProgressStyle::with_template(&template) {
            bar.set_style(style);
        }
        let finished = Arc::new(AtomicBool::new(false));
        if !quiet {
            let (bar, finished) = (bar.clone(), Arc::clone(&finished));
            std::thread::spawn(move || {
                let step = Duration::from_millis(50);
                let mut waited = Duration::ZERO;
                while waited < SHOW_AFTER {
                    if finished.load(Ordering::Relaxed) {
                        return;
                    }
                    std::thread::sleep(step);
                    waited += step;
                }
                if !finished.load(Ordering::Relaxed) {
                    bar.set_draw_target(ProgressDrawTarget::stderr());
                    bar.enable_steady_tick(Duration::from_millis(200));
                }
            });
        }
        Progress { bar, finished }
    }

    /// Names the item being worked on.
    pub fn working_on(&self, input: &Path) {
        let name = input.file_name().map_or_else(
            || input.display().to_string(),
            |n| n.to_string_lossy().to_string(),
        );
        self.bar.set_message(name);
    }

    /// Sets the number of items done (for work reported in steps of several items).
    pub fn set_done(&self, done: usize) {
        self.bar.set_position(done as u64);
    }

    /// Counts one item done.
    pub fn done_one(&self) {
        self.bar.inc(1);
    }

    /// Clears the line (if it was shown) before the run prints its results.
    pub fn finish(&self) {
        self.finished.store(true, Ordering::Relaxed);
        self.bar.finish_and_clear();
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.finish();
    }
}
