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

use crate::array::Elem;
use crate::array::{Endian, VarInfo, element_count};
use crate::decode::{Sink, inflate_bound, pump};
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
        ('f', 2 | 4 | 8) | ('i' | 'u', 1 | 2 | 4 | 8) | ('b', 1) => Some((kind, size, e)),
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

const SUPPORTED: &str = "supported: float16/32/64, (u)int8/16/32/64, bool";

/// Bytes of data the header announces: element count × element size, or
/// `None` if the element type is unsupported or the product overflows.
fn data_bytes(h: &NpyHeader) -> Option<usize> {
    let (_, size, _) = parse_descr(&h.descr)?;
    element_count(&h.shape)?.checked_mul(size)
}

fn header_info(name: &str, h: &NpyHeader) -> VarInfo {
    let elem = parse_descr(&h.descr).and_then(|(k, s, e)| Elem::new(k, s, e));
    VarInfo {
        name: name.to_string(),
        shape: h.shape.clone(),
        dtype: dtype_name(&h.descr),
        numeric: elem.is_some(),
        note: if elem.is_some() {
            String::new()
        } else {
            SUPPORTED.into()
        },
        elem,
        fortran: h.fortran,
        unstored: false,
        max_bytes: None,
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
        let mut info = header_info(&stem, &header);
        info.max_bytes = Some(bytes.len().saturating_sub(header.data_offset) as u64);
        // Check the data length against the header now, so a truncated file
        // fails even on `describe`, before anything is decoded.
        let have = bytes.len().saturating_sub(header.data_offset);
        if let Some(need) = data_bytes(&header) {
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
        } else if info.numeric {
            return Err(IoError::Truncated {
                path: path.to_path_buf(),
                format: "NumPy .npy file",
                detail: format!(
                    "shape {:?} of {} needs more than 2^64 bytes of data but only {have} are present",
                    header.shape, info.dtype
                ),
            });
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
    pub(crate) fn stream(&self, path: &Path, sink: &mut dyn Sink) -> Result<()> {
        let need = data_bytes(&self.header).unwrap_or(0);
        let data = self.bytes.get(self.header.data_offset..).unwrap_or(&[]);
        if data.len() > need {
            return Err(IoError::Corrupt {
                path: path.to_path_buf(),
                format: "NumPy .npy file",
                detail: format!(
                    "array '{}' has {} extra bytes after its data",
                    self.info.name,
                    data.len() - need
                ),
            });
        }
        // The length was checked at parse: `data` holds exactly `need` bytes.
        sink.take(&data[..need.min(data.len())]);
        Ok(())
    }
}

/// One array of an `.npz`: where it is and what its header says.
struct Member {
    index: usize,
    /// The member's name in the archive (`x.npy`).
    file_name: String,
    data_offset: usize,
    /// Bytes of data the header announces.
    need: usize,
    /// Uncompressed size the archive declares.
    size: u64,
}

/// An opened `.npz` archive.
pub(crate) struct Npz {
    zip: zip::ZipArchive<File>,
    members: Vec<Member>,
    vars: Vec<VarInfo>,
}

fn zip_err(path: &Path, e: zip::result::ZipError) -> IoError {
    if let Some(d) = diagnose_truncation(path) {
        return IoError::Truncated {
            path: path.to_path_buf(),
            format: "NumPy .npz file",
            detail: d,
        };
    }
    IoError::Corrupt {
        path: path.to_path_buf(),
        format: "NumPy .npz file",
        detail: e.to_string(),
    }
}

/// Walks the local file headers of a zip from its start to tell which
/// member a short file cuts off (the central directory at its end is gone,
/// so the zip reader itself can only say that the archive is invalid).
/// `None` when the file does not look like a cut zip.
fn diagnose_truncation(path: &Path) -> Option<String> {
    let mut f = File::open(path).ok()?;
    let len = f.metadata().ok()?.len();
    let mut pos = 0u64;
    let mut last: Option<String> = None;
    for _ in 0..100_000 {
        let mut h = [0u8; 30];
        f.seek(std::io::SeekFrom::Start(pos)).ok()?;
        let n = read_full(&mut f, &mut h);
        if n < 4 || h[..4] != *b"PK\x03\x04" {
            // The central directory (or garbage) begins here.
            return match (&last, n) {
                (Some(m), 0) => Some(format!(
                    "the file ends after member '{m}' (byte {len}) without the zip central directory"
                )),
                _ => None,
            };
        }
        let u16_at = |i: usize| u16::from_le_bytes([h[i], h[i + 1]]) as u64;
        let u32_at = |i: usize| u32::from_le_bytes([h[i], h[i + 1], h[i + 2], h[i + 3]]) as u64;
        if n < 30 {
            return Some(format!(
                "the file ends at byte {len}, inside the header of a member after {}",
                last.map_or("the start".to_string(), |m| format!("'{m}'"))
            ));
        }
        let (flags, csize, nlen, xlen) = (u16_at(6), u32_at(18), u16_at(26), u16_at(28));
        let mut name = vec![0u8; nlen as usize];
        let got = read_full(&mut f, &mut name);
        let name = String::from_utf8_lossy(&name[..got]).into_owned();
        let data_start = pos + 30 + nlen + xlen;
        if flags & 8 != 0 {
            // Sizes follow the data: the walk cannot go on.
            return (data_start > len).then(|| format!("member '{name}' is cut off in its header"));
        }
        let data_end = data_start + csize;
        if data_end > len {
            return Some(format!(
                "member '{name}' is truncated: its {csize} stored bytes start at byte {data_start}, \
                 but the file ends at byte {len}"
            ));
        }
        last = Some(name);
        pos = data_end;
    }
    None
}

fn read_full(f: &mut File, buf: &mut [u8]) -> usize {
    let mut n = 0;
    while n < buf.len() {
        match f.read(&mut buf[n..]) {
            Ok(0) | Err(_) => break,
            Ok(k) => n += k,
        }
    }
    n
}

fn read_member_prefix(
    path: &Path,
    zip: &mut zip::ZipArchive<File>,
    idx: usize,
    name: &str,
    limit: u64,
) -> Result<Vec<u8>> {
    let member = zip.by_index(idx).map_err(|e| zip_err(path, e))?;
    let mut buf = Vec::new();
    member
        .take(limit)
        .read_to_end(&mut buf)
        .map_err(|e| member_io_err(path, name, e))?;
    Ok(buf)
}

/// An error reading a member's bytes: a short or damaged member, named.
fn member_io_err(path: &Path, name: &str, e: std::io::Error) -> IoError {
    if e.kind() == std::io::ErrorKind::UnexpectedEof {
        IoError::Truncated {
            path: path.to_path_buf(),
            format: "NumPy .npz file",
            detail: format!("member '{name}' is truncated: {e}"),
        }
    } else {
        IoError::Corrupt {
            path: path.to_path_buf(),
            format: "NumPy .npz file",
            detail: format!("member '{name}' cannot be read: {e}"),
        }
    }
}

impl Npz {
    pub(crate) fn open(path: &Path) -> Result<Self> {
        let file = File::open(path).map_err(|e| IoError::from_read(path, e))?;
        let mut zip = zip::ZipArchive::new(file).map_err(|e| zip_err(path, e))?;
        let mut members = Vec::new();
        let mut vars = Vec::new();
        for index in 0..zip.len() {
            let (file_name, size, stored) = {
                let m = zip.by_index(index).map_err(|e| zip_err(path, e))?;
                if m.is_dir() {
                    continue;
                }
                let stored = match m.compression() {
                    zip::CompressionMethod::Stored => m.compressed_size(),
                    _ => inflate_bound(m.compressed_size()),
                };
                (m.name().to_string(), m.size(), stored)
            };
            if size > stored {
                return Err(IoError::Corrupt {
                    path: path.to_path_buf(),
                    format: "NumPy .npz file",
                    detail: format!(
                        "member '{file_name}' declares {size} bytes, more than its stored \
                         bytes can hold (at most {stored})"
                    ),
                });
            }
            let name = file_name
                .strip_suffix(".npy")
                .unwrap_or(&file_name)
                .to_string();
            // The header is at most a few KiB; read enough to parse it.
            let prefix = read_member_prefix(path, &mut zip, index, &file_name, 65_536 + 12)?;
            let what = format!("member '{name}': ");
            let header = parse_header(path, &what, &prefix)?;
            let mut info = header_info(&name, &header);
            info.max_bytes = Some(size.saturating_sub(header.data_offset as u64));
            let need = data_bytes(&header);
            let total = need.and_then(|n| n.checked_add(header.data_offset));
            if info.numeric && total.is_none_or(|t| size < t as u64) {
                return Err(IoError::Truncated {
                    path: path.to_path_buf(),
                    format: "NumPy .npz file",
                    detail: format!(
                        "member '{name}' of shape {:?} needs {} bytes but holds {size}",
                        header.shape,
                        total.map_or("more than 2^64".to_string(), |t| t.to_string())
                    ),
                });
            }
            members.push(Member {
                index,
                file_name,
                data_offset: header.data_offset,
                need: need.unwrap_or(0),
                size,
            });
            vars.push(info);
        }
        Ok(Npz { zip, members, vars })
    }
    pub(crate) fn vars(&self) -> Vec<VarInfo> {
        self.vars.clone()
    }
    /// Inflates member `i`'s data into `sink`, never more than its header
    /// announces (checked against the archive's declared size at open).
    pub(crate) fn stream(&mut self, path: &Path, i: usize, sink: &mut dyn Sink) -> Result<()> {
        let (Some(m), Some(info)) = (self.members.get(i), self.vars.get(i)) else {
            return Err(IoError::Corrupt {
                path: path.to_path_buf(),
                format: "NumPy .npz file",
                detail: format!("no member #{i}"),
            });
        };
        let extra = m.size - (m.data_offset + m.need) as u64;
        if extra > 0 {
            return Err(IoError::Corrupt {
                path: path.to_path_buf(),
                format: "NumPy .npz file",
                detail: format!(
                    "array '{}' has {extra} extra bytes after its data",
                    info.name
                ),
            });
        }
        let el = info.elem.map_or(1, |e| e.size);
        let mut r = self.zip.by_index(m.index).map_err(|e| zip_err(path, e))?;
        let io = |e| member_io_err(path, &m.file_name, e);
        let skipped = std::io::copy(
            &mut (&mut r).take(m.data_offset as u64),
            &mut std::io::sink(),
        )
        .map_err(io)?;
        let got = pump(&mut r, m.need as u64, el, sink).map_err(io)?;
        if skipped < m.data_offset as u64 || got < m.need as u64 {
            return Err(IoError::Truncated {
                path: path.to_path_buf(),
                format: "NumPy .npz file",
                detail: format!(
                    "member '{}' is truncated: it declares {} bytes but its data end after {}",
                    m.file_name,
                    m.size,
                    skipped + got
                ),
            });
        }
        // Reading to the end lets the zip reader check the member's CRC.
        let mut one = [0u8; 1];
        match r.read(&mut one) {
            Ok(0) => Ok(()),
            Ok(_) => Err(IoError::Corrupt {
                path: path.to_path_buf(),
                format: "NumPy .npz file",
                detail: format!(
                    "member '{}' holds more bytes than it declares ({})",
                    m.file_name, m.size
                ),
            }),
            Err(e) => Err(io(e)),
        }
    }
}

/// `shape` as NumPy writes and prints it: `(3,)`, `(28, 256, 256)`.
pub fn numpy_shape(shape: &[usize]) -> String {
    match shape {
        [one] => format!("({one},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Encodes `data` (C order of `shape`) as a little-endian float32 `.npy`.
pub(crate) fn encode_f32(shape: &[usize], data: &[f32]) -> Vec<u8> {
    let dims = numpy_shape(shape);
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
