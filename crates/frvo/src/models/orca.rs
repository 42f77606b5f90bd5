//! Reciprocal velocity obstacles for a crowd: FRVO (oriented ellipses) and, with circles, the
//! classic RVO/ORCA baseline. Both share the polygon velocity obstacles, the grid and the LP.

use crate::agent::Agent;
use crate::geometry::{heading, is_finite, Ellipse, Polygon, MIN_SIZE, V2};
use crate::lp::{self, Line};
use crate::minkowski::minkowski_sum;
use crate::model::{MotionKind, MotionModel, MotionParams};
use crate::neighbors::NeighborGrid;
use crate::velocity_obstacle::{avoidance, avoidance_circle, reciprocal_line};

/// How a pedestrian's footprint is built from its axes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Footprint {
    /// Ellipse `l` along the heading x `w` across (FRVO).
    Ellipse,
    /// Circle of diameter `max(l, w)`, as circular RVO models a pedestrian (exact disc
    /// velocity obstacles, no polygon).
    Circle,
}

/// ORCA-style crowd stepper over convex polygon footprints.
#[derive(Clone, Debug)]
pub struct Orca {
    params: MotionParams,
    footprint: Footprint,
    grid: NeighborGrid,
    positions: Vec<V2>,
    valid: Vec<bool>,
    shapes: Vec<Polygon>,
    radii: Vec<f64>,
    neighbors: Vec<(f64, usize)>,
    lines: Vec<Line>,
    scratch: Vec<Line>,
}

impl Orca {
    pub fn new(params: MotionParams, footprint: Footprint) -> Self {
        Self {
            params: params.sanitized(),
            footprint,
            grid: NeighborGrid::default(),
            positions: Vec::new(),
            valid: Vec::new(),
            shapes: Vec::new(),
            radii: Vec::new(),
            neighbors: Vec::new(),
            lines: Vec::new(),
            scratch: Vec::new(),
        }
    }

    pub fn params(&self) -> &MotionParams {
        &self.params
    }

    fn polygon_of(&self, a: &Agent) -> Polygon {
        Ellipse::new(a.l, a.w, heading(a.vel, a.pref_vel)).polygon(self.params.polygon_sides)
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
        self.shapes.clear();
        self.radii.clear();
        match self.footprint {
            Footprint::Ellipse => {
                for a in agents {
                    let s = self.polygon_of(a);
                    self.shapes.push(s);
                }
            }
            Footprint::Circle => self.radii.extend(
                agents
                    .iter()
                    .map(|a| 0.5 * finite_max(a.l, a.w).max(MIN_SIZE)),
            ),
        }
        self.grid
            .build(&self.positions, &self.valid, p.neighbor_radius);

        let mut out = Vec::with_capacity(agents.len());
        for (i, a) in agents.iter().enumerate() {
            let pref = finite_pref(a);
            if !self.valid[i] {
                out.push(pref);
                continue;
            }
            self.grid
                .query(&self.positions, i, p.max_neighbors, &mut self.neighbors);
            let minus_me = match self.footprint {
                Footprint::Ellipse => self.shapes[i].negated(),
                Footprint::Circle => Polygon::default(),
            };
            self.lines.clear();
            for &(_, j) in &self.neighbors {
                let b = &agents[j];
                let (mut rel_pos, rel_vel) = (b.pos - a.pos, a.vel - b.vel);
                if rel_pos.norm_squared() < 1e-18 {
                    // Coincident: a tiny offset by index order, so the two push apart instead
                    // of computing the same velocity.
                    rel_pos = V2::new(if i < j { 1e-6 } else { -1e-6 }, 0.0);
                }
                let avoid = match self.footprint {
                    Footprint::Ellipse => {
                        let sum = minkowski_sum(&self.shapes[j], &minus_me);
                        avoidance(rel_pos, &sum, rel_vel, p.time_horizon, dt)
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
            let sol = lp::solve(&self.lines, p.max_speed, pref, &mut self.scratch);
            out.push(if is_finite(sol.velocity) {
                sol.velocity
            } else {
                pref
            });
        }
        out
    }
}
