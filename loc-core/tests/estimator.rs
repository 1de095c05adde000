//! The f64 reference estimator end to end: refinements, path-loss fits, grid MLE/MMSE, bounds.

use loc_core::bounds::{crlb, fisher, mmse_floor};
use loc_core::grid::{
    self, cost, lattice_point, locate, mle, mmse, mmse_window, posterior_mean_window,
    search_lattice, Estimator, Search, FINE_DIVS,
};
use loc_core::params::{estimate, fit, Ar1, Bounds, CalStats, FitMethod, OnlineParams, ParamMode};
use loc_core::refine::{observations, Obs, Observations, Refinement};
use loc_core::{Area, LocError, Measurements, PathLoss, Point, MAX_CHANNELS};
use proptest::prelude::*;

const SQUARE: [Point; 4] = [
    Point::new(0.0, 0.0),
    Point::new(10.0, 0.0),
    Point::new(10.0, 10.0),
    Point::new(0.0, 10.0),
];
const ROOM: Area = Area::new(10.0, 10.0);
const SEARCHES: [Search; 3] = [Search::Thesis, Search::MultiStart, Search::Exhaustive];

/// Small deterministic normal generator (xorshift64 + Box–Muller): tests need no RNG crate.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (2.0 * core::f64::consts::PI * v).cos()
    }
}

/// Noise-free measurements of an agent at `agent` on `channels` channels, with a2a filled in.
fn noise_free(anchors: &[Point], channels: usize, model: PathLoss, agent: Point) -> Measurements {
    let mut m = Measurements::new(anchors, channels);
    for i in 0..anchors.len() {
        let z = model.rssi_at(agent.dist(anchors[i]));
        for c in 0..channels {
            m.anchors[i].rssi[c] = Some(z);
        }
        for j in 0..anchors.len() {
            if i != j {
                let z = model.rssi_at(anchors[i].dist(anchors[j]));
                m.a2a[i][j][..channels].fill(Some(z));
            }
        }
    }
    m
}

fn close(a: Point, b: Point, tol: f64) -> bool {
    a.dist(b) <= tol
}

// ---------------------------------------------------------------- refinements

#[test]
fn refinements_on_hand_examples() {
    let mut m = Measurements::new(&SQUARE[..3], 2);
    m.anchors[0].rssi = [Some(-40.0), Some(-50.0), Some(0.0), None]; // channel 2 not in use
    m.anchors[1].rssi = [None, Some(-61.0), None, None];
    m.anchors[2].rssi = [Some(-70.0), None, None, None];

    let lin = observations(&m, Refinement::LinearAvg);
    assert_eq!(lin.len(), 3);
    assert!((lin.as_slice()[0].z - -42.596_373_105_057_56).abs() < 1e-9);
    assert_eq!(lin.as_slice()[1].z, -61.0);

    let max = observations(&m, Refinement::Max);
    let zs: Vec<f64> = max.as_slice().iter().map(|o| o.z).collect();
    assert_eq!(zs, [-40.0, -61.0, -70.0]);

    let ch1 = observations(&m, Refinement::Single(1));
    assert_eq!(ch1.len(), 2, "anchor 2 has no channel 1");
    assert_eq!(ch1.as_slice()[1].pos, SQUARE[1]);
    assert!(
        observations(&m, Refinement::Single(2)).is_empty(),
        "channel 2 not in use"
    );

    let ext = observations(&m, Refinement::Extended);
    let got: Vec<(f64, f64)> = ext.as_slice().iter().map(|o| (o.z, o.weight)).collect();
    assert_eq!(got, [(-45.0, 2.0), (-61.0, 1.0), (-70.0, 1.0)]);
    assert_eq!(ext.const_cost, 50.0); // (−40 + 45)² + (−50 + 45)²
    assert_eq!(ext.total_weight(), 4.0);
}

#[test]
fn extended_cost_is_the_full_multichannel_cost() {
    let model = PathLoss {
        p0: -43.0,
        alpha: 2.7,
    };
    let mut rng = Rng(7);
    let mut m = Measurements::new(&SQUARE, 3);
    for a in m.anchors.iter_mut().take(4) {
        for c in 0..3 {
            a.rssi[c] = Some(-40.0 - 40.0 * rng.uniform());
        }
    }
    m.anchors[2].rssi[1] = None;
    let ext = observations(&m, Refinement::Extended);
    for p in [
        Point::new(3.3, 7.1),
        Point::new(0.0, 0.0),
        Point::new(9.9, 5.0),
    ] {
        let mut full = 0.0;
        for a in m.anchors() {
            let pred = model.rssi_at(p.dist(a.pos));
            for z in a.rssi.iter().take(3).flatten() {
                full += (z - pred) * (z - pred);
            }
        }
        let c = cost(&ext, model, p);
        assert!((c - full).abs() < 1e-9 * full.max(1.0), "{c} vs {full}");
    }
}

// ---------------------------------------------------------------- noise-free positions

#[test]
fn noise_free_lattice_points_are_found_exactly() {
    let model = PathLoss::THESIS;
    for anchors in [&SQUARE[..3], &SQUARE[..]] {
        for i in (0..=50).step_by(3) {
            for j in (0..=50).step_by(4) {
                let truth = lattice_point(ROOM, i, j);
                let m = noise_free(anchors, 2, model, truth);
                for r in [Refinement::Single(0), Refinement::Max, Refinement::Extended] {
                    for s in SEARCHES {
                        let e = locate(&m, r, model, ROOM, Estimator::Mle(s)).unwrap();
                        assert!(
                            close(e.pos, truth, 1e-9),
                            "{s:?} {r:?} {} anchors: {:?} vs {truth:?}",
                            anchors.len(),
                            e.pos
                        );
                        assert!(e.min_cost < 1e-12, "{e:?}");
                        assert_eq!(e.anchors, anchors.len());
                        assert_eq!(e.estimator, Estimator::Mle(s));
                    }
                }
            }
        }
    }
}

#[test]
fn noise_free_off_lattice_is_within_a_fine_step() {
    let model = PathLoss {
        p0: -45.0,
        alpha: 2.5,
    };
    let area = Area::new(7.0, 7.0);
    let anchors = [
        Point::new(0.0, 0.0),
        Point::new(7.0, 0.0),
        Point::new(7.0, 7.0),
    ];
    // The thesis' experiment-1 positions.
    for truth in [(3.5, 3.5), (2.0, 3.5), (2.0, 5.0), (5.0, 5.0), (6.0, 3.5)] {
        let truth = Point::new(truth.0, truth.1);
        let m = noise_free(&anchors, 1, model, truth);
        for s in SEARCHES {
            let e = locate(&m, Refinement::Single(0), model, area, Estimator::Mle(s)).unwrap();
            // Fine step 0.14 m: a lattice point next to the truth (the cost is anisotropic, so not
            // necessarily the nearest one).
            assert!(close(e.pos, truth, 0.14 * 2f64.sqrt()), "{s:?}: {e:?}");
        }
    }
}

