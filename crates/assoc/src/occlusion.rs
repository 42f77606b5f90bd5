//! Scene reasoning for a track the detector did not find this frame: is the person hidden behind
//! people nearer the camera (occluded: keep predicting and reporting them), or gone (left the
//! image, or nothing stands in front of where they should be)?
//!
//! Nearer the camera means a lower foot point (the box's bottom edge further down the image): in a
//! front or elevated view the ground rises towards the horizon, so of two people on the ground the
//! one whose feet are lower stands nearer.

use crate::cost::{area, BBox};
use crate::perspective::GroundMap;

/// What the scene says about a track that was not matched this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unmatched {
    /// Its predicted box is covered by boxes nearer the camera: it is probably still there.
    Occluded,
    /// Too little of its predicted box lies inside the image: it left.
    LeftImage,
    /// Neither: a miss of the detector, or the person is gone.
    Uncovered,
}

/// Covered fraction of an unmatched track's predicted box (by nearer people) from which it is
/// occluded, and of a reported box's hidden lower part from which `amodal_boxes` completes it.
pub const OCCLUSION_COVERAGE: f64 = 0.5;

/// Share of an unmatched track's predicted box inside the image below which it has left.
pub const LEFT_IMAGE_INSIDE: f64 = 0.9;

/// Sample points per side of the grid that measures coverage (`GRID * GRID` points).
const GRID: usize = 8;

/// Fraction of `target` covered by the union of `front` (boxes nearer the camera), estimated on a
/// regular grid of sample points (the centres of `GRID x GRID` equal cells).
pub fn covered_fraction(target: &BBox, front: &[BBox]) -> f64 {
    if front.is_empty() || area(target) <= 0.0 {
        return 0.0;
    }
    let (w, h) = (target[2] - target[0], target[3] - target[1]);
    let mut hits = 0usize;
    for iy in 0..GRID {
        let y = target[1] + h * (iy as f64 + 0.5) / GRID as f64;
        for ix in 0..GRID {
            let x = target[0] + w * (ix as f64 + 0.5) / GRID as f64;
            if front
                .iter()
                .any(|b| x >= b[0] && x <= b[2] && y >= b[1] && y <= b[3])
            {
                hits += 1;
            }
        }
    }
    hits as f64 / (GRID * GRID) as f64
}

/// Whether `other` stands nearer the camera than `target`: its foot point is lower in the image.
#[inline]
pub fn nearer(other: &BBox, target: &BBox) -> bool {
    other[3] > target[3]
}

/// Fraction of `b` inside the image `[0, w] x [0, h]`.
pub fn inside_fraction(b: &BBox, image: [f64; 2]) -> f64 {
    let iw = (b[2].min(image[0]) - b[0].max(0.0)).max(0.0);
    let ih = (b[3].min(image[1]) - b[1].max(0.0)).max(0.0);
    let a = area(b);
    if a > 0.0 {
        iw * ih / a
    } else {
        0.0
    }
}

/// The boxes seen this frame, sorted by left edge so that the boxes overlapping a target are
/// found by a range query rather than by testing every box.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Sorted by `x1`.
    boxes: Vec<BBox>,
    /// The widest box's width: a box overlapping `[x1, x2]` starts after `x1 - max_width`.
    max_width: f64,
}

impl Scene {
    pub fn new(mut boxes: Vec<BBox>) -> Self {
        boxes.sort_by(|a, b| a[0].total_cmp(&b[0]));
        let max_width = boxes.iter().map(|b| b[2] - b[0]).fold(0.0, f64::max);
        Self { boxes, max_width }
    }

    /// The boxes whose interior overlaps that of `target`.
    pub fn overlapping<'a>(&'a self, target: &'a BBox) -> impl Iterator<Item = &'a BBox> + 'a {
        // Twice the widest width: a margin no rounding of the subtraction can eat into.
        let from = target[0] - 2.0 * self.max_width;
        let lo = self.boxes.partition_point(|b| b[0] < from);
        self.boxes[lo..]
            .iter()
            .take_while(|b| b[0] < target[2])
            .filter(|b| overlaps(b, target))
    }
}

