//! Reciprocal velocity obstacles for a crowd: FRVO (oriented ellipses) and, with circles, the
//! classic RVO/ORCA baseline. One step, for every pedestrian `p_i` on its own (as RVO2's
//! `Agent::computeNewVelocity`):
//! 1. its neighbourhood `H_i`: the `max_neighbors` nearest pedestrians within `rho`;
//! 2. for each neighbour `p_j`, the velocity obstacle `VO^tau_{p_i|p_j}` of their polygonised
//!    ellipses (a Minkowski sum, [`crate::velocity_obstacle::avoidance`]) and the half-plane
//!    of velocities that takes half of the avoidance ([`crate::velocity_obstacle::reciprocal_line`]);
//! 3. `v_new = argmin |v - v_pref|` over the intersection of those half-planes and the speed
//!    disc, i.e. `v_new` outside `FRVO^tau_{p_i}` (the 2-D LP, [`crate::lp::solve`]).
//!
//! Pedestrians are independent within a step, so a large crowd is split over threads (rayon)
//! with the same velocities, bit for bit, as on one thread.

use std::sync::{Arc, OnceLock};

use rayon::prelude::*;

use crate::agent::Agent;
use crate::geometry::{heading, is_finite, Ellipse, Polygon, MIN_SIZE, V2};
use crate::lp::{self, Line};
use crate::minkowski::minkowski_sum;
use crate::model::{MotionKind, MotionModel, MotionParams};
use crate::neighbors::NeighborGrid;
use crate::velocity_obstacle::{avoidance, avoidance_circle, reciprocal_line};

/// Below this many agent-neighbour pairs (agents x `max_neighbors`) a step stays on the calling
/// thread: measured with `examples/thread_cost.rs` (README, Speed), smaller crowds were slower
/// on every core than on one thread.
pub const PARALLEL_MIN_PAIRS: usize = 10_000;

/// How a pedestrian's footprint is built from its axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Footprint {
    /// Ellipse `l` along the heading x `w` across, as a polygon (FRVO).
    Ellipse,
    /// Circle of diameter `max(l, w)`, as circular RVO models a pedestrian (exact disc
    /// velocity obstacles, no polygon).
    Circle,
}

/// A pedestrian's footprint for one step, centred at the origin.
#[derive(Clone, Copy, Debug)]
#[allow(clippy::large_enum_variant)] // one per agent and step; boxing would allocate for each
enum Shape {
    /// The ellipse's polygon `A` and its reflection `-A`.
    Polygon {
        own: Polygon,
        negated: Polygon,
    },
    Circle {
        radius: f64,
    },
}

impl Shape {
    fn new(a: &Agent, footprint: Footprint, sides: usize) -> Self {
        match footprint {
            Footprint::Ellipse => {
                let own = Ellipse::new(a.l, a.w, heading(a.vel, a.pref_vel)).polygon(sides);
                Shape::Polygon {
                    own,
                    negated: own.negated(),
                }
            }
            Footprint::Circle => Shape::Circle {
                radius: 0.5 * finite_max(a.l, a.w).max(MIN_SIZE),
            },
        }
    }
}

/// ORCA-style crowd stepper over elliptical (polygon) or circular footprints.
#[derive(Clone, Debug)]
pub struct Orca {
    params: MotionParams,
    footprint: Footprint,
    grid: NeighborGrid,
    /// The pool of a model with `threads` > 1, made at its first parallel step and shared by
    /// its clones (`threads` = 0 uses the process's pool, see [`every_core_pool`]).
    own_pool: OnceLock<Arc<Pool>>,
    feasible: Vec<bool>,
    parallel: bool,
    parallel_min_pairs: usize,
}

impl Orca {
    pub fn new(params: MotionParams, footprint: Footprint) -> Self {
        Self {
            params: params.sanitized(),
            footprint,
            grid: NeighborGrid::default(),
            own_pool: OnceLock::new(),
            feasible: Vec::new(),
            parallel: false,
            parallel_min_pairs: PARALLEL_MIN_PAIRS,
        }
    }

