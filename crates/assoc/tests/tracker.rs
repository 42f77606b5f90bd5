//! Tracker behaviour: lifecycle, crossing, appearance stage, options, determinism, bad input.

use assoc::{Embeddings, ParamValue, TrackError, TrackOutput, Tracker, TrackerParams};
use frvo::MotionKind;

/// Defaults with constant velocity and only matched tracks reported (the lifecycle tests count
/// reported tracks).
/// Constant velocity, lost tracks not reported; when a test reports them, whatever their number
/// of matches (the scenes' tracks are short).
fn cv_params() -> TrackerParams {
    TrackerParams {
        motion: MotionKind::ConstantVelocity,
        output_lost: 0,
        coast_min_hits: 0,
        ..TrackerParams::default()
    }
}

fn bx(cx: f64, cy: f64) -> [f64; 4] {
    [cx - 20.0, cy - 50.0, cx + 20.0, cy + 50.0]
}

fn run(t: &mut Tracker, boxes: &[[f64; 4]]) -> Vec<TrackOutput> {
    let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
    let scores = vec![1.0; boxes.len()];
    t.update(&flat, &scores, None).unwrap()
}

#[test]
fn tentative_until_n_init_then_deleted_after_max_age() {
    let mut t = Tracker::new(TrackerParams {
        n_init: 3,
        max_age: 2,
        ..cv_params()
    })
    .unwrap();
    assert!(run(&mut t, &[bx(100.0, 100.0)]).is_empty());
    assert!(run(&mut t, &[bx(101.0, 100.0)]).is_empty());
    let out = run(&mut t, &[bx(102.0, 100.0)]);
    assert_eq!(out.len(), 1);
    assert_eq!((out[0].id, out[0].det_index), (1, Some(0)));
    // Unmatched for max_age frames: kept (not reported); one more: deleted.
    assert!(run(&mut t, &[]).is_empty());
    assert!(run(&mut t, &[]).is_empty());
    assert_eq!(t.num_tracks(), 1);
    assert!(run(&mut t, &[]).is_empty());
    assert_eq!(t.num_tracks(), 0);
}

#[test]
fn lost_track_is_recovered_within_max_age_with_same_id() {
    let mut t = Tracker::new(TrackerParams {
        n_init: 1,
        max_age: 5,
        ..cv_params()
    })
    .unwrap();
    for k in 0..5 {
        run(&mut t, &[bx(100.0 + 4.0 * f64::from(k), 100.0)]);
    }
    run(&mut t, &[]);
    run(&mut t, &[]);
    // The prediction kept moving at 4 px/frame, so the detection at frame 8 still overlaps.
    let out = run(&mut t, &[bx(100.0 + 4.0 * 7.0, 100.0)]);
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].id, 1);
}

#[test]
fn unmatched_tentative_track_is_dropped_after_tentative_max_age() {
    let mut t = Tracker::new(TrackerParams {
        tentative_max_age: 0,
        ..cv_params()
    })
    .unwrap();
    run(&mut t, &[bx(100.0, 100.0)]);
    run(&mut t, &[]);
    assert_eq!(t.num_tracks(), 0);
    let mut t = Tracker::new(cv_params()).unwrap();
    assert_eq!(t.params().tentative_max_age, 2);
    run(&mut t, &[bx(100.0, 100.0)]);
    run(&mut t, &[]);
    run(&mut t, &[]);
    assert_eq!(t.num_tracks(), 1);
    run(&mut t, &[]);
    assert_eq!(t.num_tracks(), 0);
}

fn crossing_frames() -> Vec<Vec<[f64; 4]>> {
    // Two people walking towards each other, boxes overlapping heavily when they cross.
    (0..60)
        .map(|k| {
            let k = f64::from(k);
            vec![bx(100.0 + 6.0 * k, 200.0), bx(460.0 - 6.0 * k, 215.0)]
        })
        .collect()
}

#[test]
fn two_crossing_tracks_keep_their_ids_with_constant_velocity() {
    let mut t = Tracker::new(TrackerParams {
        n_init: 1,
        ..cv_params()
    })
    .unwrap();
    for (k, frame) in crossing_frames().iter().enumerate() {
        let out = run(&mut t, frame);
        assert_eq!(out.len(), 2, "frame {k}");
        // Detection 0 is always the left-to-right walker, who got id 1.
        for o in &out {
            assert_eq!(o.det_index, Some(o.id as usize - 1), "frame {k}: {out:?}");
        }
    }
}

