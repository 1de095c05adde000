//! `report-check`'s random reports, drawn alike on the MCU and on the host: the firmware runs
//! `uno_board::AvrFit`'s report routine on each and prints a digest of the results, the host
//! (`tests/tests/report_check.rs`) computes `loc_core::fixed::portable_report_inputs` on the same
//! reports and compares. The reference runs on the host: LLVM-AVR was seen to miscompile the
//! portable twin's pair loop inside the check firmware (samples lost, the count changing with
//! unrelated code), where the host's build is held to the generic path by sink-fw's tests.

use core::hash::{Hash, Hasher};
use loc_core::fixed::{AreaCm, CalStats, Obs, Observations, PointCm, ReportBytes};

/// Reports drawn.
pub const REPORTS: u32 = 3_000;
/// The generator's seed.
pub const SEED: u32 = 0x9E37_79B9;

/// One report and what its results are added to.
#[derive(Clone, Copy, Debug)]
pub struct Case {
    /// The bytes: `start` of a header (anything), then the report's (8 anchors, 4 channels and
    /// the relay bytes fit).
    pub buf: [u8; 13 + 4 * 8 + 4 * 8 * 8],
    /// Where the first position is (0–13).
    pub start: u8,
    /// How many of them the report passes (sometimes one short of its layout).
    pub len: usize,
    /// Anchors (0–8, sometimes 9).
    pub n: u8,
    /// Channels (1–4, sometimes 0 or 5).
    pub c: u8,
    /// Whether the relay bytes are there.
    pub relay: bool,
    /// The sums to add to (none, some, or nearly 256 samples).
    pub stats: CalStats,
    /// The observations to add to (none, some, or nearly full; `const_cost` sometimes near its
    /// top).
    pub obs: Observations,
    /// The area to widen (none, or anything).
    pub area: AreaCm,
}

impl Case {
    /// The report.
    pub fn bytes(&self) -> ReportBytes<'_> {
        ReportBytes {
            bytes: &self.buf[..self.len],
            start: self.start,
            anchors: self.n,
            channels: self.c,
            relay: self.relay,
        }
    }
}

/// xorshift32 ([`crate::rng::xorshift`]) over the caller's seed.
struct Rng<'a>(&'a mut u32);

impl Rng<'_> {
    fn next(&mut self) -> u32 {
        crate::rng::xorshift(self.0)
    }

    fn below(&mut self, n: u32) -> u32 {
        self.next() % n
    }

    /// A value in `[lo, hi]`.
    fn range(&mut self, lo: i32, hi: i32) -> i32 {
        lo.wrapping_add(self.below(hi.wrapping_sub(lo) as u32 + 1) as i32)
    }

    fn pick<T: Copy>(&mut self, v: &[T]) -> T {
        v[self.below(v.len() as u32) as usize]
    }

    fn byte(&mut self, base: u8) -> u8 {
        match self.below(8) {
            0 | 1 => 0,
            2 => self.pick(&[1, 255, 254, 128]),
            3 => self.next() as u8,
            _ => base.wrapping_add(self.below(12) as u8),
        }
    }
}

