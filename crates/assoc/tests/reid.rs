//! Deferred re-identification (`reid_newborn`): a person who comes back away from their lost
//! track's prediction gets their id back once the new track's first matches agree with it.

use assoc::{Embeddings, TrackOutput, Tracker, TrackerParams};
use frvo::MotionKind;

fn params(reid_newborn: u32) -> TrackerParams {
    TrackerParams {
        motion: MotionKind::ConstantVelocity,
        output_lost: 0,
        coast_min_hits: 0,
        reid_newborn,
        ..TrackerParams::default()
    }
}

fn bx(cx: f64, cy: f64) -> [f64; 4] {
    [cx - 20.0, cy - 50.0, cx + 20.0, cy + 50.0]
}

fn step(t: &mut Tracker, people: &[([f64; 4], [f32; 3])]) -> Vec<TrackOutput> {
    let flat: Vec<f64> = people.iter().flat_map(|p| p.0).collect();
    let emb: Vec<f32> = people.iter().flat_map(|p| p.1).collect();
    let scores = vec![1.0; people.len()];
    let e = Some(Embeddings { data: &emb, dim: 3 });
    t.update(&flat, &scores, e).unwrap()
}

const WALKER: [f32; 3] = [1.0, 0.0, 0.0];
const STRANGER: [f32; 3] = [0.0, 0.0, 1.0];

/// Walkers (one per appearance, 300 px apart) are seen for 10 frames, all hidden for 10, then one
/// person with appearance `back` is seen again 150 px beyond the first walker's prediction
/// (outside the appearance stage's gate of one box height, overlapping neither its prediction nor
/// its last box) for 8 frames. Returns the first walker's id and the ids reported on the person
/// who came back, frame by frame.
fn come_back(p: TrackerParams, walkers: &[[f32; 3]], back: [f32; 3]) -> (u64, Vec<u64>) {
    let mut t = Tracker::new(p).unwrap();
    let x = |k: u32| 100.0 + 5.0 * f64::from(k);
    let mut first = 0;
    for k in 0..10 {
        let seen: Vec<([f64; 4], [f32; 3])> = walkers
            .iter()
            .enumerate()
            .map(|(i, &e)| (bx(x(k), 200.0 + 300.0 * i as f64), e))
            .collect();
        if let Some(o) = step(&mut t, &seen).first() {
            first = o.id;
        }
    }
    for _ in 10..20 {
        step(&mut t, &[]);
    }
    let mut ids = Vec::new();
    for k in 20..28 {
        let out = step(&mut t, &[(bx(x(k) + 150.0, 200.0), back)]);
        ids.extend(out.iter().filter(|o| o.det_index == Some(0)).map(|o| o.id));
    }
    (first, ids)
}

#[test]
fn a_walker_back_away_from_the_prediction_gets_the_id_back_after_enough_matches() {
    // Without the rule the walker comes back under a new id for good.
    let (first, ids) = come_back(params(0), &[WALKER], WALKER);
    assert_eq!(ids.len(), 7, "{ids:?}"); // reported from the second match (n_init 2)
    assert!(ids.iter().all(|&i| i != first), "{ids:?}");
    // With it, the new track is reported under its own id until its third match, then under the
    // walker's, to the end.
    let (first, ids) = come_back(params(3), &[WALKER], WALKER);
    assert_eq!(ids.len(), 7, "{ids:?}");
    assert_ne!(ids[0], first, "{ids:?}");
    assert!(ids[1..].iter().all(|&i| i == first), "{ids:?}");
    // The pure method leaves it off.
    assert_eq!(TrackerParams::pure().reid_newborn, 0);
}

#[test]
fn a_stranger_keeps_their_own_id() {
    let (first, ids) = come_back(params(3), &[WALKER], STRANGER);
    assert_eq!(ids.len(), 7);
    assert!(ids.iter().all(|&i| i != first && i == ids[0]), "{ids:?}");
}

#[test]
fn two_lost_walkers_alike_within_the_margin_keep_the_new_id() {
    // A second lost walker at cosine distance 0.02 from the first: the person who comes back is
    // nearer the first, but not by the margin.
    let twin: [f32; 3] = [0.98, (1.0f32 - 0.98 * 0.98).sqrt(), 0.0];
    let (first, ids) = come_back(params(3), &[WALKER, twin], WALKER);
    assert!(ids.iter().all(|&i| i != first), "{ids:?}");
}
