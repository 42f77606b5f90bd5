//! One track's state: the FRVO agent (centre, velocity, preferred velocity, ellipse from the box),
//! lifecycle counters and a bounded, summarised appearance gallery.
//!
//! Mapping from a box of size `w x h` to the FRVO ellipse: `l = ellipse_l_scale * h` (the visible
//! face, along the motion) and `w = ellipse_w_scale * w` (the shoulders, across it); the agent sits
//! at the box centre. Velocities are in pixels per frame.

use crate::cost::{box_from_centre, centre, max_dot, normalise, BBox};
use crate::params::TrackerParams;
use nalgebra::Vector2;
use std::collections::VecDeque;

#[derive(Clone, Debug)]
pub(crate) struct Track {
    /// Public id, assigned when the track is confirmed (0 while tentative).
    pub id: u64,
    pub confirmed: bool,
    /// Current centre estimate (the last match, or the prediction while unmatched).
    pub pos: Vector2<f64>,
    pub vel: Vector2<f64>,
    pub pref_vel: Vector2<f64>,
    pub w: f64,
    pub h: f64,
    /// The box reported for the current frame.
    pub bbox: BBox,
    /// This frame's prediction: velocity from the motion model and the box it leads to.
    pub pred_vel: Vector2<f64>,
    /// This frame's predicted box size over the current one (1 in image space).
    pub pred_scale: f64,
    pub predicted: BBox,
    pub last_obs: BBox,
    pub last_obs_frame: u64,
    /// The frame of the track's first detection.
    pub born: u64,
    /// Recent matched centres `(frame, centre)`, for the preferred velocity.
    history: VecDeque<(u64, Vector2<f64>)>,
    pub hits: u32,
    pub time_since_update: u32,
    /// Unmatched this frame and hidden behind people nearer the camera.
    pub occluded: bool,
    /// Whether the track was occluded in the first frame of its current gap (unmatched run).
    pub gap_occluded: bool,
    pub score: f64,
    /// Running mean of the matched detections' width over height.
    pub aspect: f64,
    /// Detection matched in the current frame.
    pub det_index: Option<usize>,
    gallery: Gallery,
}

/// Matches the running mean of a track's aspect ratio averages over (then a moving average).
const ASPECT_WINDOW: f64 = 30.0;

fn to_vec(c: [f64; 2]) -> Vector2<f64> {
    Vector2::new(c[0], c[1])
}

impl Track {
    pub fn new(
        det_index: usize,
        bbox: BBox,
        score: f64,
        frame: u64,
        embedding: Option<&[f32]>,
        gallery_size: usize,
    ) -> Self {
        let c = to_vec(centre(&bbox));
        let mut t = Self {
            id: 0,
            confirmed: false,
            pos: c,
            vel: Vector2::zeros(),
            pref_vel: Vector2::zeros(),
            w: bbox[2] - bbox[0],
            h: bbox[3] - bbox[1],
            bbox,
            pred_vel: Vector2::zeros(),
            pred_scale: 1.0,
            predicted: bbox,
            last_obs: bbox,
            last_obs_frame: frame,
            born: frame,
            history: VecDeque::from([(frame, c)]),
            hits: 1,
            time_since_update: 0,
            occluded: false,
            gap_occluded: false,
            score,
            aspect: (bbox[2] - bbox[0]) / (bbox[3] - bbox[1]).max(f64::MIN_POSITIVE),
            det_index: Some(det_index),
            gallery: Gallery::new(gallery_size),
        };
        if let Some(e) = embedding {
            t.gallery.add(e);
        }
        t
    }

    /// The track as a motion-model agent.
    pub fn agent(&self, p: &TrackerParams) -> frvo::Agent {
        frvo::Agent::new(
            self.pos,
            self.vel,
            self.pref_vel,
            p.ellipse_l_scale * self.h,
            p.ellipse_w_scale * self.w,
        )
    }

    /// Stores this frame's prediction: the centre's velocity and the box's change of size
    /// (non-finite values: no motion, no change).
    pub fn set_prediction(&mut self, v: Vector2<f64>, scale: f64) {
        let finite = v.iter().all(|x| x.is_finite()) && scale.is_finite() && scale > 0.0;
        (self.pred_vel, self.pred_scale) = if finite {
            (v, scale)
        } else {
            (Vector2::zeros(), 1.0)
        };
        let c = self.pos + self.pred_vel;
        let s = self.pred_scale;
        self.predicted = box_from_centre([c.x, c.y], s * self.w, s * self.h);
    }

