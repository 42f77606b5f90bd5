//! The score reading: the cuts against brute force over the scores seen (quantile floor and
//! ceiling), and the tracker's behaviour under them (a detector scaled down tracked as the
//! original, a self-thresholded detector's bottom scores, the pure tracker unchanged).

use assoc::{ScoreScaler, TrackOutput, Tracker, TrackerParams};
use frvo::MotionKind;

/// A small deterministic generator (no dependency): uniform in [0, 1).
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

/// The smallest value `v` of `window` with `#{x <= v} >= t * n`, by counting.
fn brute_quantile(window: &[f64], t: f64) -> f64 {
    if t <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if t > 1.0 {
        return f64::INFINITY;
    }
    let n = window.len() as f64;
    window
        .iter()
        .copied()
        .filter(|&v| window.iter().filter(|&&x| x <= v).count() as f64 / n >= t)
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn quantile_floor_raises_det_and_new_cuts_to_the_window_quantile() {
    let mut rng = Lcg(13);
    for (q, window, warm_up) in [(0.15, 40, 30), (0.5, 7, 0), (1.0, 100, 0)] {
        let p = TrackerParams {
            score_quantile_floor: q,
            score_window: window,
            score_warm_up: warm_up,
            ..TrackerParams::default()
        };
        let mut s = ScoreScaler::new();
        let mut all: Vec<f64> = Vec::new();
        for _ in 0..25 {
            let scores: Vec<f64> = (0..5).map(|_| 0.5 + 0.5 * rng.next()).collect();
            let got = s.cuts(&p.score_reading(), p.score_thresholds(), &scores);
            all.extend(&scores);
            let last = &all[all.len().saturating_sub(window)..];
            let floor = if all.len() >= warm_up {
                brute_quantile(last, q)
            } else {
                f64::NEG_INFINITY
            };
            assert_eq!(got.det, p.det_threshold.max(floor));
            assert_eq!(got.new_track, p.new_track_threshold.max(floor));
            assert_eq!(got.low, p.low_threshold);
        }
    }
}

fn bx(cx: f64, cy: f64) -> [f64; 4] {
    [cx - 20.0, cy - 50.0, cx + 20.0, cy + 50.0]
}

fn track(p: TrackerParams, frames: &[(Vec<f64>, Vec<f64>)]) -> Vec<Vec<(u64, Option<usize>)>> {
    let mut t = Tracker::new(p).unwrap();
    frames
        .iter()
        .map(|(b, s)| {
            let out: Vec<TrackOutput> = t.update(b, s, None).unwrap();
            out.iter().map(|o| (o.id, o.det_index)).collect()
        })
        .collect()
}

#[test]
fn the_pure_tracker_reads_scores_as_given() {
    assert_eq!(TrackerParams::pure().score_quantile_floor, 0.0);
    assert_eq!(TrackerParams::pure().score_quantile_ceiling, 0.0);
    let mut s = ScoreScaler::new();
    s.observe(&[2.0, 4.0], 10);
    let pure = TrackerParams::pure();
    let q = s.cuts(&pure.score_reading(), pure.score_thresholds(), &[0.1]);
    assert_eq!(q, pure.score_thresholds());
    assert_eq!(q.det, f64::NEG_INFINITY);
}

#[test]
fn quantile_ceiling_lowers_starved_cuts_to_the_window_quantile_and_ratio_reading() {
    let mut rng = Lcg(17);
    // (score offset, width, ceiling c, floor q, window, warm-up): scores squeezed below the cuts,
    // as today, shifted up, and unbounded with negatives.
    for (lo, width, c, q, window, warm_up) in [
        (0.0, 0.3, 0.7, 0.0, 40, 30),
        (0.0, 1.0, 0.5, 0.15, 25, 0),
        (0.5, 0.5, 0.7, 0.0, 60, 10),
        (-3.0, 6.0, 0.9, 0.1, 7, 12),
        (0.0, 0.05, 1.0, 0.0, 100, 0),
    ] {
        let p = TrackerParams {
            score_quantile_ceiling: c,
            score_quantile_floor: q,
            score_window: window,
            score_warm_up: warm_up,
            ..TrackerParams::default()
        };
        let mut s = ScoreScaler::new();
        let mut all: Vec<f64> = Vec::new();
        let mut lowered = 0;
        for _ in 0..30 {
            let n = (rng.next() * 6.0) as usize;
            let scores: Vec<f64> = (0..n).map(|_| lo + width * rng.next()).collect();
            let got = s.cuts(&p.score_reading(), p.score_thresholds(), &scores);
            all.extend(&scores);
            if all.is_empty() {
                assert_eq!(got, p.score_thresholds());
                continue;
            }
            let last = &all[all.len().saturating_sub(window)..];
            let hi = all.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let floor_lo = all.iter().copied().fold(0.0, f64::min);
            let ratio = |t: f64| floor_lo + t * (hi - floor_lo);
            let warm = all.len() >= warm_up;
            let ceiling = if warm { brute_quantile(last, c) } else { hi };
            let floor = if warm && q > 0.0 {
                brute_quantile(last, q)
            } else {
                f64::NEG_INFINITY
            };
            let guard = |t: f64| {
                if ceiling < t {
                    t.min(ceiling).min(ratio(t))
                } else {
                    t
                }
            };
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1.0);
            let det = guard(p.det_threshold);
            lowered += usize::from(det < p.det_threshold);
            assert!(close(got.det, det.max(floor)));
            assert!(close(
                got.new_track,
                guard(p.new_track_threshold).max(floor)
            ));
            let low = if ceiling < p.det_threshold {
                p.low_threshold.min(ratio(p.low_threshold))
            } else {
                p.low_threshold
            };
            assert!(close(got.low, low));
        }
        // Squeezed scores lower the cuts; scores above them never do.
        if width <= 0.3 {
            assert!(lowered > 0, "offset {lo} width {width}");
        }
        if lo >= p.det_threshold {
            assert_eq!(lowered, 0, "offset {lo} width {width}");
        }
    }
}

