//! fluorite: fit, check, export, plot and render diffuse fluorescent materials
//! (the BBRRDF of Jung, Hanika, Marschner and Dachsbacher 2018) from measured
//! bispectral reradiation matrices.
//!
//! Data flow one way: [`formats`] read a [`Measurement`] ([`eem`] prepares raw instrument
//! EEMs); [`fit`] turns it into a [`Material`] (or, for sets of files, a joint fit);
//! downstream modules ([`model`], [`colour`], [`check`], [`export`], [`plot`], [`render`])
//! read the material and the fit's results (and, for comparisons, the measurement), and
//! never read a measurement or run a fit themselves. [`pipeline`] strings the steps
//! together as a run does (read and prepare, fit one or many or jointly, write, plot and
//! render beside): the command line and the Python package both call it.

pub mod check;
pub mod colour;
pub mod eem;
pub mod error;
pub mod evaluate;
pub mod export;
pub mod files;
pub mod fit;
pub mod formats;
pub mod image;
pub mod import;
pub mod limits;
pub mod material;
pub mod measurement;
pub mod model;
pub mod numeric;
pub mod optimise;
pub mod parametric;
pub mod pipeline;
pub mod plot;
pub mod render;
pub mod spectrum;
pub mod synth;

pub use error::{Error, Result};
pub use material::{Fluorophore, Material, YieldForm};
pub use measurement::{Measurement, Units};
pub use spectrum::Spectrum;
