//! fluorite: fit, check, export, plot and render diffuse fluorescent materials
//! (the BBRRDF of Jung, Hanika, Marschner and Dachsbacher 2018) from measured
//! bispectral reradiation matrices.
//!
//! Data flow one way: [`formats`] read a [`Measurement`]; [`fit`] turns it into a
//! [`Material`]; downstream modules ([`model`], [`colour`], [`export`], [`plot`],
//! [`render`]) read only the material (and, for comparisons, the measurement).

pub mod check;
pub mod colour;
pub mod eem;
pub mod error;
pub mod evaluate;
pub mod export;
pub mod files;
pub mod fit;
pub mod formats;
pub mod import;
pub mod material;
pub mod measurement;
pub mod model;
pub mod numeric;
pub mod optimise;
pub mod parametric;
pub mod plot;
pub mod render;
pub mod spectrum;
pub mod synth;

pub use error::{Error, Result};
pub use material::{Fluorophore, Material, YieldForm};
pub use measurement::{Measurement, Units};
pub use spectrum::Spectrum;
