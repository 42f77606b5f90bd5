//! Minkowski sum of two convex polygons in O(n + m) by merging their edges in angle order.

use crate::geometry::{cross, Polygon};

/// `a ⊕ b` for counter-clockwise convex polygons. Both walks start at the lowest vertex, where
/// edge angles begin at 0, and at each step the edge that turns least is taken (both when
/// parallel or undefined), so the result is counter-clockwise and has at most `n + m` vertices.
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must advance, see below
pub fn minkowski_sum(a: &Polygon, b: &Polygon) -> Polygon {
    let (pa, pb) = (a.points(), b.points());
    let (n, m) = (pa.len(), pb.len());
    let mut out = Polygon::default();
    if n == 0 || m == 0 {
        return out;
    }
    let (sa, sb) = (a.lowest_vertex(), b.lowest_vertex());
    let va = |i: usize| pa[(sa + i) % n];
    let vb = |j: usize| pb[(sb + j) % m];
    let (mut i, mut j) = (0, 0);
    while i < n || j < m {
        out.push(va(i) + vb(j));
        if i == n {
            j += 1;
            continue;
        }
        if j == m {
            i += 1;
            continue;
        }
        let turn = cross(va(i + 1) - va(i), vb(j + 1) - vb(j));
        // Written with negations so that a NaN advances both walks (no endless loop).
        if !(turn < 0.0) {
            i += 1;
        }
        if !(turn > 0.0) {
            j += 1;
        }
    }
    out
}
