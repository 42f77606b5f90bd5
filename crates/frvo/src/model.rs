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
    /// Sides of the polygon approximating each ellipse.
    pub polygon_sides: usize,
}

impl Default for MotionParams {
    fn default() -> Self {
        Self {
            neighbor_radius: 150.0,
            max_neighbors: 10,
            time_horizon: 5.0,
            max_speed: 50.0,
            polygon_sides: 8,
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

/// Builds the model of the given kind. Until the other models land, every kind falls back to
/// constant velocity (the frvo crate replaces this).
pub fn make_model(kind: MotionKind, params: MotionParams) -> Box<dyn MotionModel> {
    let _ = (kind, params);
    Box::new(ConstantVelocity)
}
