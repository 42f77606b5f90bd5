//! Polygon velocity obstacles against the exact disc formulas and a brute-force membership test.

use frvo::geometry::{Ellipse, V2};
use frvo::minkowski::minkowski_sum;
use frvo::velocity_obstacle::{avoidance, avoidance_circle};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(0x0b57_ac1e),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

proptest! {
    #![proptest_config(config(1000))]

    /// Discs as 32-gons: the polygon obstacle's avoidance approaches the exact disc one.
    #[test]
    fn polygon_discs_match_exact_discs(
        ra in 5.0f64..30.0, rb in 5.0f64..30.0,
        dist in 0.0f64..300.0, angle in 0.0f64..std::f64::consts::TAU,
        w in (-10.0f64..10.0, -10.0f64..10.0),
        tau in 1.0f64..30.0,
    ) {
        let x = V2::new(1.0, 0.0);
        let a = Ellipse::new(2.0 * ra, 2.0 * ra, x).polygon(32);
        let b = Ellipse::new(2.0 * rb, 2.0 * rb, x).polygon(32);
        let sum = minkowski_sum(&b, &a.negated());
        let p = V2::new(angle.cos(), angle.sin()) * dist;
        let w = V2::new(w.0, w.1);
        let poly = avoidance(p, &sum, w, tau, 1.0);
        let disc = avoidance_circle(p, ra + rb, w, tau, 1.0);
        // The 32-gon is at most 0.5% larger than the disc, and its side normals are quantised
        // to 11.25 degrees: allow for both.
        let tol = 0.02 * (ra + rb) / if dist > ra + rb { tau } else { 1.0 } + 1e-9;
        prop_assert!((poly.u - disc.u).norm() <= tol + 0.1 * disc.u.norm(),
            "u {:?} vs {:?}", poly.u, disc.u);
        if disc.u.norm() > 10.0 * tol {
            prop_assert!((poly.normal - disc.normal).norm() <= 0.2,
                "normal {:?} vs {:?}", poly.normal, disc.normal);
        }
    }

    /// Membership by brute force: `w` is in the obstacle iff `t w` lies in `P = p + B ⊕ (-A)`
    /// for some `t` in `(0, tau]`; `avoidance` says inside when `u` points along the normal.
    #[test]
    fn polygon_obstacle_membership_matches_brute_force(
        (la, wa, ha) in (5.0f64..40.0, 5.0f64..40.0, 0.0f64..std::f64::consts::TAU),
        (lb, wb, hb) in (5.0f64..40.0, 5.0f64..40.0, 0.0f64..std::f64::consts::TAU),
        sides in 3usize..=16,
        dist in 45.0f64..200.0, angle in 0.0f64..std::f64::consts::TAU,
        w in (-20.0f64..20.0, -20.0f64..20.0),
        tau in 1.0f64..20.0,
    ) {
        let unit = |t: f64| V2::new(t.cos(), t.sin());
        let a = Ellipse::new(la, wa, unit(ha)).polygon(sides);
        let b = Ellipse::new(lb, wb, unit(hb)).polygon(sides);
        let sum = minkowski_sum(&b, &a.negated());
        let p = unit(angle) * dist;
        let w = V2::new(w.0, w.1);
        let av = avoidance(p, &sum, w, tau, 1.0);
        let shifted: Vec<V2> = sum.points().iter().map(|q| q + p).collect();
        let poly = frvo::geometry::Polygon::from_ccw(&shifted);
        prop_assume!(!poly.contains(V2::zeros(), 0.0));
        let steps = 4000;
        let hit = (1..=steps).any(|k| poly.contains(w * (tau * k as f64 / steps as f64), 0.0));
        let depth = av.u.norm();
        prop_assume!(depth > 0.05 * w.norm().max(1.0)); // clear of the boundary
        let inside = av.u.dot(&av.normal) > 0.0;
        prop_assert_eq!(inside, hit, "u {:?} n {:?}", av.u, av.normal);
        // And w + u lies on the boundary: just beyond it along the normal is outside.
        let edge = w + av.u;
        let out = edge + av.normal * 1e-6 * depth.max(1.0);
        let out_hit = (1..=steps).any(|k| poly.contains(out * (tau * k as f64 / steps as f64), 0.0));
        prop_assert!(!out_hit || !inside, "boundary point {:?} not on the boundary", edge);
    }

    /// The reciprocal half-plane is only safe if its line supports the whole obstacle: every
    /// point of `VO = { s x : x in P, s >= 1/tau }` (or `P / dt` when overlapping) lies on the
    /// inner side of the line through `w + u` with normal `n`. Checked on the brute-force
    /// pairwise vertex sums, for shapes with the same heading and size (their polygons have
    /// parallel edges) placed at or near contact, where the tangent search is ill-conditioned.
    #[test]
    fn half_plane_supports_obstacle_at_contact(
        (l, wid, h) in (5.0f64..40.0, 5.0f64..60.0, 0.0f64..std::f64::consts::TAU),
        same_shape in any::<bool>(),
        (lb, wb, hb) in (5.0f64..40.0, 5.0f64..60.0, 0.0f64..std::f64::consts::TAU),
        sides in 3usize..=16,
        (edge, along) in (0usize..64, 0.0f64..1.0),
        gap in prop::sample::select(vec![-1e-3, -1e-9, 0.0, 0.0, 0.0, 1e-12, 1e-9, 1e-3, 0.5]),
        w in (-8.0f64..8.0, -8.0f64..8.0),
        tau in 1.0f64..20.0,
    ) {
        let unit = |t: f64| V2::new(t.cos(), t.sin());
        let a = Ellipse::new(l, wid, unit(h)).polygon(sides);
        let b = if same_shape {
            a
        } else {
            Ellipse::new(lb, wb, unit(hb)).polygon(sides)
        };
        let sum = minkowski_sum(&b, &a.negated());
        // Touching: the origin on a point of an edge of P = p + sum, then moved out by `gap`.
        let pts = sum.points();
        let k = edge % pts.len();
        let (q0, q1) = (pts[k], pts[(k + 1) % pts.len()]);
        let outward = V2::new(q1.y - q0.y, q0.x - q1.x).normalize();
        let p = -(q0 + (q1 - q0) * along + outward * gap);
        let w = V2::new(w.0, w.1);
        let dt = 1.0;
        let av = avoidance(p, &sum, w, tau, dt);
        prop_assert!(av.normal.norm() > 0.5, "no normal: {:?}", av);
        let c = w + av.u;
        let tol = 1e-7 * (1.0 + p.norm());
        // Whether apart or overlapping (at contact either reading is fair), the obstacle
        // contains P / tau and P / dt; clearly apart, it also holds the rays through P.
        for qb in b.points() {
            for qa in a.points() {
                let x = p + qb - qa;
                for s in [1.0 / tau, 1.0 / dt] {
                    prop_assert!((x * s - c).dot(&av.normal) <= tol,
                        "obstacle point {:?} beyond the line (gap {}, {:?})", x * s, gap, av);
                }
                if gap > 1e-6 {
                    prop_assert!(x.dot(&av.normal) <= tol,
                        "cone direction {:?} crosses the line (gap {}, {:?})", x, gap, av);
                }
            }
        }
    }
}