/// Classifies an unmatched track from its predicted box, the boxes seen this frame (`scene`:
/// detections, the track's own excluded by the caller) and the image size when known.
/// `min_coverage` is the covered fraction from which the track counts as occluded, `min_inside`
/// the fraction of the predicted box inside the image below which it left.
pub fn classify(
    predicted: &BBox,
    scene: &Scene,
    image: Option<[f64; 2]>,
    min_coverage: f64,
    min_inside: f64,
) -> Unmatched {
    if let Some(size) = image {
        if inside_fraction(predicted, size) < min_inside {
            return Unmatched::LeftImage;
        }
    }
    let front: Vec<BBox> = scene
        .overlapping(predicted)
        .filter(|b| nearer(b, predicted))
        .copied()
        .collect();
    if covered_fraction(predicted, &front) >= min_coverage {
        Unmatched::Occluded
    } else {
        Unmatched::Uncovered
    }
}

/// The whole person behind a box whose lower part is hidden: where the perspective expects a
/// taller person from the box's top row and the missing part below the box is covered (at least
/// `min_coverage`) by boxes of `scene` nearer the camera than that full box, the box is extended
/// down to the full height; otherwise it is returned as is (never shrunk).
pub fn complete(b: &BBox, scene: &[BBox], ground: &GroundMap, min_coverage: f64) -> BBox {
    let Some(h) = ground.height_from_top(b[1]) else {
        return *b;
    };
    let bottom = b[1] + h;
    if bottom <= b[3] {
        return *b;
    }
    let full = [b[0], b[1], b[2], bottom];
    let missing = [b[0], b[3], b[2], bottom];
    let front: Vec<BBox> = scene
        .iter()
        .filter(|o| nearer(o, &full) && overlaps(o, &missing))
        .copied()
        .collect();
    if covered_fraction(&missing, &front) >= min_coverage {
        full
    } else {
        *b
    }
}

