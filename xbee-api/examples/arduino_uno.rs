//! An arduino-hal firmware for an Arduino Uno with an XBee 802.15.4 (Series 1) radio on its
//! UART (pins 0 and 1): it brings the radio up, broadcasts a beacon every second, and lights the
//! LED on pin 13 while the last frame it heard came in stronger than −60 dBm.
//!
//! What it takes from outside the driver:
//!
//! * the UART: arduino-hal's `Usart`, which implements the embedded-hal **0.2** serial traits,
//!   wrapped in [`xbee_api::serial::Eh02`] (feature `embedded-hal-02`) for the driver's
//!   embedded-hal-nb 1.0 ones;
//! * [`SetBaud`](xbee_api::driver::SetBaud), for bring-up to look for the radio at each baud
//!   rate: arduino-hal has no call that changes a running `Usart`'s rate, so [`set_baud`] sets
//!   the USART0 registers the way `Usart::new` does, and [`WithBaud`] hands it to the driver;
//! * a millisecond [`Clock`](xbee_api::driver::Clock): arduino-hal has none either, so
//!   [`millis`] counts timer TC0's 1 ms compare-match interrupts (as avr-hal's `uno-millis`
//!   example does), and [`FnClock`] makes the function a clock.
//!
//! On the Uno this file is the whole firmware: a crate with `arduino-hal` (from avr-hal, feature
//! `arduino-uno`), `avr-device`, `panic-halt` and `xbee-api` (feature `embedded-hal-02`) as
//! dependencies, built with `-Z build-std=core --target avr-none -C target-cpu=atmega328p` on a
//! nightly toolchain. Everything AVR-only below is behind `cfg(target_arch = "avr")`.
//!
//! Elsewhere (`cargo build --example arduino_uno --features embedded-hal-02`, which `cargo test`
//! does too) it compiles against `avr-stand-in/`, a host stand-in for the few items of
//! arduino-hal and avr-device it uses, with the same names and trait shapes (the `Usart`
//! implements the embedded-hal 0.2 serial traits with `Infallible` errors, as arduino-hal's
//! does). avr-hal is not on crates.io, so the crate's tests cannot build against it: the
//! stand-in keeps this firmware compiling; it does not run on the host.
#![cfg_attr(target_arch = "avr", no_std, no_main, feature(abi_avr_interrupt))]

#[cfg(not(target_arch = "avr"))]
#[path = "avr-stand-in/mod.rs"]
mod avr_stand_in;
#[cfg(not(target_arch = "avr"))]
use avr_stand_in::{arduino_hal, avr_device};
#[cfg(target_arch = "avr")]
use panic_halt as _;

use core::cell::Cell;

use arduino_hal::usart::{Baudrate, UsartOps};
use xbee_api::driver::{BringUpConfig, FnClock, Radio, BAUD};
use xbee_api::serial::{Eh02, WithBaud};
use xbee_api::Mode;

/// The Uno's UART 0 on pins 0 (RX) and 1 (TX), as arduino-hal types it.
type Serial = arduino_hal::hal::usart::Usart0<arduino_hal::DefaultClock>;

// The millisecond clock: TC0 in CTC mode, prescaler 64, 250 counts: a compare match every
// 1 ms at 16 MHz.
const PRESCALER: u32 = 64;
const TIMER_COUNTS: u32 = 250;
const MILLIS_INCREMENT: u32 = PRESCALER * TIMER_COUNTS / 16_000;

static MILLIS_COUNTER: avr_device::interrupt::Mutex<Cell<u32>> =
    avr_device::interrupt::Mutex::new(Cell::new(0));

fn millis_init(tc0: arduino_hal::pac::TC0) {
    tc0.tccr0a().write(|w| w.wgm0().ctc());
    tc0.ocr0a().write(|w| w.set((TIMER_COUNTS - 1) as u8));
    tc0.tccr0b().write(|w| w.cs0().prescale_64());
    tc0.timsk0().write(|w| w.ocie0a().set_bit());
}

#[cfg_attr(target_arch = "avr", avr_device::interrupt(atmega328p))]
#[cfg_attr(not(target_arch = "avr"), allow(non_snake_case, dead_code))]
fn TIMER0_COMPA() {
    avr_device::interrupt::free(|cs| {
        let counter = MILLIS_COUNTER.borrow(cs);
        counter.set(counter.get().wrapping_add(MILLIS_INCREMENT));
    })
}

/// Milliseconds since `millis_init`; wraps after 49 days, which the driver allows for.
fn millis() -> u32 {
    avr_device::interrupt::free(|cs| MILLIS_COUNTER.borrow(cs).get())
}

/// Switches USART0 to `baud` bit/s: what `Usart::new` does with its `Baudrate` (the UBRR0
/// divisor, U2X0, 8N1), on the register block the `Usart` owns. Bring-up calls it only while
/// the UART has nothing left to send; the `flush` makes sure.
fn set_baud(serial: &mut Eh02<Serial>, baud: u32) {
    serial.0.flush();
    // SAFETY: only the baud rate registers change, between two bytes, and the `Usart` keeps
    // working with the new rate.
    let mut usart0 = unsafe { arduino_hal::pac::USART0::steal() };
    usart0.raw_init(Baudrate::<arduino_hal::DefaultClock>::new(baud));
}

#[cfg_attr(target_arch = "avr", arduino_hal::entry)]
fn main() -> ! {
    let dp = arduino_hal::Peripherals::take().unwrap();
    let pins = arduino_hal::pins!(dp);
    let mut led = pins.d13.into_output();
    let usart = arduino_hal::Usart::new(
        dp.USART0,
        pins.d0,
        pins.d1.into_output(),
        Baudrate::new(BAUD),
    );
    millis_init(dp.TC0);
    // SAFETY: the interrupt handler above is the only one, and it shares nothing but
    // `MILLIS_COUNTER`, behind its mutex.
    unsafe { avr_device::interrupt::enable() };

    let serial = WithBaud::new(Eh02(usart), set_baud);
    let mut radio = Radio::new(serial, FnClock(millis), Mode::Escaped);
    // Finds the radio at any baud rate and in any mode, leaves it in API mode 2 at 57600 (written
    // to its flash only if that had to change), then sets these registers.
    let config = BringUpConfig {
        my: Some(0x0001),
        pan_id: Some(0x3332),
        channel: Some(0x0C),
        ..BringUpConfig::new()
    };
    if let Err(e) = radio.bring_up(&config) {
        // Blink the error's code (1…12) for ever.
        loop {
            for _ in 0..e.code() {
                led.set_high();
                arduino_hal::delay_ms(200);
                led.set_low();
                arduino_hal::delay_ms(300);
            }
            arduino_hal::delay_ms(1500);
        }
    }

    let mut last_beacon = millis();
    loop {
        if millis().wrapping_sub(last_beacon) >= 1000 {
            last_beacon = millis();
            // A UART that takes no byte for 100 ms is the only failure here: try again later.
            let _ = radio.send_tx16(0xFFFF, b"beacon");
        }
        // One received frame at most per call; `None` when the UART has nothing more.
        match radio.poll(|raw| raw.rx16().map(|rx| rx.rssi.dbm())) {
            Some(Ok(Some(dbm))) if dbm > -60 => led.set_high(),
            Some(Ok(Some(_))) => led.set_low(),
            // A TX status or another frame type; or line noise, counted in `radio.stats()`.
            Some(Ok(None)) | Some(Err(_)) | None => {}
        }
    }
}
