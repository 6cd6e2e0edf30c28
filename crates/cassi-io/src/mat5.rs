//! MATLAB Level 5 MAT-files (`save -v6` / `-v7`, what `scipy.io.savemat`
//! writes): reader and uncompressed writer.
//!
//! Layout (MathWorks, "MAT-File Format", R2024): a 128-byte header (116 bytes of
//! text, 8 bytes of subsystem offset, version 0x0100, endian indicator "IM"/"MI"),
//! then data elements, each an 8-byte tag (type, byte count) and its data. Only
//! `miMATRIX` (14) and `miCOMPRESSED` (15, a zlib stream holding one element)
//! appear at the top level. A matrix holds the sub-elements array flags, dims,
//! name, then class-specific data (for numeric classes the real part and, if
//! complex, the imaginary part), all stored column-major. Small sub-elements
//! (≤ 4 bytes) may use the packed 4-byte tag form.
//!
//! Our own parser rather than the `matfile` crate, whose 0.5 release silently
//! drops the variables of a truncated uncompressed file, rejects whole files
//! holding an `int32` variable, hides the `logical` flag and non-numeric
//! variables, and prints to stdout/stderr. `matfile` stays as a test oracle.

use std::io::Read;
use std::path::Path;

use crate::array::Elem;
use crate::array::{Endian, VarInfo, element_count};
use crate::decode::{Sink, inflate_bound, pump};
use crate::error::{IoError, Result};

const FORMAT: &str = "MATLAB v5 MAT-file";
const MI_INT8: u32 = 1;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_SINGLE: u32 = 7;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;

/// Bytes of a decompressed element read to learn its name, class and dims.
const HEADER_PEEK: u64 = 65_536;

fn corrupt(path: &Path, detail: impl Into<String>) -> IoError {
    IoError::Corrupt {
        path: path.to_path_buf(),
        format: FORMAT,
        detail: detail.into(),
    }
}

fn truncated(path: &Path, detail: impl Into<String>) -> IoError {
    IoError::Truncated {
        path: path.to_path_buf(),
        format: FORMAT,
        detail: detail.into(),
    }
}

/// Why a parse of a byte buffer stopped.
enum Stop {
    /// Ran past the end of the buffer.
    Short(String),
    /// Structurally invalid.
    Bad(String),
}

impl Stop {
    fn into_error(self, path: &Path, what: &str) -> IoError {
        match self {
            Stop::Short(d) => truncated(path, format!("{what}: {d}")),
            Stop::Bad(d) => corrupt(path, format!("{what}: {d}")),
        }
    }
}

struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
    e: Endian,
}

struct Tag {
    dtype: u32,
    start: usize,
    len: usize,
}

impl<'a> Reader<'a> {
    fn u32_at(&self, pos: usize) -> Option<u32> {
        let b = self.buf.get(pos..pos.checked_add(4)?)?;
        let a = [b[0], b[1], b[2], b[3]];
        Some(match self.e {
            Endian::Little => u32::from_le_bytes(a),
            Endian::Big => u32::from_be_bytes(a),
        })
    }

    /// Reads a sub-element tag (long or packed form) and skips its data and
    /// padding. `pad` is false only for top-level compressed elements.
    fn tag(&mut self, pad: bool) -> std::result::Result<Tag, Stop> {
        let first = self.u32_at(self.pos).ok_or_else(|| {
            Stop::Short(format!(
                "a data element tag at byte {} is cut off",
                self.pos
            ))
        })?;
        if first >> 16 != 0 {
            // Packed form: byte count in the upper 16 bits, data in the next 4 bytes.
            let len = (first >> 16) as usize;
            if len > 4 {
                return Err(Stop::Bad(format!(
                    "packed data element at byte {} claims {len} bytes (at most 4)",
                    self.pos
                )));
            }
            let start = self.pos + 4;
            if start + 4 > self.buf.len() {
                return Err(Stop::Short(format!(
                    "packed data element at byte {} is cut off",
                    self.pos
                )));
            }
            self.pos = start + 4;
            return Ok(Tag {
                dtype: first & 0xFFFF,
                start,
                len,
            });
        }
        let len = self.u32_at(self.pos + 4).ok_or_else(|| {
            Stop::Short(format!(
                "a data element tag at byte {} is cut off",
                self.pos
            ))
        })? as usize;
        let start = self.pos + 8;
        let end = start.saturating_add(len);
        if end > self.buf.len() {
            return Err(Stop::Short(format!(
                "data element at byte {} announces {len} bytes but only {} remain",
                self.pos,
                self.buf.len().saturating_sub(start)
            )));
        }
        let padded = if pad { end.div_ceil(8) * 8 } else { end };
        // The final padding of a buffer may be missing; tolerate that.
        self.pos = padded.min(self.buf.len()).max(end);
        Ok(Tag {
            dtype: first,
            start,
            len,
        })
    }

