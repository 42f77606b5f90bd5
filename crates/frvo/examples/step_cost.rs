//! Fixed work for load-insensitive cost counts (`perf stat -e instructions:u,task-clock`):
//! `cargo run -p frvo --release --example step_cost -- <frvo|rvo> <neighbours> <agents> <steps>`
//! steps the benchmark's crowd (see `benches/crowd.rs`) and prints a checksum of the velocities.

use frvo::{make_model, MotionKind};

#[path = "../benches/support/crowd.rs"]
mod support;
use support::{crowd, params};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg =
        |i: usize, default: usize| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(default);
    let kind = match args.get(1).map(String::as_str) {
        Some("rvo") => MotionKind::Rvo,
        _ => MotionKind::Frvo,
    };
    let (k, n, steps) = (arg(2, 10), arg(3, 200), arg(4, 200));
    let mut model = make_model(kind, params(k));
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
