//! Neighbour search on a uniform grid of a few cells per agent. A query searches a disc that
//! the crowd's density predicts to hold a few more agents than wanted, and a wider one only
//! where that disc holds too few (the agents within a disc are the nearest if there are enough
//! of them), reading the cells row by row (one contiguous slice of the agents per row). Building
//! is O(N).

use crate::geometry::V2;
use std::ops::Range;

/// Upper bound on agent spacings per axis, so that far-flung coordinates cannot blow up memory.
const MAX_CELLS_PER_AXIS: usize = 1024;
/// Cell width and row height, in agent spacings. A query reads one slice of agents per row (a
/// loop, with its fixed costs and an exit that branch predictors miss), whose end cells stick
/// out of the disc: narrow cells waste fewer candidates at no cost per row, and rows a bit
/// taller than the spacing make fewer rows for a few more candidates.
const CELL_WIDTH: f64 = 0.25;
const ROW_HEIGHT: f64 = 2.0;

#[derive(Clone, Debug, Default)]
pub struct NeighborGrid {
    radius: f64,
    /// The agents' typical spacing.
    spacing: f64,
    /// Cell width and row height.
    cell: V2,
    /// Row height over cell width.
    aspect: f64,
    /// Bounding box of the agents.
    min: V2,
    max: V2,
    /// Agents per unit area of the bounding box padded by a spacing.
    density: f64,
    nx: usize,
    ny: usize,
    /// The last cell along each axis, `nx - 1` and `ny - 1`.
    last: (u32, u32),
    /// Agents of cell `c` are `items[starts[c]..starts[c + 1]]`, stored with their positions
    /// so that a query reads memory in order.
    starts: Vec<u32>,
    items: Vec<(V2, u32)>,
}

/// What queries for up to `max` agents share, computed once per built grid (see
/// `NeighborGrid::plan`).
#[derive(Clone, Copy, Debug)]
pub struct Plan {
    max: usize,
    /// Whether every query finds nothing.
    none: bool,
    /// A few more agents than `max`, so that the first disc rarely falls short.
    want: f64,
    /// Room in front of the agents found (see `NeighborGrid::search`).
    front: usize,
    buckets: usize,
    /// `buckets`, as a float.
    buckets_f64: f64,
    /// Radius of a disc that the crowd's density predicts to hold `want` agents.
    reach: f64,
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
        let mut n = 0usize;
        for (p, _) in positions.iter().zip(valid).filter(|(_, &ok)| ok) {
            lo = lo.inf(p);
            hi = hi.sup(p);
            n += 1;
        }
        self.starts.clear();
        self.items.clear();
        if n == 0 {
            (self.nx, self.ny) = (0, 0);
            return;
        }
        let extent = hi - lo;
        let longest = extent.x.max(extent.y);
        // The bounding box's area per agent, but no more spacings along an axis than agents,
        // so that a thin crowd cannot blow up the grid. A query's first disc holds about `max`
        // agents whatever the radius: cells sized by the radius would make it read many more.
        self.spacing = (extent.x * extent.y / n as f64)
            .sqrt()
            .max(longest / n as f64)
            .max(longest / MAX_CELLS_PER_AXIS as f64)
            .max(1e-9);
        let finite = |x: f64| if x.is_finite() { x } else { f64::MAX };
        self.spacing = finite(self.spacing);
        self.cell = V2::new(
            finite(self.spacing * CELL_WIDTH),
            finite(self.spacing * ROW_HEIGHT),
        );
        self.aspect = self.cell.y / self.cell.x;
        // Padded, as a lattice of m x m agents spaced s spans (m - 1) s.
        self.density = n as f64 / ((extent.x + self.spacing) * (extent.y + self.spacing));
        self.min = lo;
        self.max = hi;
        self.nx = axis_cells(extent.x, self.cell.x);
        self.ny = axis_cells(extent.y, self.cell.y);
        self.last = ((self.nx - 1) as u32, (self.ny - 1) as u32);
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

