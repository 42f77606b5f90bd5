//! Optimal assignment: a shortest-augmenting-path (Jonker-Volgenant family) solver for
//! rectangular cost matrices with forbidden pairs, and the partial matching the tracker needs.
//!
//! Forbidden pairs have cost `f64::INFINITY`. The core solver assigns every row of an `n x m`
//! problem with `n <= m`; the partial matcher adds one private "stay unmatched" column per row so
//! that a pair is only used when it beats leaving both sides unmatched.

use crate::TrackError;

/// Reusable buffers for the shortest augmenting path solver, so the tracker's hot path does not
/// allocate per frame.
#[derive(Default, Debug, Clone)]
pub struct LapWorkspace {
    u: Vec<f64>,
    v: Vec<f64>,
    shortest: Vec<f64>,
    path: Vec<usize>,
    col4row: Vec<usize>,
    row4col: Vec<usize>,
    remaining: Vec<usize>,
    visited_rows: Vec<usize>,
    visited_cols: Vec<usize>,
}

const NONE: usize = usize::MAX;

impl LapWorkspace {
    /// Assigns each of `n` rows to a distinct one of `m >= n` columns minimising the total of
    /// `cost(i, j)`; `INFINITY` marks a forbidden pair. Returns the column of each row, or `None`
    /// when no assignment avoids every forbidden pair. Costs must not be NaN or `-INFINITY`.
    pub fn solve<F: Fn(usize, usize) -> f64>(
        &mut self,
        n: usize,
        m: usize,
        cost: F,
    ) -> Option<&[usize]> {
        assert!(n <= m, "solve needs n <= m (got {n} x {m})");
        self.u.clear();
        self.u.resize(n, 0.0);
        self.v.clear();
        self.v.resize(m, 0.0);
        self.col4row.clear();
        self.col4row.resize(n, NONE);
        self.row4col.clear();
        self.row4col.resize(m, NONE);
        self.shortest.resize(m, 0.0);
        self.path.resize(m, NONE);

        for cur_row in 0..n {
            // Dijkstra over the residual graph (reduced costs are non-negative) from `cur_row`
            // until it reaches an unassigned column.
            self.shortest.fill(f64::INFINITY);
            self.remaining.clear();
            self.remaining.extend(0..m);
            self.visited_rows.clear();
            self.visited_cols.clear();
            let mut min_val = 0.0;
            let mut i = cur_row;
            let sink = loop {
                self.visited_rows.push(i);
                let ui = self.u[i];
                let mut lowest = f64::INFINITY;
                let mut best = NONE;
                for (k, &j) in self.remaining.iter().enumerate() {
                    let r = min_val + cost(i, j) - ui - self.v[j];
                    if r < self.shortest[j] {
                        self.path[j] = i;
                        self.shortest[j] = r;
                    }
                    let s = self.shortest[j];
                    // Prefer a free column on ties: it ends the search sooner.
                    if s < lowest || (s == lowest && s < f64::INFINITY && self.row4col[j] == NONE) {
                        lowest = s;
                        best = k;
                    }
                }
                if best == NONE || !lowest.is_finite() {
                    return None;
                }
                min_val = lowest;
                let j = self.remaining.swap_remove(best);
                self.visited_cols.push(j);
                if self.row4col[j] == NONE {
                    break j;
                }
                i = self.row4col[j];
            };

            // Dual update keeps reduced costs non-negative and zero along the matching.
            self.u[cur_row] += min_val;
            for &r in &self.visited_rows[1..] {
                self.u[r] += min_val - self.shortest[self.col4row[r]];
            }
            for &c in &self.visited_cols {
                self.v[c] -= min_val - self.shortest[c];
            }

            // Augment along the path back to `cur_row`.
            let mut j = sink;
            loop {
                let r = self.path[j];
                self.row4col[j] = r;
                let prev = std::mem::replace(&mut self.col4row[r], j);
                if r == cur_row {
                    break;
                }
                j = prev;
            }
        }
        Some(&self.col4row)
    }
}