#[test]
fn agent_on_an_anchor_is_found() {
    let model = PathLoss::THESIS;
    for a in SQUARE {
        let m = noise_free(&SQUARE, 1, model, a);
        for s in SEARCHES {
            let e = locate(&m, Refinement::Max, model, ROOM, Estimator::Mle(s)).unwrap();
            assert!(close(e.pos, a, 1e-9), "{s:?} {a:?}: {e:?}");
        }
    }
}

// ---------------------------------------------------------------- search quality

#[test]
fn multi_start_misses_the_lattice_minimum_far_less_often() {
    // The 6 m × 4 m room of experiment 2, where the thesis search misses most often.
    let area = Area::new(6.0, 4.0);
    let anchors = [
        Point::new(1.0, 0.0),
        Point::new(6.0, 1.0),
        Point::new(6.0, 4.0),
        Point::new(0.0, 4.0),
    ];
    let model = PathLoss::THESIS;
    let mut rng = Rng(0x5eed);
    let (mut thesis, mut multi, mut trials) = (0, 0, 0);
    for k in 0..12 {
        for l in 0..8 {
            let truth = Point::new(0.25 + 0.5 * k as f64, 0.25 + 0.5 * l as f64);
            for _ in 0..30 {
                let mut obs = Observations::new();
                for a in anchors {
                    let z = model.rssi_at(truth.dist(a)) + 3.0 * rng.normal();
                    obs.push(Obs {
                        pos: a,
                        z,
                        weight: 1.0,
                    });
                }
                let [t, ms, ex] = SEARCHES.map(|s| mle(&obs, model, area, s).unwrap());
                assert!(t.evaluations <= 242 && ms.evaluations <= 242);
                assert_eq!(ex.evaluations, (FINE_DIVS + 1) * (FINE_DIVS + 1));
                assert!(t.min_cost >= ex.min_cost && ms.min_cost >= ex.min_cost);
                thesis += usize::from(t.min_cost > ex.min_cost);
                multi += usize::from(ms.min_cost > ex.min_cost);
                trials += 1;
            }
        }
    }
    assert!(thesis > 10, "thesis missed {thesis} of {trials}");
    assert!(
        multi * 4 < thesis,
        "multi-start {multi}, thesis {thesis} of {trials}"
    );
}

/// Reference multi-start without the shortcuts: the four best coarse points (ties in scan order),
/// each descended by a full look at its 8 neighbours until none is strictly cheaper, no budget;
/// the cheapest end wins (ties: the earlier start). Returns `(i, j, cost)`.
fn plain_multi_start(cost: &dyn Fn(usize, usize) -> f64) -> (usize, usize, f64) {
    let mut coarse: Vec<(f64, usize, usize)> = Vec::new();
    for ci in 0..=10 {
        for cj in 0..=10 {
            coarse.push((cost(5 * ci, 5 * cj), 5 * ci, 5 * cj));
        }
    }
    // A stable sort keeps scan order among equal costs.
    coarse.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best = (coarse[0].1, coarse[0].2, coarse[0].0);
    for &(mut c, mut i, mut j) in &coarse[..4] {
        loop {
            let mut next = (c, i, j);
            for a in i.saturating_sub(1)..=(i + 1).min(50) {
                for b in j.saturating_sub(1)..=(j + 1).min(50) {
                    let x = cost(a, b);
                    if x < next.0 {
                        next = (x, a, b);
                    }
                }
            }
            if next.0 < c {
                (c, i, j) = next;
            } else {
                break;
            }
        }
        if c < best.2 {
            best = (i, j, c);
        }
    }
    best
}

#[test]
fn multi_start_misses_are_lattice_pits() {
    // Noise-free, 4 anchors, agent at (0.5, 1.0): the sampled cost along the narrow circular
    // valley around the (0, 0) anchor has two pits, the lattice minimum (2, 5) and (4, 4); every
    // start descends into (4, 4) or (0, 6), so multi-start returns (4, 4) (see the grid module
    // docs). That is where a correct descent stops: all 8 neighbours of (4, 4) cost more.
    let model = PathLoss::THESIS;
    let truth = Point::new(0.5, 1.0);
    let obs = observations(&noise_free(&SQUARE, 1, model, truth), Refinement::Single(0));
    let c = |i: usize, j: usize| cost(&obs, model, lattice_point(ROOM, i, j));
    let ms = search_lattice(Search::MultiStart, c);
    let ex = search_lattice(Search::Exhaustive, c);
    assert_eq!((ex.i, ex.j), (2, 5));
    assert!(close(lattice_point(ROOM, 2, 5), truth, 0.2));
    assert_eq!((ms.i, ms.j), (4, 4));
    assert!(ms.evaluations < 242, "not a budget stop: {ms:?}");
    for a in 3..=5 {
        for b in 3..=5 {
            if (a, b) != (4, 4) {
                assert!(c(a, b) > ms.cost, "({a}, {b}) is cheaper than (4, 4)");
            }
        }
    }
    assert_eq!(plain_multi_start(&c), (4, 4, ms.cost));

    // Everywhere else too: on the thesis study's points, noise-free and noisy, 3 and 4 anchors, the
    // search (ranking, shortcut descent, shared budget) ends where the plain reference does
    // whenever it did not run out of budget, and every miss of the lattice minimum is such an end.
    let mut rng = Rng(0xd15c);
    let (mut compared, mut misses) = (0, 0);
    for anchors in [&SQUARE[..3], &SQUARE[..]] {
        for sigma in [0.0, 0.01, 2.0, 4.0] {
            for k in 0..19 {
                for l in 0..19 {
                    let truth = Point::new(0.5 * (k + 1) as f64, 0.5 * (l + 1) as f64);
                    let mut obs = Observations::new();
                    for &a in anchors {
                        let z = model.rssi_at(truth.dist(a)) + sigma * rng.normal();
                        obs.push(Obs {
                            pos: a,
                            z,
                            weight: 1.0,
                        });
                    }
                    let c = |i: usize, j: usize| cost(&obs, model, lattice_point(ROOM, i, j));
                    let ms = search_lattice(Search::MultiStart, c);
                    if ms.evaluations >= 242 {
                        continue;
                    }
                    compared += 1;
                    assert_eq!(
                        plain_multi_start(&c),
                        (ms.i, ms.j, ms.cost),
                        "{} anchors, σ {sigma}, {truth:?}",
                        anchors.len()
                    );
                    misses += usize::from(ms.cost > search_lattice(Search::Exhaustive, c).cost);
                }
            }
        }
    }
    assert!(compared > 2500, "only {compared} searches within budget");
    assert!(misses > 0, "no miss to explain");
}

// ---------------------------------------------------------------- MMSE

