//! USART baud-rate arithmetic (portable, unit-tested on the host).
//!
//! The board always runs USART0 in double-speed mode (U2X0 = 1), where the bit rate is
//! `F_CPU / (8 · (UBRR + 1))`. With a 16 MHz crystal this gives the smallest error for every
//! rate the XBee supports (Arduino's core does the same):
//!
//! | baud   | UBRR0 | actual bit/s | error   |
//! |--------|-------|--------------|---------|
//! | 9600   | 207   | 9615.4       | +0.16 % |
//! | 19200  | 103   | 19230.8      | +0.16 % |
//! | 38400  | 51    | 38461.5      | +0.16 % |
//! | 57600  | 34    | 57142.9      | −0.79 % |
//! | 115200 | 16    | 117647.1     | +2.12 % |
//!
//! 57600 (the XBee's `BD=6`, the testbed's rate) is −0.79 %, well inside the ±2 % a receiver
//! tolerates at 8N1; 115200 at +2.1 % works in practice (it is what the Uno bootloader uses), but
//! is marginal against a peer that is itself off in the other direction.
//!
//! simavr computes its byte time when UBRR0 is written, so U2X0 must be set *before* UBRR0
//! (uno-board does so).

/// CPU clock of the Uno.
pub const F_CPU: u32 = 16_000_000;

/// The rates [`ubrr_u2x`] is meant for (the XBee 802.15.4 `BD` values 3…7).
pub const SUPPORTED: [u32; 5] = [9600, 19200, 38400, 57600, 115200];

/// The UBRR value for `baud` in double-speed mode (U2X = 1), rounded to the nearest divisor, or
/// `None` if the rate is out of reach of the 12-bit register (or zero).
pub const fn ubrr_u2x(f_cpu: u32, baud: u32) -> Option<u16> {
    if baud == 0 {
        return None;
    }
    // round(f_cpu / (8 * baud)) - 1, in integers: ceil(floor(f_cpu / 4 / baud) / 2) is that
    // rounding exactly, with one division and no `8 * baud` to overflow.
    let div = (f_cpu / 4 / baud).div_ceil(2);
    if div == 0 || div > 4096 {
        return None;
    }
    Some((div - 1) as u16)
}

/// The bit rate that UBRR value `ubrr` really produces in double-speed mode.
pub const fn actual_baud_u2x(f_cpu: u32, ubrr: u16) -> u32 {
    f_cpu / (8 * (ubrr as u32 + 1))
}

/// Error of the real rate against the requested one, in tenths of a percent (rounded toward zero).
pub const fn error_permille(f_cpu: u32, baud: u32, ubrr: u16) -> i32 {
    let actual = actual_baud_u2x(f_cpu, ubrr) as i64;
    ((actual - baud as i64) * 1000 / baud as i64) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_matches_doc() {
        let expect = [
            (9600, 207, 1),
            (19200, 103, 1),
            (38400, 51, 1),
            (57600, 34, -7),
            (115200, 16, 21),
        ];
        for (baud, ubrr, permille) in expect {
            let u = ubrr_u2x(F_CPU, baud).unwrap();
            assert_eq!(u, ubrr, "{baud}");
            assert_eq!(error_permille(F_CPU, baud, u), permille, "{baud}");
        }
    }

    #[test]
    fn every_supported_rate_within_2_5_percent() {
        for baud in SUPPORTED {
            let u = ubrr_u2x(F_CPU, baud).unwrap();
            assert!(error_permille(F_CPU, baud, u).abs() <= 25, "{baud}");
        }
    }

    #[test]
    fn rounds_to_the_nearest_divisor() {
        // Against the definition in 64-bit arithmetic, over every rate up to 2.1 Mbit/s in steps
        // that hit each divisor's rounding boundaries, and a few clocks.
        for f_cpu in [F_CPU, 8_000_000, 20_000_000] {
            for baud in (1..2_100_000u32)
                .step_by(7)
                .chain([u32::MAX, 1 << 29, (1 << 29) + 1])
            {
                let div = (f_cpu as u64 + 4 * baud as u64) / (8 * baud as u64);
                let want = (div != 0 && div <= 4096).then(|| (div - 1) as u16);
                assert_eq!(ubrr_u2x(f_cpu, baud), want, "{f_cpu} {baud}");
            }
        }
    }

    #[test]
    fn out_of_range() {
        assert_eq!(ubrr_u2x(F_CPU, 0), None);
        assert_eq!(ubrr_u2x(F_CPU, 10), None); // needs a divisor > 4096
        assert_eq!(ubrr_u2x(F_CPU, 5_000_000), None); // rounds to a zero divisor
        assert_eq!(ubrr_u2x(F_CPU, 2_000_000), Some(0));
    }
}
