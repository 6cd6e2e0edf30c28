//! The embedded font: DejaVu Sans (Bitstream Vera licence, see
//! `assets/DejaVuSans-LICENSE.txt`). Our [`Surface`](super::surface::Surface)
//! draws all text with it; it is also registered with plotters' own ab_glyph
//! renderer, so that any text plotters would draw itself finds a font too.

use std::sync::OnceLock;

use plotters::style::FontStyle;

/// DejaVu Sans 2.37, the only font file the crate carries.
pub(crate) static DEJAVU_SANS: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// The family name every text style of this module uses.
pub(crate) const FAMILY: &str = "sans-serif";

/// Registers the embedded font (once) under the generic family names plotters
/// uses by default. Returns false if the font could not be parsed (never
/// expected: the file is embedded and tested).
pub(crate) fn ensure_registered() -> bool {
    static OK: OnceLock<bool> = OnceLock::new();
    *OK.get_or_init(|| {
        ["sans-serif", "serif", "monospace"].iter().all(|name| {
            plotters::style::register_font(name, FontStyle::Normal, DEJAVU_SANS).is_ok()
        })
    })
}