    fn cell_xy(&self, p: V2) -> (usize, usize) {
        let d = (p - self.min).component_div(&self.cell);
        let ix = (d.x.max(0.0) as usize).min(self.nx - 1);
        let iy = (d.y.max(0.0) as usize).min(self.ny - 1);
        (ix, iy)
    }

    fn cell_of(&self, p: V2) -> usize {
        let (ix, iy) = self.cell_xy(p);
        iy * self.nx + ix
    }

    /// The constants of queries for up to `max` agents in this grid (until it is built again).
    pub fn plan(&self, max: usize) -> Plan {
        // Enough that the first disc falls short for one query in 70 to 200 in the benchmark's
        // crowds (each costs a second disc), but little more: every agent wanted costs some 1.5
        // candidates read.
        let want = max as f64 + 0.75 * (max as f64).sqrt() + 2.0;
        let buckets = ((want * BUCKETS_PER_AGENT) as usize).clamp(1, BUCKETS);
        Plan {
            max,
            none: self.nx == 0 || max == 0 || self.radius <= 0.0,
            want,
            front: (want + want.sqrt()).min(FILED as f64) as usize,
            buckets,
            buckets_f64: buckets as f64,
            reach: (want / (std::f64::consts::PI * self.density)).sqrt(),
        }
    }

    /// Up to `max` agents other than `me` strictly within the radius of `positions[me]`, nearest
    /// first (equal distances by index), as (squared distance, index) in `out`.
    pub fn query(&self, positions: &[V2], me: usize, max: usize, out: &mut Vec<(f64, usize)>) {
        let found = self.search(positions, me, &self.plan(max), out);
        out.copy_within(found.clone(), 0);
        out.truncate(found.len());
    }