#[test]
fn appearance_stage_resolves_a_swap_that_iou_gets_wrong() {
    // Two people side by side; in frame 3 the detections come in swapped order *and* positions
    // jump so that IoU alone would swap the ids; embeddings tell them apart.
    let mut t = Tracker::new(TrackerParams {
        n_init: 1,
        gate_radius: 2.0,
        ..cv_params()
    })
    .unwrap();
    let ea = [1.0f32, 0.0, 0.0];
    let eb = [0.0f32, 1.0, 0.0];
    let step = |t: &mut Tracker, boxes: &[[f64; 4]], emb: &[f32]| {
        let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
        t.update(
            &flat,
            &vec![1.0; boxes.len()],
            Some(Embeddings { data: emb, dim: 3 }),
        )
        .unwrap()
    };
    let both = [ea, eb].concat();
    step(&mut t, &[bx(100.0, 100.0), bx(130.0, 100.0)], &both);
    step(&mut t, &[bx(100.0, 100.0), bx(130.0, 100.0)], &both);
    // A moved right to 128, B moved left to 102: IoU favours keeping places, appearance does not.
    let out = step(&mut t, &[bx(128.0, 100.0), bx(102.0, 100.0)], &both);
    let id_of = |j: usize| out.iter().find(|o| o.det_index == Some(j)).unwrap().id;
    assert_eq!((id_of(0), id_of(1)), (1, 2));
    // Without embeddings the motion-only tracker swaps them (documents why stage 1 exists).
    let mut m = Tracker::new(TrackerParams {
        n_init: 1,
        ..cv_params()
    })
    .unwrap();
    run(&mut m, &[bx(100.0, 100.0), bx(130.0, 100.0)]);
    run(&mut m, &[bx(100.0, 100.0), bx(130.0, 100.0)]);
    let out = run(&mut m, &[bx(128.0, 100.0), bx(102.0, 100.0)]);
    let id_of = |j: usize| out.iter().find(|o| o.det_index == Some(j)).unwrap().id;
    assert_eq!((id_of(0), id_of(1)), (2, 1));
}

#[test]
fn same_input_gives_same_ids() {
    let frames: Vec<Vec<[f64; 4]>> = (0..40)
        .map(|k| {
            (0..30)
                .filter(|p| (p * 7 + k) % 11 != 0)
                .map(|p| {
                    let p = f64::from(p);
                    let k = f64::from(k);
                    bx(50.0 * p + 2.0 * k, 100.0 + 30.0 * (p % 3.0) + k)
                })
                .collect()
        })
        .collect();
    let run_all = || {
        let mut t = Tracker::new(TrackerParams::default()).unwrap();
        frames.iter().map(|f| run(&mut t, f)).collect::<Vec<_>>()
    };
    let a = run_all();
    assert!(a.iter().any(|o| !o.is_empty()));
    assert_eq!(a, run_all());
    // reset() restarts ids.
    let mut t = Tracker::new(TrackerParams::default()).unwrap();
    let first: Vec<_> = frames.iter().map(|f| run(&mut t, f)).collect();
    t.reset();
    let second: Vec<_> = frames.iter().map(|f| run(&mut t, f)).collect();
    assert_eq!(first, second);
}

#[test]
fn second_pass_uses_low_score_detections_only_when_enabled() {
    let make = |second_pass| {
        Tracker::new(TrackerParams {
            n_init: 1,
            det_threshold: 0.5,
            second_pass,
            low_threshold: 0.1,
            ..cv_params()
        })
        .unwrap()
    };
    for (second_pass, expect) in [(false, 0usize), (true, 1)] {
        let mut t = make(second_pass);
        t.update(&bx(100.0, 100.0), &[0.9], None).unwrap();
        let out = t.update(&bx(101.0, 100.0), &[0.3], None).unwrap();
        assert_eq!(out.len(), expect, "second_pass={second_pass}");
        // A low-score detection never starts a track.
        assert_eq!(t.num_tracks(), 1);
    }
}

