//! One track's state: the FRVO agent (centre, velocity, preferred velocity, ellipse from the box),
//! lifecycle counters and a bounded appearance gallery.
//!
//! Mapping from a box of size `w x h` to the FRVO ellipse: `l = ellipse_l_scale * h` (the visible
//! face, along the motion) and `w = ellipse_w_scale * w` (the shoulders, across it); the agent sits
//! at the box centre. Velocities are in pixels per frame.

use crate::cost::{box_from_centre, centre, dot, BBox};
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
    pub predicted: BBox,
    pub last_obs: BBox,
    pub last_obs_frame: u64,
    /// Recent matched centres `(frame, centre)`, for the preferred velocity.
    history: VecDeque<(u64, Vector2<f64>)>,
    pub hits: u32,
    pub time_since_update: u32,
    /// Unmatched this frame and hidden behind people nearer the camera.
    pub occluded: bool,
    pub score: f64,
    /// Detection matched in the current frame.
    pub det_index: Option<usize>,
    /// Ring buffer of unit-length embeddings, `gallery_len` rows of the tracker's dimension.
    gallery: Vec<f32>,
    gallery_len: usize,
    gallery_next: usize,
}

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
            predicted: bbox,
            last_obs: bbox,
            last_obs_frame: frame,
            history: VecDeque::from([(frame, c)]),
            hits: 1,
            time_since_update: 0,
            occluded: false,
            score,
            det_index: Some(det_index),
            gallery: Vec::new(),
            gallery_len: 0,
            gallery_next: 0,
        };
        if let Some(e) = embedding {
            t.add_embedding(e, gallery_size);
        }
        t
    }

    pub fn agent(&self, p: &TrackerParams) -> frvo::Agent {
        frvo::Agent::new(
            self.pos,
            self.vel,
            self.pref_vel,
            p.ellipse_l_scale * self.h,
            p.ellipse_w_scale * self.w,
        )
    }

    /// Stores this frame's prediction from the motion model's velocity.
    pub fn set_prediction(&mut self, v: Vector2<f64>) {
        self.pred_vel = if v.iter().all(|x| x.is_finite()) {
            v
        } else {
            Vector2::zeros()
        };
        let c = self.pos + self.pred_vel;
        self.predicted = box_from_centre([c.x, c.y], self.w, self.h);
    }

    pub fn predicted_centre(&self) -> [f64; 2] {
        centre(&self.predicted)
    }

    /// Updates the state from a matched detection in `frame`.
    pub fn apply_match(
        &mut self,
        det_index: usize,
        det: BBox,
        score: f64,
        frame: u64,
        embedding: Option<&[f32]>,
        p: &TrackerParams,
    ) {
        let c = to_vec(centre(&det));
        let gap = frame.saturating_sub(self.last_obs_frame).max(1) as f64;
        // Observation-centric: the velocity spans the gap since the last real observation,
        // not the drifted prediction.
        let observed = (c - to_vec(centre(&self.last_obs))) / gap;
        self.vel = if self.history.len() == 1 {
            observed
        } else {
            observed * p.velocity_smoothing + self.vel * (1.0 - p.velocity_smoothing)
        };
        self.history.push_back((frame, c));
        while self.history.len() > p.pref_window + 1 {
            self.history.pop_front();
        }
        let (f0, c0) = self.history[0];
        self.pref_vel = if frame > f0 {
            (c - c0) / (frame - f0) as f64
        } else {
            self.vel
        };
        let s = p.size_smoothing;
        let (dw, dh) = (det[2] - det[0], det[3] - det[1]);
        if s > 0.0 {
            self.w = s * self.w + (1.0 - s) * dw;
            self.h = s * self.h + (1.0 - s) * dh;
            self.bbox = box_from_centre([c.x, c.y], self.w, self.h);
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
            self.add_embedding(e, p.gallery_size);
        }
    }

    /// No detection this frame: move to the prediction.
    pub fn coast(&mut self) {
        self.pos += self.pred_vel;
        self.vel = self.pred_vel;
        self.bbox = self.predicted;
        self.time_since_update += 1;
        self.det_index = None;
    }

    fn add_embedding(&mut self, e: &[f32], capacity: usize) {
        let d = e.len();
        if self.gallery_len < capacity {
            self.gallery.extend_from_slice(e);
            self.gallery_len += 1;
        } else {
            // Full: overwrite the oldest row.
            let k = self.gallery_next;
            self.gallery[k * d..(k + 1) * d].copy_from_slice(e);
            self.gallery_next = (k + 1) % self.gallery_len;
        }
    }

    pub fn has_gallery(&self) -> bool {
        self.gallery_len > 0
    }

    /// Smallest cosine distance from `e` (unit length) to the gallery (unit-length rows).
    pub fn appearance_distance(&self, e: &[f32]) -> f64 {
        let d = e.len();
        let best = self
            .gallery
            .chunks_exact(d)
            .map(|g| dot(g, e))
            .fold(f32::NEG_INFINITY, f32::max);
        (1.0 - f64::from(best)).max(0.0)
    }
}
