//! The ground plane, estimated online from the boxes: people are of similar height, so in a view
//! from above the ground (no roll) a person's box height grows linearly with how far below the
//! horizon the feet stand, `h = k (y_foot - y_h)`. A least-squares fit of height on foot row over
//! the matched boxes gives `k` and the horizon row `y_h`.
//!
//! With the horizon known, [`GroundMap`] rectifies the image onto the ground up to one unknown
//! aspect (the camera's tilt): distances along a row shrink as `1 / (y - y_h)` and down the image
//! as `1 / (y - y_h)^2`. The map is scaled to be the identity to first order at the reference row
//! `y_ref` (the mean foot row seen), so ground units are pixels at that row and every pixel
//! parameter of the motion model keeps its meaning there.

use crate::cost::BBox;
use nalgebra::{Matrix2, Vector2};

/// Boxes to see before the fit is used.
const MIN_BOXES: f64 = 50.0;
/// Weight kept per observed box: the fit follows a moving camera over a few thousand boxes.
const FORGET: f64 = 0.9995;
/// Smallest correlation of box height with foot row for the fit to count as a ground plane.
const MIN_CORRELATION: f64 = 0.5;
/// The nearest a foot row may come to the horizon, as a fraction of the reference depth
/// `y_ref - y_h` (keeps the map finite for a box above the fitted horizon).
const MIN_DEPTH: f64 = 0.2;

/// Running least-squares sums of box height on foot row, exponentially forgotten.
#[derive(Clone, Debug, Default)]
pub struct Perspective {
    n: f64,
    sx: f64,
    sy: f64,
    sh: f64,
    syy: f64,
    syh: f64,
    shh: f64,
    /// Highest foot row seen (smallest y), forgotten with the sums.
    top: f64,
}

impl Perspective {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds one person's box (`[x1, y1, x2, y2]`, feet at the bottom edge).
    pub fn observe(&mut self, b: &BBox) {
        let (x, y, h) = (0.5 * (b[0] + b[2]), b[3], b[3] - b[1]);
        if !(x.is_finite() && y.is_finite() && h.is_finite() && h > 0.0) {
            return;
        }
        let f = FORGET;
        self.top = if self.n == 0.0 { y } else { self.top.min(y) };
        self.n = f * self.n + 1.0;
        self.sx = f * self.sx + x;
        self.sy = f * self.sy + y;
        self.sh = f * self.sh + h;
        self.syy = f * self.syy + y * y;
        self.syh = f * self.syh + y * h;
        self.shh = f * self.shh + h * h;
    }

    /// The ground map, once enough boxes were seen and they say that lower feet mean taller
    /// boxes (correlation at least `MIN_CORRELATION`) with the horizon above every foot seen;
    /// `None` otherwise (use image space).
    pub fn ground(&self) -> Option<GroundMap> {
        if self.n < MIN_BOXES {
            return None;
        }
        let (my, mh) = (self.sy / self.n, self.sh / self.n);
        let var = self.syy / self.n - my * my;
        let cov = self.syh / self.n - my * mh;
        let var_h = self.shh / self.n - mh * mh;
        if !(var > 0.0 && var_h > 0.0 && cov >= MIN_CORRELATION * (var * var_h).sqrt()) {
            return None;
        }
        // k > 0: cov and var are positive here.
        let k = cov / var;
        let horizon = my - mh / k;
        if !(horizon < self.top && horizon.is_finite()) {
            return None;
        }
        Some(GroundMap {
            k,
            x0: self.sx / self.n,
            horizon,
            y_ref: my,
        })
    }
}

/// Image point <-> ground point, see the module doc. Points are foot points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroundMap {
    /// Box height per row of depth below the horizon: `h = k (y_foot - y_h)`.
    pub k: f64,
    /// Column of no shear (the mean foot column seen).
    pub x0: f64,
    /// Horizon row `y_h`.
    pub horizon: f64,
    /// Reference row, where the map is the identity to first order.
    pub y_ref: f64,
}

impl GroundMap {
    fn d_ref(&self) -> f64 {
        self.y_ref - self.horizon
    }

    /// Depth below the horizon of row `y`, kept at least `MIN_DEPTH * d_ref`.
    fn depth(&self, y: f64) -> f64 {
        (y - self.horizon).max(MIN_DEPTH * self.d_ref())
    }

    /// Image scale at row `y` relative to the reference row (`h(y) / h(y_ref)`).
    pub fn scale(&self, y: f64) -> f64 {
        self.depth(y) / self.d_ref()
    }

    /// Box height of a person whose feet are on the reference row.
    pub fn reference_height(&self) -> f64 {
        self.k * self.d_ref()
    }

    /// Height of a person whose head is at row `top`, from `h = k (top + h - y_h)`; `None`
    /// where the fit gives no finite positive answer.
    pub fn height_from_top(&self, top: f64) -> Option<f64> {
        let h = self.k * (top - self.horizon) / (1.0 - self.k);
        (h.is_finite() && h > 0.0).then_some(h)
    }

    pub fn to_ground(&self, p: Vector2<f64>) -> Vector2<f64> {
        let (r, d) = (self.d_ref(), self.depth(p.y));
        Vector2::new(
            self.x0 + (p.x - self.x0) * r / d,
            self.horizon + 2.0 * r - r * r / d,
        )
    }