#[test]
fn second_pass_reaches_tracks_lost_up_to_low_max_age() {
    // A confirmed track misses two frames, then only a low-score detection (0.2, under
    // det_threshold 0.3) sits on its prediction: it extends the track when the second pass
    // covers tracks lost for 2 frames, and otherwise is dropped (it may not start a track).
    for (low_max_age, expect) in [(0u32, None), (1, None), (2, Some(1u64)), (60, Some(1))] {
        let mut t = Tracker::new(TrackerParams {
            n_init: 2,
            low_max_age,
            ..cv_params()
        })
        .unwrap();
        for k in 0..3 {
            run(&mut t, &[bx(100.0 + 2.0 * f64::from(k), 100.0)]);
        }
        run(&mut t, &[]);
        run(&mut t, &[]);
        let out = t.update(&bx(110.0, 100.0), &[0.2], None).unwrap();
        assert_eq!(
            out.first().map(|o| o.id),
            expect,
            "low_max_age={low_max_age}"
        );
        assert_eq!(t.num_tracks(), 1, "low_max_age={low_max_age}");
    }
}

#[test]
fn low_score_detections_start_no_track_by_default_but_do_in_the_pure_form() {
    let low = bx(100.0, 100.0);
    // A detector seen so far scoring only 0.1 is read on its own scale by the quantile ceiling
    // (tests/score_scale.rs); here a 0.1 beside a 0.9 is a low score.
    let with_high = [low, bx(400.0, 100.0)].concat();
    for (params, expect) in [
        (TrackerParams::default(), 1usize),
        (TrackerParams::pure(), 2),
    ] {
        let mut t = Tracker::new(TrackerParams {
            n_init: 1,
            ..params
        })
        .unwrap();
        let out = t.update(&with_high, &[0.1, 0.9], None).unwrap();
        assert_eq!((out.len(), t.num_tracks()), (expect, expect));
    }
}

#[test]
fn output_lost_reports_coasting_tracks_at_their_prediction() {
    let mut t = Tracker::new(TrackerParams {
        n_init: 1,
        output_lost: 2,
        size_smoothing: 0.0,
        ..cv_params()
    })
    .unwrap();
    run(&mut t, &[bx(100.0, 100.0)]);
    run(&mut t, &[bx(104.0, 100.0)]);
    for k in 1..=2 {
        let out = run(&mut t, &[]);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].det_index, None);
        // Constant velocity: 4 px/frame on from the last match.
        let cx = 0.5 * (out[0].bbox[0] + out[0].bbox[2]);
        assert!((cx - (104.0 + 4.0 * f64::from(k))).abs() < 1e-9, "cx {cx}");
    }
    assert!(run(&mut t, &[]).is_empty());
}

#[test]
fn recovery_rematches_by_last_observation() {
    // The track moved fast, then stopped while unseen: its prediction overshoots, but the last
    // observation still overlaps the new detection.
    let make = |recovery| {
        Tracker::new(TrackerParams {
            n_init: 1,
            recovery,
            ..cv_params()
        })
        .unwrap()
    };
    for (recovery, expect_id) in [(false, 2u64), (true, 1)] {
        let mut t = make(recovery);
        for k in 0..4 {
            run(&mut t, &[bx(100.0 + 15.0 * f64::from(k), 100.0)]);
        }
        for _ in 0..3 {
            run(&mut t, &[]);
        }
        let out = run(&mut t, &[bx(150.0, 100.0)]);
        assert_eq!(out[0].id, expect_id, "recovery={recovery}");
    }
}