/// `people` rows of walkers with scores in [0.4, 1) (the first one 1.0) and clutter boxes
/// scoring in [0.05, 0.3) (below the default cuts), each frame's scores multiplied by `gain`.
fn scaled_scene(gain: f64) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut rng = Lcg(29);
    (0..40)
        .map(|k| {
            let mut boxes = Vec::new();
            let mut scores = Vec::new();
            for p in 0..5 {
                boxes.extend(bx(
                    100.0 + 4.0 * k as f64 + 30.0 * p as f64,
                    150.0 * p as f64,
                ));
                let s = if k == 0 && p == 0 {
                    1.0
                } else {
                    0.4 + 0.6 * rng.next()
                };
                scores.push(gain * s);
            }
            for _ in 0..2 {
                boxes.extend(bx(2000.0 * rng.next(), 1000.0 * rng.next()));
                scores.push(gain * (0.05 + 0.25 * rng.next()));
            }
            (boxes, scores)
        })
        .collect()
}

#[test]
fn quantile_ceiling_tracks_a_detector_scaled_down_as_the_original() {
    // 0.25 is a power of two: the scaled scores and cuts are the original ones times 0.25
    // exactly, so the ratio reading of the scaled scores is the original cut exactly.
    let p = TrackerParams {
        motion: MotionKind::ConstantVelocity,
        n_init: 1,
        output_lost: 0,
        ..TrackerParams::default()
    };
    assert!(p.score_quantile_ceiling > 0.0, "on by default");
    let (frames, squeezed) = (scaled_scene(1.0), scaled_scene(0.25));
    let original = track(p.clone(), &frames);
    assert!(original.iter().all(|f| f.len() == 5), "{original:?}");
    assert_eq!(track(p.clone(), &squeezed), original);
    // Without the ceiling, every squeezed score (<= 0.25) is below the cuts: nothing is tracked.
    let old = TrackerParams {
        score_quantile_ceiling: 0.0,
        ..p
    };
    assert_eq!(track(old.clone(), &frames), original);
    assert!(track(old, &squeezed).iter().all(Vec::is_empty));
}

/// A walker's id at the first and the last frame of a scene from a detector that thresholds its
/// own output (every score >= 0.5, above det_threshold and new_track_threshold; `stray` adds one
/// far-away 0.1 detection in frame 1, so that the detector has low scores too): the
/// walker goes right at 5 px a frame, full boxes scored 0.98 among five bystanders at 0.97;
/// in frames 31-45 only its upper 45% is seen (the legs hidden), scored 0.8, the bottom of the
/// detector's scores, which the quantile floor keeps out of stages 1-2; it stops at frame 39,
/// and from frame 46 it is seen whole again.
fn walker_ids(thresholded_low_iou: f64, stray: bool) -> (u64, u64) {
    let (w, h) = (40.0, 100.0);
    let params = TrackerParams {
        thresholded_low_iou,
        ..TrackerParams::default()
    };
    let mut t = Tracker::new(params).unwrap();
    let mut ids = Vec::new();
    let mut x = 100.0;
    for frame in 1..=60u32 {
        if frame <= 38 {
            x += 5.0;
        }
        let hidden = (31..=45).contains(&frame);
        let walker = if hidden {
            [x, 200.0, x + w, 200.0 + 0.45 * h]
        } else {
            [x, 200.0, x + w, 200.0 + h]
        };
        let mut boxes: Vec<f64> = walker.to_vec();
        let mut scores = vec![if hidden { 0.8 } else { 0.98 }];
        for k in 0..5 {
            let bx = 600.0 + 120.0 * f64::from(k);
            boxes.extend([bx, 100.0, bx + w, 100.0 + h]);
            scores.push(0.97);
        }
        if stray && frame == 1 {
            boxes.extend([1500.0, 900.0, 1540.0, 1000.0]);
            scores.push(0.1);
        }
        let out = t.update(&boxes, &scores, None).unwrap();
        if let Some(o) = out.iter().find(|o| o.det_index == Some(0)) {
            ids.push(o.id);
        }
    }
    (ids[0], *ids.last().unwrap())
}

#[test]
fn a_thresholded_detectors_bottom_scores_extend_tracks_at_the_stage_2_overlap() {
    // The cut-short boxes overlap the walker's predicted box by IoU 0.45: below low_iou_threshold
    // (0.5), above iou_threshold (0.3).
    let p = TrackerParams::default();
    assert!(p.iou_threshold <= 0.45 && 0.45 < p.low_iou_threshold);
    assert_eq!(p.thresholded_low_iou, 0.3);
    // The rule on: the partly hidden walker is followed through its stop and keeps its id.
    let (first, last) = walker_ids(0.3, false);
    assert_eq!(first, last);
    // Off: its track coasts on past the stop, and the walker seen whole again gets a new id.
    let (first, last) = walker_ids(1.0, false);
    assert_ne!(first, last);
    // A detector that also gives low scores (one 0.1 ever) keeps ByteTrack's rule.
    let (first, last) = walker_ids(0.3, true);
    assert_ne!(first, last);
    assert_eq!(TrackerParams::pure().thresholded_low_iou, 1.0);
}