    pub fn predicted_centre(&self) -> [f64; 2] {
        centre(&self.predicted)
    }

    /// Whether the track is tentative and missed a frame (kept by `tentative_max_age`).
    pub fn is_lingering(&self) -> bool {
        !self.confirmed && self.time_since_update > 0
    }

    /// Whether the track was matched in the previous frame too (called before this frame's
    /// match is applied): its one-frame prediction measures the detector's jitter.
    pub fn is_followed(&self) -> bool {
        self.time_since_update == 0 && self.hits > 1
    }

    /// Updates the state from a matched detection in `frame`. `adaptive` is the weight of the
    /// prediction the detector's jitter calls for (`jitter_floor`), applied to a followed track
    /// (matched in the previous frame too): to its state, or with `jitter_smoothing_state` false
    /// only to its reported box.
    #[allow(clippy::too_many_arguments)]
    pub fn apply_match(
        &mut self,
        det_index: usize,
        det: BBox,
        score: f64,
        frame: u64,
        embedding: Option<&[f32]>,
        adaptive: f64,
        p: &TrackerParams,
    ) {
        let followed = self.is_followed();
        let predicted = to_vec(centre(&self.predicted));
        let (state_w, sp) = match (followed, p.jitter_smoothing_state) {
            (false, _) => (0.0, 0.0),
            (true, true) => (adaptive, p.position_smoothing),
            (true, false) => (0.0, p.position_smoothing.max(adaptive)),
        };
        let raw = to_vec(centre(&det));
        let c = raw * (1.0 - state_w) + predicted * state_w;

        let gap = frame.saturating_sub(self.last_obs_frame).max(1) as f64;
        // Observation-centric: the velocity spans the gap since the last real observation,
        // not the drifted prediction, and the preferred velocity is measured on the detections
        // (a smoothed state does not feed back into the velocity).
        let observed = (raw - to_vec(centre(&self.last_obs))) / gap;
        self.vel = if self.history.len() == 1 {
            observed
        } else {
            observed * p.velocity_smoothing + self.vel * (1.0 - p.velocity_smoothing)
        };
        self.history.push_back((frame, raw));
        while self.history.len() > p.pref_window + 1 {
            self.history.pop_front();
        }
        let (f0, c0) = self.history[0];
        self.pref_vel = if frame > f0 {
            (raw - c0) / (frame - f0) as f64
        } else {
            self.vel
        };
        let s = p.size_smoothing;
        let (dw, dh) = (det[2] - det[0], det[3] - det[1]);
        let aspect = dw / dh.max(f64::MIN_POSITIVE);
        if aspect.is_finite() {
            self.aspect += (aspect - self.aspect) / f64::from(self.hits + 1).min(ASPECT_WINDOW);
        }
        // The reported centre: the state's, pulled toward this frame's prediction when the
        // track was also matched in the previous frame.
        if s > 0.0 || sp > 0.0 || state_w > 0.0 {
            self.w = s * self.w + (1.0 - s) * dw;
            self.h = s * self.h + (1.0 - s) * dh;
            let shown = c * (1.0 - sp) + predicted * sp;
            self.bbox = box_from_centre([shown.x, shown.y], self.w, self.h);
        } else {
            (self.w, self.h) = (dw, dh);
            self.bbox = det;
        }
        self.pos = c;
        self.last_obs = det;
        self.last_obs_frame = frame;
        self.hits += 1;
        self.time_since_update = 0;
        self.occluded = false;
        self.score = score;
        self.det_index = Some(det_index);
        if let Some(e) = embedding {
            self.gallery.add(e);
        }
    }