    fn data(&self, t: &Tag) -> &'a [u8] {
        // In bounds: checked when the tag was read.
        &self.buf[t.start..t.start + t.len]
    }
}

/// The parsed head of a `miMATRIX` element.
struct MatrixHead {
    class: u8,
    complex: bool,
    logical: bool,
    dims: Vec<usize>,
    name: String,
}

fn class_name(class: u8, logical: bool) -> &'static str {
    match class {
        1 => "cell",
        2 => "struct",
        3 => "object",
        4 => "char",
        5 => "sparse",
        6 => "double",
        7 => "single",
        8 => "int8",
        9 if logical => "logical",
        9 => "uint8",
        10 => "int16",
        11 => "uint16",
        12 => "int32",
        13 => "uint32",
        14 => "int64",
        15 => "uint64",
        16 => "function_handle",
        17 => "opaque",
        _ => "unknown class",
    }
}

fn is_numeric_class(class: u8) -> bool {
    (6..=15).contains(&class)
}

/// Parses flags, dims and name of a matrix whose payload starts at `r.pos`.
fn matrix_head(r: &mut Reader<'_>) -> std::result::Result<MatrixHead, Stop> {
    let flags = r.tag(true)?;
    if flags.dtype != MI_UINT32 || flags.len != 8 {
        return Err(Stop::Bad(format!(
            "array flags sub-element has type {} and {} bytes (expected miUINT32, 8 bytes)",
            flags.dtype, flags.len
        )));
    }
    let word = r.u32_at(flags.start).unwrap_or(0);
    let class = (word & 0xFF) as u8;
    let complex = word & 0x0800 != 0;
    let logical = word & 0x0200 != 0;
    let dims_tag = r.tag(true)?;
    if dims_tag.dtype != MI_INT32 || dims_tag.len < 8 || dims_tag.len % 4 != 0 {
        return Err(Stop::Bad(format!(
            "dimensions sub-element has type {} and {} bytes (expected miINT32, ≥ 2 values)",
            dims_tag.dtype, dims_tag.len
        )));
    }
    let mut dims = Vec::with_capacity(dims_tag.len / 4);
    for k in 0..dims_tag.len / 4 {
        let d = r.u32_at(dims_tag.start + 4 * k).unwrap_or(0) as i32;
        if d < 0 {
            return Err(Stop::Bad(format!("negative dimension {d}")));
        }
        dims.push(d as usize);
    }
    let name_tag = r.tag(true)?;
    if name_tag.dtype != MI_INT8 {
        return Err(Stop::Bad(format!(
            "array name sub-element has type {} (expected miINT8)",
            name_tag.dtype
        )));
    }
    let name = String::from_utf8_lossy(r.data(&name_tag)).into_owned();
    Ok(MatrixHead {
        class,
        complex,
        logical,
        dims,
        name,
    })
}

fn head_info(h: &MatrixHead) -> VarInfo {
    let base = class_name(h.class, h.logical);
    let numeric = is_numeric_class(h.class) && !h.complex;
    let (dtype, note) = if is_numeric_class(h.class) && h.complex {
        (
            format!("complex {base}"),
            "complex values are not supported; save real(x) or abs(x)".to_string(),
        )
    } else if numeric {
        (base.to_string(), String::new())
    } else if h.class == 5 {
        (
            base.to_string(),
            "sparse matrices are not supported; save full(x)".to_string(),
        )
    } else {
        (
            base.to_string(),
            format!("a MATLAB {base} is not a numeric array"),
        )
    };
    VarInfo {
        name: h.name.clone(),
        shape: h.dims.clone(),
        dtype,
        numeric,
        note,
        elem: None,
        fortran: true,
        unstored: false,
        max_bytes: None,
    }
}

