//! The matcher on crowds of overlapping boxes: components far larger than the dense limit are
//! solved on their edges (memory linear in the gated pairs) and as well as the dense solver; the
//! tracker refuses a frame of more detections than it takes, at once and with one error.

use assoc::cost::{iou, MAX_DETECTIONS_PER_FRAME};
use assoc::{Edge, SparseMatcher, Tracker, TrackerParams, DENSE_COMPONENT_MAX};
use proptest::prelude::*;

/// `n` boxes of about 40 x 100 pixels whose corners fall in a `spread`-pixel square: all of
/// them overlap one another for a small spread.
fn crowd(n: usize, spread: f64) -> impl Strategy<Value = Vec<[f64; 4]>> {
    prop::collection::vec((0.0..=spread, 0.0..=spread, 30.0f64..50.0), n).prop_map(|v| {
        v.into_iter()
            .map(|(x, y, w)| [x, y, x + w, y + 2.5 * w])
            .collect()
    })
}

fn gated_edges(rows: &[[f64; 4]], cols: &[[f64; 4]], min_iou: f64) -> Vec<Edge> {
    let mut edges = Vec::new();
    for (i, a) in rows.iter().enumerate() {
        for (j, b) in cols.iter().enumerate() {
            let o = iou(a, b);
            if o > 0.0 && o >= min_iou {
                edges.push(Edge {
                    row: i,
                    col: j,
                    cost: 1.0 - o,
                });
            }
        }
    }
    edges
}

fn total(edges: &[Edge], pairs: &[(usize, usize)], limit: f64) -> f64 {
    pairs
        .iter()
        .map(|&(i, j)| {
            let e = edges.iter().find(|e| e.row == i && e.col == j);
            e.expect("a pair without an edge").cost - limit
        })
        .sum()
}

fn check_matching(pairs: &[(usize, usize)], n: usize, m: usize) {
    let mut rows = vec![false; n];
    let mut cols = vec![false; m];
    for &(i, j) in pairs {
        assert!(
            !rows[i] && !cols[j],
            "a row or column used twice: {pairs:?}"
        );
        rows[i] = true;
        cols[j] = true;
    }
}

proptest! {
    // Each case solves components of up to 400 x 400 twice: a few dozen cases stay within
    // seconds and a few MB.
    #![proptest_config(ProptestConfig { cases: 24, max_shrink_iters: 64, ..ProptestConfig::default() })]

    #[test]
    fn overlapping_crowd_sparse_equals_dense(
        tracks in (260usize..400).prop_flat_map(|n| crowd(n, 120.0)),
        dets in (260usize..400).prop_flat_map(|n| crowd(n, 120.0)),
        min_iou in 0.05f64..0.6,
    ) {
        let edges = gated_edges(&tracks, &dets, min_iou);
        let limit = 1.0 - min_iou;
        let (n, m) = (tracks.len(), dets.len());
        // One big component: beyond the dense limit, so the default matcher goes sparse.
        prop_assume!(n * m > DENSE_COMPONENT_MAX);
        let sparse = SparseMatcher::default().solve(n, m, &edges, limit);
        let dense = SparseMatcher::with_dense_limit(usize::MAX).solve(n, m, &edges, limit);
        check_matching(&sparse, n, m);
        check_matching(&dense, n, m);
        let (a, b) = (total(&edges, &sparse, limit), total(&edges, &dense, limit));
        prop_assert!((a - b).abs() <= 1e-9 * (n as f64), "sparse {} vs dense {}", a, b);
    }
}

#[test]
fn a_frame_past_the_bound_is_one_error_and_changes_nothing() {
    let mut t = Tracker::new(TrackerParams::default()).unwrap();
    let n = MAX_DETECTIONS_PER_FRAME + 1;
    let boxes: Vec<f64> = (0..n)
        .flat_map(|k| [k as f64 * 1e-3, 0.0, 40.0, 100.0])
        .collect();
    let err = t.update(&boxes, &vec![0.9; n], None).unwrap_err();
    assert!(err.to_string().contains("at most"), "{err}");
    assert_eq!(t.frame_count(), 0);
    assert_eq!(t.num_tracks(), 0);
}

#[test]
fn frames_of_the_bound_all_overlapping_are_tracked() {
    // The worst frame the tracker takes: every detection overlaps every other, twice in a row
    // (every track gated to every detection: one component of n x n). Completes, one track each.
    let n = MAX_DETECTIONS_PER_FRAME / 4;
    let mut t = Tracker::new(TrackerParams::default()).unwrap();
    let boxes: Vec<f64> = (0..n)
        .flat_map(|k| {
            let d = (k % 97) as f64 * 0.05;
            [d, d, 40.0 + d, 100.0 + d]
        })
        .collect();
    for _ in 0..3 {
        t.update(&boxes, &vec![0.9; n], None).unwrap();
    }
    assert!(t.num_tracks() >= n / 2, "{} tracks", t.num_tracks());
}

#[test]
fn infinite_scores_are_refused() {
    let mut t = Tracker::new(TrackerParams::default()).unwrap();
    let boxes = [0.0, 0.0, 10.0, 20.0, 50.0, 0.0, 60.0, 20.0];
    for bad in [f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
        assert!(
            t.update(&boxes, &[0.9, bad], None).is_err(),
            "score {bad} accepted"
        );
    }
    assert_eq!(t.frame_count(), 0);
}