    /// The model with another threshold than [`PARALLEL_MIN_PAIRS`] (to measure it).
    pub fn with_parallel_min_pairs(mut self, pairs: usize) -> Self {
        self.parallel_min_pairs = pairs;
        self
    }

    pub fn params(&self) -> &MotionParams {
        &self.params
    }

    /// Per agent of the last [`MotionModel::step`]: whether its half-planes and the speed disc
    /// had a common point (its velocity then satisfies every neighbour's constraint). False
    /// when the LP fell back to the least-violation velocity, or the agent was skipped
    /// (non-finite position or velocity).
    pub fn last_feasible(&self) -> &[bool] {
        &self.feasible
    }

    /// Whether the last [`MotionModel::step`] was spread over more than one thread.
    pub fn last_parallel(&self) -> bool {
        self.parallel
    }

    /// The pool to spread a step of `n` agents over, or `None` to stay on the calling thread.
    fn pool(&self, n: usize) -> Option<Arc<Pool>> {
        let pairs = n * self.params.max_neighbors.min(n.saturating_sub(1));
        if self.params.threads == 1 || pairs < self.parallel_min_pairs {
            return None;
        }
        Some(match self.params.threads {
            0 => every_core_pool(),
            threads => Arc::clone(self.own_pool.get_or_init(|| Arc::new(Pool::new(threads)))),
        })
    }
}

impl MotionModel for Orca {
    fn kind(&self) -> MotionKind {
        match self.footprint {
            Footprint::Ellipse => MotionKind::Frvo,
            Footprint::Circle => MotionKind::Rvo,
        }
    }

    fn step(&mut self, agents: &[Agent], dt: f64) -> Vec<V2> {
        let positions: Vec<V2> = agents.iter().map(|a| a.pos).collect();
        let valid: Vec<bool> = agents.iter().map(is_valid).collect();
        self.grid
            .build(&positions, &valid, self.params.neighbor_radius);
        let sides = self.params.polygon_sides;
        let crowd = Crowd {
            agents,
            positions: &positions,
            valid: &valid,
            shapes: agents
                .iter()
                .map(|a| Shape::new(a, self.footprint, sides))
                .collect(),
            grid: &self.grid,
            params: &self.params,
            dt: sane_dt(dt),
        };
        let pool = self.pool(agents.len());
        let threads = pool.as_deref().and_then(Pool::threads);
        self.parallel = threads.is_some();
        let results: Vec<(V2, bool)> = match threads {
            Some(threads) => threads.install(|| {
                (0..agents.len())
                    .into_par_iter()
                    .map_init(Scratch::default, |s, i| crowd.new_velocity(i, s))
                    .collect()
            }),
            None => {
                let mut s = Scratch::default();
                (0..agents.len())
                    .map(|i| crowd.new_velocity(i, &mut s))
                    .collect()
            }
        };
        self.feasible = results.iter().map(|&(_, ok)| ok).collect();
        results.into_iter().map(|(v, _)| v).collect()
    }
}

/// One step's input, read by every agent's computation.
struct Crowd<'a> {
    agents: &'a [Agent],
    positions: &'a [V2],
    valid: &'a [bool],
    shapes: Vec<Shape>,
    grid: &'a NeighborGrid,
    params: &'a MotionParams,
    dt: f64,
}

/// Buffers an agent's computation reuses (one per thread).
#[derive(Default)]
struct Scratch {
    neighbors: Vec<(f64, usize)>,
    lines: Vec<Line>,
    lp: Vec<Line>,
}

