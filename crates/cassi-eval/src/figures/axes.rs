//! A Cartesian plot panel: axes, grid, tick labels and axis titles, sized so
//! that the labels fit; categorical x axes (methods, scenes) get their names
//! under integer positions, turned vertical when they would overlap.

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::canvas::{DrawError, Root};
use super::layout::{fit_text, text_width};
use super::style::{GRID, Theme, text};
use super::surface::Surface;

/// A chart whose both axes are f64.
pub(crate) type Chart<'a, 'b> =
    ChartContext<'a, Surface<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// What to draw around a panel.
pub(crate) struct AxesSpec<'s> {
    pub x: (f64, f64),
    pub y: (f64, f64),
    pub x_label: &'s str,
    pub y_label: &'s str,
    /// Names under x = 0, 1, …, n−1 instead of numeric ticks.
    pub categories: Option<&'s [String]>,
    /// Panel title drawn above the plot (small multiples), if not empty.
    pub panel_title: &'s str,
}

/// Decimal places for ticks over `span` (about 8 ticks), trailing zeros are
/// trimmed afterwards.
fn tick_decimals(span: f64) -> usize {
    let step = span / 8.0;
    if !(step.is_finite() && step > 0.0) {
        return 2;
    }
    (-(step.log10().floor()) + 1.0).clamp(0.0, 6.0) as usize
}

/// `v` with `d` decimals, trailing zeros (and a bare point) removed; no "-0".
pub(crate) fn fmt_num(v: f64, d: usize) -> String {
    let mut s = format!("{v:.d$}");
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
        if s.ends_with('.') {
            s.pop();
        }
    }
    if s == "-0" { "0".into() } else { s }
}

/// How the category names are placed.
struct CategoryLayout {
    names: Vec<String>,
    size: f64,
    vertical: bool,
    /// Height the names need below the axis.
    height: u32,
}

fn layout_categories(
    area: &Root,
    theme: &Theme,
    cats: &[String],
    slot_w: f64,
) -> Result<CategoryLayout, DrawError> {
    let (_, area_h) = area.dim_in_pixel();
    for scale in [1.0, 0.9, 0.8] {
        let size = theme.tick * scale;
        let mut widest = 0;
        for c in cats {
            widest = widest.max(text_width(area, c, size)?);
        }
        if f64::from(widest) <= 0.92 * slot_w {
            return Ok(CategoryLayout {
                names: cats.to_vec(),
                size,
                vertical: false,
                height: (1.5 * size).round() as u32,
            });
        }
    }
    // Vertical names, each cut to at most a third of the panel height.
    let size = (theme.tick * 0.9).min(0.9 * slot_w).max(7.0);
    let max_len = (f64::from(area_h) / 3.0) as u32;
    let mut names = Vec::with_capacity(cats.len());
    let mut longest = 0;
    for c in cats {
        let (n, _) = fit_text(area, c, size, max_len)?;
        longest = longest.max(text_width(area, &n, size)?);
        names.push(n);
    }
    Ok(CategoryLayout {
        names,
        size,
        vertical: true,
        height: longest + 6,
    })
}

/// Builds the panel in `area` and draws its mesh, tick labels, axis titles
/// and (optional) panel title.
pub(crate) fn axes<'a, 'b>(
    area: &'a Root<'b>,
    theme: &Theme,
    spec: &AxesSpec,
) -> Result<Chart<'a, 'b>, DrawError> {
    let (w, h) = area.dim_in_pixel();
    let (x0, x1) = spec.x;
    let (y0, y1) = spec.y;
    let yd = tick_decimals(y1 - y0);
    let xd = tick_decimals(x1 - x0);
    let yfmt = move |v: &f64| fmt_num(*v, yd);
    let xfmt = move |v: &f64| fmt_num(*v, xd);

    let pad = (theme.tick * 0.8).round() as u32;
    let label_h = if spec.y_label.is_empty() {
        0
    } else {
        (theme.label * 1.5).round() as u32
    };
    let mut widest_tick = 0;
    for v in [y0, y1, 0.5 * (y0 + y1), y0 + 0.1 * (y1 - y0)] {
        widest_tick = widest_tick.max(text_width(area, &yfmt(&v), theme.tick)?);
    }
    let y_area = widest_tick + label_h + pad;
    let right = (theme.tick * 1.2).round() as u32;
    let top = if spec.panel_title.is_empty() {
        (theme.tick * 0.8).round() as u32
    } else {
        (theme.subtitle * 1.8).round() as u32
    };

    let x_desc_h = if spec.x_label.is_empty() {
        0
    } else {
        (theme.label * 1.6).round() as u32
    };
    let cats = match spec.categories {
        Some(c) => {
            let plot_w = f64::from(w.saturating_sub(y_area + right + 4));
            Some(layout_categories(
                area,
                theme,
                c,
                plot_w / (x1 - x0).max(1.0),
            )?)
        }
        None => None,
    };
    let x_ticks_h = match &cats {
        Some(c) => c.height,
        None => (theme.tick * 1.5).round() as u32,
    };
    let x_area = (x_ticks_h + x_desc_h + pad / 2).min(h / 2);

    if !spec.panel_title.is_empty() {
        let (band, _) = area.split_vertically(top);
        let band = band.margin(0, 0, y_area, right);
        super::layout::centred_text(&band, spec.panel_title, theme.subtitle)?;
    }

    let mut chart = ChartBuilder::on(area)
        .margin_top(top)
        .margin_right(right)
        .margin_left((0.3 * theme.label).round() as u32)
        .margin_bottom(2)
        .x_label_area_size(x_area)
        .y_label_area_size(y_area)
        .build_cartesian_2d(x0..x1, y0..y1)?;

    // As many numeric ticks as fit without crowding the labels.
    let plot_w = f64::from(w.saturating_sub(y_area + right));
    let plot_h = f64::from(h.saturating_sub(top + x_area));
    let n_x = if cats.is_some() {
        0
    } else {
        let widest = [x0, x1, 0.5 * (x0 + x1)]
            .iter()
            .map(|v| f64::from(super::surface::measure(&xfmt(v), theme.tick)))
            .fold(0.0, f64::max);
        ((plot_w / (widest + 2.5 * theme.tick)) as usize).clamp(2, 10)
    };
    let n_y = ((plot_h / (2.6 * theme.tick)) as usize).clamp(3, 8);
    chart
        .configure_mesh()
        .x_desc(spec.x_label)
        .y_desc(spec.y_label)
        .axis_desc_style(text(theme.label, HPos::Center, VPos::Center))
        .label_style(text(theme.tick, HPos::Center, VPos::Center))
        .bold_line_style(GRID.stroke_width(1))
        .light_line_style(TRANSPARENT)
        .axis_style(BLACK.stroke_width(1))
        .x_labels(n_x)
        .y_labels(n_y)
        .x_label_formatter(&xfmt)
        .y_label_formatter(&yfmt)
        .draw()?;

    if let Some(c) = cats {
        let screen = area.use_screen_coord();
        let tick = (theme.tick * 0.4).round() as i32;
        for (i, name) in c.names.iter().enumerate() {
            let (px, py) = chart.backend_coord(&(i as f64, y0));
            screen.draw(&PathElement::new(
                vec![(px, py), (px, py + tick)],
                BLACK.stroke_width(1),
            ))?;
            let style = if c.vertical {
                text(c.size, HPos::Right, VPos::Center).transform(FontTransform::Rotate270)
            } else {
                text(c.size, HPos::Center, VPos::Top)
            };
            screen.draw(&Text::new(name.clone(), (px, py + tick + 3), style))?;
        }
    }
    Ok(chart)
}
