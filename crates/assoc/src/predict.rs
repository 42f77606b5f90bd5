//! One frame's prediction for every live track: all step together through the motion model
//! (where crowd interaction enters), in image pixels or, with a fitted [`GroundMap`], with their
//! feet on the ground plane, where a near person and a far one walking alike move alike.

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
        let vels = model.step(&agents, 1.0);
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
    let vels = model.step(&on_ground, 1.0);
    for (k, t) in tracks.iter_mut().enumerate() {
        let f = foot(t);
        let v = vels.get(k).copied().unwrap_or(on_ground[k].pref_vel);
        let next = g.to_image(on_ground[k].pos + v);
        let scale = g.scale(next.y) / g.scale(f.y);
        let centre = next - Vector2::new(0.0, 0.5 * scale * t.h);
        t.set_prediction(centre - t.pos, scale);
    }
}
