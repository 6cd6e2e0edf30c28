//! Run-time SIMD dispatch: hot loops are compiled three times — for the
//! baseline target, with AVX and with AVX-512 — and the copy the CPU
//! supports is picked at run time (no target-cpu build flags, so binaries
//! stay portable). Every copy does the same arithmetic per element in the
//! same order (no fused multiply-adds, no reordered sums: LLVM makes
//! neither without being told), so results do not depend on the CPU; the
//! tests compare each copy this CPU runs against the baseline's bits.

/// Which compiled copy of the row kernels to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Simd {
    /// The baseline target's (SSE2 on x86-64; the only one elsewhere).
    Portable,
    /// AVX: 8 lanes of f32.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    Avx,
    /// AVX-512 (F, BW, DQ, VL): 16 lanes of f32. On the 2-core AMD EPYC
    /// VM the calibration benchmark's 256² cases take 0.88–0.95 of their
    /// time with AVX (per-case ratio, two sittings), the real 660×714
    /// snapshots 0.89–0.92, every answer bitwise the same
    /// (`bench/results/calibrate_physical_timing_stop64/`).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    Avx512,
}

impl Simd {
    /// The widest copy this CPU runs (`portable_only`: the baseline's).
    pub(crate) fn detect(portable_only: bool) -> Self {
        #[cfg(test)]
        if let Some(forced) = forced::get() {
            return if portable_only {
                Simd::Portable
            } else {
                forced
            };
        }
        if portable_only {
            return Simd::Portable;
        }
        Self::widest()
    }

    fn widest() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            if has!("avx512f") && has!("avx512bw") && has!("avx512dq") && has!("avx512vl") {
                return Simd::Avx512;
            }
            if has!("avx") {
                return Simd::Avx;
            }
        }
        Simd::Portable
    }

    /// The copy's name in records: `portable`, `avx`, `avx512`.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Simd::Portable => "portable",
            Simd::Avx => "avx",
            Simd::Avx512 => "avx512",
        }
    }

    /// Whether AVX's instructions may run (the AVX and AVX-512 copies): for
    /// hand-written AVX kernels.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub(crate) fn has_avx(self) -> bool {
        matches!(self, Simd::Avx | Simd::Avx512)
    }

    /// Every copy this CPU runs, the baseline's first: what the tests
    /// compare.
    #[cfg(test)]
    pub(crate) fn available() -> Vec<Simd> {
        match Self::widest() {
            Simd::Portable => vec![Simd::Portable],
            Simd::Avx => vec![Simd::Portable, Simd::Avx],
            Simd::Avx512 => vec![Simd::Portable, Simd::Avx, Simd::Avx512],
        }
    }
}

/// Which compiled copy of the kernels this CPU runs (`portable`, `avx`,
/// `avx512`): for benchmark records, whose times depend on it.
pub fn kernel_copy() -> &'static str {
    Simd::detect(false).name()
}

/// Compiles a row kernel three times — baseline, AVX and AVX-512 — behind
/// one dispatcher. The slices are arguments of a non-inlined function, so
/// LLVM knows they do not alias and vectorises the lane loops.
macro_rules! kernel {
    ($vis:vis $name:ident, $port:ident, $avx:ident, ($($a:ident: $t:ty),* $(,)?) -> $r:ty = $call:expr) => {
        #[inline(never)]
        #[allow(clippy::too_many_arguments)]
        fn $port($($a: $t),*) -> $r {
            $call
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx")]
        #[inline(never)]
        #[allow(clippy::too_many_arguments)]
        unsafe fn $avx($($a: $t),*) -> $r {
            $call
        }

        #[inline(always)]
        #[allow(clippy::too_many_arguments)]
        $vis fn $name(simd: $crate::simd::Simd, $($a: $t),*) -> $r {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx,avx512f,avx512bw,avx512dq,avx512vl")]
                #[inline(never)]
                #[allow(clippy::too_many_arguments)]
                unsafe fn avx512($($a: $t),*) -> $r {
                    $call
                }
                match simd {
                    $crate::simd::Simd::Avx512 => {
                        // SAFETY: `Simd::detect` answers `Avx512` only when
                        // it found AVX-512 F, BW, DQ and VL at run time (tests
                        // pass its answers or the copies `Simd::available`
                        // lists, found the same way).
                        return unsafe { avx512($($a),*) };
                    }
                    $crate::simd::Simd::Avx => {
                        // SAFETY: `Avx` only where AVX was found, as above
                        // (every AVX-512 CPU has AVX).
                        return unsafe { $avx($($a),*) };
                    }
                    $crate::simd::Simd::Portable => {}
                }
            }
            let _ = simd;
            $port($($a),*)
        }
    };
}

pub(crate) use kernel;

/// Tests only: every [`Simd::detect`] in the process answers a chosen copy
/// while a [`forced::Forced`] guard lives, so a test can run whole operators
/// and solvers on each copy. Guards are taken one at a time (a lock); other
/// tests running meanwhile get a copy that gives the same bits.
#[cfg(test)]
pub(crate) mod forced {
    use super::Simd;
    use std::sync::{Mutex, MutexGuard, PoisonError};

    static FORCED: Mutex<Option<Simd>> = Mutex::new(None);
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

    pub(super) fn get() -> Option<Simd> {
        *FORCED.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Forces `simd` until dropped.
    pub(crate) struct Forced(#[allow(dead_code)] MutexGuard<'static, ()>);

    impl Forced {
        pub(crate) fn new(simd: Simd) -> Self {
            let turn = ONE_AT_A_TIME.lock().unwrap_or_else(PoisonError::into_inner);
            *FORCED.lock().unwrap_or_else(PoisonError::into_inner) = Some(simd);
            Self(turn)
        }
    }

    impl Drop for Forced {
        fn drop(&mut self) {
            *FORCED.lock().unwrap_or_else(PoisonError::into_inner) = None;
        }
    }
}
