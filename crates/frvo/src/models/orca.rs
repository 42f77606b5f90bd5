//! Reciprocal velocity obstacles for a crowd: FRVO (oriented ellipses) and, with circles, the
//! classic RVO/ORCA baseline. Both share the polygon velocity obstacles, the grid and the LP.
//!
//! A step runs in four phases over contiguous blocks of agents, each block on one thread
//! when the crowd is large enough (see [`MotionParams::threads`]):
//! 1. each agent's polygon and ellipse (FRVO) and its neighbours (the grid is read-only);
//! 2. (FRVO) the pairs each agent owns: of a pair that both agents list, the earlier agent
//!    computes the avoidance (or the cull bound) once, for both. Only near pairs (among the
//!    [`NEAR_SLOTS`] nearest neighbours of either agent) are computed here;
//! 3. (FRVO) each agent's LP over its near neighbours' half-planes, then its far owned pairs,
//!    culled by a weaker test that this LP's solution allows: a far half-plane that cannot
//!    move the solution needs no computing (see [`Near`]);
//! 4. each agent's LP: the near one, when no far half-plane can move it, else the LP over all
//!    its half-planes (its own pairs, the negated reverse ones).
//!
//! Every agent's result depends only on the phases before, never on which thread ran what, so
//! any number of threads gives the same velocities bit for bit.

use std::ops::Range;
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use crate::agent::Agent;
use crate::cull::{self, Body, Bound, Limits, Motion, Pair};
use crate::geometry::{heading, is_finite, Ellipse, UnitPolygon, MIN_SIZE, V2};
use crate::lp::{self, Line};
use crate::model::{MotionKind, MotionModel, MotionParams};
use crate::neighbors::NeighborGrid;
use crate::pair::{pair_avoidance, PairScratch, Shapes};
use crate::team::Team;
use crate::velocity_obstacle::{avoidance_circle, reciprocal_line, Avoidance};

/// Below this many neighbour slots (agents x neighbours) a step stays on one thread: handing
/// out a phase costs about a microsecond, and a crowd needs blocks for both threads (measured
/// break-even on the 2-core benchmark machine: about 20-30 agents with 10 neighbours).
const PARALLEL_MIN_SLOTS: usize = 300;
/// Blocks per thread, so that a thread that finishes early can take another block.
const BLOCKS_PER_THREAD: usize = 4;
/// Fewest agents in a block.
const MIN_BLOCK_AGENTS: usize = 8;
/// No slot: past the end of every slot array.
const NONE: u32 = u32::MAX;
/// Each agent's nearest neighbours whose half-planes are solved first (FRVO, phase 3). In
/// dense crowds, where most LPs are infeasible, their min-max level lets most farther pairs be
/// culled without computing them.
const NEAR_SLOTS: usize = 8;

/// How a pedestrian's footprint is built from its axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Footprint {
    /// Ellipse `l` along the heading x `w` across (FRVO).
    Ellipse,
    /// Circle of diameter `max(l, w)`, as circular RVO models a pedestrian (exact disc
    /// velocity obstacles, no polygon).
    Circle,
}

/// What the owner of a pair left in its neighbour slot (FRVO).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// The pair's avoidance.
    Exact,
    /// The cull test's bound: the owner's half-plane contains the speed disc. The other agent
    /// decides for itself from the bound.
    Culled,
    /// The cull test's bound, for the weaker test: the owner's half-plane is violated by no
    /// more than the owner's slack anywhere in the disc (see [`Near`]).
    CulledWithSlack,
    /// A far pair: what its owner computed is in the step's `far` array (phase 3).
    Far,
}

/// What the owner of a pair leaves in its neighbour slot (FRVO): the pair's avoidance or the
/// cull test's bound, both in one shape.
#[derive(Clone, Copy, Debug)]
struct Slot {
    /// The avoidance's `u`, or the bound's `(gap, tol)`.
    a: V2,
    /// The avoidance's normal, or the bound's.
    normal: V2,
    kind: Kind,
}

impl Slot {
    fn exact(avoid: Avoidance) -> Self {
        Self {
            a: avoid.u,
            normal: avoid.normal,
            kind: Kind::Exact,
        }
    }

    fn culled(bound: Bound, kind: Kind) -> Self {
        let (gap, tol, normal) = bound.parts();
        Self {
            a: V2::new(gap, tol),
            normal,
            kind,
        }
    }

    fn far() -> Self {
        Self {
            a: V2::zeros(),
            normal: V2::zeros(),
            kind: Kind::Far,
        }
    }

    /// The avoidance for the owner (`own`), or for the other agent: the owner's negated (see
    /// `pair_avoidance`). By a sign, not a branch: which slots an agent owns follows no
    /// pattern a predictor could learn (and negating is exact either way).
    #[inline]
    fn avoidance_for(&self, own: bool) -> Avoidance {
        let sign = if own { 1.0 } else { -1.0 };
        Avoidance {
            u: self.a * sign,
            normal: self.normal * sign,
        }
    }

    /// The bound of a culled slot.
    fn bound(&self) -> Bound {
        Bound::from_parts(self.a.x, self.a.y, self.normal)
    }

    /// The bound of a culled slot, for the other agent of the pair.
    fn reversed_bound(&self) -> Bound {
        self.bound().reversed()
    }
}

fn negated(avoid: Avoidance) -> Avoidance {
    Avoidance {
        u: -avoid.u,
        normal: -avoid.normal,
    }
}