/// Where a top-level numeric variable's data live.
enum Loc {
    /// Not numeric: nothing to read.
    None,
    /// Uncompressed data: this byte range of the file.
    Plain { start: usize, len: usize },
    /// Inside the zlib stream at `z` (a byte range of the file): `len` bytes
    /// from offset `offset` of the inflated element, which announces
    /// `announced` bytes after its 8-byte tag.
    Compressed {
        z: (usize, usize),
        offset: u64,
        len: u64,
        announced: u64,
    },
}

/// An opened MAT v5 file: the raw bytes and the list of its variables.
pub(crate) struct Mat5 {
    bytes: Vec<u8>,
    vars: Vec<(VarInfo, Loc)>,
}

/// Checks the 128-byte header; returns the byte order.
pub(crate) fn header_endian(bytes: &[u8]) -> Option<Endian> {
    let v = bytes.get(124..128)?;
    match (v[0], v[1], &v[2..4]) {
        (0x00, 0x01, b"IM") => Some(Endian::Little),
        (0x01, 0x00, b"MI") => Some(Endian::Big),
        _ => None,
    }
}

fn zlib_error(path: &Path, what: &str, e: std::io::Error) -> IoError {
    // A stream cut short reads as an early EOF; anything else is damage.
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        truncated(path, format!("{what}: compressed data end early ({e})"))
    } else {
        corrupt(path, format!("{what}: zlib error: {e}"))
    }
}

/// Inflates at most `limit` bytes of `zdata` (a hard cap: a zlib bomb costs
/// no more than that).
fn decompress(path: &Path, zdata: &[u8], limit: u64, what: &str) -> Result<Vec<u8>> {
    let mut out = Vec::new();
    flate2::read::ZlibDecoder::new(zdata)
        .take(limit)
        .read_to_end(&mut out)
        .map_err(|e| zlib_error(path, what, e))?;
    Ok(out)
}

/// The element type of numeric data stored with MAT data type `mi`.
fn mi_elem(mi: u32, e: Endian) -> Option<Elem> {
    let (kind, size) = match mi {
        1 => ('i', 1),
        2 => ('u', 1),
        3 => ('i', 2),
        4 => ('u', 2),
        5 => ('i', 4),
        6 => ('u', 4),
        7 => ('f', 4),
        9 => ('f', 8),
        12 => ('i', 8),
        13 => ('u', 8),
        _ => return None,
    };
    Elem::new(kind, size, e)
}

/// Reads the tag of a numeric matrix's real part at `r.pos` (the bytes of
/// its data need not be present) and checks it against the dimensions:
/// returns the element type, where the data start and their byte length.
fn data_tag(r: &Reader<'_>, h: &MatrixHead) -> std::result::Result<(Elem, usize, usize), Stop> {
    let count = element_count(&h.dims)
        .ok_or_else(|| Stop::Bad(format!("dimensions {:?} overflow", h.dims)))?;
    let first = r
        .u32_at(r.pos)
        .ok_or_else(|| Stop::Short(format!("the data tag at byte {} is cut off", r.pos)))?;
    let (dtype, start, len) = if first >> 16 != 0 {
        (first & 0xFFFF, r.pos + 4, (first >> 16) as usize)
    } else {
        let len = r
            .u32_at(r.pos + 4)
            .ok_or_else(|| Stop::Short(format!("the data tag at byte {} is cut off", r.pos)))?;
        (first, r.pos + 8, len as usize)
    };
    let el = mi_elem(dtype, r.e).ok_or_else(|| {
        Stop::Bad(format!(
            "numeric data stored with data type {dtype}, which is not a number type"
        ))
    })?;
    if Some(len) != count.checked_mul(el.size) {
        return Err(Stop::Bad(format!(
            "holds {len} bytes of {}-byte numbers, but its dimensions {:?} need {count} numbers",
            el.size, h.dims
        )));
    }
    Ok((el, start, len))
}