#[test]
fn mmse_matches_a_direct_posterior_mean() {
    let model = PathLoss::THESIS;
    let truth = Point::new(2.7, 8.1);
    let mut rng = Rng(11);
    let mut obs = Observations::new();
    for a in SQUARE {
        let z = model.rssi_at(truth.dist(a)) + 3.0 * rng.normal();
        obs.push(Obs {
            pos: a,
            z,
            weight: 2.0,
        });
    }
    let sigma = 3.0;
    let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for i in 0..=50 {
        for j in 0..=50 {
            let p = lattice_point(ROOM, i, j);
            let w = (-cost(&obs, model, p) / (2.0 * sigma * sigma)).exp();
            s += w;
            sx += w * p.x;
            sy += w * p.y;
        }
    }
    let e = mmse(&obs, model, ROOM, sigma).unwrap();
    assert!(close(e.pos, Point::new(sx / s, sy / s), 1e-9), "{e:?}");
    assert_eq!(e.estimator, Estimator::Mmse { sigma });
    assert_eq!(e.evaluations, (FINE_DIVS + 1) * (FINE_DIVS + 1));
    // Its min cost is the exhaustive MLE's.
    let ex = mle(&obs, model, ROOM, Search::Exhaustive).unwrap();
    assert!((e.min_cost - ex.min_cost).abs() < 1e-12);
}

#[test]
fn mmse_limits() {
    let model = PathLoss::THESIS;
    let truth = Point::new(6.1, 3.3);
    let mut rng = Rng(3);
    let mut obs = Observations::new();
    for a in &SQUARE[..3] {
        let z = model.rssi_at(truth.dist(*a)) + 4.0 * rng.normal();
        obs.push(Obs {
            pos: *a,
            z,
            weight: 1.0,
        });
    }
    let ex = mle(&obs, model, ROOM, Search::Exhaustive).unwrap();
    // Tiny σ: the posterior collapses onto the lattice MLE; σ = 0 is that limit.
    for sigma in [1e-3, 1e-200, 0.0, f64::NAN] {
        let e = mmse(&obs, model, ROOM, sigma).unwrap();
        assert!(close(e.pos, ex.pos, 1e-9), "σ = {sigma}: {e:?} vs {ex:?}");
    }
    // Infinite σ: a flat posterior, the area's centre.
    let e = mmse(&obs, model, ROOM, f64::INFINITY).unwrap();
    assert!(close(e.pos, Point::new(5.0, 5.0), 1e-9), "{e:?}");
    // Larger σ pulls towards the centre but stays in the area.
    for sigma in [1.0, 4.0, 30.0, 1e6] {
        let e = mmse(&obs, model, ROOM, sigma).unwrap();
        assert!(ROOM.contains(e.pos) && e.pos.x.is_finite(), "{e:?}");
    }
}

#[test]
fn mmse_is_stable_with_huge_costs() {
    // −255 dBm everywhere: costs ~10⁵, exp(−cost/2σ²) underflows without stabilisation.
    let mut m = Measurements::new(&SQUARE, 1);
    for a in m.anchors.iter_mut().take(4) {
        a.rssi[0] = Some(-255.0);
    }
    m.anchors[0].rssi[0] = Some(0.0);
    let e = locate(
        &m,
        Refinement::Single(0),
        PathLoss::THESIS,
        ROOM,
        Estimator::Mmse { sigma: 0.5 },
    )
    .unwrap();
    assert!(
        e.pos.x.is_finite() && e.pos.y.is_finite() && ROOM.contains(e.pos),
        "{e:?}"
    );
    assert!(e.min_cost > 1e4);
    let w = locate(
        &m,
        Refinement::Single(0),
        PathLoss::THESIS,
        ROOM,
        Estimator::MmseWindow { sigma: 0.5 },
    )
    .unwrap();
    assert!(
        w.pos.x.is_finite() && w.pos.y.is_finite() && ROOM.contains(w.pos),
        "{w:?}"
    );
    // The window's smallest cost is at least the lattice's.
    assert!(
        w.min_cost.is_finite() && w.min_cost >= e.min_cost,
        "{w:?} vs {e:?}"
    );
}

// ---------------------------------------------------------------- windowed MMSE

/// Noisy observations of `truth` from `anchors` (σ dB, each with `weight`).
fn noisy(anchors: &[Point], truth: Point, sigma: f64, weight: f64, rng: &mut Rng) -> Observations {
    let model = PathLoss::THESIS;
    let mut obs = Observations::new();
    for a in anchors {
        obs.push(Obs {
            pos: *a,
            z: model.rssi_at(truth.dist(*a)) + sigma * rng.normal(),
            weight,
        });
    }
    obs
}

/// The thesis' fine window around the coarse winner, found directly: `(i0..=i1, j0..=j1)`.
fn thesis_window(
    obs: &Observations,
    model: PathLoss,
    area: Area,
) -> (
    std::ops::RangeInclusive<usize>,
    std::ops::RangeInclusive<usize>,
) {
    let mut best = (0, 0, f64::INFINITY);
    for i in (0..=50).step_by(5) {
        for j in (0..=50).step_by(5) {
            let c = cost(obs, model, lattice_point(area, i, j));
            if c < best.2 {
                best = (i, j, c);
            }
        }
    }
    let win = |c: usize| c.saturating_sub(5)..=(c + 5).min(50);
    (win(best.0), win(best.1))
}

#[test]
fn mmse_window_is_the_posterior_mean_over_the_thesis_window() {
    let model = PathLoss::THESIS;
    let mut rng = Rng(23);
    // Inside, at a corner and at an edge (clipped windows), with 3 and 4 anchors.
    let truths = [
        (2.7, 8.1),
        (0.3, 0.2),
        (9.9, 5.0),
        (5.0, 5.0),
        (6.1, 3.3),
        (4.4, 9.8),
    ];
    for (k, (x, y)) in truths.into_iter().enumerate() {
        let anchors = if k % 2 == 0 {
            &SQUARE[..]
        } else {
            &SQUARE[..3]
        };
        let obs = noisy(anchors, Point::new(x, y), 3.0, 2.0, &mut rng);
        let (wi, wj) = thesis_window(&obs, model, ROOM);
        let points: Vec<(usize, usize)> = wi
            .clone()
            .flat_map(|i| wj.clone().map(move |j| (i, j)))
            .collect();
        let coarse_inside = points.iter().filter(|(i, j)| i % 5 == 0 && j % 5 == 0);
        let thesis = mle(&obs, model, ROOM, Search::Thesis).unwrap();
        for sigma in [0.7, 3.0, 8.0] {
            let cmin = points
                .iter()
                .map(|&(i, j)| cost(&obs, model, lattice_point(ROOM, i, j)))
                .fold(f64::INFINITY, f64::min);
            let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
            for &(i, j) in &points {
                let p = lattice_point(ROOM, i, j);
                let w = (-(cost(&obs, model, p) - cmin) / (2.0 * sigma * sigma)).exp();
                s += w;
                sx += w * p.x;
                sy += w * p.y;
            }
            let e = mmse_window(&obs, model, ROOM, sigma).unwrap();
            assert!(
                close(e.pos, Point::new(sx / s, sy / s), 1e-9),
                "{k} σ = {sigma}: {e:?} vs ({}, {})",
                sx / s,
                sy / s
            );
            assert_eq!(e.estimator, Estimator::MmseWindow { sigma });
            // The coarse points in the window keep their coarse costs.
            assert_eq!(
                e.evaluations,
                121 + points.len() - coarse_inside.clone().count()
            );
            // Its smallest cost is the window's, which is the thesis MLE's.
            assert_eq!(e.min_cost, thesis.min_cost);
            assert!((e.min_cost - (cmin + obs.const_cost)).abs() < 1e-12);
        }
    }
}

