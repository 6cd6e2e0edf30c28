//! The format-neutral view of a file: a list of variables, each with a name,
//! a shape as the file shows it, an element type, and (for numeric ones) the
//! values in row-major (C) order.

use crate::escape::esc;

/// One stored element type: kind ('f' IEEE float, 'i' signed, 'u' unsigned,
/// 'b' bool), width in bytes, byte order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Elem {
    pub kind: char,
    pub size: usize,
    pub endian: Endian,
}

impl Elem {
    /// The element type, if cassi can decode it (float16/32/64, (u)int8…64, bool).
    pub(crate) fn new(kind: char, size: usize, endian: Endian) -> Option<Self> {
        match (kind, size) {
            ('f', 2 | 4 | 8) | ('i' | 'u', 1 | 2 | 4 | 8) | ('b', 1) => {
                Some(Elem { kind, size, endian })
            }
            _ => None,
        }
    }
}

/// What a reader knows about one variable before decoding its values.
#[derive(Debug, Clone, Default)]
pub(crate) struct VarInfo {
    pub name: String,
    /// The shape as the file's own tool shows it (MATLAB `size`, NumPy `shape`).
    /// Empty for things without a shape (an HDF5 group).
    pub shape: Vec<usize>,
    /// Element type in the file's own vocabulary ("double", "logical", "float32").
    pub dtype: String,
    /// Whether the values can be read as real numbers.
    pub numeric: bool,
    /// For a non-numeric variable: why it cannot be read (shown in errors).
    pub note: String,
    /// How the values are stored, for a numeric variable.
    pub elem: Option<Elem>,
    /// Whether the values are stored column-major (MATLAB, NumPy `fortran_order`).
    pub fortran: bool,
    /// Whether the file allocates no storage for the values (an HDF5 dataset
    /// never written: reading it would only repeat its fill value).
    pub unstored: bool,
    /// The most bytes of values the file can yield for it (the bytes present,
    /// or what its compressed bytes can inflate to), when known: a shape
    /// declaring more is refused before anything is allocated.
    pub max_bytes: Option<u64>,
}

/// Byte order of multi-byte numbers in a file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Endian {
    Little,
    Big,
}

/// Formats a shape the MATLAB way: `256×256×28`; 1-D as `6 (1-D)`, 0-D as `scalar`.
pub(crate) fn shape_str(shape: &[usize]) -> String {
    match shape.len() {
        0 => "scalar".to_string(),
        1 => format!("{} (1-D)", shape[0]),
        _ => shape
            .iter()
            .map(|d| d.to_string())
            .collect::<Vec<_>>()
            .join("×"),
    }
}

/// Lists variables as `'name' 4×5 double, 'txt' 1×5 char`, for error messages.
pub(crate) fn list_vars(vars: &[VarInfo]) -> String {
    if vars.is_empty() {
        return "(no variables)".to_string();
    }
    vars.iter()
        .map(|v| {
            if v.shape.is_empty() && !v.numeric {
                format!("'{}' {}", esc(&v.name), esc(&v.dtype))
            } else {
                format!(
                    "'{}' {} {}",
                    esc(&v.name),
                    shape_str(&v.shape),
                    esc(&v.dtype)
                )
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Number of elements of `shape`, or `None` on overflow.
pub(crate) fn element_count(shape: &[usize]) -> Option<usize> {
    shape.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d))
}

/// Reorders column-major (Fortran/MATLAB) data of `shape` into row-major (C)
/// order of the same shape: the element at index (i0, …, in) moves from
/// offset i0 + d0·(i1 + d1·(…)) to offset (…(i0·d1 + i1)·d2 + …) + in.
pub(crate) fn col_major_to_row_major<T: Copy>(data: &[T], shape: &[usize]) -> Vec<T> {
    let n = data.len();
    if shape.len() < 2 || n == 0 || element_count(shape) != Some(n) {
        return data.to_vec();
    }
    // Column-major strides.
    let mut fstride = vec![1usize; shape.len()];
    for d in 1..shape.len() {
        fstride[d] = fstride[d - 1] * shape[d - 1];
    }
    let last = shape.len() - 1;
    let inner = shape[last];
    let inner_stride = fstride[last];
    let mut out = Vec::with_capacity(n);
    let mut idx = vec![0usize; last]; // odometer over all axes but the last
    loop {
        let base: usize = idx.iter().zip(&fstride).map(|(i, s)| i * s).sum();
        out.extend((0..inner).map(|k| data[base + k * inner_stride]));
        // Advance the odometer (last of the outer axes fastest).
        let mut d = last;
        loop {
            if d == 0 {
                return out;
            }
            d -= 1;
            idx[d] += 1;
            if idx[d] < shape[d] {
                break;
            }
            idx[d] = 0;
        }
    }
}

/// The inverse of [`col_major_to_row_major`]: C-order data of `shape` into
/// column-major order.
pub(crate) fn row_major_to_col_major<T: Copy>(data: &[T], shape: &[usize]) -> Vec<T> {
    // Column-major data of shape (d0…dn) is row-major data of the reversed
    // shape, so reversing every axis of the C-order array does it.
    let reversed: Vec<usize> = shape.iter().rev().copied().collect();
    // Interpreting `data` (row-major of `shape`) as column-major of the reversed
    // shape and converting gives row-major of the reversed shape = column-major of `shape`.
    col_major_to_row_major(data, &reversed)
}

/// The 0-based multi-index of flat C-order offset `i` in `shape`, as `[a, b, c]`.
pub(crate) fn index_str(shape: &[usize], mut i: usize) -> String {
    let mut idx = vec![0usize; shape.len()];
    for (d, &n) in shape.iter().enumerate().rev() {
        if n > 0 {
            idx[d] = i % n;
            i /= n;
        }
    }
    format!(
        "[{}]",
        idx.iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn column_major_reorder_matches_index_formula() {
        // MATLAB A(r, c, b) = 100 r + 10 c + b for size (2, 3, 4), stored column-major.
        let shape = [2usize, 3, 4];
        let mut fdata = Vec::new();
        for b in 0..4 {
            for c in 0..3 {
                for r in 0..2 {
                    fdata.push((100 * r + 10 * c + b) as f64);
                }
            }
        }
        let cdata = col_major_to_row_major(&fdata, &shape);
        let mut i = 0;
        for r in 0..2 {
            for c in 0..3 {
                for b in 0..4 {
                    assert_eq!(cdata[i], (100 * r + 10 * c + b) as f64);
                    i += 1;
                }
            }
        }
        assert_eq!(row_major_to_col_major(&cdata, &shape), fdata);
    }

    #[test]
    fn index_and_shape_strings() {
        assert_eq!(index_str(&[2, 3, 4], 23), "[1, 2, 3]");
        assert_eq!(index_str(&[3, 4], 6), "[1, 2]");
        assert_eq!(shape_str(&[256, 256, 28]), "256×256×28");
        assert_eq!(shape_str(&[6]), "6 (1-D)");
    }
}