/// An agent's LP over its near neighbours' half-planes (the first [`NEAR_SLOTS`] of its
/// list), phase 3.
///
/// The full LP adds the far neighbours' lines after the near ones, and its incremental pass
/// skips every later line violated at the current optimum by no more than the current level:
/// 0 while feasible, the min-max level once infeasible (`lp::Solution::violation`). So if no
/// far line is violated by more at the near optimum, the full solution is the near one, bit
/// for bit.
/// Many far lines cannot be, which the cull test proves cheaply with a slack `s`
/// ([`cull::Limits::with_slack`]: the line's violation anywhere in the speed disc `|v| <= S`
/// is at most `s`): `s` = the level when infeasible, `S - |v_near|` when feasible (the line
/// then holds the disc of radius `|v_near|`, so `v_near`). Such far pairs need no computing.
/// Should a far line be violated by more, the agent solves the full LP, with every line the
/// plain computation keeps.
#[derive(Clone, Copy, Debug)]
struct Near {
    sol: lp::Solution,
    /// The far lines' allowed violation in the disc, as above (never negative).
    slack: f64,
    /// Whether the near neighbours are all the neighbours: the near LP is the full one.
    complete: bool,
}

impl Near {
    fn new(sol: lp::Solution, max_speed: f64, complete: bool) -> Self {
        let slack = if sol.feasible {
            max_speed - sol.velocity.norm()
        } else {
            sol.violation
        };
        Self {
            sol,
            // Not NaN (`max` drops it): no slack then.
            slack: slack.max(0.0),
            complete,
        }
    }

    /// Limits for the agent's far pairs (with no slack, the plain ones bit for bit).
    fn limits(&self, limits: &Limits) -> Limits {
        limits.with_slack(self.slack)
    }

    /// What a far pair culled with [`Near::limits`] is.
    fn cull_kind(&self) -> Kind {
        if self.slack > 0.0 {
            Kind::CulledWithSlack
        } else {
            Kind::Culled
        }
    }
}

/// Where a step's phases run: on the caller alone, or on a team of helper threads with it.
#[derive(Clone, Debug)]
struct Threads {
    /// Threads a parallel step uses, the caller's included.
    count: usize,
    /// Every core: the process's one team, shared by all such models (as a global pool
    /// would be), so that a model made per call does not start threads per call.
    every_core: bool,
    /// Taken at the first parallel step; clones of the model share it. A team busy with
    /// another caller's phase leaves this caller to run its phase alone (see [`Team::run`]).
    team: Option<Arc<Team>>,
}

impl Threads {
    /// `threads` as in [`MotionParams::threads`]: 0 is every core.
    fn new(threads: usize) -> Self {
        let count = match threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        };
        Self {
            count,
            every_core: threads == 0,
            team: None,
        }
    }

    fn count(&self) -> usize {
        self.count
    }

    /// Takes the team if this is the first parallel step; returns whether the step can
    /// spread over it (not in a forked child, which has none of its helpers).
    fn prepare(&mut self, parallel: bool) -> bool {
        static EVERY_CORE: OnceLock<Arc<Team>> = OnceLock::new();
        if parallel && self.team.is_none() {
            let count = self.count;
            self.team = Some(if self.every_core {
                Arc::clone(EVERY_CORE.get_or_init(|| Arc::new(Team::new(count))))
            } else {
                Arc::new(Team::new(count))
            });
        }
        parallel && self.team.as_ref().is_some_and(|team| team.has_helpers())
    }

    /// Calls `work` on every item: spread over the team when `parallel` (after
    /// [`Threads::prepare`]), each item taken by whichever thread claims its index.
    fn for_each<T: Send>(&self, parallel: bool, items: Vec<T>, work: impl Fn(T) + Sync) {
        match &self.team {
            Some(team) if parallel => {
                let items: Vec<Mutex<Option<T>>> =
                    items.into_iter().map(|x| Mutex::new(Some(x))).collect();
                team.run(items.len(), &|k| {
                    // Each index is claimed once, so the lock is never contended.
                    let item = items[k]
                        .lock()
                        .unwrap_or_else(PoisonError::into_inner)
                        .take();
                    if let Some(item) = item {
                        work(item);
                    }
                });
            }
            _ => items.into_iter().for_each(work),
        }
    }
}

/// One block's agents and its thread's scratch, reused across steps.
#[derive(Clone, Debug, Default)]
struct Block {
    agents: Range<usize>,
    /// Phase 1: the block's neighbour lists, concatenated; where each agent's ends.
    list: Vec<u32>,
    ends: Vec<u32>,
    found: Vec<(f64, usize)>,
    pair: PairScratch,
    /// Phase 2: the agent's slots sorted into earlier and later neighbours, then its owned
    /// ones (see `View::own_pairs`); the far owned ones of all the block's agents, and where
    /// each agent's end.
    owned: Vec<u32>,
    pending: Vec<u32>,
    pending_ends: Vec<u32>,
    /// Phase 3: each agent's near LP.
    near: Vec<Near>,
    /// Phases 3 and 4: the agent's half-planes.
    lines: Vec<Line>,
    /// Phase 4: the block's agents with far neighbours that kept the near solution, and that
    /// solved the full LP.
    near_kept: usize,
    full_solved: usize,
    lp: Vec<Line>,
    /// Phase 1 (FRVO): the block's prepared polygons and ellipses, appended to the step's.
    shapes: Shapes,
    negated_shapes: Shapes,
    bodies: Vec<Body>,
    polygon: Vec<V2>,
}

