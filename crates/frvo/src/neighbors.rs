//! Neighbour search on a uniform grid of cells at least half as wide as the search radius: a
//! query reads, row by row, the run of cells that the disc reaches (one contiguous slice of
//! the agents per row, about twice the disc's area). Building is O(N).

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
        // Cells no narrower than half the radius, and not so many that the grid outgrows the
        // crowd.
        let floor = extent.x.max(extent.y) / per_axis as f64;
        self.cell = (0.5 * self.radius).max(floor).max(1e-9);
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
    /// first (equal distances by index), as (squared distance, index) in `out`.
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
        let local = (p - self.min) / self.cell;
        let reach = self.radius / self.cell;
        let cells = |lo: f64, hi: f64, n: usize| {
            let first = lo.floor().max(0.0) as usize;
            let last = (hi.floor().max(0.0) as usize).min(n - 1);
            first..last + 1
        };
        for iy in cells(local.y - reach, local.y + reach, self.ny) {
            // The disc's half-width (in cells) at the row's nearest edge to p: the cells of the
            // row within it are contiguous in `items`, so they are read as one slice.
            let gap = axis_gap(local.y, iy);
            let half = reach * reach - gap * gap;
            if half.is_nan() || half <= 0.0 {
                continue;
            }
            let half = half.sqrt();
            let xs = cells(local.x - half, local.x + half, self.nx);
            if xs.is_empty() {
                continue;
            }
            let row = iy * self.nx;
            let slice = &self.items
                [self.starts[row + xs.start] as usize..self.starts[row + xs.end] as usize];
            // All are written, then compacted to those strictly within the radius: no branch
            // to mispredict on about half of them.
            let start = out.len();
            out.extend(
                slice
                    .iter()
                    .map(|&(q, j)| ((q - p).norm_squared(), j as usize)),
            );
            let mut len = start;
            for idx in start..out.len() {
                let item = out[idx];
                out[len] = item;
                len += usize::from(item.0 < r2 && item.1 != me);
            }
            out.truncate(len);
        }
        // Squared distances are >= +0 and never NaN (finite positions), so their bit patterns
        // order like the numbers: (bits, index) is the total order "nearest, then lower index".
        let key = |x: &(f64, usize)| (x.0.to_bits(), x.1);
        if out.len() > max && max <= SMALL_MAX {
            // A few nearest of many: keep `max` of them unsorted in front, replacing the worst
            // kept one when a nearer candidate comes (rare once the front is near).
            let worst_of = |front: &[(f64, usize)]| {
                let mut w = 0;
                for (i, x) in front.iter().enumerate() {
                    if key(x) > key(&front[w]) {
                        w = i;
                    }
                }
                w
            };
            let mut worst = worst_of(&out[..max]);
            for idx in max..out.len() {
                if key(&out[idx]) < key(&out[worst]) {
                    out[worst] = out[idx];
                    worst = worst_of(&out[..max]);
                }
            }
            out.truncate(max);
        } else if out.len() > max {
            out.select_nth_unstable_by_key(max - 1, key);
            out.truncate(max);
        }
        out.sort_unstable_by_key(key);
    }
}

/// Up to this many nearest are picked by replacement, more by selection; then sorted.
const SMALL_MAX: usize = 16;

/// Distance (in cells) from coordinate `x` (in cells) to the nearest point of cell `i`.
#[inline]
fn axis_gap(x: f64, i: usize) -> f64 {
    let lo = i as f64;
    if x < lo {
        lo - x
    } else if x > lo + 1.0 {
        x - lo - 1.0
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig { cases: 500, failure_persistence: None, ..ProptestConfig::default() })]

        /// The grid's answer is the brute-force one: within the radius, nearest first, ties by
        /// index, at most `max`.
        #[test]
        fn query_matches_brute_force(
            pts in prop::collection::vec((0.0f64..300.0, 0.0f64..300.0), 1..120),
            radius in 0.0f64..200.0,
            max in 0usize..60,
            snap in any::<bool>(),
        ) {
            // Snapped to a 10 px lattice, many distances tie exactly.
            let positions: Vec<V2> = pts.iter().map(|&(x, y)| {
                if snap { V2::new((x / 10.0).round() * 10.0, (y / 10.0).round() * 10.0) } else { V2::new(x, y) }
            }).collect();
            let valid = vec![true; positions.len()];
            let mut grid = NeighborGrid::default();
            grid.build(&positions, &valid, radius);
            let mut out = Vec::new();
            for me in 0..positions.len() {
                grid.query(&positions, me, max, &mut out);
                let mut want: Vec<(f64, usize)> = (0..positions.len())
                    .filter(|&j| j != me)
                    .map(|j| ((positions[j] - positions[me]).norm_squared(), j))
                    .filter(|&(d2, _)| d2 < radius * radius)
                    .collect();
                want.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                want.truncate(max);
                prop_assert_eq!(&out, &want);
            }
        }
    }
}
