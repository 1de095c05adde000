//! The host baselines: trilateration, quadlateration, MDS-MAP.

use loc_core::baselines::{mds_map, quadlaterate, trilaterate, Baseline, DEGENERATE_TOL};
use loc_core::{Area, LocError, Point, MAX_ANCHORS};
use proptest::prelude::*;

/// The thesis' anchors (the first three are the 3-anchor layout).
const THESIS: [Point; 4] = [
    Point::new(0.0, 0.0),
    Point::new(10.0, 0.0),
    Point::new(10.0, 10.0),
    Point::new(0.0, 10.0),
];
const AREA: Area = Area::new(10.0, 10.0);

type Method = fn(&[Point], &[f64]) -> Result<Point, LocError>;
const METHODS: [(&str, Method); 3] = [
    ("trilaterate", trilaterate),
    ("quadlaterate", quadlaterate),
    ("mds_map", mds_map),
];

fn dists(anchors: &[Point], agent: Point) -> Vec<f64> {
    anchors.iter().map(|a| a.dist(agent)).collect()
}

/// Deterministic standard normals (SplitMix64 + Box–Muller).
struct Gauss(u64);
impl Gauss {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The thesis' 361 agent positions ((k+1)/2, (m+1)/2).
fn thesis_points() -> impl Iterator<Item = Point> {
    (0..19)
        .flat_map(|k| (0..19).map(move |m| Point::new((k + 1) as f64 / 2.0, (m + 1) as f64 / 2.0)))
}

fn assert_near(got: Point, want: Point, tol: f64, what: &str) {
    assert!(
        got.dist(want) <= tol,
        "{what}: got {got:?}, want {want:?} (error {})",
        got.dist(want)
    );
}

#[test]
fn thesis_layout_exact_distances_give_the_exact_position() {
    for agent in thesis_points() {
        let d = dists(&THESIS, agent);
        let p3 = trilaterate(&THESIS[..3], &d[..3]).unwrap();
        assert_near(p3, agent, 1e-9, "TRLT-3");
        let p4 = quadlaterate(&THESIS, &d).unwrap();
        assert_near(p4, agent, 1e-9, "QUAD-4");
        let m3 = mds_map(&THESIS[..3], &d[..3]).unwrap();
        assert_near(m3, agent, 1e-9, "MDS-3");
        let m4 = mds_map(&THESIS, &d).unwrap();
        assert_near(m4, agent, 1e-9, "MDS-4");
    }
    // The anchors themselves (zero distances) and the far corner / outside points too.
    for agent in THESIS.iter().copied().chain([
        Point::new(5.0, 5.0),
        Point::new(-7.0, 23.0),
        Point::new(40.0, -3.5),
    ]) {
        let d = dists(&THESIS, agent);
        for (name, f) in METHODS {
            assert_near(f(&THESIS, &d).unwrap(), agent, 1e-9, name);
        }
    }
}

#[test]
fn dispatcher_picks_the_first_three_four_or_all_anchors() {
    let anchors = [
        Point::new(0.0, 0.0),
        Point::new(10.0, 0.0),
        Point::new(10.0, 10.0),
        Point::new(0.0, 10.0),
        Point::new(5.0, -4.0),
    ];
    let agent = Point::new(3.0, 6.0);
    let mut g = Gauss(7);
    let d: Vec<f64> = dists(&anchors, agent)
        .iter()
        .map(|d| d + 0.5 * g.normal())
        .collect();
    let trlt = Baseline::Trilateration
        .estimate(&anchors, &d, None)
        .unwrap();
    assert_eq!(trlt, trilaterate(&anchors[..3], &d[..3]).unwrap());
    assert_eq!(trlt, trilaterate(&anchors, &d).unwrap());
    let quad = Baseline::Quadlateration
        .estimate(&anchors, &d, None)
        .unwrap();
    assert_eq!(quad, quadlaterate(&anchors[..4], &d[..4]).unwrap());
    let mds = Baseline::MdsMap.estimate(&anchors, &d, None).unwrap();
    assert_eq!(mds, mds_map(&anchors, &d).unwrap());
    // MDS really uses the fifth anchor: dropping it changes a noisy estimate.
    assert!(mds.dist(mds_map(&anchors[..4], &d[..4]).unwrap()) > 1e-6);
    // Noisy estimates of different methods differ (they are different algorithms).
    assert!(trlt.dist(quad) > 1e-6 && quad.dist(mds) > 1e-6);
    assert_eq!(Baseline::ALL.map(Baseline::label), ["TRLT", "QUAD", "MDS"]);
    assert_eq!(Baseline::Quadlateration.anchors_used(), Some(4));
}

#[test]
fn quadlateration_is_the_mean_of_the_four_trilaterations() {
    let mut g = Gauss(11);
    let agent = Point::new(2.5, 7.0);
    let d: Vec<f64> = dists(&THESIS, agent)
        .iter()
        .map(|d| d * (1.0 + 0.1 * g.normal()))
        .collect();
    let (mut sx, mut sy) = (0.0, 0.0);
    for skip in 0..4 {
        let a: Vec<Point> = (0..4).filter(|&i| i != skip).map(|i| THESIS[i]).collect();
        let dd: Vec<f64> = (0..4).filter(|&i| i != skip).map(|i| d[i]).collect();
        let p = trilaterate(&a, &dd).unwrap();
        sx += p.x;
        sy += p.y;
    }
    let q = quadlaterate(&THESIS, &d).unwrap();
    assert_near(q, Point::new(sx / 4.0, sy / 4.0), 1e-12, "mean of the four");
    assert!(q.dist(agent) > 1e-6, "noise should move the estimate");
}

#[test]
fn quadlateration_skips_degenerate_triples() {
    // (0,0), (5,0), (10,0) are collinear: the other three triples still solve it.
    let anchors = [
        Point::new(0.0, 0.0),
        Point::new(5.0, 0.0),
        Point::new(10.0, 0.0),
        Point::new(5.0, 8.0),
    ];
    let agent = Point::new(3.0, 2.0);
    let d = dists(&anchors, agent);
    assert_near(quadlaterate(&anchors, &d).unwrap(), agent, 1e-9, "QUAD");
    // Under noise, the mean is over those three.
    let dn: Vec<f64> = d
        .iter()
        .zip([0.3, -0.2, 0.1, 0.4])
        .map(|(a, b)| a + b)
        .collect();
    let mut s = Point::default();
    for (i, j, k) in [(0, 1, 3), (0, 2, 3), (1, 2, 3)] {
        let p = trilaterate(
            &[anchors[i], anchors[j], anchors[k]],
            &[dn[i], dn[j], dn[k]],
        )
        .unwrap();
        s = Point::new(s.x + p.x / 3.0, s.y + p.y / 3.0);
    }
    assert_near(
        quadlaterate(&anchors, &dn).unwrap(),
        s,
        1e-12,
        "QUAD mean of 3",
    );
    // All four collinear: every triple degenerate.
    let line = [
        Point::new(0.0, 1.0),
        Point::new(2.0, 2.0),
        Point::new(4.0, 3.0),
        Point::new(8.0, 5.0),
    ];
    assert_eq!(
        quadlaterate(&line, &[1.0, 2.0, 3.0, 4.0]),
        Err(LocError::DegenerateGeometry)
    );
    // Three usable anchors: one triple, equal to trilateration.
    let d3 = [3.0, 8.0, 9.0];
    assert_eq!(
        quadlaterate(&THESIS[..3], &d3),
        trilaterate(&THESIS[..3], &d3)
    );
}

#[test]
fn collinear_and_coincident_anchors_are_degenerate() {
    let collinear = [
        Point::new(0.0, 0.0),
        Point::new(5.0, 0.0),
        Point::new(10.0, 0.0),
    ];
    let diagonal = [
        Point::new(1.0, 1.0),
        Point::new(3.0, 3.0),
        Point::new(-2.0, -2.0),
        Point::new(7.0, 7.0),
    ];
    let coincident = [
        Point::new(2.0, 3.0),
        Point::new(2.0, 3.0),
        Point::new(8.0, 1.0),
    ];
    let all_same = [Point::new(4.0, 4.0); 4];
    let d = [3.0, 4.0, 5.0, 6.0];
    for anchors in [
        &collinear[..],
        &diagonal[..],
        &coincident[..],
        &all_same[..],
    ] {
        for (name, f) in METHODS {
            assert_eq!(
                f(anchors, &d[..anchors.len()]),
                Err(LocError::DegenerateGeometry),
                "{name} {anchors:?}"
            );
        }
        for b in Baseline::ALL {
            assert_eq!(
                b.estimate(anchors, &d[..anchors.len()], Some(AREA)),
                Err(LocError::DegenerateGeometry)
            );
        }
    }
    // Relative tolerance: a bump of 1e-12 on a 10 m baseline is still collinear …
    let flat = [
        Point::new(0.0, 0.0),
        Point::new(5.0, 1e-12),
        Point::new(10.0, 0.0),
    ];
    assert_eq!(
        trilaterate(&flat, &d[..3]),
        Err(LocError::DegenerateGeometry)
    );
    assert_eq!(mds_map(&flat, &d[..3]), Err(LocError::DegenerateGeometry));
    // … while a micrometre-sized proper triangle is solved exactly.
    let tiny = [
        Point::new(1e-6, 0.0),
        Point::new(2e-6, 0.0),
        Point::new(1e-6, 1e-6),
    ];
    let agent = Point::new(1.3e-6, 0.4e-6);
    let dt = dists(&tiny, agent);
    assert_near(trilaterate(&tiny, &dt).unwrap(), agent, 1e-15, "tiny TRLT");
    assert_near(mds_map(&tiny, &dt).unwrap(), agent, 1e-15, "tiny MDS");
    // The threshold itself: twice the area over the longest side squared, h / 10 here.
    let bump = |h: f64| {
        [
            Point::new(0.0, 0.0),
            Point::new(10.0, 0.0),
            Point::new(5.0, h),
        ]
    };
    assert!(trilaterate(&bump(100.0 * DEGENERATE_TOL), &d[..3]).is_ok());
    assert_eq!(
        trilaterate(&bump(DEGENERATE_TOL), &d[..3]),
        Err(LocError::DegenerateGeometry)
    );
}

#[test]
fn mds_recovers_a_rotated_reflected_scaled_configuration() {
    // Similarity transforms of the thesis layout and agent, with and without reflection.
    for &(theta, reflect, k, tx, ty) in &[
        (0.7, false, 1.0, 0.0, 0.0),
        (0.7, true, 1.0, 0.0, 0.0),
        (2.9, true, 3.5, -100.0, 42.0),
        (-1.2, false, 0.01, 1e3, -1e3),
        (std::f64::consts::PI, true, 250.0, 5.0, 5.0),
    ] {
        let (c, s) = (f64::cos(theta), f64::sin(theta));
        let t = |p: Point| {
            let x = if reflect { -p.x } else { p.x };
            Point::new(tx + k * (c * x - s * p.y), ty + k * (s * x + c * p.y))
        };
        let anchors: Vec<Point> = THESIS.iter().map(|&p| t(p)).collect();
        for agent in [
            Point::new(2.0, 7.5),
            Point::new(5.0, 5.0),
            Point::new(12.0, -3.0),
        ] {
            let want = t(agent);
            let d = dists(&anchors, want);
            for (name, f) in METHODS {
                let got = f(&anchors, &d).unwrap();
                assert_near(got, want, 1e-9 * k.max(1.0), name);
            }
        }
        // Equivariance under noise: the estimate moves with the configuration.
        let mut g = Gauss(3);
        let agent = Point::new(6.0, 2.0);
        let d0: Vec<f64> = dists(&THESIS, agent)
            .iter()
            .map(|d| (d + g.normal()).max(0.0))
            .collect();
        let dk: Vec<f64> = d0.iter().map(|d| d * k).collect();
        for (name, f) in METHODS {
            let base = f(&THESIS, &d0).unwrap();
            let moved = f(&anchors, &dk).unwrap();
            assert_near(moved, t(base), 1e-9 * k.max(1.0), name);
        }
    }
}

#[test]
fn clipping_puts_estimates_in_the_area() {
    // Exact distances to a point outside the area: unclipped it is recovered, clipped it moves to
    // the nearest point of the area.
    for (agent, clipped) in [
        (Point::new(15.0, -3.0), Point::new(10.0, 0.0)),
        (Point::new(-2.0, 4.0), Point::new(0.0, 4.0)),
        (Point::new(5.0, 12.0), Point::new(5.0, 10.0)),
    ] {
        let d = dists(&THESIS, agent);
        for b in Baseline::ALL {
            assert_near(
                b.estimate(&THESIS, &d, None).unwrap(),
                agent,
                1e-9,
                b.label(),
            );
            assert_near(
                b.estimate(&THESIS, &d, Some(AREA)).unwrap(),
                clipped,
                1e-9,
                b.label(),
            );
        }
    }
    // Inside the area, clipping changes nothing.
    let agent = Point::new(3.0, 4.0);
    let d = dists(&THESIS, agent);
    for b in Baseline::ALL {
        assert_eq!(
            b.estimate(&THESIS, &d, Some(AREA)),
            b.estimate(&THESIS, &d, None)
        );
    }
    // An area without points (negative or NaN side) cannot hold the estimate.
    for bad in [Area::new(-1.0, 10.0), Area::new(10.0, f64::NAN)] {
        for b in Baseline::ALL {
            assert_eq!(
                b.estimate(&THESIS, &d, Some(bad)),
                Err(LocError::DegenerateGeometry)
            );
        }
    }
}

#[test]
fn noisy_distances_give_estimates_near_the_truth() {
    // 2 % distance noise (≈ 0.26 dB at α = 3): mean error well under a metre over the grid
    // (guessing the centre would be ≈ 3.8 m).
    let mut g = Gauss(2024);
    for b in Baseline::ALL {
        let anchors = if b == Baseline::Trilateration {
            &THESIS[..3]
        } else {
            &THESIS[..]
        };
        let (mut sum, mut worst, mut n) = (0.0, 0.0f64, 0);
        for agent in thesis_points() {
            let d: Vec<f64> = dists(anchors, agent)
                .iter()
                .map(|d| d * (1.0 + 0.02 * g.normal()))
                .collect();
            let p = b.estimate(anchors, &d, Some(AREA)).unwrap();
            let e = p.dist(agent);
            sum += e;
            worst = worst.max(e);
            n += 1;
        }
        let mean = sum / n as f64;
        assert!(mean < 0.5, "{}: mean error {mean}", b.label());
        assert!(
            mean > 0.01,
            "{}: noise should cost something ({mean})",
            b.label()
        );
        assert!(worst < 3.0, "{}: worst error {worst}", b.label());
    }
}

#[test]
fn unusable_and_negative_distances() {
    let agent = Point::new(4.0, 3.0);
    let d = dists(&THESIS, agent);
    // Fewer than three anchors.
    for (name, f) in METHODS {
        assert_eq!(
            f(&THESIS[..2], &d[..2]),
            Err(LocError::TooFewAnchors { usable: 2 }),
            "{name}"
        );
        assert_eq!(f(&[], &[]), Err(LocError::TooFewAnchors { usable: 0 }));
        // Non-finite distances make an anchor unusable.
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert_eq!(
                f(&THESIS[..3], &[d[0], bad, d[2]]),
                Err(LocError::TooFewAnchors { usable: 2 }),
                "{name}"
            );
            // With a fourth anchor the remaining three still give the position.
            assert_near(
                f(&THESIS, &[d[0], bad, d[2], d[3]]).unwrap(),
                agent,
                1e-9,
                name,
            );
        }
        // A non-finite anchor position likewise.
        let mut a = THESIS;
        a[0] = Point::new(f64::NAN, 0.0);
        assert_near(f(&a, &d).unwrap(), agent, 1e-9, name);
        // Mismatched lengths: only the pairs count.
        assert_near(f(&THESIS, &d[..3]).unwrap(), agent, 1e-9, name);
        assert_eq!(
            f(&THESIS[..2], &d),
            Err(LocError::TooFewAnchors { usable: 2 })
        );
        // A negative distance is a zero distance.
        let dn = [-2.0, 9.0, 11.0, 8.0];
        let dz = [0.0, 9.0, 11.0, 8.0];
        assert_eq!(f(&THESIS, &dn), f(&THESIS, &dz), "{name}");
    }
    // The agent at an anchor, slightly negative estimate there: still exact.
    let d0 = dists(&THESIS, THESIS[2]);
    let dneg = [d0[0], d0[1], -1e-3, d0[3]];
    for (name, f) in METHODS {
        assert_near(f(&THESIS, &dneg).unwrap(), THESIS[2], 1e-9, name);
    }
    // Distances whose squares overflow: an error, not an infinite point.
    for (name, f) in METHODS {
        let r = f(&THESIS, &[1e200, 1e300, 1.0, 1e250]);
        if let Ok(p) = r {
            assert!(p.x.is_finite() && p.y.is_finite(), "{name}: {p:?}");
        }
    }
    assert_eq!(
        trilaterate(&THESIS[..3], &[1e200, 1e300, 1.0]),
        Err(LocError::DegenerateGeometry)
    );
}

