//! Measures where threads start to pay: one thread against every core (forced parallel at any
//! size) on the benchmark's crowd, interleaved in one process so that both see the same
//! machine load. `cargo run -p frvo --release --example thread_cost -- [neighbours] [rounds]`
//! prints, per crowd size, the median time per step of each and their ratio, as the Markdown of
//! `benchmarks/results/frvo-threads.md` (its head names the command, the cores and the load).

use frvo::{Footprint, MotionModel, MotionParams, Orca};
use std::time::Instant;

#[path = "../benches/support/crowd.rs"]
mod support;
use support::{crowd, params};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg =
        |i: usize, default: usize| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(default);
    let (k, rounds) = (arg(1, 10), arg(2, 30).max(1));
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let load = |when: &str| {
        let text = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
        let first = text.split_whitespace().next().unwrap_or("?").to_string();
        format!("{when} {first}")
    };
    println!("# FRVO step time: one thread against every core\n");
    println!(
        "Written by `cargo run -p frvo --release --example thread_cost -- {k} {rounds} > \
         benchmarks/results/frvo-threads.md`: the benchmark's dense crowd (agents 25 px apart, \
         20 x 40 px ellipses, 8-sided polygons, {k} neighbours), one thread and every core \
         ({cores} here, forced parallel at every size) taking turns in one process; median of \
         {rounds} rounds. Load average (1 min): {}.\n",
        load("at the start")
    );
    println!("| agents | pairs | one thread us/step | every core us/step | every core / one |");
    println!("|---:|---:|---:|---:|---:|");
    for n in [20, 40, 80, 160, 300, 500, 1000, 2000, 4000] {
        let agents = crowd(n);
        let model = |threads| {
            let p = MotionParams {
                threads,
                ..params(k)
            };
            Orca::new(p, Footprint::Ellipse).with_parallel_min_pairs(0)
        };
        let mut models = [model(1), model(0)];
        // About 20,000 agent-steps per round and model.
        let steps = (20_000 / n).max(2);
        let mut times = [Vec::new(), Vec::new()];
        for _ in 0..rounds {
            for (model, times) in models.iter_mut().zip(&mut times) {
                let start = Instant::now();
                for _ in 0..steps {
                    std::hint::black_box(model.step(&agents, 1.0));
                }
                times.push(start.elapsed().as_secs_f64() * 1e6 / steps as f64);
            }
        }
        let [one, all] = times.map(|mut t| {
            t.sort_by(f64::total_cmp);
            t[t.len() / 2]
        });
        let pairs = n * k.min(n - 1);
        println!("| {n} | {pairs} | {one:.1} | {all:.1} | {:.2} |", all / one);
    }
    println!("\nLoad average (1 min): {}.", load("at the end"));
}
