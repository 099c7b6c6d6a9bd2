//! Bispectral images: a reradiation matrix per pixel, fitted into a material map (shared
//! fluorophores, a concentration per fluorophore and pixel, a reflectance per pixel).
//!
//! [`source`] streams an image's pixels block by block, [`sink`] writes images tile by
//! tile ([`tiles`]: the bytes and places of their tiles), [`layout`] names the cells of a pixel, [`map`] is the material map every
//! downstream step reads, [`synth`] writes synthetic images with their truth. [`diff`]
//! compares two images (a fit against its truth); [`per_pixel`] is the baseline that
//! fits every pixel on its own.

pub mod array;
pub mod diff;
pub mod layout;
pub mod map;
pub mod per_pixel;
pub mod sink;
pub mod source;
pub mod synth;
pub mod tiles;

pub use array::{ArrayImage, PixelSource};
pub use layout::{Cell, Layout};
pub use map::MaterialMap;
pub use source::{ExrImage, PixelBlock};
pub mod fit;
