//! A cheap, conservative test for neighbours whose ORCA half-plane contains the whole speed
//! disc `|v| <= S`. Such a half-plane never constrains the LP ([`crate::lp::solve`]): the
//! feasible optimum lies in the disc, and in the infeasible (min-max) case its violation is
//! `<= 0` everywhere in the disc, below the positive optimum, so neither it nor its bisectors
//! ever bind. The crowd step skips the exact pair computation for them.
//!
//! # Why the test is sound
//!
//! Let `p = pos_b - pos_a`, `w = v_a - v_b`, `P = p + B ⊕ (-A)` (the agents' polygons) and `K`
//! the velocity obstacle: when the shapes are apart, the truncated cone
//! `{s x : x in P, s >= 1/tau}`. Its support function is `h_K(m) = h_P(m) / tau` where
//! `h_P(m) <= 0` and `+inf` elsewhere. For `w` outside `K`, the distance `d` and the outward
//! normal `n` at the nearest point are the maximum and the unique maximiser over unit `m` of
//! `f(m) = m·w - h_K(m)`. The half-plane is `{v : (v - v_a)·n >= -d/2}`
//! ([`crate::velocity_obstacle::reciprocal_line`]), which contains the disc iff
//! `d >= 2 (S + v_a·n)`.
//!
//! Each polygon lies between its ellipse `E` and `rho E` (`rho = 1/cos(pi/sides)`: its
//! vertices lie on `rho E`), so, with `e(m) = h_EA(m) + h_EB(m)` (`h_E` in closed form),
//! `lo(m) = m·p + e(m) <= h_P(m) <= m·p + rho e(m) = hi(m)`.
//!
//! 1. A lower bound on `d`: for any unit `m` with `hi(m) < 0` (which also proves the shapes
//!    apart), `d >= f(m) >= L = m·w - hi(m) / tau`. We take for `m` the normal of the obstacle
//!    of two discs that hold the polygons (exact in closed form, and close to `n`: the loss
//!    in `L` is second order in the angle).
//! 2. Where `n` can be: `f <= f_lo(m) = m·w - lo(m) / tau` (`+inf` support where `lo > 0`), so
//!    `n` lies in `N = {m : f_lo(m) >= L}`. `N` is the set of normals of lines separating the
//!    disc of radius `L` about `w` from the ellipses' obstacle (convex): an arc.
//! 3. The bad directions `G = {m : v_a·m > c}`, `c = L/2 - S`, form an arc with end points
//!    `g±` (`v_a·g± = c`). If the `m` of step 1 (in `N`, as `f_lo >= f_hi`) is not in `G`
//!    and neither `g±` is in `N`, then `N` (connected) does not meet `G`: `v_a·n <= c`, and
//!    `d >= L >= 2 (S + v_a·n)`.
//!
//! With a slack `s >= 0` ([`Limits::with_slack`]) the same steps show that the half-plane's
//! largest violation in the disc, `S + v_a·n - d/2`, is at most `s`: `S` becomes `S - s`.
//!
//! Every comparison keeps a relative margin for rounding. Cheap necessary conditions turn most
//! pairs down before the ellipses are evaluated; turning down is always safe. Step 1 does not
//! depend on which agent asks (for the reverse pair `m`, `p`, `w` negate and `L` stays): the
//! crowd step keeps the [`Bound`] of a culled pair, and the other agent only redoes step 3.

// Conditions are written so that a NaN turns the pair down: `!(x < y)`, not `x >= y`.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use crate::geometry::{cross, left_normal, Ellipse, MAX_SIDES, V2};

/// Relative margin of every comparison (rounding is about 1e-16 relative).
const MARGIN: f64 = 1e-9;

/// An agent's ellipse, as the test needs it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Body {
    heading: V2,
    a: f64,
    b: f64,
    /// Radius of the disc about the centre that holds the polygon (`rho max(a, b)`).
    reach: f64,
    /// Least support of `rho E` in any direction (`rho min(a, b)`).
    waist: f64,
}

impl Body {
    /// The ellipse of a polygon from [`Ellipse::polygon`] (with `limits`' number of sides).
    pub(crate) fn new(e: &Ellipse, limits: &Limits) -> Self {
        let rho = limits.rho;
        Self {
            heading: e.heading,
            a: e.a,
            b: e.b,
            reach: rho * e.a.max(e.b),
            waist: rho * e.a.min(e.b),
        }
    }

