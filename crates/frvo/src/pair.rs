//! The hot path of the polygon crowd step: one pair's avoidance straight from the two agents'
//! prepared polygons, in one pass.
//!
//! It computes what [`crate::minkowski::merge_prepared`] followed by
//! [`crate::velocity_obstacle::avoidance`] computes, without building the obstacle's features
//! as a separate list: the merge carries each edge's unit normal from its source polygon (where
//! it was computed once per agent and step, not per pair), and the facing test of every edge is
//! made while it is merged. Only the features on whose outer side `w` lies can hold its nearest
//! boundary point, so only those are projected on. `tests/orca_reference.rs` checks the crowd
//! step built on this against the plain composition of the public pieces.

use crate::geometry::{cross, left_normal, lowest_vertex, right_normal, MAX_VERTICES, V2};
use crate::velocity_obstacle::{unit, Avoidance};

/// Edges whose pseudo-angles (see [`pseudo_angle`]) differ by at most this are merged as
/// parallel: a few times rounding noise, like [`crate::minkowski::PARALLEL_SIN`] for the
/// cross-product test.
const PARALLEL_ANGLE: f64 = 1e-9;
/// Past every pseudo-angle: ends each agent's edge list, so the merge needs no bounds test.
const SENTINEL_ANGLE: f64 = 8.0;

/// A number in `[0, 4)` that increases with the direction's angle in `[0, 2 pi)` (the "diamond
/// angle"): orders edges like `atan2` with one division.
#[inline]
fn pseudo_angle(d: V2) -> f64 {
    let s = d.x.abs() + d.y.abs();
    if s.is_nan() || s <= 0.0 {
        return 0.0;
    }
    let (x, y) = (d.x / s, d.y / s);
    match (y >= 0.0, x >= 0.0) {
        (true, true) => y,
        (true, false) => 1.0 - x,
        (false, false) => 2.0 - y,
        (false, true) => 3.0 + x,
    }
}

/// Every agent's polygon prepared for [`pair_avoidance`], in flat arrays: per agent `sides + 1`
/// points (from the lowest vertex, closed), and `sides + 1` edges, each with its unit outward
/// normal and its pseudo-angle (the last a sentinel: zero edge, angle past every other).
#[derive(Clone, Debug, Default)]
pub(crate) struct Shapes {
    sides: usize,
    pts: Vec<V2>,
    edges: Vec<Edge>,
}

/// An edge vector, its unit outward normal and its pseudo-angle (and that plus the tie margin).
#[derive(Clone, Copy, Debug)]
struct Edge {
    vec: V2,
    normal: V2,
    angle: f64,
    angle_hi: f64,
}

impl Edge {
    fn new(vec: V2, normal: V2, angle: f64) -> Self {
        Self {
            vec,
            normal,
            angle,
            angle_hi: angle + PARALLEL_ANGLE,
        }
    }

    /// Ends each agent's edge list: zero edge, angle past every other.
    const SENTINEL: Self = Self {
        vec: V2::new(0.0, 0.0),
        normal: V2::new(0.0, 0.0),
        angle: SENTINEL_ANGLE,
        angle_hi: SENTINEL_ANGLE,
    };
}

/// One agent's prepared polygon.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Prepared<'a> {
    pts: &'a [V2],
    edges: &'a [Edge],
}

impl Shapes {
    /// Empties the arrays; every polygon pushed next must have `sides` vertices.
    pub(crate) fn reset(&mut self, sides: usize) {
        self.sides = sides;
        self.pts.clear();
        self.edges.clear();
    }

    /// Appends polygon `k` of `shapes` reflected through the origin (what [`Shapes::push`] of
    /// the negated vertices gives, without its square roots and divisions: the lowest vertex of
    /// the reflection is the reflected highest one, and every edge turns by half a circle).
    pub(crate) fn push_negated(&mut self, shapes: &Shapes, k: usize) {
        let src = shapes.get(k);
        let n = src.pts.len() - 1;
        debug_assert_eq!(n, self.sides);
        // Highest vertex: largest y, then largest x (the reflection's smallest y, smallest x).
        let mut top = 0;
        for (i, q) in src.pts[..n].iter().enumerate() {
            let t = src.pts[top];
            if q.y > t.y || (q.y == t.y && q.x > t.x) {
                top = i;
            }
        }
        for i in (top..n).chain(0..=top) {
            self.pts.push(-src.pts[i]);
        }
        for i in (top..n).chain(0..top) {
            let e = src.edges[i];
            let angle = if e.angle >= 2.0 {
                e.angle - 2.0
            } else {
                e.angle + 2.0
            };
            self.edges.push(Edge::new(-e.vec, -e.normal, angle));
        }
        self.edges.push(Edge::SENTINEL);
    }

