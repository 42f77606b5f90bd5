//! Neighbour search on a uniform grid: cells at least as wide as the search radius, so only the
//! 3 x 3 block around an agent's cell can hold its neighbours. Building is O(N); a query costs
//! the agents in those cells.

use crate::geometry::V2;

/// Upper bound on cells per axis, so that far-flung coordinates cannot blow up memory.
const MAX_CELLS_PER_AXIS: usize = 1024;

#[derive(Clone, Debug, Default)]
pub struct NeighborGrid {
    radius: f64,
    cell: f64,
    min: V2,
    nx: usize,
    ny: usize,
    /// Agents of cell `c` are `items[starts[c]..starts[c + 1]]`, stored with their positions
    /// so that a query reads memory in order.
    starts: Vec<u32>,
    items: Vec<(V2, u32)>,
}

impl NeighborGrid {
    /// Indexes the agents with `valid[i]` (finite positions). `radius` <= 0 or NaN finds nothing.
    pub fn build(&mut self, positions: &[V2], valid: &[bool], radius: f64) {
        self.radius = if radius.is_nan() {
            0.0
        } else {
            radius.max(0.0)
        };
        let (mut lo, mut hi) = (V2::repeat(f64::INFINITY), V2::repeat(f64::NEG_INFINITY));
        for (p, _) in positions.iter().zip(valid).filter(|(_, &ok)| ok) {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        self.starts.clear();
        self.items.clear();
        if lo.x > hi.x {
            (self.nx, self.ny) = (0, 0);
            return;
        }
        let extent = hi - lo;
        let per_axis =
            ((positions.len() as f64).sqrt().ceil() as usize).clamp(1, MAX_CELLS_PER_AXIS);
        // Cells no narrower than the radius, and not so many that the grid outgrows the crowd.
        let floor = extent.x.max(extent.y) / per_axis as f64;
        self.cell = self.radius.max(floor).max(1e-9);
        if !self.cell.is_finite() {
            self.cell = f64::MAX;
        }
        self.min = lo;
        self.nx = self.axis_cells(extent.x);
        self.ny = self.axis_cells(extent.y);
        let cells = self.nx * self.ny;
        self.starts.resize(cells + 1, 0);
        for (p, _) in positions.iter().zip(valid).filter(|(_, &ok)| ok) {
            let c = self.cell_of(*p);
            self.starts[c + 1] += 1;
        }
        for c in 0..cells {
            self.starts[c + 1] += self.starts[c];
        }
        self.items
            .resize(self.starts[cells] as usize, (V2::zeros(), 0));
        let mut fill = self.starts[..cells].to_vec();
        for (i, (p, _)) in positions
            .iter()
            .zip(valid)
            .enumerate()
            .filter(|(_, (_, &ok))| ok)
        {
            let c = self.cell_of(*p);
            self.items[fill[c] as usize] = (*p, i as u32);
            fill[c] += 1;
        }
    }

    fn axis_cells(&self, extent: f64) -> usize {
        let n = (extent / self.cell).floor();
        if n.is_finite() {
            (n as usize + 1).min(MAX_CELLS_PER_AXIS)
        } else {
            1
        }
    }

    fn cell_xy(&self, p: V2) -> (usize, usize) {
        let d = (p - self.min) / self.cell;
        let ix = (d.x.max(0.0) as usize).min(self.nx - 1);
        let iy = (d.y.max(0.0) as usize).min(self.ny - 1);
        (ix, iy)
    }

    fn cell_of(&self, p: V2) -> usize {
        let (ix, iy) = self.cell_xy(p);
        iy * self.nx + ix
    }

    /// Up to `max` agents other than `me` strictly within the radius of `positions[me]`, nearest
    /// first, as (squared distance, index) in `out`.
    pub fn query(&self, positions: &[V2], me: usize, max: usize, out: &mut Vec<(f64, usize)>) {
        out.clear();
        if self.nx == 0 || max == 0 || self.radius <= 0.0 {
            return;
        }
        let p = positions[me];
        if !(p.x.is_finite() && p.y.is_finite()) {
            return;
        }
        let r2 = self.radius * self.radius;
        let (cx, cy) = self.cell_xy(p);
        for iy in cy.saturating_sub(1)..(cy + 2).min(self.ny) {
            for ix in cx.saturating_sub(1)..(cx + 2).min(self.nx) {
                let c = iy * self.nx + ix;
                for &(q, j) in &self.items[self.starts[c] as usize..self.starts[c + 1] as usize] {
                    let d2 = (q - p).norm_squared();
                    if d2 < r2 && j as usize != me {
                        insert_nearest(out, max, (d2, j as usize));
                    }
                }
            }
        }
    }
}

/// Keeps `out` sorted by distance (ties in arrival order) and at most `max` long. An insertion
/// step by hand: `out` is short, and `Vec::insert`'s memmove call cost more than the shift.
fn insert_nearest(out: &mut Vec<(f64, usize)>, max: usize, item: (f64, usize)) {
    if out.len() == max {
        if item.0 >= out[max - 1].0 {
            return;
        }
        out.pop();
    }
    out.push(item);
    let mut k = out.len() - 1;
    while k > 0 && out[k - 1].0 > item.0 {
        out[k] = out[k - 1];
        k -= 1;
    }
    out[k] = item;
}
