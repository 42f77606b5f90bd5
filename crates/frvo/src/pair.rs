//! The hot path of the polygon crowd step: one pair's avoidance straight from the two agents'
//! prepared polygons, in one pass.
//!
//! It computes what [`crate::minkowski::merge_prepared`] followed by
//! [`crate::velocity_obstacle::avoidance`] computes, without building the obstacle's features
//! as a separate list: the merge carries each edge's unit normal from its source polygon (where
//! it was computed once per agent and step, not per pair), and the facing test of every edge is
//! made while it is merged. For symmetric shapes only the first half of the sum is merged and
//! the other half is read as its reflection, never written out. Only the cap (the facing run)
//! and the legs are visited when the shapes are apart, in one pass without data-dependent
//! branches. `tests/orca_reference.rs` checks the crowd step built on this against the plain
//! composition of the public pieces.

use crate::geometry::{left_normal, lowest_vertex, right_normal, MAX_VERTICES, V2};
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
    // Every quadrant's value, then selects: the quadrant follows no pattern a branch predictor
    // could learn.
    let (upper, right) = (y >= 0.0, x >= 0.0);
    let above = if right { y } else { 1.0 - x };
    let below = if right { 3.0 + x } else { 2.0 - y };
    if upper {
        above
    } else {
        below
    }
}

/// Every agent's polygon prepared for [`pair_avoidance`], in one flat array. Per agent, from
/// the lowest vertex: each edge with its start vertex, unit outward normal and pseudo-angle,
/// then a sentinel (the next vertex, zero normal, an angle past every other). A polygon that
/// is its own reflection through the origin (an even number of sides, see
/// [`crate::geometry::UnitPolygon::is_symmetric`]) keeps only its first half of edges, those
/// with pseudo-angles in `[0, 2)`: the other half is their negation, and the Minkowski sum of
/// two such polygons is symmetric too, so only its first half is merged.
#[derive(Clone, Debug, Default)]
pub(crate) struct Shapes {
    sides: usize,
    symmetric: bool,
    /// Edges per polygon with the sentinel: kept, not worked out on every `get`.
    stride: usize,
    edges: Vec<Edge>,
}

/// An edge's start vertex, unit outward normal and pseudo-angle (and that plus the tie
/// margin). The edge vector itself is not kept: the pair computation takes it from the merged
/// vertices.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Edge {
    start: V2,
    normal: V2,
    angle: f64,
    angle_hi: f64,
}

impl Edge {
    fn new(start: V2, normal: V2, angle: f64) -> Self {
        Self {
            start,
            normal,
            angle,
            angle_hi: angle + PARALLEL_ANGLE,
        }
    }

    /// Ends each agent's edge list at the next vertex: zero normal, angle past every other.
    fn sentinel(start: V2) -> Self {
        Self {
            start,
            normal: V2::zeros(),
            angle: SENTINEL_ANGLE,
            angle_hi: SENTINEL_ANGLE,
        }
    }
}

/// One agent's prepared polygon: its stored edges and the sentinel.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Prepared<'a> {
    edges: &'a [Edge],
    symmetric: bool,
}

impl Shapes {
    /// Empties the array; every polygon pushed next must have `sides` vertices and, with
    /// `symmetric` (which needs an even `sides`), be its own reflection bit for bit.
    pub(crate) fn reset(&mut self, sides: usize, symmetric: bool) {
        debug_assert!(!symmetric || sides % 2 == 0);
        self.sides = sides;
        self.symmetric = symmetric && sides % 2 == 0;
        self.stride = self.stored() + 1;
        self.edges.clear();
    }

    /// Edges stored per polygon (without the sentinel).
    fn stored(&self) -> usize {
        if self.symmetric {
            self.sides / 2
        } else {
            self.sides
        }
    }

