//! Qualitative panel: a row of RGB images (pseudo-RGB of the truth and of each
//! scenario), each titled, and under them a row of per-pixel error maps drawn
//! with one colormap on one shared scale, with a colour bar and its values.

use std::path::Path;

use cassi_core::color::RgbImage;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::axes::fmt_num;
use super::canvas::{DrawError, Root, Size, check_png_path, render, save};
use super::check;
use super::colormap::viridis;
use super::error::{Result, invalid};
use super::layout::{centred_text, text_width, title_band, title_height};
use super::resample::resize_rgb;
use super::scale::nice_step;
use super::style::{Theme, text};
use super::surface::measure;

const FIGURE: &str = "image panel";

/// A per-pixel scalar map (e.g. |reconstruction − truth| averaged over
/// bands), row-major: value (r, c) is `values[r · cols + c]`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ErrorMap {
    /// Title shown above the map, e.g. "|Assumed − truth|".
    pub title: String,
    pub rows: usize,
    pub cols: usize,
    pub values: Vec<f32>,
}

/// One column of the panel: an image, and optionally an error map under it.
#[derive(Debug, Clone, PartialEq)]
pub struct PanelColumn {
    /// Title shown above the image, e.g. "Truth", "Corrected (31.2 dB)".
    pub title: String,
    /// The image, e.g. from [`cassi_core::color::pseudo_rgb`].
    pub image: RgbImage,
    /// The error map shown under the image (none under the truth).
    pub error: Option<ErrorMap>,
}

/// Data of an image panel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ImagePanel {
    pub columns: Vec<PanelColumn>,
    /// Title of the colour bar, e.g. "mean |error| over bands".
    pub error_label: String,
    /// The shared colour scale of all error maps (values outside are
    /// clamped); `None`: from 0 (or the minimum, if negative) to the largest
    /// value over all maps.
    pub error_range: Option<(f64, f64)>,
}

fn validate(data: &ImagePanel) -> Result<()> {
    check::nonempty(FIGURE, "columns", data.columns.len())?;
    for col in &data.columns {
        let im = &col.image;
        if im.rows == 0 || im.cols == 0 || im.data.len() != 3 * im.rows * im.cols {
            return Err(invalid(
                FIGURE,
                format!(
                    "image '{}' is {}×{} with {} bytes (need a non-empty image of 3 bytes per pixel)",
                    col.title,
                    im.rows,
                    im.cols,
                    im.data.len()
                ),
            ));
        }
        if let Some(e) = &col.error {
            if e.rows == 0 || e.cols == 0 || e.values.len() != e.rows * e.cols {
                return Err(invalid(
                    FIGURE,
                    format!(
                        "error map '{}' is {}×{} with {} values (need a non-empty map, one value per pixel)",
                        e.title,
                        e.rows,
                        e.cols,
                        e.values.len()
                    ),
                ));
            }
            if let Some((i, v)) = e.values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(invalid(
                    FIGURE,
                    format!("error map '{}' value {i} is {v}, not finite", e.title),
                ));
            }
        }
    }
    check::range(FIGURE, "error_range", data.error_range)
}

/// The shared colour scale.
fn error_scale(data: &ImagePanel) -> Option<(f64, f64)> {
    let maps: Vec<&ErrorMap> = data
        .columns
        .iter()
        .filter_map(|c| c.error.as_ref())
        .collect();
    if maps.is_empty() {
        return None;
    }
    if data.error_range.is_some() {
        return data.error_range;
    }
    let vals = maps
        .iter()
        .flat_map(|m| m.values.iter().map(|&v| f64::from(v)));
    let (lo, hi) = super::scale::extent(vals)?;
    let lo = lo.min(0.0);
    let hi = if hi > lo {
        hi
    } else if lo == 0.0 {
        1.0
    } else {
        lo + 0.1 * lo.abs()
    };
    Some((lo, hi))
}

/// The error map as RGB through the colormap.
fn colorize(m: &ErrorMap, (lo, hi): (f64, f64)) -> Vec<u8> {
    m.values
        .iter()
        .flat_map(|&v| viridis((f64::from(v) - lo) / (hi - lo)))
        .collect()
}

/// Draws an RGB image of `rows`×`cols` resized to `(w, h)` at `(x, y)`,
/// with a thin grey frame.
fn blit(
    area: &Root,
    rgb: &[u8],
    (rows, cols): (usize, usize),
    (x, y): (i32, i32),
    (w, h): (u32, u32),
) -> std::result::Result<(), DrawError> {
    let buf = resize_rgb(rgb, rows, cols, h as usize, w as usize);
    let el = BitMapElement::with_owned_buffer((x, y), (w, h), buf)
        .ok_or_else(|| DrawError("image buffer of the wrong size".into()))?;
    area.draw(&el)?;
    area.draw(&Rectangle::new(
        [(x - 1, y - 1), (x + w as i32, y + h as i32)],
        RGBColor(0x99, 0x99, 0x99).stroke_width(1),
    ))?;
    Ok(())
}

