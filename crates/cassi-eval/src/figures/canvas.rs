//! The drawing surface: an RGB buffer that plotters draws into, then a PNG
//! written atomically through cassi-io.

use std::path::Path;

use cassi_core::color::RgbImage;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::error::{FigureError, Result, invalid};
use super::font;
use super::style::Theme;
use super::surface::{self, Surface};

/// The size of a figure in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Size {
    pub width: u32,
    pub height: u32,
}

impl Size {
    /// The smallest figure accepted (smaller cannot hold its text).
    pub const MIN: Size = Size {
        width: 200,
        height: 150,
    };
    /// The largest figure accepted, per side.
    pub const MAX_SIDE: u32 = 8192;

    pub const fn new(width: u32, height: u32) -> Self {
        Self { width, height }
    }
}

/// The root drawing area of a figure, in pixels from its top-left corner.
pub(crate) type Root<'a> = DrawingArea<Surface<'a>, Shift>;

/// A failure inside plotters, before the figure's name is attached.
#[derive(Debug)]
pub(crate) struct DrawError(pub String);

impl<E: std::error::Error + Send + Sync> From<DrawingAreaErrorKind<E>> for DrawError {
    fn from(e: DrawingAreaErrorKind<E>) -> Self {
        DrawError(e.to_string())
    }
}

pub(crate) type Drawn = std::result::Result<(), DrawError>;

/// Checks the figure size.
pub(crate) fn check_size(figure: &'static str, size: Size) -> Result<()> {
    if size.width < Size::MIN.width
        || size.height < Size::MIN.height
        || size.width > Size::MAX_SIDE
        || size.height > Size::MAX_SIDE
    {
        return Err(invalid(
            figure,
            format!(
                "figure size {}×{} px is outside {}×{} … {m}×{m}",
                size.width,
                size.height,
                Size::MIN.width,
                Size::MIN.height,
                m = Size::MAX_SIDE
            ),
        ));
    }
    Ok(())
}

/// Checks that the output path names a `.png` file.
pub(crate) fn check_png_path(figure: &'static str, path: &Path) -> Result<()> {
    let ok = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if ok {
        Ok(())
    } else {
        Err(invalid(
            figure,
            format!("output '{}' must end in .png", path.display()),
        ))
    }
}

/// Renders a figure of `size` on a white background: `draw` gets the root
/// area and the font sizes for this size.
pub(crate) fn render(
    figure: &'static str,
    size: Size,
    draw: impl FnOnce(&Root, &Theme) -> Drawn,
) -> Result<RgbImage> {
    check_size(figure, size)?;
    if surface::font().is_none() || !font::ensure_registered() {
        return Err(FigureError::Render {
            figure,
            reason: "the embedded font could not be loaded".into(),
        });
    }
    let (w, h) = (size.width, size.height);
    let mut buf = vec![255u8; 3 * w as usize * h as usize];
    let theme = Theme::for_size(w, h);
    {
        let root = Surface::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let drawn = draw(&root, &theme).and_then(|()| root.present().map_err(DrawError::from));
        drawn.map_err(|DrawError(reason)| FigureError::Render { figure, reason })?;
    }
    Ok(RgbImage {
        rows: h as usize,
        cols: w as usize,
        data: buf,
    })
}

/// Writes a rendered figure as PNG, atomically.
pub(crate) fn save(path: &Path, image: &RgbImage) -> Result<()> {
    cassi_io::write_rgb_png(path, image)?;
    Ok(())
}
