//! The random sink searches of `search-check` and `search-check2` (shared source).

/// Search `t`'s inputs: observations, model, area, σ (Q.8 dB).
#[inline(never)]
pub fn search_inputs(
    t: u32,
    r: &mut u32,
) -> (
    loc_core::fixed::Observations,
    loc_core::fixed::PathLoss,
    loc_core::fixed::AreaCm,
    u16,
) {
    use loc_core::fixed::{AreaCm, Obs, Observations, PathLoss, PointCm, ALPHA, DB};
    use mcu_bench::fw::xorshift;
    let mut next = || xorshift(r);
    let area = match t % 9 {
        0 => AreaCm::new(100, 100),
        1 => AreaCm::new(6_500, 6_500),
        _ => AreaCm::new(100 + (next() % 3_000) as u16, 100 + (next() % 3_000) as u16),
    };
    let mut obs = Observations::new();
    for k in 0..3 + next() % 6 {
        let (x, y) = (next(), next());
        let pos = match (t + k) % 6 {
            // Area corners.
            0 => PointCm::new(0, 0),
            1 => PointCm::new(area.width as i16, area.height as i16),
            // Outside.
            2 => PointCm::new(-((x % 500) as i16), (y % 9_000) as i16),
            _ => PointCm::new(
                (x % (area.width as u32 + 1)) as i16,
                (y % (area.height as u32 + 1)) as i16,
            ),
        };
        obs.push(Obs {
            pos,
            z: -(30 * DB) - (next() % (60 * DB as u32)) as i32,
            weight: 1 + (x >> 24) as u8 % 4,
        });
    }
    obs.const_cost = next() % 1_000;
    let model = match t % 6 {
        0 => PathLoss {
            p0: -40 * DB,
            alpha: 0,
        },
        1 => PathLoss {
            p0: -40 * DB,
            alpha: 1 + (next() % 64) as i32,
        },
        2 => PathLoss {
            p0: -((next() % (60 * DB as u32)) as i32),
            alpha: -2 * ALPHA,
        },
        _ => PathLoss {
            p0: -(30 * DB) - (next() % (30 * DB as u32)) as i32,
            alpha: ALPHA + (next() % (4 * ALPHA as u32)) as i32,
        },
    };
    let sigma = match t % 5 {
        0 => 0,
        1 => 1,
        2 => u16::MAX,
        _ => (next() % (8 << 8)) as u16,
    };
    (obs, model, area, sigma)
}