    /// Appends polygon `k` of `shapes` (not symmetric ones, which are their own reflection)
    /// reflected through the origin: what [`Shapes::push`] of the negated vertices gives,
    /// without its square roots and divisions (the lowest vertex of the reflection is the
    /// reflected highest one, and every edge turns by half a circle).
    pub(crate) fn push_negated(&mut self, shapes: &Shapes, k: usize) {
        debug_assert!(!shapes.symmetric && !self.symmetric);
        let src = shapes.get(k).edges;
        let n = src.len() - 1;
        debug_assert_eq!(n, self.sides);
        // Highest vertex: largest y, then largest x (the reflection's smallest y, smallest x).
        let mut top = 0;
        for (i, e) in src[..n].iter().enumerate() {
            let (q, t) = (e.start, src[top].start);
            if q.y > t.y || (q.y == t.y && q.x > t.x) {
                top = i;
            }
        }
        for i in (top..n).chain(0..top) {
            let e = src[i];
            let angle = if e.angle >= 2.0 {
                e.angle - 2.0
            } else {
                e.angle + 2.0
            };
            self.edges.push(Edge::new(-e.start, -e.normal, angle));
        }
        self.edges.push(Edge::sentinel(-src[top].start));
    }

    /// Appends a counter-clockwise polygon of `sides` vertices.
    pub(crate) fn push(&mut self, poly: &[V2]) {
        debug_assert_eq!(poly.len(), self.sides);
        let n = poly.len();
        let start = lowest_vertex(poly);
        // Vertex `start + k` for `k <= n`: one subtraction, not a division, wraps it.
        let at = |k: usize| {
            let i = start + k;
            poly[if i >= n { i - n } else { i }]
        };
        let mut from = at(0);
        // A range, so `extend` reserves once instead of checking the capacity per edge.
        self.edges.extend((1..self.stored() + 1).map(|k| {
            let to = at(k);
            let vec = to - from;
            // Never NaN (an overflowing polygon): the merge's walks then only both advance on
            // a tie, and never past their sentinels.
            let angle = pseudo_angle(vec);
            let angle = if angle.is_nan() { 0.0 } else { angle };
            let edge = Edge::new(from, unit(right_normal(vec)), angle);
            from = to;
            edge
        }));
        self.edges.push(Edge::sentinel(from));
    }

    /// Appends every polygon of `other` (prepared with the same `reset`).
    pub(crate) fn append(&mut self, other: &Shapes) {
        debug_assert!(self.sides == other.sides && self.symmetric == other.symmetric);
        self.edges.extend_from_slice(&other.edges);
    }

    #[inline]
    pub(crate) fn get(&self, k: usize) -> Prepared<'_> {
        let n = self.stride;
        Prepared {
            edges: &self.edges[k * n..][..n],
            symmetric: self.symmetric,
        }
    }
}

/// One merged edge: its start vertex `v` without the offset `p`, its unit outward normal `n`,
/// and the signed offsets from the origin of its line and of its reflection's (`-v`, `-n`),
/// `h = [p · n + v · n, v · n - p · n]` (negative: the edge faces the origin).
#[derive(Clone, Copy, Debug, Default)]
struct Merged {
    v: V2,
    n: V2,
    h: [f64; 2],
}

/// The merged edges of one pair (for symmetric shapes the first half of the sum, whose edge
/// `k + half` is edge k's reflection), edge k running from `edges[k].v` to `edges[k + 1].v`:
/// after the last stored edge comes the vertex that closes the polygon (`v[0]`) or, for a
/// half, the reflected first vertex (`-v[0]`). Reused between pairs.
#[derive(Clone, Debug)]
pub(crate) struct PairScratch {
    edges: [Merged; MAX_VERTICES + 1],
    /// The nearest point, normal and frame of each feature in [`nearest`] (after slot 0).
    feats: [(V2, V2, usize); MAX_VERTICES + 3],
}

impl Default for PairScratch {
    fn default() -> Self {
        Self {
            edges: [Merged::default(); MAX_VERTICES + 1],
            feats: [(V2::zeros(), V2::zeros(), 0); MAX_VERTICES + 3],
        }
    }
}

