//! One position fix as a sink makes it: four anchors in a 10 m × 10 m room that hear each other
//! and an agent on two channels, RSSI with log-normal shadowing; the path-loss model fitted
//! from the anchor-to-anchor RSSI, then the agent located by the maximum-likelihood grid search
//! and by the posterior mean. `cargo run --example locate` (in the workspace: `-p loc-core`).

use loc_core::grid::{self, Estimator, Search};
use loc_core::params::{self, Bounds, FitMethod, ParamMode};
use loc_core::refine::Refinement;
use loc_core::{Area, Measurements, PathLoss, Point};

/// Shadowing, dB.
const SIGMA: f64 = 3.0;

/// A small deterministic normal sampler (xorshift + Box–Muller), so the example needs no
/// dependency and prints the same every run.
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-12), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

fn main() {
    let area = Area::new(10.0, 10.0);
    let anchors = [
        Point::new(0.0, 0.0),
        Point::new(10.0, 0.0),
        Point::new(10.0, 10.0),
        Point::new(0.0, 10.0),
    ];
    let agent = Point::new(3.0, 6.5);
    // The room's real model, which the sink does not know.
    let truth = PathLoss {
        p0: -45.0,
        alpha: 2.6,
    };
    let mut noise = Noise(0x5EED);
    let mut heard = |d: f64| Some((truth.rssi_at(d) + SIGMA * noise.normal()).round());

    let channels = 2;
    let mut m = Measurements::new(&anchors, channels);
    for i in 0..anchors.len() {
        for c in 0..channels {
            m.anchors[i].rssi[c] = heard(anchors[i].dist(agent));
            for j in 0..anchors.len() {
                if i != j {
                    m.a2a[i][j][c] = heard(anchors[i].dist(anchors[j]));
                }
            }
        }
    }

    // The model from what the anchors hear of each other, starting from a textbook prior.
    let prior = PathLoss {
        p0: -40.0,
        alpha: 3.0,
    };
    let fit = params::estimate(
        &m,
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        prior,
        &Bounds::default(),
    )
    .expect("the anchors hear each other");
    // Anchors that are all 10 m or 14.1 m apart pin P0 and alpha down only together: the fit may
    // trade one for the other, which moves the position little.
    let model = fit.model;
    println!(
        "fitted P0 = {:.1} dBm, alpha = {:.2} (true {:.1}, {:.2}); sigma = {:.1} dB",
        model.p0,
        model.alpha,
        truth.p0,
        truth.alpha,
        fit.sigma.unwrap_or(f64::NAN)
    );

    let estimators = [
        ("MLE, thesis search", Estimator::Mle(Search::Thesis)),
        ("MLE, multi-start", Estimator::Mle(Search::MultiStart)),
        ("MMSE", Estimator::Mmse { sigma: SIGMA }),
    ];
    for (name, estimator) in estimators {
        let fix = grid::locate(&m, Refinement::Max, model, area, estimator).expect("4 anchors");
        println!(
            "{name:>20}: ({:.2}, {:.2}) m, {:.2} m from the agent at ({}, {})",
            fix.pos.x,
            fix.pos.y,
            fix.pos.dist(agent),
            agent.x,
            agent.y
        );
    }
}
