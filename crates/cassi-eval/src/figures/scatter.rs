//! "Estimated vs true" scatter plots, one small panel per parameter (dx, dy,
//! θ, a1, α) in one figure, each with the y = x line and equal axes.

use std::path::Path;

use cassi_core::color::RgbImage;
use plotters::prelude::*;

use super::axes::{AxesSpec, axes};
use super::canvas::{Size, check_png_path, render, save};
use super::check;
use super::error::Result;
use super::layout::{Glyph, LegendEntry, legend_band, panel_grid, title_band};
use super::scale::{extent, padded};
use super::style::{Marker, REFERENCE, series_color};

const FIGURE: &str = "estimated-vs-true scatter";

/// One parameter's panel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScatterPanel {
    /// Parameter name, e.g. "dx", "θ", "a1".
    pub name: String,
    /// Unit shown after the name, e.g. "px", "°"; may be empty.
    pub unit: String,
    /// (true, estimated) pairs, one list per series, in the order of
    /// [`EstimatedVsTrue::series_names`] (a list may be empty).
    pub series: Vec<Vec<(f64, f64)>>,
}

/// Data of an estimated-vs-true figure.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EstimatedVsTrue {
    /// Names of the series (e.g. calibration presets, or one name such as
    /// "scenes"); shared by all panels and shown once in the legend.
    pub series_names: Vec<String>,
    /// One panel per parameter, laid out in a grid.
    pub panels: Vec<ScatterPanel>,
}

fn validate(data: &EstimatedVsTrue) -> Result<()> {
    check::nonempty(FIGURE, "series_names", data.series_names.len())?;
    check::nonempty(FIGURE, "panels", data.panels.len())?;
    for p in &data.panels {
        let what = format!("panel '{}'", p.name);
        check::same_len(
            FIGURE,
            &format!("{what} series"),
            p.series.len(),
            data.series_names.len(),
            "series name",
        )?;
        let n: usize = p.series.iter().map(Vec::len).sum();
        check::nonempty(FIGURE, &format!("{what} points"), n)?;
        for (j, s) in p.series.iter().enumerate() {
            check::finite_points(
                FIGURE,
                &format!("{what} series '{}'", data.series_names[j]),
                s,
            )?;
        }
    }
    Ok(())
}

/// Renders the figure into an RGB image of `size`.
pub fn render_estimated_vs_true(
    data: &EstimatedVsTrue,
    title: &str,
    size: Size,
) -> Result<RgbImage> {
    validate(data)?;
    // Same range on both axes of a panel, hugging the data (parameters are
    // signed and need not include 0).
    let ranges = data
        .panels
        .iter()
        .map(|panel| {
            let pts = panel.series.iter().flatten().flat_map(|&(t, e)| [t, e]);
            let (lo, hi) = extent(pts).expect("validated: points exist");
            check::plottable(
                FIGURE,
                &format!("panel '{}'", panel.name),
                padded(lo, hi, 0.1),
            )
        })
        .collect::<Result<Vec<_>>>()?;
    render(FIGURE, size, |root, theme| {
        let rest = title_band(root, theme, title)?;
        let mut entries: Vec<LegendEntry> = data
            .series_names
            .iter()
            .enumerate()
            .map(|(j, s)| LegendEntry {
                name: s.clone(),
                color: series_color(j),
                glyph: Glyph::Point(Marker::for_series(j)),
            })
            .collect();
        entries.push(LegendEntry {
            name: "y = x".into(),
            color: REFERENCE,
            glyph: Glyph::Line {
                marker: None,
                width: 1,
            },
        });
        let grid = legend_band(&rest, theme, &entries)?;
        let areas = panel_grid(&grid, data.panels.len());
        for ((panel, area), &(a, b)) in data.panels.iter().zip(areas).zip(&ranges) {
            let area = area.margin(0, 4, 4, 4);
            let unit = if panel.unit.is_empty() {
                String::new()
            } else {
                format!(" ({})", panel.unit)
            };
            let spec = AxesSpec {
                x: (a, b),
                y: (a, b),
                x_label: "true",
                y_label: "estimated",
                categories: None,
                panel_title: &format!("{}{unit}", panel.name),
            };
            let mut chart = axes(&area, theme, &spec)?;
            chart.draw_series(DashedLineSeries::new(
                [(a, a), (b, b)],
                6,
                4,
                REFERENCE.stroke_width(1),
            ))?;
            let screen = area.use_screen_coord();
            for (j, s) in panel.series.iter().enumerate() {
                for p in s {
                    let c = chart.backend_coord(p);
                    Marker::for_series(j).draw(&screen, c, theme.marker(), series_color(j))?;
                }
            }
        }
        Ok(())
    })
}

/// Renders the figure and writes it as a PNG at `path`, atomically.
pub fn write_estimated_vs_true(
    data: &EstimatedVsTrue,
    title: &str,
    size: Size,
    path: impl AsRef<Path>,
) -> Result<()> {
    let path = path.as_ref();
    check_png_path(FIGURE, path)?;
    save(path, &render_estimated_vs_true(data, title, size)?)
}