#[test]
fn mds_uses_at_most_max_anchors() {
    // 10 anchors on a circle, the last two wildly wrong: only the first MAX_ANCHORS count.
    let anchors: Vec<Point> = (0..10)
        .map(|i| {
            let a = i as f64 * 0.6;
            Point::new(5.0 + 4.0 * a.cos(), 5.0 + 4.0 * a.sin())
        })
        .collect();
    let agent = Point::new(4.0, 6.5);
    let mut d = dists(&anchors, agent);
    d[8] = 100.0;
    d[9] = 0.0;
    assert_near(mds_map(&anchors, &d).unwrap(), agent, 1e-9, "MDS-8 of 10");
    assert_eq!(MAX_ANCHORS, 8);
}

/// A point with coordinates in ±`r`.
fn point(r: f64) -> impl Strategy<Value = Point> {
    (-r..r, -r..r).prop_map(|(x, y)| Point::new(x, y))
}

/// Twice the triangle's area over its longest side squared (0: flat; 0.87: equilateral).
fn roundness(a: Point, b: Point, c: Point) -> f64 {
    let l = a.dist(b).max(a.dist(c)).max(b.dist(c));
    ((b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x)).abs() / (l * l)
}

/// Whether every triple of `a` is reasonably round.
fn well_conditioned(a: &[Point], min: f64) -> bool {
    let n = a.len();
    (0..n).all(|i| (i + 1..n).all(|j| (j + 1..n).all(|k| roundness(a[i], a[j], a[k]) >= min)))
}