#[inline]
fn overlaps(a: &BBox, b: &BBox) -> bool {
    a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coverage_matches_the_exact_area_on_grid_aligned_boxes() {
        let target = [0.0, 0.0, 8.0, 8.0];
        assert_eq!(covered_fraction(&target, &[]), 0.0);
        assert_eq!(covered_fraction(&target, &[[0.0, 0.0, 4.0, 8.0]]), 0.5);
        // Two overlapping boxes: the union counts once (6 of 8 columns).
        let two = [[0.0, 0.0, 4.0, 8.0], [2.0, 0.0, 6.0, 8.0]];
        assert_eq!(covered_fraction(&target, &two), 0.75);
        assert_eq!(covered_fraction(&target, &[[-1.0, -1.0, 9.0, 9.0]]), 1.0);
    }

    #[test]
    fn scene_queries_find_exactly_the_overlapping_boxes() {
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |scale: f64| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64 * scale
        };
        for n in [0, 1, 5, 200] {
            let boxes: Vec<BBox> = (0..n)
                .map(|k| {
                    // Some zero-width and zero-height boxes, and a few wide ones.
                    let (x0, y0) = (next(1000.0), next(600.0));
                    let w = if k % 17 == 0 {
                        0.0
                    } else {
                        next(if k % 5 == 0 { 400.0 } else { 60.0 })
                    };
                    let h = if k % 13 == 0 { 0.0 } else { next(150.0) };
                    [x0, y0, x0 + w, y0 + h]
                })
                .collect();
            let scene = Scene::new(boxes.clone());
            for _ in 0..300 {
                let (x0, y0) = (next(1100.0) - 50.0, next(700.0) - 50.0);
                let target = [x0, y0, x0 + next(120.0), y0 + next(200.0)];
                let mut want: Vec<[u64; 4]> = boxes
                    .iter()
                    .filter(|b| overlaps(b, &target))
                    .map(|b| b.map(f64::to_bits))
                    .collect();
                let mut got: Vec<[u64; 4]> = scene
                    .overlapping(&target)
                    .map(|b| b.map(f64::to_bits))
                    .collect();
                want.sort_unstable();
                got.sort_unstable();
                assert_eq!(got, want, "n {n}, target {target:?}");
            }
        }
    }

    #[test]
    fn a_person_behind_a_nearer_one_is_occluded_and_one_in_front_is_not() {
        // Far person: feet at y = 100; near person: feet at y = 140, a bigger box over it.
        let far = [50.0, 20.0, 80.0, 100.0];
        let near = [40.0, 10.0, 95.0, 140.0];
        assert_eq!(
            classify(&far, &Scene::new(vec![near]), None, 0.5, 0.5),
            Unmatched::Occluded
        );
        // The near one, unmatched, with the far one in the scene: nothing in front of it.
        assert_eq!(
            classify(&near, &Scene::new(vec![far]), None, 0.5, 0.5),
            Unmatched::Uncovered
        );
        // Nobody around.
        assert_eq!(
            classify(&far, &Scene::new(vec![]), None, 0.5, 0.5),
            Unmatched::Uncovered
        );
    }

    #[test]
    fn partly_covered_is_occluded_only_from_the_threshold() {
        let far = [0.0, 0.0, 40.0, 80.0];
        let near = [20.0, 0.0, 80.0, 120.0]; // covers the right half
        assert_eq!(
            classify(&far, &Scene::new(vec![near]), None, 0.5, 0.5),
            Unmatched::Occluded
        );
        assert_eq!(
            classify(&far, &Scene::new(vec![near]), None, 0.6, 0.5),
            Unmatched::Uncovered
        );
    }

    #[test]
    fn a_box_cut_by_a_nearer_person_is_completed_to_the_expected_height() {
        // Horizon at row 0, people 0.5 x their depth below it: h = k (y_foot - 0), k = 0.5.
        let ground = GroundMap {
            k: 0.5,
            x0: 0.0,
            horizon: 0.0,
            y_ref: 200.0,
        };
        // A head at row 100: full height 100 (feet at 200). Only the top 60 px were seen.
        let cut = [50.0, 100.0, 90.0, 160.0];
        let near = [30.0, 120.0, 110.0, 280.0];
        assert_eq!(
            complete(&cut, &[near], &ground, 0.5),
            [50.0, 100.0, 90.0, 200.0]
        );
        // Nobody in front of the missing part: as seen.
        assert_eq!(complete(&cut, &[], &ground, 0.5), cut);
        let far = [30.0, 120.0, 110.0, 190.0]; // feet above the full box's feet: behind it
        assert_eq!(complete(&cut, &[far], &ground, 0.5), cut);
        // Already as tall as expected: never shrunk.
        let whole = [50.0, 100.0, 90.0, 215.0];
        assert_eq!(complete(&whole, &[near], &ground, 0.5), whole);
    }

    #[test]
    fn a_box_mostly_outside_the_image_has_left() {
        let image = Some([640.0, 480.0]);
        let at_edge = [620.0, 100.0, 660.0, 200.0]; // half inside: still there
        let out = [630.0, 100.0, 670.0, 200.0]; // a quarter inside
        let near = [600.0, 90.0, 700.0, 260.0];
        assert_eq!(
            classify(&at_edge, &Scene::new(vec![near]), image, 0.5, 0.5),
            Unmatched::Occluded
        );
        assert_eq!(
            classify(&out, &Scene::new(vec![near]), image, 0.5, 0.5),
            Unmatched::LeftImage
        );
        assert_eq!(
            inside_fraction(&[-10.0, 0.0, 10.0, 10.0], [640.0, 480.0]),
            0.5
        );
    }
}