    /// Inverse of [`GroundMap::to_ground`]; a ground point beyond the camera's reach (at or
    /// past `horizon + 2 d_ref`) comes back at the nearest row the map reaches.
    pub fn to_image(&self, g: Vector2<f64>) -> Vector2<f64> {
        let r = self.d_ref();
        let gap = (self.horizon + 2.0 * r - g.y).max(r * 1e-3);
        let d = (r * r / gap).max(MIN_DEPTH * r);
        Vector2::new(self.x0 + (g.x - self.x0) * d / r, self.horizon + d)
    }

    /// Derivative of [`GroundMap::to_ground`] at image point `p`: maps an image velocity there
    /// to a ground velocity.
    pub fn jacobian(&self, p: Vector2<f64>) -> Matrix2<f64> {
        let (r, d) = (self.d_ref(), self.depth(p.y));
        let clamped = p.y - self.horizon < MIN_DEPTH * r;
        let dy = if clamped { 0.0 } else { 1.0 };
        Matrix2::new(
            r / d,
            -dy * (p.x - self.x0) * r / (d * d),
            0.0,
            dy * r * r / (d * d),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Boxes of people of height 1.7 standing on a ground plane seen by a pinhole camera at
    /// height `cam_h`, horizon at row `hz`, focal `f`: a person at depth `z` and lateral offset
    /// `x` has feet at row `hz + f cam_h / z` and height `f 1.7 / z`.
    fn person(x: f64, z: f64) -> BBox {
        let (f, cam_h, hz, cx) = (800.0, 5.0, 100.0, 640.0);
        let (u, foot, h) = (cx + f * x / z, hz + f * cam_h / z, f * 1.7 / z);
        [u - 0.2 * h, foot - h, u + 0.2 * h, foot]
    }

    fn fitted() -> GroundMap {
        let mut p = Perspective::new();
        for i in 0..200 {
            let (x, z) = (-8.0 + 0.08 * i as f64, 6.0 + 0.1 * ((i * 7) % 200) as f64);
            p.observe(&person(x, z));
        }
        p.ground().expect("a fit from a perspective view")
    }

    #[test]
    fn fit_recovers_the_horizon_of_a_pinhole_camera() {
        let g = fitted();
        assert!((g.horizon - 100.0).abs() < 1e-6, "horizon {}", g.horizon);
        // h = k (y - y_h) exactly for this camera: the scale is the height ratio.
        let (a, b) = (person(0.0, 8.0), person(0.0, 16.0));
        let ratio = (a[3] - a[1]) / (b[3] - b[1]);
        assert!((g.scale(a[3]) / g.scale(b[3]) - ratio).abs() < 1e-9);
    }

    #[test]
    fn equal_ground_steps_are_equal_after_the_map_and_the_map_inverts() {
        let g = fitted();
        let foot = |b: BBox| Vector2::new(0.5 * (b[0] + b[2]), b[3]);
        // One metre sideways at depth 8 and at depth 16: 2:1 in pixels, equal on the ground.
        let near = g.to_ground(foot(person(1.0, 8.0))) - g.to_ground(foot(person(0.0, 8.0)));
        let far = g.to_ground(foot(person(1.0, 16.0))) - g.to_ground(foot(person(0.0, 16.0)));
        assert!((near.norm() / far.norm() - 1.0).abs() < 1e-9);
        // One metre in depth, near and far: equal too (the map is projective: exact).
        let dn = g.to_ground(foot(person(0.0, 9.0))) - g.to_ground(foot(person(0.0, 8.0)));
        let df = g.to_ground(foot(person(0.0, 17.0))) - g.to_ground(foot(person(0.0, 16.0)));
        assert!((dn.y / df.y - 1.0).abs() < 1e-9);
        for p in [Vector2::new(10.0, 200.0), Vector2::new(900.0, 700.0)] {
            assert!((g.to_image(g.to_ground(p)) - p).norm() < 1e-9);
        }
    }

    #[test]
    fn the_full_height_follows_from_the_head_row() {
        let g = fitted();
        for z in [7.0, 12.0, 25.0] {
            let b = person(1.0, z);
            let h = g.height_from_top(b[1]).unwrap();
            assert!((h - (b[3] - b[1])).abs() < 1e-6, "depth {z}: {h}");
        }
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let g = fitted();
        for p in [Vector2::new(200.0, 300.0), Vector2::new(1000.0, 650.0)] {
            let j = g.jacobian(p);
            for (k, e) in [Vector2::new(1e-4, 0.0), Vector2::new(0.0, 1e-4)]
                .iter()
                .enumerate()
            {
                let fd = (g.to_ground(p + e) - g.to_ground(p - e)) / 2e-4;
                assert!((j.column(k) - fd).norm() < 1e-6, "{p:?} column {k}");
            }
        }
    }

    #[test]
    fn no_fit_without_perspective_or_enough_boxes() {
        let mut p = Perspective::new();
        for i in 0..20 {
            p.observe(&person(0.1 * i as f64, 8.0 + i as f64));
        }
        assert!(p.ground().is_none(), "too few boxes");
        // Equal heights everywhere (a side view): no slope, no map.
        let mut flat = Perspective::new();
        for i in 0..200 {
            let y = 100.0 + i as f64;
            flat.observe(&[0.0, y - 80.0, 30.0, y]);
        }
        assert!(flat.ground().is_none());
        // Taller boxes higher up: not a ground plane seen from above.
        let mut inverted = Perspective::new();
        for i in 0..200 {
            let y = 100.0 + i as f64;
            inverted.observe(&[0.0, y - (300.0 - y), 30.0, y]);
        }
        assert!(inverted.ground().is_none());
    }
}
