//! `assoc::Tracker::update` over a run of frames with arbitrary boxes, scores and embeddings,
//! under each motion model.
//!
//! Any input: no panic and no hang; a rejected frame changes nothing (the frame count stays);
//! an accepted frame reports tracks sorted by distinct positive ids, each pointing at a real
//! detection of that frame or at none. Frames whose coordinates stay within +-1e9 px also give
//! finite boxes.
#![no_main]

use arbitrary::Arbitrary;
use assoc::{Embeddings, Tracker, TrackerParams};
use frvo::MotionKind;
use libfuzzer_sys::fuzz_target;

#[derive(Arbitrary, Debug)]
struct Det {
    bbox: [f64; 4],
    score: f64,
    /// Build a well-formed box from these (centre, size) instead of taking `bbox` as it is.
    tidy: bool,
}

#[derive(Arbitrary, Debug)]
struct Frame {
    dets: Vec<Det>,
    /// Embedding values, cycled over the detections; none when empty.
    emb: Vec<f32>,
}

#[derive(Arbitrary, Debug)]
struct Input {
    motion: u8,
    pure: bool,
    dim: u8,
    frames: Vec<Frame>,
}

const BOUND: f64 = 1e9;

fn tidy(b: [f64; 4]) -> [f64; 4] {
    let f = |x: f64, lo: f64, hi: f64| {
        if x.is_finite() {
            lo + x.abs() % (hi - lo)
        } else {
            lo
        }
    };
    let (cx, cy) = (f(b[0], 0.0, 2000.0), f(b[1], 0.0, 1200.0));
    let (w, h) = (f(b[2], 0.0, 200.0), f(b[3], 0.0, 400.0));
    [cx - w / 2.0, cy - h / 2.0, cx + w / 2.0, cy + h / 2.0]
}

fuzz_target!(|input: Input| {
    let mut params = if input.pure {
        TrackerParams::pure()
    } else {
        TrackerParams::default()
    };
    params.motion = match input.motion % 4 {
        0 => MotionKind::Frvo,
        1 => MotionKind::Rvo,
        2 => MotionKind::SocialForce,
        _ => MotionKind::ConstantVelocity,
    };
    params.motion_params.threads = 1;
    let mut tracker = Tracker::new(params).expect("valid parameters");
    let dim = usize::from(input.dim % 8) + 1;
    for frame in input.frames.iter().take(64) {
        let dets = &frame.dets[..frame.dets.len().min(64)];
        let boxes: Vec<f64> = dets
            .iter()
            .flat_map(|d| if d.tidy { tidy(d.bbox) } else { d.bbox })
            .collect();
        let scores: Vec<f64> = dets.iter().map(|d| d.score).collect();
        let emb: Vec<f32> = if frame.emb.is_empty() {
            Vec::new()
        } else {
            (0..dets.len() * dim)
                .map(|k| frame.emb[k % frame.emb.len()])
                .collect()
        };
        let embeddings = (!frame.emb.is_empty()).then_some(Embeddings { data: &emb, dim });
        let before = tracker.frame_count();
        match tracker.update(&boxes, &scores, embeddings) {
            Err(_) => assert_eq!(tracker.frame_count(), before, "a rejected frame counted"),
            Ok(out) => {
                assert_eq!(tracker.frame_count(), before + 1);
                let bounded = boxes.iter().all(|x| x.abs() <= BOUND);
                for w in out.windows(2) {
                    assert!(w[0].id < w[1].id, "ids not sorted and distinct: {out:?}");
                }
                for t in &out {
                    assert!(t.id > 0);
                    if let Some(j) = t.det_index {
                        assert!(j < dets.len(), "det_index {j} of {}", dets.len());
                    }
                    if bounded {
                        assert!(t.bbox.iter().all(|x| x.is_finite()), "{t:?} from {boxes:?}");
                    }
                }
            }
        }
    }
});
