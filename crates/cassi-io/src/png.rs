//! PNG previews: 16-bit grayscale frames and bands, 8-bit sRGB images.

use std::path::{Path, PathBuf};

use cassi_core::color::RgbImage;
use cassi_core::{Cube, Frame};
use image::ExtendedColorType;
use image::ImageEncoder;
use image::codecs::png::PngEncoder;

use crate::atomic;
use crate::error::{IoError, Result};

fn dims(path: &Path, rows: usize, cols: usize) -> Result<(u32, u32)> {
    match (u32::try_from(cols), u32::try_from(rows)) {
        (Ok(w), Ok(h)) if w > 0 && h > 0 => Ok((w, h)),
        _ => Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: format!("cannot write a {rows}×{cols} image as PNG"),
        }),
    }
}

fn encode(path: &Path, buf: &[u8], w: u32, h: u32, ct: ExtendedColorType) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    PngEncoder::new(&mut out)
        .write_image(buf, w, h, ct)
        .map_err(|e| IoError::write(path, std::io::Error::other(e)))?;
    Ok(out)
}

/// Maps `v` to 0…65535 with `white` → 65535; NaN → 0; clamped.
fn level16(v: f32, white: f32) -> u16 {
    let x = (v / white * 65535.0).round();
    if x.is_nan() || x <= 0.0 {
        0
    } else if x >= 65535.0 {
        65535
    } else {
        x as u16
    }
}

fn gray16_png(
    path: &Path,
    rows: usize,
    cols: usize,
    values: &[f32],
    white: f32,
) -> Result<Vec<u8>> {
    let (w, h) = dims(path, rows, cols)?;
    let mut buf = Vec::with_capacity(2 * values.len());
    for &v in values {
        // PngEncoder wants native-endian 16-bit samples.
        buf.extend_from_slice(&level16(v, white).to_ne_bytes());
    }
    encode(path, &buf, w, h, ExtendedColorType::L16)
}

/// The white level: `scale`, or the largest finite value (None when ≤ 0 or absent).
fn white_level(path: &Path, scale: Option<f32>, values: &[f32]) -> Result<Option<f32>> {
    match scale {
        Some(s) if s.is_finite() && s > 0.0 => Ok(Some(s)),
        Some(s) => Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: format!("the PNG white level must be a positive number, got {s}"),
        }),
        None => {
            let max = values
                .iter()
                .copied()
                .filter(|v| v.is_finite())
                .fold(f32::NEG_INFINITY, f32::max);
            Ok((max > 0.0).then_some(max))
        }
    }
}

/// Writes `frame` as a 16-bit grayscale PNG, atomically. `scale` is the data
/// value shown as full white (65535); `None` uses the frame's largest finite
/// value. Values are mapped linearly from 0, clamped to 0…65535; NaN → 0. An
/// all-zero (or all-negative) frame gives a black image.
pub fn write_frame_png16(path: impl AsRef<Path>, frame: &Frame, scale: Option<f32>) -> Result<()> {
    let path = path.as_ref();
    let white = white_level(path, scale, frame.as_slice())?.unwrap_or(1.0);
    let png = gray16_png(path, frame.rows(), frame.cols(), frame.as_slice(), white)?;
    atomic::write_bytes(path, &png)
}

/// Writes one 16-bit grayscale PNG per band into `dir`, named
/// `{stem}_band{kk}.png` with `kk` the 0-based band index, zero-padded to two
/// digits (three when there are more than 100 bands). All bands share one white
/// level, the cube's largest finite value, so their brightness is comparable.
/// Returns the paths written (each write atomic).
pub fn write_band_pngs(dir: impl AsRef<Path>, stem: &str, cube: &Cube) -> Result<Vec<PathBuf>> {
    let dir = dir.as_ref();
    if stem.is_empty() || stem.contains(['/', '\\']) {
        return Err(IoError::InvalidArgument {
            path: dir.to_path_buf(),
            reason: format!("'{stem}' is not a usable file name stem"),
        });
    }
    if !dir.is_dir() {
        return Err(IoError::NotFound {
            path: dir.to_path_buf(),
        });
    }
    let white = white_level(dir, None, cube.as_slice())?.unwrap_or(1.0);
    let digits = if cube.bands() > 100 { 3 } else { 2 };
    let mut written = Vec::with_capacity(cube.bands());
    for k in 0..cube.bands() {
        let path = dir.join(format!("{stem}_band{k:0digits$}.png"));
        let png = gray16_png(&path, cube.rows(), cube.cols(), cube.band(k), white)?;
        atomic::write_bytes(&path, &png)?;
        written.push(path);
    }
    Ok(written)
}

/// Writes an 8-bit sRGB image (e.g. from [`cassi_core::color::pseudo_rgb`]) as
/// PNG, atomically.
pub fn write_rgb_png(path: impl AsRef<Path>, image: &RgbImage) -> Result<()> {
    let path = path.as_ref();
    let (w, h) = dims(path, image.rows, image.cols)?;
    if image.data.len() != 3 * image.rows * image.cols {
        return Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: format!(
                "RGB image data has {} bytes, expected 3×{}×{}",
                image.data.len(),
                image.rows,
                image.cols
            ),
        });
    }
    let png = encode(path, &image.data, w, h, ExtendedColorType::Rgb8)?;
    atomic::write_bytes(path, &png)
}