#[test]
fn bad_input_is_rejected_without_changing_state() {
    let mut t = Tracker::new(cv_params()).unwrap();
    let e = |r: Result<Vec<TrackOutput>, TrackError>| {
        assert!(matches!(r, Err(TrackError::InvalidInput(_))), "{r:?}")
    };
    e(t.update(&[0.0, 0.0, 1.0], &[1.0], None));
    e(t.update(&[0.0, 0.0, 1.0, 1.0], &[1.0, 2.0], None));
    e(t.update(&[0.0, 0.0, f64::INFINITY, 1.0], &[1.0], None));
    e(t.update(&[5.0, 0.0, 1.0, 1.0], &[1.0], None));
    e(t.update(&[0.0, 0.0, 1.0, 1.0], &[f64::NAN], None));
    let emb = |data: &'static [f32], dim| Some(Embeddings { data, dim });
    e(t.update(&[0.0, 0.0, 1.0, 1.0], &[1.0], emb(&[1.0, 2.0, 3.0], 2)));
    e(t.update(&[0.0, 0.0, 1.0, 1.0], &[1.0], emb(&[f32::NAN, 2.0], 2)));
    e(t.update(&[0.0, 0.0, 1.0, 1.0], &[1.0], emb(&[], 0)));
    assert_eq!(t.frame_count(), 0);
    t.update(&[0.0, 0.0, 1.0, 1.0], &[1.0], emb(&[1.0, 2.0], 2))
        .unwrap();
    e(t.update(&[0.0, 0.0, 1.0, 1.0], &[1.0], emb(&[1.0, 2.0, 3.0], 3)));
    // Frames without embeddings are fine after frames with them.
    t.update(&[0.0, 0.0, 1.0, 1.0], &[1.0], None).unwrap();
    // Scores have no range: negative and large values are valid.
    t.update(
        &[0.0, 0.0, 1.0, 1.0, 3.0, 3.0, 4.0, 4.0],
        &[-3.5, 93.7],
        None,
    )
    .unwrap();
}

#[test]
fn parameters_are_validated_and_settable_by_name() {
    let bad = |f: fn(&mut TrackerParams)| {
        let mut p = TrackerParams::default();
        f(&mut p);
        assert!(matches!(
            Tracker::new(p),
            Err(TrackError::InvalidParameter(_))
        ));
    };
    bad(|p| p.n_init = 0);
    bad(|p| p.iou_threshold = 1.5);
    bad(|p| p.appearance_threshold = -0.1);
    bad(|p| p.gate_radius = 0.0);
    bad(|p| p.gallery_size = 0);
    bad(|p| p.det_threshold = f64::NAN);
    bad(|p| p.size_smoothing = 1.0);
    bad(|p| p.motion_params.max_speed = -1.0);
    let mut p = TrackerParams::default();
    assert!(p.set("nope", ParamValue::Float(1.0)).is_err());
    assert!(p.set("n_init", ParamValue::Float(1.5)).is_err());
    assert!(p.set("n_init", ParamValue::Int(-1)).is_err());
    assert!(p.set("recovery", ParamValue::Int(1)).is_err());
    p.set("n_init", ParamValue::Int(5)).unwrap();
    p.set("recovery", ParamValue::Bool(true)).unwrap();
    p.set("iou_threshold", ParamValue::Int(0)).unwrap();
    p.set("neighbor_radius", ParamValue::Float(80.0)).unwrap();
    assert_eq!(p.get("n_init"), Some(ParamValue::Int(5)));
    assert_eq!(p.get("recovery"), Some(ParamValue::Bool(true)));
    assert_eq!(p.get("iou_threshold"), Some(ParamValue::Float(0.0)));
    assert_eq!(p.motion_params.neighbor_radius, 80.0);
    for spec in assoc::PARAMS {
        let v = p.get(spec.name).unwrap();
        p.set(spec.name, v).unwrap();
    }
}

/// Constant velocity, tracks confirmed at once, lost tracks reported for one frame, scene
/// reasoning on with `occluded_output` frames.
fn occlusion_params(occluded_output: u32) -> TrackerParams {
    TrackerParams {
        n_init: 1,
        output_lost: 1,
        occluded_output,
        size_smoothing: 0.0,
        ..cv_params()
    }
}

/// A far person (feet at y = 150) walks right at 4 px/frame behind a near, bigger person
/// standing at x = 200 (feet at y = 230); `seen(k)` says whether the far one is detected.
fn behind_scene(t: &mut Tracker, frames: u32, seen: impl Fn(u32) -> bool) -> Vec<Vec<TrackOutput>> {
    let near = [170.0, 40.0, 230.0, 230.0];
    (0..frames)
        .map(|k| {
            let far = bx(140.0 + 4.0 * f64::from(k), 100.0);
            let boxes: Vec<[f64; 4]> = if seen(k) { vec![near, far] } else { vec![near] };
            run(t, &boxes)
        })
        .collect()
}