#[test]
fn mmse_window_limits() {
    let model = PathLoss::THESIS;
    let mut rng = Rng(3);
    for (k, (x, y)) in [(6.1, 3.3), (0.4, 9.3), (5.0, 0.0)].into_iter().enumerate() {
        let anchors = if k == 1 { &SQUARE[..] } else { &SQUARE[..3] };
        let obs = noisy(anchors, Point::new(x, y), 4.0, 1.0, &mut rng);
        let thesis = mle(&obs, model, ROOM, Search::Thesis).unwrap();
        // Tiny σ: the window's posterior collapses onto its minimum, the thesis MLE; σ = 0 (or
        // NaN) is that limit.
        for sigma in [1e-3, 1e-200, 0.0, f64::NAN] {
            let e = mmse_window(&obs, model, ROOM, sigma).unwrap();
            assert!(
                close(e.pos, thesis.pos, 1e-9),
                "σ = {sigma}: {e:?} vs {thesis:?}"
            );
        }
        // Infinite σ: flat weights, the centroid of the (clipped) window.
        let (wi, wj) = thesis_window(&obs, model, ROOM);
        let mid = |r: &std::ops::RangeInclusive<usize>| (r.start() + r.end()) as f64 / 2.0 * 0.2;
        let e = mmse_window(&obs, model, ROOM, f64::INFINITY).unwrap();
        assert!(
            close(e.pos, Point::new(mid(&wi), mid(&wj)), 1e-9),
            "{e:?} vs {wi:?} × {wj:?}"
        );
        // Any σ: inside the window.
        for sigma in [0.5, 1.0, 4.0, 30.0, 1e6] {
            let e = mmse_window(&obs, model, ROOM, sigma).unwrap();
            let inside = |v: f64, r: &std::ops::RangeInclusive<usize>| {
                (*r.start() as f64 * 0.2 - 1e-12..=*r.end() as f64 * 0.2 + 1e-12).contains(&v)
            };
            assert!(
                inside(e.pos.x, &wi) && inside(e.pos.y, &wj),
                "σ = {sigma}: {e:?}"
            );
        }
    }
    // Noise-free with the agent on the lattice: the cost is 0 there and only there, so with a
    // small σ the windowed mean is the agent's position whenever the thesis window holds it (the
    // thesis search finds it), and the thesis MLE always.
    let (mut found, mut points) = (0, 0);
    for anchors in [&SQUARE[..3], &SQUARE[..]] {
        for i in (0..=50).step_by(7) {
            for j in (0..=50).step_by(6) {
                let truth = lattice_point(ROOM, i, j);
                let m = noise_free(anchors, 2, model, truth);
                let est = Estimator::MmseWindow { sigma: 0.01 };
                let e = locate(&m, Refinement::Extended, model, ROOM, est).unwrap();
                let t = locate(
                    &m,
                    Refinement::Extended,
                    model,
                    ROOM,
                    Estimator::Mle(Search::Thesis),
                )
                .unwrap();
                assert!(close(e.pos, t.pos, 1e-6), "{e:?} vs {t:?}");
                assert_eq!(e.min_cost, t.min_cost);
                if t.min_cost < 1e-12 {
                    assert!(close(e.pos, truth, 1e-6), "{e:?} vs {truth:?}");
                    found += 1;
                }
                points += 1;
            }
        }
    }
    assert!(found * 10 >= points * 9, "{found} of {points}");
}

/// The windowed mean is the full-lattice posterior mean truncated to the thesis window: the same
/// when the posterior's mass lies inside the window (small σ), pulled to the window otherwise.
#[test]
fn mmse_window_differs_from_the_full_mmse_by_the_truncation() {
    let model = PathLoss::THESIS;
    let mut rng = Rng(77);
    let obs = noisy(&SQUARE, Point::new(4.3, 5.6), 1.0, 2.0, &mut rng);
    // (Here the truncation moves it by ~1 µm at σ = 0.5 dB, 9 mm at 1 dB, 0.27 m at 3 dB.)
    for sigma in [0.2, 0.3] {
        let (w, f) = (
            mmse_window(&obs, model, ROOM, sigma).unwrap(),
            mmse(&obs, model, ROOM, sigma).unwrap(),
        );
        assert!(close(w.pos, f.pos, 1e-9), "σ = {sigma}: {w:?} vs {f:?}");
        assert_eq!(w.min_cost, f.min_cost);
    }
    // Near a corner with a wide posterior: the full mean heads for the area's centre, the
    // windowed one cannot leave the window (at most 1 m from the coarse winner in this room).
    let obs = noisy(&SQUARE, Point::new(1.1, 0.9), 1.0, 2.0, &mut rng);
    let (wi, wj) = thesis_window(&obs, model, ROOM);
    let sigma = 40.0;
    let (w, f) = (
        mmse_window(&obs, model, ROOM, sigma).unwrap(),
        mmse(&obs, model, ROOM, sigma).unwrap(),
    );
    assert!(f.pos.dist(Point::new(5.0, 5.0)) < 1.5, "{f:?}");
    assert!(
        w.pos.x <= *wi.end() as f64 * 0.2 && w.pos.y <= *wj.end() as f64 * 0.2,
        "{w:?}"
    );
    assert!(w.pos.dist(f.pos) > 2.0, "{w:?} vs {f:?}");
}

