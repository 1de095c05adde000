//! avr-libc's `f32` math (`libm.a`, linked by [`link_avr_libc!`](crate::link_avr_libc)) behind safe
//! wrappers, for firmware that needs transcendental functions in floating point.
//!
//! Hand-written assembly: faster than the pure-Rust `libm` crate on this MCU, even with
//! avr-libc's float arithmetic under that crate. avr-libc's `double` is 32 bits, so its
//! `log10`, `exp` and `sqrt` are the `f32` functions (its `math.h` defines `log10f` & co. as
//! aliases of them; `libm.a` exports only the unsuffixed names).

mod ffi {
    extern "C" {
        pub fn log10(x: f32) -> f32;
        pub fn exp(x: f32) -> f32;
        pub fn sqrt(x: f32) -> f32;
    }
}

/// `log10(x)` (NaN for `x < 0`, −∞ for 0).
#[inline]
pub fn log10f(x: f32) -> f32 {
    // SAFETY: a pure function of its argument for every input, no pointers or global state; the
    // C `double` of avr-libc is an IEEE single, passed and returned in r22–r25 like Rust's `f32`.
    unsafe { ffi::log10(x) }
}

/// `e^x` (0 on underflow, +∞ on overflow).
#[inline]
pub fn expf(x: f32) -> f32 {
    // SAFETY: as `log10f`.
    unsafe { ffi::exp(x) }
}

/// `√x` (NaN for `x < 0`).
#[inline]
pub fn sqrtf(x: f32) -> f32 {
    // SAFETY: as `log10f`.
    unsafe { ffi::sqrt(x) }
}
