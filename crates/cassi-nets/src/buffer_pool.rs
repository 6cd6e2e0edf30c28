//! Recycled storage for large feature maps. A forward pass allocates and
//! drops maps of a few sizes hundreds of times; fresh multi-MB allocations
//! come from the kernel as new pages, so each one costs page faults and
//! the kernel's zeroing (with our own zero fill on top: ~15 % of an MST
//! forward pass). A dropped map's buffer is kept in a process-wide pool
//! and handed to the next map that fits.

use std::sync::{Mutex, MutexGuard};

/// Buffers smaller than this go back to the allocator (cheap to get anew).
const MIN_POOLED_FLOATS: usize = 1 << 18; // 1 MiB
/// The most the process-wide pool keeps, in bytes (the distinct map sizes
/// of an MST-L pass fit); beyond it, the largest buffers are freed.
pub const MAX_POOLED_BYTES: usize = 256 << 20;

/// A bounded set of spare buffers, handed out best fit.
struct BufferPool {
    spare: Mutex<Vec<Vec<f32>>>,
    max_bytes: usize,
}

static POOL: BufferPool = BufferPool::new(MAX_POOLED_BYTES);

impl BufferPool {
    const fn new(max_bytes: usize) -> Self {
        Self {
            spare: Mutex::new(Vec::new()),
            max_bytes,
        }
    }

    fn spare(&self) -> MutexGuard<'_, Vec<Vec<f32>>> {
        // A panic while holding the lock cannot leave the list inconsistent.
        self.spare.lock().unwrap_or_else(|e| e.into_inner())
    }

    fn take(&self, len: usize) -> Vec<f32> {
        if len >= MIN_POOLED_FLOATS {
            let mut spare = self.spare();
            let best = (spare.iter().enumerate())
                .filter(|(_, b)| b.capacity() >= len)
                .min_by_key(|(_, b)| b.capacity())
                .map(|(i, _)| i);
            if let Some(i) = best {
                let mut buf = spare.swap_remove(i);
                drop(spare);
                // Within capacity: no reallocation; only a grown tail is written.
                buf.resize(len, 0.0);
                return buf;
            }
        }
        vec![0.0; len]
    }

    fn give(&self, buf: Vec<f32>) {
        if buf.capacity() < MIN_POOLED_FLOATS {
            return;
        }
        let mut spare = self.spare();
        spare.push(buf);
        while bytes(&spare) > self.max_bytes {
            let largest = (spare.iter().enumerate())
                .max_by_key(|(_, b)| b.capacity())
                .map(|(i, _)| i)
                .expect("a non-empty pool");
            spare.swap_remove(largest);
        }
    }
}

fn bytes(spare: &[Vec<f32>]) -> usize {
    spare.iter().map(|b| b.capacity() * 4).sum()
}

/// A buffer of `len` floats whose contents are unspecified (stale values
/// of an earlier map, or zeros): for outputs that write every element.
pub(crate) fn take(len: usize) -> Vec<f32> {
    POOL.take(len)
}

/// Keeps `buf` for a later [`take`] if it is large enough to be worth it.
pub(crate) fn give(buf: Vec<f32>) {
    POOL.give(buf)
}

/// Frees every buffer the networks keep for reuse (up to
/// [`MAX_POOLED_BYTES`]), e.g. after the last reconstruction of a
/// long-running process.
pub fn release_cached_buffers() {
    POOL.spare().clear();
}

/// Bytes of buffers the networks keep for reuse now.
pub fn cached_buffer_bytes() -> usize {
    bytes(&POOL.spare())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_are_reused_best_fit_and_bounded() {
        let m = MIN_POOLED_FLOATS;
        let pool = BufferPool::new(10 * 3 * m * 4); // ten buffers of 3m floats
        let small = vec![1.0f32; 2 * m];
        let big = vec![2.0f32; 4 * m];
        let (small_ptr, big_ptr) = (small.as_ptr(), big.as_ptr());
        pool.give(big);
        pool.give(small);
        let got = pool.take(m + 5);
        assert_eq!(
            (got.as_ptr(), got.len()),
            (small_ptr, m + 5),
            "smallest fit"
        );
        let got = pool.take(6 * m);
        assert_ne!(got.as_ptr(), big_ptr, "too small to serve");
        assert_eq!(got, vec![0.0; 6 * m], "a fresh buffer is zeros");
        let got = pool.take(3 * m);
        assert_eq!((got.as_ptr(), got.len()), (big_ptr, 3 * m));
        assert_eq!(
            pool.take(m - 1).len(),
            m - 1,
            "small requests bypass the pool"
        );
        assert!(pool.spare().is_empty());
        // Small buffers are not kept; the byte bound drops the largest first.
        pool.give(vec![0.0; 16]);
        for _ in 0..10 {
            pool.give(vec![0.0; 3 * m]);
        }
        pool.give(vec![0.0; 9 * m]);
        assert_eq!(bytes(&pool.spare()), 10 * 3 * m * 4);
        assert!(pool.spare().iter().all(|b| b.capacity() == 3 * m));
    }
}