/// Avoidance for relative position `p = pos_b - pos_a` and relative velocity `w = v_a - v_b`,
/// from B's polygon and A's negated polygon (so the obstacle is `P = p + B ⊕ (-A)`; for
/// symmetric shapes A's own polygon is its negation): the truncated cone for horizon `tau`
/// when the shapes are apart, `P / dt` when they overlap (see [`crate::velocity_obstacle`]).
///
/// Swapping the agents negates `p`, `w` and the obstacle, so the reverse pair's avoidance is
/// this one negated, up to rounding (of two parallel edges the merged one takes B's normal,
/// and of two features at exactly the same distance either may be named): a caller may reuse
/// it for the reverse pair.
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
    debug_assert_eq!(b.symmetric, neg_a.symmetric);
    let (b, neg_a, mirror) = (b.edges, neg_a.edges, b.symmetric);
    if b.len() < 2 || neg_a.len() < 2 {
        return Avoidance {
            u: V2::zeros(),
            normal: V2::zeros(),
        };
    }
    // Merge the edges in angle order (the smaller pseudo-angle first; both when within
    // PARALLEL_ANGLE), recording whether each faces the origin (the origin lies on its outer
    // side: h < 0) in `facing`, and whether its reflection does in `facing_m`, shifted in
    // from bit 0 (one shift, not one by k: edge k ends in bit `half - 1 - k`). An exhausted
    // walk rests on its sentinel, whose angle is past every other.
    let (n, m) = (b.len() - 1, neg_a.len() - 1);
    let (mut i, mut j, mut k) = (0usize, 0usize, 0usize);
    let (mut facing, mut facing_m) = (0u64, 0u64);
    // Every step advances at least one walk (two angles cannot each exceed the other by the
    // margin), and neither passes its sentinel before the other's is reached: n + m steps at
    // most, within MAX_VERTICES since each polygon has at most MAX_SIDES.
    while i + j < n + m && k < MAX_VERTICES {
        // Neither walk passes its sentinel (see above): the clamps only spare bounds checks,
        // whose branches would cost more than the selects.
        let (eb, ea) = (b[i.min(n)], neg_a[j.min(m)]);
        let adv_b = !(ea.angle_hi < eb.angle);
        let adv_a = !(eb.angle_hi < ea.angle);
        let v = eb.start + ea.start;
        // Parallel edges merge into one with B's normal.
        let normal = if adv_b { eb.normal } else { ea.normal };
        let (along_p, along_v) = (p.dot(&normal), v.dot(&normal));
        let (h, hm) = (along_p + along_v, along_v - along_p);
        facing = facing << 1 | u64::from(h < 0.0);
        facing_m = facing_m << 1 | u64::from(hm < 0.0);
        out.edges[k] = Merged {
            v,
            n: normal,
            h: [h, hm],
        };
        i += usize::from(adv_b);
        j += usize::from(adv_a);
        k += 1;
    }
    // The reflected half is not written out: edge `half + r` is read as edge r reflected
    // (see `Run` and `nearest`).
    let half = k;
    let mirror = mirror && 2 * half <= MAX_VERTICES;
    // Edge k (of `len`) in bit `len - 1 - k`.
    let (len, closing) = if mirror {
        facing = facing << half | facing_m;
        (2 * half, -out.edges[0].v)
    } else {
        (half, out.edges[0].v)
    };
    out.edges[half].v = closing;
    // The facing edges of a convex polygon are one contiguous run (none when the origin is
    // inside); it starts at a facing edge whose predecessor (the bit above) does not face.
    let first = if len >= 3 {
        let prev = facing >> 1 | facing << (len - 1);
        let starts = facing & !prev & (u64::MAX >> (64 - len));
        (starts != 0).then(|| starts.leading_zeros() as usize + len - 64)
    } else {
        None
    };
    let Some(first) = first else {
        return overlapping(w, 1.0 / dt, p, out, half, mirror);
    };
    // Apart: the cap is the facing run of P / tau, the legs the rays from the origin through
    // its end vertices. The run ends where the facing bits (rotated to start at `first` in
    // the top bit) first stop.
    let rotated = (facing << first | facing >> (len - first)) & (u64::MAX >> (64 - len));
    let count = (!(rotated << (64 - len))).leading_zeros().min(len as u32) as usize;
    let run = Run::at(first, half, mirror);
    nearest(w, 1.0 / tau, p, out, run, count, true)
}

