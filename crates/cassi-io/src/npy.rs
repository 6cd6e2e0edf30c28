//! NumPy `.npy` (format versions 1.0, 2.0, 3.0) and `.npz` (a zip archive of
//! `.npy` members, stored or deflated).
//!
//! Our own `.npy` codec rather than `ndarray-npy`: we must accept several
//! element types and convert them, bound every allocation by the bytes really
//! present (a hostile header cannot make us allocate), and name what is wrong.
//! `ndarray-npy` stays as a test oracle for what we write.

use std::fs::File;
use std::io::{Read, Seek, Write};
use std::path::Path;

use crate::array::{Endian, VarInfo, col_major_to_row_major, decode_numbers, element_count};
use crate::error::{IoError, Result};

const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// A parsed `.npy` header.
#[derive(Debug, Clone)]
pub(crate) struct NpyHeader {
    pub descr: String,
    pub fortran: bool,
    pub shape: Vec<usize>,
    /// Byte length of magic + version + length field + header text.
    pub data_offset: usize,
}

/// The element type a descriptor names: kind ('f','i','u','b'), size, byte order.
fn parse_descr(descr: &str) -> Option<(char, usize, Endian)> {
    let mut chars = descr.chars();
    let (order, rest) = match chars.next()? {
        c @ ('<' | '>' | '|' | '=') => (c, chars.as_str()),
        _ => ('=', descr),
    };
    let mut rc = rest.chars();
    let kind = rc.next()?;
    let size: usize = rc.as_str().parse().ok()?;
    let e = if order == '>' {
        Endian::Big
    } else {
        Endian::Little
    };
    match (kind, size) {
        ('f', 4 | 8) | ('i' | 'u', 1 | 2 | 4 | 8) | ('b', 1) => Some((kind, size, e)),
        _ => None,
    }
}

/// The NumPy name of a descriptor (`<f4` → `float32`), or the descriptor itself.
pub(crate) fn dtype_name(descr: &str) -> String {
    match parse_descr(descr) {
        Some(('f', s, _)) => format!("float{}", 8 * s),
        Some(('i', s, _)) => format!("int{}", 8 * s),
        Some(('u', s, _)) => format!("uint{}", 8 * s),
        Some(('b', _, _)) => "bool".to_string(),
        _ => format!("'{descr}'"),
    }
}

/// A tiny parser for the Python dict literal of the header, e.g.
/// `{'descr': '<f4', 'fortran_order': False, 'shape': (28, 256, 256), }`.
struct Lit<'a> {
    s: &'a [u8],
    i: usize,
}

impl<'a> Lit<'a> {
    fn ws(&mut self) {
        while self.s.get(self.i).is_some_and(|c| c.is_ascii_whitespace()) {
            self.i += 1;
        }
    }
    fn eat(&mut self, c: u8) -> bool {
        self.ws();
        if self.s.get(self.i) == Some(&c) {
            self.i += 1;
            true
        } else {
            false
        }
    }
    fn string(&mut self) -> Option<String> {
        self.ws();
        let q = *self.s.get(self.i)?;
        if q != b'\'' && q != b'"' {
            return None;
        }
        let start = self.i + 1;
        let len = self.s.get(start..)?.iter().position(|&c| c == q)?;
        self.i = start + len + 1;
        Some(String::from_utf8_lossy(&self.s[start..start + len]).into_owned())
    }
    fn word(&mut self) -> Option<&'a str> {
        self.ws();
        let start = self.i;
        while self
            .s
            .get(self.i)
            .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_')
        {
            self.i += 1;
        }
        std::str::from_utf8(self.s.get(start..self.i)?).ok()
    }
}