impl Block {
    /// Builds each agent's polygon (no trigonometry: the unit polygon is cached) and prepares
    /// it (and for odd sides its negation) for the pair computations, and its ellipse for the
    /// cull test.
    fn prepare_shapes(&mut self, agents: &[Agent], unit: &UnitPolygon, limits: &Limits) {
        let symmetric = unit.is_symmetric();
        self.shapes.reset(unit.sides(), symmetric);
        self.negated_shapes.reset(unit.sides(), false);
        self.bodies.clear();
        for (k, a) in agents.iter().enumerate() {
            let e = Ellipse::new(a.l, a.w, heading(a.vel, a.pref_vel));
            self.bodies.push(Body::new(&e, limits));
            self.polygon.clear();
            e.for_each_vertex(unit, |q| self.polygon.push(q));
            self.shapes.push(&self.polygon);
            if !symmetric {
                self.negated_shapes.push_negated(&self.shapes, k);
            }
        }
    }
}

/// ORCA-style crowd stepper over convex polygon footprints.
#[derive(Clone, Debug)]
pub struct Orca {
    params: MotionParams,
    footprint: Footprint,
    threads: Threads,
    unit: UnitPolygon,
    grid: NeighborGrid,
    positions: Vec<V2>,
    valid: Vec<bool>,
    /// Each agent's polygon (and, for odd sides, its negation), prepared for the pairs.
    shapes: Shapes,
    negated_shapes: Shapes,
    radii: Vec<f64>,
    /// Each agent's ellipse for the cull test (FRVO).
    bodies: Vec<Body>,
    limits: Limits,
    /// Neighbours of agent `i`, nearest first: `nbr[nbr_start[i]..nbr_start[i + 1]]`.
    nbr_start: Vec<u32>,
    nbr: Vec<u32>,
    /// Per neighbour slot (FRVO): the slot of the same pair in an earlier agent's list, which
    /// owns it, else `NONE`; and, for owned slots, what the owner computed.
    partner: Vec<u32>,
    avoid: Vec<Slot>,
    /// Per owned far slot (FRVO, `Kind::Far` in `avoid`): what its owner computed.
    far: Vec<Slot>,
    feasible: Vec<bool>,
    blocks: Vec<Block>,
    parallel: bool,
    /// [`NEAR_SLOTS`], but for tests.
    near_slots: usize,
}

