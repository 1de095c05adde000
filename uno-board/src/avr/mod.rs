//! The AVR half of the crate: peripherals, interrupt handlers, the node boot, panic handler.

mod boot;
mod config;
mod eeprom;
mod led;
pub mod libm;
pub mod node;
mod power;
mod radio;
mod serial;
mod time;
mod watchdog;

pub use boot::{boot, Node};
pub use config::load_config;
pub use eeprom::Eeprom;
pub use led::{blink_code, Led};
pub use power::sleep_unless;
pub use radio::{bring_up_radio, write_line, NodeRadio};
pub use serial::{rx_frame_start_us, rx_pending, Serial};
pub use time::{now_ms, now_us, Delay, SysClock};
pub use watchdog::{reset, Watchdog};

/// The embedded-hal traits the board's types implement, for `use uno_board::prelude::*;`.
pub mod prelude {
    pub use embedded_hal::delay::DelayNs as _;
    pub use embedded_hal::digital::{OutputPin as _, StatefulOutputPin as _};
    pub use embedded_hal_nb::serial::{Read as _, Write as _};
}

/// The data-space address of a PAC peripheral's register block, for assembly operands.
pub(crate) trait BlockAddr {
    /// The address of the block's first register.
    const ADDR: usize;
}

impl<RB, const A: usize> BlockAddr for avr_device::generic::Periph<RB, A> {
    const ADDR: usize = A;
}

/// Data-space address of I/O address 0 (`in`, `out`, `sbi` and `cbi` take I/O addresses).
pub(crate) const IO_BASE: usize = 0x20;

/// The PAC, for peripherals uno-board does not wrap yet.
pub use avr_device::atmega328p as pac;
/// The entry-point attribute (`#[uno_board::entry] fn main() -> ! { … }`).
pub use avr_device::entry;

// For builds without LTO, where upstream native libraries precede compiler-builtins; with LTO
// only the binary's own `link_avr_libc!()` is early enough (see there).
#[link(name = "m")]
#[link(name = "c")]
#[link(name = "gcc")]
extern "C" {}

/// Links avr-libc (`-lm -lc`) and libgcc into the calling binary, ahead of compiler-builtins.
///
/// Invoke it once at the top level of every AVR binary (each `*-fw` main.rs does). The native
/// libraries of the binary crate itself are the only ones the linker sees before
/// compiler-builtins (with LTO, those of upstream crates such as this one come after it), and
/// compiler-builtins exports slower and larger versions of the same symbols, which would win:
/// avr-libc's and libgcc's hand-written `__udivmodsi4`, `memcpy`/`memmove`/`memset` and `f32`
/// arithmetic are much smaller and faster (`docs/design.md`, section 7).
#[macro_export]
macro_rules! link_avr_libc {
    () => {
        #[link(name = "m")]
        #[link(name = "c")]
        #[link(name = "gcc")]
        extern "C" {}
    };
}

/// Everything on the board, configured: USART0 at 57600 8N1 with RX interrupts, the 1 ms tick,
/// LED off, idle sleep mode selected, watchdog off, interrupts enabled. A node firmware takes it
/// through [`boot`].
pub struct Board {
    /// USART0 (D0/D1): the XBee and the USB serial.
    pub serial: Serial,
    /// The LED on D13.
    pub led: Led,
    /// The 1 KB EEPROM.
    pub eeprom: Eeprom,
    /// The watchdog (off until [`Watchdog::start`]).
    pub watchdog: Watchdog,
    /// The millisecond clock.
    pub clock: SysClock,
    /// Delays on the millisecond clock.
    pub delay: Delay,
}

impl Board {
    /// Takes the peripherals and sets the board up; `None` if called a second time.
    ///
    /// Call it first thing in `main`: after a watchdog reset the watchdog is still running with
    /// its shortest timeout, and this turns it off.
    pub fn take() -> Option<Board> {
        let dp = pac::Peripherals::take()?;
        let watchdog = Watchdog::init(dp.WDT, &dp.CPU);
        let led = Led::init(dp.PORTB);
        time::init(&dp.TC0);
        let serial = Serial::init(dp.USART0);
        power::init(&dp.CPU);
        // SAFETY: every shared state the interrupt handlers touch is initialised above (statics
        // are const-initialised; the peripherals are configured), so enabling interrupts is sound.
        unsafe { avr_device::interrupt::enable() };
        Some(Board {
            serial,
            led,
            eeprom: Eeprom::new(dp.EEPROM),
            watchdog,
            clock: SysClock,
            delay: Delay,
        })
    }
}

/// Panic: reset the MCU through the watchdog (16 ms). No formatting, no message.
#[cfg(feature = "panic-reset")]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    reset()
}
