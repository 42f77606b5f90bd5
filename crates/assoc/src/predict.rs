//! One frame's prediction for every live track: all step together through the motion model
//! (where crowd interaction enters), in image pixels or, with a fitted [`GroundMap`], with their
//! feet on the ground plane, where a near person and a far one walking alike move alike.
//!
//! With `motion_person_height` set, the crowd is scaled before the step so that a typical person
//! is that many units tall (the median box height in image space, the fitted height at the
//! reference row on the ground plane): the motion model's lengths (`neighbor_radius`,
//! `max_speed`, the social-force range and strength) then mean the same on every image scale.

use crate::params::TrackerParams;
use crate::perspective::GroundMap;
use crate::track::Track;
use frvo::{Agent, MotionModel};
use nalgebra::Vector2;

/// Sets every track's prediction for this frame.
pub(crate) fn predict(
    tracks: &mut [Track],
    model: &mut dyn MotionModel,
    p: &TrackerParams,
    ground: Option<&GroundMap>,
) {
    if tracks.is_empty() {
        return;
    }
    let agents: Vec<Agent> = tracks.iter().map(|t| t.agent(p)).collect();
    let Some(g) = ground else {
        let u = units_per_pixel(p.motion_person_height, || median_height(tracks));
        let vels = step_scaled(model, &agents, u);
        for (k, t) in tracks.iter_mut().enumerate() {
            let v = vels.get(k).copied().unwrap_or(t.pref_vel);
            t.set_prediction(v, 1.0);
        }
        return;
    };
    let foot = |t: &Track| t.pos + Vector2::new(0.0, 0.5 * t.h);
    let on_ground: Vec<Agent> = agents
        .iter()
        .zip(tracks.iter())
        .map(|(a, t)| {
            let f = foot(t);
            let (j, s) = (g.jacobian(f), g.scale(f.y));
            let pref = t.ground_pref_vel(g, p);
            Agent::new(g.to_ground(f), j * a.vel, pref, a.l / s, a.w / s)
        })
        .collect();
    let u = units_per_pixel(p.motion_person_height, || Some(g.reference_height()));
    let vels = step_scaled(model, &on_ground, u);
    for (k, t) in tracks.iter_mut().enumerate() {
        let f = foot(t);
        let v = vels.get(k).copied().unwrap_or(on_ground[k].pref_vel);
        let next = g.to_image(on_ground[k].pos + v);
        let scale = g.scale(next.y) / g.scale(f.y);
        let centre = next - Vector2::new(0.0, 0.5 * scale * t.h);
        t.set_prediction(centre - t.pos, scale);
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
