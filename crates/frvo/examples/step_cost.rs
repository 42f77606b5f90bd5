//! Fixed work for load-insensitive cost counts (`perf stat -e instructions:u,task-clock`):
//! `cargo run -p frvo --release --example step_cost -- <frvo|rvo> <neighbours> <agents> <steps>`
//! steps the benchmark's crowd (see `benches/crowd.rs`) and prints a checksum of the velocities.

use frvo::{make_model, Agent, MotionKind, MotionParams};
use nalgebra::Vector2;

fn crowd(n: usize) -> Vec<Agent> {
    let side = (n as f64).sqrt().ceil() as usize;
    (0..n)
        .map(|i| {
            let (r, c) = ((i / side) as f64, (i % side) as f64);
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

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg =
        |i: usize, default: usize| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(default);
    let kind = match args.get(1).map(String::as_str) {
        Some("rvo") => MotionKind::Rvo,
        _ => MotionKind::Frvo,
    };
    let (k, n, steps) = (arg(2, 10), arg(3, 200), arg(4, 200));
    let params = MotionParams {
        neighbor_radius: 25.0 * ((k as f64 / 3.0).sqrt() + 1.5),
        max_neighbors: k,
        max_speed: 4.0,
        ..MotionParams::default()
    };
    let mut model = make_model(kind, params);
    let agents = crowd(n);
    let mut checksum = 0.0;
    for _ in 0..steps {
        checksum += model
            .step(&agents, 1.0)
            .iter()
            .map(|v| v.x + v.y)
            .sum::<f64>();
    }
    println!("{kind:?} k={k} n={n} steps={steps} checksum={checksum:.12e}");
}
