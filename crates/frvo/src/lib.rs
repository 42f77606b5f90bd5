//! FRVO: the DensePeds motion model.
//!
//! Each pedestrian is an ellipse (visible face height `l` x shoulder width `w`) oriented along its
//! direction of motion. Ellipses are conservatively approximated by convex polygons, velocity
//! obstacles come from their Minkowski sums, and each agent's new velocity is the one closest to
//! its preferred velocity that satisfies the reciprocal half-plane constraints (a 2-D LP).
//!
//! The [`MotionModel`] trait is the contract the tracker (`assoc`) relies on; constant velocity,
//! social forces and circular RVO implement it too, for the method's ablation.

pub mod agent;
pub mod geometry;
pub mod lp;
pub mod minkowski;
pub mod model;
pub mod models;
pub mod neighbors;
pub mod velocity_obstacle;

pub use agent::Agent;
pub use model::{ConstantVelocity, MotionKind, MotionModel, MotionParams};
pub use models::{make_model, Footprint, Orca, SocialForce};