impl Orca {
    pub fn new(params: MotionParams, footprint: Footprint) -> Self {
        let params = params.sanitized();
        Self {
            params,
            footprint,
            threads: Threads::new(params.threads),
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
            partner: Vec::new(),
            avoid: Vec::new(),
            far: Vec::new(),
            feasible: Vec::new(),
            blocks: Vec::new(),
            parallel: false,
            near_slots: NEAR_SLOTS,
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

    /// Whether the last [`MotionModel::step`] was spread over more than one thread.
    pub fn last_parallel(&self) -> bool {
        self.parallel
    }

    /// Splits the agents into blocks: one, or a few per thread when `parallel`.
    fn make_blocks(&mut self, n: usize, parallel: bool) {
        let count = if parallel {
            (self.threads.count() * BLOCKS_PER_THREAD)
                .min(n / MIN_BLOCK_AGENTS)
                .max(1)
        } else {
            1
        };
        self.blocks.resize_with(count, Block::default);
        for (b, block) in self.blocks.iter_mut().enumerate() {
            block.agents = b * n / count..(b + 1) * n / count;
        }
    }

    /// Phase 1: every valid agent's neighbour list, gathered into `nbr`, and (FRVO) its
    /// prepared polygon and ellipse.
    fn gather(&mut self, agents: &[Agent], parallel: bool) {
        let (grid, positions, valid) = (&self.grid, &self.positions, &self.valid);
        let (max, unit, limits) = (self.params.max_neighbors, &self.unit, &self.limits);
        let ellipse = self.footprint == Footprint::Ellipse;
        let plan = grid.plan(max);
        let blocks: Vec<&mut Block> = self.blocks.iter_mut().collect();
        self.threads.for_each(parallel, blocks, |block| {
            if ellipse {
                block.prepare_shapes(&agents[block.agents.clone()], unit, limits);
            }
            block.list.clear();
            block.ends.clear();
            for i in block.agents.clone() {
                if valid[i] {
                    let found = grid.nearest(positions, i, &plan, &mut block.found);
                    block.list.extend(found.iter().map(|&(_, j)| j as u32));
                }
                block.ends.push(block.list.len() as u32);
            }
        });
        self.nbr_start.clear();
        self.nbr.clear();
        self.nbr_start.push(0);
        let (sides, symmetric) = (self.unit.sides(), self.unit.is_symmetric());
        self.shapes.reset(sides, symmetric);
        self.negated_shapes.reset(sides, false);
        self.bodies.clear();
        if let [block] = &mut self.blocks[..] {
            // One block: take its buffers over (it clears them before it writes again).
            self.nbr_start.extend_from_slice(&block.ends);
            std::mem::swap(&mut self.nbr, &mut block.list);
            if ellipse {
                std::mem::swap(&mut self.shapes, &mut block.shapes);
                std::mem::swap(&mut self.negated_shapes, &mut block.negated_shapes);
                std::mem::swap(&mut self.bodies, &mut block.bodies);
            }
            return;
        }
        for block in &self.blocks {
            let base = self.nbr.len() as u32;
            self.nbr_start.extend(block.ends.iter().map(|&e| base + e));
            self.nbr.extend_from_slice(&block.list);
            if ellipse {
                self.shapes.append(&block.shapes);
                self.negated_shapes.append(&block.negated_shapes);
                self.bodies.extend_from_slice(&block.bodies);
            }
        }
    }

    /// Phase 2 (FRVO): every slot's partner, and the pairs each agent owns.
    fn own_pairs(&mut self, agents: &[Agent], dt: f64, parallel: bool) {
        let slots = self.nbr.len();
        let mut partner = std::mem::take(&mut self.partner);
        partner.resize(slots, NONE);
        let mut avoid = std::mem::take(&mut self.avoid);
        if avoid.len() < slots {
            // Never read before written: a slot is read only when owned, after its owner wrote it.
            avoid.resize(slots, Slot::far());
        }
        let mut blocks = std::mem::take(&mut self.blocks);
        let view = self.view(agents, dt, &[], &[], &[]);
        // Each block's slots: its agents' lists are contiguous.
        let ranges: Vec<Range<usize>> = blocks.iter().map(|b| view.slots_of(&b.agents)).collect();
        let lens = || ranges.iter().map(|r| r.len());
        let work: Vec<_> = blocks
            .iter_mut()
            .zip(split_mut(&mut partner, lens()))
            .zip(split_mut(&mut avoid[..slots], lens()))
            .zip(ranges.iter().map(|r| r.start))
            .collect();
        self.threads
            .for_each(parallel, work, |(((block, partner), avoid), base)| {
                block.pending.clear();
                block.pending_ends.clear();
                for i in block.agents.clone() {
                    view.own_pairs(i, block, partner, avoid, base);
                }
            });
        (self.partner, self.avoid, self.blocks) = (partner, avoid, blocks);
    }

    /// Phase 3 (FRVO): every agent's near LP, then its far owned pairs.
    fn solve_near(&mut self, agents: &[Agent], dt: f64, parallel: bool) {
        let slots = self.nbr.len();
        let mut far = std::mem::take(&mut self.far);
        if far.len() < slots {
            // Never read before written: a far slot is read only after its owner wrote it.
            far.resize(slots, Slot::far());
        }
        let mut blocks = std::mem::take(&mut self.blocks);
        let view = self.view(agents, dt, &self.partner, &self.avoid, &[]);
        let ranges: Vec<Range<usize>> = blocks.iter().map(|b| view.slots_of(&b.agents)).collect();
        let work: Vec<_> = blocks
            .iter_mut()
            .zip(split_mut(&mut far[..slots], ranges.iter().map(|r| r.len())))
            .zip(ranges.iter().map(|r| r.start))
            .collect();
        self.threads
            .for_each(parallel, work, |((block, far), base)| {
                block.near.clear();
                for (k, i) in block.agents.clone().enumerate() {
                    view.solve_near(i, k, block, far, base);
                }
            });
        (self.far, self.blocks) = (far, blocks);
    }

    /// Phase 4: every agent's LP.
    fn solve_all(&mut self, agents: &[Agent], dt: f64, parallel: bool) -> Vec<V2> {
        let n = agents.len();
        let mut out = vec![V2::zeros(); n];
        let mut feasible = std::mem::take(&mut self.feasible);
        feasible.clear();
        feasible.resize(n, false);
        let mut blocks = std::mem::take(&mut self.blocks);
        let view = self.view(agents, dt, &self.partner, &self.avoid, &self.far);
        let lens: Vec<usize> = blocks.iter().map(|b| b.agents.len()).collect();
        let work: Vec<_> = blocks
            .iter_mut()
            .zip(split_mut(&mut out, lens.iter().copied()))
            .zip(split_mut(&mut feasible, lens.iter().copied()))
            .collect();
        self.threads.for_each(parallel, work, |((block, vel), ok)| {
            (block.near_kept, block.full_solved) = (0, 0);
            let first = block.agents.start;
            for i in block.agents.clone() {
                (vel[i - first], ok[i - first]) = view.solve(i, block);
            }
        });
        (self.feasible, self.blocks) = (feasible, blocks);
        out
    }

    fn view<'a>(
        &'a self,
        agents: &'a [Agent],
        dt: f64,
        partner: &'a [u32],
        avoid: &'a [Slot],
        far: &'a [Slot],
    ) -> View<'a> {
        View {
            agents,
            dt,
            params: &self.params,
            footprint: self.footprint,
            symmetric: self.unit.is_symmetric(),
            valid: &self.valid,
            nbr_start: &self.nbr_start,
            nbr: &self.nbr,
            partner,
            avoid,
            far,
            shapes: &self.shapes,
            negated_shapes: &self.negated_shapes,
            bodies: &self.bodies,
            radii: &self.radii,
            limits: &self.limits,
            near_slots: self.near_slots,
        }
    }
}

/// What the phases read: the step's input and the earlier phases' results (`partner` and
/// `avoid` are phase 2's, empty during it; `far` is phase 3's, empty until phase 4).
#[derive(Clone, Copy)]
struct View<'a> {
    agents: &'a [Agent],
    dt: f64,
    params: &'a MotionParams,
    footprint: Footprint,
    symmetric: bool,
    valid: &'a [bool],
    nbr_start: &'a [u32],
    nbr: &'a [u32],
    partner: &'a [u32],
    avoid: &'a [Slot],
    far: &'a [Slot],
    shapes: &'a Shapes,
    negated_shapes: &'a Shapes,
    bodies: &'a [Body],
    radii: &'a [f64],
    limits: &'a Limits,
    near_slots: usize,
}

