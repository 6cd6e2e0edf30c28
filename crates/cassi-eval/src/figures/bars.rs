//! Grouped bar chart: groups (e.g. methods) along x, one bar per series (e.g.
//! the scenarios Ideal / Assumed / Corrected / Oracle) in each group.

use std::path::Path;

use cassi_core::color::RgbImage;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::axes::{AxesSpec, axes};
use super::canvas::{Size, check_png_path, render, save};
use super::check;
use super::error::Result;
use super::layout::{Glyph, LegendEntry, legend_band, text_width, title_band};
use super::scale::{axis_range, extent};
use super::style::{series_color, text};

const FIGURE: &str = "grouped bar chart";

/// One series of bars: a value for each group.
#[derive(Debug, Clone, PartialEq)]
pub struct BarSeries {
    pub name: String,
    /// One value per group, in the order of [`GroupedBars::groups`].
    pub values: Vec<f64>,
}

/// Data of a grouped bar chart.
#[derive(Debug, Clone, PartialEq)]
pub struct GroupedBars {
    /// Group names along x (e.g. methods).
    pub groups: Vec<String>,
    /// The bars of each group, left to right, coloured in this order.
    pub series: Vec<BarSeries>,
    /// Y axis title, e.g. "PSNR (dB)".
    pub y_label: String,
    /// Print each bar's value above it.
    pub show_values: bool,
    /// Decimal places of the printed values.
    pub value_decimals: usize,
    /// Y axis range; `None` chooses one from the data (from a little below
    /// the smallest value, or from 0 when 0 is close).
    pub y_range: Option<(f64, f64)>,
}

impl Default for GroupedBars {
    fn default() -> Self {
        Self {
            groups: Vec::new(),
            series: Vec::new(),
            y_label: String::new(),
            show_values: false,
            value_decimals: 2,
            y_range: None,
        }
    }
}

fn validate(data: &GroupedBars) -> Result<()> {
    check::nonempty(FIGURE, "groups", data.groups.len())?;
    check::nonempty(FIGURE, "series", data.series.len())?;
    for s in &data.series {
        let what = format!("series '{}'", s.name);
        check::same_len(FIGURE, &what, s.values.len(), data.groups.len(), "group")?;
        check::finite(FIGURE, &what, &s.values)?;
    }
    check::range(FIGURE, "y_range", data.y_range)
}

/// Renders the chart into an RGB image of `size`.
pub fn render_grouped_bars(data: &GroupedBars, title: &str, size: Size) -> Result<RgbImage> {
    validate(data)?;
    let (lo, hi) = extent(data.series.iter().flat_map(|s| s.values.iter().copied()))
        .expect("validated: at least one finite value");
    let (y0, y1) = data
        .y_range
        .unwrap_or_else(|| axis_range(lo, hi, 0.25, if data.show_values { 0.15 } else { 0.08 }));
    let (y0, y1) = check::plottable(FIGURE, "y", (y0, y1))?;
    let n = data.groups.len();
    let ns = data.series.len();
    render(FIGURE, size, |root, theme| {
        let rest = title_band(root, theme, title)?;
        let entries: Vec<LegendEntry> = data
            .series
            .iter()
            .enumerate()
            .map(|(j, s)| LegendEntry {
                name: s.name.clone(),
                color: series_color(j),
                glyph: Glyph::Swatch,
            })
            .collect();
        let plot = legend_band(&rest, theme, &entries)?;
        let spec = AxesSpec {
            x: (-0.5, n as f64 - 0.5),
            y: (y0, y1),
            x_label: "",
            y_label: &data.y_label,
            categories: Some(&data.groups),
            panel_title: "",
        };
        let chart = axes(&plot, theme, &spec)?;
        let base = if y0 > 0.0 {
            y0
        } else if y1 < 0.0 {
            y1
        } else {
            0.0
        };
        let group_w = if ns == 1 { 0.6 } else { 0.8 };
        let bw = group_w / ns as f64;
        for (j, s) in data.series.iter().enumerate() {
            let color = series_color(j);
            for (i, &v) in s.values.iter().enumerate() {
                let xl = i as f64 - group_w / 2.0 + j as f64 * bw;
                let inset = bw * 0.06;
                let v = v.clamp(y0, y1);
                chart.plotting_area().draw(&Rectangle::new(
                    [(xl + inset, base), (xl + bw - inset, v)],
                    color.filled(),
                ))?;
            }
        }
        if data.show_values {
            let screen = plot.use_screen_coord();
            let size = theme.value;
            for (j, s) in data.series.iter().enumerate() {
                for (i, &v) in s.values.iter().enumerate() {
                    let xl = i as f64 - group_w / 2.0 + j as f64 * bw;
                    let (px0, _) = chart.backend_coord(&(xl, v));
                    let (px1, py) = chart.backend_coord(&(xl + bw, v.clamp(y0, y1)));
                    let d = data.value_decimals.min(6);
                    let label = format!("{v:.d$}");
                    let tw = text_width(&screen, &label, size)? as i32;
                    let cx = (px0 + px1) / 2;
                    let up = v >= base;
                    let style = if tw <= px1 - px0 {
                        let vpos = if up { VPos::Bottom } else { VPos::Top };
                        text(size, HPos::Center, vpos)
                    } else {
                        let hpos = if up { HPos::Left } else { HPos::Right };
                        text(size, hpos, VPos::Center).transform(FontTransform::Rotate270)
                    };
                    let dy = if up { -3 } else { 3 };
                    screen.draw(&Text::new(label, (cx, py + dy), style))?;
                }
            }
        }
        Ok(())
    })
}

/// Renders the chart and writes it as a PNG at `path`, atomically.
pub fn write_grouped_bars(
    data: &GroupedBars,
    title: &str,
    size: Size,
    path: impl AsRef<Path>,
) -> Result<()> {
    let path = path.as_ref();
    check_png_path(FIGURE, path)?;
    save(path, &render_grouped_bars(data, title, size)?)
}
