//! Ellipse polygons and Minkowski sums against parry2d (f32) and brute force.
//! (The ellipse polygons are built in f64 on the stack for speed; parry2d is the reference.)

use frvo::geometry::{cross, Ellipse, Polygon, V2};
use frvo::minkowski::minkowski_sum;
use parry2d::math::Point;
use parry2d::query::PointQuery;
use parry2d::shape::ConvexPolygon;
use parry2d::transformation::convex_hull;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

fn to_parry(p: &Polygon) -> ConvexPolygon {
    let pts: Vec<Point<f32>> = p
        .points()
        .iter()
        .map(|q| Point::new(q.x as f32, q.y as f32))
        .collect();
    ConvexPolygon::from_convex_hull(&pts).expect("a polygon with area")
}

fn is_ccw_convex(p: &Polygon, eps: f64) -> bool {
    let q = p.points();
    let n = q.len();
    (0..n).all(|i| cross(q[(i + 1) % n] - q[i], q[(i + 2) % n] - q[(i + 1) % n]) >= -eps)
}

/// Pedestrian-like ellipses: 1 to 120 px, aspect ratio within 1:5 (parry2d works in f32 and its
/// hull drops vertices of needle-thin polygons).
fn ellipse_strategy() -> impl Strategy<Value = (Ellipse, usize)> {
    (
        1.0f64..120.0,
        0.2f64..5.0,
        0.0f64..std::f64::consts::TAU,
        3usize..=32,
    )
        .prop_map(|(w, ratio, angle, sides)| {
            (
                Ellipse::new(w * ratio, w, V2::new(angle.cos(), angle.sin())),
                sides,
            )
        })
}

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(0x0e11_1b5e),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(config(1000))]

    #[test]
    fn polygon_contains_its_ellipse((e, sides) in ellipse_strategy()) {
        let poly = e.polygon(sides);
        prop_assert_eq!(poly.len(), sides);
        prop_assert!(is_ccw_convex(&poly, 0.0));
        let parry = to_parry(&poly);
        let scale = e.a.max(e.b);
        for k in 0..360 {
            let t = k as f64 * std::f64::consts::TAU / 360.0;
            let local = V2::new(e.a * t.cos(), e.b * t.sin());
            let h = e.heading;
            let p = V2::new(h.x * local.x - h.y * local.y, h.y * local.x + h.x * local.y);
            prop_assert!(e.contains(p * 0.999_999));
            prop_assert!(poly.contains(p, 1e-12 * scale), "boundary point {:?} outside", p);
            // parry (f32, GJK-based queries) as the independent reference.
            let q = Point::new(p.x as f32, p.y as f32);
            let outside = parry.distance_to_local_point(&q, true) as f64;
            prop_assert!(outside <= 1e-4 * scale, "parry: {:?} is {} outside", p, outside);
        }
        // Conservative but tight: the area is exactly that of the circumscribed n-gon mapped to
        // the ellipse, n tan(pi/n) a b (parry computes the area independently).
        let n = sides as f64;
        let expected = n * (std::f64::consts::PI / n).tan() * e.a * e.b;
        let area = parry2d::shape::Shape::mass_properties(&parry, 1.0).mass() as f64;
        prop_assert!((area - expected).abs() <= 1e-4 * expected, "area {} vs {}", area, expected);
    }

    /// With an even number of sides the polygon is its own reflection bit for bit, so that the
    /// two agents of a pair see their obstacle as exact mirrors.
    #[test]
    fn even_polygons_are_exactly_centrally_symmetric((e, sides) in ellipse_strategy()) {
        let poly = e.polygon(sides);
        let pts = poly.points();
        let n = pts.len();
        if n % 2 == 0 {
            for k in 0..n {
                prop_assert_eq!(pts[(k + n / 2) % n], -pts[k], "vertex {}", k);
            }
        }
    }

    #[test]
    fn minkowski_sum_is_hull_of_pairwise_sums(
        (ea, na) in ellipse_strategy(),
        (eb, nb) in ellipse_strategy(),
        shift in (-200.0f64..200.0, -200.0f64..200.0),
    ) {
        let a = ea.polygon(na);
        let mut b = eb.polygon(nb);
        let offset = V2::new(shift.0, shift.1);
        b = Polygon::from_ccw(&b.points().iter().map(|p| p + offset).collect::<Vec<_>>());
        let sum = minkowski_sum(&a, &b);
        prop_assert!(sum.len() <= na + nb);
        let scale = ea.a.max(ea.b) + eb.a.max(eb.b) + offset.norm();
        prop_assert!(is_ccw_convex(&sum, 1e-9 * scale * scale));

        // Brute force in f64: a convex polygon whose vertices are pairwise sums and which holds
        // every pairwise sum is their convex hull.
        for p in a.points() {
            for q in b.points() {
                prop_assert!(sum.contains(p + q, 1e-9 * scale), "pairwise sum {:?} outside", p + q);
            }
        }
        for v in sum.points() {
            let is_sum = a.points().iter().any(|p| b.points().iter().any(|q| (p + q - v).norm() <= 1e-9 * scale));
            prop_assert!(is_sum, "vertex {:?} is not a pairwise sum", v);
        }

        let pairwise: Vec<Point<f32>> = a
            .points()
            .iter()
            .flat_map(|p| b.points().iter().map(move |q| p + q))
            .map(|s| Point::new(s.x as f32, s.y as f32))
            .collect();
        let hull = convex_hull(&pairwise);
        // parry works in f32 with GJK queries: a looser tolerance than the f64 check above.
        let tol = 1e-3 * scale;
        // Every hull vertex is a vertex of the sum...
        for h in &hull {
            let h = V2::new(h.x as f64, h.y as f64);
            let nearest = sum.points().iter().map(|p| (p - h).norm()).fold(f64::INFINITY, f64::min);
            prop_assert!(nearest <= tol, "hull vertex {:?} missing (off by {})", h, nearest);
        }
        // (The converse is the f64 brute-force check above: parry's f32 hull drops vertices
        // that are nearly collinear, so it cannot be the reference for that direction.)
    }
}

#[test]
fn degenerate_ellipses_give_small_valid_polygons() {
    for (l, w) in [
        (0.0, 0.0),
        (f64::NAN, 3.0),
        (-1.0, f64::INFINITY),
        (5.0, 0.0),
    ] {
        let e = Ellipse::new(l, w, V2::new(f64::NAN, 0.0));
        let p = e.polygon(8);
        assert_eq!(p.len(), 8);
        assert!(p
            .points()
            .iter()
            .all(|q| q.x.is_finite() && q.y.is_finite()));
        assert!(is_ccw_convex(&p, 0.0));
        assert_eq!(e.heading, V2::new(1.0, 0.0));
    }
    // Sides outside 3..=32 are clamped.
    let e = Ellipse::new(10.0, 5.0, V2::new(0.0, 1.0));
    assert_eq!(e.polygon(0).len(), 3);
    assert_eq!(e.polygon(1000).len(), 32);
}
