//! The check firmwares' random inputs: xorshift32, the same sequence on the MCU and on the host
//! (the host recomputes `checkasm`'s jobs from their seeds).

/// One step of xorshift32.
#[inline(always)]
pub fn xorshift(r: &mut u32) -> u32 {
    *r ^= *r << 13;
    *r ^= *r >> 17;
    *r ^= *r << 5;
    *r
}

/// A xorshift32 generator and the draws the checks make of it.
pub struct Rng(pub u32);

impl Rng {
    /// The next 32 bits.
    pub fn bits(&mut self) -> u32 {
        xorshift(&mut self.0)
    }

    /// A value in `[0, n)` (`n > 0`).
    pub fn below(&mut self, n: u32) -> u32 {
        self.bits() % n
    }

    /// A value in `[lo, hi]`.
    pub fn range(&mut self, lo: i32, hi: i32) -> i32 {
        lo.wrapping_add(self.below(hi.wrapping_sub(lo) as u32 + 1) as i32)
    }

    /// One of `v` (not empty).
    pub fn pick<T: Copy>(&mut self, v: &[T]) -> T {
        v[self.below(v.len() as u32) as usize]
    }
}
