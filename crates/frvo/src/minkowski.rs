//! Minkowski sum of two convex polygons in O(n + m): both polygons' edges, merged in angle
//! order, are the sum's edges.

use crate::geometry::{cross, lowest_vertex, Polygon};

/// Sine of the angle below which two edges are merged as parallel.
pub const PARALLEL_SIN: f64 = 1e-9;

/// `a ⊕ b` for counter-clockwise convex polygons: counter-clockwise, starting at the lowest
/// vertex, with at most `n + m` vertices (truncated to [`crate::geometry::MAX_VERTICES`]).
/// Empty when either polygon is.
pub fn minkowski_sum(a: &Polygon, b: &Polygon) -> Polygon {
    let (pa, pb) = (a.points(), b.points());
    let (n, m) = (pa.len(), pb.len());
    let mut sum = Polygon::default();
    if n == 0 || m == 0 {
        return sum;
    }
    // Each polygon's k-th vertex counted from its lowest one, where edge angles start at 0.
    let (start_a, start_b) = (lowest_vertex(pa), lowest_vertex(pb));
    let va = |k: usize| pa[wrap(start_a + k, n)];
    let vb = |k: usize| pb[wrap(start_b + k, m)];
    let (mut i, mut j) = (0, 0);
    while i < n || j < m {
        sum.push(va(i) + vb(j));
        if i == n {
            j += 1;
            continue;
        }
        if j == m {
            i += 1;
            continue;
        }
        // Take the edge that turns least; both when parallel to within PARALLEL_SIN, so that
        // rounding cannot leave two collinear edges side by side (their facing tests could
        // then disagree for touching shapes). A NaN advances both walks (no endless loop).
        let (ea, eb) = (va(i + 1) - va(i), vb(j + 1) - vb(j));
        let turn = cross(ea, eb);
        let parallel =
            turn * turn <= PARALLEL_SIN * PARALLEL_SIN * ea.norm_squared() * eb.norm_squared();
        if parallel || turn.is_nan() || turn > 0.0 {
            i += 1;
        }
        if parallel || turn.is_nan() || turn < 0.0 {
            j += 1;
        }
    }
    sum
}

/// `i` modulo `n` for `i < 2n`.
pub(crate) fn wrap(i: usize, n: usize) -> usize {
    if i >= n {
        i - n
    } else {
        i
    }
}
