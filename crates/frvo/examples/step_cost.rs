//! Fixed work for load-insensitive cost counts (`perf stat -e instructions:u,task-clock`):
//! `cargo run -p frvo --release --example step_cost -- <frvo|rvo> <neighbours> <agents> <steps>
//! [threads]` steps the benchmark's crowd (see `benches/crowd.rs`) on `threads` (default 1; 0 =
//! every core) and prints a checksum of the velocities and a hash of their bits (equal hashes:
//! the same velocities bit for bit).

use frvo::{make_model, MotionKind, MotionParams};

#[path = "../benches/support/crowd.rs"]
mod support;
use support::{crowd, params};

/// FNV-1a over 64-bit words.
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
const FNV_PRIME: u64 = 0x0100_0000_01b3;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg =
        |i: usize, default: usize| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(default);
    let kind = match args.get(1).map(String::as_str) {
        Some("rvo") => MotionKind::Rvo,
        _ => MotionKind::Frvo,
    };
    let (k, n, steps, threads) = (arg(2, 10), arg(3, 200), arg(4, 200), arg(5, 1));
    let mut model = make_model(
        kind,
        MotionParams {
            threads,
            ..params(k)
        },
    );
    let agents = crowd(n);
    let (mut checksum, mut bits) = (0.0, FNV_OFFSET);
    for _ in 0..steps {
        let vel = model.step(&agents, 1.0);
        checksum += vel.iter().map(|v| v.x + v.y).sum::<f64>();
        // The sum hides rounding-level changes; the hash of every bit does not.
        for x in vel.iter().flat_map(|v| [v.x, v.y]) {
            bits = (bits ^ x.to_bits()).wrapping_mul(FNV_PRIME);
        }
    }
    println!("{kind:?} k={k} n={n} steps={steps} checksum={checksum:.12e} bits={bits:016x}");
}
