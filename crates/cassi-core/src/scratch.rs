//! Per-thread buffers reused across calls: a calibration builds one
//! operator per candidate, and buffers allocated per candidate (2 MB each
//! at 660×714) were handed back to the kernel and faulted in again every
//! time.

use std::cell::RefCell;
use std::thread::LocalKey;

/// Runs `f` with the value in the thread-local `key` taken out, then puts
/// it back. A nested call on the same thread (rayon may run another job
/// here while this one waits) finds the default and allocates its own.
pub(crate) fn with_taken<T: Default + 'static, R>(
    key: &'static LocalKey<RefCell<T>>,
    f: impl FnOnce(&mut T) -> R,
) -> R {
    let mut value = key.with_borrow_mut(std::mem::take);
    let out = f(&mut value);
    key.with_borrow_mut(|slot| *slot = value);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    thread_local! {
        static KEPT: RefCell<Vec<u32>> = RefCell::default();
    }

    /// The value survives between calls, and a nested call neither panics
    /// nor sees the outer call's value.
    #[test]
    fn the_value_is_kept_and_a_nested_call_gets_its_own() {
        with_taken(&KEPT, |v| v.push(1));
        let inner = with_taken(&KEPT, |outer| {
            outer.push(2);
            with_taken(&KEPT, |nested| nested.clone())
        });
        assert!(inner.is_empty());
        assert_eq!(KEPT.with_borrow(|v| v.clone()), vec![1, 2]);
    }
}
