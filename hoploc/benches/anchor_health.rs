//! The anchor health check (`hoploc::health`) on synthetic rooms (`hoploc::health::synthetic`):
//! its false alarms and its detection rates. Per layout and medium, `ROOMS` rooms (seeds: each
//! its own fading and shadowing) with every anchor where it is configured count the rooms that
//! flag an anchor; then anchor 3 (configured at the corner (10, 10)) stands elsewhere, moved
//! by each distance towards the room's centre and along the wall, in the same rooms: the share
//! of rooms that flag anchor 3, those that flag another anchor, and the median error of the
//! reported offset. The check assumes the room's fading (`HealthConfig::fading_db`), a window
//! of 50 reports, the default threshold; a last row per layout has a room with more fading
//! than the check assumes (false alarms only). Prints a table; not a timed test.
//! `cargo bench -p hoploc --bench anchor_health`; `HOPLOC_HEALTH_ROOMS` sets the number of rooms,
//! `HOPLOC_HEALTH_LAYOUT` (0, 1 or 2) runs one layout only.

use std::time::Instant;

use hoploc::health::synthetic::Room;
use hoploc::health::{Health, HealthConfig};

const ROOM10: [(f64, f64); 4] = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)];

/// What one room gave: the flagged anchor (the first the rule found) and its offset, m.
type Verdict = Option<(u8, f64)>;

fn verdict(room: &Room, cfg: HealthConfig, seed: u64) -> Verdict {
    let mut h = Health::new(cfg);
    for r in room.reports(cfg.window, seed) {
        h.push(&r);
    }
    h.assess().flags.first().map(|f| (f.id, f.test.offset_m))
}

/// Every room's verdict, on two threads.
fn verdicts(room: &Room, cfg: HealthConfig, rooms: u64) -> Vec<Verdict> {
    let half = rooms / 2;
    std::thread::scope(|s| {
        let a = s.spawn(|| (0..half).map(|k| verdict(room, cfg, k)).collect::<Vec<_>>());
        let mut b: Vec<Verdict> = (half..rooms).map(|k| verdict(room, cfg, k)).collect();
        let mut v = a.join().expect("thread");
        v.append(&mut b);
        v
    })
}

fn main() {
    let rooms: u64 = std::env::var("HOPLOC_HEALTH_ROOMS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(500);
    let t0 = Instant::now();
    let only: Option<usize> = std::env::var("HOPLOC_HEALTH_LAYOUT")
        .ok()
        .and_then(|v| v.parse().ok());
    let layouts: [(&str, Vec<(f64, f64)>); 3] = [
        ("4 corners", ROOM10.to_vec()),
        ("4 corners + centre", [&ROOM10[..], &[(5.0, 5.0)]].concat()),
        (
            "4 corners + 2 walls' middles",
            [&ROOM10[..], &[(5.0, 0.0), (5.0, 10.0)]].concat(),
        ),
    ];
    // (fading σ per link and channel dB, channels)
    let media = [(3.0, 2), (3.0, 4), (1.5, 2), (1.0, 2)];
    let distances = [0.5, 1.0, 2.0, 3.0, 4.0, 5.66];
    println!(
        "anchor health on synthetic 10 m rooms, {rooms} rooms per row: P0 −40 dBm, α 3, shadowing σ 2 dB, \
         window 50 reports; anchor 3 configured at (10, 10)"
    );
    println!(
        "a cell: rooms that flag anchor 3 % / that flag another anchor % / median |offset − move| m\n"
    );
    for (li, (name, layout)) in layouts.iter().enumerate() {
        if only.is_some_and(|o| o != li) {
            continue;
        }
        for &(fading, channels) in &media {
            let cfg = HealthConfig {
                fading_db: fading,
                ..HealthConfig::default()
            };
            let mut base = Room::new(layout);
            base.fading_db = fading;
            base.channels = channels;
            let h0 = verdicts(&base, cfg, rooms);
            let fa = h0.iter().filter(|v| v.is_some()).count();
            println!(
                "{name}, fading σ {fading} dB × {channels} channels: false alarms {fa} of {rooms} rooms"
            );
            for (dir, to) in [
                ("to the centre", (-1.0 / 2f64.sqrt(), -1.0 / 2f64.sqrt())),
                ("along the wall", (0.0, -1.0)),
            ] {
                let mut row = format!("  moved {dir:<14}");
                for &d in &distances {
                    let room = base.clone().moved(2, (10.0 + d * to.0, 10.0 + d * to.1));
                    let v = verdicts(&room, cfg, rooms);
                    let right: Vec<f64> = v
                        .iter()
                        .filter_map(|v| v.filter(|f| f.0 == 3).map(|f| (f.1 - d).abs()))
                        .collect();
                    let wrong = v.iter().filter(|v| v.is_some_and(|f| f.0 != 3)).count();
                    let mut errs = right.clone();
                    errs.sort_by(f64::total_cmp);
                    let median = errs
                        .get(errs.len() / 2)
                        .map_or("-".to_string(), |m| format!("{m:.1}"));
                    row += &format!(
                        " | {d} m: {:.0}/{:.0}/{median}",
                        100.0 * right.len() as f64 / rooms as f64,
                        100.0 * wrong as f64 / rooms as f64
                    );
                }
                println!("{row}");
            }
        }
    }
    // A room with 1.5 times the fading the check assumes.
    for (li, (name, layout)) in layouts.iter().enumerate() {
        if only.is_some_and(|o| o != li) {
            continue;
        }
        let cfg = HealthConfig {
            fading_db: 3.0,
            ..HealthConfig::default()
        };
        let mut room = Room::new(layout);
        room.fading_db = 4.5;
        let fa = verdicts(&room, cfg, rooms)
            .iter()
            .filter(|v| v.is_some())
            .count();
        println!(
            "{name}, fading σ 4.5 dB × 2 channels, the check assuming 3 dB: false alarms {fa} of \
             {rooms} rooms"
        );
    }
    println!("\n{:.0} s", t0.elapsed().as_secs_f64());
}
