//! Reciprocal velocity obstacles for a crowd: FRVO (oriented ellipses) and, with circles, the
//! classic RVO/ORCA baseline. Both share the polygon velocity obstacles, the grid and the LP.

use crate::agent::Agent;
use crate::cull::{self, Body, Bound, Limits, Motion, Pair};
use crate::geometry::{heading, is_finite, Ellipse, UnitPolygon, MIN_SIZE, V2};
use crate::lp::{self, Line};
use crate::model::{MotionKind, MotionModel, MotionParams};
use crate::neighbors::NeighborGrid;
use crate::pair::{pair_avoidance, PairScratch, Shapes};
use crate::velocity_obstacle::{avoidance_circle, reciprocal_line, Avoidance};

/// How a pedestrian's footprint is built from its axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Footprint {
    /// Ellipse `l` along the heading x `w` across (FRVO).
    Ellipse,
    /// Circle of diameter `max(l, w)`, as circular RVO models a pedestrian (exact disc
    /// velocity obstacles, no polygon).
    Circle,
}

/// What an agent leaves in a neighbour slot for the reverse pair (FRVO).
#[derive(Clone, Copy, Debug)]
enum Slot {
    /// The pair's avoidance.
    Exact(Avoidance),
    /// The half-plane provably contains the speed disc and was skipped: the cull test's
    /// bound, from which the other agent decides for itself.
    Culled(Bound),
}

/// ORCA-style crowd stepper over convex polygon footprints.
#[derive(Clone, Debug)]
pub struct Orca {
    params: MotionParams,
    footprint: Footprint,
    unit: UnitPolygon,
    grid: NeighborGrid,
    positions: Vec<V2>,
    valid: Vec<bool>,
    /// Each agent's polygon and its negation, prepared for the pair computations.
    shapes: Shapes,
    negated_shapes: Shapes,
    radii: Vec<f64>,
    /// Neighbours of agent `i`, nearest first: `nbr[nbr_start[i]..nbr_start[i + 1]]`.
    nbr_start: Vec<u32>,
    nbr: Vec<u32>,
    /// Each agent's ellipse for the cull test (FRVO).
    bodies: Vec<Body>,
    limits: Limits,
    /// Per neighbour slot (FRVO): what the reverse pair needs.
    avoid: Vec<Slot>,
    /// The neighbour lists transposed to earlier agents: agent `i`'s entries
    /// `rev[rev_start[i]..rev_start[i + 1]]` are `(j, t)` with `j < i` and `nbr[t] == i`, so the
    /// reverse pair is found without searching `j`'s list.
    rev_start: Vec<u32>,
    rev: Vec<(u32, u32)>,
    /// While agent `i` is processed: `slot_in[j]` is the slot of `i` in `j`'s list (from `rev`),
    /// else `u32::MAX`.
    slot_in: Vec<u32>,
    feasible: Vec<bool>,
    // Per-agent scratch, reused across agents and steps.
    polygon: Vec<V2>,
    pair_scratch: PairScratch,
    neighbors: Vec<(f64, usize)>,
    lines: Vec<Line>,
    scratch: Vec<Line>,
}

