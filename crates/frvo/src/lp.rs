//! Incremental 2-D linear programming over half-planes and a speed disc (Seidel-style, the
//! scheme of RVO2's `linearProgram1/2/3`): find the velocity closest to the preferred one
//! inside every half-plane and the disc `|v| <= max_speed`; when none exists, the velocity in
//! the disc whose largest violation of a half-plane is smallest.
//!
//! Lines are added one at a time. The current optimum only moves when the new line cuts it off,
//! and then the new optimum lies on that line, which is a 1-D problem over the earlier lines.

use crate::geometry::{cross, left_normal, V2};

/// Lines whose directions' cross product is below this are treated as parallel.
const PARALLEL_EPS: f64 = 1e-12;

/// Below this cross product of two lines' directions, their bisector in the infeasible phase is
/// placed by its offset rather than through their far-away crossing point.
const NEAR_PARALLEL: f64 = 1e-6;

/// A directed line; its feasible half-plane lies to the left of `dir` (a unit vector).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    pub point: V2,
    pub dir: V2,
}

impl Line {
    /// Signed distance of `v` on the wrong (right) side of the line: <= 0 when feasible.
    pub fn violation(&self, v: V2) -> f64 {
        cross(self.dir, self.point - v)
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solution {
    pub velocity: V2,
    /// False when the half-planes and the disc have no common point; `velocity` then minimises
    /// the largest violation.
    pub feasible: bool,
    /// When infeasible, the min-max violation level reached (no line is violated by more at
    /// `velocity`, up to rounding); zero when feasible.
    pub violation: f64,
}

#[derive(Clone, Copy)]
enum Goal {
    /// Get as close as possible to this point.
    Nearest(V2),
    /// Go as far as possible along this unit direction.
    Farthest(V2),
}

/// Velocity closest to `pref` in all half-planes and `|v| <= max_speed` (or the min-max
/// violation point when infeasible). `scratch` is reused between calls to avoid allocation.
pub fn solve(lines: &[Line], max_speed: f64, pref: V2, scratch: &mut Vec<Line>) -> Solution {
    let mut v = V2::zeros();
    let failed = lp2(lines, max_speed, Goal::Nearest(pref), &mut v);
    if failed == lines.len() {
        return Solution {
            velocity: v,
            feasible: true,
            violation: 0.0,
        };
    }
    let violation = lp3(lines, failed, max_speed, &mut v, scratch);
    Solution {
        velocity: v,
        feasible: false,
        violation,
    }
}

/// Optimum on line `i` subject to lines `0..i` and the disc of `radius`; false if that segment
/// is empty.
fn lp1(lines: &[Line], i: usize, radius: f64, goal: Goal, out: &mut V2) -> bool {
    // Parameterise from the line's point nearest the origin: a far-away point (bisectors of
    // nearly parallel lines) would lose the disc bounds to cancellation.
    let dir = lines[i].dir;
    let offset = cross(dir, lines[i].point);
    let point = offset * left_normal(dir);
    // Parameter range [lo, hi] of point + t * dir inside the disc.
    let disc = radius * radius - offset * offset;
    if disc.is_nan() || disc < 0.0 {
        return false;
    }
    let root = disc.sqrt();
    let (mut lo, mut hi) = (-root, root);
    for other in &lines[..i] {
        // other.violation(point + t dir) <= 0  <=>  t * denom <= numer.
        let denom = cross(dir, other.dir);
        let numer = cross(other.dir, point - other.point);
        if denom.abs() <= PARALLEL_EPS {
            if numer >= -PARALLEL_EPS * radius.max(1.0) {
                // Parallel, and this line lies inside the other or within rounding of it (a
                // duplicate): the other bounds nothing here.
                continue;
            }
            if denom == 0.0 || numer < -denom.abs() * root {
                return false; // this line's segment in the disc lies wholly outside the other
            }
            // Nearly parallel lines crossing inside the disc: the other still bounds t.
        }
        let t = numer / denom;
        if denom > 0.0 {
            hi = hi.min(t);
        } else {
            lo = lo.max(t);
        }
        if lo > hi {
            return false;
        }
    }
    let t = match goal {
        Goal::Farthest(d) if d.dot(&dir) > 0.0 => hi,
        Goal::Farthest(_) => lo,
        // lo <= hi and neither is NaN here, so `clamp` cannot panic.
        Goal::Nearest(target) => dir.dot(&(target - point)).clamp(lo, hi),
    };
    *out = point + t * dir;
    true
}

/// Adds the lines one by one; returns `lines.len()` on success, or the index of the first line
/// that made the problem infeasible (`out` then holds the optimum of the lines before it).
fn lp2(lines: &[Line], radius: f64, goal: Goal, out: &mut V2) -> usize {
    *out = match goal {
        Goal::Farthest(d) => d * radius,
        Goal::Nearest(target) if target.norm_squared() > radius * radius => {
            target.normalize() * radius
        }
        Goal::Nearest(target) => target,
    };
    for i in 0..lines.len() {
        if lines[i].violation(*out) > 0.0 {
            let before = *out;
            if !lp1(lines, i, radius, goal, out) {
                *out = before;
                return i;
            }
        }
    }
    lines.len()
}

/// Infeasible case, from line `begin` on: minimise the largest violation `d` (a 3-D LP in
/// (v, d)). Whenever a line is violated by more than the current `d`, the new optimum has equal
/// violation of that line and the worst earlier ones: a 2-D LP over the bisectors of that line
/// and each earlier line, pushing as far as possible into the line's feasible side. Returns
/// the level reached: a later line violated by no more than it is skipped.
fn lp3(lines: &[Line], begin: usize, radius: f64, out: &mut V2, projected: &mut Vec<Line>) -> f64 {
    let mut worst = 0.0;
    for i in begin..lines.len() {
        let line = lines[i];
        if line.violation(*out) <= worst {
            continue;
        }
        projected.clear();
        for other in &lines[..i] {
            let denom = cross(line.dir, other.dir);
            if denom.abs() <= PARALLEL_EPS && line.dir.dot(&other.dir) > 0.0 {
                continue; // same direction: the other is less violated everywhere
            }
            let dir = other.dir - line.dir;
            let norm = dir.norm();
            if norm == 0.0 {
                continue;
            }
            let dir = dir / norm;
            let point = if denom.abs() < NEAR_PARALLEL {
                // Nearly (anti)parallel lines cross far away: take the bisector's point nearest
                // the origin, cross(e, v) = cross(do, po) - cross(dl, pl) with e = do - dl.
                let c = cross(other.dir, other.point) - cross(line.dir, line.point);
                (c / norm) * left_normal(dir)
            } else {
                line.point + (cross(other.dir, line.point - other.point) / denom) * line.dir
            };
            projected.push(Line { point, dir });
        }
        let before = *out;
        let goal = Goal::Farthest(left_normal(line.dir));
        if lp2(projected, radius, goal, out) < projected.len() {
            // Only reachable through rounding; keep the previous point.
            *out = before;
        }
        worst = line.violation(*out);
    }
    worst
}
