//! Hand-built hostile files and seeded mutations for the `hostile` harness.

use std::io::Write;

/// SplitMix64: small, seeded, deterministic.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed ^ 0x9e37_79b9_7f4a_7c15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in 0..n (n > 0).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
        &v[self.below(v.len())]
    }
}

/// FNV-1a 64-bit hash, hex.
pub fn hash(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

// ---------------------------------------------------------------- .npy / .npz

pub fn npy_raw(descr: &str, shape: &str, fortran: bool, data: &[u8]) -> Vec<u8> {
    let mut hdr = format!(
        "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}",
        if fortran { "True" } else { "False" }
    );
    let total = 10 + hdr.len() + 1;
    hdr.push_str(&" ".repeat((64 - total % 64) % 64));
    hdr.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((hdr.len() as u16).to_le_bytes());
    out.extend(hdr.as_bytes());
    out.extend(data);
    out
}

pub fn shape_str(shape: &[u64]) -> String {
    match shape.len() {
        1 => format!("({},)", shape[0]),
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

pub fn npy_f32(shape: &[u64], vals: &[f32]) -> Vec<u8> {
    let data: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
    npy_raw("<f4", &shape_str(shape), false, &data)
}

pub fn npz(entries: &[(&str, &[u8])], deflate: bool) -> Vec<u8> {
    let mut buf = std::io::Cursor::new(Vec::new());
    {
        let mut z = zip::ZipWriter::new(&mut buf);
        let opts = zip::write::SimpleFileOptions::default().compression_method(if deflate {
            zip::CompressionMethod::Deflated
        } else {
            zip::CompressionMethod::Stored
        });
        for (name, data) in entries {
            z.start_file(*name, opts).expect("zip entry");
            z.write_all(data).expect("zip write");
        }
        z.finish().expect("zip finish");
    }
    buf.into_inner()
}

/// An .npz whose one entry is a float32 array of `shape` full of zeros, deflated
/// (1 GiB of zeros is about 1 MB).
pub fn npz_zero_bomb(shape: &[u64]) -> Vec<u8> {
    let n: u64 = shape.iter().product::<u64>() * 4;
    let header = npy_raw("<f4", &shape_str(shape), false, &[]);
    let mut buf = std::io::Cursor::new(Vec::new());
    {
        let mut z = zip::ZipWriter::new(&mut buf);
        let opts = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Deflated)
            .large_file(n > u32::MAX as u64 / 2);
        z.start_file("zeros.npy", opts).expect("zip entry");
        z.write_all(&header).expect("zip write");
        let chunk = vec![0u8; 1 << 20];
        let mut left = n;
        while left > 0 {
            let k = left.min(chunk.len() as u64) as usize;
            z.write_all(&chunk[..k]).expect("zip write");
            left -= k as u64;
        }
        z.finish().expect("zip finish");
    }
    buf.into_inner()
}

// ---------------------------------------------------------------- MAT v5

pub fn mat5_header() -> Vec<u8> {
    let mut h = format!(
        "MATLAB 5.0 MAT-file, Platform: hostile, Created on: Thu Jan  1 00:00:00 2026{}",
        " ".repeat(116)
    )
    .into_bytes();
    h.truncate(116);
    h.extend([0u8; 8]);
    h.extend(0x0100u16.to_le_bytes());
    h.extend(b"IM");
    h
}

fn tag(out: &mut Vec<u8>, ty: u32, n: u32) {
    out.extend(ty.to_le_bytes());
    out.extend(n.to_le_bytes());
}

fn pad8(out: &mut Vec<u8>) {
    while !out.len().is_multiple_of(8) {
        out.push(0);
    }
}

/// The body (without its 8-byte tag) of a double miMATRIX: flags, dims, name, real part
/// (`data_bytes` bytes declared, `data` written).
fn mat5_matrix_body(name: &[u8], dims: &[u32], data_bytes: u32, data: &[u8]) -> Vec<u8> {
    let mut b = Vec::new();
    tag(&mut b, 6, 8); // miUINT32 array flags
    b.extend(6u32.to_le_bytes()); // mxDOUBLE_CLASS
    b.extend(0u32.to_le_bytes());
    tag(&mut b, 5, 4 * dims.len() as u32); // miINT32 dims
    for d in dims {
        b.extend(d.to_le_bytes());
    }
    pad8(&mut b);
    tag(&mut b, 1, name.len() as u32); // miINT8 name
    b.extend(name);
    pad8(&mut b);
    tag(&mut b, 9, data_bytes); // miDOUBLE
    b.extend(data);
    pad8(&mut b);
    b
}

/// An uncompressed MAT v5 file with one double variable.
pub fn mat5_double(name: &[u8], rows: u32, cols: u32, vals: &[f64]) -> Vec<u8> {
    let data: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
    let body = mat5_matrix_body(name, &[rows, cols], data.len() as u32, &data);
    let mut out = mat5_header();
    tag(&mut out, 14, body.len() as u32);
    out.extend(body);
    out
}

/// A MAT v5 file with one miCOMPRESSED element holding a rows×cols double matrix of
/// zeros (256 MiB of zeros is about 261 KB of zlib).
pub fn mat5_zlib_bomb(rows: u32, cols: u32) -> Vec<u8> {
    let n = rows as u64 * cols as u64 * 8;
    let body_head = mat5_matrix_body(b"x", &[rows, cols], n as u32, &[]);
    let mut enc = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
    let mut el = Vec::new();
    tag(&mut el, 14, (body_head.len() as u64 + n) as u32);
    el.extend(&body_head);
    enc.write_all(&el).unwrap();
    let chunk = vec![0u8; 1 << 20];
    let mut left = n;
    while left > 0 {
        let k = left.min(chunk.len() as u64) as usize;
        enc.write_all(&chunk[..k]).unwrap();
        left -= k as u64;
    }
    let z = enc.finish().unwrap();
    let mut out = mat5_header();
    tag(&mut out, 15, z.len() as u32);
    out.extend(z);
    out
}

/// Decompress the first miCOMPRESSED element of a MAT v5 file: (offset of its tag, inner bytes).
pub fn mat5_first_compressed(b: &[u8]) -> Option<(usize, Vec<u8>)> {
    let mut pos = 128;
    while pos + 8 <= b.len() {
        let ty = u32::from_le_bytes(b[pos..pos + 4].try_into().ok()?);
        let n = u32::from_le_bytes(b[pos + 4..pos + 8].try_into().ok()?) as usize;
        if ty == 15 {
            let end = (pos + 8 + n).min(b.len());
            let mut d = flate2::read::ZlibDecoder::new(&b[pos + 8..end]);
            let mut inner = Vec::new();
            use std::io::Read;
            (&mut d).take(1 << 24).read_to_end(&mut inner).ok()?;
            return Some((pos, inner));
        }
        pos += 8 + n;
        pos = pos.div_ceil(8) * 8;
    }
    None
}

/// Replace the miCOMPRESSED element at `pos` (and everything after it) with `inner` recompressed.
pub fn mat5_recompress(b: &[u8], pos: usize, inner: &[u8]) -> Vec<u8> {
    let mut enc = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    enc.write_all(inner).unwrap();
    let z = enc.finish().unwrap();
    let mut out = b[..pos].to_vec();
    tag(&mut out, 15, z.len() as u32);
    out.extend(z);
    out
}

// ---------------------------------------------------------------- HDF5 (MAT v7.3)

/// Offsets of v1 dataspace messages (type 1) in an HDF5 file: (message data offset, rank).
pub fn hdf5_dataspaces(b: &[u8]) -> Vec<(usize, usize)> {
    let mut v = Vec::new();
    let mut i = 0;
    while i + 16 <= b.len() {
        // header: type u16 = 1, size u16, flags u8, reserved 3; data: version 1, rank, flags, reserved 5
        if b[i] == 1
            && b[i + 1] == 0
            && b[i + 5..i + 8] == [0, 0, 0]
            && b[i + 8] == 1
            && (1..=4).contains(&b[i + 9])
            && b[i + 11..i + 16] == [0, 0, 0, 0, 0]
        {
            let size = u16::from_le_bytes([b[i + 2], b[i + 3]]) as usize;
            let rank = b[i + 9] as usize;
            if size >= 8 + 8 * rank && size <= 8 + 16 * rank + 8 {
                v.push((i + 8, rank));
            }
        }
        i += 1;
    }
    v
}

/// Offsets of v3 contiguous layout messages (type 8): offset of the address field.
pub fn hdf5_contiguous_layouts(b: &[u8]) -> Vec<usize> {
    let mut v = Vec::new();
    let mut i = 0;
    while i + 26 <= b.len() {
        if b[i] == 8 && b[i + 1] == 0 && b[i + 8] == 3 && b[i + 9] == 1 {
            v.push(i + 10);
        }
        i += 1;
    }
    v
}

/// The seed HDF5 file with every dataset declared `dims` (elements of `elem` bytes) and, where the
/// layout is contiguous, a never-written (undefined address) data block of the full size.
pub fn hdf5_bomb(seed: &[u8], dims: &[u64], elem: u64) -> Option<Vec<u8>> {
    let mut b = seed.to_vec();
    let spaces = hdf5_dataspaces(&b);
    if spaces.is_empty() {
        return None;
    }
    for (off, rank) in spaces {
        let flags = b[off + 2];
        for k in 0..rank {
            let d = dims.get(k).copied().unwrap_or(1);
            b[off + 8 + 8 * k..off + 16 + 8 * k].copy_from_slice(&d.to_le_bytes());
            if flags & 1 != 0 {
                let m = off + 8 + 8 * rank + 8 * k;
                b[m..m + 8].copy_from_slice(&d.to_le_bytes());
            }
        }
    }
    let total: u64 = dims.iter().product::<u64>() * elem;
    for a in hdf5_contiguous_layouts(&b) {
        b[a..a + 8].copy_from_slice(&u64::MAX.to_le_bytes());
        b[a + 8..a + 16].copy_from_slice(&total.to_le_bytes());
    }
    Some(b)
}

// ---------------------------------------------------------------- PyTorch .pth / safetensors

/// A protocol-2 pickle of OrderedDict(w = tensor(storage '0' of `numel` floats, shape, stride)).
pub fn pth_pickle(shape: &[u32], stride: &[u32], numel: u32) -> Vec<u8> {
    fn int(p: &mut Vec<u8>, v: u32) {
        p.push(b'J');
        p.extend((v as i32).to_le_bytes());
    }
    fn tuple(p: &mut Vec<u8>, v: &[u32]) {
        p.push(b'(');
        for &x in v {
            int(p, x);
        }
        p.push(b't');
    }
    let mut p: Vec<u8> = vec![0x80, 2];
    p.extend(b"ccollections\nOrderedDict\nq\x00)R(X\x01\x00\x00\x00w");
    p.extend(b"ctorch._utils\n_rebuild_tensor_v2\n(");
    p.extend(
        b"(X\x07\x00\x00\x00storagectorch\nFloatStorage\nX\x01\x00\x00\x000X\x03\x00\x00\x00cpu",
    );
    int(&mut p, numel);
    p.extend(b"tQ");
    int(&mut p, 0);
    tuple(&mut p, shape);
    tuple(&mut p, stride);
    p.extend(b"\x89h\x00)Rt");
    p.extend(b"Ru.");
    p
}

/// A PyTorch zip checkpoint: `archive/data.pkl`, `archive/data/0`, stored.
pub fn pth_zip(pickle: &[u8], storage: &[u8]) -> Vec<u8> {
    npz(
        &[
            ("archive/data.pkl", pickle),
            ("archive/byteorder", b"little"),
            ("archive/data/0", storage),
            ("archive/version", b"3\n"),
        ],
        false,
    )
}

/// The tiny .pth with a strided view: 2^15 × 2^15 = 2^30 elements over one float (stride 0).
pub fn pth_strided_bomb() -> Vec<u8> {
    pth_zip(
        &pth_pickle(&[32768, 32768], &[0, 0], 1),
        &0f32.to_le_bytes(),
    )
}

/// Entries of a zip archive (name, bytes), or None.
pub fn unzip(b: &[u8]) -> Option<Vec<(String, Vec<u8>)>> {
    use std::io::Read;
    let mut z = zip::ZipArchive::new(std::io::Cursor::new(b)).ok()?;
    let mut out = Vec::new();
    for i in 0..z.len() {
        let mut f = z.by_index(i).ok()?;
        let name = f.name().to_string();
        let mut v = Vec::new();
        (&mut f).take(64 << 20).read_to_end(&mut v).ok()?;
        out.push((name, v));
    }
    Some(out)
}

pub fn safetensors(header: &str, data: &[u8]) -> Vec<u8> {
    let mut out = (header.len() as u64).to_le_bytes().to_vec();
    out.extend(header.as_bytes());
    out.extend(data);
    out
}

// ---------------------------------------------------------------- mutations

pub const BIG_U32: [u32; 9] = [
    0xFFFF_FFFF,
    0x7FFF_FFFF,
    0x8000_0000,
    0x4000_0000,
    0x1000_0000,
    0x0001_0000,
    0xFFFF,
    0,
    1,
];
pub const BIG_U64: [u64; 8] = [
    u64::MAX,
    i64::MAX as u64,
    1 << 40,
    1 << 32,
    1 << 30,
    0xFFFF_FFFF,
    0,
    3,
];

pub fn truncate(rng: &mut Rng, b: &[u8]) -> (Vec<u8>, String) {
    let n = b.len();
    let at = if rng.below(2) == 0 {
        rng.below(n.min(1024))
    } else {
        rng.below(n)
    };
    (b[..at].to_vec(), format!("truncated at {at}/{n}"))
}

pub fn flip(rng: &mut Rng, b: &[u8], header_len: usize) -> (Vec<u8>, String) {
    let mut v = b.to_vec();
    if v.is_empty() {
        return (v, "empty".into());
    }
    let k = 1 + rng.below(8);
    let mut at = Vec::new();
    for _ in 0..k {
        let i = if rng.below(10) < 6 {
            rng.below(header_len.min(v.len()))
        } else {
            rng.below(v.len())
        };
        let x = 1 + rng.below(255) as u8;
        v[i] ^= x;
        at.push(i);
    }
    (v, format!("flipped bytes at {at:?}"))
}

/// Overwrite a u32 (or u64) at an aligned offset in `lo..hi` with a big value.
pub fn overwrite(rng: &mut Rng, b: &[u8], lo: usize, hi: usize, wide: bool) -> (Vec<u8>, String) {
    let mut v = b.to_vec();
    let w = if wide { 8 } else { 4 };
    let hi = hi.min(v.len());
    if hi < lo + w {
        return truncate(rng, b);
    }
    let off = lo + rng.below((hi - lo - w) / w + 1) * w;
    if wide {
        let x = *rng.pick(&BIG_U64);
        v[off..off + 8].copy_from_slice(&x.to_le_bytes());
        (v, format!("u64 at {off} := {x:#x}"))
    } else {
        let x = *rng.pick(&BIG_U32);
        v[off..off + 4].copy_from_slice(&x.to_le_bytes());
        (v, format!("u32 at {off} := {x:#x}"))
    }
}

/// Rewrite an .npy header: a huge / odd shape, another dtype, fortran order.
pub fn npy_header_edit(rng: &mut Rng, b: &[u8]) -> (Vec<u8>, String) {
    if b.len() < 10 || &b[..6] != b"\x93NUMPY" {
        return overwrite(rng, b, 0, 128, false);
    }
    let hl = u16::from_le_bytes([b[8], b[9]]) as usize;
    let data = b.get(10 + hl..).unwrap_or(&[]);
    let shapes = [
        "(2147483647,)",
        "(4294967296, 2)",
        "(100000, 100000)",
        "(65536, 65536, 28)",
        "(9223372036854775807,)",
        "(-1, 38)",
        "(0, 38)",
        "(32, 0)",
        "(1, 1, 1, 1, 1, 1)",
        "(32, 38, 4, 2)",
        "(1000000, 38)",
        "(32, 1000000)",
        "()",
        "(3, 3)",
        "(28, 256, 256)",
        "(18446744073709551615, 2)",
    ];
    let descrs = [
        "<f4", "<f8", ">f4", "<f2", "<c8", "|O", "<U4", "|b1", "<i8", "|V16", "<M8[s]", "xyz",
    ];
    let kind = rng.below(3);
    let (descr, shape, fortran, what) = match kind {
        0 => {
            let s = *rng.pick(&shapes);
            ("<f4", s.to_string(), false, format!("shape {s}"))
        }
        1 => {
            let d = *rng.pick(&descrs);
            (d, "(32, 38)".into(), false, format!("descr {d}"))
        }
        _ => {
            let s = *rng.pick(&shapes);
            let d = *rng.pick(&descrs);
            (
                d,
                s.to_string(),
                true,
                format!("descr {d} shape {s} fortran"),
            )
        }
    };
    (
        npy_raw(descr, &shape, fortran, data),
        format!("npy header: {what}"),
    )
}

/// Mutate JSON text: a numeric leaf set to an absurd value, a key removed, a value retyped,
/// or parameters made positional.
pub fn json_edit(rng: &mut Rng, text: &str) -> (Vec<u8>, String) {
    let Ok(mut v) = serde_json::from_str::<serde_json::Value>(text) else {
        return (text.as_bytes().to_vec(), "unparsable seed".into());
    };
    let mut paths = Vec::new();
    fn walk(v: &serde_json::Value, p: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
        match v {
            serde_json::Value::Object(m) => {
                for (k, x) in m {
                    p.push(k.clone());
                    out.push(p.clone());
                    walk(x, p, out);
                    p.pop();
                }
            }
            serde_json::Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    p.push(i.to_string());
                    out.push(p.clone());
                    walk(x, p, out);
                    p.pop();
                }
            }
            _ => {}
        }
    }
    walk(&v, &mut Vec::new(), &mut paths);
    if paths.is_empty() {
        return (text.as_bytes().to_vec(), "no leaves".into());
    }
    let path = rng.pick(&paths).clone();
    let values: Vec<serde_json::Value> = vec![
        serde_json::json!(1e308),
        serde_json::json!(-1e308),
        serde_json::json!(1e-300),
        serde_json::json!(0),
        serde_json::json!(-1),
        serde_json::json!(1e9),
        serde_json::json!(u64::MAX),
        serde_json::json!("NaN"),
        serde_json::json!("x"),
        serde_json::Value::Null,
        serde_json::json!([1, 2, 3, 4, 5]),
        serde_json::json!({}),
        serde_json::json!(true),
    ];
    let op = rng.below(10);
    let (parent_path, last) = path.split_at(path.len() - 1);
    let mut parent = &mut v;
    for k in parent_path {
        parent = match parent {
            serde_json::Value::Object(m) => m.get_mut(k).unwrap(),
            serde_json::Value::Array(a) => &mut a[k.parse::<usize>().unwrap()],
            _ => unreachable!(),
        };
    }
    let what;
    match (op, parent) {
        (0, serde_json::Value::Object(m)) => {
            m.remove(&last[0]);
            what = format!("removed {}", path.join("."));
        }
        (_, serde_json::Value::Object(m)) => {
            let x = rng.pick(&values).clone();
            what = format!("{} := {x}", path.join("."));
            m.insert(last[0].clone(), x);
        }
        (_, serde_json::Value::Array(a)) => {
            let x = rng.pick(&values).clone();
            what = format!("{} := {x}", path.join("."));
            a[last[0].parse::<usize>().unwrap()] = x;
        }
        _ => what = "no-op".into(),
    }
    let mut s = serde_json::to_string_pretty(&v).unwrap();
    if rng.below(8) == 0 {
        // literal non-JSON numbers some writers emit
        s = s.replacen("0.0", "NaN", 1);
    }
    (s.into_bytes(), what)
}
