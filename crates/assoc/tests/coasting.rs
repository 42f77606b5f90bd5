//! Where an unmatched track is predicted and how its box is reported, against closed-form
//! expectations.

use assoc::{TrackOutput, Tracker, TrackerParams};
use frvo::MotionKind;

/// Constant velocity, confirmed at once, exact box sizes, lost tracks reported `output_lost`
/// frames.
fn params(output_lost: u32) -> TrackerParams {
    TrackerParams {
        motion: MotionKind::ConstantVelocity,
        n_init: 1,
        output_lost,
        size_smoothing: 0.0,
        ..TrackerParams::default()
    }
}

fn run(t: &mut Tracker, boxes: &[[f64; 4]]) -> Vec<TrackOutput> {
    let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
    t.update(&flat, &vec![1.0; boxes.len()], None).unwrap()
}

fn cx(b: &[f64; 4]) -> f64 {
    0.5 * (b[0] + b[2])
}

/// A person walking right at 4 px/frame, seen for frames 0-9 and then not: the centre reported
/// in each lost frame.
fn lost_centres() -> Vec<f64> {
    let mut t = Tracker::new(params(8)).unwrap();
    for k in 0..10 {
        let x = 100.0 + 4.0 * f64::from(k);
        run(&mut t, &[[x - 20.0, 50.0, x + 20.0, 150.0]]);
    }
    (0..8).map(|_| cx(&run(&mut t, &[])[0].bbox)).collect()
}

#[test]
fn a_lost_track_keeps_its_velocity() {
    let got = lost_centres();
    for (m, c) in got.iter().enumerate() {
        let want = 140.0 + 4.0 * m as f64;
        assert!((c - want).abs() < 1e-9, "lost frame {m}: {c} vs {want}");
    }
}

/// A person standing still, seen whole (40 x 100) for ten frames, then cut narrow (20 x 100)
/// for two, then missed: the reported box of the lost track.
fn narrowed_then_lost(coast_aspect: bool) -> [f64; 4] {
    let mut t = narrowed_tracker(coast_aspect, false);
    run(&mut t, &[])
        .first()
        .expect("the lost track is reported")
        .bbox
}

/// The tracker after the ten whole and two narrow frames.
fn narrowed_tracker(coast_aspect: bool, coast_aspect_state: bool) -> Tracker {
    let mut t = Tracker::new(TrackerParams {
        coast_aspect,
        coast_aspect_state,
        position_smoothing: 0.0,
        jitter_floor: 0.0,
        ..params(3)
    })
    .unwrap();
    for _ in 0..10 {
        run(&mut t, &[[100.0, 50.0, 140.0, 150.0]]);
    }
    for _ in 0..2 {
        run(&mut t, &[[110.0, 50.0, 130.0, 150.0]]);
    }
    t
}

#[test]
fn a_lost_track_is_reported_as_wide_as_its_mean_aspect_ratio() {
    // Mean width over height of the twelve matched boxes, times the height.
    let mean_aspect = (10.0 * 0.4 + 2.0 * 0.2) / 12.0;
    let b = narrowed_then_lost(true);
    assert!(((b[2] - b[0]) - mean_aspect * 100.0).abs() < 1e-9, "{b:?}");
    assert!(
        (cx(&b) - 120.0).abs() < 1e-9 && (b[3] - b[1] - 100.0).abs() < 1e-9,
        "{b:?}"
    );
    let narrow = narrowed_then_lost(false);
    assert!(((narrow[2] - narrow[0]) - 20.0).abs() < 1e-9, "{narrow:?}");
}

#[test]
fn with_coast_aspect_state_a_lost_track_is_matched_at_its_usual_width() {
    // Lost for two frames, the person reappears whole, 20 px to the right: IoU 0.2 with the
    // narrow prediction (below iou_threshold 0.3), 0.31 with the usual width's.
    let reappear = |state: bool| {
        let mut t = narrowed_tracker(true, state);
        let id = run(&mut t, &[[110.0, 50.0, 130.0, 150.0]])[0].id;
        run(&mut t, &[]);
        run(&mut t, &[]);
        let out = run(&mut t, &[[120.0, 50.0, 160.0, 150.0]]);
        out.iter().any(|o| o.id == id && o.det_index == Some(0))
    };
    assert!(reappear(true), "matched again at the usual width");
    assert!(!reappear(false), "the narrow prediction misses it");
}