impl Orca {
    pub fn new(params: MotionParams, footprint: Footprint) -> Self {
        let params = params.sanitized();
        Self {
            params,
            footprint,
            unit: UnitPolygon::new(params.polygon_sides),
            grid: NeighborGrid::default(),
            positions: Vec::new(),
            valid: Vec::new(),
            shapes: Shapes::default(),
            negated_shapes: Shapes::default(),
            radii: Vec::new(),
            bodies: Vec::new(),
            limits: Limits::new(params.time_horizon, params.max_speed, params.polygon_sides),
            nbr_start: Vec::new(),
            nbr: Vec::new(),
            avoid: Vec::new(),
            rev_start: Vec::new(),
            rev: Vec::new(),
            slot_in: Vec::new(),
            feasible: Vec::new(),
            polygon: Vec::new(),
            pair_scratch: PairScratch::default(),
            neighbors: Vec::new(),
            lines: Vec::new(),
            scratch: Vec::new(),
        }
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

    /// Every valid agent's neighbour list (nearest first, at most `max_neighbors`).
    fn find_neighbors(&mut self) {
        self.nbr_start.clear();
        self.nbr.clear();
        self.nbr_start.push(0);
        for i in 0..self.positions.len() {
            if self.valid[i] {
                self.grid.query(
                    &self.positions,
                    i,
                    self.params.max_neighbors,
                    &mut self.neighbors,
                );
                self.nbr
                    .extend(self.neighbors.iter().map(|&(_, j)| j as u32));
            }
            self.nbr_start.push(self.nbr.len() as u32);
        }
    }

    /// Transposes the neighbour lists onto later agents (see `rev`): O(pairs), where searching
    /// `j`'s list for every pair cost O(pairs x neighbours).
    fn transpose_neighbors(&mut self) {
        let n = self.positions.len();
        self.rev_start.clear();
        self.rev_start.resize(n + 1, 0);
        // Whether a listed neighbour comes later is data-dependent: counted and written
        // without branches (an earlier one is written to a spare last entry, then dropped).
        for j in 0..n {
            for &i in &self.nbr[self.nbr_start[j] as usize..self.nbr_start[j + 1] as usize] {
                self.rev_start[i as usize + 1] += u32::from((j as u32) < i);
            }
        }
        for i in 0..n {
            self.rev_start[i + 1] += self.rev_start[i];
        }
        let total = self.rev_start[n] as usize;
        self.rev.clear();
        self.rev.resize(total + 1, (0, 0));
        let mut fill = self.rev_start[..n].to_vec();
        for j in 0..n {
            for t in self.nbr_start[j]..self.nbr_start[j + 1] {
                let i = self.nbr[t as usize] as usize;
                let later = j < i;
                let at = if later { fill[i] as usize } else { total };
                self.rev[at] = (j as u32, t);
                fill[i] += u32::from(later);
            }
        }
        self.rev.truncate(total);
        self.slot_in.clear();
        self.slot_in.resize(n, u32::MAX);
    }

    /// Marks (or, with `u32::MAX`, clears) the slots of `i` in earlier agents' lists.
    fn mark_incoming(&mut self, i: usize, clear: bool) {
        for &(j, t) in &self.rev[self.rev_start[i] as usize..self.rev_start[i + 1] as usize] {
            self.slot_in[j as usize] = if clear { u32::MAX } else { t };
        }
    }

    /// Builds every agent's polygon once per step (no trigonometry: the unit polygon is cached)
    /// and prepares it and its negation for the pair computations, and its ellipse for the
    /// cull test.
    fn prepare_shapes(&mut self, agents: &[Agent]) {
        let sides = self.unit.sides();
        let symmetric = self.unit.is_symmetric();
        self.shapes.reset(sides, symmetric);
        self.negated_shapes.reset(sides, false);
        self.bodies.clear();
        for (k, a) in agents.iter().enumerate() {
            let e = Ellipse::new(a.l, a.w, heading(a.vel, a.pref_vel));
            self.bodies.push(Body::new(&e, &self.limits));
            self.polygon.clear();
            e.for_each_vertex(&self.unit, |q| self.polygon.push(q));
            self.shapes.push(&self.polygon);
            if !symmetric {
                self.negated_shapes.push_negated(&self.shapes, k);
            }
        }
    }

    /// Agent `i`'s avoidance of neighbour `j` from their polygons, or `None` when its
    /// half-plane provably contains the speed disc (see [`crate::cull`]). Records in `avoid`
    /// what the reverse pair needs.
    fn polygon_avoidance(
        &mut self,
        i: usize,
        j: usize,
        a: Motion,
        p: V2,
        w: V2,
        dt: f64,
    ) -> Option<Avoidance> {
        // What agent j left for the pair, if it is done and lists i (else `slot_in[j]` is
        // u32::MAX, past the end).
        let reverse = self.avoid.get(self.slot_in[j] as usize);
        let slot = if let Some(Slot::Exact(r)) = reverse {
            // The negation of the reverse pair's (see `pair_avoidance`).
            Slot::Exact(Avoidance {
                u: -r.u,
                normal: -r.normal,
            })
        } else {
            let pair = Pair {
                p,
                w,
                a: &self.bodies[i],
                b: &self.bodies[j],
            };
            let culled = match reverse {
                // Agent j skipped it: whether i may too depends on i's own velocity.
                Some(Slot::Culled(bound)) => {
                    let bound = bound.reversed();
                    cull::contains_disc(&pair, &bound, a, &self.limits).then_some(bound)
                }
                _ => cull::cull(&pair, a, &self.limits),
            };
            match culled {
                Some(bound) => Slot::Culled(bound),
                None => {
                    let b = self.shapes.get(j);
                    let neg_a = if self.unit.is_symmetric() {
                        self.shapes.get(i) // each polygon is its own reflection
                    } else {
                        self.negated_shapes.get(i)
                    };
                    let tau = self.params.time_horizon;
                    let scratch = &mut self.pair_scratch;
                    Slot::Exact(pair_avoidance(p, w, b, neg_a, tau, dt, scratch))
                }
            }
        };
        self.avoid.push(slot);
        match slot {
            Slot::Exact(avoid) => Some(avoid),
            Slot::Culled(_) => None,
        }
    }
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

impl MotionModel for Orca {
    fn kind(&self) -> MotionKind {
        match self.footprint {
            Footprint::Ellipse => MotionKind::Frvo,
            Footprint::Circle => MotionKind::Rvo,
        }
    }

    fn step(&mut self, agents: &[Agent], dt: f64) -> Vec<V2> {
        let dt = sane_dt(dt);
        let p = self.params;
        self.positions.clear();
        self.positions.extend(agents.iter().map(|a| a.pos));
        self.valid.clear();
        self.valid.extend(agents.iter().map(is_valid));
        self.radii.clear();
        match self.footprint {
            Footprint::Ellipse => self.prepare_shapes(agents),
            Footprint::Circle => self.radii.extend(
                agents
                    .iter()
                    .map(|a| 0.5 * finite_max(a.l, a.w).max(MIN_SIZE)),
            ),
        }
        self.grid
            .build(&self.positions, &self.valid, p.neighbor_radius);
        self.find_neighbors();
        if self.footprint == Footprint::Ellipse {
            self.transpose_neighbors();
        }
        self.feasible.clear();
        self.avoid.clear();

        let mut out = Vec::with_capacity(agents.len());
        for (i, a) in agents.iter().enumerate() {
            let pref = finite_pref(a);
            let motion = Motion::new(a.vel);
            let slots = self.nbr_start[i] as usize..self.nbr_start[i + 1] as usize;
            if !self.valid[i] {
                out.push(pref);
                self.feasible.push(false);
                continue;
            }
            self.lines.clear();
            let ellipse = self.footprint == Footprint::Ellipse;
            if ellipse {
                self.mark_incoming(i, false);
            }
            for slot in slots {
                let j = self.nbr[slot] as usize;
                let b = &agents[j];
                let (mut rel_pos, rel_vel) = (b.pos - a.pos, a.vel - b.vel);
                if rel_pos.norm_squared() < 1e-18 {
                    // Coincident: a tiny offset by index order, so the two push apart instead
                    // of computing the same velocity.
                    rel_pos = V2::new(if i < j { 1e-6 } else { -1e-6 }, 0.0);
                }
                let avoid = match self.footprint {
                    Footprint::Ellipse => {
                        match self.polygon_avoidance(i, j, motion, rel_pos, rel_vel, dt) {
                            Some(avoid) => avoid,
                            None => continue, // never binds: the LP is the same without it
                        }
                    }
                    Footprint::Circle => {
                        let r = self.radii[i] + self.radii[j];
                        avoidance_circle(rel_pos, r, rel_vel, p.time_horizon, dt)
                    }
                };
                let line = reciprocal_line(a.vel, avoid);
                if is_finite(line.point) && line.dir.norm_squared() > 0.5 {
                    self.lines.push(line);
                }
            }
            if ellipse {
                self.mark_incoming(i, true);
            }
            let sol = lp::solve(&self.lines, p.max_speed, pref, &mut self.scratch);
            let ok = is_finite(sol.velocity);
            out.push(if ok { sol.velocity } else { pref });
            self.feasible.push(ok && sol.feasible);
        }
        out
    }
}
