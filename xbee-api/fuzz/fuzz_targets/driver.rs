//! The driver's stream path with arbitrary radio output: polling, AT commands, channel switching,
//! config read-out and bring-up must never panic or hang, whatever the radio sends.
#![no_main]

use std::cell::Cell;
use std::convert::Infallible;
use std::rc::Rc;

use embedded_hal_nb::serial::{ErrorType, Read, Write};
use libfuzzer_sys::fuzz_target;
use xbee_api::driver::{BringUpConfig, Clock, Encryption, Radio, SetBaud};
use xbee_api::Mode;

/// Serves the fuzz input as the radio's output; every empty read moves time on by 1 ms.
struct Line<'a> {
    input: &'a [u8],
    time: Rc<Cell<u32>>,
}

impl ErrorType for Line<'_> {
    type Error = Infallible;
}

impl Read<u8> for Line<'_> {
    fn read(&mut self) -> nb::Result<u8, Infallible> {
        match self.input.split_first() {
            // 0xFF 0xFF in the input stands for a pause in the radio's output.
            Some((&0xFF, rest)) if rest.first() == Some(&0xFF) => {
                self.input = &rest[1..];
                self.time.set(self.time.get().wrapping_add(25));
                Err(nb::Error::WouldBlock)
            }
            Some((&b, rest)) => {
                self.input = rest;
                Ok(b)
            }
            None => {
                self.time.set(self.time.get().wrapping_add(1));
                Err(nb::Error::WouldBlock)
            }
        }
    }
}

impl Write<u8> for Line<'_> {
    fn write(&mut self, _: u8) -> nb::Result<(), Infallible> {
        Ok(())
    }
    fn flush(&mut self) -> nb::Result<(), Infallible> {
        Ok(())
    }
}

impl SetBaud for Line<'_> {
    fn set_baud(&mut self, _: u32) {}
}

struct SharedClock(Rc<Cell<u32>>);

impl Clock for SharedClock {
    fn now_ms(&mut self) -> u32 {
        self.0.get()
    }
}

fuzz_target!(|input: &[u8]| {
    let Some((&ctl, bytes)) = input.split_first() else {
        return;
    };
    let time = Rc::new(Cell::new(u32::MAX - 500 + (ctl as u32 & 0x0F))); // crosses the wrap
    let line = Line { input: bytes, time: time.clone() };
    let mode = if ctl & 0x10 == 0 { Mode::Api } else { Mode::Escaped };
    let mut radio = Radio::new(line, SharedClock(time.clone()), mode);
    let mut frames = 0u32;
    match ctl >> 5 {
        0 | 1 => {
            // Receive loop: must end once the input is used up.
            let mut calls = 0u32;
            loop {
                calls += 1;
                assert!(calls < 100_000, "poll never returned None");
                match radio.poll(|raw| raw.parse().is_ok()) {
                    Some(Ok(_)) => frames += 1,
                    Some(Err(_)) => {}
                    None if radio.serial_mut().input.is_empty() => break,
                    None => {}
                }
            }
            // Every frame the decoder accepted reached the caller.
            assert_eq!(radio.stats().decoder.frames, frames);
        }
        2 => {
            let _ = radio.at_command(*b"MY", &[], 50, |_| frames += 1);
        }
        3 => {
            let _ = radio.send_tx16(0xFFFF, b"beacon");
            let _ = radio.set_channel(0x0C, 40, |_| frames += 1);
        }
        4 => {
            let _ = radio.read_config(30, |_| frames += 1);
        }
        sel => {
            let cfg = BringUpConfig {
                my: Some(1),
                pan_id: Some(0x3332),
                channel: Some(0x0B),
                encryption: match sel {
                    5 => Encryption::Leave,
                    6 => Encryption::Off,
                    _ => Encryption::Key([0x7E; 16]),
                },
                guard_ms: 15,
                timeout_ms: 20,
            };
            let _ = radio.bring_up(&cfg);
        }
    }
    // Every wait is bounded by the clock: a run never takes more than a few seconds of radio time.
    assert!(time.get().wrapping_sub(u32::MAX - 500) < 600_000);
});
