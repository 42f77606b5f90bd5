//! One thread against every core on the benchmark's crowd, interleaved in one process so that
//! both see the same machine load:
//! `cargo run -p frvo --release --example thread_cost -- <neighbours> <agents> <rounds>`
//! prints the fastest round's time per agent-step for each (FRVO).

use frvo::{make_model, MotionKind, MotionParams};
use std::time::Instant;

#[path = "../benches/support/crowd.rs"]
mod support;
use support::{crowd, params};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg =
        |i: usize, default: usize| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(default);
    let (k, n, rounds) = (arg(1, 10), arg(2, 200).max(1), arg(3, 20));
    let agents = crowd(n);
    // About 20,000 agent-steps per round.
    let steps = (20_000 / n).max(2);
    let mut models: Vec<_> = [1, 0]
        .into_iter()
        .map(|threads| {
            make_model(
                MotionKind::Frvo,
                MotionParams {
                    threads,
                    ..params(k)
                },
            )
        })
        .collect();
    let mut best = [f64::INFINITY; 2];
    for _ in 0..rounds {
        for (model, best) in models.iter_mut().zip(&mut best) {
            let start = Instant::now();
            for _ in 0..steps {
                std::hint::black_box(model.step(&agents, 1.0));
            }
            let per_agent = start.elapsed().as_secs_f64() / (steps * n) as f64;
            *best = best.min(per_agent * 1e6);
        }
    }
    println!(
        "FRVO k={k} n={n}: one thread {:.3} us, every core {:.3} us per agent-step (fastest of {rounds} rounds)",
        best[0], best[1]
    );
}