/// The next report of the generator at `seed` into `case`.
#[inline(never)]
pub fn draw(seed: &mut u32, case: &mut Case) {
    let mut r = Rng(seed);
    let n = match r.below(16) {
        0 => r.pick(&[0u8, 1, 2, 9]),
        _ => r.range(3, 8) as u8,
    };
    let c = match r.below(16) {
        0 => r.pick(&[0u8, 5]),
        _ => r.range(1, 4) as u8,
    };
    let relay = r.below(5) != 0;
    let rows = if relay { n as usize } else { 1 };
    let mut len = 4 * n as usize + c as usize * n as usize * rows;
    if r.below(16) == 0 && len > 0 {
        len -= 1;
    }
    let start = r.pick(&[0u8, 1, 10, 13]);
    // (9 anchors or 5 channels are refused whatever the length.)
    case.len = (start as usize + len).min(case.buf.len());
    case.start = start;
    (case.n, case.c, case.relay) = (n, c, relay);
    // Positions: anywhere, the i16 extremes, 1 cm from (or on) the previous one, a room.
    let style = r.below(4);
    let (head, buf) = case.buf.split_at_mut(start as usize);
    for b in head.iter_mut() {
        *b = r.next() as u8;
    }
    for k in 0..(n as usize).min(8) {
        let (x, y) = match style {
            0 => (r.next() as i16, r.next() as i16),
            1 => (
                r.pick(&[i16::MIN, i16::MAX, 0, -1, 1, i16::MIN + 1]),
                r.pick(&[i16::MIN, i16::MAX, 0, -1]),
            ),
            2 if k > 0 && r.below(2) == 0 => {
                let at = 4 * (k - 1);
                let px = i16::from_le_bytes([buf[at], buf[at + 1]]);
                let py = i16::from_le_bytes([buf[at + 2], buf[at + 3]]);
                (
                    px.wrapping_add(r.range(-1, 1) as i16),
                    py.wrapping_add(r.range(-1, 1) as i16),
                )
            }
            _ => (r.range(-100, 2000) as i16, r.range(-100, 2000) as i16),
        };
        buf[4 * k..4 * k + 2].copy_from_slice(&x.to_le_bytes());
        buf[4 * k + 2..4 * k + 4].copy_from_slice(&y.to_le_bytes());
    }
    let base = r.range(30, 90) as u8;
    let start = (4 * n as usize).min(buf.len());
    for b in buf[start..].iter_mut() {
        *b = r.byte(base);
    }
    // The sums to add to.
    let mut s = CalStats::new();
    let pushes = match r.below(4) {
        0 | 1 => 0,
        2 => r.range(1, 3),
        _ => 4,
    };
    let fill = [Some(r.pick(&[1u8, 255, 60])); 64];
    for k in 0..pushes {
        let len = if pushes == 4 && k < 3 {
            64
        } else {
            r.range(1, 64) as usize
        };
        s.push_at(r.range(-(20 << 18), 20 << 18), &fill[..len]);
    }
    case.stats = s;
    // The observations to add to.
    let mut o = Observations::new();
    let k = match r.below(4) {
        0 | 1 => 0,
        2 => r.range(1, 8),
        _ => r.range(6, 8),
    };
    for _ in 0..k {
        o.push(Obs {
            pos: PointCm::new(r.next() as i16, r.next() as i16),
            z: r.next() as i32,
            weight: r.range(1, 4) as u8,
        });
    }
    o.const_cost = match r.below(4) {
        0 => u32::MAX - r.below(200_000),
        1 => r.next(),
        _ => 0,
    };
    case.obs = o;
    case.area = match r.below(4) {
        0 => AreaCm::new(r.next() as u16, r.next() as u16),
        1 => AreaCm::new(r.range(0, 2000) as u16, r.range(0, 2000) as u16),
        _ => AreaCm::new(0, 0),
    };
}

/// FNV-1a over the bytes `Hash` feeds it, `usize` as `u16` (the same on the AVR and the host).
struct Fnv(u32);

impl Hasher for Fnv {
    fn finish(&self) -> u64 {
        self.0 as u64
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ b as u32).wrapping_mul(0x0100_0193);
        }
    }

    fn write_usize(&mut self, i: usize) {
        self.write(&(i as u16).to_le_bytes());
    }
}

/// What the firmware prints of a report's results: a hash of every field of the sums, one of
/// every field of the observations (the unused slots too), the sample count, the observation
/// count, `const_cost` and the area (width in the high half).
pub fn digest(stats: &CalStats, obs: &Observations, area: &AreaCm) -> [u32; 6] {
    let mut h = Fnv(0x811C_9DC5);
    stats.hash(&mut h);
    let mut g = Fnv(0x811C_9DC5);
    obs.hash(&mut g);
    [
        h.0,
        g.0,
        stats.len() as u32,
        obs.len() as u32,
        obs.const_cost,
        (area.width as u32) << 16 | area.height as u32,
    ]
}
