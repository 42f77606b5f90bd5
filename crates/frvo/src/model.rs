use crate::geometry::MAX_SIDES;
use crate::Agent;
use nalgebra::Vector2;

/// Which motion model predicts the next velocities.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MotionKind {
    /// Elliptical reciprocal velocity obstacles (the method).
    Frvo,
    /// Circular RVO (ORCA) baseline.
    Rvo,
    /// Helbing-Molnar social forces baseline.
    SocialForce,
    /// Constant velocity baseline.
    ConstantVelocity,
}

impl std::str::FromStr for MotionKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "frvo" => Ok(Self::Frvo),
            "rvo" => Ok(Self::Rvo),
            "sf" => Ok(Self::SocialForce),
            "cv" => Ok(Self::ConstantVelocity),
            other => Err(format!(
                "unknown motion model {other:?}: expected frvo, rvo, sf or cv"
            )),
        }
    }
}

/// Parameters shared by the motion models (units: pixels and frames).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotionParams {
    /// Neighbourhood radius rho: only agents closer than this constrain each other.
    pub neighbor_radius: f64,
    /// At most this many neighbours (nearest first) constrain an agent.
    pub max_neighbors: usize,
    /// Time horizon tau of the velocity obstacles, in frames.
    pub time_horizon: f64,
    /// Maximum speed, pixels per frame.
    pub max_speed: f64,
    /// Sides of the polygon approximating each ellipse (3 to 32).
    pub polygon_sides: usize,
    /// Social forces: relaxation time toward the preferred velocity, frames.
    pub sf_relaxation_time: f64,
    /// Social forces: repulsion strength A at contact, pixels per frame squared.
    pub sf_strength: f64,
    /// Social forces: repulsion range B, pixels.
    pub sf_range: f64,
    /// Threads for a crowd step (FRVO and circular RVO), the caller's included: 0 is every
    /// core (`std::thread::available_parallelism`), 1 stays on the caller's thread. Small
    /// crowds (under 300 agent-neighbour pairs) always stay on one thread. The velocities are the
    /// same bit for bit whatever the number.
    pub threads: usize,
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            neighbor_radius: 150.0,
            max_neighbors: 10,
            time_horizon: 5.0,
            max_speed: 50.0,
            polygon_sides: 8,
            sf_relaxation_time: 2.0,
            sf_strength: 1.0,
            sf_range: 10.0,
            threads: 0,
        }
    }
}

/// Most threads a step may ask for: more could only cost (and a typo like 100000 would try
/// to start that many).
pub const MAX_THREADS: usize = 1024;

/// Largest finite speed the solver works with (keeps the disc arithmetic finite).
const SPEED_CAP: f64 = 1e9;

impl MotionParams {
    /// Every problem with the parameters, for a clear error at an API boundary.
    pub fn validate(&self) -> Result<(), String> {
        let mut bad = Vec::new();
        if self.neighbor_radius.is_nan() || self.neighbor_radius < 0.0 {
            bad.push(format!(
                "neighbor_radius must be >= 0, got {}",
                self.neighbor_radius
            ));
        }
        if !(self.time_horizon.is_finite() && self.time_horizon > 0.0) {
            bad.push(format!(
                "time_horizon must be finite and > 0, got {}",
                self.time_horizon
            ));
        }
        if !(self.max_speed.is_finite() && self.max_speed >= 0.0) {
            bad.push(format!(
                "max_speed must be finite and >= 0, got {}",
                self.max_speed
            ));
        }
        if !(3..=MAX_SIDES).contains(&self.polygon_sides) {
            bad.push(format!(
                "polygon_sides must be in 3..={MAX_SIDES}, got {}",
                self.polygon_sides
            ));
        }
        for (name, value) in [
            ("sf_relaxation_time", self.sf_relaxation_time),
            ("sf_range", self.sf_range),
        ] {
            if !(value.is_finite() && value > 0.0) {
                bad.push(format!("{name} must be finite and > 0, got {value}"));
            }
        }
        if !(self.sf_strength.is_finite() && self.sf_strength >= 0.0) {
            bad.push(format!(
                "sf_strength must be finite and >= 0, got {}",
                self.sf_strength
            ));
        }
        if self.threads > MAX_THREADS {
            bad.push(format!(
                "threads must be in 0..={MAX_THREADS} (0: every core), got {}",
                self.threads
            ));
        }
        if bad.is_empty() {
            Ok(())
        } else {
            Err(bad.join("; "))
        }
    }

    /// The nearest usable parameters: invalid values fall back to the defaults (radius and
    /// speed to 0), so the models never see NaN or out-of-range settings.
    pub fn sanitized(&self) -> Self {
        let d = Self::default();
        let positive = |v: f64, default: f64| {
            if v.is_finite() && v > 0.0 {
                v
            } else {
                default
            }
        };
        Self {
            neighbor_radius: if self.neighbor_radius.is_nan() {
                0.0
            } else {
                self.neighbor_radius.max(0.0)
            },
            max_neighbors: self.max_neighbors,
            time_horizon: positive(self.time_horizon, d.time_horizon),
            max_speed: if self.max_speed.is_nan() {
                0.0
            } else {
                self.max_speed.clamp(0.0, SPEED_CAP)
            },
            polygon_sides: self.polygon_sides.clamp(3, MAX_SIDES),
            sf_relaxation_time: positive(self.sf_relaxation_time, d.sf_relaxation_time),
            sf_strength: if self.sf_strength.is_finite() {
                self.sf_strength.max(0.0)
            } else {
                d.sf_strength
            },
            sf_range: positive(self.sf_range, d.sf_range),
            threads: self.threads.min(MAX_THREADS),
        }
    }
}

/// A motion model steps a whole crowd: given every agent's state, it returns each agent's new
/// velocity (same order). Positions advance by `pos + vel * dt` in the caller.
pub trait MotionModel: Send + Sync {
    fn kind(&self) -> MotionKind;
    /// New velocities for all agents after one step of `dt` frames. Must never panic, even on
    /// degenerate input (NaN, zero size, coincident agents); non-finite input yields the agent's
    /// preferred velocity or zero.
    fn step(&mut self, agents: &[Agent], dt: f64) -> Vec<Vector2<f64>>;
}

/// Constant velocity: the new velocity is the preferred velocity.
#[derive(Clone, Debug, Default)]
pub struct ConstantVelocity;

impl MotionModel for ConstantVelocity {
    fn kind(&self) -> MotionKind {
        MotionKind::ConstantVelocity
    }
    fn step(&mut self, agents: &[Agent], _dt: f64) -> Vec<Vector2<f64>> {
        agents
            .iter()
            .map(|a| {
                if a.pref_vel.iter().all(|x| x.is_finite()) {
                    a.pref_vel
                } else {
                    Vector2::zeros()
                }
            })
            .collect()
    }
}
