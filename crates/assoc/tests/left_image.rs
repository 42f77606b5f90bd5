//! An unmatched track whose predicted box lies partly outside the image is judged to have left
//! (deleted, no longer reported) once less than 90% of it is inside.

use assoc::{TrackOutput, Tracker, TrackerParams};
use frvo::MotionKind;

fn params() -> TrackerParams {
    TrackerParams {
        motion: MotionKind::ConstantVelocity,
        n_init: 1,
        size_smoothing: 0.0,
        position_smoothing: 0.0,
        output_lost: 5,
        output_lost_adaptive: false,
        coast_min_hits: 0,
        ..TrackerParams::default()
    }
}

fn bx(x1: f64) -> [f64; 4] {
    [x1, 50.0, x1 + 40.0, 150.0]
}

fn run(t: &mut Tracker, boxes: &[[f64; 4]]) -> Vec<TrackOutput> {
    let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
    t.update(&flat, &vec![1.0; boxes.len()], None).unwrap()
}

/// One person walks right at 8 px a frame, last seen at `last_x1` (box 40 px wide, image 640 px
/// wide), beside a second person standing still in the middle of the image and detected
/// throughout; returns, per frame after the walker's last detection, whether the walker is
/// still a live track and whether it is reported.
fn walk(last_x1: f64, frames: usize) -> Vec<(bool, bool)> {
    let mut t = Tracker::new(params()).unwrap();
    t.set_image_size(640.0, 480.0).unwrap();
    let still = bx(300.0);
    let mut walker_id = 0;
    for k in (0..8).rev() {
        let out = run(&mut t, &[bx(last_x1 - 8.0 * f64::from(k)), still]);
        walker_id = out.iter().find(|o| o.bbox[0] != still[0]).unwrap().id;
    }
    (0..frames)
        .map(|_| {
            let out = run(&mut t, &[still]);
            let reported = out.iter().any(|o| o.id == walker_id);
            (t.num_tracks() == 2, reported)
        })
        .collect()
}

#[test]
fn a_track_leaving_the_image_is_deleted_from_the_share_inside() {
    // Last seen at x 600..640, touching the right edge; predicted at 608..648 (80% inside): left.
    assert_eq!(walk(600.0, 4), vec![(false, false); 4]);
    // Last seen at x 560..600: predicted at 568..608 (wholly inside), 576..616 (also inside),
    // 584..624 and 592..632 (inside): kept and reported (output_lost).
    assert_eq!(walk(560.0, 4), vec![(true, true); 4]);
    // Last seen at x 564..604: predicted at 572..612, 580..620, 588..628, 596..636 (inside),
    // then 604..644 (90% inside: kept), 612..652 (70%: left).
    assert_eq!(
        walk(564.0, 6),
        vec![
            (true, true),
            (true, true),
            (true, true),
            (true, true),
            (true, true),
            (false, false)
        ]
    );
    assert_eq!(walk(400.0, 3), vec![(true, true); 3]);
}

#[test]
fn without_an_image_size_or_scene_reasoning_nothing_leaves() {
    let mut t = Tracker::new(TrackerParams {
        occluded_output: 0,
        ..params()
    })
    .unwrap();
    t.set_image_size(640.0, 480.0).unwrap();
    for k in (0..8).rev() {
        run(&mut t, &[bx(600.0 - 8.0 * f64::from(k))]);
    }
    run(&mut t, &[]);
    assert_eq!(t.num_tracks(), 1, "occluded_output 0: no scene reasoning");
    let mut t = Tracker::new(params()).unwrap();
    for k in (0..8).rev() {
        run(&mut t, &[bx(600.0 - 8.0 * f64::from(k))]);
    }
    run(&mut t, &[]);
    assert_eq!(t.num_tracks(), 1, "no image size");
}
