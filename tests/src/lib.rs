//! Helpers for the firmware-in-simavr tests in `tests/`: the real node ELFs (built by `cargo fw`,
//! built here if missing) and the board's LED as the simulator sees it.

use std::path::PathBuf;
use std::sync::Mutex;

use hoploc::firmware::{self, Role};
use simavr::Avr;

/// Data-space address of PORTB; the Uno's LED is PB5 (D13).
pub const PORTB: usize = 0x25;
/// The LED's bit in PORTB.
pub const LED_BIT: u8 = 1 << 5;

static BUILD: Mutex<()> = Mutex::new(());

/// The ELF of `role`'s firmware (`target/avr-none/fw/<role>-fw.elf`), running `cargo fw` first if
/// it is missing. Panics with the reason if it cannot be had: a firmware test never skips.
pub fn firmware_elf(role: Role) -> PathBuf {
    let _guard = BUILD.lock().unwrap_or_else(|e| e.into_inner());
    let dir = firmware::default_dir();
    firmware::ensure_built(&dir).unwrap_or_else(|e| panic!("firmware: {e}"));
    firmware::elf(&dir, role)
}

/// `role`'s firmware loaded into a fresh simulated Uno.
pub fn boot(role: Role) -> Avr {
    let elf = firmware_elf(role);
    Avr::load(&elf).unwrap_or_else(|e| panic!("{}: {e}", elf.display()))
}

/// Whether the LED is on.
pub fn led_on(avr: &Avr) -> bool {
    avr.data().get(PORTB).is_some_and(|&v| v & LED_BIT != 0)
}
