//! USART baud-rate arithmetic (portable, unit-tested on the host).
//!
//! The board always runs USART0 in double-speed mode (U2X0 = 1), where the bit rate is
//! `F_CPU / (8 · (UBRR + 1))`. With a 16 MHz crystal this gives, for every rate the XBee S1 runs
//! (`BD` 0…7):
//!
//! | `BD` | S1 rate | UBRR0 | actual bit/s | error   |
//! |------|---------|-------|--------------|---------|
//! | 0    | 1200    | 1666  | 1199.8       | −0.02 % |
//! | 1    | 2400    | 832   | 2400.96      | +0.04 % |
//! | 2    | 4800    | 416   | 4796.2       | −0.08 % |
//! | 3    | 9600    | 207   | 9615.4       | +0.16 % |
//! | 4    | 19200   | 103   | 19230.8      | +0.16 % |
//! | 5    | 38400   | 51    | 38461.5      | +0.16 % |
//! | 6    | 57600   | 34    | 57142.9      | −0.79 % |
//! | 7    | 111 111 | 17    | 111 111.1    | 0       |
//!
//! 57600 (`BD=6`, the testbed's rate) is −0.79 %, well inside the ±2 % a receiver tolerates at
//! 8N1. `BD=7` is named 115200, but the S1 runs it at 111 111 bit/s (Digi's manual): the Uno's
//! nearest divisor for 115200 (UBRR0 16, 117 647 bit/s) is 5.9 % from it, beyond what two UARTs
//! tolerate together, while 111 111 is exact with UBRR0 17.
//!
//! simavr computes its byte time when UBRR0 is written, so U2X0 must be set *before* UBRR0
//! (uno-board does so).

/// CPU clock of the Uno.
pub const F_CPU: u32 = 16_000_000;

/// The rates [`ubrr_u2x`] is meant for: the XBee S1's, `BD` 0…7 (7 at the 111 111 bit/s the S1 runs).
pub const SUPPORTED: [u32; 8] = [1200, 2400, 4800, 9600, 19200, 38400, 57600, 111_111];

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
            (111_111, 17, 0),
            (115200, 16, 21),
            (1200, 1666, 0),
            (2400, 832, 0),
            (4800, 416, 0),
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