impl Mat5 {
    pub(crate) fn parse(path: &Path, bytes: Vec<u8>) -> Result<Self> {
        if bytes.len() < 128 {
            return Err(truncated(
                path,
                format!("{} bytes, shorter than the 128-byte header", bytes.len()),
            ));
        }
        let e = header_endian(&bytes).ok_or_else(|| {
            corrupt(
                path,
                "bad version/endian field in the header (expected 0x0100 and 'IM' or 'MI')",
            )
        })?;
        let mut vars = Vec::new();
        let mut r = Reader {
            buf: &bytes,
            pos: 128,
            e,
        };
        while r.pos < bytes.len() {
            let elem_no = vars.len() + 1;
            let at = r.pos;
            // Trailing zero padding (some writers align the file end) is not an element.
            if bytes[at..].iter().all(|&b| b == 0) && bytes.len() - at < 8 {
                break;
            }
            let what = format!("variable #{elem_no} (byte {at})");
            let first = r.u32_at(at).unwrap_or(0);
            let pad = first != MI_COMPRESSED;
            let tag = r.tag(pad).map_err(|s| s.into_error(path, &what))?;
            match tag.dtype {
                MI_MATRIX => {
                    let mut sub = Reader {
                        buf: &bytes[..tag.start + tag.len],
                        pos: tag.start,
                        e,
                    };
                    let head = matrix_head(&mut sub).map_err(|s| s.into_error(path, &what))?;
                    let mut info = head_info(&head);
                    let mut loc = Loc::None;
                    // Check the data against the dimensions now (without
                    // decoding them), so damage surfaces early.
                    if info.numeric {
                        let (el, start, len) = data_tag(&sub, &head).map_err(|s| {
                            s.into_error(path, &format!("variable '{}'", head.name))
                        })?;
                        sub.tag(true).map_err(|s| {
                            s.into_error(path, &format!("variable '{}'", head.name))
                        })?;
                        info.elem = Some(el);
                        info.max_bytes = Some(len as u64);
                        loc = Loc::Plain { start, len };
                    }
                    vars.push((info, loc));
                }
                MI_COMPRESSED => {
                    let z = &bytes[tag.start..tag.start + tag.len];
                    let peek = decompress(path, z, HEADER_PEEK, &what)?;
                    let mut sub = Reader {
                        buf: &peek,
                        pos: 0,
                        e,
                    };
                    let inner = sub.u32_at(0).ok_or_else(|| {
                        truncated(path, format!("{what}: empty compressed element"))
                    })?;
                    if inner != MI_MATRIX {
                        return Err(corrupt(
                            path,
                            format!("{what}: compressed element holds type {inner}, not miMATRIX"),
                        ));
                    }
                    let announced = sub.u32_at(4).unwrap_or(0) as u64;
                    sub.pos = 8;
                    let head = matrix_head(&mut sub).map_err(|s| s.into_error(path, &what))?;
                    let mut info = head_info(&head);
                    let mut loc = Loc::None;
                    if info.numeric {
                        let what = format!("variable '{}'", head.name);
                        let (el, start, len) =
                            data_tag(&sub, &head).map_err(|s| s.into_error(path, &what))?;
                        let end = (start as u64).saturating_add(len as u64);
                        if end > 8 + announced {
                            return Err(corrupt(
                                path,
                                format!(
                                    "{what}: compressed element announces {announced} bytes, \
                                     but its data need {} (shape {:?})",
                                    end - 8,
                                    head.dims
                                ),
                            ));
                        }
                        info.elem = Some(el);
                        info.max_bytes = Some(inflate_bound(tag.len as u64).min(len as u64));
                        loc = Loc::Compressed {
                            z: (tag.start, tag.start + tag.len),
                            offset: start as u64,
                            len: len as u64,
                            announced,
                        };
                    }
                    vars.push((info, loc));
                }
                other => {
                    return Err(corrupt(
                        path,
                        format!(
                            "{what}: top-level data element of type {other} (expected miMATRIX or miCOMPRESSED)"
                        ),
                    ));
                }
            }
        }
        Ok(Mat5 { bytes, vars })
    }

    pub(crate) fn vars(&self) -> Vec<VarInfo> {
        self.vars.iter().map(|(v, _)| v.clone()).collect()
    }

    /// Hands variable `i`'s stored bytes (column-major) to `sink`. A
    /// compressed element is inflated only up to the end of its data.
    pub(crate) fn stream(&self, path: &Path, i: usize, sink: &mut dyn Sink) -> Result<()> {
        let Some((info, loc)) = self.vars.get(i) else {
            return Err(corrupt(path, format!("no variable #{i}")));
        };
        let what = format!("variable '{}'", info.name);
        match *loc {
            Loc::None => Err(corrupt(path, format!("{what} holds no numeric data"))),
            Loc::Plain { start, len } => {
                // In bounds: checked at parse.
                sink.take(&self.bytes[start..start + len]);
                Ok(())
            }
            Loc::Compressed {
                z: (zs, ze),
                offset,
                len,
                announced,
            } => {
                let mut dec = flate2::read::ZlibDecoder::new(&self.bytes[zs..ze]);
                let skipped = std::io::copy(&mut (&mut dec).take(offset), &mut std::io::sink())
                    .map_err(|e| zlib_error(path, &what, e))?;
                let el = info.elem.map_or(1, |e| e.size);
                let got = if skipped == offset {
                    pump(&mut dec, len, el, sink).map_err(|e| zlib_error(path, &what, e))?
                } else {
                    0
                };
                if got < len {
                    return Err(truncated(
                        path,
                        format!(
                            "{what}: compressed element announces {announced} bytes but decompresses to {}",
                            (skipped + got).saturating_sub(8)
                        ),
                    ));
                }
                Ok(())
            }
        }
    }
}

