//! Convex polygons and the conservative polygon of a pedestrian's ellipse.

use nalgebra::Vector2;

pub type V2 = Vector2<f64>;

/// Most sides an ellipse polygon may have; Minkowski sums hold up to twice as many vertices.
pub const MAX_SIDES: usize = 32;
/// Capacity of a [`Polygon`]: enough for the Minkowski sum of two `MAX_SIDES` polygons.
pub const MAX_VERTICES: usize = 2 * MAX_SIDES;
/// Sizes below this (pixels), and non-finite sizes, are treated as this: a dot, so that the
/// polygon keeps a positive area and the velocity obstacle stays well defined.
pub const MIN_SIZE: f64 = 1e-3;

/// 2-D cross product (z component).
pub fn cross(a: V2, b: V2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Left normal: `a` rotated by +90 degrees.
pub fn left_normal(a: V2) -> V2 {
    V2::new(-a.y, a.x)
}

/// Right normal: `a` rotated by -90 degrees (outward normal of a counter-clockwise edge).
pub fn right_normal(a: V2) -> V2 {
    V2::new(a.y, -a.x)
}

pub fn is_finite(v: V2) -> bool {
    v.x.is_finite() && v.y.is_finite()
}

/// A convex polygon with counter-clockwise vertices, stored inline (no allocation).
#[derive(Clone, Copy, Debug)]
pub struct Polygon {
    pts: [V2; MAX_VERTICES],
    len: usize,
}

impl Default for Polygon {
    fn default() -> Self {
        Self {
            pts: [V2::zeros(); MAX_VERTICES],
            len: 0,
        }
    }
}

impl Polygon {
    /// Counter-clockwise vertices; at most [`MAX_VERTICES`] are kept.
    pub fn from_ccw(points: &[V2]) -> Self {
        let mut p = Self::default();
        for &q in points {
            p.push(q);
        }
        p
    }

    /// Appends a vertex (ignored once [`MAX_VERTICES`] are held).
    pub fn push(&mut self, p: V2) {
        if self.len < MAX_VERTICES {
            self.pts[self.len] = p;
            self.len += 1;
        }
    }

    pub fn points(&self) -> &[V2] {
        &self.pts[..self.len]
    }

    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The polygon reflected through the origin (still counter-clockwise).
    pub fn negated(&self) -> Self {
        let mut p = *self;
        for q in &mut p.pts[..p.len] {
            *q = -*q;
        }
        p
    }

    /// Index of the lowest vertex (smallest y, then smallest x): where edge angles start at 0.
    pub fn lowest_vertex(&self) -> usize {
        lowest_vertex(self.points())
    }

    /// Whether `p` lies inside or on the polygon, with tolerance `eps` (distance units).
    pub fn contains(&self, p: V2, eps: f64) -> bool {
        let n = self.len;
        (0..n).all(|i| {
            let a = self.pts[i];
            let e = self.pts[(i + 1) % n] - a;
            let len = e.norm();
            len == 0.0 || cross(e, p - a) >= -eps * len
        })
    }
}

/// Index of the lowest point (smallest y, then smallest x; 0 when empty).
pub fn lowest_vertex(pts: &[V2]) -> usize {
    let mut best = 0;
    for (i, q) in pts.iter().enumerate() {
        let b = pts[best];
        if q.y < b.y || (q.y == b.y && q.x < b.x) {
            best = i;
        }
    }
    best
}

/// A pedestrian's ellipse: full extent `l` along its heading (the visible face) and `w`
/// across it (the shoulders).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipse {
    /// Half extent along the heading.
    pub a: f64,
    /// Half extent across the heading.
    pub b: f64,
    /// Unit heading (cos, sin).
    pub heading: V2,
}

impl Ellipse {
    /// Ellipse of full sizes `l` x `w`; sizes below [`MIN_SIZE`] or non-finite become
    /// [`MIN_SIZE`], and a zero or non-finite heading becomes the x axis.
    pub fn new(l: f64, w: f64, heading: V2) -> Self {
        let size = |s: f64| {
            if s.is_finite() && s > MIN_SIZE {
                s
            } else {
                MIN_SIZE
            }
        };
        let norm = heading.norm();
        let heading = if norm.is_finite() && norm > 1e-12 {
            heading / norm
        } else {
            V2::new(1.0, 0.0)
        };
        Self {
            a: 0.5 * size(l),
            b: 0.5 * size(w),
            heading,
        }
    }

    /// Whether the point `p` (relative to the centre) is inside the ellipse.
    pub fn contains(&self, p: V2) -> bool {
        let u = p.dot(&self.heading) / self.a;
        let v = cross(self.heading, p) / self.b;
        u * u + v * v <= 1.0
    }

    /// A counter-clockwise convex polygon with `sides` sides (clamped to 3..=[`MAX_SIDES`]) that
    /// contains the ellipse (the paper's "conservative linear approximation"): the regular
    /// polygon circumscribing the unit circle, scaled to the axes (an affine map keeps the
    /// containment) and rotated to the heading. A vertex, not a flat side, points along the
    /// heading: flat fronts make head-on pairs stall (their avoidance has no sideways
    /// component). With an even number of sides the polygon is its own reflection through the
    /// centre, bit for bit, so that two agents see their pair's obstacle as exact mirrors.
    pub fn polygon(&self, sides: usize) -> Polygon {
        let n = sides.clamp(3, MAX_SIDES);
        let step = std::f64::consts::TAU / n as f64;
        let r = 1.0 / (0.5 * step).cos();
        let (c, s) = (self.heading.x, self.heading.y);
        let mut p = Polygon::default();
        for k in 0..n {
            let q = if n % 2 == 0 && k >= n / 2 {
                -p.pts[k - n / 2]
            } else {
                let t = k as f64 * step;
                let (x, y) = (self.a * r * t.cos(), self.b * r * t.sin());
                V2::new(c * x - s * y, s * x + c * y)
            };
            p.push(q);
        }
        p
    }
}

/// Heading of a pedestrian (people are assumed to face where they walk): the direction of its
/// preferred velocity, else of its velocity, else the x axis. Facing the intended direction
/// rather than the instantaneous velocity keeps the ellipse from turning with every avoidance
/// sidestep; a turning ellipse sweeps into its neighbours, which breaks the velocity obstacles'
/// no-overlap guarantee (they assume fixed shapes).
pub fn heading(vel: V2, pref_vel: V2) -> V2 {
    const MIN_SPEED: f64 = 1e-9;
    for v in [pref_vel, vel] {
        let n = v.norm();
        if n.is_finite() && n > MIN_SPEED {
            return v / n;
        }
    }
    V2::new(1.0, 0.0)
}
