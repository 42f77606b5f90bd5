//! The detector's jitter, estimated online, and the smoothing gain it calls for.
//!
//! The innovation of a followed track (matched in this frame and the previous one) is the distance
//! from its one-frame prediction to the centre of the detection it matched, over the track's box
//! height. Its mean over all tracks and frames so far holds two parts: what the motion model
//! cannot foresee (people change pace and direction) and the detector's own noise (a box that
//! flickers between neighbours, or is wider than the person). With `floor` the part motion alone
//! explains, the detector's share of the innovation's square is `1 - (floor / mean)²`: the weight a
//! matched track gives its prediction, in the manner of a Kalman gain whose measurement noise is
//! estimated from the innovations (covariance matching). A precise detector, whose innovations
//! stay near `floor`, gets no smoothing; a flickery one gets strong smoothing.

/// Innovations to see before the gain leaves 0.
pub const JITTER_WARM_UP: u64 = 50;

/// Innovations the running mean spans at most (older ones fade exponentially beyond it).
pub const JITTER_WINDOW: u64 = 2000;

/// Running mean of the normalised innovation.
#[derive(Clone, Debug, Default)]
pub struct JitterEstimate {
    mean: f64,
    seen: u64,
}

impl JitterEstimate {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Records one innovation: `distance` pixels between prediction and detection for a box
    /// `height` pixels tall (ignored unless both are finite and the height positive).
    pub fn observe(&mut self, distance: f64, height: f64) {
        if !(distance.is_finite() && height.is_finite() && height > 0.0) {
            return;
        }
        self.seen += 1;
        let n = self.seen.min(JITTER_WINDOW) as f64;
        self.mean += (distance / height - self.mean) / n;
    }

    /// Mean normalised innovation so far (0 before any).
    pub fn mean(&self) -> f64 {
        self.mean
    }

    pub fn seen(&self) -> u64 {
        self.seen
    }

    /// Weight of the prediction in a matched track's centre: `1 - (floor / mean)²`, at least 0,
    /// and 0 during warm-up or with `floor` 0 (off).
    pub fn gain(&self, floor: f64) -> f64 {
        if floor <= 0.0 || self.seen < JITTER_WARM_UP || self.mean <= floor {
            return 0.0;
        }
        let r = floor / self.mean;
        1.0 - r * r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gain_is_zero_at_or_below_the_floor_and_rises_above_it() {
        let mut j = JitterEstimate::new();
        for _ in 0..JITTER_WARM_UP - 1 {
            j.observe(10.0, 100.0);
        }
        assert_eq!(j.gain(0.05), 0.0, "warm-up");
        j.observe(10.0, 100.0);
        assert!((j.mean() - 0.1).abs() < 1e-12);
        assert!((j.gain(0.05) - 0.75).abs() < 1e-12);
        assert_eq!(j.gain(0.1), 0.0);
        assert_eq!(j.gain(0.2), 0.0);
        assert_eq!(j.gain(0.0), 0.0, "off");
        j.observe(f64::NAN, 100.0);
        j.observe(1.0, 0.0);
        assert_eq!(j.seen(), JITTER_WARM_UP);
    }
}