/// Colour bar of height `h` at `(x, y)`, ticks and title to its right.
fn colour_bar(
    screen: &Root,
    theme: &Theme,
    (x, y): (i32, i32),
    h: i32,
    (lo, hi): (f64, f64),
    label: &str,
) -> std::result::Result<(), DrawError> {
    let bar_w = (1.3 * theme.label).round() as i32;
    for k in 0..h {
        let t = 1.0 - (f64::from(k) + 0.5) / f64::from(h);
        let [r, g, b] = viridis(t);
        screen.draw(&Rectangle::new(
            [(x, y + k), (x + bar_w, y + k + 1)],
            RGBColor(r, g, b).filled(),
        ))?;
    }
    screen.draw(&Rectangle::new(
        [(x - 1, y - 1), (x + bar_w, y + h)],
        RGBColor(0x66, 0x66, 0x66).stroke_width(1),
    ))?;
    let step = nice_step((hi - lo) / 5.0);
    let decimals = bar_decimals((lo, hi));
    let first = (lo / step).ceil() as i64;
    let last = (hi / step + 1e-9).floor() as i64;
    let tick = (0.4 * theme.tick).round() as i32;
    let mut widest = 0;
    for i in first..=last.min(first + 20) {
        let v = i as f64 * step;
        let py = y + ((hi - v) / (hi - lo) * f64::from(h - 1)).round() as i32;
        screen.draw(&PathElement::new(
            vec![(x + bar_w, py), (x + bar_w + tick, py)],
            BLACK.stroke_width(1),
        ))?;
        let s = fmt_num(v, decimals);
        widest = widest.max(text_width(screen, &s, theme.tick)? as i32);
        screen.draw(&Text::new(
            s,
            (x + bar_w + tick + 3, py),
            text(theme.tick, HPos::Left, VPos::Center),
        ))?;
    }
    if !label.is_empty() {
        let lx = x + bar_w + tick + 3 + widest + (0.5 * theme.label).round() as i32;
        screen.draw(&Text::new(
            label.to_string(),
            (lx, y + h / 2),
            text(theme.label, HPos::Center, VPos::Top).transform(FontTransform::Rotate270),
        ))?;
    }
    Ok(())
}

/// Where everything goes, in pixels relative to the area under the title.
struct Plan {
    /// Display scale of every picture (screen pixels per image pixel).
    scale: f64,
    /// Left edge of the first column, and the column width.
    x0: i32,
    cell_w: i32,
    /// Top of each row's subtitle band, and that band's height.
    row_top: [i32; 2],
    sub_h: i32,
    /// Total height of the block (for sizing the figure).
    block_h: i32,
}

/// Decimal places of the colour bar's tick labels.
fn bar_decimals((lo, hi): (f64, f64)) -> usize {
    (-(nice_step((hi - lo) / 5.0).log10().floor())).clamp(0.0, 8.0) as usize + 1
}

/// Width of the colour bar column (bar, ticks, labels, rotated title).
fn colour_bar_width(theme: &Theme, range: Option<(f64, f64)>, pad: i32) -> i32 {
    let Some((lo, hi)) = range else { return 0 };
    let d = bar_decimals((lo, hi));
    let widest = [lo, hi, 0.5 * (lo + hi)]
        .iter()
        .map(|&v| measure(&fmt_num(v, d), theme.tick))
        .max()
        .unwrap_or(0);
    (1.3 * theme.label + 0.4 * theme.tick + 3.0 + f64::from(widest) + 2.2 * theme.label).round()
        as i32
        + pad
}

/// Lays the pictures out in `(w, h)`: one scale for all, as large as fits,
/// the block centred.
fn plan(data: &ImagePanel, theme: &Theme, (w, h): (i32, i32), range: Option<(f64, f64)>) -> Plan {
    let n = data.columns.len() as i32;
    let pad = (0.8 * theme.tick).round() as i32;
    let sub_h = (1.8 * theme.subtitle).round() as i32;
    let cbar_w = colour_bar_width(theme, range, pad);
    let rows = if range.is_some() { 2 } else { 1 };
    let cell_w = ((w - cbar_w - pad) / n).max(1);
    let box_w = f64::from((cell_w - pad).max(1));
    let box_h = f64::from(((h - pad * rows) / rows - sub_h).max(1));
    let pictures = data.columns.iter().flat_map(|c| {
        std::iter::once((c.image.rows, c.image.cols))
            .chain(c.error.as_ref().map(|e| (e.rows, e.cols)))
    });
    let scale = pictures
        .clone()
        .map(|(r, c)| (box_w / c as f64).min(box_h / r as f64))
        .fold(f64::INFINITY, f64::min);
    let widest = pictures.clone().map(|(_, c)| c).max().unwrap_or(1) as f64 * scale;
    let tallest = |row: usize| -> i32 {
        data.columns
            .iter()
            .filter_map(|c| match row {
                0 => Some(c.image.rows),
                _ => c.error.as_ref().map(|e| e.rows),
            })
            .max()
            .map_or(0, |r| (r as f64 * scale).round() as i32)
    };
    // Columns only as wide as the pictures need, the block centred.
    let cell_w = cell_w.min(widest.round() as i32 + 2 * pad);
    let block_w = n * cell_w + cbar_w;
    let block_h = sub_h
        + tallest(0)
        + if rows == 2 {
            pad + sub_h + tallest(1)
        } else {
            0
        };
    let top = ((h - block_h) / 2).max(0);
    Plan {
        scale,
        x0: ((w - block_w) / 2).max(0),
        cell_w,
        row_top: [top, top + sub_h + tallest(0) + pad],
        sub_h,
        block_h,
    }
}

