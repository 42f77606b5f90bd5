//! `assoc::SparseMatcher` on crowds of overlapping boxes: a few seeds grow into up to 600 tracks
//! and 600 detections packed into a small area, gated by IoU as the tracker gates them.
//!
//! Any crowd: no panic; the answer is a matching (each row and column at most once) using only
//! gated pairs, each cheaper than the limit; its total equals the dense solver's (every
//! component on one matrix) and the edge-list solver's (every component on its edges).
//! Bounded: at most 600 x 600 gated pairs, so each run takes milliseconds and a few MB.
#![no_main]

use arbitrary::Arbitrary;
use assoc::cost::iou;
use assoc::{Edge, SparseMatcher};
use libfuzzer_sys::fuzz_target;

#[derive(Arbitrary, Debug)]
struct Input {
    tracks: u16,
    dets: u16,
    /// Side of the square the boxes' corners fall in (pixels), before the `% 400` bound.
    spread: u16,
    /// Offsets cycled to place the boxes (pseudo-random from these bytes).
    jitter: Vec<u8>,
    min_iou: u8,
}

fn boxes(n: usize, spread: f64, jitter: &[u8], salt: usize) -> Vec<[f64; 4]> {
    (0..n)
        .map(|k| {
            let b = |i: usize| f64::from(jitter[(k * 3 + i + salt) % jitter.len()]) / 255.0;
            let (x, y, w) = (b(0) * spread, b(1) * spread, 20.0 + 30.0 * b(2));
            [x, y, x + w, y + 2.5 * w]
        })
        .collect()
}

/// The total `sum(cost - limit)` of a checked matching; `gated[i * m + j]` is the pair's cost
/// (`INFINITY` where there is no edge).
fn check(pairs: &[(usize, usize)], gated: &[f64], n: usize, m: usize, limit: f64) -> f64 {
    let mut rows = vec![false; n];
    let mut cols = vec![false; m];
    let mut total = 0.0;
    for &(i, j) in pairs {
        assert!(!rows[i] && !cols[j], "row or column used twice: {pairs:?}");
        rows[i] = true;
        cols[j] = true;
        let cost = gated[i * m + j];
        assert!(cost.is_finite(), "a pair that is not a gated edge");
        assert!(cost <= limit, "a pair dearer than leaving both unmatched");
        total += cost - limit;
    }
    total
}

fuzz_target!(|input: Input| {
    if input.jitter.is_empty() {
        return;
    }
    let n = usize::from(input.tracks % 600) + 1;
    let m = usize::from(input.dets % 600) + 1;
    let spread = f64::from(input.spread % 400);
    let min_iou = 0.05 + 0.9 * f64::from(input.min_iou) / 255.0;
    let limit = 1.0 - min_iou;
    let tracks = boxes(n, spread, &input.jitter, 0);
    let dets = boxes(m, spread, &input.jitter, 1);
    let mut edges = Vec::new();
    let mut gated = vec![f64::INFINITY; n * m];
    for (i, a) in tracks.iter().enumerate() {
        for (j, b) in dets.iter().enumerate() {
            let o = iou(a, b);
            if o > 0.0 && o >= min_iou {
                edges.push(Edge {
                    row: i,
                    col: j,
                    cost: 1.0 - o,
                });
                gated[i * m + j] = 1.0 - o;
            }
        }
    }
    let default = SparseMatcher::default().solve(n, m, &edges, limit);
    let dense = SparseMatcher::with_dense_limit(usize::MAX).solve(n, m, &edges, limit);
    let sparse = SparseMatcher::with_dense_limit(0).solve(n, m, &edges, limit);
    let totals = [
        check(&default, &gated, n, m, limit),
        check(&dense, &gated, n, m, limit),
        check(&sparse, &gated, n, m, limit),
    ];
    let tol = 1e-9 * (n.min(m) as f64 + 1.0);
    assert!(
        (totals[0] - totals[1]).abs() <= tol && (totals[2] - totals[1]).abs() <= tol,
        "totals differ: {totals:?}"
    );
});