#[test]
fn posterior_mean_window_on_a_table() {
    // Flat: the coarse winner is the first point, its window clipped at the corner (6 × 6, 4
    // coarse points among them), the mean its centroid; the smallest cost the thesis' (0, 0).
    let m = posterior_mean_window(1.0, |_, _| 1.0);
    assert_eq!((m.i, m.j), (2.5, 2.5));
    assert_eq!((m.min.i, m.min.j, m.min.cost), (0, 0, 1.0));
    assert_eq!(m.min.evaluations, 121 + 36 - 4);
    // A bowl at (27, 23): coarse winner (25, 25), window 20…30 × 20…30, 9 coarse points in it.
    let bowl = |i: usize, j: usize| {
        let (x, y) = (i as f64 - 27.0, j as f64 - 23.0);
        0.5 * (x * x + y * y)
    };
    let m = posterior_mean_window(0.0, bowl);
    assert_eq!((m.i, m.j), (27.0, 23.0));
    assert_eq!(m.min.evaluations, 121 + 121 - 9);
    let t = search_lattice(Search::Thesis, bowl);
    assert_eq!((m.min.i, m.min.j, m.min.cost), (t.i, t.j, t.cost));
    // σ = 1: weights exp(−(x² + y²)/4) truncated to the window, x = i − 27 ∈ [−7, 3] and
    // y = j − 23 ∈ [−3, 7]: mirror images, so the mean is pulled by the same small amount (the
    // tail beyond 3, ≈ 0.024) left of 27 and above 23.
    let m = posterior_mean_window(1.0, bowl);
    assert!((m.i - 27.0 + (m.j - 23.0)).abs() < 1e-12, "{m:?}");
    assert!(m.j > 23.01 && m.j < 23.05, "{m:?}");
    // Ties: the coarse winner keeps the smallest cost (as in the thesis search), σ = 0 averages
    // every minimiser of the window. Minimum 0 on the row j = 25, i = 20…30 (the coarse winner is
    // (20, 25), the first coarse point on it).
    let row = |i: usize, j: usize| {
        if j == 25 && (20..=30).contains(&i) {
            0.0
        } else {
            1.0
        }
    };
    let m = posterior_mean_window(0.0, row);
    assert_eq!((m.min.i, m.min.j), (20, 25));
    let t = search_lattice(Search::Thesis, row);
    assert_eq!((t.i, t.j), (20, 25));
    // Window 15…25: the minimisers 20…25 of the row.
    assert_eq!((m.i, m.j), (22.5, 25.0));
    // NaN and +∞ never win and weigh nothing; nothing finite: the coarse winner (0, 0).
    let m = posterior_mean_window(2.0, |i, j| if i == 3 && j == 4 { 7.0 } else { f64::NAN });
    assert_eq!(
        (m.i, m.j, m.min.i, m.min.j, m.min.cost),
        (3.0, 4.0, 3, 4, 7.0)
    );
    let m = posterior_mean_window(2.0, |_, _| f64::INFINITY);
    assert_eq!((m.i, m.j, m.min.cost), (0.0, 0.0, f64::INFINITY));
}

// ---------------------------------------------------------------- too few anchors

#[test]
fn too_few_anchors() {
    let model = PathLoss::THESIS;
    let m = noise_free(&SQUARE[..2], 2, model, Point::new(1.0, 1.0));
    for est in [
        Estimator::Mle(Search::Thesis),
        Estimator::Mmse { sigma: 2.0 },
        Estimator::MmseWindow { sigma: 2.0 },
    ] {
        assert_eq!(
            locate(&m, Refinement::Max, model, ROOM, est),
            Err(LocError::TooFewAnchors { usable: 2 })
        );
    }
    // Four anchors, two never heard.
    let mut m = noise_free(&SQUARE, 2, model, Point::new(1.0, 1.0));
    m.anchors[1].rssi = [None; MAX_CHANNELS];
    m.anchors[3].rssi = [None; MAX_CHANNELS];
    assert_eq!(
        locate(
            &m,
            Refinement::Extended,
            model,
            ROOM,
            Estimator::Mle(Search::MultiStart)
        ),
        Err(LocError::TooFewAnchors { usable: 2 })
    );
    // Heard, but not on the selected channel.
    let mut m = noise_free(&SQUARE, 2, model, Point::new(1.0, 1.0));
    m.anchors[0].rssi[1] = None;
    m.anchors[2].rssi[1] = None;
    assert_eq!(
        locate(
            &m,
            Refinement::Single(1),
            model,
            ROOM,
            Estimator::Mle(Search::Thesis)
        ),
        Err(LocError::TooFewAnchors { usable: 2 })
    );
    assert!(locate(
        &m,
        Refinement::Single(0),
        model,
        ROOM,
        Estimator::Mle(Search::Thesis)
    )
    .is_ok());
    assert_eq!(
        mle(&Observations::new(), model, ROOM, Search::Exhaustive),
        Err(LocError::TooFewAnchors { usable: 0 })
    );
}

// ---------------------------------------------------------------- path-loss parameters

fn a2a_measurements(model: PathLoss, channels: usize) -> Measurements {
    // Five anchors: six distinct distances among them.
    let anchors = [
        Point::new(0.0, 0.0),
        Point::new(10.0, 0.0),
        Point::new(10.0, 10.0),
        Point::new(0.0, 10.0),
        Point::new(3.0, 4.0),
    ];
    noise_free(&anchors, channels, model, Point::new(5.0, 5.0))
}

#[test]
fn least_squares_recovers_the_model_exactly() {
    let truth = PathLoss {
        p0: -47.3,
        alpha: 2.63,
    };
    let m = a2a_measurements(truth, 2);
    let f = estimate(
        &m,
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        PathLoss::THESIS,
        &Bounds::THESIS,
    )
    .unwrap();
    assert!((f.model.p0 - truth.p0).abs() < 1e-9, "{f:?}");
    assert!((f.model.alpha - truth.alpha).abs() < 1e-9, "{f:?}");
    assert_eq!(f.n, 5 * 4 * 2);
    assert_eq!(f.fitted, 2);
    assert!(f.sse < 1e-9 && f.sigma.unwrap() < 1e-4, "{f:?}");
    // Per channel, same answer.
    let s = CalStats::from_measurements(&m, Some(1));
    assert_eq!(s.len(), 20);
    let f1 = fit(
        &s,
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        PathLoss::THESIS,
        &Bounds::THESIS,
    )
    .unwrap();
    assert!((f1.model.alpha - truth.alpha).abs() < 1e-9);
}

#[test]
fn grid_fit_is_within_one_step() {
    for truth in [(-47.3, 2.63), (-40.0, 3.0), (-58.9, 4.96), (-21.2, 2.04)] {
        let truth = PathLoss {
            p0: truth.0,
            alpha: truth.1,
        };
        let m = a2a_measurements(truth, 1);
        let f = estimate(
            &m,
            ParamMode::P0AndAlpha,
            FitMethod::Grid,
            PathLoss::THESIS,
            &Bounds::THESIS,
        )
        .unwrap();
        assert!(
            (f.model.alpha - truth.alpha).abs() <= 0.1 + 1e-9,
            "{truth:?}: {f:?}"
        );
        assert!(
            (f.model.p0 - truth.p0).abs() <= 0.5 + 1e-9,
            "{truth:?}: {f:?}"
        );
        // On the grid.
        let k = (f.model.alpha - 2.0) / 0.1;
        let j = (f.model.p0 + 60.0) / 0.5;
        assert!(
            (k - k.round()).abs() < 1e-6 && (j - j.round()).abs() < 1e-6,
            "{f:?}"
        );
    }
    // A grid point is found exactly.
    let truth = PathLoss {
        p0: -40.0,
        alpha: 3.0,
    };
    let f = estimate(
        &a2a_measurements(truth, 1),
        ParamMode::P0AndAlpha,
        FitMethod::Grid,
        PathLoss::THESIS,
        &Bounds::THESIS,
    )
    .unwrap();
    assert!((f.model.alpha - 3.0).abs() < 1e-9 && (f.model.p0 + 40.0).abs() < 1e-9);
}

