//! Spectra at a few pixels: one small panel per pixel, the true spectrum (a
//! thick black line) and each scenario's reconstruction, against wavelength.

use std::path::Path;

use cassi_core::color::RgbImage;
use plotters::prelude::*;

use super::axes::{AxesSpec, axes};
use super::canvas::{Size, check_png_path, render, save};
use super::check;
use super::error::{Result, invalid};
use super::layout::{Glyph, LegendEntry, legend_band, panel_grid, title_band};
use super::scale::{axis_range, extent, padded};
use super::style::{Marker, series_color};

const FIGURE: &str = "spectra plot";

/// The spectra at one pixel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PixelSpectra {
    /// Panel title, e.g. "pixel (row 40, col 120)".
    pub label: String,
    /// The true spectrum, one value per wavelength.
    pub truth: Vec<f64>,
    /// One spectrum per series, in the order of [`Spectra::series_names`].
    pub estimates: Vec<Vec<f64>>,
}

/// Data of a spectra figure.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Spectra {
    /// Band centres in nm, strictly increasing.
    pub wavelengths_nm: Vec<f64>,
    /// Legend name of the truth curve; empty: "Truth".
    pub truth_name: String,
    /// Names of the estimates (e.g. the scenarios), shared by all panels.
    pub series_names: Vec<String>,
    /// One panel per pixel, laid out in a grid.
    pub pixels: Vec<PixelSpectra>,
    /// Y axis title, e.g. "intensity".
    pub y_label: String,
}

fn validate(data: &Spectra) -> Result<()> {
    let wl = &data.wavelengths_nm;
    check::nonempty(FIGURE, "wavelengths_nm", wl.len())?;
    check::finite(FIGURE, "wavelengths_nm", wl)?;
    if wl.windows(2).any(|w| w[1] <= w[0]) {
        return Err(invalid(
            FIGURE,
            "wavelengths_nm must be strictly increasing",
        ));
    }
    check::nonempty(FIGURE, "pixels", data.pixels.len())?;
    for p in &data.pixels {
        let what = format!("pixel '{}'", p.label);
        check::same_len(
            FIGURE,
            &format!("{what} truth"),
            p.truth.len(),
            wl.len(),
            "wavelength",
        )?;
        check::finite(FIGURE, &format!("{what} truth"), &p.truth)?;
        check::same_len(
            FIGURE,
            &format!("{what} estimates"),
            p.estimates.len(),
            data.series_names.len(),
            "series name",
        )?;
        for (j, e) in p.estimates.iter().enumerate() {
            let what = format!("{what} series '{}'", data.series_names[j]);
            check::same_len(FIGURE, &what, e.len(), wl.len(), "wavelength")?;
            check::finite(FIGURE, &what, e)?;
        }
    }
    Ok(())
}

/// Renders the figure into an RGB image of `size`.
pub fn render_spectra(data: &Spectra, title: &str, size: Size) -> Result<RgbImage> {
    validate(data)?;
    let wl = &data.wavelengths_nm;
    let x = check::plottable(FIGURE, "wavelength", padded(wl[0], wl[wl.len() - 1], 0.02))?;
    let y_ranges = data
        .pixels
        .iter()
        .map(|p| {
            let vals = p.truth.iter().chain(p.estimates.iter().flatten()).copied();
            let (lo, hi) = extent(vals).expect("validated: values exist");
            check::plottable(
                FIGURE,
                &format!("pixel '{}'", p.label),
                axis_range(lo, hi, 0.08, 0.08),
            )
        })
        .collect::<Result<Vec<_>>>()?;
    let nb = wl.len();
    // Markers on a subset of bands (every band when few), staggered between
    // series so that they do not sit on top of each other.
    let every = nb.div_ceil(9).max(1);
    render(FIGURE, size, |root, theme| {
        let rest = title_band(root, theme, title)?;
        let truth_name = if data.truth_name.is_empty() {
            "Truth"
        } else {
            &data.truth_name
        };
        let mut entries = vec![LegendEntry {
            name: truth_name.to_string(),
            color: BLACK,
            glyph: Glyph::Line {
                marker: None,
                width: theme.stroke() + 2,
            },
        }];
        entries.extend(
            data.series_names
                .iter()
                .enumerate()
                .map(|(j, s)| LegendEntry {
                    name: s.clone(),
                    color: series_color(j),
                    glyph: Glyph::Line {
                        marker: Some(Marker::for_series(j)),
                        width: theme.stroke(),
                    },
                }),
        );
        let grid = legend_band(&rest, theme, &entries)?;
        let areas = panel_grid(&grid, data.pixels.len());
        for ((p, area), &y) in data.pixels.iter().zip(areas).zip(&y_ranges) {
            let area = area.margin(0, 4, 4, 4);
            let spec = AxesSpec {
                x,
                y,
                x_label: "wavelength (nm)",
                y_label: &data.y_label,
                categories: None,
                panel_title: &p.label,
            };
            let mut chart = axes(&area, theme, &spec)?;
            let curve = |v: &[f64]| {
                wl.iter()
                    .copied()
                    .zip(v.iter().copied())
                    .collect::<Vec<_>>()
            };
            chart.draw_series(LineSeries::new(
                curve(&p.truth),
                BLACK.stroke_width(theme.stroke() + 2),
            ))?;
            for (j, e) in p.estimates.iter().enumerate() {
                chart.draw_series(LineSeries::new(
                    curve(e),
                    series_color(j).stroke_width(theme.stroke()),
                ))?;
            }
            let screen = area.use_screen_coord();
            let r = (theme.marker() * 4 / 5).max(3);
            for (j, e) in p.estimates.iter().enumerate() {
                let offset = if every > 1 { j % every } else { 0 };
                for k in (offset..nb).step_by(every) {
                    let c = chart.backend_coord(&(wl[k], e[k]));
                    Marker::for_series(j).draw(&screen, c, r, series_color(j))?;
                }
            }
        }
        Ok(())
    })
}

/// Renders the figure and writes it as a PNG at `path`, atomically.
pub fn write_spectra(
    data: &Spectra,
    title: &str,
    size: Size,
    path: impl AsRef<Path>,
) -> Result<()> {
    let path = path.as_ref();
    check_png_path(FIGURE, path)?;
    save(path, &render_spectra(data, title, size)?)
}