impl View<'_> {
    #[inline]
    fn slots(&self, i: usize) -> Range<usize> {
        // One bounds check for both ends.
        match self.nbr_start[i..i + 2] {
            [start, end] => start as usize..end as usize,
            _ => unreachable!(),
        }
    }

    /// The slots of a range of agents.
    fn slots_of(&self, agents: &Range<usize>) -> Range<usize> {
        self.nbr_start[agents.start] as usize..self.nbr_start[agents.end] as usize
    }

    /// `p = pos_j - pos_i` and `w = v_i - v_j`.
    #[inline]
    fn relative(&self, i: usize, j: usize) -> (V2, V2) {
        let (a, b) = (&self.agents[i], &self.agents[j]);
        let p = b.pos - a.pos;
        // Coincident: a tiny offset by index order, so the two push apart instead of computing
        // the same velocity.
        let p = if p.norm_squared() < 1e-18 {
            V2::new(if i < j { 1e-6 } else { -1e-6 }, 0.0)
        } else {
            p
        };
        (p, a.vel - b.vel)
    }

    fn pair(&self, i: usize, j: usize, p: V2, w: V2) -> Pair<'_> {
        Pair {
            p,
            w,
            a: &self.bodies[i],
            b: &self.bodies[j],
        }
    }

    /// Agent `i`'s exact avoidance of `j` from their polygons.
    #[inline]
    fn exact(&self, i: usize, j: usize, p: V2, w: V2, scratch: &mut PairScratch) -> Avoidance {
        let b = self.shapes.get(j);
        let neg_a = if self.symmetric {
            self.shapes.get(i) // each polygon is its own reflection
        } else {
            self.negated_shapes.get(i)
        };
        pair_avoidance(p, w, b, neg_a, self.params.time_horizon, self.dt, scratch)
    }

    /// Agent `i`'s exact avoidance of `j` for a pair `j` owns: as the owner computes it,
    /// negated (one side per pair, so the same bits whoever needs it).
    fn reversed_exact(
        &self,
        i: usize,
        j: usize,
        p: V2,
        w: V2,
        scratch: &mut PairScratch,
    ) -> Avoidance {
        negated(self.exact(j, i, -p, -w, scratch))
    }

    /// Phase 2 for agent `i`: the partner of each of its slots and, for the near pairs it
    /// owns, the cull bound or the exact avoidance (`partner` and `avoid` are its block's, from
    /// slot `base`). Its far owned pairs are left for phase 3, in `block.pending`.
    fn own_pairs(
        &self,
        i: usize,
        block: &mut Block,
        partner: &mut [u32],
        avoid: &mut [Slot],
        base: usize,
    ) {
        // Each slot's partner: where an earlier neighbour `j` lists `i` (a later one's list is
        // not searched: `i` owns the pair). Which neighbours are earlier follows no pattern a
        // predictor could learn, so the slots are first sorted without a branch, the earlier
        // neighbours' to the front half of `order` and the others' to the back half (each in
        // slot order), and only then are the earlier ones' lists (all about as long) searched.
        let slots = self.slots(i);
        let len = slots.len();
        block.owned.resize(2 * len, 0);
        let order = &mut block.owned[..2 * len];
        let mut earlier = 0;
        for (k, &j) in self.nbr[slots.clone()].iter().enumerate() {
            let front = (j as usize) < i;
            // The back holds the other `k - earlier` so far.
            let at = if front { earlier } else { len + k - earlier };
            order[at] = (slots.start + k) as u32;
            earlier += usize::from(front);
        }
        // The front's owned slots are moved to the end of the front half, next to the back's,
        // from the last one down, so that none overwrites a slot not yet read: the owned slots
        // end up in `order[first..2 * len - earlier]`.
        let mut first = len;
        for k in (0..earlier).rev() {
            let s = order[k] as usize;
            let list = self.slots(self.nbr[s] as usize);
            let at = position(&self.nbr[list.clone()], i as u32);
            partner[s - base] = if at == NONE {
                NONE
            } else {
                list.start as u32 + at
            };
            order[first - 1] = s as u32;
            first -= usize::from(at == NONE);
        }
        // The owned pairs' order does not matter: each slot gets its own pair's result (the
        // back's partners, all `NONE`, are written here too).
        let motion = Motion::new(self.agents[i].vel);
        for &s in &block.owned[first..2 * len - earlier] {
            let s = s as usize;
            partner[s - base] = NONE;
            let j = self.nbr[s] as usize;
            if !self.is_near(i, j, s - slots.start) {
                avoid[s - base] = Slot::far();
                block.pending.push(s as u32);
                continue;
            }
            avoid[s - base] =
                self.owned_pair(i, j, motion, self.limits, Kind::Culled, &mut block.pair);
        }
        block.pending_ends.push(block.pending.len() as u32);
    }

    /// Whether agent `i`'s slot `rank` (of neighbour `j`) holds a near pair: among the
    /// [`NEAR_SLOTS`] nearest neighbours of `i`, or of `j` if `j` lists `i` there (a `j`
    /// before `i` that lists `i` owns the pair, so only a later one is looked up).
    fn is_near(&self, i: usize, j: usize, rank: usize) -> bool {
        if rank < self.near_slots {
            return true;
        }
        let list = self.slots(j);
        let first = list.start..list.start.saturating_add(self.near_slots).min(list.end);
        j > i && position(&self.nbr[first], i as u32) != NONE
    }

    /// What agent `i`, owning its pair with `j`, leaves in the slot: the bound if `limits`'
    /// cull test culls it (as `kind`; with a slack, first by distances alone), else the exact
    /// avoidance.
    fn owned_pair(
        &self,
        i: usize,
        j: usize,
        motion: Motion,
        limits: &Limits,
        kind: Kind,
        scratch: &mut PairScratch,
    ) -> Slot {
        let (p, w) = self.relative(i, j);
        let pair = self.pair(i, j, p, w);
        let bound = if kind == Kind::CulledWithSlack {
            cull::cull_far(&pair, motion, limits)
        } else {
            cull::cull(&pair, motion, limits)
        };
        match bound {
            Some(bound) => Slot::culled(bound, kind),
            None => Slot::exact(self.exact(i, j, p, w, scratch)),
        }
    }

    /// Phase 3 for agent `i` (the block's `k`-th): the LP over its near lines, then its far
    /// owned pairs, culled against its near level (`far` is its block's, from slot `base`).
    fn solve_near(&self, i: usize, k: usize, block: &mut Block, far: &mut [Slot], base: usize) {
        let slots = self.slots(i);
        let near_end = slots.start.saturating_add(self.near_slots).min(slots.end);
        block.lines.clear();
        self.polygon_lines(i, slots.start..near_end, block);
        let pref = finite_pref(&self.agents[i]);
        let sol = lp::solve(&block.lines, self.params.max_speed, pref, &mut block.lp);
        let near = Near::new(sol, self.params.max_speed, near_end == slots.end);
        block.near.push(near);
        let first = if k == 0 { 0 } else { block.pending_ends[k - 1] };
        let pending = first as usize..block.pending_ends[k] as usize;
        let (motion, limits, kind) = (
            Motion::new(self.agents[i].vel),
            near.limits(self.limits),
            near.cull_kind(),
        );
        for q in pending {
            let s = block.pending[q] as usize;
            let j = self.nbr[s] as usize;
            far[s - base] = self.owned_pair(i, j, motion, &limits, kind, &mut block.pair);
        }
    }

    /// Phase 4 for agent `i`: its new velocity, and whether its LP was feasible.
    fn solve(&self, i: usize, block: &mut Block) -> (V2, bool) {
        let a = &self.agents[i];
        let pref = finite_pref(a);
        if !self.valid[i] {
            return (pref, false);
        }
        let sol = match self.footprint {
            Footprint::Ellipse => self.solve_ellipses(i, block, pref),
            Footprint::Circle => {
                block.lines.clear();
                for s in self.slots(i) {
                    let j = self.nbr[s] as usize;
                    let (p, w) = self.relative(i, j);
                    let r = self.radii[i] + self.radii[j];
                    let avoid = avoidance_circle(p, r, w, self.params.time_horizon, self.dt);
                    if let Some(line) = usable(reciprocal_line(a.vel, avoid)) {
                        block.lines.push(line);
                    }
                }
                lp::solve(&block.lines, self.params.max_speed, pref, &mut block.lp)
            }
        };
        let ok = is_finite(sol.velocity);
        (if ok { sol.velocity } else { pref }, ok && sol.feasible)
    }

    /// Agent `i`'s LP (FRVO): the near one when it is the full one or when no far line
    /// binds; else the LP over all its lines.
    fn solve_ellipses(&self, i: usize, block: &mut Block, pref: V2) -> lp::Solution {
        let near = block.near[i - block.agents.start];
        if near.complete {
            return near.sol;
        }
        let slots = self.slots(i);
        let far = slots.start + self.near_slots..slots.end;
        if !self.far_binds(i, far.clone(), &near, block) {
            block.near_kept += 1;
            return near.sol;
        }
        // Rare: the near lines are made again (the same, bit for bit) rather than kept for
        // every agent.
        block.full_solved += 1;
        block.lines.clear();
        self.polygon_lines(i, slots.start..far.start, block);
        self.polygon_lines(i, far, block);
        lp::solve(&block.lines, self.params.max_speed, pref, &mut block.lp)
    }

    /// Whether slot `s` is its agent's own, and what the pair's owner left for it.
    #[inline]
    fn owner_slot(&self, s: usize) -> (bool, Slot) {
        let t = self.partner[s];
        let own = t == NONE;
        (own, self.slot(if own { s } else { t as usize }))
    }

    /// What the owner of slot `t` left for it.
    #[inline]
    fn slot(&self, t: usize) -> Slot {
        let slot = self.avoid[t];
        if slot.kind == Kind::Far {
            self.far[t]
        } else {
            slot
        }
    }

    /// Agent `i`'s half-planes (FRVO) from the given slots, appended to `block.lines` in slot
    /// order: its own pairs', the negation of its partners', none where its half-plane
    /// provably contains the speed disc. These are the lines of the plain computation (one
    /// exact avoidance per pair, cull tests against the speed disc only): the owner's cull
    /// test is made again for a pair culled with a slack.
    fn polygon_lines(&self, i: usize, slots: Range<usize>, block: &mut Block) {
        let vel = self.agents[i].vel;
        let motion = Motion::new(vel);
        for s in slots {
            let (own, slot) = self.owner_slot(s);
            let avoid = match (own, slot.kind) {
                (_, Kind::Exact) => slot.avoidance_for(own),
                (true, Kind::Culled) => continue, // never binds: the LP is the same without it
                (true, _) => {
                    let j = self.nbr[s] as usize;
                    let (p, w) = self.relative(i, j);
                    if cull::cull(&self.pair(i, j, p, w), motion, self.limits).is_some() {
                        continue;
                    }
                    self.exact(i, j, p, w, &mut block.pair)
                }
                // The owner skipped it: whether `i` may too depends on its own velocity.
                (false, kind) => {
                    let j = self.nbr[s] as usize;
                    let (p, w) = self.relative(i, j);
                    // Culled with the owner's slack: the plain test's bound, if it culls.
                    let bound = if kind == Kind::Culled {
                        Some(slot.bound())
                    } else {
                        let motion = Motion::new(self.agents[j].vel);
                        cull::cull(&self.pair(j, i, -p, -w), motion, self.limits)
                    };
                    let pair = self.pair(i, j, p, w);
                    if bound.is_some_and(|bound| {
                        cull::contains_disc(&pair, &bound.reversed(), motion, self.limits)
                    }) {
                        continue;
                    }
                    self.reversed_exact(i, j, p, w, &mut block.pair)
                }
            };
            if let Some(line) = usable(reciprocal_line(vel, avoid)) {
                block.lines.push(line);
            }
        }
    }

    /// Whether a far line of agent `i` (from the given slots) is violated by more than the
    /// near level at the near optimum, so that the full LP may differ from the near one. Far
    /// pairs culled with the near slack are skipped uncomputed (see [`Near`]).
    fn far_binds(&self, i: usize, slots: Range<usize>, near: &Near, block: &mut Block) -> bool {
        let vel = self.agents[i].vel;
        let motion = Motion::new(vel);
        let limits = near.limits(self.limits);
        for s in slots {
            let (own, slot) = self.owner_slot(s);
            let avoid = match (own, slot.kind) {
                (_, Kind::Exact) => slot.avoidance_for(own),
                // Culled against the disc, or with `i`'s own slack.
                (true, _) => continue,
                (false, _) => {
                    let j = self.nbr[s] as usize;
                    let (p, w) = self.relative(i, j);
                    let pair = self.pair(i, j, p, w);
                    let bound = slot.reversed_bound();
                    // A bound from distances alone may fail where `i`'s own test would not.
                    if cull::contains_disc(&pair, &bound, motion, &limits)
                        || (bound.is_from_distances()
                            && cull::cull(&pair, motion, &limits).is_some())
                    {
                        continue;
                    }
                    self.reversed_exact(i, j, p, w, &mut block.pair)
                }
            };
            if let Some(line) = usable(reciprocal_line(vel, avoid)) {
                if line.violation(near.sol.velocity) > near.sol.violation {
                    return true;
                }
            }
        }
        false
    }
}

