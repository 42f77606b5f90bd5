//! Minkowski sum of two convex polygons in O(n + m) by merging their edges in angle order.
//!
//! [`prepare`] puts a polygon in merge order (vertices from the lowest one, closed, with edge
//! vectors) and [`merge_prepared`] merges two such; [`minkowski_sum`] is the form on
//! [`Polygon`]s. The crowd step does its own merge (`pair::pair_avoidance`), tested against
//! this one.

use crate::geometry::{cross, lowest_vertex, Polygon, MAX_VERTICES, V2};

/// Sine of the angle below which two edges are merged as parallel.
pub const PARALLEL_SIN: f64 = 1e-9;

/// Appends a counter-clockwise polygon prepared for [`merge_prepared`]: its `n` vertices
/// starting at the lowest one (where edge angles begin at 0) followed by that vertex again
/// (`n + 1` points), and its `n` edge vectors.
pub fn prepare(poly: &[V2], pts: &mut Vec<V2>, edges: &mut Vec<V2>) {
    let n = poly.len();
    if n == 0 {
        return;
    }
    let start = lowest_vertex(poly);
    let first = pts.len();
    pts.extend_from_slice(&poly[start..]);
    pts.extend_from_slice(&poly[..start]);
    pts.push(poly[start]);
    edges.extend(pts[first..].windows(2).map(|w| w[1] - w[0]));
}

/// `a ⊕ b` for polygons prepared by [`prepare`] (`a`: `n + 1` points and `n` edges, likewise
/// `b`), written to `out` (cleared first). At each step the edge that turns least is taken
/// (both when parallel to within [`PARALLEL_SIN`], or undefined), so the result is
/// counter-clockwise, never holds an edge of `a` and a near-parallel one of `b` side by side,
/// starts at the lowest vertex and has at most `n + m` vertices (truncated to
/// [`MAX_VERTICES`]).
#[allow(clippy::neg_cmp_op_on_partial_ord)] // NaN must advance, see below
#[inline]
pub fn merge_prepared(a: &[V2], ea: &[V2], b: &[V2], eb: &[V2], out: &mut Polygon) {
    let (n, m) = (
        ea.len().min(a.len().saturating_sub(1)),
        eb.len().min(b.len().saturating_sub(1)),
    );
    if n == 0 || m == 0 {
        out.clear();
        return;
    }
    let (a, ea, b, eb) = (&a[..=n], &ea[..n], &b[..=m], &eb[..m]);
    out.fill(|buf| {
        let (mut i, mut j, mut k) = (0, 0, 0);
        // Branch-free advance: which edge comes next is data-dependent, so a branch would
        // mispredict about every other vertex.
        while i < n && j < m && k < MAX_VERTICES {
            buf[k] = a[i] + b[j];
            k += 1;
            let turn = cross(ea[i], eb[j]);
            // Edges parallel to within PARALLEL_SIN count as parallel and are taken together:
            // rounding must not leave two collinear edges, whose facing tests could then
            // disagree when the origin lies on their common line (touching shapes), which
            // turns the velocity obstacle's cone inside out.
            let tie = turn * turn
                <= PARALLEL_SIN * PARALLEL_SIN * ea[i].norm_squared() * eb[j].norm_squared();
            // Written with negations so that a NaN advances both walks (no endless loop).
            i += usize::from(tie || !(turn < 0.0));
            j += usize::from(tie || !(turn > 0.0));
        }
        // One walk is done (back at its first vertex); finish the other.
        for (slot, &q) in buf[k..].iter_mut().zip(&a[i..n]) {
            *slot = q + b[j];
            k += 1;
        }
        for (slot, &q) in buf[k..].iter_mut().zip(&b[j..m]) {
            *slot = a[i] + q;
            k += 1;
        }
        k
    });
}

/// `a ⊕ b` for counter-clockwise convex polygons (see [`merge_prepared`]).
pub fn minkowski_sum(a: &Polygon, b: &Polygon) -> Polygon {
    let mut prepared = [(Vec::new(), Vec::new()), (Vec::new(), Vec::new())];
    for (poly, (pts, edges)) in [a, b].into_iter().zip(&mut prepared) {
        prepare(poly.points(), pts, edges);
    }
    let [(pa, ea), (pb, eb)] = &prepared;
    let mut out = Polygon::default();
    if !pa.is_empty() && !pb.is_empty() {
        merge_prepared(pa, ea, pb, eb, &mut out);
    }
    out
}
