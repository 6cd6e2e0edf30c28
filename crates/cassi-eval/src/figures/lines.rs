//! Line chart: several series of (x, y) points joined by lines, with a
//! marker at each point (sensitivity curves such as PSNR vs mismatch scale;
//! per-scene PSNR with scene names along x).

use std::path::Path;

use cassi_core::color::RgbImage;
use plotters::prelude::*;

use super::axes::{AxesSpec, axes};
use super::canvas::{Size, check_png_path, render, save};
use super::check;
use super::error::{Result, invalid};
use super::layout::{Glyph, LegendEntry, legend_band, title_band};
use super::scale::{axis_range, extent, padded};
use super::style::{Marker, series_color};

const FIGURE: &str = "line chart";

/// One curve: points joined in the order given.
#[derive(Debug, Clone, PartialEq)]
pub struct LineSeries {
    pub name: String,
    /// (x, y) points; with [`LineChart::x_categories`], x is the category index.
    pub points: Vec<(f64, f64)>,
}

/// Data of a line chart.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LineChart {
    /// The curves, coloured (and given markers) in this order.
    pub series: Vec<LineSeries>,
    pub x_label: String,
    pub y_label: String,
    /// Names shown under x = 0, 1, …, n−1 instead of numbers (e.g. scene
    /// names for per-scene PSNR). Empty: a numeric x axis.
    pub x_categories: Vec<String>,
    /// Axis ranges; `None` chooses them from the data.
    pub x_range: Option<(f64, f64)>,
    pub y_range: Option<(f64, f64)>,
}

fn validate(data: &LineChart) -> Result<()> {
    check::nonempty(FIGURE, "series", data.series.len())?;
    for s in &data.series {
        let what = format!("series '{}'", s.name);
        check::nonempty(FIGURE, &format!("{what} points"), s.points.len())?;
        check::finite_points(FIGURE, &what, &s.points)?;
        let n = data.x_categories.len() as f64;
        let outside = |&&(x, _): &&(f64, f64)| x < -0.5 || x > n - 0.5;
        if let Some((x, _)) = s.points.iter().find(outside).filter(|_| n > 0.0) {
            return Err(invalid(
                FIGURE,
                format!(
                    "{what} has x = {x}, outside the category indices 0…{}",
                    n - 1.0
                ),
            ));
        }
    }
    check::range(FIGURE, "x_range", data.x_range)?;
    check::range(FIGURE, "y_range", data.y_range)
}

/// Renders the chart into an RGB image of `size`.
pub fn render_line_chart(data: &LineChart, title: &str, size: Size) -> Result<RgbImage> {
    validate(data)?;
    let all = || data.series.iter().flat_map(|s| s.points.iter().copied());
    let (xlo, xhi) = extent(all().map(|p| p.0)).expect("validated: points exist");
    let (ylo, yhi) = extent(all().map(|p| p.1)).expect("validated: points exist");
    let x = data.x_range.unwrap_or_else(|| {
        if data.x_categories.is_empty() {
            padded(xlo, xhi, 0.04)
        } else {
            (-0.5, data.x_categories.len() as f64 - 0.5)
        }
    });
    let y = data
        .y_range
        .unwrap_or_else(|| axis_range(ylo, yhi, 0.1, 0.1));
    let x = check::plottable(FIGURE, "x", x)?;
    let y = check::plottable(FIGURE, "y", y)?;
    render(FIGURE, size, |root, theme| {
        let rest = title_band(root, theme, title)?;
        let entries: Vec<LegendEntry> = data
            .series
            .iter()
            .enumerate()
            .map(|(j, s)| LegendEntry {
                name: s.name.clone(),
                color: series_color(j),
                glyph: Glyph::Line {
                    marker: Some(Marker::for_series(j)),
                    width: theme.stroke(),
                },
            })
            .collect();
        let plot = legend_band(&rest, theme, &entries)?;
        let cats = (!data.x_categories.is_empty()).then_some(data.x_categories.as_slice());
        let spec = AxesSpec {
            x,
            y,
            x_label: &data.x_label,
            y_label: &data.y_label,
            categories: cats,
            panel_title: "",
        };
        let mut chart = axes(&plot, theme, &spec)?;
        for (j, s) in data.series.iter().enumerate() {
            let style = series_color(j).stroke_width(theme.stroke());
            chart.draw_series(plotters::series::LineSeries::new(
                s.points.iter().copied(),
                style,
            ))?;
        }
        let screen = plot.use_screen_coord();
        let inside = |&(px, py): &(f64, f64)| px >= x.0 && px <= x.1 && py >= y.0 && py <= y.1;
        for (j, s) in data.series.iter().enumerate() {
            for p in s.points.iter().filter(|p| inside(p)) {
                let c = chart.backend_coord(p);
                Marker::for_series(j).draw(&screen, c, theme.marker(), series_color(j))?;
            }
        }
        Ok(())
    })
}

/// Renders the chart and writes it as a PNG at `path`, atomically.
pub fn write_line_chart(
    data: &LineChart,
    title: &str,
    size: Size,
    path: impl AsRef<Path>,
) -> Result<()> {
    let path = path.as_ref();
    check_png_path(FIGURE, path)?;
    save(path, &render_line_chart(data, title, size)?)
}
