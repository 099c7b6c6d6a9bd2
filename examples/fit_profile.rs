//! A fixed number of grid fits of one file, for instruction counts: run under
//! `valgrind --tool=callgrind`, the inclusive cost of `fluorite::fit::fit` divided by the
//! number of fits is the cost of one fit (less the first fit's colorimeter builds,
//! `PatchColorimeter::new`, which later fits find cached).
//!
//! `cargo run --release --example fit_profile -- FILE [FITS] [tabulated|default]`
//! (default 5 fits, `--model tabulated`). The fits run inside a one-thread rayon pool, so
//! the fit's `rayon::join` of the two yield forms runs in turn on one thread and every
//! instruction of a fit counts under `fluorite::fit::fit`:
//!
//! ```sh no-run: runs the fits under valgrind
//! valgrind --tool=callgrind --callgrind-out-file=cg.out \
//!   target/release/examples/fit_profile ../shared/data/measured/HERPICER.BFC 5
//! callgrind_annotate --inclusive=yes cg.out | grep -E 'fluorite::fit::fit |PatchColorimeter::new '
//! ```

use fluorite::fit::{FitOptions, ModelChoice, fit};
use fluorite::formats::{ReadOptions, read};

fn main() {
    let mut args = std::env::args().skip(1);
    let path = args
        .next()
        .expect("usage: fit_profile FILE [FITS] [tabulated|default]");
    let fits: usize = args
        .next()
        .map_or(5, |n| n.parse().expect("FITS is a count"));
    let model = match args.next().as_deref() {
        None | Some("tabulated") => ModelChoice::Tabulated,
        Some("default") => FitOptions::default().model,
        Some(other) => panic!("unknown model {other}: tabulated or default"),
    };
    let m = read(std::path::Path::new(&path), &ReadOptions::default()).expect("file reads");
    let options = FitOptions {
        model,
        ..FitOptions::default()
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a one-thread pool");
    pool.install(|| {
        for _ in 0..fits {
            std::hint::black_box(fit(std::hint::black_box(&m), &options).expect("fits"));
        }
    });
}
