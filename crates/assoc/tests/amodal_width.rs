//! `amodal_width_quantile` through the tracker: a person seen narrow (here behind a nearer one)
//! is reported at the scene's whole width once enough matched boxes are seen; off, as detected.

use assoc::crowd_aspect::ASPECT_WARM_UP;
use assoc::{TrackOutput, Tracker, TrackerParams};
use frvo::MotionKind;

fn params(quantile: f64) -> TrackerParams {
    TrackerParams {
        motion: MotionKind::ConstantVelocity,
        size_smoothing: 0.0,
        position_smoothing: 0.0,
        jitter_floor: 0.0,
        amodal_width_quantile: quantile,
        ..TrackerParams::default()
    }
}

// A person seen whole (aspect 0.4) and one behind them (feet higher), cut narrow (aspect 0.16)
// and about 30% covered by the nearer box.
const FRONT: [f64; 4] = [80.0, 150.0, 120.0, 250.0];
const BEHIND: [f64; 4] = [110.0, 100.0, 126.0, 200.0];

fn frames(t: &mut Tracker, n: usize) -> Vec<Vec<TrackOutput>> {
    let flat: Vec<f64> = FRONT.iter().chain(BEHIND.iter()).copied().collect();
    (0..n)
        .map(|_| t.update(&flat, &[0.9, 0.9], None).unwrap())
        .collect()
}

fn behind(out: &[TrackOutput]) -> [f64; 4] {
    out.iter().find(|o| o.det_index == Some(1)).unwrap().bbox
}

fn front(out: &[TrackOutput]) -> [f64; 4] {
    out.iter().find(|o| o.det_index == Some(0)).unwrap().bbox
}

#[test]
fn a_covered_narrow_box_is_reported_at_the_scenes_width_after_the_warm_up() {
    let mut t = Tracker::new(params(0.75)).unwrap();
    let n = ASPECT_WARM_UP;
    let outs = frames(&mut t, n);
    for (k, out) in outs.iter().enumerate().skip(1) {
        assert_eq!(
            front(out),
            FRONT,
            "frame {k}: the nearer box is not covered"
        );
        // Two matched boxes a frame from the second (the first starts the tracks).
        let seen = 2 * k;
        let want = if seen >= ASPECT_WARM_UP {
            // 0.4 (the 75% quantile of 0.16s and 0.4s) x height 100, about x = 118.
            [98.0, 100.0, 138.0, 200.0]
        } else {
            BEHIND
        };
        let got = behind(out);
        assert!(
            got.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-9),
            "frame {k}: {got:?} != {want:?}"
        );
    }
}

#[test]
fn off_the_box_is_as_detected() {
    let mut off = Tracker::new(params(0.0)).unwrap();
    for out in frames(&mut off, 2 * ASPECT_WARM_UP).iter().skip(1) {
        assert_eq!(behind(out), BEHIND);
    }
    assert_eq!(TrackerParams::pure().amodal_width_quantile, 0.0);
}