fn parse_dict(text: &[u8]) -> std::result::Result<(String, bool, Vec<usize>), String> {
    let mut p = Lit { s: text, i: 0 };
    let (mut descr, mut fortran, mut shape) = (None, None, None);
    if !p.eat(b'{') {
        return Err("header does not start with '{'".into());
    }
    loop {
        if p.eat(b'}') {
            break;
        }
        let key = p.string().ok_or("expected a quoted key in the header")?;
        if !p.eat(b':') {
            return Err(format!("expected ':' after key '{key}'"));
        }
        match key.as_str() {
            "descr" => {
                if let Some(d) = p.string() {
                    descr = Some(d);
                } else {
                    return Err(
                        "structured (record) dtypes are not supported; save a plain numeric array"
                            .into(),
                    );
                }
            }
            "fortran_order" => match p.word() {
                Some("True") => fortran = Some(true),
                Some("False") => fortran = Some(false),
                other => return Err(format!("fortran_order is {other:?}, not True/False")),
            },
            "shape" => {
                if !p.eat(b'(') {
                    return Err("shape is not a tuple".into());
                }
                let mut dims = Vec::new();
                loop {
                    if p.eat(b')') {
                        break;
                    }
                    let w = p.word().unwrap_or("");
                    let d: usize = w
                        .trim_end_matches('L')
                        .parse()
                        .map_err(|_| format!("shape entry '{w}' is not a size"))?;
                    dims.push(d);
                    if !p.eat(b',') {
                        if p.eat(b')') {
                            break;
                        }
                        return Err("expected ',' or ')' in shape".into());
                    }
                }
                shape = Some(dims);
            }
            other => return Err(format!("unexpected header key '{other}'")),
        }
        if !p.eat(b',') {
            if p.eat(b'}') {
                break;
            }
            return Err("expected ',' or '}' in the header".into());
        }
    }
    Ok((
        descr.ok_or("the header has no 'descr'")?,
        fortran.ok_or("the header has no 'fortran_order'")?,
        shape.ok_or("the header has no 'shape'")?,
    ))
}

/// Parses the header at the start of `bytes`. `what` names the file/member.
pub(crate) fn parse_header(path: &Path, what: &str, bytes: &[u8]) -> Result<NpyHeader> {
    let corrupt = |d: String| IoError::Corrupt {
        path: path.to_path_buf(),
        format: "NumPy .npy file",
        detail: format!("{what}{d}"),
    };
    let truncated = |d: String| IoError::Truncated {
        path: path.to_path_buf(),
        format: "NumPy .npy file",
        detail: format!("{what}{d}"),
    };
    if bytes.len() < 10 {
        if MAGIC.starts_with(bytes) {
            return Err(truncated(format!("only {} bytes", bytes.len())));
        }
        return Err(corrupt(
            "does not start with the NumPy magic \\x93NUMPY".into(),
        ));
    }
    if &bytes[..6] != MAGIC {
        return Err(corrupt(
            "does not start with the NumPy magic \\x93NUMPY".into(),
        ));
    }
    let major = bytes[6];
    let (hlen, start): (usize, usize) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            let b = bytes
                .get(8..12)
                .ok_or_else(|| truncated("header length cut off".into()))?;
            (u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize, 12)
        }
        v => return Err(corrupt(format!("unsupported .npy format version {v}"))),
    };
    let end = start.saturating_add(hlen);
    let text = bytes.get(start..end).ok_or_else(|| {
        truncated(format!(
            "header announces {hlen} bytes but only {} remain",
            bytes.len().saturating_sub(start)
        ))
    })?;
    let (descr, fortran, shape) =
        parse_dict(text).map_err(|d| corrupt(format!("bad header: {d}")))?;
    Ok(NpyHeader {
        descr,
        fortran,
        shape,
        data_offset: end,
    })
}