/// `slice` cut into consecutive pieces of the given lengths (one per block), so that each
/// block's thread gets its own.
fn split_mut<T>(mut slice: &mut [T], lens: impl Iterator<Item = usize>) -> Vec<&mut [T]> {
    lens.map(|len| {
        let (piece, rest) = std::mem::take(&mut slice).split_at_mut(len);
        slice = rest;
        piece
    })
    .collect()
}

/// Where `x` is in `list` (listed at most once), else `NONE`. Without branches, so that the
/// compiler can vectorise it: the matching position plus one is summed, zero where none matches.
#[inline]
fn position(list: &[u32], x: u32) -> u32 {
    let found: u32 = list
        .iter()
        .zip(1u32..)
        .map(|(&y, k)| if y == x { k } else { 0 })
        .sum();
    found.wrapping_sub(1)
}

/// The half-plane if usable: finite, with a unit direction (a degenerate avoidance has a zero
/// normal).
#[inline]
fn usable(line: Line) -> Option<Line> {
    (is_finite(line.point) && line.dir.norm_squared() > 0.5).then_some(line)
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
        let n = agents.len();
        let parallel = self.threads.count() > 1
            && n * self.params.max_neighbors.min(n.saturating_sub(1)) >= PARALLEL_MIN_SLOTS;
        let parallel = self.threads.prepare(parallel);
        self.parallel = parallel;
        self.step_on(agents, sane_dt(dt), parallel)
    }
}

