//! Runtime CPU dispatch for hot element loops: the crate is built for
//! baseline x86-64 (SSE2), so a loop written plainly vectorises 4-wide; a
//! function declared through [`avx2_dispatch!`] is compiled a second time
//! with AVX2 (8-wide) and that copy runs when the CPU has it. Bodies use
//! plain `a * b + c` (never `mul_add`, a libm call without FMA), so both
//! copies give bit-identical results.

macro_rules! avx2_dispatch {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $body:block) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) {
            #[inline(always)]
            fn body($($arg: $ty),*) $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                unsafe fn avx2($($arg: $ty),*) {
                    body($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports the feature `avx2` was compiled for.
                    return unsafe { avx2($($arg),*) };
                }
            }
            body($($arg),*)
        }
    };
}

pub(crate) use avx2_dispatch;
