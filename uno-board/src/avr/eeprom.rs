//! The 1 KB EEPROM: reads, and verified writes that skip unchanged bytes.

use super::pac::EEPROM;
use super::{BlockAddr, IO_BASE};
use crate::{eeprom_range, EepromError};
use core::arch::asm;

/// EECR's I/O address (for `sbi`): EECR is the first register of the PAC's EEPROM block.
const EECR_IO: usize = <EEPROM as BlockAddr>::ADDR - IO_BASE;
/// EECR bit: EEPROM master write enable (opens the four-cycle window for EEPE).
const EEMPE: u8 = 2;
/// EECR bit: EEPROM write enable (starts the erase + write).
const EEPE: u8 = 1;

/// The ATmega328P's EEPROM. A byte write takes ~3.4 ms and blocks; writes only touch bytes whose
/// value changes (the cells last ~100 000 writes).
pub struct Eeprom {
    ee: EEPROM,
}

impl Eeprom {
    pub(crate) fn new(ee: EEPROM) -> Eeprom {
        Eeprom { ee }
    }

    fn wait_ready(&self) {
        while self.ee.eecr().read().eepe().bit_is_set() {}
    }

    fn read_at(&self, addr: u16) -> u8 {
        self.wait_ready();
        self.ee.eear().write(|w| w.set(addr));
        self.ee.eecr().write(|w| w.eere().set_bit());
        self.ee.eedr().read().bits()
    }

    /// Writes `value` (erase + write), unconditionally, at the address [`Eeprom::read_at`] has
    /// just read: that read waited for the EEPROM and set EEAR, so neither is done again.
    fn program_read(&mut self, value: u8) {
        // The watchdog may be running: each write is bounded (~3.4 ms), so progress is not a hang.
        avr_device::asm::wdr();
        self.ee.eedr().write(|w| w.set(value));
        avr_device::interrupt::free(|_| {
            // SAFETY: the datasheet's timed sequence: EEMPE then, within four cycles, EEPE, with
            // interrupts off. EEPM1:0 are 0 (erase + write).
            unsafe {
                asm!(
                    "sbi {eecr}, {eempe}",
                    "sbi {eecr}, {eepe}",
                    eecr = const EECR_IO,
                    eempe = const EEMPE,
                    eepe = const EEPE,
                    options(nostack),
                )
            };
        });
    }

    /// Writes `data` from `addr` (only the bytes that change) and reads each byte back: `false`
    /// if one did not take its value (a worn-out cell) or the range is not in the EEPROM. One
    /// read per byte, and one more after a write: one read site.
    pub fn write_verified(&mut self, addr: u16, data: &[u8]) -> bool {
        if eeprom_range(addr, data.len()).is_err() {
            return false;
        }
        for (a, &b) in (addr..).zip(data.iter()) {
            let mut written = false;
            while self.read_at(a) != b {
                if written {
                    return false;
                }
                self.program_read(b);
                written = true;
            }
        }
        true
    }

    /// Fills `buf` from the bytes starting at `addr`.
    pub fn read(&self, addr: u16, buf: &mut [u8]) -> Result<(), EepromError> {
        eeprom_range(addr, buf.len())?;
        for (a, b) in (addr..).zip(buf.iter_mut()) {
            *b = self.read_at(a);
        }
        Ok(())
    }
}
