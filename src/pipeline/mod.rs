//! What a run does between reading files and writing results, shared by the command line
//! and the Python package so that both call the same functions:
//!
//! - [`input`]: read a file and prepare it as the options say (units, blank, inner filter,
//!   scatter of raw instrument EEMs) into a [`Prepared`] sample.
//! - [`single`]: fit one prepared sample or file (timing runs, the preprocessing recorded),
//!   many in parallel, name the outputs of a run and write them.
//! - [`joint`]: a joint fit of a sample set: which files are samples, and the dispatch to
//!   the EEM PARAFAC (one fit per component count) or the surface concentration series.
//! - [`beside`]: what `fit --plot` and `fit --render` write next to a material.

pub mod beside;
pub mod input;
pub mod joint;
pub mod single;

pub use input::{EemSettings, InputOptions, Prepared, read_input};
pub use joint::{JointOutcome, JointRequest};
pub use single::{Fitted, fit_file, fit_many, fit_prepared};
