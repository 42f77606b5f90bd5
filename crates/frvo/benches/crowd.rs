//! Time per agent-step of the motion models in a dense crowd (`cargo bench -p frvo`).
//! Agents stand on a jittered 25 px grid (dense: about 20 x 40 px ellipses), walking in four
//! directions, so every agent has at least `k` neighbours within the radius.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use frvo::{make_model, Agent, MotionKind, MotionParams};
use nalgebra::Vector2;
use std::time::Duration;

fn crowd(n: usize) -> Vec<Agent> {
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

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("agent_step");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    for kind in [MotionKind::Frvo, MotionKind::Rvo] {
        for k in [10usize, 50] {
            for n in [50usize, 200, 1000] {
                let agents = crowd(n);
                // A radius that holds at least k neighbours on the 25 px grid.
                let params = MotionParams {
                    neighbor_radius: 25.0 * ((k as f64 / 3.0).sqrt() + 1.5),
                    max_neighbors: k,
                    max_speed: 4.0,
                    ..MotionParams::default()
                };
                let mut model = make_model(kind, params);
                group.throughput(Throughput::Elements(n as u64));
                let id = BenchmarkId::new(format!("{kind:?}/k{k}"), n);
                group.bench_with_input(id, &agents, |b, agents| b.iter(|| model.step(agents, 1.0)));
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
