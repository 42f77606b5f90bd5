//! One frame's prediction for every live track: all step together through the motion model
//! (where crowd interaction enters), in image pixels.

use crate::params::TrackerParams;
use crate::track::Track;
use frvo::{Agent, MotionModel};

/// Sets every track's prediction for this frame.
pub(crate) fn predict(tracks: &mut [Track], model: &mut dyn MotionModel, p: &TrackerParams) {
    if tracks.is_empty() {
        return;
    }
    let agents: Vec<Agent> = tracks.iter().map(|t| t.agent(p)).collect();
    let vels = model.step(&agents, 1.0);
    for (k, t) in tracks.iter_mut().enumerate() {
        let v = vels.get(k).copied().unwrap_or(t.pref_vel);
        t.set_prediction(v, 1.0);
    }
}