#[test]
fn least_squares_clamps_to_the_constrained_optimum() {
    let b = Bounds::THESIS;
    // α above its bound: α = 5, P0 re-fitted with α = 5 (the mean of z + 50·log10 d).
    let truth = PathLoss {
        p0: -35.0,
        alpha: 6.0,
    };
    let m = a2a_measurements(truth, 1);
    let f = estimate(
        &m,
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        PathLoss::THESIS,
        &b,
    )
    .unwrap();
    let mut want_p0 = 0.0;
    let mut n = 0.0;
    let anchors = m.anchors();
    for i in 0..anchors.len() {
        for j in 0..anchors.len() {
            if i != j {
                let d = anchors[i].pos.dist(anchors[j].pos);
                want_p0 += m.a2a[i][j][0].unwrap() + 50.0 * d.log10();
                n += 1.0;
            }
        }
    }
    want_p0 /= n;
    assert_eq!(f.model.alpha, 5.0);
    assert!((f.model.p0 - want_p0).abs() < 1e-9, "{f:?} vs {want_p0}");
    assert!(
        (-60.0..=-20.0).contains(&want_p0),
        "P0 needs no clamping here: {want_p0}"
    );

    // P0 above its bound: P0 = −20, α re-fitted with P0 fixed: α = Σ x(z − P0) / Σ x².
    let truth = PathLoss {
        p0: -12.0,
        alpha: 3.4,
    };
    let m = a2a_measurements(truth, 1);
    let f = estimate(
        &m,
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        PathLoss::THESIS,
        &b,
    )
    .unwrap();
    let (mut num, mut den) = (0.0, 0.0);
    let anchors = m.anchors();
    for i in 0..anchors.len() {
        for j in 0..anchors.len() {
            if i != j {
                let x = -10.0 * anchors[i].pos.dist(anchors[j].pos).log10();
                num += x * (m.a2a[i][j][0].unwrap() + 20.0);
                den += x * x;
            }
        }
    }
    assert_eq!(f.model.p0, -20.0);
    assert!(
        (f.model.alpha - num / den).abs() < 1e-9,
        "{f:?} vs {}",
        num / den
    );

    // Both out: the corner.
    let truth = PathLoss {
        p0: -5.0,
        alpha: 1.2,
    };
    let f = estimate(
        &a2a_measurements(truth, 1),
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        PathLoss::THESIS,
        &b,
    )
    .unwrap();
    assert_eq!((f.model.p0, f.model.alpha), (-20.0, 2.0));
}

#[test]
fn p0_only_mode() {
    let truth = PathLoss {
        p0: -45.0,
        alpha: 3.0,
    };
    let m = a2a_measurements(truth, 2);
    let ls = |prior| {
        estimate(
            &m,
            ParamMode::P0Only,
            FitMethod::LeastSquares,
            prior,
            &Bounds::THESIS,
        )
        .unwrap()
    };
    let f = ls(PathLoss::THESIS);
    assert_eq!(f.model.alpha, 3.0);
    assert!((f.model.p0 + 45.0).abs() < 1e-9, "{f:?}");
    assert_eq!(f.fitted, 1);
    // A wrong α: P0 is the mean of z + 25·log10 d. The fixed α is not clamped to the bounds.
    for alpha in [2.5, 1.5] {
        let f = ls(PathLoss { p0: -40.0, alpha });
        let anchors = m.anchors();
        let (mut s, mut n) = (0.0, 0.0);
        for i in 0..anchors.len() {
            for j in 0..anchors.len() {
                if i != j {
                    let d = anchors[i].pos.dist(anchors[j].pos);
                    s += 2.0 * (truth.rssi_at(d) + 10.0 * alpha * d.log10());
                    n += 2.0;
                }
            }
        }
        assert_eq!(f.model.alpha, alpha);
        assert!((f.model.p0 - s / n).abs() < 1e-9, "{f:?} vs {}", s / n);
    }
    // Grid: snapped to the 0.5 dB grid and clamped to the bounds.
    let g = estimate(
        &a2a_measurements(
            PathLoss {
                p0: -45.2,
                alpha: 3.0,
            },
            1,
        ),
        ParamMode::P0Only,
        FitMethod::Grid,
        PathLoss::THESIS,
        &Bounds::THESIS,
    )
    .unwrap();
    assert!((g.model.p0 + 45.0).abs() < 1e-9, "{g:?}");
    let g = estimate(
        &a2a_measurements(
            PathLoss {
                p0: -75.0,
                alpha: 3.0,
            },
            1,
        ),
        ParamMode::P0Only,
        FitMethod::Grid,
        PathLoss::THESIS,
        &Bounds::THESIS,
    )
    .unwrap();
    assert_eq!(g.model.p0, -60.0);
}

#[test]
fn sigma_from_residuals() {
    // Residuals +1, −1 at each of two distances: orthogonal to [1, x], so LS fits the truth
    // exactly, SSE = 4, n = 4, two parameters: σ = √(4 / 2).
    let truth = PathLoss {
        p0: -41.0,
        alpha: 3.2,
    };
    let mut s = CalStats::new();
    for d in [2.0, 7.0] {
        s.push(d, truth.rssi_at(d) + 1.0);
        s.push(d, truth.rssi_at(d) - 1.0);
    }
    let f = fit(
        &s,
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        PathLoss::THESIS,
        &Bounds::THESIS,
    )
    .unwrap();
    assert!((f.model.alpha - 3.2).abs() < 1e-9 && (f.model.p0 + 41.0).abs() < 1e-9);
    assert!((f.sse - 4.0).abs() < 1e-9);
    assert!((f.sigma.unwrap() - 2f64.sqrt()).abs() < 1e-9);
    // P0 only: one parameter, σ = √(4 / 3); fixed: √(4 / 4).
    let f = fit(
        &s,
        ParamMode::P0Only,
        FitMethod::LeastSquares,
        truth,
        &Bounds::THESIS,
    )
    .unwrap();
    assert!((f.sigma.unwrap() - (4.0f64 / 3.0).sqrt()).abs() < 1e-9);
    let f = fit(
        &s,
        ParamMode::Fixed,
        FitMethod::LeastSquares,
        truth,
        &Bounds::THESIS,
    )
    .unwrap();
    assert!((f.sigma.unwrap() - 1.0).abs() < 1e-9);
    // Two samples, two parameters: no σ.
    let mut s = CalStats::new();
    s.push(2.0, -50.0);
    s.push(3.0, -55.0);
    let f = fit(
        &s,
        ParamMode::P0AndAlpha,
        FitMethod::LeastSquares,
        truth,
        &Bounds::THESIS,
    )
    .unwrap();
    assert_eq!(f.sigma, None);
}

