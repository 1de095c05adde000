//! Synthetic reports for studying the health check: anchors configured at one place and
//! standing at another, on the log-normal model with the emulated testbed medium's two kinds
//! of noise (`simavr::medium`): a static offset per link and channel, the same both ways
//! (fading), and a fresh draw per packet and receiver (shadowing); levels in whole dBm, lost
//! below the sensitivity. One seed is one room: its fading and its shadowing.

use loc_core::{PathLoss, Point, MAX_ANCHORS, MAX_CHANNELS};
use loc_proto::msg::{ChannelList, Position, Report};

use crate::study::{stream_seed, Normal};

/// A room of anchors and the medium between them.
#[derive(Clone, Debug, PartialEq)]
pub struct Room {
    /// Where each anchor is configured (what its beacons carry), m.
    pub configured: Vec<Point>,
    /// Where each anchor stands, m.
    pub truth: Vec<Point>,
    /// Channels (1…4).
    pub channels: usize,
    /// The path loss.
    pub model: PathLoss,
    /// σ of the static offset per link and channel, dB.
    pub fading_db: f64,
    /// σ of the per-packet shadowing, dB.
    pub shadow_db: f64,
    /// Packets below this level are lost, dBm.
    pub sensitivity_dbm: f64,
    /// Where the agent stands, m (its RSSI only tells the health check which anchors it heard).
    pub agent: Point,
}

impl Room {
    /// Anchors at `configured` (m), each standing where it is configured, 2 channels, the
    /// emulated testbed's default medium (P0 −40 dBm, α 3, fading σ 3 dB, shadowing σ 2 dB,
    /// sensitivity −92 dBm); the agent at the anchors' centroid.
    pub fn new(configured: &[(f64, f64)]) -> Room {
        let configured: Vec<Point> = configured
            .iter()
            .take(MAX_ANCHORS)
            .map(|&(x, y)| Point::new(x, y))
            .collect();
        let n = configured.len().max(1) as f64;
        let agent = Point::new(
            configured.iter().map(|p| p.x).sum::<f64>() / n,
            configured.iter().map(|p| p.y).sum::<f64>() / n,
        );
        Room {
            truth: configured.clone(),
            configured,
            channels: 2,
            model: PathLoss::THESIS,
            fading_db: 3.0,
            shadow_db: 2.0,
            sensitivity_dbm: -92.0,
            agent,
        }
    }

    /// The room with anchor `index` (0-based) standing at `to` (m).
    pub fn moved(mut self, index: usize, to: (f64, f64)) -> Room {
        if let Some(t) = self.truth.get_mut(index) {
            *t = Point::new(to.0, to.1);
        }
        self
    }

    /// `count` consecutive reports of agent 1 in the room of `seed`, with the relay matrix.
    #[allow(clippy::needless_range_loop)] // a symmetric matrix: [i][j] and [j][i] together
    pub fn reports(&self, count: usize, seed: u64) -> Vec<Report> {
        let n = self.configured.len().min(MAX_ANCHORS);
        let c = self.channels.clamp(1, MAX_CHANNELS);
        let mut fade = Normal::new(stream_seed(seed, 0.0, n, 0, 1));
        let mut fading = [[[0.0; MAX_CHANNELS]; MAX_ANCHORS]; MAX_ANCHORS];
        for i in 0..n {
            for j in i + 1..n {
                for ch in 0..c {
                    let f = self.fading_db * fade.draw();
                    fading[i][j][ch] = f;
                    fading[j][i][ch] = f;
                }
            }
        }
        let mut noise = Normal::new(stream_seed(seed, 0.0, n, 0, 2));
        let mut byte = |level: f64| {
            let l = (level + self.shadow_db * noise.draw()).round();
            if l < self.sensitivity_dbm {
                0
            } else {
                (-l).clamp(1.0, 255.0) as u8
            }
        };
        let channels: Vec<u8> = (1..=c as u8).collect();
        let Ok(list) = ChannelList::new(&channels) else {
            return Vec::new();
        };
        (0..count)
            .map(|seq| {
                let mut r = Report::new(1, seq as u16, n as u8, list);
                for (i, p) in self.configured.iter().take(n).enumerate() {
                    r.positions[i] = Position {
                        x: (p.x * 100.0).round() as i16,
                        y: (p.y * 100.0).round() as i16,
                    };
                }
                for ch in 0..c {
                    for i in 0..n {
                        r.rssi[ch][i] = byte(self.model.rssi_at(self.agent.dist(self.truth[i])));
                        for j in 0..n {
                            if i != j {
                                let d = self.truth[i].dist(self.truth[j]);
                                r.relay[ch][i][j] = byte(self.model.rssi_at(d) + fading[i][j][ch]);
                            }
                        }
                    }
                }
                r
            })
            .collect()
    }
}
