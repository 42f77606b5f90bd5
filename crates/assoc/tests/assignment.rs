//! The assignment solvers against brute force on small matrices.

use assoc::{linear_sum_assignment, Edge, SparseMatcher};
use proptest::prelude::*;

const INF: f64 = f64::INFINITY;

/// Smallest total over injective maps rows -> cols (n <= m), or None if all use a forbidden pair.
fn brute_full(cost: &[f64], n: usize, m: usize) -> Option<f64> {
    fn rec(i: usize, n: usize, m: usize, cost: &[f64], used: &mut [bool]) -> f64 {
        if i == n {
            return 0.0;
        }
        let mut best = INF;
        for j in 0..m {
            if !used[j] && cost[i * m + j].is_finite() {
                used[j] = true;
                best = best.min(cost[i * m + j] + rec(i + 1, n, m, cost, used));
                used[j] = false;
            }
        }
        best
    }
    let v = rec(0, n, m, cost, &mut vec![false; m]);
    v.is_finite().then_some(v)
}

/// Smallest `sum(cost - limit)` over partial matchings using only finite entries.
fn brute_partial(cost: &[f64], n: usize, m: usize, limit: f64) -> f64 {
    fn rec(i: usize, n: usize, m: usize, cost: &[f64], limit: f64, used: &mut [bool]) -> f64 {
        if i == n {
            return 0.0;
        }
        let mut best = rec(i + 1, n, m, cost, limit, used);
        for j in 0..m {
            if !used[j] && cost[i * m + j].is_finite() {
                used[j] = true;
                best = best.min(cost[i * m + j] - limit + rec(i + 1, n, m, cost, limit, used));
                used[j] = false;
            }
        }
        best
    }
    rec(0, n, m, cost, limit, &mut vec![false; m])
}

fn matrix() -> impl Strategy<Value = (usize, usize, Vec<f64>)> {
    (1usize..=6, 1usize..=6).prop_flat_map(|(n, m)| {
        let cell = prop_oneof![4 => (0u32..100).prop_map(f64::from), 1 => Just(INF)];
        (Just(n), Just(m), prop::collection::vec(cell, n * m))
    })
}

fn check_pairs_distinct(pairs: &[(usize, usize)]) {
    let mut rows: Vec<usize> = pairs.iter().map(|p| p.0).collect();
    let mut cols: Vec<usize> = pairs.iter().map(|p| p.1).collect();
    rows.sort_unstable();
    cols.sort_unstable();
    rows.dedup();
    cols.dedup();
    assert_eq!(rows.len(), pairs.len(), "a row is used twice");
    assert_eq!(cols.len(), pairs.len(), "a column is used twice");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn full_assignment_matches_brute_force((n, m, cost) in matrix()) {
        let expected = if n <= m {
            brute_full(&cost, n, m)
        } else {
            let t: Vec<f64> = (0..m * n).map(|k| cost[(k % n) * m + k / n]).collect();
            brute_full(&t, m, n)
        };
        match (linear_sum_assignment(&cost, n, m), expected) {
            (Ok(pairs), Some(best)) => {
                prop_assert_eq!(pairs.len(), n.min(m));
                check_pairs_distinct(&pairs);
                let total: f64 = pairs.iter().map(|&(i, j)| cost[i * m + j]).sum();
                prop_assert!((total - best).abs() < 1e-9, "total {} vs brute {}", total, best);
            }
            (Err(_), None) => {}
            (got, want) => prop_assert!(false, "solver {:?} but brute force {:?}", got, want),
        }
    }

    #[test]
    fn partial_matching_matches_brute_force((n, m, cost) in matrix(), limit in 1.0f64..120.0) {
        let edges: Vec<Edge> = (0..n * m)
            .filter(|&k| cost[k] <= limit)
            .map(|k| Edge { row: k / m, col: k % m, cost: cost[k] })
            .collect();
        let gated: Vec<f64> = cost.iter().map(|&c| if c <= limit { c } else { INF }).collect();
        let pairs = SparseMatcher::default().solve(n, m, &edges, limit);
        check_pairs_distinct(&pairs);
        let total: f64 = pairs.iter().map(|&(i, j)| gated[i * m + j] - limit).sum();
        prop_assert!(total.is_finite(), "used a forbidden pair: {:?}", pairs);
        let best = brute_partial(&gated, n, m, limit);
        prop_assert!((total - best).abs() < 1e-9, "total {} vs brute {}", total, best);
    }
}

#[test]
fn infeasible_and_bad_matrices_are_errors() {
    assert!(linear_sum_assignment(&[INF, INF, 1.0, 2.0], 2, 2).is_err());
    assert!(linear_sum_assignment(&[f64::NAN, 1.0], 1, 2).is_err());
    assert!(linear_sum_assignment(&[1.0, 2.0, 3.0], 2, 2).is_err());
    assert_eq!(linear_sum_assignment(&[], 0, 3).unwrap(), vec![]);
}

#[test]
fn known_small_case() {
    // Greedy would take (0,0)=1 then (1,1)=10; the optimum is 2 + 3.
    let cost = [1.0, 2.0, 3.0, 10.0];
    assert_eq!(
        linear_sum_assignment(&cost, 2, 2).unwrap(),
        vec![(0, 1), (1, 0)]
    );
}

/// Random gated pairs among `n` rows and `m` columns, dense or thin.
fn edges_strategy() -> impl Strategy<Value = (usize, usize, Vec<Edge>, f64)> {
    (1usize..=7, 1usize..=7, 0.05f64..1.0, 1.0f64..120.0).prop_flat_map(|(n, m, p, limit)| {
        let cell = (0.0f64..1.0, 0u32..130).prop_map(move |(keep, c)| (keep < p, f64::from(c)));
        (
            Just(n),
            Just(m),
            prop::collection::vec(cell, n * m),
            Just(limit),
        )
            .prop_map(|(n, m, cells, limit)| {
                let edges = cells
                    .iter()
                    .enumerate()
                    .filter(|(_, &(keep, _))| keep)
                    .map(|(k, &(_, cost))| Edge {
                        row: k / m,
                        col: k % m,
                        cost,
                    })
                    .collect();
                (n, m, edges, limit)
            })
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// The edge-list solver (every component forced onto it) is optimal too.
    #[test]
    fn sparse_path_matches_brute_force((n, m, edges, limit) in edges_strategy()) {
        let mut gated = vec![INF; n * m];
        for e in &edges {
            gated[e.row * m + e.col] = e.cost;
        }
        let pairs = SparseMatcher::with_dense_limit(0).solve(n, m, &edges, limit);
        check_pairs_distinct(&pairs);
        let total: f64 = pairs.iter().map(|&(i, j)| gated[i * m + j] - limit).sum();
        prop_assert!(total.is_finite(), "used a pair without an edge: {:?}", pairs);
        let best = brute_partial(&gated, n, m, limit);
        prop_assert!((total - best).abs() < 1e-9, "total {} vs brute {}", total, best);
        let dense = SparseMatcher::with_dense_limit(usize::MAX).solve(n, m, &edges, limit);
        let dense_total: f64 = dense.iter().map(|&(i, j)| gated[i * m + j] - limit).sum();
        prop_assert!((total - dense_total).abs() < 1e-9);
    }
}
