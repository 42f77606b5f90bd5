//! The whole width of a person seen in part (`amodal_width_quantile`; `amodal_boxes` completes
//! the height).
//!
//! A person standing behind others is detected by the part that shows, cut narrow, while
//! MOTChallenge annotates the whole person. A matched box that is covered by reported boxes nearer
//! the camera (lower foot point) and narrower than the scene's people seen whole (a high quantile
//! of every matched detection's aspect ratio, [`crate::crowd_aspect`]) is reported at that width,
//! about its own centre (with a coverage of 0, every narrower matched box: a detector's boxes
//! can be tighter than the annotation's whole person). Reporting only: the track's state and its
//! matching are unchanged.

use crate::cost::{box_from_centre, centre, BBox};
use crate::occlusion::{covered_fraction, nearer, Scene};

/// Widens in place every box of `boxes` marked in `matched` that is covered at least
/// `min_coverage` by the other boxes of `boxes` nearer the camera and narrower than `aspect`
/// (width over height) makes its height. The coverage is measured on the boxes as given.
pub fn widen_occluded(boxes: &mut [BBox], matched: &[bool], aspect: f64, min_coverage: f64) {
    let scene = Scene::new(boxes.to_vec());
    for (b, _) in boxes.iter_mut().zip(matched).filter(|(_, &m)| m) {
        let target = *b;
        let (w, h) = (target[2] - target[0], target[3] - target[1]);
        let whole = aspect * h;
        if !(whole > w && whole.is_finite()) {
            continue;
        }
        // A box is never nearer than itself, so the scene needs no exclusion of it.
        let front: Vec<BBox> = scene
            .overlapping(&target)
            .filter(|o| nearer(o, &target))
            .copied()
            .collect();
        if covered_fraction(&target, &front) >= min_coverage {
            *b = box_from_centre(centre(&target), whole, h);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_covered_narrow_matched_box_widens_about_its_centre() {
        // A narrow box (aspect 0.2) half covered by a nearer one (lower feet), and the nearer
        // one itself (covered by nothing nearer).
        let back = [10.0, 0.0, 30.0, 100.0];
        let front = [20.0, 40.0, 60.0, 120.0];
        let mut b = [back, front];
        widen_occluded(&mut b, &[true, true], 0.4, 0.3);
        assert_eq!(
            b[0],
            [0.0, 0.0, 40.0, 100.0],
            "widened to 0.4 x 100 about x = 20"
        );
        assert_eq!(b[1], front, "the nearer box is not covered");

        // Below the coverage asked for, unmatched, or already as wide: unchanged.
        let covered = covered_fraction(&back, &[front]);
        assert!(covered > 0.3 && covered < 0.6, "{covered}");
        let mut b = [back, front];
        widen_occluded(&mut b, &[true, true], 0.4, 0.6);
        assert_eq!(b[0], back);
        let mut b = [back, front];
        widen_occluded(&mut b, &[false, true], 0.4, 0.3);
        assert_eq!(b[0], back);
        let mut b = [back, front];
        widen_occluded(&mut b, &[true, true], 0.2, 0.3);
        assert_eq!(b[0], back);
    }

    #[test]
    fn a_box_behind_is_not_covered_by_one_further_back() {
        // The covering box's feet are higher (further from the camera): not in front.
        let me = [10.0, 0.0, 30.0, 100.0];
        let behind = [0.0, 0.0, 40.0, 90.0];
        let mut b = [me, behind];
        widen_occluded(&mut b, &[true, true], 0.4, 0.1);
        assert_eq!(b[0], me);
        // The box behind is covered by `me` but only where `me` stands (20 of 40 columns).
        assert_eq!(b[1], behind, "already as wide as 0.4 x 90");
    }
}
