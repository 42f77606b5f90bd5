use nalgebra::Vector2;

/// One pedestrian's state `[x, v, v_pref, l, w]` in image coordinates
/// (pixels, and pixels per frame for velocities).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Agent {
    /// Centre of the ellipse.
    pub pos: Vector2<f64>,
    /// Current velocity.
    pub vel: Vector2<f64>,
    /// Preferred velocity: where the pedestrian would go without neighbours.
    pub pref_vel: Vector2<f64>,
    /// Ellipse extent along the direction of motion (visible face height), full length.
    pub l: f64,
    /// Ellipse extent across the direction of motion (shoulder width), full length.
    pub w: f64,
}

impl Agent {
    pub fn new(
        pos: Vector2<f64>,
        vel: Vector2<f64>,
        pref_vel: Vector2<f64>,
        l: f64,
        w: f64,
    ) -> Self {
        Self {
            pos,
            vel,
            pref_vel,
            l,
            w,
        }
    }
}