    /// Support function of the ellipse: `max over x in E of m·x`.
    #[inline]
    fn support(&self, m: V2) -> f64 {
        self.support_squared(m).sqrt()
    }

    /// The support's square (no square root).
    #[inline]
    fn support_squared(&self, m: V2) -> f64 {
        let along = self.a * m.dot(&self.heading);
        let across = self.b * cross(self.heading, m);
        along * along + across * across
    }
}

/// One ordered pair: `p = pos_b - pos_a`, `w = v_a - v_b`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pair<'a> {
    pub(crate) p: V2,
    pub(crate) w: V2,
    pub(crate) a: &'a Body,
    pub(crate) b: &'a Body,
}

impl Pair<'_> {
    /// `e(m)`: support of `EA ⊕ EB` (each ellipse is symmetric, so of `EB ⊕ (-EA)` too).
    #[inline]
    fn ellipses(&self, m: V2) -> f64 {
        self.a.support(m) + self.b.support(m)
    }
}

/// The model's constants: horizon, speed limit and polygons.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Limits {
    inv_tau: f64,
    /// The test's disc radius `S`: the speed limit, less the slack (see [`Limits::with_slack`]).
    max_speed: f64,
    /// Speed scale of the rounding margins: the speed limit plus the slack.
    scale: f64,
    /// `rho`: the regular polygon circumscribing the unit circle has circumradius
    /// `1/cos(pi/sides)` (a hair more, for rounding).
    rho: f64,
}

impl Limits {
    /// `sides` is clamped as [`crate::geometry::UnitPolygon`] clamps it.
    pub(crate) fn new(tau: f64, max_speed: f64, sides: usize) -> Self {
        let sides = sides.clamp(3, MAX_SIDES);
        Self {
            inv_tau: 1.0 / tau,
            max_speed,
            scale: max_speed,
            rho: (1.0 + MARGIN) / (std::f64::consts::PI / sides as f64).cos(),
        }
    }

    /// These limits for a weaker question: is the half-plane's largest violation anywhere in
    /// the speed disc at most `slack >= 0` (rather than 0)? That is the same test with the
    /// disc's radius `S - slack` (negative when the slack exceeds the speed limit): the
    /// largest violation is `S + v_a·n - d/2`. The crowd step asks it of far neighbours once
    /// the near ones' min-max optimum has violation `slack` (see `models::orca`). Made on
    /// limits from [`Limits::new`]; a zero slack gives them back unchanged.
    pub(crate) fn with_slack(&self, slack: f64) -> Self {
        Self {
            max_speed: self.max_speed - slack,
            scale: self.scale + slack,
            ..*self
        }
    }
}

/// Step 1's result: `d >= gap` (already less the margin), realised by the unit `normal`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Bound {
    gap: f64,
    normal: V2,
    /// Rounding margin of the pair's comparisons.
    tol: f64,
}

impl Bound {
    /// `(gap, tol, normal)`, to be stored compactly.
    pub(crate) fn parts(&self) -> (f64, f64, V2) {
        (self.gap, self.tol, self.normal)
    }

    /// The bound from [`Bound::parts`].
    pub(crate) fn from_parts(gap: f64, tol: f64, normal: V2) -> Self {
        Self { gap, normal, tol }
    }

    /// Whether the bound is [`distance_bound`]'s, without a normal.
    pub(crate) fn is_from_distances(&self) -> bool {
        self.normal.x == 0.0 && self.normal.y == 0.0
    }

    /// The bound for the reverse pair (`p` and `w` negated, the agents swapped).
    pub(crate) fn reversed(&self) -> Self {
        Self {
            normal: -self.normal,
            ..*self
        }
    }
}

/// An agent's velocity and its norm (once per agent, not per pair).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Motion {
    pub(crate) v: V2,
    pub(crate) speed: f64,
}

impl Motion {
    pub(crate) fn new(v: V2) -> Self {
        Self { v, speed: v.norm() }
    }
}

/// Whether agent `a` of `pair` may skip it: the bound that proves its half-plane contains the
/// speed disc, else `None`.
#[inline]
pub(crate) fn cull(pair: &Pair, a: Motion, limits: &Limits) -> Option<Bound> {
    let bound = bound(pair, a, limits)?;
    contains_disc(pair, &bound, a, limits).then_some(bound)
}

