//! Page layout shared by the figures: a title band on top, a legend band
//! under it, then the plot area (one panel or a grid of panels). The legend
//! sits outside the data so that it can never hide a bar or a point.

use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, VPos};

use super::canvas::{DrawError, Root};
use super::style::{Marker, Theme, text};

/// Text width in pixels at `size`.
pub(crate) fn text_width(area: &Root, s: &str, size: f64) -> Result<u32, DrawError> {
    if s.is_empty() {
        return Ok(0);
    }
    Ok(area
        .estimate_text_size(s, &text(size, HPos::Left, VPos::Top))?
        .0)
}

/// Fits `s` into `max_w` pixels: shrinks the font down to 75 % of `size`,
/// then cuts the text and ends it with "…". Returns the text and its size.
pub(crate) fn fit_text(
    area: &Root,
    s: &str,
    size: f64,
    max_w: u32,
) -> Result<(String, f64), DrawError> {
    let mut sz = size;
    while text_width(area, s, sz)? > max_w {
        if sz <= 0.75 * size {
            // The longest prefix that fits with "…" (binary search).
            let chars: Vec<char> = s.chars().collect();
            let cut = |n: usize| chars[..n].iter().collect::<String>() + "…";
            let (mut lo, mut hi) = (0, chars.len());
            while lo < hi {
                let mid = (lo + hi).div_ceil(2);
                if text_width(area, &cut(mid), sz)? <= max_w {
                    lo = mid;
                } else {
                    hi = mid - 1;
                }
            }
            return Ok((cut(lo), sz));
        }
        sz *= 0.92;
    }
    Ok((s.to_string(), sz))
}

/// Draws `s` centred in `area` (shrunk or cut to fit its width).
pub(crate) fn centred_text(area: &Root, s: &str, size: f64) -> Result<(), DrawError> {
    if s.is_empty() {
        return Ok(());
    }
    let (w, h) = area.dim_in_pixel();
    let (s, sz) = fit_text(area, s, size, w.saturating_sub(8))?;
    area.draw(&Text::new(
        s,
        (w as i32 / 2, h as i32 / 2),
        text(sz, HPos::Center, VPos::Center),
    ))?;
    Ok(())
}

/// Height of the title band (a small top margin when there is no title).
pub(crate) fn title_height(theme: &Theme, title: &str) -> u32 {
    let h = if title.is_empty() {
        theme.title * 0.5
    } else {
        theme.title * 2.0
    };
    h.round() as u32
}

/// Splits off a band for the figure title and draws it; returns the rest.
pub(crate) fn title_band<'a>(
    root: &Root<'a>,
    theme: &Theme,
    title: &str,
) -> Result<Root<'a>, DrawError> {
    let (band, rest) = root.split_vertically(title_height(theme, title));
    centred_text(&band, title, theme.title)?;
    Ok(rest)
}

/// How a legend entry shows its series.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Glyph {
    /// A filled square (bars).
    Swatch,
    /// A line segment, with a marker in its middle if any.
    Line { marker: Option<Marker>, width: u32 },
    /// A marker alone (scatter).
    Point(Marker),
}

/// One legend entry.
#[derive(Debug, Clone)]
pub(crate) struct LegendEntry {
    pub name: String,
    pub color: RGBColor,
    pub glyph: Glyph,
}

/// Splits off a band under the title holding the legend, entries laid out in
/// rows (wrapped to the width, each row centred); returns the rest. No
/// entries: no band.
pub(crate) fn legend_band<'a>(
    area: &Root<'a>,
    theme: &Theme,
    entries: &[LegendEntry],
) -> Result<Root<'a>, DrawError> {
    if entries.is_empty() {
        return Ok(area.clone());
    }
    let f = theme.legend;
    let glyph_w = (2.4 * f).round() as i32;
    let gap = (0.45 * f).round() as i32;
    let spacing = (1.6 * f).round() as i32;
    let row_h = (1.7 * f).round() as i32;
    let (w, _) = area.dim_in_pixel();
    let avail = (w as i32 - 2 * spacing).max(glyph_w * 2);

    // Lay out: (entry index, width) per row.
    let mut rows: Vec<Vec<(usize, i32, String)>> = vec![vec![]];
    let mut row_w = 0;
    for (i, e) in entries.iter().enumerate() {
        let (name, _) = fit_text(area, &e.name, f, (avail - glyph_w - gap).max(1) as u32)?;
        let ew = glyph_w + gap + text_width(area, &name, f)? as i32;
        let cur = rows.last_mut().expect("rows is never empty");
        if !cur.is_empty() && row_w + spacing + ew > avail {
            rows.push(vec![(i, ew, name)]);
            row_w = ew;
        } else {
            row_w += if cur.is_empty() { ew } else { spacing + ew };
            cur.push((i, ew, name));
        }
    }
    let band_h = rows.len() as i32 * row_h + (0.5 * f).round() as i32;
    let (band, rest) = area.split_vertically(band_h as u32);
    let r = (f * 0.38).round().max(3.0) as i32;
    for (k, row) in rows.iter().enumerate() {
        let total: i32 =
            row.iter().map(|(_, ew, _)| ew).sum::<i32>() + spacing * (row.len() as i32 - 1);
        let mut x = (w as i32 - total) / 2;
        let y = k as i32 * row_h + row_h / 2;
        for (i, ew, name) in row {
            let e = &entries[*i];
            let cx = x + glyph_w / 2;
            match e.glyph {
                Glyph::Swatch => {
                    let q = (0.5 * f).round() as i32;
                    band.draw(&Rectangle::new(
                        [(cx - q, y - q), (cx + q, y + q)],
                        e.color.filled(),
                    ))?;
                }
                Glyph::Line { marker, width } => {
                    band.draw(&PathElement::new(
                        vec![(x, y), (x + glyph_w, y)],
                        e.color.stroke_width(width),
                    ))?;
                    if let Some(m) = marker {
                        m.draw(&band, (cx, y), r, e.color)?;
                    }
                }
                Glyph::Point(m) => m.draw(&band, (cx, y), r, e.color)?,
            }
            band.draw(&Text::new(
                name.clone(),
                (x + glyph_w + gap, y),
                text(f, HPos::Left, VPos::Center),
            ))?;
            x += ew + spacing;
        }
    }
    Ok(rest)
}

/// Splits `area` into a grid for `n` panels of roughly square shape: the
/// column count that gives the largest square panel (ties: fewer empty
/// cells). Returns the first `n` cells, row by row.
pub(crate) fn panel_grid<'a>(area: &Root<'a>, n: usize) -> Vec<Root<'a>> {
    let (w, h) = area.dim_in_pixel();
    let best = (1..=n.max(1))
        .max_by_key(|&cols| {
            let rows = n.div_ceil(cols);
            let side = (w as usize / cols).min(h as usize / rows);
            (side, usize::MAX - (rows * cols - n))
        })
        .unwrap_or(1);
    let rows = n.div_ceil(best);
    area.split_evenly((rows, best))
        .into_iter()
        .take(n)
        .collect()
}
