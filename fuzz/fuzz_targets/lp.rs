//! `frvo::lp::solve` on arbitrary lines, speed limits and preferred velocities.
//!
//! Any input (NaN, infinities, zero or non-unit directions, subnormals): no panic and no hang.
//! Inputs inside the solver's contract (finite, unit directions, magnitudes up to 1e4, and no
//! value so small that products of two underflow: below 1e-30 it is taken as 0): the answer lies
//! in the speed disc, satisfies every half-plane when reported feasible, violates none by more
//! than the reported level when infeasible, equals the preferred velocity when that is already
//! allowed, and is the same bit for bit when solved again with a used scratch buffer.
#![no_main]

use arbitrary::Arbitrary;
use frvo::lp::{solve, Line};
use libfuzzer_sys::fuzz_target;
use nalgebra::Vector2;

#[derive(Arbitrary, Debug)]
struct RawLine {
    px: f64,
    py: f64,
    dx: f64,
    dy: f64,
}

#[derive(Arbitrary, Debug)]
struct Input {
    lines: Vec<RawLine>,
    max_speed: f64,
    pref: (f64, f64),
}

/// Largest coordinate (and speed) the contract check uses: pedestrian velocities and velocity
/// obstacle offsets in pixels per frame are far below it.
const BOUND: f64 = 1e4;

/// Magnitudes below this are flushed to zero for the contract check. Velocities in pixels per
/// frame differ by at least about 1e-19 where they differ at all, so their products never come
/// near the subnormal range (about 1e-308) in which the LP's cross products lose their bits.
const TINY: f64 = 1e-30;

fn in_contract(x: f64) -> bool {
    x.is_finite() && x.abs() <= BOUND
}

fn flush(v: Vector2<f64>) -> Vector2<f64> {
    v.map(|x| if x.abs() < TINY { 0.0 } else { x })
}

fuzz_target!(|input: Input| {
    if input.lines.len() > 64 {
        return;
    }
    // Anything goes: only no panic.
    let raw: Vec<Line> = input
        .lines
        .iter()
        .map(|l| Line {
            point: Vector2::new(l.px, l.py),
            dir: Vector2::new(l.dx, l.dy),
        })
        .collect();
    let pref = Vector2::new(input.pref.0, input.pref.1);
    let mut scratch = Vec::new();
    let _ = solve(&raw, input.max_speed, pref, &mut scratch);
    let pref = flush(pref);

    // Inside the contract: check the answer.
    let speed = input.max_speed.abs();
    if !(in_contract(speed) && speed > 1e-6 && in_contract(pref.x) && in_contract(pref.y)) {
        return;
    }
    let mut lines = Vec::with_capacity(raw.len());
    for l in &raw {
        let norm = l.dir.norm();
        if !(in_contract(l.point.x) && in_contract(l.point.y) && norm.is_finite() && norm > 1e-3) {
            return;
        }
        let dir = flush(l.dir / norm);
        lines.push(Line {
            point: flush(l.point),
            dir: dir / dir.norm(),
        });
    }
    let sol = solve(&lines, speed, pref, &mut scratch);
    let v = sol.velocity;
    assert!(v.x.is_finite() && v.y.is_finite(), "{sol:?}");
    let scale = lines
        .iter()
        .map(|l| l.point.norm())
        .fold(speed.max(pref.norm()).max(1.0), f64::max);
    let tol = 1e-9 * scale;
    assert!(
        v.norm() <= speed + tol,
        "speed {} > {speed}: {sol:?}",
        v.norm()
    );
    let worst = lines
        .iter()
        .map(|l| l.violation(v))
        .fold(f64::NEG_INFINITY, f64::max);
    if sol.feasible {
        assert!(
            worst <= tol,
            "feasible but a line is violated by {worst}: {sol:?}"
        );
        assert_eq!(sol.violation, 0.0);
    } else {
        assert!(sol.violation.is_finite() && sol.violation > -tol, "{sol:?}");
        assert!(
            worst <= sol.violation + tol,
            "a line is violated by {worst} > reported {}: {sol:?}",
            sol.violation
        );
    }
    let pref_ok = pref.norm() <= speed && lines.iter().all(|l| l.violation(pref) <= 0.0);
    if pref_ok {
        assert!(sol.feasible, "the preferred velocity is allowed: {sol:?}");
        assert!(
            (v - pref).norm() <= tol,
            "allowed preferred velocity moved: {sol:?}"
        );
    }
    let again = solve(&lines, speed, pref, &mut scratch);
    assert_eq!(
        (
            again.velocity.x.to_bits(),
            again.velocity.y.to_bits(),
            again.feasible
        ),
        (v.x.to_bits(), v.y.to_bits(), sol.feasible),
        "not repeatable with a used scratch buffer"
    );
});
