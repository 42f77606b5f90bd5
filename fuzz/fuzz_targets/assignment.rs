//! `assoc::linear_sum_assignment` (the Hungarian / shortest-augmenting-path solver) on arbitrary
//! cost matrices.
//!
//! Any costs (NaN, infinities, huge values): no panic; an `Ok` answer is a valid assignment of
//! `min(n, m)` distinct rows and columns using no forbidden (`+inf`) pair. Small matrices with
//! finite or forbidden costs: the total equals the brute-force optimum over every assignment.
#![no_main]

use arbitrary::Arbitrary;
use assoc::linear_sum_assignment;
use libfuzzer_sys::fuzz_target;

#[derive(Arbitrary, Debug)]
struct Input {
    n: u8,
    m: u8,
    costs: Vec<f64>,
    /// Map costs to a few small values (ties, the solver's hard case) instead of raw floats.
    coarse: bool,
}

/// Smallest total over every injective map of the shorter side into the longer one, or `None`
/// when each uses a forbidden pair. `c(i, j)` with `i` on the shorter side.
fn brute_force(short: usize, long: usize, c: &dyn Fn(usize, usize) -> f64) -> Option<f64> {
    fn go(
        i: usize,
        short: usize,
        long: usize,
        used: &mut Vec<bool>,
        acc: f64,
        c: &dyn Fn(usize, usize) -> f64,
        best: &mut Option<f64>,
    ) {
        if i == short {
            if best.is_none_or(|b| acc < b) {
                *best = Some(acc);
            }
            return;
        }
        for j in 0..long {
            let x = c(i, j);
            if !used[j] && x.is_finite() {
                used[j] = true;
                go(i + 1, short, long, used, acc + x, c, best);
                used[j] = false;
            }
        }
    }
    let mut best = None;
    go(0, short, long, &mut vec![false; long], 0.0, c, &mut best);
    best
}

fuzz_target!(|input: Input| {
    let (n, m) = (usize::from(input.n % 9), usize::from(input.m % 9));
    if input.costs.is_empty() {
        return;
    }
    let cost: Vec<f64> = (0..n * m)
        .map(|k| {
            let x = input.costs[k % input.costs.len()];
            if input.coarse && x.is_finite() {
                (x.abs() % 4.0).floor()
            } else {
                x
            }
        })
        .collect();
    let res = linear_sum_assignment(&cost, n, m);
    let bad_value = cost.iter().any(|c| c.is_nan() || *c == f64::NEG_INFINITY);
    let small = n.min(m) <= 6 && !cost.iter().any(|c| c.is_finite() && c.abs() > 1e12);
    let optimum = || {
        if n <= m {
            brute_force(n, m, &|i, j| cost[i * m + j])
        } else {
            brute_force(m, n, &|j, i| cost[i * m + j])
        }
    };
    let Ok(pairs) = res else {
        if !bad_value && small {
            assert!(
                optimum().is_none(),
                "reported infeasible, but {:?} exists",
                optimum()
            );
        }
        return;
    };
    assert!(!bad_value, "NaN or -inf accepted");
    assert_eq!(pairs.len(), n.min(m));
    let mut rows = vec![false; n];
    let mut cols = vec![false; m];
    let mut total = 0.0;
    for &(i, j) in &pairs {
        assert!(
            i < n && j < m && !rows[i] && !cols[j],
            "not an assignment: {pairs:?}"
        );
        rows[i] = true;
        cols[j] = true;
        let x = cost[i * m + j];
        assert!(x < f64::INFINITY, "forbidden pair used: {pairs:?}");
        total += x;
    }
    // Brute force only where sums are exact enough to compare.
    if !small {
        return;
    }
    let best = optimum().expect("solver found an assignment that brute force did not");
    let scale = cost
        .iter()
        .filter(|c| c.is_finite())
        .fold(1.0f64, |a, c| a.max(c.abs()));
    assert!(
        (total - best).abs() <= 1e-9 * scale * (n.min(m) as f64 + 1.0),
        "total {total} != optimum {best} for {n}x{m} {cost:?}"
    );
});