/// [`cull`] for far pairs, which a slack often lets a cruder bound cull: one from distances
/// alone (see [`distance_bound`]) is tried first. Its bound has no normal; the other agent
/// of the pair can use it in [`contains_disc`] all the same.
#[inline]
pub(crate) fn cull_far(pair: &Pair, a: Motion, limits: &Limits) -> Option<Bound> {
    if let Some(bound) = distance_bound(pair, limits) {
        if contains_disc(pair, &bound, a, limits) {
            return Some(bound);
        }
    }
    cull(pair, a, limits)
}

/// A lower bound on `d` from distances: the polygons lie within discs of radius `reach`
/// about their centres, so `P` within `|p| - reach_a - reach_b` of the origin at the least,
/// and the cone `K` (points `x / t`, `x` in `P`, `0 < t <= tau`) beyond that over `tau`: for
/// a `w` nearer the origin, `d >= (|p| - reach_a - reach_b) / tau - |w|`. Without a normal
/// (zero), it can only prove the disc contained through `|v_a| <= c` in [`contains_disc`],
/// where `v_a·n <= |v_a|` for whatever `n` is.
#[inline]
fn distance_bound(pair: &Pair, limits: &Limits) -> Option<Bound> {
    let (p, w, inv_tau) = (pair.p, pair.w, limits.inv_tau);
    let reach = pair.a.reach + pair.b.reach;
    let tol = tolerance(w, p.x.abs() + p.y.abs() + reach, inv_tau);
    // Positive only when |p| > reach: the shapes are apart.
    let gap = (p.norm() - reach) * inv_tau - w.norm() - tol;
    (gap > 0.0).then_some(Bound {
        gap,
        normal: V2::zeros(),
        tol,
    })
}

/// The rounding margin of a bound on `d` for relative velocity `w` and a pair of the given
/// size (`|p_x| + |p_y|` plus the reaches).
#[inline]
fn tolerance(w: V2, size: f64, inv_tau: f64) -> f64 {
    MARGIN * (1.0 + w.x.abs() + w.y.abs() + size * inv_tau)
}

/// Step 1, `None` when the shapes may touch, or when a cheap necessary condition shows that
/// step 3 must fail for agent `a` (most pairs that are not culled end there, before the
/// ellipses' support functions are evaluated).
#[inline]
fn bound(pair: &Pair, a: Motion, limits: &Limits) -> Option<Bound> {
    let (p, w, inv_tau) = (pair.p, pair.w, limits.inv_tau);
    let reach = pair.a.reach + pair.b.reach;
    let dist2 = p.norm_squared();
    if !(dist2 > reach * reach) {
        return None; // near neighbours: rarely culled, and the discs' cone needs |p| > reach
    }
    let m = disc_cone_normal(p, dist2, reach, w - p * inv_tau);
    // Step 3 needs v_a·m < L/2 - S, and L <= m·w - (m·p + rho (min axes))/tau as
    // h_E >= min(a, b).
    let towards = m.dot(&p);
    let most = m.dot(&w) - (towards + pair.a.waist + pair.b.waist) * inv_tau;
    if !(a.v.dot(&m) < 0.5 * most - limits.max_speed) {
        return None;
    }
    let hi = towards + limits.rho * pair.ellipses(m);
    let size = p.x.abs() + p.y.abs() + reach;
    if !(hi < -MARGIN * size) {
        return None; // not provably apart
    }
    let tol = tolerance(w, size, inv_tau);
    let gap = m.dot(&w) - hi * inv_tau - tol;
    (gap > 0.0).then_some(Bound {
        gap,
        normal: m,
        tol,
    })
}

/// Outward unit normal at the point nearest to `w` of the obstacle of the disc of radius `r`
/// about `p` (`dist2 = |p|^2 > r^2`), given `q = w - p/tau` (as in [`avoidance_circle`]):
/// on the cap `q/|q|`, else the normal of the leg on `w`'s side.
///
/// [`avoidance_circle`]: crate::velocity_obstacle::avoidance_circle
#[inline]
fn disc_cone_normal(p: V2, dist2: f64, r: f64, q: V2) -> V2 {
    let along = q.dot(&p);
    if along < 0.0 && along * along > r * r * q.norm_squared() {
        return q / q.norm(); // along < 0: q is not zero
    }
    // The legs' normals (s leg left(p) - r p) / |p|^2, leg = sqrt(|p|^2 - r^2), are unit.
    let leg = (dist2 - r * r).sqrt();
    let leg = if cross(p, q) > 0.0 { leg } else { -leg };
    (leg * left_normal(p) - r * p) / dist2
}

