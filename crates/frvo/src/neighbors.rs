//! Neighbour search on a uniform grid: the agents within a radius, nearest first (the paper's
//! neighbourhood `H_i`, capped at the `max` nearest as RVO2's `maxNeighbors`). Building is
//! O(N); a query reads rings of cells around the agent, nearest ring first, and stops when no
//! cell left can hold an agent nearer than the farthest it keeps (RVO2 does the same on a k-d
//! tree).

use crate::geometry::{is_finite, V2};

/// Cells along an axis at most, so that far-flung coordinates cannot blow up memory.
const MAX_CELLS_PER_AXIS: usize = 1024;
/// Agents per cell in an evenly spread crowd.
const AGENTS_PER_CELL: f64 = 2.0;

#[derive(Clone, Debug, Default)]
pub struct NeighborGrid {
    radius: f64,
    /// Corner of the grid (the agents' smallest coordinates) and side of its square cells.
    min: V2,
    cell: f64,
    nx: usize,
    ny: usize,
    /// Agents of cell `c` (row-major) are `items[starts[c]..starts[c + 1]]`, stored with their
    /// positions.
    starts: Vec<usize>,
    items: Vec<(V2, usize)>,
}

impl NeighborGrid {
    /// Indexes the agents with `valid[i]` and a finite position. `radius` <= 0 or NaN finds nothing.
    pub fn build(&mut self, positions: &[V2], valid: &[bool], radius: f64) {
        self.radius = if radius.is_nan() {
            0.0
        } else {
            radius.max(0.0)
        };
        let agents = || {
            positions
                .iter()
                .zip(valid)
                .enumerate()
                .filter(|(_, (&p, &ok))| ok && is_finite(p))
                .map(|(i, (&p, _))| (i, p))
        };
        let (mut lo, mut hi) = (V2::repeat(f64::INFINITY), V2::repeat(f64::NEG_INFINITY));
        let mut n = 0;
        for (_, p) in agents() {
            lo = lo.inf(&p);
            hi = hi.sup(&p);
            n += 1;
        }
        self.starts.clear();
        self.items.clear();
        (self.nx, self.ny) = (0, 0);
        if n == 0 {
            return;
        }
        // Cells sized for a few agents each, but no more cells along an axis than agents (a
        // thin crowd) or than MAX_CELLS_PER_AXIS.
        let extent = hi - lo;
        let longest = extent.x.max(extent.y);
        let cell = (extent.x * extent.y * AGENTS_PER_CELL / n as f64)
            .sqrt()
            .max(longest / n as f64)
            .max(longest / MAX_CELLS_PER_AXIS as f64);
        self.cell = if cell > 0.0 { cell.min(f64::MAX) } else { 1.0 };
        self.min = lo;
        let cells = |extent: f64| ((extent / self.cell) as usize).min(MAX_CELLS_PER_AXIS - 1) + 1;
        (self.nx, self.ny) = (cells(extent.x), cells(extent.y));
        // A counting sort of the agents by cell.
        self.starts.resize(self.nx * self.ny + 1, 0);
        for (_, p) in agents() {
            let c = self.cell_of(p);
            self.starts[c + 1] += 1;
        }
        for c in 1..self.starts.len() {
            self.starts[c] += self.starts[c - 1];
        }
        self.items.resize(n, (V2::zeros(), 0));
        let mut fill = self.starts.clone();
        for (i, p) in agents() {
            let c = self.cell_of(p);
            self.items[fill[c]] = (p, i);
            fill[c] += 1;
        }
    }

    /// Column and row of the cell holding `p` (the nearest cell for a point outside the grid).
    fn cell_xy(&self, p: V2) -> (usize, usize) {
        let d = (p - self.min) / self.cell;
        // `as` saturates: negative and NaN to 0.
        (
            (d.x as usize).min(self.nx - 1),
            (d.y as usize).min(self.ny - 1),
        )
    }

    fn cell_of(&self, p: V2) -> usize {
        let (x, y) = self.cell_xy(p);
        y * self.nx + x
    }

    /// Up to `max` agents other than `me` strictly within the radius of `positions[me]`, nearest
    /// first (equal distances by index), as (squared distance, index) in `out`.
    pub fn query(&self, positions: &[V2], me: usize, max: usize, out: &mut Vec<(f64, usize)>) {
        out.clear();
        let p = positions[me];
        if self.nx == 0 || max == 0 || self.radius <= 0.0 || !is_finite(p) {
            return;
        }
        let radius2 = self.radius * self.radius;
        // Squared distance beyond which no agent can be kept: the radius's, then, once `max`
        // are kept, the farthest one's.
        let mut reach2 = radius2;
        let (cx, cy) = self.cell_xy(p);
        for ring in 0..=self.nx.max(self.ny) {
            // Every cell of ring `ring` (the cells `ring` steps from p's, counted along the
            // farther axis) is at least `ring - 1` cells from p.
            let gap = ring.saturating_sub(1) as f64 * self.cell;
            if gap * gap > reach2 {
                break;
            }
            for (x, y) in ring_cells(cx, cy, ring, self.nx, self.ny) {
                let c = y * self.nx + x;
                for &(q, j) in &self.items[self.starts[c]..self.starts[c + 1]] {
                    let d2 = (q - p).norm_squared();
                    if j == me || d2 >= radius2 {
                        continue;
                    }
                    if out.len() == max && (d2, j) >= out[max - 1] {
                        continue; // no nearer than the farthest kept
                    }
                    out.insert(out.partition_point(|&x| x < (d2, j)), (d2, j));
                    out.truncate(max);
                    if out.len() == max {
                        reach2 = out[max - 1].0;
                    }
                }
            }
        }
    }
}

/// The cells of the square ring `ring` cells from (cx, cy) that lie in an `nx` x `ny` grid.
fn ring_cells(
    cx: usize,
    cy: usize,
    ring: usize,
    nx: usize,
    ny: usize,
) -> impl Iterator<Item = (usize, usize)> {
    let (x0, x1) = (cx.saturating_sub(ring), (cx + ring).min(nx - 1));
    let (y0, y1) = (cy.saturating_sub(ring), (cy + ring).min(ny - 1));
    (y0..=y1).flat_map(move |y| {
        // The ring's top and bottom rows whole, its other rows at its left and right ends.
        let (row, ends) = if y.abs_diff(cy) == ring {
            (x0..x1 + 1, [None, None])
        } else {
            let left = cx.checked_sub(ring);
            let right = Some(cx + ring).filter(|&x| x < nx && ring > 0);
            (0..0, [left, right])
        };
        row.chain(ends.into_iter().flatten()).map(move |x| (x, y))
    })
}
