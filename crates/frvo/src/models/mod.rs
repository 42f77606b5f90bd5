//! The motion models behind [`crate::MotionModel`].

pub mod orca;
pub mod social_force;

pub use orca::{Footprint, Orca};
pub use social_force::SocialForce;