/// Steps 2 and 3 for agent `a` of `pair`, given step 1's `bound` (of this pair, or the
/// reversed bound of the reverse pair).
#[inline]
pub(crate) fn contains_disc(pair: &Pair, bound: &Bound, a: Motion, limits: &Limits) -> bool {
    let (v, speed) = (a.v, a.speed);
    let c = 0.5 * bound.gap - limits.max_speed - MARGIN * (limits.scale + speed);
    if !(v.dot(&bound.normal) < c) {
        return false;
    }
    if speed <= c {
        return true; // G is empty
    }
    if !speed.is_finite() || bound.is_from_distances() {
        return false; // |v| overflowed: no end points; or no normal to start the arc from
    }
    // End points of G: v·g = c, |g| = 1.
    let dir = v / speed;
    let cos = c / speed;
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (mid, side) = (cos * dir, sin * left_normal(dir));
    outside_arc(pair, bound, mid + side, limits) && outside_arc(pair, bound, mid - side, limits)
}

/// Whether the unit `m` is provably outside `N = {m : f_lo(m) >= gap}`.
#[inline]
fn outside_arc(pair: &Pair, bound: &Bound, m: V2, limits: &Limits) -> bool {
    // With lo = m·p + e(m): lo > MARGIN size (infinite support), or m·w - lo / tau below the
    // gap. Both say lo > t for a threshold t, and e(m) is a sum of two square roots: the
    // comparison is made on squares (square roots are slow, and these calls are hot).
    let size = pair.p.x.abs() + pair.p.y.abs() + pair.a.reach + pair.b.reach;
    let t = (MARGIN * size).min((m.dot(&pair.w) - bound.gap + bound.tol) / limits.inv_tau);
    sqrt_sum_exceeds(
        pair.a.support_squared(m),
        pair.b.support_squared(m),
        t - m.dot(&pair.p),
    )
}