/// `scipy.optimize.linear_sum_assignment` semantics on a row-major `n x m` matrix: assigns
/// `min(n, m)` pairs of minimum total cost; `INFINITY` entries are forbidden. Returns `(row, col)`
/// pairs sorted by row. Errors on NaN / `-INFINITY` or when every full assignment uses a forbidden
/// pair.
pub fn linear_sum_assignment(
    cost: &[f64],
    n: usize,
    m: usize,
) -> Result<Vec<(usize, usize)>, TrackError> {
    if cost.len() != n * m {
        return Err(TrackError::InvalidInput(format!(
            "cost has {} entries, expected {n} x {m}",
            cost.len()
        )));
    }
    if cost.iter().any(|c| c.is_nan() || *c == f64::NEG_INFINITY) {
        return Err(TrackError::InvalidInput(
            "cost matrix contains NaN or -inf".into(),
        ));
    }
    let mut ws = LapWorkspace::default();
    let infeasible = || TrackError::InvalidInput("cost matrix is infeasible".into());
    if n <= m {
        let cols = ws
            .solve(n, m, |i, j| cost[i * m + j])
            .ok_or_else(infeasible)?;
        Ok(cols.iter().enumerate().map(|(i, &j)| (i, j)).collect())
    } else {
        let rows = ws
            .solve(m, n, |j, i| cost[i * m + j])
            .ok_or_else(infeasible)?;
        let mut pairs: Vec<(usize, usize)> =
            rows.iter().enumerate().map(|(j, &i)| (i, j)).collect();
        pairs.sort_unstable();
        Ok(pairs)
    }
}

/// A candidate pair for partial matching: `row`, `col` and its cost.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edge {
    pub row: usize,
    pub col: usize,
    pub cost: f64,
}

/// Largest component (rows x columns) solved on a dense matrix; a larger one is solved on its
/// edges alone, so memory follows the gated pairs rather than the component's square.
pub const DENSE_COMPONENT_MAX: usize = 1 << 16;

/// Partial matching on a sparse set of allowed pairs: minimises `sum(cost - limit)` over the chosen
/// pairs, so a pair is used only when it beats leaving its row and column unmatched (the
/// `cost_limit` idea of LAPJV). Independent groups of rows/columns (connected components of the
/// allowed pairs) are solved separately, which keeps sparse, gated crowds cheap. A small component
/// is solved on a dense matrix; one of more than [`DENSE_COMPONENT_MAX`] cells by shortest
/// augmenting paths over its edges (a binary heap instead of a scan of every column), whose
/// memory is linear in the edges.
#[derive(Debug, Clone)]
pub struct SparseMatcher {
    dense_max: usize,
    ws: LapWorkspace,
    sparse: SparseWorkspace,
    parent: Vec<usize>,
    order: Vec<usize>,
    rows: Vec<usize>,
    cols: Vec<usize>,
    local_row: Vec<usize>,
    local_col: Vec<usize>,
    dense: Vec<f64>,
}

impl Default for SparseMatcher {
    fn default() -> Self {
        Self::with_dense_limit(DENSE_COMPONENT_MAX)
    }
}

