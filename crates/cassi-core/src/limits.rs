//! Resource limits checked before work starts: no array larger than the
//! element budget is allocated, whether its size comes from a file header, a
//! flag (`--stride`, `--bands`, `--size`) or arithmetic on both.
//!
//! The budget is per array (a cube, a measurement, a decoded variable). The
//! default, 2^25 elements (128 MiB as f32), fits a 660×714×28 real snapshot's
//! cube (13.2 M elements) 2.5 times over, and keeps the largest problem a
//! solver works on (a few cube-sized buffers) within a few GB on a 24 GB
//! machine. It is process-wide and configurable (the CLI's `--max-elements`
//! and `CASSI_MAX_ELEMENTS`).

use std::sync::atomic::{AtomicUsize, Ordering};

use crate::error::{CassiError, Result};

/// The default budget: elements in one array.
pub const DEFAULT_MAX_ELEMENTS: usize = 1 << 25;

static MAX_ELEMENTS: AtomicUsize = AtomicUsize::new(DEFAULT_MAX_ELEMENTS);

/// The largest number of elements one array may have.
pub fn max_elements() -> usize {
    MAX_ELEMENTS.load(Ordering::Relaxed)
}

/// Sets the process-wide budget (at least 1).
pub fn set_max_elements(n: usize) {
    MAX_ELEMENTS.store(n.max(1), Ordering::Relaxed);
}

/// The element count of `shape` if it is within the budget; otherwise an
/// error naming `what`, the shape, the count it would need and the budget.
/// `hint` says how the size came about (e.g. "from --stride 0.001"), and may
/// be empty.
pub fn check_elements(what: &str, shape: &[usize], hint: &str) -> Result<usize> {
    let dims = shape
        .iter()
        .map(|d| d.to_string())
        .collect::<Vec<_>>()
        .join("×");
    let count = shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d));
    let budget = max_elements();
    match count {
        Some(n) if n <= budget => Ok(n),
        _ => {
            let need = count.map_or_else(|| "more than 2^64".to_string(), |n| n.to_string());
            let hint = if hint.is_empty() {
                String::new()
            } else {
                format!(" ({hint})")
            };
            Err(CassiError::TooLarge {
                what: what.to_string(),
                detail: format!(
                    "{dims}{hint} would need {need} elements, over the budget of {budget} \
                     (raise it with --max-elements or CASSI_MAX_ELEMENTS if this is intended)"
                ),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_refuses_large_and_overflowing_shapes_and_names_them() {
        assert_eq!(
            check_elements("cube", &[28, 256, 256], "").unwrap(),
            28 * 65536
        );
        assert_eq!(
            check_elements("cube", &[28, 660, 714], "").unwrap(),
            28 * 660 * 714
        );
        let e = check_elements("cube", &[55001, 256, 256], "from --stride 0.001")
            .unwrap_err()
            .to_string();
        assert!(e.contains("cube"), "{e}");
        assert!(e.contains("55001×256×256"), "{e}");
        assert!(e.contains("from --stride 0.001"), "{e}");
        assert!(e.contains(&(55001usize * 65536).to_string()), "{e}");
        let e = check_elements("x", &[usize::MAX, 3], "")
            .unwrap_err()
            .to_string();
        assert!(e.contains("more than 2^64"), "{e}");
    }
}