#[test]
fn occluded_track_is_reported_at_its_prediction_and_reattached_with_its_id() {
    // Hidden behind the near person for frames 10-22 (13 frames), seen again from frame 23.
    let seen = |k: u32| !(10..23).contains(&k);
    let mut t = Tracker::new(occlusion_params(30)).unwrap();
    t.set_image_size(640.0, 480.0).unwrap();
    let outs = behind_scene(&mut t, 30, seen);
    let far_id = outs[0].iter().find(|o| o.bbox[3] == 150.0).unwrap().id;
    for (k, out) in outs.iter().enumerate() {
        let far = out.iter().find(|o| o.id == far_id);
        let far = far.unwrap_or_else(|| panic!("far person not reported in frame {k}"));
        // Reported where constant velocity puts them, matched or not.
        let cx = 0.5 * (far.bbox[0] + far.bbox[2]);
        assert!(
            (cx - (140.0 + 4.0 * k as f64)).abs() < 1e-6,
            "frame {k}: cx {cx}"
        );
        assert_eq!(far.det_index.is_some(), seen(k as u32), "frame {k}");
    }
    assert_eq!(outs[29].len(), 2);
}

#[test]
fn without_scene_reasoning_an_occluded_track_is_reported_only_output_lost_frames() {
    let seen = |k: u32| !(10..23).contains(&k);
    let mut t = Tracker::new(occlusion_params(0)).unwrap();
    let outs = behind_scene(&mut t, 30, seen);
    // Frame 10 is the one lost frame reported; 11-22 only the near person.
    assert_eq!(outs[10].len(), 2);
    assert!(outs[11..23].iter().all(|o| o.len() == 1));
    // Re-attached with its id all the same (the track lived on unreported).
    assert_eq!(outs[23].len(), 2);
    assert_eq!(outs[23][1].id, outs[0][1].id);
}

#[test]
fn occluded_output_is_bounded() {
    let seen = |k: u32| k < 10;
    let mut t = Tracker::new(occlusion_params(5)).unwrap();
    t.set_image_size(640.0, 480.0).unwrap();
    let outs = behind_scene(&mut t, 20, seen);
    // Unmatched from frame 10: reported while covered for 5 frames (10-14), then not.
    assert!(outs[10..15].iter().all(|o| o.len() == 2));
    assert!(outs[15..20].iter().all(|o| o.len() == 1));
}

#[test]
fn a_track_with_nothing_in_front_is_not_kept_as_occluded() {
    // The far person vanishes in the open (no one in front): reported only `output_lost` frames.
    let mut t = Tracker::new(occlusion_params(30)).unwrap();
    t.set_image_size(640.0, 480.0).unwrap();
    for k in 0..10 {
        run(&mut t, &[bx(400.0 + 4.0 * f64::from(k), 100.0)]);
    }
    assert_eq!(run(&mut t, &[]).len(), 1);
    assert!(run(&mut t, &[]).is_empty());
    assert_eq!(t.num_tracks(), 1, "kept alive (unreported) until max_age");
}

/// A person walks right at 8 px/frame until their box touches the right edge of a 640 px wide
/// image, then is no longer detected; returns the live tracks after each of 4 empty frames.
fn walk_out(occluded_output: u32, image_size: bool) -> Vec<usize> {
    let mut t = Tracker::new(occlusion_params(occluded_output)).unwrap();
    if image_size {
        t.set_image_size(640.0, 480.0).unwrap();
    }
    for k in 0..8 {
        run(&mut t, &[bx(564.0 + 8.0 * f64::from(k), 100.0)]); // last box: x 600..640
    }
    (0..4)
        .map(|_| {
            run(&mut t, &[]);
            t.num_tracks()
        })
        .collect()
}

#[test]
fn a_track_that_leaves_the_image_is_deleted() {
    // Predicted box: x 608..648, 80% inside (below 90%: left).
    assert_eq!(walk_out(30, true), vec![0, 0, 0, 0]);
    // Without an image size nothing is judged to have left.
    assert_eq!(walk_out(30, false), vec![1, 1, 1, 1]);
    // Without scene reasoning the track lives on until max_age.
    assert_eq!(walk_out(0, true), vec![1, 1, 1, 1]);
}

