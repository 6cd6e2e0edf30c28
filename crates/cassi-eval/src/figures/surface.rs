//! The drawing surface: plotters' bitmap backend over our RGB buffer, with
//! text drawn by us from the embedded font.
//!
//! plotters' own ab_glyph text path places each glyph at the left edge of its
//! ink box (the side bearing is dropped) on whole pixels, so "MST-S" reads
//! "MS T-S" at tick sizes. Here glyphs sit at their true advance positions
//! with kerning, on sub-pixel offsets, and are alpha-blended by coverage.
//! A font size is the em size in pixels.

use std::sync::OnceLock;

use ab_glyph::{Font, FontRef, PxScale, ScaleFont, point};
use plotters::prelude::BitMapBackend;
use plotters_backend::text_anchor::{HPos, VPos};
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
};

use super::font::DEJAVU_SANS;

type BitMapError = <BitMapBackend<'static> as DrawingBackend>::ErrorType;

/// The parsed embedded font, or None if it does not parse (never expected).
pub(crate) fn font() -> Option<&'static FontRef<'static>> {
    static FONT: OnceLock<Option<FontRef<'static>>> = OnceLock::new();
    FONT.get_or_init(|| FontRef::try_from_slice(DEJAVU_SANS).ok())
        .as_ref()
}

/// A laid-out line of text: glyph outlines relative to the top-left corner of
/// the line box, and that box's size.
struct Line {
    width: f32,
    height: f32,
    glyphs: Vec<ab_glyph::OutlinedGlyph>,
}

fn layout(font: &FontRef<'static>, size: f64, s: &str) -> Line {
    let units = font.units_per_em().unwrap_or(2048.0);
    // PxScale is the ascent-to-descent height; we want `size` to be the em.
    let scale = PxScale::from(size as f32 * font.height_unscaled() / units);
    let sf = font.as_scaled(scale);
    let ascent = sf.ascent();
    let mut x = 0f32;
    let mut prev = None;
    let mut glyphs = Vec::with_capacity(s.len());
    for c in s.chars() {
        let id = sf.glyph_id(c);
        if let Some(p) = prev {
            x += sf.kern(p, id);
        }
        let g = id.with_scale_and_position(scale, point(x, ascent));
        if let Some(o) = font.outline_glyph(g) {
            glyphs.push(o);
        }
        x += sf.h_advance(id);
        prev = Some(id);
    }
    Line {
        width: x,
        height: sf.height(),
        glyphs,
    }
}

/// The width in pixels of `s` at font size `size` (0 if the font is missing).
pub(crate) fn measure(s: &str, size: f64) -> u32 {
    font().map_or(0, |f| layout(f, size, s).width.ceil() as u32)
}

/// plotters' bitmap backend with our text rendering.
pub(crate) struct Surface<'a> {
    inner: BitMapBackend<'a>,
}

impl<'a> Surface<'a> {
    /// A surface over an RGB buffer of `size` (3 bytes per pixel).
    pub fn with_buffer(buf: &'a mut [u8], size: (u32, u32)) -> Self {
        Self {
            inner: BitMapBackend::with_buffer(buf, size),
        }
    }
}

fn font_missing() -> DrawingErrorKind<BitMapError> {
    DrawingErrorKind::FontError(Box::new(std::io::Error::other(
        "the embedded font could not be parsed",
    )))
}

impl DrawingBackend for Surface<'_> {
    type ErrorType = BitMapError;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.ensure_prepared()
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.present()
    }

    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_pixel(point, color)
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_line(from, to, style)
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_rect(upper_left, bottom_right, style, fill)
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_path(path, style)
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_circle(center, radius, style, fill)
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.fill_polygon(vert, style)
    }

    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        (sw, sh): (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        if src.len() < 3 * sw as usize * sh as usize {
            return Err(DrawingErrorKind::FontError(Box::new(
                std::io::Error::other("bitmap smaller than its stated size"),
            )));
        }
        let (w, h) = self.get_size();
        let (x0, y0) = (i64::from(pos.0), i64::from(pos.1));
        if x0 >= 0
            && y0 >= 0
            && x0 + i64::from(sw) <= i64::from(w)
            && y0 + i64::from(sh) <= i64::from(h)
        {
            return self.inner.blit_bitmap(pos, (sw, sh), src);
        }
        // plotters-bitmap 0.3.7 mis-clips a partly visible bitmap (and can
        // panic on one wholly off to the right): clip here, pixel by pixel.
        for y in 0..sh {
            for x in 0..sw {
                let (px, py) = (x0 + i64::from(x), y0 + i64::from(y));
                if px < 0 || py < 0 || px >= i64::from(w) || py >= i64::from(h) {
                    continue;
                }
                let i = 3 * (y as usize * sw as usize + x as usize);
                let c = BackendColor {
                    alpha: 1.0,
                    rgb: (src[i], src[i + 1], src[i + 2]),
                };
                self.inner.draw_pixel((px as i32, py as i32), c)?;
            }
        }
        Ok(())
    }

    fn estimate_text_size<TStyle: BackendTextStyle>(
        &self,
        text: &str,
        style: &TStyle,
    ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
        let font = font().ok_or_else(font_missing)?;
        let line = layout(font, style.size(), text);
        Ok((line.width.ceil() as u32, line.height.ceil() as u32))
    }

    fn draw_text<TStyle: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &TStyle,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        let color = style.color();
        if color.alpha == 0.0 || text.is_empty() {
            return Ok(());
        }
        let font = font().ok_or_else(font_missing)?;
        let line = layout(font, style.size(), text);
        // Offset of the line box's top-left from the anchor, in the text's
        // own (unrotated) frame.
        let anchor = style.anchor();
        let dx = match anchor.h_pos {
            HPos::Left => 0.0,
            HPos::Center => -line.width / 2.0,
            HPos::Right => -line.width,
        };
        let dy = match anchor.v_pos {
            VPos::Top => 0.0,
            VPos::Center => -line.height / 2.0,
            VPos::Bottom => -line.height,
        };
        // Whole-pixel shift: the glyphs keep their sub-pixel phases.
        let (dx, dy) = (dx.round() as i32, dy.round() as i32);
        let trans = style.transform();
        let (w, h) = self.get_size();
        for g in &line.glyphs {
            let mut result = Ok(());
            let b = g.px_bounds();
            let (gx, gy) = (b.min.x as i32 + dx, b.min.y as i32 + dy);
            g.draw(|x, y, coverage| {
                if result.is_err() || coverage <= 0.0 {
                    return;
                }
                let (tx, ty) = trans.transform(gx + x as i32, gy + y as i32);
                let (px, py) = (pos.0 + tx, pos.1 + ty);
                if px >= 0 && py >= 0 && (px as u32) < w && (py as u32) < h {
                    let c = BackendColor {
                        alpha: color.alpha * f64::from(coverage.min(1.0)),
                        rgb: color.rgb,
                    };
                    result = self.inner.draw_pixel((px, py), c);
                }
            });
            result?;
        }
        Ok(())
    }
}