/// Decodes the data of a parsed `.npy` into f64 values in C order.
/// `bytes` is the whole `.npy` (header included).
pub(crate) fn decode_data(
    path: &Path,
    name: &str,
    h: &NpyHeader,
    bytes: &[u8],
) -> Result<Vec<f64>> {
    let Some((kind, size, e)) = parse_descr(&h.descr) else {
        return Err(IoError::UnsupportedType {
            path: path.to_path_buf(),
            name: name.to_string(),
            dtype: dtype_name(&h.descr),
            hint: "supported: float32/64, (u)int8/16/32/64, bool".into(),
        });
    };
    let count = element_count(&h.shape).ok_or_else(|| IoError::Corrupt {
        path: path.to_path_buf(),
        format: "NumPy .npy file",
        detail: format!("shape {:?} overflows", h.shape),
    })?;
    let need = count.saturating_mul(size);
    let data = bytes.get(h.data_offset..).unwrap_or(&[]);
    if data.len() < need {
        return Err(IoError::Truncated {
            path: path.to_path_buf(),
            format: "NumPy .npy file",
            detail: format!(
                "array '{name}' of shape {:?} needs {need} bytes of data but only {} are present",
                h.shape,
                data.len()
            ),
        });
    }
    if data.len() > need {
        return Err(IoError::Corrupt {
            path: path.to_path_buf(),
            format: "NumPy .npy file",
            detail: format!(
                "array '{name}' has {} extra bytes after its data",
                data.len() - need
            ),
        });
    }
    let values = decode_numbers(data, kind, size, e).ok_or_else(|| IoError::UnsupportedType {
        path: path.to_path_buf(),
        name: name.to_string(),
        dtype: dtype_name(&h.descr),
        hint: String::new(),
    })?;
    Ok(if h.fortran {
        col_major_to_row_major(&values, &h.shape)
    } else {
        values
    })
}

fn header_info(name: &str, h: &NpyHeader) -> VarInfo {
    let supported = parse_descr(&h.descr).is_some();
    VarInfo {
        name: name.to_string(),
        shape: h.shape.clone(),
        dtype: dtype_name(&h.descr),
        numeric: supported,
        note: if supported {
            String::new()
        } else {
            "supported: float32/64, (u)int8/16/32/64, bool".into()
        },
    }
}

/// A `.npy` file held in memory; its one array is named after the file stem.
pub(crate) struct Npy {
    bytes: Vec<u8>,
    header: NpyHeader,
    info: VarInfo,
}

impl Npy {
    pub(crate) fn parse(path: &Path, bytes: Vec<u8>) -> Result<Self> {
        let header = parse_header(path, "", &bytes)?;
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "array".into());
        let info = header_info(&stem, &header);
        // Check the data length now, so a truncated file fails even on `describe`.
        let need = element_count(&header.shape)
            .zip(parse_descr(&header.descr))
            .and_then(|(n, (_, s, _))| n.checked_mul(s));
        if let Some(need) = need {
            let have = bytes.len().saturating_sub(header.data_offset);
            if have < need {
                return Err(IoError::Truncated {
                    path: path.to_path_buf(),
                    format: "NumPy .npy file",
                    detail: format!(
                        "shape {:?} of {} needs {need} bytes of data but only {have} are present",
                        header.shape, info.dtype
                    ),
                });
            }
        }
        Ok(Npy {
            bytes,
            header,
            info,
        })
    }
    pub(crate) fn vars(&self) -> Vec<VarInfo> {
        vec![self.info.clone()]
    }
    pub(crate) fn read(&self, path: &Path) -> Result<Vec<f64>> {
        decode_data(path, &self.info.name, &self.header, &self.bytes)
    }
}

/// An opened `.npz` archive.
pub(crate) struct Npz {
    zip: zip::ZipArchive<File>,
    /// Per variable: archive member index.
    members: Vec<usize>,
    vars: Vec<VarInfo>,
}

fn zip_err(path: &Path, e: zip::result::ZipError) -> IoError {
    IoError::Corrupt {
        path: path.to_path_buf(),
        format: "NumPy .npz file",
        detail: e.to_string(),
    }
}

fn read_member_prefix(
    path: &Path,
    zip: &mut zip::ZipArchive<File>,
    idx: usize,
    limit: u64,
) -> Result<Vec<u8>> {
    let member = zip.by_index(idx).map_err(|e| zip_err(path, e))?;
    let mut buf = Vec::new();
    member
        .take(limit)
        .read_to_end(&mut buf)
        .map_err(|e| IoError::Corrupt {
            path: path.to_path_buf(),
            format: "NumPy .npz file",
            detail: format!("member #{idx}: {e}"),
        })?;
    Ok(buf)
}