/// Any f64, with the special values well represented.
fn any_dist() -> impl Strategy<Value = f64> {
    prop_oneof![
        3 => 0.0..30.0f64,
        1 => -30.0..0.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(0.0),
        1 => Just(f64::MAX),
        1 => Just(f64::MIN_POSITIVE),
        1 => any::<f64>(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn exact_distances_recover_random_positions(
        // Trilateration uses the first three, quadlateration the first four: those must be
        // non-degenerate; MDS needs some proper triangle, which the first three give.
        anchors in prop::collection::vec(point(20.0), 3..=MAX_ANCHORS)
            .prop_filter("first four well conditioned", |a| {
                well_conditioned(&a[..a.len().min(4)], 0.02)
            }),
        agent in point(40.0),
    ) {
        let d = dists(&anchors, agent);
        for (name, f) in METHODS {
            let p = f(&anchors, &d).unwrap();
            prop_assert!(p.dist(agent) < 1e-9, "{}: {:?} vs {:?}", name, p, agent);
        }
    }

    #[test]
    fn mds_recovers_random_layouts_with_all_anchors(
        // Only the first triple is required to be proper: the rest may be anywhere (collinear,
        // coincident with each other or with the agent).
        anchors in prop::collection::vec(point(20.0), 3..=MAX_ANCHORS)
            .prop_filter("first triple proper", |a| roundness(a[0], a[1], a[2]) >= 0.02),
        agent in point(40.0),
    ) {
        let d = dists(&anchors, agent);
        let p = mds_map(&anchors, &d).unwrap();
        prop_assert!(p.dist(agent) < 1e-9, "{:?} vs {:?}", p, agent);
    }

    #[test]
    fn nothing_panics_or_returns_non_finite(
        anchors in prop::collection::vec(point(50.0), 3..=MAX_ANCHORS),
        d in prop::collection::vec(any_dist(), MAX_ANCHORS),
        width in 0.0..20.0f64,
        height in 0.0..20.0f64,
    ) {
        let area = Area::new(width, height);
        for b in Baseline::ALL {
            for clip in [None, Some(area)] {
                match b.estimate(&anchors, &d, clip) {
                    Ok(p) => {
                        prop_assert!(p.x.is_finite() && p.y.is_finite(), "{:?}", p);
                        if clip.is_some() {
                            prop_assert!(area.contains(p), "{:?} not in {:?}", p, area);
                        }
                    }
                    Err(LocError::TooFewAnchors { usable }) => prop_assert!(usable < 3),
                    Err(LocError::DegenerateGeometry) => {}
                    Err(e) => prop_assert!(false, "unexpected {:?}", e),
                }
            }
        }
    }

    #[test]
    fn arbitrary_anchor_positions_never_panic(
        coords in prop::collection::vec(any::<f64>(), 6..=2 * MAX_ANCHORS),
        d in prop::collection::vec(any::<f64>(), 3..=MAX_ANCHORS),
    ) {
        let anchors: Vec<Point> = coords.chunks_exact(2).map(|c| Point::new(c[0], c[1])).collect();
        for b in Baseline::ALL {
            if let Ok(p) = b.estimate(&anchors, &d, Some(AREA)) {
                prop_assert!(AREA.contains(p), "{:?}", p);
            }
            if let Ok(p) = b.estimate(&anchors, &d, None) {
                prop_assert!(p.x.is_finite() && p.y.is_finite(), "{:?}", p);
            }
        }
    }

    #[test]
    fn clipped_estimates_lie_in_the_area(
        d in prop::collection::vec(0.0..25.0f64, 4),
    ) {
        for b in Baseline::ALL {
            let p = b.estimate(&THESIS, &d, Some(AREA)).unwrap();
            prop_assert!(AREA.contains(p), "{}: {:?}", b.label(), p);
        }
    }

    #[test]
    fn small_noise_gives_small_errors(
        agent in (0.5..9.5f64, 0.5..9.5f64).prop_map(|(x, y)| Point::new(x, y)),
        noise in prop::collection::vec(-0.05..0.05f64, 4),
    ) {
        // ±5 cm on every distance: each baseline stays within 0.5 m on the thesis layout.
        let d: Vec<f64> = dists(&THESIS, agent).iter().zip(&noise).map(|(d, n)| d + n).collect();
        for b in Baseline::ALL {
            let p = b.estimate(&THESIS, &d, None).unwrap();
            prop_assert!(p.dist(agent) < 0.5, "{}: {:?} vs {:?}", b.label(), p, agent);
        }
    }
}