/// Whether `name` is a valid MATLAB variable name (letter, then letters,
/// digits, underscores; at most 63 characters).
pub(crate) fn valid_matlab_name(name: &str) -> bool {
    let mut chars = name.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
        && name.len() <= 63
}

/// Encodes one single-precision variable as an uncompressed MAT v5 file.
/// `shape` is the MATLAB size; `data` is row-major (C order) of `shape`.
pub(crate) fn encode_single(
    path: &Path,
    name: &str,
    shape: &[usize],
    data: &[f32],
) -> Result<Vec<u8>> {
    if !valid_matlab_name(name) {
        return Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: format!(
                "'{name}' is not a valid MATLAB variable name (a letter, then letters, digits or _; at most 63 characters)"
            ),
        });
    }
    let too_big = || IoError::InvalidArgument {
        path: path.to_path_buf(),
        reason: format!(
            "an array of shape {} is too large for a MAT v5 file (4 GiB per variable); save it as .npy",
            crate::array::shape_str(shape)
        ),
    };
    let mut shape = shape.to_vec();
    while shape.len() < 2 {
        shape.push(1);
    }
    if element_count(&shape) != Some(data.len()) {
        return Err(IoError::InvalidArgument {
            path: path.to_path_buf(),
            reason: format!(
                "{} values do not fill shape {}",
                data.len(),
                crate::array::shape_str(&shape)
            ),
        });
    }
    let pad8 = |n: usize| n.div_ceil(8) * 8;
    let data_bytes = data.len().checked_mul(4).ok_or_else(too_big)?;
    let payload = 16 + 8 + pad8(4 * shape.len()) + 8 + pad8(name.len()) + 8 + pad8(data_bytes);
    let payload_u32 = u32::try_from(payload).map_err(|_| too_big())?;
    let dims_i32: Vec<i32> = shape
        .iter()
        .map(|&d| i32::try_from(d).map_err(|_| too_big()))
        .collect::<Result<_>>()?;

    let mut out = Vec::with_capacity(128 + 8 + payload);
    let mut text = b"MATLAB 5.0 MAT-file, Platform: cassi-io, written by cassi".to_vec();
    text.resize(116, b' ');
    out.extend_from_slice(&text);
    out.extend_from_slice(&[0u8; 8]); // no subsystem data
    out.extend_from_slice(&0x0100u16.to_le_bytes());
    out.extend_from_slice(b"IM");

    let put_u32 = |out: &mut Vec<u8>, v: u32| out.extend_from_slice(&v.to_le_bytes());
    let pad = |out: &mut Vec<u8>| {
        while out.len() & 7 != 0 {
            out.push(0);
        }
    };
    put_u32(&mut out, MI_MATRIX);
    put_u32(&mut out, payload_u32);
    // Array flags: class mxSINGLE_CLASS (7), no flags; nzmax 0.
    put_u32(&mut out, MI_UINT32);
    put_u32(&mut out, 8);
    put_u32(&mut out, 7);
    put_u32(&mut out, 0);
    // Dimensions.
    put_u32(&mut out, MI_INT32);
    put_u32(&mut out, (4 * dims_i32.len()) as u32);
    for d in &dims_i32 {
        out.extend_from_slice(&d.to_le_bytes());
    }
    pad(&mut out);
    // Name.
    put_u32(&mut out, MI_INT8);
    put_u32(&mut out, name.len() as u32);
    out.extend_from_slice(name.as_bytes());
    pad(&mut out);
    // Real part, column-major.
    put_u32(&mut out, MI_SINGLE);
    put_u32(&mut out, data_bytes as u32);
    for v in crate::array::row_major_to_col_major(data, &shape) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    pad(&mut out);
    debug_assert_eq!(out.len(), 128 + 8 + payload);
    Ok(out)
}