/// `sqrt(a2) + sqrt(b2) > t`, without square roots; false when anything is NaN.
#[inline]
fn sqrt_sum_exceeds(a2: f64, b2: f64, t: f64) -> bool {
    if !(t >= 0.0) {
        return t < 0.0;
    }
    // a2 + b2 + 2 sqrt(a2 b2) > t^2.
    let r = t * t - a2 - b2;
    r < 0.0 || 4.0 * a2 * b2 > r * r
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::minkowski::minkowski_sum;
    use crate::velocity_obstacle::{avoidance, reciprocal_line};
    use proptest::prelude::*;
    use proptest::strategy::ValueTree;
    use proptest::test_runner::{RngSeed, TestRunner};
    use std::f64::consts::TAU;

    /// One random ordered pair and the model's constants.
    #[derive(Clone, Debug)]
    struct Case {
        /// (l, w, heading angle) of each agent.
        shapes: [(f64, f64, f64); 2],
        sides: usize,
        p: V2,
        vel: [V2; 2],
        tau: f64,
        dt: f64,
        max_speed: f64,
        /// The violation agents may leave (see [`Limits::with_slack`]): zero in half the cases.
        slack: f64,
    }

    /// A cull decision to check: `Some` for "the half-plane of agent 0 contains the disc".
    type Test = fn(&Pair, Motion, &Limits) -> Option<Bound>;

    fn ellipse((l, w, h): (f64, f64, f64)) -> Ellipse {
        Ellipse::new(l, w, V2::new(h.cos(), h.sin()))
    }

    /// How far the exact half-plane of agent 0 (`v_a`) is from containing the speed disc
    /// (negative: it contains it), which is its largest violation in the disc, from the plain
    /// obstacle of `p`, `w` and the polygons.
    fn excess(c: &Case, p: V2, w: V2, v_a: V2, a: usize) -> f64 {
        let (pa, pb) = (
            ellipse(c.shapes[a]).polygon(c.sides),
            ellipse(c.shapes[1 - a]).polygon(c.sides),
        );
        let avoid = avoidance(p, &minkowski_sum(&pb, &pa.negated()), w, c.tau, c.dt);
        assert!((avoid.normal.norm() - 1.0).abs() < 1e-9, "{c:?}: {avoid:?}");
        let line = reciprocal_line(v_a, avoid);
        // Half-plane {v : (v - point)·n >= 0}: the disc is inside iff -point·n >= S.
        c.max_speed + line.point.dot(&avoid.normal)
    }

    /// Checks `test` for both agents of the case (agent 1 through the reversed bound, as the
    /// crowd step reuses it). Returns how many of the two were culled, or the failure.
    fn check(c: &Case, test: Test) -> Result<usize, String> {
        let limits = Limits::new(c.tau, c.max_speed, c.sides).with_slack(c.slack);
        let bodies = c.shapes.map(|s| Body::new(&ellipse(s), &limits));
        let (va, vb) = (c.vel[0], c.vel[1]);
        let pair = Pair {
            p: c.p,
            w: va - vb,
            a: &bodies[0],
            b: &bodies[1],
        };
        let scale = 1.0 + c.p.norm() / c.tau + (va - vb).norm() + va.norm() + vb.norm() + c.slack;
        let mut culled = 0;
        if let Some(bound) = test(&pair, Motion::new(va), &limits) {
            let x = excess(c, c.p, va - vb, va, 0) - c.slack;
            if x > 1e-9 * scale {
                return Err(format!("agent 0 culled, disc sticks out by {x}"));
            }
            culled += 1;
            let rev = Pair {
                p: -pair.p,
                w: -pair.w,
                a: pair.b,
                b: pair.a,
            };
            let bound = bound.reversed();
            if contains_disc(&rev, &bound, Motion::new(vb), &limits) {
                let x = excess(c, -c.p, vb - va, vb, 1) - c.slack;
                if x > 1e-9 * scale {
                    return Err(format!("agent 1 culled, disc sticks out by {x}"));
                }
                culled += 1;
            }
        }
        Ok(culled)
    }

    /// Sizes from below `MIN_SIZE` (a dot) up.
    fn shape() -> impl Strategy<Value = (f64, f64, f64)> {
        (0.0f64..60.0, 0.0f64..60.0, 0.0f64..TAU)
    }

    /// Sometimes standing still.
    fn velocity() -> impl Strategy<Value = V2> {
        prop_oneof![
            1 => Just(V2::zeros()),
            9 => (-6.0f64..6.0, -6.0f64..6.0).prop_map(|(x, y)| V2::new(x, y)),
        ]
    }

    /// Random pairs, from touching to far apart (distance in units of the sum of the
    /// polygons' circumradii, where the test starts to apply).
    fn case() -> impl Strategy<Value = Case> {
        (
            [shape(), shape()],
            3usize..=16,
            (0.8f64..4.0, 0.0f64..TAU),
            [velocity(), velocity()],
            (0.5f64..10.0, prop::sample::select(vec![0.5, 1.0, 2.0])),
            (0.0f64..6.0, prop_oneof![Just(0.0), 0.0f64..8.0]),
        )
            .prop_map(
                |(shapes, sides, (dist, angle), vel, (tau, dt), (max_speed, slack))| {
                    let reach = |(l, w, _): (f64, f64, f64)| 0.5 * l.max(w);
                    let rho = 1.0 / (std::f64::consts::PI / sides as f64).cos();
                    let dist = dist * rho * (reach(shapes[0]) + reach(shapes[1]));
                    Case {
                        shapes,
                        sides,
                        p: dist * V2::new(angle.cos(), angle.sin()),
                        vel,
                        tau,
                        dt,
                        max_speed,
                        slack,
                    }
                },
            )
    }

    /// The case with the speed limit moved to `offset` from the largest one at which agent 0's
    /// exact half-plane is violated by at most the slack: the decision is then as close as it
    /// gets.
    fn at_the_limit(mut c: Case, offset: f64) -> Case {
        let x = excess(&c, c.p, c.vel[0] - c.vel[1], c.vel[0], 0);
        c.max_speed = (c.max_speed - x + c.slack + offset).max(0.0);
        c
    }

    fn config(cases: u32) -> ProptestConfig {
        ProptestConfig {
            cases,
            rng_seed: RngSeed::Fixed(0xc011),
            failure_persistence: None,
            ..ProptestConfig::default()
        }
    }

    proptest! {
        #![proptest_config(config(20_000))]

        /// Whenever the test culls, the exact half-plane's largest violation in the disc is at
        /// most the slack (it contains the disc when the slack is zero).
        #[test]
        fn culled_half_planes_contain_the_disc(c in case()) {
            prop_assert_eq!(check(&c, cull).err(), None, "{:?}", c);
            prop_assert_eq!(check(&c, cull_far).err(), None, "{:?}", c);
        }

        /// The square-free comparison agrees with the square roots wherever they differ by
        /// more than rounding.
        #[test]
        fn sqrt_sum_comparison(a in 0.0f64..1e4, b in 0.0f64..1e4, t in -10.0f64..300.0) {
            let (a2, b2) = (a * a, b * b);
            let sum = a2.sqrt() + b2.sqrt();
            if (sum - t).abs() > 1e-9 * (1.0 + sum) {
                prop_assert_eq!(sqrt_sum_exceeds(a2, b2, t), sum > t);
            }
        }

        /// The same with the speed limit at the edge of containment.
        #[test]
        fn sound_at_the_limit(c in case(), offset in -1e-3f64..1e-3) {
            let c = at_the_limit(c, offset);
            prop_assert_eq!(check(&c, cull).err(), None, "{:?}", c);
            prop_assert_eq!(check(&c, cull_far).err(), None, "{:?}", c);
        }
    }

    /// The bound from distances alone culls on its own in these cases (so the checks above
    /// test it), soundly; with `reach` left out of it, it would not be sound.
    #[test]
    fn distance_bounds_cull_soundly() {
        let from_distances: Test = |pair, a, limits| {
            distance_bound(pair, limits).filter(|b| contains_disc(pair, b, a, limits))
        };
        let (culled, failed) = survey(from_distances, 5000, false);
        assert_eq!(failed, 0);
        assert!(culled > 500, "only {culled} of 10000 agents culled");
        let (_, failed) = survey(from_distances, 5000, true);
        assert_eq!(failed, 0);
        let careless: Test = |pair, a, limits| {
            let gap = pair.p.norm() * limits.inv_tau - pair.w.norm();
            let bound = Bound::from_parts(gap, 0.0, V2::zeros());
            (gap > 0.0 && contains_disc(pair, &bound, a, limits)).then_some(bound)
        };
        let (_, failed) = survey(careless, 5000, false);
        assert!(failed > 0, "the unsound test was not caught");
    }

    #[test]
    fn sqrt_sum_comparison_edges() {
        assert!(sqrt_sum_exceeds(0.0, 0.0, -1.0));
        assert!(!sqrt_sum_exceeds(0.0, 0.0, 0.0));
        assert!(sqrt_sum_exceeds(9.0, 16.0, 6.999));
        assert!(!sqrt_sum_exceeds(9.0, 16.0, 7.001));
        assert!(!sqrt_sum_exceeds(f64::NAN, 1.0, 0.5));
        assert!(!sqrt_sum_exceeds(1.0, 1.0, f64::NAN));
        // Overflow gives no answer, which turns the pair down (always safe).
        assert!(!sqrt_sum_exceeds(f64::INFINITY, 1.0, 1e300));
    }

    /// Runs `test` on `n` cases of the strategy: (culled agents, failures).
    fn survey(test: Test, n: usize, limit: bool) -> (usize, usize) {
        let mut runner = TestRunner::new(config(0));
        let (mut culled, mut failed) = (0, 0);
        for _ in 0..n {
            let mut c = case().new_tree(&mut runner).unwrap().current();
            if limit {
                c = at_the_limit(c, 1e-3);
            }
            match check(&c, test) {
                Ok(k) => culled += k,
                Err(_) => failed += 1,
            }
        }
        (culled, failed)
    }

    /// The checks above can fail: the cases cull often, and a test that trusts the normal of
    /// step 1 as if it were the exact one (skipping step 3's arc) is caught.
    #[test]
    fn the_check_has_teeth() {
        let (culled, failed) = survey(cull, 5000, false);
        assert_eq!(failed, 0);
        assert!(culled > 1500, "only {culled} of 10000 agents culled");
        let trusting: Test = |pair, a, limits| {
            let bound = bound(pair, a, limits)?;
            let c = 0.5 * bound.gap - limits.max_speed;
            (a.v.dot(&bound.normal) < c).then_some(bound)
        };
        let (_, failed) = survey(trusting, 5000, true);
        assert!(failed > 0, "the unsound test was not caught");
    }
}
