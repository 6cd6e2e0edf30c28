//! Strided f32 matrix products on top of the `gemm` crate, plus the shared
//! output pointer that lets rayon tiles write disjoint parts of one result.

/// A read-only strided matrix view: element (i, j) is `data[i * rs + j * cs]`.
#[derive(Clone, Copy)]
pub(crate) struct Mat<'a> {
    pub data: &'a [f32],
    pub rows: usize,
    pub cols: usize,
    pub rs: usize,
    pub cs: usize,
}

impl<'a> Mat<'a> {
    /// A row-major matrix whose rows are `ld` apart.
    pub fn rows(data: &'a [f32], rows: usize, cols: usize, ld: usize) -> Self {
        Self {
            data,
            rows,
            cols,
            rs: ld,
            cs: 1,
        }
    }
    /// The transpose of the row-major `cols × rows` matrix stored with leading dimension `ld`.
    pub fn transposed(data: &'a [f32], rows: usize, cols: usize, ld: usize) -> Self {
        Self {
            data,
            rows,
            cols,
            rs: 1,
            cs: ld,
        }
    }
    fn check(&self) {
        if self.rows > 0 && self.cols > 0 {
            let last = (self.rows - 1) * self.rs + (self.cols - 1) * self.cs;
            assert!(last < self.data.len(), "matrix view out of bounds");
        }
    }
}

/// A mutable output pointer shared by parallel tiles that write disjoint
/// elements (e.g. column ranges of one row-major matrix).
#[derive(Clone, Copy)]
pub(crate) struct SharedOut {
    ptr: *mut f32,
    len: usize,
}
// SAFETY: the pointer is reached only through the `unsafe` `slice_mut` and
// `matmul_into`, whose callers promise that threads write disjoint elements
// while the underlying slice is alive; moving the handle to another thread
// changes neither.
unsafe impl Send for SharedOut {}
// SAFETY: `&SharedOut` gives no access by itself (see `Send` above).
unsafe impl Sync for SharedOut {}

impl SharedOut {
    pub fn new(out: &mut [f32]) -> Self {
        Self {
            ptr: out.as_mut_ptr(),
            len: out.len(),
        }
    }

    /// Elements `offset .. offset + len` as a slice.
    ///
    /// # Safety
    /// No other thread may touch those elements while the slice lives, and
    /// the slice behind `self` must outlive it.
    #[allow(clippy::mut_from_ref)]
    pub unsafe fn slice_mut(&self, offset: usize, len: usize) -> &mut [f32] {
        assert!(
            offset + len <= self.len,
            "shared output range out of bounds"
        );
        // SAFETY: in bounds (checked); exclusivity is the caller's contract.
        unsafe { std::slice::from_raw_parts_mut(self.ptr.add(offset), len) }
    }
}

/// `out[offset + i*out_rs + j*out_cs] (+)= Σ_k a(i,k) b(k,j)` for
/// i < a.rows, j < b.cols, into the shared output. Single threaded (callers
/// parallelise over tiles). `accumulate` adds to out instead of overwriting.
///
/// # Safety
/// No other thread may touch the written elements during the call, the
/// output strides must not map two (i, j) to one element, and the slice
/// behind `out` must be alive.
pub(crate) unsafe fn matmul_into(
    a: Mat,
    b: Mat,
    out: SharedOut,
    offset: usize,
    (out_rs, out_cs): (usize, usize),
    accumulate: bool,
) {
    assert_eq!(a.cols, b.rows, "inner dimensions differ");
    assert!(a.cols > 0, "empty inner dimension");
    a.check();
    b.check();
    let (m, n, k) = (a.rows, b.cols, a.cols);
    if m == 0 || n == 0 {
        return;
    }
    assert!(
        offset + (m - 1) * out_rs + (n - 1) * out_cs < out.len,
        "output out of bounds"
    );
    // SAFETY: `a` and `b` lie inside their slices (`check`), the output's
    // last element is inside `out` (asserted), and gemm reads and writes
    // only the elements of these strided views; exclusivity and liveness
    // of the output are this function's contract with its caller.
    unsafe {
        gemm::gemm(
            m,
            n,
            k,
            out.ptr.add(offset),
            out_cs as isize,
            out_rs as isize,
            accumulate,
            a.data.as_ptr(),
            a.cs as isize,
            a.rs as isize,
            b.data.as_ptr(),
            b.cs as isize,
            b.rs as isize,
            1.0,
            1.0,
            false,
            false,
            false,
            gemm::Parallelism::None,
        )
    }
}

/// `out (a.rows × b.cols, row-major, contiguous) = a · b`, parallel over
/// column chunks of `b` with rayon.
pub(crate) fn matmul(a: Mat, b: Mat, out: &mut [f32]) {
    use rayon::prelude::*;
    let (m, n) = (a.rows, b.cols);
    assert_eq!(out.len(), m * n, "output length");
    let chunk = column_chunk(n);
    let shared = SharedOut::new(out);
    (0..n.div_ceil(chunk)).into_par_iter().for_each(|t| {
        let j0 = t * chunk;
        let j1 = (j0 + chunk).min(n);
        let bj = Mat {
            data: &b.data[j0 * b.cs..],
            cols: j1 - j0,
            ..b
        };
        // SAFETY: tiles write disjoint column ranges [j0, j1) of `out`.
        unsafe { matmul_into(a, bj, shared, j0, (n, 1), false) };
    });
}

/// Columns per parallel tile: a few tiles per thread, each big enough to
/// keep gemm efficient (at least 256 columns unless n is smaller).
pub(crate) fn column_chunk(n: usize) -> usize {
    let threads = rayon::current_num_threads().max(1);
    let tiles = threads * 4;
    n.div_ceil(tiles).max(256).min(n.max(1))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn naive(a: Mat, b: Mat) -> Vec<f32> {
        let mut out = vec![0.0; a.rows * b.cols];
        for i in 0..a.rows {
            for j in 0..b.cols {
                for k in 0..a.cols {
                    out[i * b.cols + j] +=
                        a.data[i * a.rs + k * a.cs] * b.data[k * b.rs + j * b.cs];
                }
            }
        }
        out
    }

    #[test]
    fn strided_products_match_the_naive_loop() {
        let a_data: Vec<f32> = (0..7 * 5).map(|i| ((i * 37) % 11) as f32 - 5.0).collect();
        let b_data: Vec<f32> = (0..5 * 600).map(|i| ((i * 13) % 7) as f32 * 0.5).collect();
        // a: 7×5 row-major; b: 5×600 row-major, and aᵀ of a 5×7 view.
        let a = Mat::rows(&a_data, 7, 5, 5);
        let b = Mat::rows(&b_data, 5, 600, 600);
        let mut out = vec![0.0; 7 * 600];
        matmul(a, b, &mut out);
        assert_eq!(out, naive(a, b));
        let at = Mat::transposed(&a_data, 5, 7, 5); // (5×7) = aᵀ
        let c = Mat::rows(&a_data, 7, 5, 5);
        let mut out2 = vec![0.0; 25];
        matmul(at, c, &mut out2);
        assert_eq!(out2, naive(at, c));
    }
}