#[test]
fn image_size_is_validated() {
    let mut t = Tracker::new(TrackerParams::default()).unwrap();
    assert!(t.set_image_size(0.0, 480.0).is_err());
    assert!(t.set_image_size(640.0, f64::NAN).is_err());
    assert!(t.set_image_size(640.0, 480.0).is_ok());
}

/// Walkers at 4 px/frame, one per row, each seen for 6 frames; `missed(k)` frames of each are
/// then unseen and the walker either comes back where it was heading (`returns`) or is gone for
/// good. Returns the number of boxes reported at prediction (no detection behind them) over the
/// last walker's gap.
fn coasted_reports(adaptive: bool, returns: bool) -> usize {
    let mut t = Tracker::new(TrackerParams {
        n_init: 1,
        output_lost: 3,
        output_lost_adaptive: adaptive,
        occluded_output: 0,
        max_age: 5,
        ..cv_params()
    })
    .unwrap();
    let mut last = 0;
    for walker in 0..6 {
        let y = 100.0 + 300.0 * f64::from(walker);
        let at = |k: u32| bx(100.0 + 4.0 * f64::from(k), y);
        for k in 0..6 {
            run(&mut t, &[at(k)]);
        }
        last = 0;
        for _ in 6..9 {
            last += run(&mut t, &[])
                .iter()
                .filter(|o| o.det_index.is_none())
                .count();
        }
        if returns {
            run(&mut t, &[at(9)]);
        }
        // Long enough for a lost walker to be deleted.
        for _ in 0..7 {
            run(&mut t, &[]);
        }
    }
    last
}

#[test]
fn output_lost_adaptive_stops_reporting_tracks_that_never_come_back() {
    // Without the adaptation every lost walker is reported for output_lost frames.
    assert_eq!(coasted_reports(false, false), 3);
    assert_eq!(coasted_reports(false, true), 3);
    // With it: walkers that come back where predicted keep being reported ...
    assert_eq!(coasted_reports(true, true), 3);
    // ... walkers that vanish stop being reported once that is what gaps have meant.
    assert_eq!(coasted_reports(true, false), 0);
}

#[test]
fn output_lost_adaptive_counts_occluded_gaps_apart() {
    let mut t = Tracker::new(TrackerParams {
        n_init: 1,
        output_lost: 3,
        output_lost_adaptive: true,
        occluded_output: 3,
        max_age: 5,
        ..cv_params()
    })
    .unwrap();
    // Walkers in the open that vanish for good: gaps in the open stop being reported.
    for walker in 0..4 {
        let y = 100.0 + 300.0 * f64::from(walker);
        for k in 0..6 {
            run(&mut t, &[bx(100.0 + 4.0 * f64::from(k), y)]);
        }
        for _ in 0..8 {
            run(&mut t, &[]);
        }
    }
    let lost = |out: &[TrackOutput]| out.iter().filter(|o| o.det_index.is_none()).count();
    for k in 0..6 {
        run(&mut t, &[bx(500.0 + 4.0 * f64::from(k), 100.0)]);
    }
    assert_eq!(lost(&run(&mut t, &[])), 0, "open gap still reported");
    // A person standing behind a nearer, larger one (lower foot point) goes undetected: that
    // gap is occluded, and occluded gaps have no record yet, so it is reported.
    let far = bx(1000.0, 100.0);
    let near = [970.0, 40.0, 1030.0, 180.0];
    for _ in 0..6 {
        run(&mut t, &[far, near]);
    }
    for _ in 0..3 {
        assert_eq!(lost(&run(&mut t, &[near])), 1, "occluded gap not reported");
    }
}

