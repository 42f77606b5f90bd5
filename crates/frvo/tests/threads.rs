//! A crowd step spread over threads gives the same velocities, bit for bit, as on one thread.

use frvo::geometry::V2;
use frvo::models::orca::PARALLEL_MIN_PAIRS;
use frvo::{Agent, Footprint, MotionModel, MotionParams, Orca};

/// A small deterministic generator (no RNG dependency): uniform in [0, 1).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `n` agents packed about one per 25 x 25 px, with random velocities, preferred velocities and
/// sizes, some coincident pairs and some invalid agents (NaN position or velocity).
fn crowd(n: usize, seed: u64) -> Vec<Agent> {
    let mut rng = Lcg(seed);
    let side = 25.0 * (n as f64).sqrt();
    let mut agents: Vec<Agent> = (0..n)
        .map(|_| {
            let pos = V2::new(side * rng.next(), side * rng.next());
            let vel = V2::new(4.0 * rng.next() - 2.0, 4.0 * rng.next() - 2.0);
            let pref = V2::new(4.0 * rng.next() - 2.0, 4.0 * rng.next() - 2.0);
            Agent::new(
                pos,
                vel,
                pref,
                10.0 + 20.0 * rng.next(),
                20.0 + 30.0 * rng.next(),
            )
        })
        .collect();
    for k in (0..n).step_by(97) {
        agents[k].pos = agents[(k + 1) % n].pos; // coincident
    }
    for k in (5..n).step_by(211) {
        agents[k].pos.x = f64::NAN;
    }
    for k in (7..n).step_by(223) {
        agents[k].vel.y = f64::INFINITY;
    }
    agents
}

fn step(
    footprint: Footprint,
    params: MotionParams,
    agents: &[Agent],
) -> (Vec<V2>, Vec<bool>, bool) {
    let mut model = Orca::new(params, footprint);
    let v = model.step(agents, 1.0);
    (v, model.last_feasible().to_vec(), model.last_parallel())
}

#[test]
fn threads_give_the_same_velocities_bit_for_bit() {
    for (footprint, sides) in [
        (Footprint::Ellipse, 8), // symmetric polygons: half the edges stored
        (Footprint::Ellipse, 7), // odd: negated polygons
        (Footprint::Circle, 8),
    ] {
        for (n, max_neighbors) in [(1500, 10), (600, 40)] {
            let agents = crowd(n, 17 + n as u64);
            let params = |threads| MotionParams {
                neighbor_radius: 120.0,
                max_neighbors,
                max_speed: 4.0,
                polygon_sides: sides,
                threads,
                ..MotionParams::default()
            };
            let (one, one_ok, one_par) = step(footprint, params(1), &agents);
            assert!(!one_par, "threads = 1 must stay on the caller's thread");
            assert!(one_ok.iter().any(|&ok| ok) && one_ok.iter().any(|&ok| !ok));
            for threads in [0, 2, 3] {
                let (many, many_ok, many_par) = step(footprint, params(threads), &agents);
                // Every core (threads = 0) may be one core.
                assert!(many_par || (threads == 0 && cores() == 1));
                let same = one
                    .iter()
                    .zip(&many)
                    .all(|(a, b)| a.x.to_bits() == b.x.to_bits() && a.y.to_bits() == b.y.to_bits());
                assert!(
                    same,
                    "{footprint:?} sides {sides} n {n} k {max_neighbors} threads {threads}"
                );
                assert_eq!(one_ok, many_ok);
            }
        }
    }
}

/// The cores the model sees for threads = 0.
fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Models stepping on several threads at once: clones of one model share its pool, every-core
/// models share the process's. Each must still give the one-thread velocities.
#[test]
fn concurrent_callers_give_the_same_velocities() {
    let crowds: Vec<Vec<Agent>> = [60, 400, 1100, 2000]
        .into_iter()
        .map(|n| crowd(n, 100 + n as u64))
        .collect();
    let params = |threads| MotionParams {
        neighbor_radius: 120.0,
        max_neighbors: 10,
        max_speed: 4.0,
        threads,
        ..MotionParams::default()
    };
    let expected: Vec<Vec<V2>> = crowds
        .iter()
        .map(|c| step(Footprint::Ellipse, params(1), c).0)
        .collect();
    let mut own = Orca::new(params(2), Footprint::Ellipse);
    own.step(&crowds[3], 1.0); // makes its pool, which its clones share
    std::thread::scope(|scope| {
        for caller in 0..4 {
            let (crowds, expected) = (&crowds, &expected);
            let mut models = [
                own.clone(),
                Orca::new(params(0), Footprint::Ellipse),
                Orca::new(params(3), Footprint::Ellipse),
            ];
            scope.spawn(move || {
                for round in 0..20 {
                    let k = (caller + round) % crowds.len();
                    let model = &mut models[round % models.len()];
                    let v = model.step(&crowds[k], 1.0);
                    let same = v.iter().zip(&expected[k]).all(|(a, b)| {
                        a.x.to_bits() == b.x.to_bits() && a.y.to_bits() == b.y.to_bits()
                    });
                    assert!(same, "caller {caller}, round {round}, crowd {k}");
                }
            });
        }
    });
}

/// A model reused across crowds of changing size and shape gives what a fresh model gives, bit
/// for bit, and spreads a step over threads exactly when the crowd has enough pairs.
#[test]
fn reused_model_gives_what_a_fresh_one_gives() {
    for footprint in [Footprint::Ellipse, Footprint::Circle] {
        let params = MotionParams {
            neighbor_radius: 120.0,
            max_neighbors: 10,
            max_speed: 4.0,
            threads: 2,
            ..MotionParams::default()
        };
        let mut reused = Orca::new(params, footprint);
        let sizes = [1.0, 2.0, 0.5, 1.5, 1.0, 1.0, 0.7, 2.0];
        for (k, (n, size)) in [300, 20, 1200, 5, 0, 1, 1100, 40]
            .into_iter()
            .zip(sizes)
            .enumerate()
        {
            // Sizes change too: stale shapes would give other velocities.
            let mut agents = crowd(n, k as u64);
            for a in &mut agents {
                (a.l, a.w) = (size * a.l, size * a.w);
            }
            let v = reused.step(&agents, 1.0);
            let (w, _, _) = step(footprint, params, &agents);
            let bits = |v: &[V2]| -> Vec<[u64; 2]> {
                v.iter().map(|x| [x.x.to_bits(), x.y.to_bits()]).collect()
            };
            assert_eq!(bits(&v), bits(&w), "{footprint:?}, crowd {k} of {n}");
            let pairs = n * params.max_neighbors.min(n.saturating_sub(1));
            assert_eq!(
                reused.last_parallel(),
                pairs >= PARALLEL_MIN_PAIRS,
                "{n} agents"
            );
        }
    }
}