fn find(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

impl SparseMatcher {
    /// A matcher that solves components of at most `cells` rows x columns densely (the default is
    /// [`DENSE_COMPONENT_MAX`]); 0 solves every component on its edges (for tests).
    pub fn with_dense_limit(cells: usize) -> Self {
        Self {
            dense_max: cells,
            ws: LapWorkspace::default(),
            sparse: SparseWorkspace::default(),
            parent: Vec::new(),
            order: Vec::new(),
            rows: Vec::new(),
            cols: Vec::new(),
            local_row: Vec::new(),
            local_col: Vec::new(),
            dense: Vec::new(),
        }
    }

    /// Matches `n_rows` rows and `n_cols` columns using only `edges` (costs finite, at most one
    /// edge per pair) and returns `(row, col)` pairs sorted by row.
    pub fn solve(
        &mut self,
        n_rows: usize,
        n_cols: usize,
        edges: &[Edge],
        limit: f64,
    ) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        if edges.is_empty() {
            return out;
        }
        // Union-find over rows (0..n_rows) and columns (n_rows..).
        self.parent.clear();
        self.parent.extend(0..n_rows + n_cols);
        for e in edges {
            let a = find(&mut self.parent, e.row);
            let b = find(&mut self.parent, n_rows + e.col);
            if a != b {
                self.parent[a.max(b)] = a.min(b);
            }
        }
        // Group edges by component (roots are stable, so the order is deterministic).
        self.order.clear();
        self.order.extend(0..edges.len());
        let parent = &mut self.parent;
        let comp_of: Vec<usize> = edges.iter().map(|e| find(parent, e.row)).collect();
        self.order.sort_by_key(|&k| (comp_of[k], k));

        self.local_row.clear();
        self.local_row.resize(n_rows, NONE);
        self.local_col.clear();
        self.local_col.resize(n_cols, NONE);
        let order = std::mem::take(&mut self.order);
        let mut start = 0;
        while start < order.len() {
            let comp = comp_of[order[start]];
            let mut end = start;
            while end < order.len() && comp_of[order[end]] == comp {
                end += 1;
            }
            let group = &order[start..end];
            if group.len() == 1 {
                let e = edges[group[0]];
                if e.cost <= limit {
                    out.push((e.row, e.col));
                }
            } else {
                self.solve_component(edges, group, limit, &mut out);
            }
            start = end;
        }
        self.order = order;
        out.sort_unstable();
        out
    }

    fn solve_component(
        &mut self,
        edges: &[Edge],
        group: &[usize],
        limit: f64,
        out: &mut Vec<(usize, usize)>,
    ) {
        self.rows.clear();
        self.cols.clear();
        for &k in group {
            let e = edges[k];
            if self.local_row[e.row] == NONE {
                self.local_row[e.row] = self.rows.len();
                self.rows.push(e.row);
            }
            if self.local_col[e.col] == NONE {
                self.local_col[e.col] = self.cols.len();
                self.cols.push(e.col);
            }
        }
        let (nr, nc) = (self.rows.len(), self.cols.len());
        if nr.saturating_mul(nc) > self.dense_max {
            let (local_row, local_col) = (&self.local_row, &self.local_col);
            let assigned = self.sparse.solve(
                nr,
                nc,
                group.iter().map(|&k| {
                    let e = edges[k];
                    (local_row[e.row], local_col[e.col], e.cost)
                }),
                limit,
            );
            for (i, &j) in assigned.iter().enumerate() {
                if j < nc {
                    out.push((self.rows[i], self.cols[j]));
                }
            }
            self.clear_locals();
            return;
        }
        self.dense.clear();
        self.dense.resize(nr * nc, f64::INFINITY);
        for &k in group {
            let e = edges[k];
            self.dense[self.local_row[e.row] * nc + self.local_col[e.col]] = e.cost;
        }
        // Column nc + i is row i's private "unmatched" option at cost `limit`.
        let dense = &self.dense;
        let assigned = self
            .ws
            .solve(nr, nc + nr, |i, j| {
                if j < nc {
                    dense[i * nc + j]
                } else if j - nc == i {
                    limit
                } else {
                    f64::INFINITY
                }
            })
            .expect("every row has its own unmatched column, so the problem is feasible");
        for (i, &j) in assigned.iter().enumerate() {
            if j < nc {
                out.push((self.rows[i], self.cols[j]));
            }
        }
        self.clear_locals();
    }

    fn clear_locals(&mut self) {
        for &r in &self.rows {
            self.local_row[r] = NONE;
        }
        for &c in &self.cols {
            self.local_col[c] = NONE;
        }
    }
}

/// A heap entry: reduced distance, then free columns first (they end the search), then index.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Reached {
    dist: f64,
    taken: bool,
    col: usize,
}

impl Eq for Reached {}

impl Ord for Reached {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        // Reversed: `BinaryHeap` is a max-heap and the search wants the nearest column.
        other
            .dist
            .total_cmp(&self.dist)
            .then(other.taken.cmp(&self.taken))
            .then(other.col.cmp(&self.col))
    }
}