/// A person walking right at 3 px/frame, detected exactly except in `jitter` frames, where the
/// detection lands `dx` px to the right (toward a neighbour); a gap (no detection) in `gap` frames.
fn walk(
    position_smoothing: f64,
    jitter: &[u32],
    dx: f64,
    gap: &[u32],
) -> Vec<(u32, f64, Option<usize>, u64)> {
    let mut t = Tracker::new(TrackerParams {
        n_init: 1,
        position_smoothing,
        ..cv_params()
    })
    .unwrap();
    let mut out = Vec::new();
    for k in 0..20u32 {
        if gap.contains(&k) {
            run(&mut t, &[]);
            continue;
        }
        let x = 100.0 + 3.0 * f64::from(k) + if jitter.contains(&k) { dx } else { 0.0 };
        for o in run(&mut t, &[bx(x, 200.0)]) {
            out.push((k, 0.5 * (o.bbox[0] + o.bbox[2]), o.det_index, o.id));
        }
    }
    out
}

#[test]
fn position_smoothing_pulls_the_reported_box_toward_the_prediction_only() {
    let (s, dx) = (0.3, 20.0); // IoU 1/3 with the prediction: still matched
    let plain = walk(0.0, &[10], dx, &[14]);
    let smooth = walk(s, &[10], dx, &[14]);
    // Association is untouched: the same ids and matched detections in every frame.
    let key = |v: &[(u32, f64, Option<usize>, u64)]| {
        v.iter().map(|r| (r.0, r.2, r.3)).collect::<Vec<_>>()
    };
    assert_eq!(key(&plain), key(&smooth));
    for (p, q) in plain.iter().zip(&smooth) {
        let line = 100.0 + 3.0 * f64::from(p.0);
        if p.0 == 10 {
            // Without smoothing the box sits on the detection; with it, (1 - s) of the way
            // from the prediction (the line: constant velocity) to the detection.
            assert!((p.1 - (line + dx)).abs() < 1e-9, "{p:?}");
            assert!((q.1 - (line + (1.0 - s) * dx)).abs() < 1e-9, "{q:?}");
        } else if p.0 == 0 || p.0 == 15 {
            // A new track, and the first match after a gap: the detection's centre.
            assert!((q.1 - line).abs() < 1e-9, "{q:?}");
        }
    }
    // The state keeps the detection's centre: the frame after the jitter the prediction is
    // the observation-centric one in both runs, so the reported boxes agree again by frame 13.
    let at = |v: &[(u32, f64, Option<usize>, u64)], k: u32| v.iter().find(|r| r.0 == k).unwrap().1;
    assert!((at(&plain, 13) - at(&smooth, 13)).abs() < 1.0);
}

