//! The path-loss model and the data the estimators work on.

/// Most anchors a measurement set holds: the testbed's limit (its reports carry 3 to this many;
/// `loc-proto` takes it from here).
pub const MAX_ANCHORS: usize = 8;
/// Most channels per anchor: the testbed's limit (it hops 1 to this many).
pub const MAX_CHANNELS: usize = 4;

/// A point in metres.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Point {
    /// x, metres.
    pub x: f64,
    /// y, metres.
    pub y: f64,
}

impl Point {
    /// `(x, y)`.
    pub const fn new(x: f64, y: f64) -> Point {
        Point { x, y }
    }

    /// Euclidean distance to `other`.
    pub fn dist(self, other: Point) -> f64 {
        libm::hypot(self.x - other.x, self.y - other.y)
    }
}

/// The localization area: the rectangle `[0, width] × [0, height]` metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Area {
    /// Extent in x, metres.
    pub width: f64,
    /// Extent in y, metres.
    pub height: f64,
}

impl Area {
    /// A `width` × `height` metre area.
    pub const fn new(width: f64, height: f64) -> Area {
        Area { width, height }
    }

    /// `p` moved to the nearest point of the area. Never panics (`f64::clamp` would on a
    /// negative or NaN side); with such a side the result is still finite for finite `p`.
    pub fn clip(self, p: Point) -> Point {
        Point::new(p.x.min(self.width).max(0.0), p.y.min(self.height).max(0.0))
    }

    /// Whether `p` lies in the area (edges included).
    pub fn contains(self, p: Point) -> bool {
        (0.0..=self.width).contains(&p.x) && (0.0..=self.height).contains(&p.y)
    }
}

/// Log-normal shadowing: `p(d) = P0 − 10·α·log10(d / d0)`, `d0 = 1 m`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathLoss {
    /// Received power at `d0 = 1 m`, dBm.
    pub p0: f64,
    /// Path-loss exponent α.
    pub alpha: f64,
}

/// Distances below this are treated as this (the model diverges at 0).
pub const MIN_DISTANCE: f64 = 0.01;

impl PathLoss {
    /// The thesis' defaults: P0 = −40 dBm, α = 3.
    pub const THESIS: PathLoss = PathLoss {
        p0: -40.0,
        alpha: 3.0,
    };

    /// Mean received power at distance `d` metres (d clamped to ≥ [`MIN_DISTANCE`]).
    pub fn rssi_at(self, d: f64) -> f64 {
        self.p0 - 10.0 * self.alpha * libm::log10(d.max(MIN_DISTANCE))
    }

    /// Distance estimate of a received power `z`: `d0 · 10^((P0 − z) / (10 α))`.
    pub fn distance(self, z: f64) -> f64 {
        libm::pow(10.0, (self.p0 - z) / (10.0 * self.alpha))
    }
}

/// One anchor: its position and what the agent measured from it on each channel (dBm; `None`
/// where that channel was not heard).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Anchor {
    /// Known position.
    pub pos: Point,
    /// RSSI per channel, dBm.
    pub rssi: [Option<f64>; MAX_CHANNELS],
}

impl Anchor {
    /// An anchor at `pos` with nothing heard yet.
    pub const fn new(pos: Point) -> Anchor {
        Anchor {
            pos,
            rssi: [None; MAX_CHANNELS],
        }
    }
}

/// What one estimate works from: the anchors (with the agent's RSSI per channel) and the
/// anchor-to-anchor RSSI (`a2a[i][j]`: anchor `i` heard from anchor `j`, per channel), the raw
/// material of path-loss estimation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Measurements {
    /// Number of anchors in use (≤ [`MAX_ANCHORS`]).
    pub n_anchors: usize,
    /// Number of channels in use (≤ [`MAX_CHANNELS`]).
    pub n_channels: usize,
    /// The anchors (first `n_anchors` used).
    pub anchors: [Anchor; MAX_ANCHORS],
    /// Anchor-to-anchor RSSI, dBm: `a2a[i][j][c]`.
    pub a2a: [[[Option<f64>; MAX_CHANNELS]; MAX_ANCHORS]; MAX_ANCHORS],
}

impl Measurements {
    /// Anchors at `positions` (at most [`MAX_ANCHORS`], extra ignored), `n_channels` channels,
    /// nothing heard yet.
    pub fn new(positions: &[Point], n_channels: usize) -> Measurements {
        let mut anchors = [Anchor::new(Point::default()); MAX_ANCHORS];
        let n = positions.len().min(MAX_ANCHORS);
        for (a, &p) in anchors.iter_mut().zip(positions) {
            a.pos = p;
        }
        Measurements {
            n_anchors: n,
            n_channels: n_channels.min(MAX_CHANNELS),
            anchors,
            a2a: [[[None; MAX_CHANNELS]; MAX_ANCHORS]; MAX_ANCHORS],
        }
    }

    /// The anchors in use.
    pub fn anchors(&self) -> &[Anchor] {
        &self.anchors[..self.n_anchors.min(MAX_ANCHORS)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_inverts_the_model() {
        let m = PathLoss::THESIS;
        for d in [0.5, 1.0, 3.0, 14.1] {
            assert!((m.distance(m.rssi_at(d)) - d).abs() < 1e-9);
        }
        assert_eq!(m.rssi_at(1.0), -40.0);
        assert!((m.rssi_at(10.0) - -70.0).abs() < 1e-12);
    }

    #[test]
    fn area_clips_and_contains() {
        let a = Area::new(10.0, 5.0);
        assert_eq!(a.clip(Point::new(-1.0, 7.0)), Point::new(0.0, 5.0));
        assert!(a.contains(Point::new(10.0, 0.0)));
        assert!(!a.contains(Point::new(10.01, 0.0)));
        // A bad area never panics.
        let bad = Area::new(-1.0, f64::NAN);
        let c = bad.clip(Point::new(3.0, 4.0));
        assert!(c.x.is_finite() && c.y.is_finite());
    }
}