    /// Appends a counter-clockwise polygon of `sides` vertices.
    pub(crate) fn push(&mut self, poly: &[V2]) {
        debug_assert_eq!(poly.len(), self.sides);
        let start = lowest_vertex(poly);
        let first = self.pts.len();
        self.pts.extend_from_slice(&poly[start..]);
        self.pts.extend_from_slice(&poly[..start]);
        self.pts.push(poly[start]);
        for k in first..first + poly.len() {
            let vec = self.pts[k + 1] - self.pts[k];
            // Never NaN (an overflowing polygon): the merge's walks then only both advance on
            // a tie, and never past their sentinels.
            let angle = pseudo_angle(vec);
            let angle = if angle.is_nan() { 0.0 } else { angle };
            self.edges
                .push(Edge::new(vec, unit(right_normal(vec)), angle));
        }
        self.edges.push(Edge::SENTINEL);
    }

    #[inline]
    pub(crate) fn get(&self, k: usize) -> Prepared<'_> {
        let n = self.sides + 1;
        Prepared {
            pts: &self.pts[k * n..(k + 1) * n],
            edges: &self.edges[k * n..(k + 1) * n],
        }
    }
}

/// The merged polygon of one pair: vertex `k` (without the offset `p`), the edge leaving it and
/// that edge's unit outward normal. Reused between pairs.
#[derive(Clone, Debug)]
pub(crate) struct PairScratch {
    v: [V2; MAX_VERTICES],
    e: [V2; MAX_VERTICES],
    n: [V2; MAX_VERTICES],
}

impl Default for PairScratch {
    fn default() -> Self {
        Self {
            v: [V2::zeros(); MAX_VERTICES],
            e: [V2::zeros(); MAX_VERTICES],
            n: [V2::zeros(); MAX_VERTICES],
        }
    }
}

/// Avoidance for relative position `p = pos_b - pos_a` and relative velocity `w = v_a - v_b`,
/// from B's polygon and A's negated polygon (so the obstacle is `P = p + B ⊕ (-A)`): the
/// truncated cone for horizon `tau` when the shapes are apart, `P / dt` when they overlap (see
/// [`crate::velocity_obstacle`]).
///
/// Swapping the agents negates `p`, `w` and every vertex, normal and edge, so each number of
/// the computation is negated or unchanged, bit for bit; only the merge starts elsewhere. The
/// result is therefore the exact negation, except that of two features at exactly the same
/// distance the other may be named: a caller may reuse it for the reverse pair.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must advance both walks, see below
pub(crate) fn pair_avoidance(
    p: V2,
    w: V2,
    b: Prepared<'_>,
    neg_a: Prepared<'_>,
    tau: f64,
    dt: f64,
    out: &mut PairScratch,
) -> Avoidance {
    let (n, m) = (b.edges.len() - 1, neg_a.edges.len() - 1);
    if n == 0 || m == 0 || b.pts.len() <= n || neg_a.pts.len() <= m {
        return Avoidance {
            u: V2::zeros(),
            normal: V2::zeros(),
        };
    }
    // Merge the edges in angle order (the smaller pseudo-angle first; both when within
    // PARALLEL_ANGLE), recording whether each faces the origin (lies on the
    // origin's inner side): bit k of `facing`, the same test as `velocity_obstacle`'s. An
    // exhausted walk rests on its sentinel, whose angle is past every other.
    let (mut i, mut j, mut k) = (0usize, 0usize, 0usize);
    let mut facing = 0u64;
    // Every step advances at least one walk (two angles cannot each exceed the other by the
    // margin), and neither passes its sentinel before the other's is reached: n + m steps at
    // most, within MAX_VERTICES since each polygon has at most MAX_SIDES.
    while i + j < n + m && k < MAX_VERTICES {
        let (eb, ea) = (b.edges[i], neg_a.edges[j]);
        let adv_b = !(ea.angle_hi < eb.angle);
        let adv_a = !(eb.angle_hi < ea.angle);
        let v = b.pts[i] + neg_a.pts[j];
        let zero = V2::zeros();
        let e = (if adv_b { eb.vec } else { zero }) + (if adv_a { ea.vec } else { zero });
        // Arithmetic, not a branch: which walk advances is data-dependent.
        let take_b = f64::from(u8::from(adv_b));
        let normal = eb.normal * take_b + ea.normal * (1.0 - take_b);
        facing |= u64::from(cross(e, -(p + v)) < 0.0) << k;
        (out.v[k], out.e[k], out.n[k]) = (v, e, normal);
        i += usize::from(adv_b);
        j += usize::from(adv_a);
        k += 1;
    }
    let len = k;
    // The facing edges of a convex polygon are one contiguous run (none when the origin is
    // inside); it starts at a facing edge whose predecessor does not face.
    let first = if len >= 3 {
        let prev = facing << 1 | facing >> (len - 1);
        let starts = facing & !prev & (u64::MAX >> (64 - len));
        (starts != 0).then(|| starts.trailing_zeros() as usize)
    } else {
        None
    };
    let next = |k: usize| if k + 1 == len { 0 } else { k + 1 };
    match first {
        Some(first) => {
            // Apart: the cap is the facing run of P / tau, the legs the rays from the origin
            // through its end vertices.
            let inv_tau = 1.0 / tau;
            let mut last = first;
            let mut count = 0;
            while facing >> last & 1 == 1 && count < len {
                last = next(last);
                count += 1;
            }
            let start = p + out.v[first];
            let end = p + out.v[last];
            let legs = [
                (start * inv_tau, start, unit(left_normal(start))),
                (end * inv_tau, end, unit(right_normal(end))),
            ];
            nearest(w, inv_tau, p, out, first, count, len, &legs)
        }
        None => nearest(w, 1.0 / dt, p, out, 0, len, len, &[]),
    }
}

