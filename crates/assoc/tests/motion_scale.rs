//! The motion model's lengths in units of a person (`motion_person_height`): the same scene seen
//! at two image scales gives the same tracks, in scaled coordinates; in image pixels it does not.

use assoc::{TrackOutput, Tracker, TrackerParams};
use frvo::{MotionKind, MotionParams};

/// A pinhole camera 5 m above the ground looking at the horizon (row 100, focal 800, principal
/// column 640): the box of a 1.7 m person at lateral offset `x` and depth `z`, times `scale`.
fn person(x: f64, z: f64, scale: f64) -> [f64; 4] {
    let (u, foot, h) = (640.0 + 800.0 * x / z, 100.0 + 4000.0 / z, 1360.0 / z);
    [u - 0.2 * h, foot - h, u + 0.2 * h, foot].map(|v| v * scale)
}

/// The boxes of frame `k`: eight people walking across each other's paths at depths 6-20 m,
/// each missed by the detector in a few frames (so that lost tracks are predicted).
fn frame(k: usize, scale: f64) -> Vec<[f64; 4]> {
    let t = k as f64;
    (0..8)
        .filter(|&i| (k + 3 * i) % 7 != 0)
        .map(|i| {
            let f = i as f64;
            let dir = if i % 2 == 0 { 1.0 } else { -1.0 };
            person(
                dir * (-3.0 + 0.12 * t) + 0.4 * f,
                6.0 + 2.0 * f - 0.03 * dir * t,
                scale,
            )
        })
        .collect()
}

/// FRVO with a speed limit that binds (3 units per frame), lost tracks reported for 5 frames.
fn params(person_height: f64) -> TrackerParams {
    TrackerParams {
        motion: MotionKind::Frvo,
        n_init: 1,
        output_lost: 5,
        motion_person_height: person_height,
        motion_params: MotionParams {
            max_speed: 3.0,
            ..MotionParams::default()
        },
        ..TrackerParams::default()
    }
}

fn run(p: TrackerParams, scale: f64) -> Vec<Vec<TrackOutput>> {
    let mut t = Tracker::new(p).unwrap();
    (0..80)
        .map(|k| {
            let boxes = frame(k, scale);
            let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
            t.update(&flat, &vec![1.0; boxes.len()], None).unwrap()
        })
        .collect()
}

/// Largest distance between a reported box at scale 2, halved, and the one at scale 1 (same
/// id, same frame), in scale-1 pixels; `None` where the ids or counts differ.
fn largest_gap(p: TrackerParams) -> Option<f64> {
    let (one, two) = (run(p.clone(), 1.0), run(p, 2.0));
    let mut gap: f64 = 0.0;
    for (a, b) in one.iter().zip(&two) {
        if a.len() != b.len() {
            return None;
        }
        for (x, y) in a.iter().zip(b) {
            if x.id != y.id || x.det_index != y.det_index {
                return None;
            }
            for (u, v) in x.bbox.iter().zip(&y.bbox) {
                gap = gap.max((u - 0.5 * v).abs());
            }
        }
    }
    Some(gap)
}

#[test]
fn in_person_units_two_image_scales_give_the_same_tracks() {
    let gap = largest_gap(params(100.0));
    assert!(gap.is_some_and(|g| g < 1e-9), "{gap:?}");
}

#[test]
fn in_image_pixels_the_speed_limit_means_another_speed_at_another_scale() {
    let gap = largest_gap(params(0.0));
    assert!(gap.is_none_or(|g| g > 1.0), "{gap:?}");
}