/// A position on the merged polygon's boundary: stored edge `r`, or its reflection (edge
/// `half + r` of a symmetric sum) when `neg` is 1.
#[derive(Clone, Copy)]
struct Run {
    r: usize,
    neg: usize,
    half: usize,
    /// 1 for a symmetric sum (the reflection follows the stored half), else 0.
    flip: usize,
}

/// By `Run::neg`: a table, not a branch, since the sign changes along the run.
const SIGN: [f64; 2] = [1.0, -1.0];

impl Run {
    fn at(k: usize, half: usize, mirror: bool) -> Self {
        let reflected = k >= half;
        Self {
            r: if reflected { k - half } else { k },
            neg: usize::from(reflected),
            half,
            flip: usize::from(mirror),
        }
    }

    /// The next edge, cyclically: past the stored half, the first stored edge or its
    /// reflection.
    fn advance(&mut self) {
        let wrap = self.r + 1 == self.half;
        self.r = if wrap { 0 } else { self.r + 1 };
        self.neg ^= usize::from(wrap) & self.flip;
    }

    /// The stored edge (`r < half <= MAX_VERTICES`: the modulo only spares bounds checks).
    fn index(&self) -> usize {
        self.r % MAX_VERTICES
    }

    /// The current edge's start vertex.
    fn vertex(&self, edges: &[Merged]) -> V2 {
        edges[self.index()].v * SIGN[self.neg]
    }
}

/// Overlapping shapes: the nearest boundary point of `P / dt` (`scale = 1 / dt`). `w` is
/// usually inside, where only the supporting lines' distances matter: they are found from the
/// stored half alone (an edge and its reflection share `w · n`), and only from outside is the
/// boundary projected on.
fn overlapping(
    w: V2,
    scale: f64,
    p: V2,
    poly: &mut PairScratch,
    half: usize,
    mirror: bool,
) -> Avoidance {
    // The farthest line, the first in edge order of equal distances: the farthest of the
    // stored edges and of their reflections are kept apart, the stored one winning ties, as a
    // walk over the whole polygon would find it (indices selected, not vectors, see `nearest`).
    let (mut best, mut best_at) = (f64::NEG_INFINITY, 0);
    let (mut best_m, mut best_m_at) = (f64::NEG_INFINITY, 0);
    for (k, e) in poly.edges[..half].iter().enumerate() {
        let along_w = w.dot(&e.n);
        let (d, d_m) = (along_w - scale * e.h[0], -along_w - scale * e.h[1]);
        let better = d > best;
        best = if better { d } else { best };
        best_at = if better { k } else { best_at };
        let better = d_m > best_m;
        best_m = if better { d_m } else { best_m };
        best_m_at = if better { k } else { best_m_at };
    }
    let (best_sd, best_normal) = if mirror && best_m > best {
        (best_m, -poly.edges[best_m_at].n)
    } else {
        (best, poly.edges[best_at].n)
    };
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
    let len = if mirror { 2 * half } else { half };
    nearest(w, scale, p, poly, Run::at(0, half, mirror), len, false)
}

