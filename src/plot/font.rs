//! Font registration: the figures use DejaVu Sans embedded in the binary (the `dejavu`
//! crate), so plotting needs no system font and renders the same everywhere.

use std::sync::OnceLock;

use plotters::style::{FontStyle, register_font};

use crate::error::{Error, Result};

/// The family name every figure asks for. "sans-serif" also makes SVG output fall back
/// to a sans font in viewers that lack DejaVu.
pub const FAMILY: &str = "sans-serif";

/// Registers the embedded DejaVu Sans (regular and bold) under [`FAMILY`]; later calls do
/// nothing. Plotting functions call it themselves.
pub fn ensure_registered() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        register_font(FAMILY, FontStyle::Normal, dejavu::sans::regular()).is_ok()
            && register_font(FAMILY, FontStyle::Bold, dejavu::sans::bold()).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::invalid(
            "plot font",
            "the embedded DejaVu Sans font could not be loaded; the build is broken, reinstall fluorite",
        ))
    }
}
