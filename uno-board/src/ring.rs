//! A fixed-capacity byte FIFO (portable, unit-tested on the host).
//!
//! The RX interrupt pushes, the main loop pops; uno-board wraps it in a critical section, so the
//! ring itself is a plain single-owner structure with no `unsafe` and no panics.

/// A FIFO of at most `N` bytes; `N` must be a power of two no larger than 256.
pub struct Ring<const N: usize> {
    buf: [u8; N],
    /// Index of the oldest byte.
    head: u8,
    /// Number of bytes stored (0..=N, so it needs more than 8 bits only when N == 256).
    len: u16,
}

impl<const N: usize> Ring<N> {
    const CHECK: () = assert!(N.is_power_of_two() && N <= 256);

    /// An empty ring.
    pub const fn new() -> Self {
        #[allow(clippy::let_unit_value)]
        let () = Self::CHECK;
        Ring {
            buf: [0; N],
            head: 0,
            len: 0,
        }
    }

    /// The capacity `N`.
    pub const fn capacity(&self) -> usize {
        N
    }

    /// Bytes stored.
    pub const fn len(&self) -> usize {
        self.len as usize
    }

    /// True when no byte is stored.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// True when a push would drop.
    pub const fn is_full(&self) -> bool {
        self.len as usize == N
    }

    /// Appends `byte`; returns `false` (and stores nothing) when the ring is full.
    #[inline]
    pub fn push(&mut self, byte: u8) -> bool {
        if self.is_full() {
            return false;
        }
        let idx = (self.head as usize + self.len as usize) & (N - 1);
        if let Some(slot) = self.buf.get_mut(idx) {
            *slot = byte;
        }
        self.len += 1;
        true
    }

    /// Removes and returns the oldest byte.
    #[inline]
    pub fn pop(&mut self) -> Option<u8> {
        if self.is_empty() {
            return None;
        }
        let byte = self.buf.get(self.head as usize & (N - 1)).copied();
        self.head = ((self.head as usize + 1) & (N - 1)) as u8;
        self.len -= 1;
        byte
    }

    /// Drops every stored byte.
    pub fn clear(&mut self) {
        self.head = 0;
        self.len = 0;
    }
}

impl<const N: usize> Default for Ring<N> {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::Ring;

    #[test]
    fn fifo_order_and_wraparound() {
        let mut r = Ring::<8>::new();
        let mut next_in = 0u8;
        let mut next_out = 0u8;
        for round in 0..50 {
            for _ in 0..(round % 8 + 1) {
                if r.push(next_in) {
                    next_in = next_in.wrapping_add(1);
                }
            }
            for _ in 0..(round % 5 + 1) {
                if let Some(b) = r.pop() {
                    assert_eq!(b, next_out);
                    next_out = next_out.wrapping_add(1);
                }
            }
            assert_eq!(r.len(), next_in.wrapping_sub(next_out) as usize);
        }
    }

    #[test]
    fn full_drops_and_empty_pops_none() {
        let mut r = Ring::<4>::new();
        assert_eq!(r.pop(), None);
        for i in 0..4 {
            assert!(r.push(i));
        }
        assert!(r.is_full());
        assert!(!r.push(99));
        assert_eq!(r.pop(), Some(0));
        assert!(r.push(4));
        assert_eq!(
            [r.pop(), r.pop(), r.pop(), r.pop(), r.pop()],
            [Some(1), Some(2), Some(3), Some(4), None]
        );
        r.push(7);
        r.clear();
        assert!(r.is_empty());
    }

    #[test]
    fn capacity_256() {
        let mut r = Ring::<256>::new();
        for i in 0..=255u8 {
            assert!(r.push(i));
        }
        assert!(!r.push(0));
        assert_eq!(r.len(), 256);
        for i in 0..=255u8 {
            assert_eq!(r.pop(), Some(i));
        }
        assert!(r.is_empty());
    }
}
