//! Tentative tracks that miss a frame (`tentative_max_age`): a person seen once with confidence,
//! missed, then seen only weakly is confirmed from the weak detections; a confident detection
//! left over starts its own track instead; a waiting tentative track does not move its
//! neighbours' predictions.

use assoc::{TrackOutput, Tracker, TrackerParams};

const CONFIDENT: f64 = 0.9;
/// Inside the second pass's band: `low_threshold` (0.05) <= score < `det_threshold` (0.3).
const WEAK: f64 = 0.2;

fn person(cx: f64, cy: f64) -> [f64; 4] {
    [cx - 20.0, cy - 50.0, cx + 20.0, cy + 50.0]
}

/// Frames of a scene: five confident bystanders standing still far from the walker (so that most
/// scores pass the cuts and no quantile rule moves them), and the walker, going right at 3 px a
/// frame from x = 100: confident in frame 1, missed in frame 2, then `later` per frame.
fn scene(later: f64, frames: u32) -> Vec<(Vec<[f64; 4]>, Vec<f64>)> {
    (1..=frames)
        .map(|f| {
            let mut boxes: Vec<[f64; 4]> = (0..5)
                .map(|k| person(600.0 + 120.0 * f64::from(k), 300.0))
                .collect();
            let mut scores = vec![CONFIDENT; 5];
            let x = 100.0 + 3.0 * f64::from(f - 1);
            match f {
                1 => scores.push(CONFIDENT),
                2 => {}
                _ => scores.push(later),
            }
            if f != 2 {
                boxes.push(person(x, 300.0));
            }
            (boxes, scores)
        })
        .collect()
}

fn track(params: TrackerParams, frames: &[(Vec<[f64; 4]>, Vec<f64>)]) -> Vec<Vec<TrackOutput>> {
    let mut t = Tracker::new(params).unwrap();
    frames
        .iter()
        .map(|(boxes, scores)| {
            let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
            t.update(&flat, scores, None).unwrap()
        })
        .collect()
}

/// Per frame, the id reported on the walker's detection (index 5), if any.
fn walker_ids(out: &[Vec<TrackOutput>]) -> Vec<Option<u64>> {
    out.iter()
        .map(|f| f.iter().find(|o| o.det_index == Some(5)).map(|o| o.id))
        .collect()
}

fn with_age(tentative_max_age: u32) -> TrackerParams {
    TrackerParams {
        tentative_max_age,
        ..TrackerParams::default()
    }
}

#[test]
fn a_person_seen_once_then_only_weakly_is_confirmed_from_the_weak_detections() {
    let p = TrackerParams::default();
    assert_eq!(p.tentative_max_age, 2);
    assert!(p.low_threshold <= WEAK && WEAK < p.det_threshold && CONFIDENT >= p.det_threshold);
    let frames = scene(WEAK, 12);
    let ids = walker_ids(&track(with_age(2), &frames));
    // Frame 3's weak detection is the tentative track's second match: reported from then on,
    // always under one id.
    assert_eq!(ids[..2], [None, None]);
    let first = ids[2].expect("reported at frame 3");
    assert!(ids[2..].iter().all(|&i| i == Some(first)), "{ids:?}");
    // Without: the tentative track ends at its miss, and weak detections start no track.
    let ids = walker_ids(&track(with_age(0), &frames));
    assert!(ids.iter().all(Option::is_none), "{ids:?}");
    assert_eq!(TrackerParams::pure().tentative_max_age, 0);
}

#[test]
fn a_confident_detection_left_over_starts_its_own_track() {
    // Confident again from frame 3: a new tentative track starts there (the waiting one takes
    // only weak detections), confirmed at frame 4, as without the rule.
    let frames = scene(CONFIDENT, 8);
    let with = walker_ids(&track(with_age(2), &frames));
    let without = walker_ids(&track(with_age(0), &frames));
    assert_eq!(with[..3], [None, None, None]);
    assert!(with[3..].iter().all(Option::is_some), "{with:?}");
    assert_eq!(with, without);
}

#[test]
fn a_waiting_tentative_track_does_not_move_its_neighbours() {
    // A second walker comes at the first one's place from the right, 4 px a frame: while the
    // first one's tentative track waits (frame 3's prediction), the motion model must not make
    // the second one yield to it.
    let frames: Vec<(Vec<[f64; 4]>, Vec<f64>)> = (1..=3u32)
        .map(|f| {
            let x = 140.0 - 4.0 * f64::from(f - 1);
            let mut boxes: Vec<[f64; 4]> = (0..5)
                .map(|k| person(600.0 + 120.0 * f64::from(k), 300.0))
                .collect();
            boxes.push(person(x, 300.0));
            let mut scores = vec![CONFIDENT; 6];
            if f != 2 {
                boxes.push(person(100.0, 300.0));
                scores.push(CONFIDENT);
            }
            (boxes, scores)
        })
        .collect();
    // The second walker is tentative in frame 1 and confirmed in frame 2: compare its reported
    // box in frame 3, which comes from frame 3's prediction (position smoothing).
    let reported = |age: u32| {
        let out = track(with_age(age), &frames);
        let o = out[2].iter().find(|o| o.det_index == Some(5)).copied();
        o.expect("the second walker is reported").bbox
    };
    assert_eq!(reported(2), reported(0));
}

/// The walker's reported ids from a detector that thresholds its own output (every score >= 0.3,
/// `det_threshold` as given): seven bystanders, five at 0.97 and two at 0.5, so that after
/// warm-up the quantile floor lifts the cuts to 0.5; the walker appears at frame 31 at 0.9, is
/// missed at frame 32 and is then scored 0.35, under the lifted cut. `stray` adds one 0.1 score
/// at frame 1: the detector then gives low scores too.
fn thresholded_walker(stray: bool) -> Vec<Option<u64>> {
    let mut t = Tracker::new(TrackerParams::default()).unwrap();
    let mut ids = Vec::new();
    for f in 1..=45u32 {
        let mut boxes: Vec<[f64; 4]> = (0..7)
            .map(|k| person(600.0 + 120.0 * f64::from(k), 300.0))
            .collect();
        let mut scores = vec![0.97, 0.97, 0.97, 0.97, 0.97, 0.5, 0.5];
        if f >= 31 && f != 32 {
            boxes.push(person(100.0 + 3.0 * f64::from(f), 300.0));
            scores.push(if f == 31 { 0.9 } else { 0.35 });
        }
        if stray && f == 1 {
            boxes.push(person(2000.0, 900.0));
            scores.push(0.1);
        }
        let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
        let out = t.update(&flat, &scores, None).unwrap();
        if f >= 31 {
            ids.push(out.iter().find(|o| o.det_index == Some(7)).map(|o| o.id));
        }
    }
    ids
}

#[test]
fn from_a_thresholded_detector_every_detection_is_confident() {
    // Seen at 0.35 by a detector that also scores 0.1: weak, so the waiting track takes it.
    let ids = thresholded_walker(true);
    assert!(ids[2..].iter().all(Option::is_some), "{ids:?}");
    // From a detector cut at 0.3, the 0.35 detections are ones the quantile floor held back, not
    // weak ones: the waiting track does not take them (nor do they start tracks).
    let ids = thresholded_walker(false);
    assert!(ids.iter().all(Option::is_none), "{ids:?}");
}
