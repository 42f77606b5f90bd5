//! The benchmark's crowd, shared by `benches/crowd.rs` and `examples/step_cost.rs` (included
//! with `#[path]`, so that both measure the same work).

use frvo::{Agent, MotionParams};
use nalgebra::Vector2;

/// `n` agents on a jittered 25 px grid (dense: 20 x 40 px ellipses), walking in four
/// directions.
pub fn crowd(n: usize) -> Vec<Agent> {
    let side = (n as f64).sqrt().ceil() as usize;
    (0..n)
        .map(|i| {
            let (r, c) = ((i / side) as f64, (i % side) as f64);
            // Deterministic jitter, no RNG dependency.
            let j = ((i * 7919) % 97) as f64 / 97.0 - 0.5;
            let pos = Vector2::new(25.0 * c + 4.0 * j, 25.0 * r - 4.0 * j);
            let dir = match i % 4 {
                0 => Vector2::new(1.0, 0.0),
                1 => Vector2::new(-1.0, 0.0),
                2 => Vector2::new(0.0, 1.0),
                _ => Vector2::new(0.0, -1.0),
            };
            Agent::new(pos, dir * 2.0, dir * 2.0, 20.0, 40.0)
        })
        .collect()
}

/// Parameters with a radius that holds at least `k` neighbours on the 25 px grid.
pub fn params(k: usize) -> MotionParams {
    MotionParams {
        neighbor_radius: 25.0 * ((k as f64 / 3.0).sqrt() + 1.5),
        max_neighbors: k,
        max_speed: 4.0,
        ..MotionParams::default()
    }
}
