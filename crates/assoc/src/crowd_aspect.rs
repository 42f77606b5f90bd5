//! The width people have in this scene, learnt online from the matched detections of every track.
//!
//! A person who walks behind others is often detected cut narrow for the last frames before the
//! detector loses them, and a person hidden for most of their track may never have been seen
//! whole, so a lost track's own aspect ratio (`coast_aspect`) can stay narrow. People in one
//! scene share a shape: a high quantile of the aspect ratios (width over height) of all matched
//! detections is the aspect of a person seen whole. With `coast_aspect_quantile` a lost track's
//! reported box is at least as wide as that quantile makes its height.

use std::collections::VecDeque;

/// Matched detections' aspect ratios remembered (the most recent ones).
pub const ASPECT_SAMPLES: usize = 2000;

/// Aspect ratios to see before the quantile is used.
pub const ASPECT_WARM_UP: usize = 50;

/// The aspect ratios of the last [`ASPECT_SAMPLES`] matched detections.
#[derive(Clone, Debug, Default)]
pub struct CrowdAspect {
    seen: VecDeque<f64>,
}

impl CrowdAspect {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn reset(&mut self) {
        self.seen.clear();
    }

    /// Records the box `[x1, y1, x2, y2]` of a matched detection (ignored unless its aspect
    /// ratio is finite and positive).
    pub fn observe(&mut self, b: &[f64; 4]) {
        let a = (b[2] - b[0]) / (b[3] - b[1]);
        if !(a.is_finite() && a > 0.0) {
            return;
        }
        if self.seen.len() == ASPECT_SAMPLES {
            self.seen.pop_front();
        }
        self.seen.push_back(a);
    }

    /// The `q` quantile (lower order statistic at `q (n - 1)`) of the aspect ratios seen; `None`
    /// before [`ASPECT_WARM_UP`] of them, or for `q` <= 0 (off).
    pub fn quantile(&self, q: f64) -> Option<f64> {
        if q <= 0.0 || self.seen.len() < ASPECT_WARM_UP {
            return None;
        }
        let mut v: Vec<f64> = self.seen.iter().copied().collect();
        let k = ((q.min(1.0) * (v.len() - 1) as f64).floor() as usize).min(v.len() - 1);
        let (_, x, _) = v.select_nth_unstable_by(k, f64::total_cmp);
        Some(*x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantile_is_the_order_statistic_of_the_last_samples() {
        let mut c = CrowdAspect::new();
        // Widths 1..=60 on height 100: aspects 0.01..0.60.
        for w in 1..=60 {
            c.observe(&[0.0, 0.0, f64::from(w), 100.0]);
        }
        // Brute force: sort and index.
        let mut sorted: Vec<f64> = (1..=60).map(|w| f64::from(w) / 100.0).collect();
        sorted.sort_by(f64::total_cmp);
        for q in [0.1, 0.5, 0.9, 1.0] {
            let k = (q * 59.0_f64).floor() as usize;
            assert_eq!(c.quantile(q), Some(sorted[k]), "q {q}");
        }
        assert_eq!(c.quantile(0.0), None);
        // Degenerate boxes are not counted.
        c.observe(&[0.0, 0.0, 10.0, 0.0]);
        c.observe(&[0.0, 0.0, f64::NAN, 10.0]);
        assert_eq!(c.seen.len(), 60);
    }

    #[test]
    fn only_the_last_samples_count_and_warm_up_holds_it_off() {
        let mut c = CrowdAspect::new();
        for _ in 0..ASPECT_WARM_UP - 1 {
            c.observe(&[0.0, 0.0, 40.0, 100.0]);
        }
        assert_eq!(c.quantile(0.9), None);
        c.observe(&[0.0, 0.0, 40.0, 100.0]);
        assert_eq!(c.quantile(0.9), Some(0.4));
        for _ in 0..ASPECT_SAMPLES {
            c.observe(&[0.0, 0.0, 20.0, 100.0]);
        }
        assert_eq!(c.quantile(1.0), Some(0.2));
    }
}
