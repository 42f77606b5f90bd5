//! Time per agent-step of the motion models in a dense crowd (`cargo bench -p frvo`).
//! Agents stand on a jittered 25 px grid (dense: about 20 x 40 px ellipses), walking in four
//! directions, so every agent has at least `k` neighbours within the radius. Each case runs on
//! one thread (`t1`) and on every core (`tall`: `MotionParams::threads = 0`); crowds under
//! `frvo::models::orca::PARALLEL_MIN_PAIRS` agent-neighbour pairs stay on one thread either way.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use frvo::{make_model, MotionKind, MotionParams};
use std::time::Duration;

#[path = "support/crowd.rs"]
mod support;
use support::{crowd, params};

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("agent_step");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    for kind in [MotionKind::Frvo, MotionKind::Rvo] {
        for (threads, label) in [(1, "t1"), (0, "tall")] {
            for k in [10usize, 50] {
                for n in [50usize, 200, 1000] {
                    let agents = crowd(n);
                    let mut model = make_model(
                        kind,
                        MotionParams {
                            threads,
                            ..params(k)
                        },
                    );
                    group.throughput(Throughput::Elements(n as u64));
                    let id = BenchmarkId::new(format!("{kind:?}/{label}/k{k}"), n);
                    group.bench_with_input(id, &agents, |b, agents| {
                        b.iter(|| model.step(agents, 1.0))
                    });
                }
            }
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
