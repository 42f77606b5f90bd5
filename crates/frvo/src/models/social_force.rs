//! Helbing-Molnar social forces baseline: each pedestrian relaxes toward its preferred velocity
//! and is pushed away from its neighbours by an exponentially decaying repulsion.

use crate::agent::Agent;
use crate::geometry::{is_finite, V2};
use crate::model::{MotionKind, MotionModel, MotionParams};
use crate::models::orca::{finite_pref, is_valid, sane_dt};
use crate::neighbors::NeighborGrid;

#[derive(Clone, Debug)]
pub struct SocialForce {
    params: MotionParams,
    grid: NeighborGrid,
    positions: Vec<V2>,
    valid: Vec<bool>,
    neighbors: Vec<(f64, usize)>,
}

impl SocialForce {
    pub fn new(params: MotionParams) -> Self {
        Self {
            params: params.sanitized(),
            grid: NeighborGrid::default(),
            positions: Vec::new(),
            valid: Vec::new(),
            neighbors: Vec::new(),
        }
    }
}

/// Radius of the circle a pedestrian occupies: half its larger axis (0 if unknown).
fn radius(a: &Agent) -> f64 {
    let r = 0.5 * a.l.max(a.w);
    if r.is_finite() && r > 0.0 {
        r
    } else {
        0.0
    }
}

impl MotionModel for SocialForce {
    fn kind(&self) -> MotionKind {
        MotionKind::SocialForce
    }

    fn step(&mut self, agents: &[Agent], dt: f64) -> Vec<V2> {
        let dt = sane_dt(dt);
        let p = self.params;
        self.positions.clear();
        self.positions.extend(agents.iter().map(|a| a.pos));
        self.valid.clear();
        self.valid.extend(agents.iter().map(is_valid));
        self.grid
            .build(&self.positions, &self.valid, p.neighbor_radius);
        // Explicit Euler; never step past the preferred velocity in one go.
        let relax = (dt / p.sf_relaxation_time).min(1.0);
        let mut out = Vec::with_capacity(agents.len());
        for (i, a) in agents.iter().enumerate() {
            let pref = finite_pref(a);
            if !self.valid[i] {
                out.push(pref);
                continue;
            }
            self.grid
                .query(&self.positions, i, p.max_neighbors, &mut self.neighbors);
            let mut push = V2::zeros();
            for &(d2, j) in &self.neighbors {
                let b = &agents[j];
                let d = d2.sqrt();
                // Coincident agents: a fixed direction by index keeps the result defined.
                let away = if d > 1e-9 {
                    (a.pos - b.pos) / d
                } else if i < j {
                    V2::new(-1.0, 0.0)
                } else {
                    V2::new(1.0, 0.0)
                };
                let gap = radius(a) + radius(b) - d;
                push += p.sf_strength * (gap / p.sf_range).min(50.0).exp() * away;
            }
            let mut v = a.vel + relax * (pref - a.vel) + dt * push;
            let speed = v.norm();
            if speed > p.max_speed {
                v *= p.max_speed / speed;
            }
            out.push(if is_finite(v) { v } else { pref });
        }
        out
    }
}