    /// No detection this frame: move to the prediction; with `coast_aspect` the reported box is
    /// at least as wide as the track's mean aspect ratio makes its height, and with
    /// `coast_aspect_state` the track's own width too; with `whole_aspect` (the scene's aspect
    /// of a person seen whole, `coast_aspect_quantile`) the reported box is at least that wide.
    pub fn coast(&mut self, p: &TrackerParams, whole_aspect: Option<f64>) {
        self.pos += self.pred_vel;
        self.vel = self.pred_vel;
        self.w *= self.pred_scale;
        self.h *= self.pred_scale;
        self.bbox = self.predicted;
        let wide = self.aspect * (self.bbox[3] - self.bbox[1]);
        if p.coast_aspect && wide > self.bbox[2] - self.bbox[0] && wide.is_finite() {
            let c = centre(&self.bbox);
            self.bbox = box_from_centre(c, wide, self.bbox[3] - self.bbox[1]);
            if p.coast_aspect_state {
                self.w = self.w.max(self.aspect * self.h);
            }
        }
        if let Some(a) = whole_aspect {
            let whole = a * (self.bbox[3] - self.bbox[1]);
            if whole > self.bbox[2] - self.bbox[0] && whole.is_finite() {
                self.bbox = box_from_centre(centre(&self.bbox), whole, self.bbox[3] - self.bbox[1]);
            }
        }
        self.time_since_update += 1;
        if self.time_since_update == 1 {
            self.gap_occluded = self.occluded;
        }
        self.det_index = None;
    }

    pub fn has_gallery(&self) -> bool {
        self.gallery.rows > 0
    }

    /// Smallest cosine distance from `e` (unit length) to the gallery.
    pub fn appearance_distance(&self, e: &[f32]) -> f64 {
        self.gallery.distance(e)
    }

    /// Smallest cosine distance between a row of this track's gallery and a row of `other`'s
    /// (1 where either is empty).
    pub fn gallery_distance(&self, other: &Track) -> f64 {
        self.gallery
            .rows()
            .map(|r| other.gallery.distance(r))
            .fold(1.0, f64::min)
    }
}

/// Rows a gallery compares against at most, whatever its capacity.
pub(crate) const GALLERY_ROWS: usize = 8;

/// A track's appearance: the last `capacity` embeddings (unit length), summarised in at most
/// [`GALLERY_ROWS`] rows. Each row is the normalised mean of `block` consecutive embeddings,
/// `block = ceil(capacity / GALLERY_ROWS)`; when full, the oldest row gives way. With a capacity
/// of at most [`GALLERY_ROWS`] every row is one embedding, as stored. An all-zero embedding (no
/// appearance) is not stored.
#[derive(Clone, Debug)]
struct Gallery {
    /// `rows` unit-length rows of the embeddings' dimension, row-major.
    data: Vec<f32>,
    rows: usize,
    max_rows: usize,
    /// Embeddings per row.
    block: usize,
    /// The row being filled, and how many embeddings it holds so far (0: start a new row).
    current: usize,
    filled: usize,
    /// Sum of the current row's embeddings (only while `block > 1`).
    sum: Vec<f32>,
}

