//! The crowd step (grid neighbours, reused buffers, threads) against a plain O(N^2) reference
//! built from the public pieces, each tested on its own: brute-force neighbours,
//! `Ellipse::polygon`, `minkowski_sum`, `avoidance`, `reciprocal_line` and `lp::solve`. The
//! step's velocity must solve the reference's LP as well as the reference's own solution does.
//! (The velocities themselves are compared too, but a min-max solution need not be unique:
//! with two antiparallel half-planes a whole segment is optimal, and rounding differences in
//! the lines can then move the solver's answer along it.)

use frvo::geometry::{heading, Ellipse, V2};
use frvo::lp::{self, Line};
use frvo::minkowski::minkowski_sum;
use frvo::velocity_obstacle::{avoidance, reciprocal_line};
use frvo::{Agent, Footprint, MotionModel, MotionParams, Orca};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

/// FRVO's step written the obvious way: O(N^2) neighbours, one polygon per pair.
fn reference_step(agents: &[Agent], p: &MotionParams, dt: f64) -> Vec<(V2, bool, Vec<Line>)> {
    let polygon =
        |a: &Agent| Ellipse::new(a.l, a.w, heading(a.vel, a.pref_vel)).polygon(p.polygon_sides);
    let mut scratch = Vec::new();
    agents
        .iter()
        .enumerate()
        .map(|(i, a)| {
            let mut near: Vec<(f64, usize)> = (0..agents.len())
                .filter(|&j| j != i)
                .map(|j| ((agents[j].pos - a.pos).norm_squared(), j))
                .filter(|&(d2, _)| d2 < p.neighbor_radius * p.neighbor_radius)
                .collect();
            near.sort_by(|x, y| x.0.total_cmp(&y.0));
            near.truncate(p.max_neighbors);
            let minus_me = polygon(a).negated();
            let lines: Vec<Line> = near
                .iter()
                .map(|&(_, j)| {
                    let b = &agents[j];
                    let mut rel_pos = b.pos - a.pos;
                    if rel_pos.norm_squared() < 1e-18 {
                        rel_pos = V2::new(if i < j { 1e-6 } else { -1e-6 }, 0.0);
                    }
                    let sum = minkowski_sum(&polygon(b), &minus_me);
                    let avoid = avoidance(rel_pos, &sum, a.vel - b.vel, p.time_horizon, dt);
                    reciprocal_line(a.vel, avoid)
                })
                .collect();
            let sol = lp::solve(&lines, p.max_speed, a.pref_vel, &mut scratch);
            (sol.velocity, sol.feasible, lines)
        })
        .collect()
}

fn agent() -> impl Strategy<Value = Agent> {
    (
        (0.0f64..400.0, 0.0f64..400.0),
        (-4.0f64..4.0, -4.0f64..4.0),
        (-4.0f64..4.0, -4.0f64..4.0),
        (4.0f64..50.0, 4.0f64..60.0),
    )
        .prop_map(|(p, v, pref, (l, w))| {
            Agent::new(
                V2::new(p.0, p.1),
                V2::new(v.0, v.1),
                V2::new(pref.0, pref.1),
                l,
                w,
            )
        })
}

fn params() -> impl Strategy<Value = MotionParams> {
    (
        20.0f64..200.0,
        1usize..40,
        0.5f64..20.0,
        1.0f64..8.0,
        3usize..=16,
    )
        .prop_map(
            |(neighbor_radius, max_neighbors, time_horizon, max_speed, polygon_sides)| {
                MotionParams {
                    neighbor_radius,
                    max_neighbors,
                    time_horizon,
                    max_speed,
                    polygon_sides,
                    ..MotionParams::default()
                }
            },
        )
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 300,
        rng_seed: RngSeed::Fixed(0x0c0a_5eed),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn frvo_step_matches_reference(
        agents in prop::collection::vec(agent(), 1..80),
        params in params(),
        dt in prop::sample::select(vec![0.5, 1.0, 2.0]),
    ) {
        let mut model = Orca::new(params, Footprint::Ellipse);
        let fast = model.step(&agents, dt);
        let reference = reference_step(&agents, &params, dt);
        prop_assert_eq!(model.last_feasible().len(), agents.len());
        for (i, ((v, (r, feasible, lines)), fast_feasible)) in
            fast.iter().zip(&reference).zip(model.last_feasible()).enumerate()
        {
            if (v - r).norm() <= 1e-9 {
                prop_assert_eq!(fast_feasible, feasible, "agent {}", i);
                continue;
            }
            // Not the same point: it must be as good a solution of the reference's problem.
            let worst = |x: V2| lines.iter().map(|l| l.violation(x)).fold(0.0f64, f64::max);
            prop_assert!(v.norm() <= params.max_speed + 1e-9, "agent {}: speed {:?}", i, v);
            if *feasible {
                prop_assert!(*fast_feasible, "agent {}: infeasible, reference feasible", i);
                prop_assert!(worst(*v) <= 1e-9, "agent {}: {:?} violates by {}", i, v, worst(*v));
                let pref = agents[i].pref_vel;
                prop_assert!(
                    (v - pref).norm() <= (r - pref).norm() + 1e-9,
                    "agent {}: {:?} farther from the preferred velocity than {:?}", i, v, r
                );
            } else {
                prop_assert!(
                    worst(*v) <= worst(*r) + 1e-9,
                    "agent {}: largest violation {} vs reference {}", i, worst(*v), worst(*r)
                );
                prop_assert!(!*fast_feasible || worst(*r) <= 1e-9, "agent {}", i);
            }
        }
    }
}