/// Nearest boundary point to `w` of the convex region bounded by the `count` merged edges
/// from `run` (scaled by `scale` about the origin after offsetting by `p`) and, with `legs`,
/// the rays from the origin through the run's end vertices.
#[inline(always)]
fn nearest(
    w: V2,
    scale: f64,
    p: V2,
    poly: &mut PairScratch,
    mut run: Run,
    count: usize,
    legs: bool,
) -> Avoidance {
    // One pass over the features, with selects rather than branches (which feature is nearest
    // is data-dependent): the signed distance of `w` outside each supporting line (inside the
    // region, all <= 0, the nearest boundary point lies on the farthest line), and the nearest
    // point of each feature whose line `w` is outside of (from outside, the nearest boundary
    // point lies on one of those; the margin keeps features whose distances are rounding
    // noise: at contact the legs and the cap can be collinear, and skipping one of them would
    // pick a far point). Ties go to the first feature in order.
    let margin = -1e-9 * (1.0 + w.norm_squared() + (p * scale).norm_squared());
    // A reflected edge is worked on as the stored one with `p` and `w` reflected, and the
    // point and normal found are reflected back: negating is exact, so every number is the
    // same up to sign as with the reflected edge itself.
    let frame = [(p, w), (-p, -w)];
    // Each feature's nearest point, normal and frame go to `feats[t]`, and only the indices
    // of the best are selected: selecting the vectors themselves compiles to branches. Slot
    // 0 is what is left when no feature qualifies: `w` itself.
    poly.feats[0] = (w, V2::zeros(), 0);
    let (mut best_sd, mut best_sd_at) = (f64::NEG_INFINITY, 0);
    let (mut best_d2, mut best_at) = (f64::INFINITY, 0);
    let mut keep = |feats: &mut [(V2, V2, usize)], t, sd: f64, normal: V2, c: V2, w: V2, neg| {
        feats[t] = (c, normal, neg);
        let better = sd > best_sd;
        best_sd = if better { sd } else { best_sd };
        best_sd_at = if better { t } else { best_sd_at };
        let d2 = (w - c).norm_squared();
        let d2 = if sd > margin { d2 } else { f64::INFINITY };
        let closer = d2 < best_d2;
        best_d2 = if closer { d2 } else { best_d2 };
        best_at = if closer { t } else { best_at };
    };
    let run_start = run.vertex(&poly.edges);
    let count = count.min(MAX_VERTICES);
    let PairScratch { edges, feats } = poly;
    for t in 1..count + 1 {
        let (k, neg) = (run.index(), run.neg);
        let (p, w) = frame[neg];
        let (e, to) = (&edges[k], edges[k + 1].v);
        let start = (p + e.v) * scale;
        let edge = (to - e.v) * scale;
        let e2 = edge.norm_squared();
        let t_edge = ((w - start).dot(&edge) / e2).clamp(0.0, 1.0);
        let t_edge = if e2 > 0.0 { t_edge } else { 0.0 };
        let sd = w.dot(&e.n) - scale * e.h[neg];
        keep(feats, t, sd, e.n, start + t_edge * edge, w, neg);
        run.advance();
    }
    if legs {
        let (start, end) = (p + run_start, p + run.vertex(edges));
        for (t, (dir, normal)) in [(start, left_normal(start)), (end, right_normal(end))]
            .into_iter()
            .enumerate()
        {
            let start = dir * scale;
            let e2 = dir.norm_squared();
            // What `unit` gives: the normal's norm is the square root of `e2` (the same
            // squares, added in the other order: the same bits), positive and finite exactly
            // when `e2` is.
            let normal = if e2 > 0.0 && e2 < f64::INFINITY {
                normal / e2.sqrt()
            } else {
                V2::zeros()
            };
            let t_ray = ((w - start).dot(&dir) / e2).max(0.0);
            let t_ray = if e2 > 0.0 { t_ray } else { 0.0 };
            let sd = (w - start).dot(&normal);
            keep(feats, count + 1 + t, sd, normal, start + t_ray * dir, w, 0);
        }
    }
    if best_sd == f64::NEG_INFINITY {
        return Avoidance {
            u: V2::zeros(),
            normal: V2::zeros(),
        };
    }
    if best_sd <= 0.0 {
        let (_, normal, neg) = poly.feats[best_sd_at];
        let normal = normal * SIGN[neg];
        return Avoidance {
            u: -best_sd * normal,
            normal,
        };
    }
    let (c, fallback, neg) = poly.feats[best_at];
    let (c, fallback) = (c * SIGN[neg], fallback * SIGN[neg]);
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
        // Even polygons both ways: halves (as the crowd step does) and whole.
        for symmetric in [false, true].into_iter().filter(|&s| !s || sides % 2 == 0) {
            let (mut sb, mut sa) = (Shapes::default(), Shapes::default());
            sb.reset(sides, symmetric);
            sa.reset(sides, symmetric);
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
                "symmetric {} u {:?} vs {:?}",
                symmetric,
                fast.u,
                reference.u
            );
            prop_assert!(
                (fast.normal - reference.normal).norm() <= 1e-9,
                "symmetric {} normal {:?} vs {:?}",
                symmetric,
                fast.normal,
                reference.normal
            );
        }
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
                shapes.reset(sides, false);
                shapes.push(poly.points());
                let (mut fast, mut slow) = (Shapes::default(), Shapes::default());
                fast.reset(sides, false);
                slow.reset(sides, false);
                fast.push_negated(&shapes, 0);
                slow.push(poly.negated().points());
                for (f, s) in fast.edges.iter().zip(&slow.edges) {
                    assert_eq!(
                        (f.start, f.normal),
                        (s.start, s.normal),
                        "sides {sides} t {t}"
                    );
                    assert!((f.angle - s.angle).abs() < 1e-12, "sides {sides} t {t}");
                }
                if sides % 2 == 0 {
                    // A symmetric polygon prepares to exactly its own negation.
                    let mut half = Shapes::default();
                    half.reset(sides, true);
                    half.push(poly.points());
                    assert_eq!(half.edges.len(), sides / 2 + 1);
                    let top = half.edges[sides / 2].start;
                    assert_eq!(top, -half.edges[0].start, "sides {sides} t {t}");
                    for (h, f) in half.edges[..sides / 2].iter().zip(&shapes.edges) {
                        assert_eq!((h.start, h.normal, h.angle), (f.start, f.normal, f.angle));
                        assert!(h.angle < 2.0, "sides {sides} t {t}");
                    }
                    for (f, s) in shapes.edges.iter().zip(&slow.edges) {
                        assert_eq!(
                            (f.start, f.normal, f.angle),
                            (s.start, s.normal, s.angle),
                            "sides {sides} t {t}"
                        );
                    }
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

        /// The origin within `gap` of P's boundary (apart or overlapping; with `same`, equal
        /// shapes at a quarter-turn heading, every edge pair parallel), `w` near the cone's
        /// cap and legs, where the features' distances tie up to rounding.
        #[test]
        fn matches_near_contact(
            a in (0.5f64..40.0, 0.5f64..40.0, 0.0f64..std::f64::consts::TAU),
            b in (0.5f64..40.0, 0.5f64..40.0, 0.0f64..std::f64::consts::TAU),
            sides in 3usize..=32,
            angle in 0.0f64..std::f64::consts::TAU,
            gap in prop::sample::select(vec![-1e-3, -1e-9, 0.0, 1e-12, 1e-9, 1e-6, 1e-3, 1.0]),
            wk in 0.0f64..2.0, wt in -1.0f64..1.0,
            tau in 1.0f64..20.0,
            dt in prop::sample::select(vec![0.5, 1.0, 2.0]),
            same in prop::bool::ANY,
        ) {
            let b = if same { (a.0, a.1, (a.2 / std::f64::consts::FRAC_PI_2).round() * std::f64::consts::FRAC_PI_2) } else { b };
            let a = if same { b } else { a };
            let unit_v = |t: f64| V2::new(t.cos(), t.sin());
            let pa = Ellipse::new(a.0, a.1, unit_v(a.2)).polygon(sides);
            let pb = Ellipse::new(b.0, b.1, unit_v(b.2)).polygon(sides);
            let sum = minkowski_sum(&pb, &pa.negated());
            let d = unit_v(angle);
            // The offset along d at which P = p + sum touches the origin.
            let reach = sum.points().iter().map(|q| -q.dot(&d)).fold(f64::NEG_INFINITY, f64::max);
            let p = d * (reach + gap);
            // Around p / tau (the cap), out to the legs.
            let w = (d * wk + V2::new(-d.y, d.x) * wt) * (reach / tau);
            check(a, b, sides, p, w, tau, dt)?;
        }
    }
}
