//! Direction consistency (`direction_weight`): in the IoU stages, a detection that continues a
//! track's observed direction of motion is preferred to one that would turn it.
//!
//! A track's direction is measured on its *observed* centres (matched detections, never
//! predictions): from its anchor, the centre observed [`DIRECTION_SPAN`] frames before its last
//! observation (or its oldest one, if younger), to the last. A candidate's direction runs from the
//! same anchor to the candidate detection's centre. Their angle `a` in `[0, pi]` gives the pair a
//! bonus of `weight * (1 - a / pi)`, taken off the IoU cost `1 - IoU`; eligibility stays the IoU
//! threshold's alone (the bonus only lowers a cost). A direction no longer than the detector's
//! jitter (its mean innovation over box height, times the track's box height) is noise: a pair
//! where either one is that short gets the neutral bonus `weight / 2`, as a random direction
//! would on average; so does a track with a single observation.

use crate::cost::{centre, BBox};
use nalgebra::Vector2;

/// Frames between the two observed centres that give a track's direction.
pub const DIRECTION_SPAN: u64 = 3;

/// The direction term of one frame: its weight and the detector's jitter.
#[derive(Clone, Copy, Debug)]
pub struct DirectionTerm {
    weight: f64,
    /// The detector's mean innovation over box height.
    jitter: f64,
}

impl DirectionTerm {
    pub fn new(weight: f64, jitter: f64) -> Self {
        Self { weight, jitter }
    }

    pub fn is_on(&self) -> bool {
        self.weight > 0.0
    }

    /// The bonus (from 0 to `weight`) of matching a track to `det`. `span` is the track's anchor
    /// and last observed centre (`None`: a single observation), `h` its box height.
    pub fn bonus(&self, span: Option<(Vector2<f64>, Vector2<f64>)>, h: f64, det: &BBox) -> f64 {
        if !self.is_on() {
            return 0.0;
        }
        let neutral = 0.5 * self.weight;
        let Some((anchor, last)) = span else {
            return neutral;
        };
        let d = centre(det);
        let step = Vector2::new(d[0], d[1]) - anchor;
        let motion = last - anchor;
        let noise = self.jitter * h;
        let (nm, ns) = (motion.norm(), step.norm());
        if !(nm > noise && ns > noise && (nm * ns).is_finite()) {
            return neutral;
        }
        let angle = (motion.dot(&step) / (nm * ns)).clamp(-1.0, 1.0).acos();
        self.weight * (1.0 - angle / std::f64::consts::PI)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::{box_from_centre, iou};
    use crate::lap::{Edge, SparseMatcher};

    fn v(x: f64, y: f64) -> Vector2<f64> {
        Vector2::new(x, y)
    }

    fn person(x: f64, y: f64) -> BBox {
        box_from_centre([x, y], 40.0, 80.0)
    }

    #[test]
    fn bonus_follows_the_angle_and_is_neutral_for_short_directions() {
        let t = DirectionTerm::new(0.4, 0.05); // noise 4 px at height 80
        let east = Some((v(0.0, 0.0), v(12.0, 0.0)));
        assert!((t.bonus(east, 80.0, &person(20.0, 0.0)) - 0.4).abs() < 1e-12);
        assert!((t.bonus(east, 80.0, &person(-20.0, 0.0))).abs() < 1e-12);
        assert!((t.bonus(east, 80.0, &person(0.0, 20.0)) - 0.2).abs() < 1e-12);
        // A candidate within the jitter of the anchor, a track that moved less, one with a single
        // observation: neutral.
        assert_eq!(t.bonus(east, 80.0, &person(3.0, 0.0)), 0.2);
        let slow = Some((v(0.0, 0.0), v(3.0, 0.0)));
        assert_eq!(t.bonus(slow, 80.0, &person(-20.0, 0.0)), 0.2);
        assert_eq!(t.bonus(None, 80.0, &person(-20.0, 0.0)), 0.2);
        assert_eq!(
            DirectionTerm::new(0.0, 0.05).bonus(east, 80.0, &person(-20.0, 0.0)),
            0.0
        );
    }

    /// Two neighbours crossing at right angles, predicted where they were last seen: A walks
    /// east, B south. The IoU with the predictions prefers giving each the other's detection;
    /// their observed directions do not, and with the term the assignment follows them.
    #[test]
    fn crossing_neighbours_keep_their_detections_where_iou_prefers_the_swap() {
        let (a_anchor, a_last) = (v(70.0, 100.0), v(100.0, 100.0));
        let (b_anchor, b_last) = (v(100.0, 68.0), v(100.0, 98.0));
        let tracks = [(a_anchor, a_last), (b_anchor, b_last)];
        let dets = [person(114.0, 98.0), person(96.0, 112.0)]; // A's, then B's
        let assign = |weight: f64| {
            let term = DirectionTerm::new(weight, 0.05);
            let mut edges = Vec::new();
            for (i, &(anchor, last)) in tracks.iter().enumerate() {
                let predicted = person(last.x, last.y);
                for (j, d) in dets.iter().enumerate() {
                    let o = iou(&predicted, d);
                    assert!(o >= 0.3, "every pair passes the IoU threshold");
                    let cost = 1.0 - o - term.bonus(Some((anchor, last)), 80.0, d);
                    edges.push(Edge {
                        row: i,
                        col: j,
                        cost,
                    });
                }
            }
            SparseMatcher::default().solve(2, 2, &edges, 0.7)
        };
        assert_eq!(assign(0.0), vec![(0, 1), (1, 0)], "IoU alone swaps them");
        assert_eq!(assign(0.4), vec![(0, 0), (1, 1)]);
    }
}
