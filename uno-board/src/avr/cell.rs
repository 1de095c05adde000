//! State shared between interrupt handlers and the main program.

use core::cell::UnsafeCell;

/// A value accessed only inside critical sections.
///
/// Unlike `Mutex<RefCell<T>>` there is no borrow flag and no panic path (which would cost flash
/// and SRAM for the panic location); instead the closures passed to [`IrqCell::with`] must never
/// call `with` on the same cell again. All uses are small leaf closures inside this crate.
pub(crate) struct IrqCell<T>(UnsafeCell<T>);

// SAFETY: the ATmega328P has one core and does not nest interrupts; every access goes through
// `with`, which runs with interrupts disabled, so no two accesses to the value can overlap.
unsafe impl<T: Send> Sync for IrqCell<T> {}

impl<T> IrqCell<T> {
    pub(crate) const fn new(value: T) -> Self {
        IrqCell(UnsafeCell::new(value))
    }

    /// Runs `f` on the value with interrupts disabled (restoring the previous interrupt state).
    #[inline(always)]
    pub(crate) fn with<R>(&self, f: impl FnOnce(&mut T) -> R) -> R {
        avr_device::interrupt::free(|_| {
            // SAFETY: interrupts are off and `f` does not re-enter `with` on this cell (see the
            // type docs), so this is the only reference to the value while `f` runs.
            f(unsafe { &mut *self.0.get() })
        })
    }
}
