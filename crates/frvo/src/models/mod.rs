//! The motion models behind [`crate::MotionModel`].

pub mod orca;
pub mod social_force;

pub use orca::{Footprint, Orca};
pub use social_force::SocialForce;

use crate::model::{ConstantVelocity, MotionKind, MotionModel, MotionParams};

/// Builds the model of the given kind. Invalid parameters are sanitised (see
/// [`MotionParams::sanitized`]); call [`MotionParams::validate`] first to report them instead.
pub fn make_model(kind: MotionKind, params: MotionParams) -> Box<dyn MotionModel> {
    match kind {
        MotionKind::Frvo => Box::new(Orca::new(params, Footprint::Ellipse)),
        MotionKind::Rvo => Box::new(Orca::new(params, Footprint::Circle)),
        MotionKind::SocialForce => Box::new(SocialForce::new(params)),
        MotionKind::ConstantVelocity => Box::new(ConstantVelocity),
    }
}
