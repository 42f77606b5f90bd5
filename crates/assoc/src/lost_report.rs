//! Whether reporting a lost track at its prediction pays, learnt online from the sequence itself.
//!
//! A confirmed track unmatched for `t` frames can be reported at its predicted box (for
//! `output_lost` frames, or `occluded_output` while it is occluded; the larger is the horizon). That box is a hit when the person is still there, undetected, where the motion
//! model put them (a detector that misses people now and then, a still camera), and a false
//! positive when the person is gone or the prediction is off (a detector that misses little, so
//! an unmatched track mostly means the person left; a moving camera). Which holds depends on the
//! detector and the scene, so the tracker counts, per gap length `t`, how the gaps it has seen
//! ended:
//!
//! - **re-found at its prediction**: the track was matched again after `g` frames and its
//!   predicted box overlapped the detection by at least [`HIT_IOU`] (the MOTChallenge match
//!   criterion): each of its coasted boxes up to `min(g, output_lost)` counts as a hit;
//! - **otherwise** (matched again away from its prediction, or deleted unmatched): each of them
//!   counts as a miss.
//!
//! The tracker keeps two such counts: for gaps that began with the track occluded (covered by
//! people nearer the camera, [`crate::occlusion`]) and for gaps that began in the open, since a
//! hidden person is more likely still there than one who vanished in the open.
//!
//! A lost track is reported at gap `t` while hits make at least a share `min_precision` of the
//! gaps counted at `t` ([`REPORT_PRECISION`]). A reported box that is a hit with probability
//! `p` adds `p` true positives for `1 - p` false positives: MOTA gains where `p > 1/2`, HOTA's
//! detection accuracy `DetA = TP / (TP + FN + FP)` where `p > DetA / (1 + DetA)`, 1/3 at
//! `DetA = 0.5`. With nothing counted yet every gap is reported, as without the adaptation.

use crate::cost::{iou, BBox};

/// Overlap between a lost track's prediction and the detection that re-finds it for its coasted
/// boxes to count as hits: the MOTChallenge criterion for a reported box to match a person.
pub const HIT_IOU: f64 = 0.5;

/// The share of gaps re-found at the prediction needed to report a lost track: a box that is a
/// hit with probability `p` raises HOTA's DetA where `p > DetA / (1 + DetA)`, 1/3 at DetA 0.5.
pub const REPORT_PRECISION: f64 = 0.33;

/// Counts of how coasted boxes at each gap length turned out.
#[derive(Clone, Debug, Default)]
pub struct LostReport {
    /// `hits[t - 1]`, `misses[t - 1]`: coasted boxes at gap `t` judged right / wrong.
    hits: Vec<u64>,
    misses: Vec<u64>,
}

impl LostReport {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn reset(&mut self) {
        self.hits.clear();
        self.misses.clear();
    }

    fn add(&mut self, gap: u32, horizon: u32, hit: bool) {
        let n = gap.min(horizon) as usize;
        if self.hits.len() < n {
            self.hits.resize(n, 0);
            self.misses.resize(n, 0);
        }
        let counts = if hit {
            &mut self.hits
        } else {
            &mut self.misses
        };
        counts[..n].iter_mut().for_each(|c| *c += 1);
    }

    /// A track lost for `gap` frames was matched again to `det`, its prediction `predicted`.
    pub fn refound(&mut self, gap: u32, horizon: u32, predicted: &BBox, det: &BBox) {
        if gap == 0 {
            return;
        }
        self.add(gap, horizon, iou(predicted, det) >= HIT_IOU);
    }

    /// A track lost for `gap` frames is deleted.
    pub fn not_refound(&mut self, gap: u32, horizon: u32) {
        if gap > 0 {
            self.add(gap, horizon, false);
        }
    }

    /// Whether a track lost for `gap` frames (`>= 1`) is worth reporting.
    pub fn report(&self, gap: u32, min_precision: f64) -> bool {
        let k = gap as usize;
        if k == 0 || k > self.hits.len() {
            return true;
        }
        let (h, m) = (self.hits[k - 1] as f64, self.misses[k - 1] as f64);
        h >= min_precision * (h + m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const A: BBox = [0.0, 0.0, 10.0, 20.0];
    const FAR: BBox = [100.0, 0.0, 110.0, 20.0];

    #[test]
    fn reports_while_gaps_end_at_the_prediction() {
        let mut r = LostReport::new();
        assert!(r.report(1, 0.5) && r.report(5, 0.5));
        // Two gaps of 3 re-found where predicted, one gap of 2 re-found elsewhere.
        r.refound(3, 5, &A, &A);
        r.refound(3, 5, &A, &A);
        r.refound(2, 5, &A, &FAR);
        assert_eq!(
            (r.hits.clone(), r.misses.clone()),
            (vec![2, 2, 2], vec![1, 1, 0])
        );
        assert!(r.report(1, 0.5) && r.report(3, 0.5));
        // Two tracks that vanish: gaps 1-2 now lean to misses, gap 3 still to hits.
        r.not_refound(2, 5);
        r.not_refound(2, 5);
        assert!(!r.report(1, 0.5) && !r.report(2, 0.5) && r.report(3, 0.5));
        // Two hits in five at gap 1: reported at a precision of 1/3, not at 1/2.
        assert!(r.report(1, 0.33) && !r.report(1, 0.5));
        // Three tracks vanish after 3 frames: gap 3 also at two hits in five.
        for _ in 0..3 {
            r.not_refound(3, 5);
        }
        assert!(r.report(3, 0.33) && !r.report(3, 0.5) && !r.report(3, 0.41));
        // Unknown gap lengths are reported.
        assert!(r.report(4, 0.5));
    }

    #[test]
    fn gaps_past_the_horizon_count_only_up_to_it() {
        let mut r = LostReport::new();
        r.not_refound(9, 4); // deleted after 9 frames
        r.refound(9, 4, &A, &A); // re-found at its prediction after 9 frames
        r.refound(7, 4, &A, &FAR);
        assert_eq!((r.hits.clone(), r.misses.clone()), (vec![1; 4], vec![2; 4]));
        r.refound(0, 4, &A, &A); // matched without a gap: not a lost track
        assert_eq!(r.hits, vec![1; 4]);
    }
}