impl Orca {
    /// The step's phases, on the current thread pool when `parallel`.
    fn step_on(&mut self, agents: &[Agent], dt: f64, parallel: bool) -> Vec<V2> {
        let n = agents.len();
        let p = self.params;
        self.positions.clear();
        self.positions.extend(agents.iter().map(|a| a.pos));
        self.valid.clear();
        self.valid.extend(agents.iter().map(is_valid));
        self.radii.clear();
        if self.footprint == Footprint::Circle {
            self.radii.extend(
                agents
                    .iter()
                    .map(|a| 0.5 * finite_max(a.l, a.w).max(MIN_SIZE)),
            );
        }
        self.grid
            .build(&self.positions, &self.valid, p.neighbor_radius);
        self.make_blocks(n, parallel);
        self.gather(agents, parallel);
        if self.footprint == Footprint::Ellipse {
            self.own_pairs(agents, dt, parallel);
            self.solve_near(agents, dt, parallel);
        }
        self.solve_all(agents, dt, parallel)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` agents on a jittered square grid `gap` px apart (about 20 x 40 px ellipses),
    /// walking in four directions at `speed`, each turned a little by a deterministic `seed`.
    fn grid_crowd(n: usize, gap: f64, speed: f64, seed: u64) -> Vec<Agent> {
        let side = (n as f64).sqrt().ceil() as usize;
        let mut state = seed;
        let mut unit = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        (0..n)
            .map(|i| {
                let (r, c) = ((i / side) as f64, (i % side) as f64);
                let pos = V2::new(gap * c + 8.0 * unit(), gap * r + 8.0 * unit());
                let angle = (i % 4) as f64 * std::f64::consts::FRAC_PI_2 + 0.6 * unit();
                let dir = V2::new(angle.cos(), angle.sin());
                let vel = dir * speed + V2::new(unit(), unit());
                Agent::new(
                    pos,
                    vel,
                    dir * speed,
                    20.0 + 10.0 * unit(),
                    40.0 + 10.0 * unit(),
                )
            })
            .collect()
    }

    /// Steps both models over `steps` frames of the crowd (moving it by the plain model's
    /// velocities) and compares velocities and feasibility flags bit for bit. Returns the
    /// agents that kept their near solution and that solved the full LP (over both).
    fn compare(mut agents: Vec<Agent>, params: MotionParams, steps: usize) -> (usize, usize) {
        let mut fast = Orca::new(params, Footprint::Ellipse);
        let mut plain = Orca::new(params, Footprint::Ellipse);
        plain.near_slots = usize::MAX; // every agent's LP over all its lines at once
        let (mut kept, mut full) = (0, 0);
        for step in 0..steps {
            let (v, w) = (fast.step(&agents, 1.0), plain.step(&agents, 1.0));
            for (i, (a, b)) in v.iter().zip(&w).enumerate() {
                let bits = |x: &V2| [x.x.to_bits(), x.y.to_bits()];
                assert_eq!(bits(a), bits(b), "step {step}, agent {i}: {a:?} vs {b:?}");
            }
            assert_eq!(fast.last_feasible(), plain.last_feasible(), "step {step}");
            kept += fast.blocks.iter().map(|b| b.near_kept).sum::<usize>();
            full += fast.blocks.iter().map(|b| b.full_solved).sum::<usize>();
            for (a, v) in agents.iter_mut().zip(w) {
                a.vel = v;
                a.pos += v;
            }
        }
        (kept, full)
    }

    fn params(k: usize, tau: f64, threads: usize) -> MotionParams {
        MotionParams {
            max_speed: 4.0,
            neighbor_radius: 150.0,
            max_neighbors: k,
            time_horizon: tau,
            threads,
            ..MotionParams::default()
        }
    }

    /// A model reused across crowds of changing size (stepped in one block and in several,
    /// whose buffers it takes over or copies) gives what a fresh model gives, bit for bit.
    #[test]
    fn reused_model_gives_what_a_fresh_one_gives() {
        for footprint in [Footprint::Ellipse, Footprint::Circle] {
            let params = params(20, 10.0, 3);
            let mut reused = Orca::new(params, footprint);
            let sizes = [1.0, 2.0, 0.5, 1.5, 1.0, 1.0, 0.7, 2.0];
            for (k, (n, size)) in [300, 20, 300, 5, 0, 1, 300, 40]
                .into_iter()
                .zip(sizes)
                .enumerate()
            {
                // Sizes change too: stale polygons would give other velocities.
                let mut crowd = grid_crowd(n, 30.0, 2.0, k as u64);
                for a in &mut crowd {
                    (a.l, a.w) = (size * a.l, size * a.w);
                }
                let v = reused.step(&crowd, 1.0);
                let w = Orca::new(params, footprint).step(&crowd, 1.0);
                let bits = |v: &[V2]| -> Vec<[u64; 2]> {
                    v.iter().map(|x| [x.x.to_bits(), x.y.to_bits()]).collect()
                };
                assert_eq!(bits(&v), bits(&w), "{footprint:?}, crowd {k} of {n}");
                let slots = n * params.max_neighbors.min(n.saturating_sub(1));
                assert_eq!(
                    reused.last_parallel(),
                    slots >= PARALLEL_MIN_SLOTS,
                    "{footprint:?}, {n} agents"
                );
            }
        }
    }

    /// Solving the near neighbours first, and skipping the far pairs that cannot change the
    /// result, gives the velocities of the plain computation bit for bit: in a packed crowd
    /// (almost every LP infeasible), looser ones (mostly feasible), a fast one with a long
    /// horizon (where far lines bind more often), on one thread and on three.
    #[test]
    fn near_first_gives_the_plain_velocities_bit_for_bit() {
        let (mut kept, mut full) = (0, 0);
        for (gap, speed, tau, k, seed) in [
            (25.0, 2.0, 5.0, 40, 1),
            (32.0, 2.0, 10.0, 30, 2),
            (45.0, 2.0, 10.0, 50, 3),
            (60.0, 2.0, 20.0, 20, 4),
            (60.0, 3.8, 30.0, 40, 5),
        ] {
            for threads in [1, 3] {
                let crowd = grid_crowd(300, gap, speed, seed);
                let (a, b) = compare(crowd, params(k, tau, threads), 40);
                kept += a;
                full += b;
            }
        }
        // Both ways out were taken, the near solution kept far more often.
        assert!(full > 50, "the full LP was solved for {full} agent-steps");
        assert!(
            kept > 10 * full,
            "near solution kept {kept}, full LP {full}"
        );
    }
}
