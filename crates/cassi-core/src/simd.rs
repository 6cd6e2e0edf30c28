//! Run-time SIMD dispatch: hot loops are compiled twice, for the baseline
//! target and with AVX enabled, and the copy the CPU supports is picked at
//! run time (no target-cpu build flags, so binaries stay portable).

/// Which compiled copy of the row kernels to run.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Simd {
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    pub(crate) avx: bool,
}

impl Simd {
    pub(crate) fn detect(portable_only: bool) -> Self {
        #[cfg(target_arch = "x86_64")]
        let avx = !portable_only && std::arch::is_x86_feature_detected!("avx");
        #[cfg(not(target_arch = "x86_64"))]
        let avx = {
            let _ = portable_only;
            false
        };
        Self { avx }
    }
}

/// Compiles a row kernel twice — baseline and AVX — behind one dispatcher.
/// The slices are arguments of a non-inlined function, so LLVM knows they do
/// not alias and vectorises the lane loops.
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
        $vis fn $name(simd: Simd, $($a: $t),*) -> $r {
            #[cfg(target_arch = "x86_64")]
            if simd.avx {
                // SAFETY: `$avx` only needs the CPU to have AVX, and
                // `simd.avx` is true only when `Simd::detect` found AVX at
                // run time (the one other constructor, a test, passes
                // detect's answer or false).
                return unsafe { $avx($($a),*) };
            }
            let _ = simd;
            $port($($a),*)
        }
    };
}

pub(crate) use kernel;
