//! Camera motion from the boxes (`camera_motion_min_tracks`): when the camera pans, a person the
//! detector misses is predicted where the scene moved them; on a still camera nothing changes.

use assoc::cost::iou;
use assoc::{TrackOutput, Tracker, TrackerParams};

/// One frame: the detections and every person's true box.
type Frame = (Vec<[f64; 4]>, Vec<[f64; 4]>);

fn person(cx: f64, cy: f64) -> [f64; 4] {
    [cx - 20.0, cy - 50.0, cx + 20.0, cy + 50.0]
}

/// Frames of six people standing still 150 px apart, seen by a camera that pans `pan` px a frame
/// from frame 40 on; person 0 is missed from frame 40. Each frame: detections and the true boxes.
fn scene(pan: f64, frames: u32) -> Vec<Frame> {
    (1..=frames)
        .map(|f| {
            let dx = pan * f64::from(f.saturating_sub(39));
            let truth: Vec<[f64; 4]> = (0..6)
                .map(|k| person(100.0 + 150.0 * f64::from(k) - dx, 300.0))
                .collect();
            let seen = if f >= 40 {
                truth[1..].to_vec()
            } else {
                truth.clone()
            };
            (seen, truth)
        })
        .collect()
}

fn track(min_tracks: u32, frames: &[Frame]) -> Vec<Vec<TrackOutput>> {
    let mut t = Tracker::new(TrackerParams {
        camera_motion_min_tracks: min_tracks,
        ..TrackerParams::default()
    })
    .unwrap();
    frames
        .iter()
        .map(|(boxes, _)| {
            let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
            t.update(&flat, &vec![0.9; boxes.len()], None).unwrap()
        })
        .collect()
}

/// Per frame from 40 on, the IoU of person 0's reported box with their true box (0 when not
/// reported).
fn lost_overlap(out: &[Vec<TrackOutput>], frames: &[Frame]) -> Vec<f64> {
    let id = out[38]
        .iter()
        .find(|o| o.det_index == Some(0))
        .expect("person 0 tracked")
        .id;
    (39..44)
        .map(|f| {
            out[f]
                .iter()
                .find(|o| o.id == id)
                .map_or(0.0, |o| iou(&o.bbox, &frames[f].1[0]))
        })
        .collect()
}

#[test]
fn a_lost_person_stays_on_the_panning_scene_only_with_the_correction() {
    let frames = scene(6.0, 45);
    let with = lost_overlap(&track(3, &frames), &frames);
    let without = lost_overlap(&track(0, &frames), &frames);
    // Five frames lost: 30 px of pan. Without the correction the box stays where the person
    // was; with it, it follows the others.
    assert!(with.iter().all(|&o| o > 0.7), "with: {with:?}");
    assert!(without[4] < 0.3, "without: {without:?}");
    assert_eq!(TrackerParams::pure().camera_motion_min_tracks, 0);
}

#[test]
fn a_still_camera_changes_nothing() {
    let frames = scene(0.0, 60);
    assert_eq!(track(3, &frames), track(0, &frames));
}