    /// `query` for `plan`'s `max`, as a part of `scratch` (whose length is of no concern to
    /// the caller): one scratch kept across queries is written only where agents are found,
    /// where `query` fills the room it needs for every query.
    pub fn nearest<'a>(
        &self,
        positions: &[V2],
        me: usize,
        plan: &Plan,
        scratch: &'a mut Vec<(f64, usize)>,
    ) -> &'a [(f64, usize)] {
        let found = self.search(positions, me, plan, scratch);
        &scratch[found]
    }

    /// Where in `out` the agents of `query` end up.
    fn search(
        &self,
        positions: &[V2],
        me: usize,
        plan: &Plan,
        out: &mut Vec<(f64, usize)>,
    ) -> Range<usize> {
        let Plan { max, front, .. } = *plan;
        if plan.none {
            return 0..0;
        }
        let p = positions[me];
        // Finite (a comparison each, cheaper than `is_finite`).
        if !((p.x.abs() < f64::INFINITY) & (p.y.abs() < f64::INFINITY)) {
            return 0..0;
        }
        // The agents found are written after `out[..front]`, over whatever `out` holds: room
        // to sort them into, which the first disc nearly always leaves enough of (`out` is
        // sized for `front` of them, and grows where a disc finds more).
        if out.len() < 2 * front + 16 {
            out.resize(2 * front + 16, (0.0, 0));
        }
        let mut disc = Disc::new(p, self.first_radius(p, plan.reach), me, plan);
        let mut found = self.collect(&mut disc, out, front);
        // With `max` agents other than `me` (which `found` counts) within r <= radius, any
        // agent outside is farther than all of them: they are the nearest `max`.
        if found <= max && disc.r < self.radius {
            found = self.widen(&mut disc, out, plan, found);
        }
        disc.sort(out, front, found, max)
    }

    /// Searches ever wider discs until one holds enough agents (or all there are, or reaches
    /// the radius), and returns how many it holds. Rare, and out of line.
    #[inline(never)]
    fn widen(
        &self,
        disc: &mut Disc,
        out: &mut Vec<(f64, usize)>,
        plan: &Plan,
        mut found: usize,
    ) -> usize {
        // Every agent lies within sqrt(far2) of p: a disc wider than that finds them all.
        let p = disc.p;
        let far = (p - self.min).abs().sup(&(self.max - p).abs());
        let far2 = far.norm_squared();
        while found <= plan.max && disc.r < self.radius && disc.r2 <= far2 {
            // Wider by the density found (at least by half), to hold `want` this time.
            let grow = (plan.want / found.max(1) as f64).sqrt().max(1.5);
            *disc = Disc::new(p, (disc.r * grow).min(self.radius), disc.me, plan);
            found = self.collect(disc, out, plan.front);
        }
        found
    }

    /// `reach` around `p`, widened where the disc sticks out of the crowd's bounding box, but
    /// no less than a spacing nor more than the radius.
    fn first_radius(&self, p: V2, reach: f64) -> f64 {
        // Comparisons and selects, which `f64::min` and `max` are not (they also order NaNs):
        // all here are numbers, and `p` lies in the box (but for an invalid `me`).
        let min = |a: f64, b: f64| if a < b { a } else { b };
        let max = |a: f64, b: f64| if a > b { a } else { b };
        // Share of the disc's bounding square inside the padded box.
        let pad = 0.5 * self.spacing;
        let inside = |lo: f64, hi: f64, x: f64| min(x + reach, hi + pad) - max(x - reach, lo - pad);
        let share = inside(self.min.x, self.max.x, p.x) * inside(self.min.y, self.max.y, p.y)
            / (4.0 * reach * reach);
        let r = if share > 0.0 && share < 1.0 {
            reach / share.sqrt()
        } else {
            reach
        };
        min(max(r, self.spacing), self.radius)
    }

    /// Writes the agents within the disc to `out[front..]`, unordered, counts them by bucket,
    /// and returns how many: `me` too, where it is valid (`Disc::sort` drops it).
    #[inline(always)]
    fn collect(&self, disc: &mut Disc, out: &mut Vec<(f64, usize)>, front: usize) -> usize {
        let (p, r2) = (disc.p, disc.r2);
        let local = (p - self.min).component_div(&self.cell);
        // In rows, and a hair wider, so that rounding cannot drop a cell that holds an agent
        // within r.
        let reach = r2.sqrt() / self.cell.y * (1.0 + 1e-9);
        // The cells from `lo` to `hi` (in cells) that exist: the conversion saturates (below 0
        // and NaN to 0) and truncates (floors the rest), without a call to `floor`.
        let cells = |lo: f64, hi: f64, last: u32| ((lo as u32).min(last), (hi as u32).min(last));
        let (y0, y1) = cells(local.y - reach, local.y + reach, self.last.1);
        let mut end = front;
        for iy in y0 as usize..y1 as usize + 1 {
            // The disc's half-width (in cells) at the row's nearest edge to p: the cells of the
            // row within it are contiguous in `items`, so they are read as one slice.
            let gap = axis_gap(local.y, iy);
            if gap > reach {
                continue;
            }
            // Not sqrt(reach^2 - gap^2), which underflows to 0 for a tiny reach.
            let half = (reach - gap).sqrt() * (reach + gap).sqrt() * self.aspect;
            let (x0, x1) = cells(local.x - half, local.x + half, self.last.0);
            let row = iy * self.nx;
            let slice = &self.items[self.starts[row + x0 as usize] as usize
                ..self.starts[row + x1 as usize + 1] as usize];
            if out.len() < end + slice.len() {
                out.resize(2 * (end + slice.len()), (0.0, 0));
            }
            // Every candidate is written and counted in its bucket, and kept by advancing `end`:
            // many lie outside the disc (a fifth to a third in the benchmark's crowd), in no
            // order that a branch predictor could learn.
            for &(q, j) in slice {
                let d2 = (q - p).norm_squared();
                let b = disc.bucket(d2);
                let keep = d2 < r2;
                out[end] = (d2, j as usize);
                // Wrapping past 255 agents, which are sorted without the buckets.
                disc.count[b as usize] = disc.count[b as usize].wrapping_add(u8::from(keep));
                end += usize::from(keep);
            }
        }
        end - front
    }
}

