//! PNG figures for evaluation reports, drawn with plotters into an RGB buffer
//! and written atomically. Text is drawn from the embedded DejaVu Sans, so it
//! renders on any machine, with no system font library.
//!
//! Each figure has a plain data struct and two functions: `render_*` returns
//! the image ([`RgbImage`]), `write_*` renders it and writes a PNG (temporary
//! file then rename, through [`cassi_io::write_rgb_png`]). Bad input (empty
//! data, mismatched lengths, NaN or ±Inf, a size outside [`Size::MIN`] …
//! [`Size::MAX_SIDE`], an output name not ending in `.png`) is a
//! [`FigureError::InvalidInput`], never a panic.
//!
//! Series are coloured in the order given, from one colour-blind-safe palette
//! (Okabe & Ito), and also get distinct marker shapes: pass the scenarios in
//! the same order everywhere (Ideal, Assumed, Corrected, Oracle) and they keep
//! their colours across figures. Legends sit in a band under the title, never
//! over the data.
//!
//! | figure | data | functions |
//! |---|---|---|
//! | grouped bars (PSNR by method × scenario, ablation) | [`GroupedBars`] | [`render_grouped_bars`], [`write_grouped_bars`] |
//! | lines with markers (sensitivity curves, per-scene PSNR) | [`LineChart`] | [`render_line_chart`], [`write_line_chart`] |
//! | estimated vs true, one panel per parameter | [`EstimatedVsTrue`] | [`render_estimated_vs_true`], [`write_estimated_vs_true`] |
//! | pseudo-RGB images + error maps on a shared scale | [`ImagePanel`] | [`render_image_panel`], [`write_image_panel`] |
//! | spectra at a few pixels, truth vs scenarios | [`Spectra`] | [`render_spectra`], [`write_spectra`] |

mod axes;
mod bars;
mod canvas;
mod check;
mod colormap;
mod error;
mod font;
mod layout;
mod lines;
mod panel;
mod resample;
mod scale;
mod scatter;
mod spectra;
mod style;
mod surface;

pub use bars::{BarSeries, GroupedBars, render_grouped_bars, write_grouped_bars};
pub use canvas::Size;
pub use cassi_core::color::RgbImage;
pub use error::{FigureError, Result};
pub use lines::{LineChart, LineSeries, render_line_chart, write_line_chart};
pub use panel::{ErrorMap, ImagePanel, PanelColumn, render_image_panel, write_image_panel};
pub use scatter::{
    EstimatedVsTrue, ScatterPanel, render_estimated_vs_true, write_estimated_vs_true,
};
pub use spectra::{PixelSpectra, Spectra, render_spectra, write_spectra};