impl PartialOrd for Reached {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

/// Shortest augmenting paths on an edge list: the partial matching of one component, where row
/// `i` may also take its private "unmatched" column `nc + i` at cost `limit`.
#[derive(Default, Debug, Clone)]
struct SparseWorkspace {
    start: Vec<usize>,
    adj: Vec<(usize, f64)>,
    u: Vec<f64>,
    v: Vec<f64>,
    dist: Vec<f64>,
    done: Vec<bool>,
    path: Vec<usize>,
    col4row: Vec<usize>,
    row4col: Vec<usize>,
    touched: Vec<usize>,
    visited_rows: Vec<usize>,
    visited_cols: Vec<usize>,
    heap: std::collections::BinaryHeap<Reached>,
}

impl SparseWorkspace {
    /// Column of each of `nr` rows: `< nc` a real column, `nc + i` unmatched. `edges` are
    /// `(row, col, cost)` in local indices with finite costs.
    fn solve(
        &mut self,
        nr: usize,
        nc: usize,
        edges: impl Iterator<Item = (usize, usize, f64)> + Clone,
        limit: f64,
    ) -> &[usize] {
        // Compressed rows: row i's edges are adj[start[i]..start[i + 1]].
        self.start.clear();
        self.start.resize(nr + 1, 0);
        for (r, _, _) in edges.clone() {
            self.start[r + 1] += 1;
        }
        for i in 0..nr {
            self.start[i + 1] += self.start[i];
        }
        self.adj.clear();
        self.adj.resize(self.start[nr], (0, 0.0));
        let mut fill = self.start[..nr].to_vec();
        for (r, c, cost) in edges {
            self.adj[fill[r]] = (c, cost);
            fill[r] += 1;
        }
        let m = nc + nr;
        self.u.clear();
        self.u.resize(nr, 0.0);
        self.v.clear();
        self.v.resize(m, 0.0);
        self.col4row.clear();
        self.col4row.resize(nr, NONE);
        self.row4col.clear();
        self.row4col.resize(m, NONE);
        self.dist.clear();
        self.dist.resize(m, f64::INFINITY);
        self.done.clear();
        self.done.resize(m, false);
        self.path.clear();
        self.path.resize(m, NONE);

        for cur_row in 0..nr {
            // Dijkstra over the residual graph from `cur_row`; row `cur_row`'s private column is
            // free, so the search always ends.
            self.touched.clear();
            self.visited_rows.clear();
            self.visited_cols.clear();
            self.heap.clear();
            let mut min_val = 0.0;
            let mut i = cur_row;
            let sink = loop {
                self.visited_rows.push(i);
                let ui = self.u[i];
                let private = (nc + i, limit);
                for &(j, c) in self.adj[self.start[i]..self.start[i + 1]]
                    .iter()
                    .chain(std::iter::once(&private))
                {
                    if self.done[j] {
                        continue;
                    }
                    let r = min_val + c - ui - self.v[j];
                    if r < self.dist[j] {
                        if self.dist[j] == f64::INFINITY {
                            self.touched.push(j);
                        }
                        self.dist[j] = r;
                        self.path[j] = i;
                        self.heap.push(Reached {
                            dist: r,
                            taken: self.row4col[j] != NONE,
                            col: j,
                        });
                    }
                }
                let j = loop {
                    let top = self
                        .heap
                        .pop()
                        .expect("the private column of the row searched from is reachable");
                    if !self.done[top.col] && top.dist == self.dist[top.col] {
                        break top.col;
                    }
                };
                min_val = self.dist[j];
                self.done[j] = true;
                self.visited_cols.push(j);
                if self.row4col[j] == NONE {
                    break j;
                }
                i = self.row4col[j];
            };

            // Dual update keeps reduced costs non-negative and zero along the matching.
            self.u[cur_row] += min_val;
            for &r in &self.visited_rows[1..] {
                self.u[r] += min_val - self.dist[self.col4row[r]];
            }
            for &c in &self.visited_cols {
                self.v[c] -= min_val - self.dist[c];
            }

            // Augment along the path back to `cur_row`.
            let mut j = sink;
            loop {
                let r = self.path[j];
                self.row4col[j] = r;
                let prev = std::mem::replace(&mut self.col4row[r], j);
                if r == cur_row {
                    break;
                }
                j = prev;
            }
            for &j in &self.touched {
                self.dist[j] = f64::INFINITY;
                self.done[j] = false;
            }
        }
        &self.col4row
    }
}