/// Cells of size `cell` along an axis of the crowd's `extent`.
fn axis_cells(extent: f64, cell: f64) -> usize {
    let n = (extent / cell).floor();
    if n.is_finite() {
        // As many as the spacings allow, cells being a quarter spacing wide.
        (n as usize + 1).min(MAX_CELLS_PER_AXIS * 4)
    } else {
        1
    }
}

/// Most buckets of a disc, less one (agents at the disc's edge may round up to one more): the
/// 256 counts of a disc take any `u8` as a bucket.
const BUCKETS: usize = 254;
/// Buckets per agent wanted: enough that few agents share a bucket with a nearer one (each
/// costs a mispredicted branch or two to move), at about an instruction per bucket.
const BUCKETS_PER_AGENT: f64 = 4.0;
/// Most agents ordered by buckets (their positions are `u8`): more are sorted whole.
const FILED: usize = u8::MAX as usize;
/// See `Disc::bucket`.
const ROUND: f64 = (1u64 << 52) as f64;
/// A `u8` in every byte of a `u64`.
const BYTES: u64 = 0x0101_0101_0101_0101;

/// A search disc around `p` (for agent `me`), whose agents are ordered by buckets of equal width
/// in squared distance: agents spread evenly over the disc spread evenly over the buckets, so
/// that a counting sort by bucket leaves little to order. Loop ends aside, only that little
/// ordering branches on the data.
struct Disc {
    p: V2,
    r: f64,
    r2: f64,
    me: usize,
    /// Buckets per unit of squared distance.
    scale: f64,
    buckets: usize,
    /// Agents found per bucket (then where each bucket starts, then ends, in `Disc::sort`).
    count: [u8; BUCKETS + 2],
}

impl Disc {
    fn new(p: V2, r: f64, me: usize, plan: &Plan) -> Self {
        let r2 = r * r;
        let scale = plan.buckets_f64 / r2;
        Self {
            p,
            r,
            r2,
            me,
            // Infinite only for a tiny r2: all in one bucket then.
            scale: if scale < f64::INFINITY { scale } else { 0.0 },
            buckets: plan.buckets,
            count: [0; BUCKETS + 2],
        }
    }

    /// The bucket of squared distance `d2`: at most `buckets` where `d2` < `r2` (rounding may
    /// reach the last), and any `u8` beyond.
    #[inline]
    fn bucket(&self, d2: f64) -> u8 {
        // Adding 2^52 rounds a number in [0, 2^52) to an integer in the low mantissa bits:
        // monotone, as a conversion to an integer is, and cheaper. Not clamped: that would
        // cost a branch, and agents beyond the disc are not counted.
        ((d2 * self.scale + ROUND).to_bits() - ROUND.to_bits()) as u8
    }

