//! The image's global motion in one frame, estimated from the tracks themselves.
//!
//! A camera that moves (pans, shakes, is pushed along) shifts every person in the image by the
//! same amount on top of their own walk, and no motion model foresees it. The tracks matched this
//! frame measure it: the offset from a track's one-frame prediction to its matched detection is
//! the person's own surprise plus the camera's, and the part every track shares is the camera's.
//! How much of the frame's mean offset is shared is learnt online ([`CameraMotion::observe`]);
//! with `camera_motion_min_tracks` every unmatched track moves by the estimate, so that a lost
//! person's predicted box follows the scene instead of drifting off with the camera. On a still
//! camera the shared part is near zero and so is the estimate.

/// Frames with at least two offsets to see before the estimate leaves zero.
pub const CAMERA_WARM_UP: u64 = 20;

/// Frames the running variances span at most (older ones fade exponentially beyond it).
pub const CAMERA_WINDOW: u64 = 500;

/// The camera's shift per frame, learnt online: how much of the offsets' shared part is the
/// camera's and how much is the people's own noise (see [`CameraMotion::observe`]).
#[derive(Clone, Debug, Default)]
pub struct CameraMotion {
    /// Running mean, per axis, of the squared mean offset less its noise share (`c²` below).
    shared: [f64; 2],
    /// Running mean, per axis, of the offsets' variance about their frame's mean (`e²`).
    spread: [f64; 2],
    seen: u64,
}

impl CameraMotion {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// This frame's camera shift from `offsets` (pixels `[dx, dy]`, one per track matched in
    /// this frame and the previous one: detection centre less one-frame predicted centre), or
    /// `None` when fewer than `min_tracks` (and 2) finite offsets are given or `min_tracks` is
    /// 0 (off).
    ///
    /// Each offset is the camera's shift `c` plus the person's own surprise and the detector's
    /// noise `e`, independent across people. Per axis, the frame's mean offset `m` over `n`
    /// tracks then has `E[m²] = c² + e²/n`, and the offsets' variance about `m` estimates `e²`.
    /// Both are averaged over frames, and the shift is the shrunk mean `g m`, with
    /// `g = c² / (c² + e²/n)`: an empirical-Bayes estimate, near `m` where the camera moves far
    /// more than people's paths wobble and near 0 on a still camera.
    pub fn observe(&mut self, offsets: &[[f64; 2]], min_tracks: usize) -> Option<[f64; 2]> {
        if min_tracks == 0 {
            return None;
        }
        let finite: Vec<[f64; 2]> = offsets
            .iter()
            .copied()
            .filter(|o| o[0].is_finite() && o[1].is_finite())
            .collect();
        let n = finite.len();
        if n < min_tracks.max(2) {
            return None;
        }
        self.seen += 1;
        let w = 1.0 / self.seen.min(CAMERA_WINDOW) as f64;
        let nf = n as f64;
        let mut shift = [0.0; 2];
        for k in 0..2 {
            let m = finite.iter().map(|o| o[k]).sum::<f64>() / nf;
            let var = finite.iter().map(|o| (o[k] - m).powi(2)).sum::<f64>() / (nf - 1.0);
            self.spread[k] += (var - self.spread[k]) * w;
            self.shared[k] += (m * m - var / nf - self.shared[k]) * w;
            let c2 = self.shared[k].max(0.0);
            let noise = self.spread[k] / nf;
            if self.seen >= CAMERA_WARM_UP && c2 > 0.0 {
                shift[k] = m * c2 / (c2 + noise);
            }
        }
        Some(shift)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small deterministic generator in [-1, 1).
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        }
    }

    /// Frames of `n` offsets: a camera shift of up to `camera` pixels shared by all, plus up
    /// to `own` pixels each on its own.
    fn frames(seed: u64, count: usize, n: usize, camera: f64, own: f64) -> Vec<Vec<[f64; 2]>> {
        let mut r = Lcg(seed);
        (0..count)
            .map(|_| {
                let c = [camera * r.next(), camera * r.next()];
                (0..n)
                    .map(|_| [c[0] + own * r.next(), c[1] + own * r.next()])
                    .collect()
            })
            .collect()
    }

    #[test]
    fn the_shift_is_the_mean_shrunk_by_plain_means_over_the_frames() {
        // Fewer frames than the window: the running means are plain means, recomputed here
        // from scratch for every frame.
        let all = frames(3, 200, 4, 5.0, 3.0);
        let mut cam = CameraMotion::new();
        for (t, offs) in all.iter().enumerate() {
            let got = cam.observe(offs, 2).unwrap();
            for k in 0..2 {
                let (mut shared, mut spread) = (0.0, 0.0);
                let mut m_now = 0.0;
                for f in &all[..=t] {
                    let n = f.len() as f64;
                    let m = f.iter().map(|o| o[k]).sum::<f64>() / n;
                    let var = f.iter().map(|o| (o[k] - m) * (o[k] - m)).sum::<f64>() / (n - 1.0);
                    shared += m * m - var / n;
                    spread += var;
                    m_now = m;
                }
                let frames_seen = (t + 1) as f64;
                let (c2, e2) = (shared / frames_seen, spread / frames_seen);
                let want = if t + 1 >= CAMERA_WARM_UP as usize && c2 > 0.0 {
                    m_now * c2 / (c2 + e2 / 4.0)
                } else {
                    0.0
                };
                assert!(
                    (got[k] - want).abs() < 1e-9,
                    "frame {t}, axis {k}: {got:?} vs {want}"
                );
            }
        }
    }

    #[test]
    fn a_moving_camera_is_followed_and_a_still_one_is_not() {
        // Camera shifts of up to 8 px against people's own 1 px: the estimate is the shared
        // shift to within the people's noise.
        let mut cam = CameraMotion::new();
        let mut err = 0.0;
        let shaky = frames(5, 300, 3, 8.0, 1.0);
        for (t, offs) in shaky.iter().enumerate() {
            let got = cam.observe(offs, 2).unwrap();
            let mean_x = offs.iter().map(|o| o[0]).sum::<f64>() / 3.0;
            if t >= CAMERA_WARM_UP as usize {
                err += (got[0] - mean_x).abs();
            }
        }
        let err = err / (300 - CAMERA_WARM_UP) as f64;
        assert!(err < 0.1, "mean distance to the shared shift {err}");
        // A still camera (no shared shift), people wobbling 4 px: the estimate stays far
        // smaller than the frame's mean offset.
        let mut cam = CameraMotion::new();
        let (mut est, mut raw) = (0.0, 0.0);
        for offs in &frames(9, 300, 3, 0.0, 4.0) {
            let got = cam.observe(offs, 2).unwrap();
            est += got[0].abs();
            raw += (offs.iter().map(|o| o[0]).sum::<f64>() / 3.0).abs();
        }
        assert!(est < 0.25 * raw, "estimate {est} vs mean offsets {raw}");
    }

    #[test]
    fn too_few_tracks_or_off_gives_none() {
        let mut cam = CameraMotion::new();
        let offsets = [[1.0, 2.0], [f64::NAN, 0.0], [3.0, 4.0]];
        assert_eq!(cam.observe(&offsets, 3), None);
        assert_eq!(cam.observe(&offsets, 0), None);
        assert_eq!(cam.observe(&offsets[..1], 1), None);
        // Before the warm-up: no shift.
        assert_eq!(cam.observe(&offsets, 2), Some([0.0, 0.0]));
    }
}