/// Nearest boundary point to `w` of the convex region bounded by the `count` merged edges from
/// `first` (cyclically, scaled by `scale` about the origin after offsetting by `p`) and the
/// `legs` (rays: start, direction, unit outward normal).
#[allow(clippy::too_many_arguments)]
#[inline]
fn nearest(
    w: V2,
    scale: f64,
    p: V2,
    poly: &PairScratch,
    first: usize,
    count: usize,
    len: usize,
    legs: &[(V2, V2, V2)],
) -> Avoidance {
    // Signed distance of `w` outside each feature's supporting line. Inside the region (all
    // <= 0) the nearest boundary point lies on the nearest line. (Recomputed below rather
    // than stored: an array for them cost a zero-fill per pair.)
    let side = |k: usize| (w - (p + poly.v[k]) * scale).dot(&poly.n[k]);
    let next = |k: usize| if k + 1 == len { 0 } else { k + 1 };
    let mut best_sd = f64::NEG_INFINITY;
    let mut best_normal = V2::zeros();
    let mut k = first;
    for _ in 0..count {
        let d = side(k);
        if d > best_sd {
            best_sd = d;
            best_normal = poly.n[k];
        }
        k = next(k);
    }
    for &(start, _, normal) in legs {
        let d = (w - start).dot(&normal);
        if d > best_sd {
            best_sd = d;
            best_normal = normal;
        }
    }
    if best_sd == f64::NEG_INFINITY {
        return Avoidance {
            u: V2::zeros(),
            normal: V2::zeros(),
        };
    }
    if best_sd <= 0.0 {
        return Avoidance {
            u: -best_sd * best_normal,
            normal: best_normal,
        };
    }
    // Outside: the nearest point lies on a feature whose line `w` is outside of (at a vertex,
    // on one of the two features meeting there), so only those are projected on; the margin
    // keeps features whose distances are rounding noise (at contact the legs and the cap can
    // be collinear, and skipping one of them would pick a far point).
    let margin = -1e-9 * (1.0 + w.norm_squared() + (p * scale).norm_squared());
    let mut best_d2 = f64::INFINITY;
    let mut best = (w, best_normal);
    let mut k = first;
    for _ in 0..count {
        if side(k) > margin {
            let start = (p + poly.v[k]) * scale;
            let edge = poly.e[k] * scale;
            let e2 = edge.norm_squared();
            let t = if e2 > 0.0 {
                ((w - start).dot(&edge) / e2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let c = start + t * edge;
            let d2 = (w - c).norm_squared();
            if d2 < best_d2 {
                best_d2 = d2;
                best = (c, poly.n[k]);
            }
        }
        k = next(k);
    }
    for &(start, dir, normal) in legs {
        if (w - start).dot(&normal) > margin {
            let e2 = dir.norm_squared();
            let t = if e2 > 0.0 {
                ((w - start).dot(&dir) / e2).max(0.0)
            } else {
                0.0
            };
            let c = start + t * dir;
            let d2 = (w - c).norm_squared();
            if d2 < best_d2 {
                best_d2 = d2;
                best = (c, normal);
            }
        }
    }
    let (c, fallback) = best;
    let d = best_d2.sqrt();
    let normal = if d > 1e-12 { (w - c) / d } else { fallback };
    Avoidance { u: c - w, normal }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Ellipse;
    use crate::minkowski::minkowski_sum;
    use crate::velocity_obstacle::avoidance;
    use proptest::prelude::*;
    use proptest::test_runner::RngSeed;

    fn check(
        (la, wa, ha): (f64, f64, f64),
        (lb, wb, hb): (f64, f64, f64),
        sides: usize,
        p: V2,
        w: V2,
        tau: f64,
        dt: f64,
    ) -> Result<(), TestCaseError> {
        let unit_v = |t: f64| V2::new(t.cos(), t.sin());
        let a = Ellipse::new(la, wa, unit_v(ha)).polygon(sides);
        let b = Ellipse::new(lb, wb, unit_v(hb)).polygon(sides);
        let reference = avoidance(p, &minkowski_sum(&b, &a.negated()), w, tau, dt);
        let (mut sb, mut sa) = (Shapes::default(), Shapes::default());
        sb.reset(sides);
        sa.reset(sides);
        sb.push(b.points());
        sa.push(a.negated().points());
        let fast = pair_avoidance(
            p,
            w,
            sb.get(0),
            sa.get(0),
            tau,
            dt,
            &mut PairScratch::default(),
        );
        prop_assert!(
            (fast.u - reference.u).norm() <= 1e-9 * (1.0 + reference.u.norm()),
            "u {:?} vs {:?}",
            fast.u,
            reference.u
        );
        prop_assert!(
            (fast.normal - reference.normal).norm() <= 1e-9,
            "normal {:?} vs {:?}",
            fast.normal,
            reference.normal
        );
        Ok(())
    }

    /// `push_negated` is `push` of the negated vertices, without recomputing.
    #[test]
    fn push_negated_matches_push() {
        for sides in 3..=16 {
            for t in 0..40 {
                let h = V2::new((t as f64 * 0.37).cos(), (t as f64 * 0.37).sin());
                let poly = Ellipse::new(10.0 + t as f64, 30.0 - 0.5 * t as f64, h).polygon(sides);
                let mut shapes = Shapes::default();
                shapes.reset(sides);
                shapes.push(poly.points());
                let (mut fast, mut slow) = (Shapes::default(), Shapes::default());
                fast.reset(sides);
                slow.reset(sides);
                fast.push_negated(&shapes, 0);
                slow.push(poly.negated().points());
                assert_eq!(fast.pts, slow.pts, "sides {sides} t {t}");
                for (f, s) in fast.edges.iter().zip(&slow.edges) {
                    assert_eq!((f.vec, f.normal), (s.vec, s.normal), "sides {sides} t {t}");
                    assert!((f.angle - s.angle).abs() < 1e-12, "sides {sides} t {t}");
                }
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            cases: 3000,
            rng_seed: RngSeed::Fixed(0x9a1e),
            failure_persistence: None,
            ..ProptestConfig::default()
        })]

        #[test]
        fn matches_merge_then_avoidance(
            a in (5.0f64..40.0, 5.0f64..40.0, 0.0f64..std::f64::consts::TAU),
            b in (5.0f64..40.0, 5.0f64..40.0, 0.0f64..std::f64::consts::TAU),
            sides in 3usize..=16,
            dist in 0.0f64..120.0, angle in 0.0f64..std::f64::consts::TAU,
            w in (-20.0f64..20.0, -20.0f64..20.0),
            tau in 1.0f64..20.0,
            dt in prop::sample::select(vec![0.5, 1.0, 2.0]),
        ) {
            let p = V2::new(angle.cos(), angle.sin()) * dist;
            check(a, b, sides, p, V2::new(w.0, w.1), tau, dt)?;
        }

        /// Same shape and heading (every edge pair parallel), near contact.
        #[test]
        fn matches_for_equal_shapes(
            a in (5.0f64..40.0, 5.0f64..40.0, prop::sample::select(vec![0.0, 0.5 * std::f64::consts::PI, 1.0, std::f64::consts::PI])),
            sides in 3usize..=16,
            dist in 0.0f64..60.0, angle in 0.0f64..std::f64::consts::TAU,
            w in (-5.0f64..5.0, -5.0f64..5.0),
            tau in 1.0f64..20.0,
            dt in prop::sample::select(vec![0.5, 1.0, 2.0]),
        ) {
            let p = V2::new(angle.cos(), angle.sin()) * dist;
            check(a, a, sides, p, V2::new(w.0, w.1), tau, dt)?;
        }
    }
}