    /// Orders `out`'s `found` agents after `out[..front]` (room), and returns where the nearest
    /// `max` of them other than `me` are in `out`, nearest first (equal distances by index).
    fn sort(
        &mut self,
        out: &mut Vec<(f64, usize)>,
        front: usize,
        found: usize,
        max: usize,
    ) -> Range<usize> {
        if found > FILED {
            let agents = &mut out[front..front + found];
            let lead = self.lead_me(agents, found);
            let (others, n) = (&mut agents[lead..], max.min(found - lead));
            if others.len() > n {
                others.select_nth_unstable_by_key(n - 1, key);
            }
            others[..n].sort_unstable_by_key(key);
            return front + lead..front + lead + n;
        }
        // Counts to starts, eight at a time: no sum exceeds `found` <= 255, so no byte carries
        // into the next, and multiplying by `BYTES` sums each byte and those below it.
        let mut sum = 0;
        for word in self.count.chunks_exact_mut(8).take(self.buckets / 8 + 1) {
            let counts = u64::from_le_bytes((&*word).try_into().unwrap());
            let through = counts.wrapping_mul(BYTES);
            word.copy_from_slice(&((through << 8) + sum * BYTES).to_le_bytes());
            sum += through >> 56;
        }
        // A counting sort by bucket into the room, or after the agents where it is too small.
        let to = if found <= front { 0 } else { front + found };
        if out.len() < to + found {
            out.resize(to + found, (0.0, 0));
        }
        let (sorted, agents) = if to == 0 {
            let (room, agents) = out.split_at_mut(front);
            (&mut room[..found], &agents[..found])
        } else {
            let (agents, rest) = out[front..].split_at_mut(found);
            (&mut rest[..found], &*agents)
        };
        for x in agents {
            let at = &mut self.count[self.bucket(x.0) as usize];
            sorted[*at as usize] = *x;
            *at += 1;
        }
        // `me`, at distance 0, lies in bucket 0 (which `count[0]` now ends).
        let lead = self.lead_me(sorted, self.count[0] as usize);
        let n = max.min(found - lead);
        if n > 0 {
            // Insertion: an agent can be out of order only among the few of its bucket, and only
            // the buckets up to the one of the `n`-th agent need ordering (`count[b]` is now the
            // end of bucket `b`). The test for order is the one data-dependent branch.
            let end = self.count[self.bucket(sorted[lead + n - 1].0) as usize] as usize;
            insertion_sort(&mut sorted[lead..end]);
        }
        to + lead..to + lead + n
    }

    /// Moves `me` to the front of `agents` and returns 1, or returns 0 where it is not among
    /// them (an invalid `me`). It is looked for in `agents[..likely]` (where it comes first or
    /// nearly), whose order is kept but for it. Beyond (where positions other than the grid's
    /// put it), the others are then sorted whole.
    fn lead_me(&self, agents: &mut [(f64, usize)], likely: usize) -> usize {
        let is_me = |x: &(f64, usize)| x.1 == self.me;
        if let Some(at) = agents[..likely].iter().position(is_me) {
            lead(agents, at);
            return 1;
        }
        match agents[likely..].iter().position(is_me) {
            Some(at) => {
                lead(agents, likely + at);
                agents[1..].sort_unstable_by_key(key);
                1
            }
            None => 0,
        }
    }
}

/// Moves `agents[at]` to the front, the others before it one place on.
fn lead(agents: &mut [(f64, usize)], at: usize) {
    let first = agents[at];
    // Usually none to move: no call to `copy_within`.
    for i in (0..at).rev() {
        agents[i + 1] = agents[i];
    }
    agents[0] = first;
}

/// Squared distances are >= +0 and never NaN (finite positions), so their bit patterns order
/// like the numbers: (bits, index) is the total order "nearest, then lower index".
fn key(x: &(f64, usize)) -> u128 {
    (u128::from(x.0.to_bits()) << 64) | x.1 as u128
}

/// Sorts `agents` by (squared distance, index), which the buckets nearly have them in.
fn insertion_sort(agents: &mut [(f64, usize)]) {
    for i in 1..agents.len() {
        let x = agents[i];
        if key(&x) < key(&agents[i - 1]) {
            let mut at = i;
            while at > 0 && key(&x) < key(&agents[at - 1]) {
                agents[at] = agents[at - 1];
                at -= 1;
            }
            agents[at] = x;
        }
    }
}