impl Crowd<'_> {
    /// Agent `i`'s new velocity, and whether its LP was feasible.
    fn new_velocity(&self, i: usize, s: &mut Scratch) -> (V2, bool) {
        let a = &self.agents[i];
        let pref = finite_pref(a);
        if !self.valid[i] {
            return (pref, false);
        }
        let p = self.params;
        // 1. The neighbourhood H_i.
        self.grid
            .query(self.positions, i, p.max_neighbors, &mut s.neighbors);
        // 2. One half-plane per neighbour.
        s.lines.clear();
        for &(_, j) in &s.neighbors {
            let b = &self.agents[j];
            let mut rel_pos = b.pos - a.pos;
            if rel_pos.norm_squared() < 1e-18 {
                // Coincident: a tiny offset by index order, so that the two push apart.
                rel_pos = V2::new(if i < j { 1e-6 } else { -1e-6 }, 0.0);
            }
            let rel_vel = a.vel - b.vel;
            let avoid = match (&self.shapes[i], &self.shapes[j]) {
                (Shape::Polygon { negated, .. }, Shape::Polygon { own, .. }) => {
                    // B ⊕ (-A): where B's centre is when the two touch, relative to A's.
                    let sum = minkowski_sum(own, negated);
                    avoidance(rel_pos, &sum, rel_vel, p.time_horizon, self.dt)
                }
                (Shape::Circle { radius: ra }, Shape::Circle { radius: rb }) => {
                    avoidance_circle(rel_pos, ra + rb, rel_vel, p.time_horizon, self.dt)
                }
                _ => unreachable!("one footprint per step"),
            };
            let line = reciprocal_line(a.vel, avoid);
            // A degenerate avoidance (zero normal) or non-finite input gives no usable line.
            if is_finite(line.point) && line.dir.norm_squared() > 0.5 {
                s.lines.push(line);
            }
        }
        // 3. The velocity closest to the preferred one that all half-planes allow.
        let sol = lp::solve(&s.lines, p.max_speed, pref, &mut s.lp);
        let ok = is_finite(sol.velocity);
        (if ok { sol.velocity } else { pref }, ok && sol.feasible)
    }
}

/// A rayon pool and the process that made it: a forked child has none of its threads, so a
/// step there stays on the calling thread, as it does where the system refused the threads.
#[derive(Debug)]
struct Pool {
    pool: Option<rayon::ThreadPool>,
    pid: u32,
}

impl Pool {
    fn new(threads: usize) -> Self {
        let builder = rayon::ThreadPoolBuilder::new().num_threads(threads);
        Self {
            pool: builder.build().ok(),
            pid: std::process::id(),
        }
    }

    /// The pool, if a step can spread over it here.
    fn threads(&self) -> Option<&rayon::ThreadPool> {
        let here = self.pid == std::process::id();
        self.pool
            .as_ref()
            .filter(|pool| here && pool.current_num_threads() > 1)
    }
}

/// The process's pool for `threads` = 0: one thread per core, made at the first such step.
fn every_core_pool() -> Arc<Pool> {
    static POOL: OnceLock<Arc<Pool>> = OnceLock::new();
    let cores = || std::thread::available_parallelism().map_or(1, |n| n.get());
    Arc::clone(POOL.get_or_init(|| Arc::new(Pool::new(cores()))))
}

/// Larger of two sizes, ignoring a non-finite one.
fn finite_max(a: f64, b: f64) -> f64 {
    match (a.is_finite(), b.is_finite()) {
        (true, true) => a.max(b),
        (true, false) => a,
        (false, true) => b,
        (false, false) => 0.0,
    }
}

/// An agent takes part only with a finite position and velocity.
pub(crate) fn is_valid(a: &Agent) -> bool {
    is_finite(a.pos) && is_finite(a.vel)
}

/// Preferred velocity, or zero when it is not finite.
pub(crate) fn finite_pref(a: &Agent) -> V2 {
    if is_finite(a.pref_vel) {
        a.pref_vel
    } else {
        V2::zeros()
    }
}

/// `dt` when positive and finite, else one frame.
pub(crate) fn sane_dt(dt: f64) -> f64 {
    if dt.is_finite() && dt > 0.0 {
        dt
    } else {
        1.0
    }
}