/// Five people walking right at 2 px/frame, 200 px apart, boxes 60 x 100 px, for 80 frames; each
/// detection's centre is off the person's by `flicker` px to the left or right, the side
/// alternating from frame to frame and from person to person. Returns the tracker and, per
/// reported box in the last 40 frames, the distance of its centre from the person's.
fn flicker_walk(jitter_floor: f64, flicker: f64) -> (Tracker, Vec<f64>) {
    let mut t = Tracker::new(TrackerParams {
        n_init: 1,
        jitter_floor,
        ..cv_params()
    })
    .unwrap();
    let mut errors = Vec::new();
    for k in 0..80u32 {
        let truth: Vec<f64> = (0..5)
            .map(|i| 100.0 + 200.0 * f64::from(i) + 2.0 * f64::from(k))
            .collect();
        let dets: Vec<[f64; 4]> = truth
            .iter()
            .enumerate()
            .map(|(i, &x)| {
                let side = if (k as usize + i) % 2 == 0 { 1.0 } else { -1.0 };
                let c = x + side * flicker;
                [c - 30.0, 150.0, c + 30.0, 250.0]
            })
            .collect();
        for o in run(&mut t, &dets) {
            if k < 40 {
                continue;
            }
            let c = 0.5 * (o.bbox[0] + o.bbox[2]);
            let err = truth
                .iter()
                .map(|x| (c - x).abs())
                .fold(f64::INFINITY, f64::min);
            errors.push(err);
        }
    }
    (t, errors)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
fn adaptive_smoothing_is_strong_for_a_flickering_detector_and_off_for_a_precise_one() {
    let floor = 0.06;
    // A detector whose boxes flicker 10 px either side of 100 px tall people: the innovation
    // stays well above the floor and the prediction gets most of the weight.
    let (t, smoothed) = flicker_walk(floor, 10.0);
    let (innovation, gain) = t.detector_jitter();
    assert!(innovation > 0.1, "innovation {innovation}");
    assert!(gain > 0.5, "gain {gain}");
    let (_, raw) = flicker_walk(0.0, 10.0);
    assert_eq!(
        smoothed.len(),
        raw.len(),
        "every person followed in both runs"
    );
    // Once settled, the reported boxes follow the people, not the flicker: the smoothed error
    // is a fraction of the unsmoothed one (where position_smoothing alone takes 0.3 of it).
    assert!(
        mean(&smoothed) < 0.5 * mean(&raw),
        "smoothed {} raw {}",
        mean(&smoothed),
        mean(&raw)
    );
    // A precise detector (0.5 px either side): the gain stays 0 and the output is exactly the
    // unsmoothed one.
    let (t, precise) = flicker_walk(floor, 0.5);
    let (innovation, gain) = t.detector_jitter();
    assert!(innovation < floor / 2.0, "innovation {innovation}");
    assert_eq!(gain, 0.0);
    assert_eq!(precise, flicker_walk(0.0, 0.5).1);
}

#[test]
fn the_pure_method_has_no_adaptive_smoothing() {
    assert_eq!(TrackerParams::pure().jitter_floor, 0.0);
}

/// A walker (appearance `a`) hidden for one frame while a bystander (appearance 0.22 from `a`
/// in cosine distance) appears beside the walker's prediction, not overlapping it; then both are
/// seen. Returns the ids reported on the walker's detection before and after, and on the
/// bystander's detection in the frame the walker was hidden.
fn bystander_beside_a_hidden_walker(apart: f64) -> (u64, Option<u64>, Option<u64>) {
    let mut t = Tracker::new(TrackerParams {
        n_init: 1,
        appearance_threshold: 0.25,
        appearance_apart: apart,
        ..cv_params()
    })
    .unwrap();
    // Unit vectors: cos(walker, bystander) = 0.78, a cosine distance of 0.22.
    let walker: [f32; 2] = [1.0, 0.0];
    let bystander: [f32; 2] = [0.78, (1.0f32 - 0.78 * 0.78).sqrt()];
    let step = |t: &mut Tracker, boxes: &[[f64; 4]], emb: &[f32]| {
        let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
        let scores = vec![1.0; boxes.len()];
        let e = Some(Embeddings { data: emb, dim: 2 });
        t.update(&flat, &scores, e).unwrap()
    };
    let x = |k: u32| 100.0 + 5.0 * f64::from(k);
    let mut first = 0;
    for k in 0..6 {
        first = step(&mut t, &[bx(x(k), 200.0)], &walker)[0].id;
    }
    // Frame 6: the walker is hidden; the bystander stands 60 px beyond its prediction (boxes
    // 40 px wide: no overlap, well within one box height).
    let stand = x(6) + 60.0;
    let hidden = step(&mut t, &[bx(stand, 200.0)], &bystander);
    let on_bystander = hidden.iter().find(|o| o.det_index == Some(0)).map(|o| o.id);
    let mut last = None;
    for k in 7..10 {
        let both: Vec<f32> = walker.iter().chain(&bystander).copied().collect();
        let out = step(&mut t, &[bx(x(k), 200.0), bx(stand, 200.0)], &both);
        last = out.iter().find(|o| o.det_index == Some(0)).map(|o| o.id);
    }
    (first, on_bystander, last)
}

#[test]
fn a_stricter_appearance_apart_keeps_a_hidden_walkers_id_off_a_bystander() {
    // Appearance alone (threshold 0.25): the hidden walker's track jumps to the bystander, and
    // the walker comes back under another id.
    let (first, on_bystander, last) = bystander_beside_a_hidden_walker(2.0);
    assert_eq!(on_bystander, Some(first));
    assert_ne!(last, Some(first));
    // With 0.2 for detections apart from the prediction, the bystander starts its own track
    // and the walker keeps its id.
    let (first, on_bystander, last) = bystander_beside_a_hidden_walker(0.2);
    assert_ne!(on_bystander, Some(first));
    assert!(on_bystander.is_some());
    assert_eq!(last, Some(first));
    // The pure method leaves it off.
    assert_eq!(TrackerParams::pure().appearance_apart, 2.0);
}