/// Distance (in cells) from coordinate `x` (in cells) to the nearest point of cell `i`.
#[inline]
fn axis_gap(x: f64, i: usize) -> f64 {
    let (before, after) = (i as f64 - x, x - i as f64 - 1.0);
    // Selects (`maxsd`), not branches or `f64::max` (which also orders NaNs).
    let gap = if before > after { before } else { after };
    if gap > 0.0 {
        gap
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Checks every agent's query (valid or not) against brute force: the valid agents other
    /// than it strictly within the radius, nearest first, ties by index, at most `max`.
    fn check(
        positions: &[V2],
        valid: &[bool],
        radius: f64,
        max: usize,
    ) -> Result<(), TestCaseError> {
        let mut grid = NeighborGrid::default();
        grid.build(positions, valid, radius);
        let plan = grid.plan(max);
        let (mut out, mut scratch) = (Vec::new(), Vec::new());
        for me in 0..positions.len() {
            grid.query(positions, me, max, &mut out);
            let found = grid.nearest(positions, me, &plan, &mut scratch);
            prop_assert_eq!(found, &out[..], "agent {}", me);
            let mut want: Vec<(f64, usize)> = (0..positions.len())
                .filter(|&j| j != me && valid[j] && radius > 0.0)
                .map(|j| ((positions[j] - positions[me]).norm_squared(), j))
                .filter(|&(d2, _)| d2 < radius * radius)
                .collect();
            want.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            want.truncate(max);
            prop_assert_eq!(&out, &want, "agent {}", me);
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 500, failure_persistence: None, ..ProptestConfig::default() })]

        /// The grid's answer is the brute-force one.
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
            check(&positions, &vec![true; positions.len()], radius, max)?;
        }

        /// Also in clusters far apart, where the crowd's density misleads the first disc (too
        /// wide in a cluster, too narrow between them), with invalid agents.
        #[test]
        fn query_matches_brute_force_in_clusters(
            clusters in prop::collection::vec(
                ((-1e4f64..1e4, -1e4f64..1e4), 0.0f64..100.0, prop::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 1..60)),
                1..4,
            ),
            valid in prop::collection::vec(prop::bool::weighted(0.9), 240),
            log_radius in 0.0f64..4.5,
            max in 0usize..80,
        ) {
            let positions: Vec<V2> = clusters.iter().flat_map(|&((cx, cy), spread, ref pts)| {
                pts.iter().map(move |&(x, y)| V2::new(cx + spread * x, cy + spread * y))
            }).collect();
            check(&positions, &valid[..positions.len()], 10f64.powf(log_radius), max)?;
        }
    }

    #[test]
    fn coincident_agents_and_odd_radii() {
        let positions = vec![V2::new(5.0, -3.0); 40];
        let valid = vec![true; 40];
        for radius in [0.0, -1.0, f64::NAN, 1e-300, 1.0, f64::INFINITY] {
            for max in [0, 1, 10, 39, 100] {
                check(&positions, &valid, radius, max).unwrap();
            }
        }
    }

    #[test]
    fn huge_coordinates() {
        let positions = vec![
            V2::new(1e300, -1e300),
            V2::new(-1e300, 1e300),
            V2::new(f64::MAX, 0.0),
            V2::new(0.0, 0.0),
            V2::new(1.0, 1.0),
            V2::new(1e6, 1e6),
        ];
        let valid = vec![true; positions.len()];
        for radius in [1.0, 10.0, 1e7, f64::INFINITY] {
            for max in [1, 3, 10] {
                check(&positions, &valid, radius, max).unwrap();
            }
        }
    }

    /// More agents within a disc than the buckets take: sorted whole. Fewer, but more than the
    /// room in front of them: sorted after them.
    #[test]
    fn crowded_discs() {
        // A dense 20 x 20 lattice, and one agent far away that makes the crowd look sparse.
        let mut positions: Vec<V2> = (0..400)
            .map(|i| V2::new((i % 20) as f64, (i / 20) as f64))
            .collect();
        positions.push(V2::new(1e5, 1e5));
        let valid = vec![true; positions.len()];
        for max in [1, 5, 254, 255, 256, 300, usize::MAX] {
            check(&positions, &valid, 1e6, max).unwrap();
            check(&positions[..400], &valid[..400], 12.0, max).unwrap();
        }
        // A 20 x 5 block of it: the first disc holds all 100.
        let mut block = positions[..100].to_vec();
        block.push(positions[400]);
        for max in [1, 5, 50, 99, 100, 200] {
            check(&block, &valid[..block.len()], 1e6, max).unwrap();
        }
    }
}
