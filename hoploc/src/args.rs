//! The command line's number parsers (clap value parsers): every number an option takes is
//! checked here, finite and within the range that works, and an error names the range, so a
//! value that cannot work stops the command before it starts (exit code 2, clap's usage error).

use std::fmt::Display;
use std::str::FromStr;

/// A finite number within `lo..=hi` (`open_lo`: above `lo`), or an error naming the range.
pub fn float_in(s: &str, lo: f64, hi: f64, open_lo: bool, unit: &str) -> Result<f64, String> {
    let range = if open_lo {
        format!("above {lo} and at most {hi}{unit}")
    } else {
        format!("within {lo}…{hi}{unit}")
    };
    let v: f64 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number; expected one {range}"))?;
    let ok = v.is_finite() && v <= hi && if open_lo { v > lo } else { v >= lo };
    if ok {
        Ok(v)
    } else {
        Err(format!(
            "`{}` is out of range: expected a number {range}",
            s.trim()
        ))
    }
}

/// An integer within `lo..=hi`, or an error naming the range.
pub fn int_in<T>(s: &str, lo: T, hi: T, unit: &str) -> Result<T, String>
where
    T: FromStr + PartialOrd + Display + Copy,
{
    let range = format!("within {lo}…{hi}{unit}");
    let v: T = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a whole number {range}"))?;
    if lo <= v && v <= hi {
        Ok(v)
    } else {
        Err(format!(
            "`{v}` is out of range: expected a whole number {range}"
        ))
    }
}

/// The longest run or wait the tools take: a year, in seconds.
pub const MAX_SECONDS: f64 = 365.0 * 86_400.0;

/// A duration in seconds: 0.001 s … a year.
pub fn seconds(s: &str) -> Result<f64, String> {
    float_in(s, 0.001, MAX_SECONDS, false, " s")
}

/// A time between live rows, seconds: 0 (every fix) … a day.
pub fn interval(s: &str) -> Result<f64, String> {
    float_in(s, 0.0, 86_400.0, false, " s")
}

/// A pace, simulated seconds per second: 0 (as fast as it goes) … 1000.
pub fn speed(s: &str) -> Result<f64, String> {
    float_in(s, 0.0, 1000.0, false, "")
}

/// A probability: 0…1.
pub fn probability(s: &str) -> Result<f64, String> {
    float_in(s, 0.0, 1.0, false, "")
}

/// A serial baud rate: 300…4 000 000.
pub fn baud(s: &str) -> Result<u32, String> {
    int_in(s, 300, 4_000_000, " baud")
}

/// Worker threads: 1…256.
pub fn threads(s: &str) -> Result<usize, String> {
    int_in(s, 1, 256, " threads")
}

/// A count of estimates: 1…100 000.
pub fn count(s: &str) -> Result<u32, String> {
    int_in(s, 1, 100_000, "")
}

/// The largest room or coordinate the host tools take, metres.
pub const MAX_METRES: f64 = 10_000.0;

/// A room's side, metres: above 0, at most [`MAX_METRES`].
pub fn side_m(s: &str) -> Result<f64, String> {
    float_in(s, 0.0, MAX_METRES, true, " m")
}

/// A coordinate, metres: −[`MAX_METRES`]…[`MAX_METRES`].
pub fn coordinate_m(s: &str) -> Result<f64, String> {
    float_in(s, -MAX_METRES, MAX_METRES, false, " m")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_outside_the_range_say_the_range() {
        for bad in [
            "nan", "NaN", "inf", "-inf", "1e400", "-1", "0", "1e9", "", "x", "1,5",
        ] {
            let e = seconds(bad).unwrap_err();
            assert!(e.contains("0.001…31536000 s"), "{bad}: {e}");
        }
        assert_eq!(seconds("2.5"), Ok(2.5));
        assert_eq!(seconds(" 60 "), Ok(60.0));
        assert_eq!(probability("1"), Ok(1.0));
        assert!(probability("1.0001").unwrap_err().contains("0…1"));
        assert!(probability("-0.1").is_err());
        assert_eq!(side_m("7"), Ok(7.0));
        assert!(side_m("0").unwrap_err().contains("above 0"));
        assert!(baud("0").unwrap_err().contains("300…4000000 baud"));
        assert!(baud("99999999999").unwrap_err().contains("300…4000000"));
        assert_eq!(threads("2"), Ok(2));
        assert!(threads("0").is_err() && threads("-1").is_err());
    }
}
