//! Velocity obstacles of convex polygons and the reciprocal (ORCA-style) half-plane they induce.
//!
//! With `p = pos_b - pos_a` and `M = B ⊕ (-A)` (shapes centred at the origin), A and B touch
//! when their relative offset lies in `P = p + M`. The relative velocity `v_a - v_b` collides
//! within `tau` iff it lies in `VO = { s x : x in P, s >= 1/tau }`: a cone from the origin over
//! `P`, truncated by `P / tau`. Its boundary is two legs (rays along the tangents from the
//! origin) and the chain of `P / tau` that faces the origin; the set is convex.

use crate::geometry::{cross, left_normal, right_normal, Polygon, MAX_VERTICES, V2};
use crate::lp::Line;
use crate::minkowski::wrap;

/// One boundary piece of a convex region: `start + t * edge`, `t` in `[0, 1]` (segment) or
/// `[0, inf)` (ray), with its unit outward normal.
#[derive(Clone, Copy, Debug, Default)]
struct Feature {
    start: V2,
    edge: V2,
    ray: bool,
    normal: V2,
}

/// The smallest change `u` of the relative velocity that reaches the boundary of the obstacle,
/// and the obstacle's outward normal `n` there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Avoidance {
    pub u: V2,
    pub normal: V2,
}

/// Avoidance for relative velocity `w`, relative position `p`, Minkowski sum `sum = B ⊕ (-A)`.
/// Apart (origin outside `P`): the truncated cone for horizon `tau`. Overlapping: as RVO2 does,
/// the obstacle is `P / dt`, so that the overlap is resolved within one step.
pub fn avoidance(p: V2, sum: &Polygon, w: V2, tau: f64, dt: f64) -> Avoidance {
    let pts = sum.points();
    let n = pts.len();
    let next = |i: usize| wrap(i + 1, n);
    // Edge i (from vertex i to i + 1) faces the origin when the origin is on its outer (right)
    // side: cross(edge, 0 - (p + v_i)) < 0, i.e. cross(edge, p + v_i) > 0. The facing edges
    // of a convex polygon are one contiguous run (none when the origin is inside); `first` is
    // where it starts.
    let mut faces = [false; MAX_VERTICES];
    for i in 0..n {
        faces[i] = cross(pts[next(i)] - pts[i], p + pts[i]) > 0.0;
    }
    let first = if n >= 3 {
        (0..n).find(|&i| faces[i] && !faces[wrap(i + n - 1, n)])
    } else {
        None
    };
    let mut feats = Vec::with_capacity(n + 2);
    match first {
        Some(first) => {
            // The cap: the facing edges of P / tau ...
            let inv_tau = 1.0 / tau;
            let mut k = first;
            while faces[k] && feats.len() < n {
                let a = p + pts[k];
                let edge = pts[next(k)] - pts[k];
                feats.push(Feature {
                    start: a * inv_tau,
                    edge: edge * inv_tau,
                    ray: false,
                    normal: unit(right_normal(edge)),
                });
                k = next(k);
            }
            // ... and the two legs: rays from the cap's ends, away from the origin.
            let (start, end) = (p + pts[first], p + pts[k]);
            feats.push(Feature {
                start: start * inv_tau,
                edge: start,
                ray: true,
                normal: unit(left_normal(start)),
            });
            feats.push(Feature {
                start: end * inv_tau,
                edge: end,
                ray: true,
                normal: unit(right_normal(end)),
            });
        }
        None => {
            let inv_dt = 1.0 / dt;
            for i in 0..n {
                let edge = pts[next(i)] - pts[i];
                feats.push(Feature {
                    start: (p + pts[i]) * inv_dt,
                    edge: edge * inv_dt,
                    ray: false,
                    normal: unit(right_normal(edge)),
                });
            }
        }
    }
    nearest_boundary(&feats, w)
}

fn unit(v: V2) -> V2 {
    let n = v.norm();
    if n > 0.0 && n.is_finite() {
        v / n
    } else {
        V2::zeros()
    }
}

/// Nearest boundary point of the convex region bounded by `feats` to `w`.
fn nearest_boundary(feats: &[Feature], w: V2) -> Avoidance {
    // Inside iff on the inner side of every supporting line; the nearest boundary point of an
    // inside point is its foot on the nearest supporting line.
    let mut best_sd = f64::NEG_INFINITY;
    let mut best = None;
    for (k, f) in feats.iter().enumerate() {
        let sd = (w - f.start).dot(&f.normal);
        if sd > best_sd {
            best_sd = sd;
            best = Some(k);
        }
    }
    let Some(k) = best else {
        return Avoidance {
            u: V2::zeros(),
            normal: V2::zeros(),
        };
    };
    if best_sd <= 0.0 {
        let normal = feats[k].normal;
        return Avoidance {
            u: -best_sd * normal,
            normal,
        };
    }
    let mut best_d2 = f64::INFINITY;
    let mut best = (w, feats[k].normal);
    for f in feats {
        let e2 = f.edge.norm_squared();
        let mut t = if e2 > 0.0 {
            (w - f.start).dot(&f.edge) / e2
        } else {
            0.0
        };
        t = if f.ray { t.max(0.0) } else { t.clamp(0.0, 1.0) };
        let c = f.start + t * f.edge;
        let d2 = (w - c).norm_squared();
        if d2 < best_d2 {
            best_d2 = d2;
            best = (c, f.normal);
        }
    }
    let (c, fallback) = best;
    let d = best_d2.sqrt();
    let normal = if d > 1e-12 { (w - c) / d } else { fallback };
    Avoidance { u: c - w, normal }
}

/// ORCA half-plane for agent A: A takes half of the avoidance, so the permitted velocities are
/// `{ v : (v - (v_a + u / 2)) · n >= 0 }`.
pub fn reciprocal_line(v_a: V2, avoid: Avoidance) -> Line {
    let n = avoid.normal;
    Line {
        point: v_a + 0.5 * avoid.u,
        dir: V2::new(n.y, -n.x),
    }
}

/// Exact avoidance for two discs of combined radius `r` (the circular RVO baseline): the cone's
/// legs are tangents from the origin, its cap the circle `(p / tau, r / tau)`; overlapping discs
/// use the circle `(p / dt, r / dt)`.
pub fn avoidance_circle(p: V2, r: f64, w: V2, tau: f64, dt: f64) -> Avoidance {
    let dist2 = p.norm_squared();
    let r2 = r * r;
    let (centre, radius) = if dist2 > r2 {
        (p / tau, r / tau)
    } else {
        (p / dt, r / dt)
    };
    let w0 = w - centre;
    let along = w0.dot(&p);
    let on_cap = dist2 <= r2 || (along < 0.0 && along * along > r2 * w0.norm_squared());
    if on_cap {
        let len = w0.norm();
        let normal = if len > 1e-12 {
            w0 / len
        } else if dist2 > 0.0 {
            -p / dist2.sqrt()
        } else {
            V2::new(1.0, 0.0)
        };
        return Avoidance {
            u: (radius - len) * normal,
            normal,
        };
    }
    // Nearest leg: the tangent on the side of `w`, rotated from `p` by the half-angle.
    let leg = (dist2 - r2).sqrt();
    let (dir, normal) = if cross(p, w0) > 0.0 {
        let d = V2::new(p.x * leg - p.y * r, p.x * r + p.y * leg) / dist2;
        (d, left_normal(d))
    } else {
        let d = V2::new(p.x * leg + p.y * r, -p.x * r + p.y * leg) / dist2;
        (d, right_normal(d))
    };
    Avoidance {
        u: w.dot(&dir) * dir - w,
        normal,
    }
}