#[test]
fn no_calibration_data() {
    let m = Measurements::new(&SQUARE, 2);
    for mode in [ParamMode::P0Only, ParamMode::P0AndAlpha] {
        for method in [FitMethod::Grid, FitMethod::LeastSquares] {
            assert_eq!(
                estimate(&m, mode, method, PathLoss::THESIS, &Bounds::THESIS),
                Err(LocError::NoCalibrationData)
            );
        }
    }
    let f = estimate(
        &m,
        ParamMode::Fixed,
        FitMethod::Grid,
        PathLoss::THESIS,
        &Bounds::THESIS,
    )
    .unwrap();
    assert_eq!((f.model, f.n, f.sigma), (PathLoss::THESIS, 0, None));
    // Coincident anchors carry no calibration; neither do channels not in use.
    let p = Point::new(2.0, 2.0);
    let mut m = Measurements::new(&[p, p, p], 1);
    m.a2a[0][1][0] = Some(-20.0);
    m.a2a[1][0][1] = Some(-30.0);
    assert_eq!(
        estimate(
            &m,
            ParamMode::P0Only,
            FitMethod::LeastSquares,
            PathLoss::THESIS,
            &Bounds::THESIS
        ),
        Err(LocError::NoCalibrationData)
    );
}

#[test]
fn ar1_smoothing() {
    let mut f = Ar1::default();
    assert_eq!(f.value(), None);
    let ys: Vec<f64> = [10.0, 20.0, 20.0, 0.0]
        .iter()
        .map(|&x| f.update(x))
        .collect();
    let want = [10.0, 12.0, 13.6, 10.88];
    for (y, w) in ys.iter().zip(want) {
        assert!((y - w).abs() < 1e-12, "{ys:?}");
    }
    f.reset();
    assert_eq!(f.update(-3.0), -3.0);
    let mut g = Ar1::new(0.5, 1.0);
    g.update(2.0);
    assert_eq!(g.update(4.0), 5.0);
}

#[test]
fn online_parameters_follow_a_drifting_p0() {
    let mut est = OnlineParams::new(
        ParamMode::P0Only,
        FitMethod::LeastSquares,
        Bounds::THESIS,
        PathLoss::THESIS,
    );
    assert_eq!(est.current(), PathLoss::THESIS);
    // No data: an error, the state is kept.
    assert_eq!(
        est.update(&Measurements::new(&SQUARE, 1)),
        Err(LocError::NoCalibrationData)
    );
    assert_eq!(est.current(), PathLoss::THESIS);
    let drifted = |p0| PathLoss { p0, alpha: 3.0 };
    est.update(&a2a_measurements(drifted(-44.0), 1)).unwrap();
    assert!(
        (est.current().p0 + 44.0).abs() < 1e-9,
        "first fit initialises"
    );
    est.update(&a2a_measurements(drifted(-54.0), 1)).unwrap();
    assert!(
        (est.current().p0 + 46.0).abs() < 1e-9,
        "{:?}",
        est.current()
    );
    assert_eq!(est.current().alpha, 3.0);

    let mut both = OnlineParams::new(
        ParamMode::P0AndAlpha,
        FitMethod::Grid,
        Bounds::THESIS,
        PathLoss::THESIS,
    );
    both.update(&a2a_measurements(
        PathLoss {
            p0: -50.0,
            alpha: 4.0,
        },
        1,
    ))
    .unwrap();
    both.update(&a2a_measurements(
        PathLoss {
            p0: -40.0,
            alpha: 2.0,
        },
        1,
    ))
    .unwrap();
    let c = both.current();
    assert!(
        (c.p0 + 48.0).abs() < 1e-9 && (c.alpha - 3.6).abs() < 1e-9,
        "{c:?}"
    );
}

// ---------------------------------------------------------------- bounds

#[test]
fn crlb_at_the_centre_of_a_square() {
    let model = PathLoss::THESIS;
    let (sigma, channels) = (2.0, 2);
    let centre = Point::new(5.0, 5.0);
    let f = fisher(centre, &SQUARE, model, sigma, channels);
    // Σ uuᵀ = 2·I, d² = 50: F = C·b·2/50·I.
    let b = (10.0 * 3.0 / (2.0 * std::f64::consts::LN_10)).powi(2);
    let diag = 2.0 * b * 2.0 / 50.0;
    assert!(
        (f[0][0] - diag).abs() < 1e-9 && (f[1][1] - diag).abs() < 1e-9,
        "{f:?}"
    );
    assert!(f[0][1].abs() < 1e-12);
    let bound = crlb(centre, &SQUARE, model, sigma, channels).unwrap();
    assert!((bound - (2.0 / diag).sqrt()).abs() < 1e-12);
    assert!((bound - 0.767_534).abs() < 1e-5, "{bound}");
    // Twice the channels: the bound shrinks by √2.
    let two = crlb(centre, &SQUARE, model, sigma, 4).unwrap();
    assert!((bound / two - 2f64.sqrt()).abs() < 1e-12);
}

#[test]
fn crlb_off_centre_by_hand() {
    // Anchors at (0,0), (10,0), (0,10), point (5,0) → (4,2) etc.: compute F by hand for one case.
    let anchors = [
        Point::new(0.0, 0.0),
        Point::new(6.0, 0.0),
        Point::new(0.0, 8.0),
    ];
    let p = Point::new(3.0, 4.0);
    // u/d for each anchor: (3,4)/25, (−3,4)/25, (3,−4)/25 (all d = 5).
    let s: [[f64; 2]; 2] = [[27.0 / 625.0, -12.0 / 625.0], [-12.0 / 625.0, 48.0 / 625.0]];
    let model = PathLoss {
        p0: -40.0,
        alpha: 2.0,
    };
    let b = (20.0 / (4.0 * std::f64::consts::LN_10)).powi(2);
    let f = fisher(p, &anchors, model, 4.0, 1);
    for r in 0..2 {
        for c in 0..2 {
            assert!((f[r][c] - b * s[r][c]).abs() < 1e-12, "{f:?}");
        }
    }
    let det = b * b * (27.0 * 48.0 - 144.0) / 625.0 / 625.0;
    let want = (b * 75.0 / 625.0 / det).sqrt();
    assert!((crlb(p, &anchors, model, 4.0, 1).unwrap() - want).abs() < 1e-12);
}

