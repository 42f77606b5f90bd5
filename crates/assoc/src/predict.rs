//! One frame's prediction for every live track: all step together through the motion model
//! (where crowd interaction enters), in image pixels.
//!
//! With `motion_person_height` set, the crowd is scaled before the step so that a typical person
//! (the median box height) is that many units tall: the motion model's lengths
//! (`neighbor_radius`, `max_speed`, the social-force range and strength) then mean the same on
//! every image scale.

use crate::params::TrackerParams;
use crate::track::Track;
use frvo::{Agent, MotionModel};
use nalgebra::Vector2;

/// Sets every track's prediction for this frame.
pub(crate) fn predict(tracks: &mut [Track], model: &mut dyn MotionModel, p: &TrackerParams) {
    if tracks.is_empty() {
        return;
    }
    let agents: Vec<Agent> = tracks.iter().map(|t| t.agent(p)).collect();
    let u = units_per_pixel(p.motion_person_height, || median_height(tracks));
    let vels = step_scaled(model, &agents, u);
    for (k, t) in tracks.iter_mut().enumerate() {
        let v = vels.get(k).copied().unwrap_or(t.pref_vel);
        t.set_prediction(v, 1.0);
    }
}

/// Motion-model units per pixel: `person_height / typical` where both are positive and
/// finite, else 1 (image pixels).
fn units_per_pixel(person_height: f64, typical: impl FnOnce() -> Option<f64>) -> f64 {
    if !(person_height > 0.0 && person_height.is_finite()) {
        return 1.0;
    }
    match typical() {
        Some(h) if h.is_finite() && h > 0.0 => {
            let u = person_height / h;
            if u.is_finite() && u > 0.0 {
                u
            } else {
                1.0
            }
        }
        _ => 1.0,
    }
}

/// Median box height of the tracks with a finite positive one.
fn median_height(tracks: &[Track]) -> Option<f64> {
    let mut h: Vec<f64> = tracks
        .iter()
        .map(|t| t.h)
        .filter(|h| h.is_finite() && *h > 0.0)
        .collect();
    if h.is_empty() {
        return None;
    }
    let mid = h.len() / 2;
    let (_, m, _) = h.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

/// One step of the model on the agents scaled by `u` units per pixel; velocities in pixels.
fn step_scaled(model: &mut dyn MotionModel, agents: &[Agent], u: f64) -> Vec<Vector2<f64>> {
    if u == 1.0 {
        return model.step(agents, 1.0);
    }
    let scaled: Vec<Agent> = agents
        .iter()
        .map(|a| Agent::new(a.pos * u, a.vel * u, a.pref_vel * u, a.l * u, a.w * u))
        .collect();
    model
        .step(&scaled, 1.0)
        .into_iter()
        .map(|v| v / u)
        .collect()
}