impl Npz {
    pub(crate) fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).map_err(|e| IoError::from_read(path, e))?;
        let mut zip = zip::ZipArchive::new(file).map_err(|e| zip_err(path, e))?;
        let mut members = Vec::new();
        let mut vars = Vec::new();
        for idx in 0..zip.len() {
            let (name, size) = {
                let m = zip.by_index(idx).map_err(|e| zip_err(path, e))?;
                if m.is_dir() {
                    continue;
                }
                let n = m.name().to_string();
                (n.strip_suffix(".npy").unwrap_or(&n).to_string(), m.size())
            };
            // The header is at most a few KiB; read enough to parse it.
            let prefix = read_member_prefix(path, &mut zip, idx, 65_536 + 12)?;
            let what = format!("member '{name}': ");
            let header = parse_header(path, &what, &prefix)?;
            let info = header_info(&name, &header);
            let need = element_count(&header.shape)
                .zip(parse_descr(&header.descr))
                .and_then(|(n, (_, s, _))| n.checked_mul(s))
                .and_then(|n| n.checked_add(header.data_offset));
            if need.is_some_and(|need| (size as u128) < need as u128) {
                let need = need.unwrap_or(0);
                return Err(IoError::Truncated {
                    path: path.to_path_buf(),
                    format: "NumPy .npz file",
                    detail: format!(
                        "member '{name}' of shape {:?} needs {need} bytes but holds {size}",
                        header.shape
                    ),
                });
            }
            members.push(idx);
            vars.push(info);
        }
        Ok(Npz { zip, members, vars })
    }
    pub(crate) fn vars(&self) -> Vec<VarInfo> {
        self.vars.clone()
    }
    pub(crate) fn read(&mut self, path: &Path, i: usize) -> Result<Vec<f64>> {
        let (Some(&idx), Some(info)) = (self.members.get(i), self.vars.get(i)) else {
            return Err(IoError::Corrupt {
                path: path.to_path_buf(),
                format: "NumPy .npz file",
                detail: format!("no member #{i}"),
            });
        };
        let name = info.name.clone();
        // The member size was checked against the header at open; read at most it (+1
        // to detect a lying size field).
        let size = self.zip.by_index(idx).map_err(|e| zip_err(path, e))?.size();
        let bytes = read_member_prefix(path, &mut self.zip, idx, size.saturating_add(1))?;
        let what = format!("member '{name}': ");
        let header = parse_header(path, &what, &bytes)?;
        decode_data(path, &name, &header, &bytes)
    }
}

/// Encodes `data` (C order of `shape`) as a little-endian float32 `.npy`.
pub(crate) fn encode_f32(shape: &[usize], data: &[f32]) -> Vec<u8> {
    let dims = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut text = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {dims}, }}");
    // Pad with spaces so that the data start is 64-byte aligned; end with '\n'.
    let total = 10 + text.len() + 1;
    let pad = (64 - total % 64) % 64;
    text.push_str(&" ".repeat(pad));
    text.push('\n');
    let mut out = Vec::with_capacity(10 + text.len() + 4 * data.len());
    out.extend_from_slice(MAGIC);
    let hlen = text.len();
    if hlen <= u16::MAX as usize {
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(hlen as u16).to_le_bytes());
    } else {
        // Version 2.0 has a 4-byte length; realign for the 2 extra bytes.
        out.clear();
        let total = 12 + text.trim_end().len() + 1;
        let pad = (64 - total % 64) % 64;
        text = format!("{}{}\n", text.trim_end(), " ".repeat(pad));
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&[2, 0]);
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    }
    out.extend_from_slice(text.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Writes one array as a deflated `.npz` member `name.npy` to `w`.
pub(crate) fn write_npz<W: Write + Seek>(w: W, name: &str, npy: &[u8]) -> std::io::Result<()> {
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .large_file(npy.len() as u64 >= 0xFFFF_FFFF);
    let mut z = zip::ZipWriter::new(w);
    z.start_file(format!("{name}.npy"), opts)
        .map_err(std::io::Error::other)?;
    z.write_all(npy)?;
    z.finish().map_err(std::io::Error::other)?;
    Ok(())
}
