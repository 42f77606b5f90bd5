//! Inputs on which `cargo fuzz run lp` (fuzz/fuzz_targets/lp.rs) once failed, kept as tests.

use frvo::geometry::V2;
use frvo::lp::{solve, Line};

fn unit(x: f64, y: f64) -> V2 {
    V2::new(x, y).normalize()
}

/// Two nearly parallel lines (cross product of their directions about 3e-148) through nearly
/// the same point: they cross inside the speed disc, so the problem is feasible and the
/// preferred velocity, on both boundaries, is the answer. It was once reported infeasible,
/// with the velocity pushed to the disc's edge and a negative "largest violation".
#[test]
fn nearly_parallel_lines_crossing_inside_the_disc() {
    let lines = [
        Line {
            point: V2::new(2.265498544049335e-309, 2.1729236899484e-311),
            dir: unit(33.26274509803921, -1.0636066443160366e-146),
        },
        Line {
            point: V2::new(-1.1031085267149825e-146, 1.339769891e-314),
            dir: unit(5.256633473081384e83, 4.41742604262458e-310),
        },
    ];
    let pref = V2::new(32.501960784313724, 8.1264e-320);
    let sol = solve(&lines, 33.26273157570109, pref, &mut Vec::new());
    assert!(sol.feasible, "{sol:?}");
    assert!((sol.velocity - pref).norm() < 1e-9, "{sol:?}");
    for l in &lines {
        assert!(l.violation(sol.velocity) <= 1e-12, "{sol:?}");
    }
}

/// The same with realistic magnitudes: the boundaries of `a` (y >= 1e-13 x) and `b`
/// (y >= -1e-14) cross at x = -0.1, inside the disc. A preference below both at x = -0.5 first
/// moves onto `a`, which then violates `b`; the optimum is on `b`, not at the disc's edge.
#[test]
fn nearly_parallel_constraints_crossing_inside_the_disc() {
    let a = Line {
        point: V2::new(0.0, 0.0),
        dir: unit(1.0, 1e-13),
    };
    let b = Line {
        point: V2::new(0.0, -1e-14),
        dir: V2::new(1.0, 0.0),
    };
    let pref = V2::new(-0.5, -0.3);
    for lines in [[a, b], [b, a]] {
        let sol = solve(&lines, 2.0, pref, &mut Vec::new());
        assert!(sol.feasible, "{sol:?}");
        assert!(
            (sol.velocity - V2::new(-0.5, -1e-14)).norm() < 1e-9,
            "{sol:?}"
        );
    }
    // A preference both allow is kept.
    let pref = V2::new(0.5, 0.2);
    let sol = solve(&[a, b], 2.0, pref, &mut Vec::new());
    assert!(sol.feasible && sol.velocity == pref, "{sol:?}");
}

/// Two nearly antiparallel lines (directions 1.7e-12 off) 84 px apart, far from the origin:
/// no velocity satisfies both, and the min-max answer violates each by the same amount (half
/// the gap). Their bisector was once placed through their crossing point, about 5e13 away,
/// where rounding moved it by 0.002 px: one line was then violated by more than the reported
/// level.
#[test]
fn nearly_antiparallel_lines_split_the_violation_evenly() {
    let lines = [
        Line {
            point: V2::new(-1.0660607428338825e-146, 1.2553953967496001e-305),
            dir: unit(5.256633473058935e83, 5.256633473076691e83),
        },
        Line {
            point: V2::new(-8493.176470555978, -8577.50588235294),
            dir: unit(-8577.50588235294, -8577.50588235294),
        },
    ];
    let pref = V2::new(-8577.50588235294, -8577.50588235294);
    let sol = solve(&lines, 8577.50588235294, pref, &mut Vec::new());
    assert!(!sol.feasible, "{sol:?}");
    let (a, b) = (
        lines[0].violation(sol.velocity),
        lines[1].violation(sol.velocity),
    );
    assert!((a - b).abs() < 1e-8, "violations {a} and {b}: {sol:?}");
    assert!(a.max(b) <= sol.violation + 1e-8, "{sol:?}");
}

/// The same line twice, far enough from the origin that projecting onto the first leaves the
/// point a rounding error outside the second: once reported infeasible (the two taken as
/// parallel with the second wholly outside the first).
#[test]
fn a_duplicate_line_changes_nothing() {
    let line = Line {
        point: V2::new(3.461765682e-314, 25.2509765625),
        dir: unit(48.501960784313724, 32.505805999157474),
    };
    let pref = V2::new(1.7619348246195804e-18, 0.0);
    let one = solve(&[line], 32.501838714001224, pref, &mut Vec::new());
    let two = solve(&[line, line], 32.501838714001224, pref, &mut Vec::new());
    assert!(one.feasible && two.feasible, "{one:?} {two:?}");
    assert!(
        (one.velocity - two.velocity).norm() < 1e-12,
        "{one:?} {two:?}"
    );
}