impl Gallery {
    fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        let block = capacity.div_ceil(GALLERY_ROWS);
        Self {
            data: Vec::new(),
            rows: 0,
            max_rows: capacity.div_ceil(block),
            block,
            current: 0,
            filled: 0,
            sum: Vec::new(),
        }
    }

    fn add(&mut self, e: &[f32]) {
        let d = e.len();
        if d == 0 || e.iter().all(|&x| x == 0.0) {
            return;
        }
        if self.filled == 0 {
            // Start a row: append while there is room, else overwrite the oldest.
            if self.rows < self.max_rows {
                self.current = self.rows;
                self.data.extend_from_slice(e);
                self.rows += 1;
            } else {
                self.current = (self.current + 1) % self.rows;
            }
            self.sum.clear();
        }
        let row = &mut self.data[self.current * d..(self.current + 1) * d];
        if self.block == 1 {
            row.copy_from_slice(e);
        } else {
            if self.sum.is_empty() {
                self.sum.resize(d, 0.0);
            }
            self.sum.iter_mut().zip(e).for_each(|(s, &x)| *s += x);
            row.copy_from_slice(&self.sum);
            normalise(row);
        }
        self.filled = (self.filled + 1) % self.block;
    }

    /// The rows (unit length).
    fn rows(&self) -> impl Iterator<Item = &[f32]> {
        let d = self.data.len().checked_div(self.rows).unwrap_or(1).max(1);
        self.data.chunks_exact(d).take(self.rows)
    }

    /// Smallest cosine distance from `e` (unit length) to the rows.
    fn distance(&self, e: &[f32]) -> f64 {
        let d = e.len();
        if d == 0 {
            return 1.0;
        }
        (1.0 - f64::from(max_dot(&self.data, e))).max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(seed: u64, d: usize) -> Vec<f32> {
        // A small deterministic generator: the test needs spread-out vectors, not randomness.
        let mut x = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut v: Vec<f32> = (0..d)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((x >> 33) as f32 / (1u64 << 31) as f32) - 0.5
            })
            .collect();
        normalise(&mut v);
        v
    }

    /// Cosine distance by the definition, in f64.
    fn cosine(a: &[f64], b: &[f32]) -> f64 {
        let dot: f64 = a.iter().zip(b).map(|(x, &y)| x * f64::from(y)).sum();
        let na = a.iter().map(|x| x * x).sum::<f64>().sqrt();
        let nb = b
            .iter()
            .map(|&y| f64::from(y) * f64::from(y))
            .sum::<f64>()
            .sqrt();
        1.0 - dot / (na * nb)
    }

    /// The gallery's answer by brute force: the last `capacity` embeddings cut into blocks of
    /// `block` in order of arrival, each block's mean a row, the nearest row wins.
    fn brute_force(history: &[Vec<f32>], capacity: usize, e: &[f32]) -> f64 {
        let block = capacity.div_ceil(GALLERY_ROWS);
        let rows = capacity.div_ceil(block);
        let blocks: Vec<&[Vec<f32>]> = history.chunks(block).collect();
        let kept = &blocks[blocks.len().saturating_sub(rows)..];
        kept.iter()
            .map(|b| {
                let mut mean = vec![0.0f64; e.len()];
                for v in b.iter() {
                    mean.iter_mut()
                        .zip(v)
                        .for_each(|(m, &x)| *m += f64::from(x));
                }
                cosine(&mean, e)
            })
            .fold(f64::INFINITY, f64::min)
            .max(0.0)
    }

    #[test]
    fn gallery_matches_brute_force_block_means() {
        let d = 37;
        for capacity in [1, 3, 8, 9, 20, 100] {
            let mut g = Gallery::new(capacity);
            let mut history = Vec::new();
            for k in 0..250u64 {
                let e = unit(k, d);
                g.add(&e);
                history.push(e);
                assert!(g.rows <= GALLERY_ROWS);
                for probe in [unit(1000 + k, d), history[history.len() / 2].clone()] {
                    let want = brute_force(&history, capacity, &probe);
                    let got = g.distance(&probe);
                    assert!(
                        (got - want).abs() < 1e-5,
                        "capacity {capacity}, k {k}: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn small_gallery_keeps_the_embeddings_exactly() {
        let d = 16;
        let mut g = Gallery::new(3);
        for k in 0..5u64 {
            g.add(&unit(k, d));
        }
        // The last three, bit for bit (in ring order), the first two gone.
        let rows: Vec<Vec<f32>> = g.data.chunks_exact(d).map(<[f32]>::to_vec).collect();
        for k in 2..5u64 {
            assert!(rows.contains(&unit(k, d)));
        }
        assert!(!rows.contains(&unit(0, d)) && !rows.contains(&unit(1, d)));
    }

    #[test]
    fn gallery_distance_is_the_nearest_pair_of_rows() {
        let d = 11;
        let track = |seeds: &[u64]| {
            let mut t = Track::new(0, [0.0, 0.0, 1.0, 2.0], 1.0, 1, None, 3);
            for &k in seeds {
                t.gallery.add(&unit(k, d));
            }
            t
        };
        let (a, b) = (track(&[1, 2, 3, 4]), track(&[5, 6]));
        let rows = |t: &Track| t.gallery.rows().map(<[f32]>::to_vec).collect::<Vec<_>>();
        assert_eq!(rows(&a).len(), 3);
        let want = rows(&a)
            .iter()
            .flat_map(|x| {
                rows(&b).into_iter().map(move |y| {
                    let x64: Vec<f64> = x.iter().map(|&v| f64::from(v)).collect();
                    cosine(&x64, &y)
                })
            })
            .fold(f64::INFINITY, f64::min);
        assert!((a.gallery_distance(&b) - want).abs() < 1e-6);
        assert!((b.gallery_distance(&a) - want).abs() < 1e-6);
        assert_eq!(a.gallery_distance(&track(&[])), 1.0);
    }

    #[test]
    fn zero_embedding_is_not_stored() {
        let mut g = Gallery::new(4);
        g.add(&[0.0; 8]);
        assert_eq!(g.rows, 0);
        g.add(&unit(1, 8));
        g.add(&[0.0; 8]);
        assert_eq!(g.rows, 1);
    }
}