impl ImagePanel {
    /// A figure size of `width` whose height fits the pictures with little
    /// empty space (the pictures' aspect ratios decide it).
    pub fn fitting_size(&self, width: u32, title: &str) -> Size {
        let width = width.clamp(Size::MIN.width, Size::MAX_SIDE);
        let range = if validate(self).is_ok() {
            error_scale(self)
        } else {
            None
        };
        let mut height = (width / 2).max(Size::MIN.height);
        // The font sizes depend on the height: a few rounds settle it.
        for _ in 0..3 {
            let theme = Theme::for_size(width, height);
            let p = plan(self, &theme, (width as i32, i32::MAX / 4), range);
            let pad = (0.8 * theme.tick).round() as i32;
            let needed = title_height(&theme, title) as i32 + p.block_h + 2 * pad;
            height = needed.clamp(Size::MIN.height as i32, Size::MAX_SIDE as i32) as u32;
        }
        Size::new(width, height)
    }
}

/// Renders the panel into an RGB image of `size`. All pictures (images and
/// maps) are shown at one common scale, as large as the size allows, and the
/// block is centred; [`ImagePanel::fitting_size`] gives a size with little
/// empty space.
pub fn render_image_panel(data: &ImagePanel, title: &str, size: Size) -> Result<RgbImage> {
    validate(data)?;
    let range = error_scale(data);
    render(FIGURE, size, |root, theme| {
        let rest = title_band(root, theme, title)?;
        let (w, h) = rest.dim_in_pixel();
        let p = plan(data, theme, (w as i32, h as i32), range);
        let dims = |r: usize, c: usize| -> (u32, u32) {
            (
                ((c as f64 * p.scale).round() as u32).max(1),
                ((r as f64 * p.scale).round() as u32).max(1),
            )
        };
        // A titled picture in column i, row `row`; returns its top and height.
        let picture = |i: usize,
                       row: usize,
                       title: &str,
                       rgb: &[u8],
                       (r, c): (usize, usize)|
         -> std::result::Result<(i32, u32), DrawError> {
            let (cx, top) = (p.x0 + i as i32 * p.cell_w, p.row_top[row]);
            let sub = rest
                .clone()
                .shrink((cx, top), (p.cell_w as u32, p.sub_h as u32));
            centred_text(&sub, title, theme.subtitle)?;
            let (dw, dh) = dims(r, c);
            let ix = cx + (p.cell_w - dw as i32) / 2;
            blit(&rest, rgb, (r, c), (ix, top + p.sub_h), (dw, dh))?;
            Ok((top + p.sub_h, dh))
        };
        let mut err_top = None;
        let mut err_h = 0u32;
        for (i, c) in data.columns.iter().enumerate() {
            let im = &c.image;
            picture(i, 0, &c.title, &im.data, (im.rows, im.cols))?;
            if let (Some(e), Some(range)) = (&c.error, range) {
                let (top, dh) = picture(i, 1, &e.title, &colorize(e, range), (e.rows, e.cols))?;
                err_top = Some(top);
                err_h = err_h.max(dh);
            }
        }
        if let (Some(range), Some(top)) = (range, err_top) {
            let pad = (0.8 * theme.tick).round() as i32;
            let bx = p.x0 + data.columns.len() as i32 * p.cell_w + pad / 2;
            colour_bar(
                &rest,
                theme,
                (bx, top),
                err_h as i32,
                range,
                &data.error_label,
            )?;
        }
        Ok(())
    })
}

/// Renders the panel and writes it as a PNG at `path`, atomically.
pub fn write_image_panel(
    data: &ImagePanel,
    title: &str,
    size: Size,
    path: impl AsRef<Path>,
) -> Result<()> {
    let path = path.as_ref();
    check_png_path(FIGURE, path)?;
    save(path, &render_image_panel(data, title, size)?)
}