#[test]
fn mmse_floor_is_the_rmse_of_the_grid_posterior_mean() {
    let model = PathLoss::THESIS;
    let (sigma, channels) = (3.0, 2);
    let truth = Point::new(3.5, 6.25);
    let mut rng = Rng(99);
    let draws: Vec<f64> = (0..4 * 37).map(|_| rng.normal()).collect();
    let floor = mmse_floor(truth, &SQUARE, model, sigma, channels, ROOM, &draws).unwrap();
    // The same thing through grid::mmse, one trial at a time.
    let mut sum = 0.0;
    for t in draws.chunks_exact(4) {
        let mut obs = Observations::new();
        for (a, d) in SQUARE.iter().zip(t) {
            let z = model.rssi_at(truth.dist(*a)) + sigma / (channels as f64).sqrt() * d;
            obs.push(Obs {
                pos: *a,
                z,
                weight: channels as f64,
            });
        }
        let e = grid::mmse(&obs, model, ROOM, sigma).unwrap();
        sum += truth.dist(e.pos).powi(2);
    }
    let want = (sum / 37.0).sqrt();
    assert!((floor - want).abs() < 1e-9, "{floor} vs {want}");
    // Same order as the CRLB here (interior point, 4 anchors).
    let bound = crlb(truth, &SQUARE, model, sigma, channels).unwrap();
    assert!(
        floor > 0.3 * bound && floor < 3.0 * bound,
        "{floor} vs {bound}"
    );
    // Partial trials are ignored; no whole trial, bad σ or too few anchors: no floor.
    let partial = mmse_floor(
        truth,
        &SQUARE,
        model,
        sigma,
        channels,
        ROOM,
        &draws[..4 * 37 - 1],
    );
    assert!(partial.is_some_and(|p| p != floor));
    assert_eq!(
        mmse_floor(truth, &SQUARE, model, sigma, channels, ROOM, &draws[..3]),
        None
    );
    assert_eq!(
        mmse_floor(truth, &SQUARE[..2], model, sigma, channels, ROOM, &draws),
        None
    );
    assert_eq!(
        mmse_floor(truth, &SQUARE, model, 0.0, channels, ROOM, &draws),
        None
    );
    assert_eq!(
        mmse_floor(truth, &SQUARE, model, sigma, 0, ROOM, &draws),
        None
    );
}

#[test]
fn search_lattice_accepts_a_table() {
    // A host driver can search a precomputed table.
    let mut table = [[0.0; 51]; 51];
    for (i, row) in table.iter_mut().enumerate() {
        for (j, c) in row.iter_mut().enumerate() {
            *c = 1.0 + (i as f64 - 17.0).powi(2) + 2.0 * (j as f64 - 33.0).powi(2);
        }
    }
    for s in [Search::MultiStart, Search::Exhaustive] {
        let m = search_lattice(s, |i, j| table[i][j]);
        assert_eq!((m.i, m.j, m.cost), (17, 33, 1.0), "{s:?}");
    }
}

// ---------------------------------------------------------------- robustness

fn anchors_strategy() -> impl Strategy<Value = Vec<(f64, f64)>> {
    prop_oneof![
        // Anywhere (coincident ones by chance from the coarse set below).
        prop::collection::vec((0.0..30.0f64, 0.0..30.0f64), 3..=8),
        // Coincident: few distinct positions.
        prop::collection::vec(
            prop::sample::select(vec![(0.0, 0.0), (5.0, 5.0), (30.0, 0.0)]),
            3..=8
        ),
        // Collinear.
        (0.0..30.0f64, prop::collection::vec(-5.0..35.0f64, 3..=8))
            .prop_map(|(y, xs)| xs.into_iter().map(|x| (x, y)).collect()),
    ]
}

fn rssi_strategy() -> impl Strategy<Value = Option<f64>> {
    prop_oneof![
        1 => Just(None),
        1 => Just(Some(0.0)),
        1 => Just(Some(-255.0)),
        5 => (-255.0..=0.0f64).prop_map(Some),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    #[test]
    fn never_panics_nor_nan(
        anchors in anchors_strategy(),
        channels in 1usize..=4,
        rssi in prop::collection::vec(rssi_strategy(), 8 * 4 + 8 * 8 * 4),
        w in 0.0..=30.0f64,
        h in 0.0..=30.0f64,
        p0 in -100.0..0.0f64,
        alpha in 0.5..6.0f64,
        sigma in prop_oneof![Just(0.0), 0.01..10.0f64],
        refinement in prop_oneof![
            (0usize..5).prop_map(Refinement::Single),
            Just(Refinement::Max),
            Just(Refinement::LinearAvg),
            Just(Refinement::Extended),
        ],
    ) {
        let pos: Vec<Point> = anchors.iter().map(|&(x, y)| Point::new(x, y)).collect();
        let mut m = Measurements::new(&pos, channels);
        let mut it = rssi.iter();
        for a in m.anchors.iter_mut() {
            for v in a.rssi.iter_mut() {
                *v = *it.next().unwrap();
            }
        }
        for row in m.a2a.iter_mut() {
            for cell in row.iter_mut() {
                for v in cell.iter_mut() {
                    *v = *it.next().unwrap();
                }
            }
        }
        let area = Area::new(w, h);
        let model = PathLoss { p0, alpha };
        let obs = observations(&m, refinement);
        for est in [
            Estimator::Mle(Search::Thesis),
            Estimator::Mle(Search::MultiStart),
            Estimator::Mle(Search::Exhaustive),
            Estimator::Mmse { sigma },
            Estimator::MmseWindow { sigma },
        ] {
            match locate(&m, refinement, model, area, est) {
                Ok(e) => {
                    prop_assert!(obs.len() >= 3);
                    prop_assert!(e.pos.x.is_finite() && e.pos.y.is_finite(), "{e:?}");
                    prop_assert!(area.contains(e.pos), "{e:?}");
                    prop_assert!(e.min_cost.is_finite() && e.min_cost >= 0.0, "{e:?}");
                    prop_assert!(e.evaluations <= (FINE_DIVS + 1) * (FINE_DIVS + 1));
                    if let Some(s) = e.sigma_hat() {
                        prop_assert!(s.is_finite());
                    }
                }
                Err(err) => {
                    prop_assert_eq!(err, LocError::TooFewAnchors { usable: obs.len() });
                    prop_assert!(obs.len() < 3);
                }
            }
        }
        for mode in [ParamMode::Fixed, ParamMode::P0Only, ParamMode::P0AndAlpha] {
            for method in [FitMethod::Grid, FitMethod::LeastSquares] {
                match estimate(&m, mode, method, model, &Bounds::THESIS) {
                    Ok(f) => {
                        prop_assert!(f.model.p0.is_finite() && f.model.alpha.is_finite());
                        prop_assert!(f.sse.is_finite() && f.sse >= 0.0);
                        if mode != ParamMode::Fixed {
                            prop_assert!((-60.0..=-20.0).contains(&f.model.p0), "{f:?}");
                        }
                        if mode == ParamMode::P0AndAlpha {
                            prop_assert!((2.0..=5.0).contains(&f.model.alpha), "{f:?}");
                        }
                        if let Some(s) = f.sigma {
                            prop_assert!(s.is_finite() && s >= 0.0);
                        }
                    }
                    Err(err) => prop_assert_eq!(err, LocError::NoCalibrationData),
                }
            }
        }
        let agent = Point::new(w / 3.0, h / 2.0);
        if let Some(b) = crlb(agent, &pos, model, sigma, channels) {
            prop_assert!(b.is_finite() && b >= 0.0);
        }
        let draws = [0.3, -1.2, 2.5, 0.0, -0.7, 1.1, 0.4, -2.0];
        if let Some(f) = mmse_floor(agent, &pos, model, sigma, channels, area, &draws) {
            prop_assert!(f.is_finite() && f >= 0.0);
        }
    }
}