/// Six people seen whole (40 x 100) and one seen only cut narrow (16 x 100), all standing still
/// for ten frames; then the narrow one is missed: its reported box in the lost frame.
fn cut_person_lost(coast_aspect_quantile: f64) -> [f64; 4] {
    let mut t = Tracker::new(TrackerParams {
        coast_aspect_quantile,
        ..params(3)
    })
    .unwrap();
    let whole: Vec<[f64; 4]> = (0..6)
        .map(|i| {
            let x = 100.0 + 80.0 * f64::from(i);
            [x, 300.0, x + 40.0, 400.0]
        })
        .collect();
    let cut = [592.0, 50.0, 608.0, 150.0];
    for _ in 0..10 {
        let mut frame = whole.clone();
        frame.push(cut);
        run(&mut t, &frame);
    }
    let out = run(&mut t, &whole);
    assert_eq!(out.len(), 7, "the six seen and the lost one reported");
    for (o, w) in out.iter().zip(&whole) {
        assert_eq!(o.bbox, *w, "a matched person's box is not widened");
    }
    out.iter()
        .find(|o| o.det_index.is_none())
        .expect("the lost track is reported")
        .bbox
}

#[test]
fn a_lost_track_is_reported_as_wide_as_the_people_seen_whole() {
    // Own mean aspect 0.16: reported 16 px wide without the rule.
    let narrow = cut_person_lost(0.0);
    assert!(((narrow[2] - narrow[0]) - 16.0).abs() < 1e-9, "{narrow:?}");
    // 70 aspects seen, 60 of them 0.4: the 0.9 quantile is 0.4, so 40 px, same centre and height.
    let b = cut_person_lost(0.9);
    assert!(((b[2] - b[0]) - 40.0).abs() < 1e-9, "{b:?}");
    assert!(
        (cx(&b) - 600.0).abs() < 1e-9 && (b[3] - b[1] - 100.0).abs() < 1e-9,
        "{b:?}"
    );
    // The 0.1 quantile is the narrow one's own 0.16: no wider than without the rule.
    let low = cut_person_lost(0.1);
    assert!(((low[2] - low[0]) - 16.0).abs() < 1e-9, "{low:?}");
}

/// Two people standing apart, one seen for ten frames and one for the last three of them, then
/// both missed: the ids reported in the first lost frame, (long-seen, young) each `Some` when
/// reported.
fn lost_after_hits(coast_min_hits: u32) -> (bool, bool) {
    let mut t = Tracker::new(TrackerParams {
        coast_min_hits,
        ..params(3)
    })
    .unwrap();
    let (old, young) = ([100.0, 50.0, 140.0, 150.0], [300.0, 50.0, 340.0, 150.0]);
    let mut ids = (0, 0);
    for k in 0..10 {
        let out = if k < 7 {
            run(&mut t, &[old])
        } else {
            run(&mut t, &[old, young])
        };
        // Matched tracks are reported whatever their age.
        assert_eq!(out.len(), if k < 7 { 1 } else { 2 }, "frame {k}");
        ids = (out[0].id, out.get(1).map_or(0, |o| o.id));
    }
    let out = run(&mut t, &[]);
    let shown = |id: u64| out.iter().any(|o| o.id == id && o.det_index.is_none());
    (shown(ids.0), shown(ids.1))
}

#[test]
fn a_young_lost_track_is_reported_only_after_enough_matches() {
    assert_eq!(lost_after_hits(0), (true, true), "off: both reported");
    // Ten matches and three: at 6 only the long-seen one is reported while lost.
    assert_eq!(lost_after_hits(6), (true, false));
    assert_eq!(
        lost_after_hits(3),
        (true, true),
        "three matches are enough for 3"
    );
    assert_eq!(lost_after_hits(11), (false, false));
}
