//! The DensePeds online tracker: per frame, predict every track with the motion model (all live
//! tracks stepped together, which is where crowd interaction enters), then associate in stages,
//! each solved optimally:
//!
//! 1. appearance: cosine distance to the track's gallery (<= lambda; <= `appearance_apart`
//!    too for a detection that does not overlap the predicted box), among detections within rho
//!    of the predicted centre (only when embeddings are given);
//! 2. motion: IoU between predicted boxes and the remaining detections (>= `iou_threshold`);
//! 3. ByteTrack-style second pass: low-score detections can extend (never start) tracks (at a
//!    smaller overlap, `thresholded_low_iou`, where the detector thresholds its own output
//!    and only the quantile floor made them low);
//! 4. OC-SORT-style recovery of lost tracks by their last observed box;
//! 5. tentative tracks that missed a frame (`tentative_max_age`): low-score detections at the
//!    second pass's overlap, after every other track has had its choice;
//!
//! then update, age and delete tracks, let a young track take a lost one's id where their
//! appearance agrees ([`crate::reid`], `reid_newborn`), and start new ones. An unmatched
//! confirmed track is classified from the scene ([`crate::occlusion`]): occluded ones keep
//! being predicted among their neighbours and reported, those that left the image are deleted.

use crate::amodal_width::widen_occluded;
use crate::cost::{centre, iou, normalise_rows, validate_boxes, BBox, MAX_DETECTIONS_PER_FRAME};
use crate::crowd_aspect::CrowdAspect;
use crate::jitter::JitterEstimate;
use crate::lap::{Edge, SparseMatcher};
use crate::lost_report::LostReport;
use crate::occlusion::{classify, complete, Scene, Unmatched};
use crate::params::TrackerParams;
use crate::perspective::{GroundMap, Perspective};
use crate::predict::predict;
use crate::reid::merge_newborn;
use crate::score_scale::ScoreScaler;
use crate::track::Track;
use crate::TrackError;
use frvo::{make_model, MotionModel};

/// Embeddings for one frame: `data` holds `N` rows of `dim` values, row-major.
#[derive(Clone, Copy, Debug)]
pub struct Embeddings<'a> {
    pub data: &'a [f32],
    pub dim: usize,
}

/// One reported track.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackOutput {
    /// Positive id, stable over the track's life, assigned in order of confirmation.
    pub id: u64,
    pub bbox: BBox,
    /// Score of the last matched detection.
    pub score: f64,
    /// Index of the detection matched this frame, `None` when the track was not matched.
    pub det_index: Option<usize>,
}

/// Online multi-pedestrian tracker. Deterministic: the same inputs give the same ids.
pub struct Tracker {
    params: TrackerParams,
    model: Box<dyn MotionModel>,
    tracks: Vec<Track>,
    next_id: u64,
    frame: u64,
    emb_dim: Option<usize>,
    matcher: SparseMatcher,
    /// Image size `[width, height]` when the caller gave it.
    image_size: Option<[f64; 2]>,
    /// The scores seen, which place the score thresholds (`score_scale`).
    scores_seen: ScoreScaler,
    /// How lost tracks' gaps ended, for `output_lost_adaptive`: gaps that began in the open
    /// (`[0]`) and gaps that began occluded (`[1]`), counted apart.
    lost_report: [LostReport; 2],
    /// The ground plane seen so far (`ground_plane`).
    perspective: Perspective,
    /// The detector's jitter against the predictions (`jitter_floor`).
    jitter: JitterEstimate,
    /// The aspect ratios of matched detections (`coast_aspect_quantile`,
    /// `amodal_width_quantile`).
    crowd_aspect: CrowdAspect,
}

impl std::fmt::Debug for Tracker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tracker")
            .field("params", &self.params)
            .field("tracks", &self.tracks.len())
            .field("frame", &self.frame)
            .finish()
    }
}

/// Detections sorted by centre x, for range queries around a track.
struct DetIndex {
    /// `(centre x, detection index)` sorted.
    by_x: Vec<(f64, usize)>,
    max_half_w: f64,
}

impl DetIndex {
    fn new(boxes: &[BBox], use_det: impl Fn(usize) -> bool) -> Self {
        let mut by_x: Vec<(f64, usize)> = (0..boxes.len())
            .filter(|&j| use_det(j))
            .map(|j| (0.5 * (boxes[j][0] + boxes[j][2]), j))
            .collect();
        by_x.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let max_half_w = by_x
            .iter()
            .map(|&(_, j)| 0.5 * (boxes[j][2] - boxes[j][0]))
            .fold(0.0, f64::max);
        Self { by_x, max_half_w }
    }

    /// Detections whose centre x lies within `half` of `cx`.
    fn near(&self, cx: f64, half: f64) -> impl Iterator<Item = usize> + '_ {
        let lo = self.by_x.partition_point(|&(x, _)| x < cx - half);
        self.by_x[lo..]
            .iter()
            .take_while(move |&&(x, _)| x <= cx + half)
            .map(|&(_, j)| j)
    }
}

impl Tracker {
    pub fn new(params: TrackerParams) -> Result<Self, TrackError> {
        params.validate()?;
        let model = make_model(params.motion, params.motion_params);
        Ok(Self {
            params,
            model,
            tracks: Vec::new(),
            next_id: 1,
            frame: 0,
            emb_dim: None,
            matcher: SparseMatcher::default(),
            image_size: None,
            scores_seen: ScoreScaler::new(),
            lost_report: [LostReport::new(), LostReport::new()],
            perspective: Perspective::new(),
            jitter: JitterEstimate::new(),
            crowd_aspect: CrowdAspect::new(),
        })
    }

    pub fn params(&self) -> &TrackerParams {
        &self.params
    }

    /// The detector's mean innovation so far (distance from a followed track's one-frame
    /// prediction to its matched detection, over box height) and the weight of the prediction
    /// it calls for under `jitter_floor`.
    pub fn detector_jitter(&self) -> (f64, f64) {
        (
            self.jitter.mean(),
            self.jitter.gain(self.params.jitter_floor),
        )
    }

    /// Forgets all tracks and restarts ids at 1 (parameters are kept).
    pub fn reset(&mut self) {
        self.tracks.clear();
        self.next_id = 1;
        self.frame = 0;
        self.emb_dim = None;
        self.scores_seen.reset();
        self.lost_report.iter_mut().for_each(LostReport::reset);
        self.perspective = Perspective::new();
        self.jitter.reset();
        self.crowd_aspect.reset();
        self.model = make_model(self.params.motion, self.params.motion_params);
    }

    /// The image size `(width, height)` in pixels: with it, an unmatched track whose predicted
    /// box lies less than `left_image_inside` inside the image is deleted (it left); without it,
    /// no track is judged to have left. Kept across [`Tracker::reset`].
    pub fn set_image_size(&mut self, width: f64, height: f64) -> Result<(), TrackError> {
        if !(width > 0.0 && height > 0.0 && width.is_finite() && height.is_finite()) {
            return Err(TrackError::InvalidInput(format!(
                "image size must be positive and finite, got {width} x {height}"
            )));
        }
        self.image_size = Some([width, height]);
        Ok(())
    }

    /// Frames processed since creation or the last reset.
    pub fn frame_count(&self) -> u64 {
        self.frame
    }

    /// Live tracks, tentative ones included.
    pub fn num_tracks(&self) -> usize {
        self.tracks.len()
    }

    fn validate(
        &self,
        boxes: &[f64],
        scores: &[f64],
        emb: Option<Embeddings<'_>>,
    ) -> Result<usize, TrackError> {
        use TrackError::InvalidInput;
        let n = validate_boxes(boxes)?;
        if n > MAX_DETECTIONS_PER_FRAME {
            return Err(InvalidInput(format!(
                "{n} detections in one frame; at most {MAX_DETECTIONS_PER_FRAME} a frame are tracked"
            )));
        }
        if scores.len() != n {
            return Err(InvalidInput(format!(
                "{n} boxes but {} scores",
                scores.len()
            )));
        }
        if let Some(k) = scores.iter().position(|s| !s.is_finite()) {
            return Err(InvalidInput(format!(
                "score {k} is not finite: {}",
                scores[k]
            )));
        }
        if let Some(e) = emb {
            if e.dim == 0 {
                return Err(InvalidInput("embedding dimension must be > 0".into()));
            }
            if e.data.len() != n * e.dim {
                return Err(InvalidInput(format!(
                    "embeddings have {} values, expected {n} rows of {}",
                    e.data.len(),
                    e.dim
                )));
            }
            if let Some(d) = self.emb_dim {
                if d != e.dim {
                    return Err(InvalidInput(format!(
                        "embedding dimension changed from {d} to {} (reset the tracker first)",
                        e.dim
                    )));
                }
            }
            if let Some(k) = e.data.iter().position(|x| !x.is_finite()) {
                return Err(InvalidInput(format!(
                    "embedding of detection {} is not finite",
                    k / e.dim
                )));
            }
        }
        Ok(n)
    }

    /// Processes one frame. `boxes` is `[x1, y1, x2, y2]` per detection (flat), `scores` one per
    /// detection (any range). Returns the confirmed tracks matched this frame (plus, with
    /// `output_lost`, recently lost ones), sorted by id. Bad input is rejected before any state
    /// changes.
    pub fn update(
        &mut self,
        boxes: &[f64],
        scores: &[f64],
        embeddings: Option<Embeddings<'_>>,
    ) -> Result<Vec<TrackOutput>, TrackError> {
        let n = self.validate(boxes, scores, embeddings)?;
        self.frame += 1;
        let frame = self.frame;
        let p = self.scores_seen.scaled(&self.params, scores);
        let dets: Vec<BBox> = boxes
            .chunks_exact(4)
            .map(|b| [b[0], b[1], b[2], b[3]])
            .collect();
        let emb: Option<(Vec<f32>, usize)> = embeddings.map(|e| {
            let mut data = e.data.to_vec();
            normalise_rows(&mut data, e.dim);
            (data, e.dim)
        });
        if let Some((_, d)) = emb {
            self.emb_dim = Some(d);
        }
        let emb_row = |j: usize| emb.as_ref().map(|(data, d)| &data[j * d..(j + 1) * d]);

        // Predict: all live tracks step together through the motion model.
        let ground = self.perspective.ground().filter(|_| p.ground_plane);
        self.predict(&p, ground.as_ref());

        let high = |j: usize| scores[j] >= p.det_threshold;
        let nt = self.tracks.len();
        let mut track_det: Vec<Option<usize>> = vec![None; nt];
        let mut det_track: Vec<Option<usize>> = vec![None; n];
        let index = DetIndex::new(&dets, high);
        let mut edges: Vec<Edge> = Vec::new();

        // Stage 1: appearance among gated detections.
        if emb.is_some() {
            for (i, t) in self.tracks.iter().enumerate() {
                if !t.has_gallery() || t.is_lingering() {
                    continue;
                }
                let c = t.predicted_centre();
                let r = p.gate_radius * t.h;
                for j in index.near(c[0], r) {
                    if !within(c, &dets[j], r) {
                        continue;
                    }
                    let d = t.appearance_distance(emb_row(j).expect("embeddings present"));
                    // A detection apart from the prediction needs the stricter threshold.
                    let limit = if iou(&t.predicted, &dets[j]) > 0.0 {
                        p.appearance_threshold
                    } else {
                        p.appearance_threshold.min(p.appearance_apart)
                    };
                    if d <= limit {
                        edges.push(Edge {
                            row: i,
                            col: j,
                            cost: d,
                        });
                    }
                }
            }
            let pairs = self.matcher.solve(nt, n, &edges, p.appearance_threshold);
            record(&pairs, &mut track_det, &mut det_track);
        }

        // Stage 2: IoU of predicted boxes with the remaining high-score detections.
        let iou_edges = |tracks: &[Track],
                         track_det: &[Option<usize>],
                         det_track: &[Option<usize>],
                         index: &DetIndex,
                         use_track: &dyn Fn(&Track) -> bool,
                         track_box: &dyn Fn(&Track) -> BBox,
                         min_iou: f64,
                         edges: &mut Vec<Edge>| {
            edges.clear();
            for (i, t) in tracks.iter().enumerate() {
                if track_det[i].is_some() || !use_track(t) {
                    continue;
                }
                let tb = track_box(t);
                let c = centre(&tb);
                let r = p.gate_radius * t.h;
                let half = (0.5 * (tb[2] - tb[0]) + index.max_half_w).min(r);
                for j in index.near(c[0], half) {
                    if det_track[j].is_some() || !within(c, &dets[j], r) {
                        continue;
                    }
                    let o = iou(&tb, &dets[j]);
                    if o > 0.0 && o >= min_iou {
                        edges.push(Edge {
                            row: i,
                            col: j,
                            cost: 1.0 - o,
                        });
                    }
                }
            }
        };
        iou_edges(
            &self.tracks,
            &track_det,
            &det_track,
            &index,
            &|t| !t.is_lingering(),
            &|t| t.predicted,
            p.iou_threshold,
            &mut edges,
        );
        let pairs = self.matcher.solve(nt, n, &edges, 1.0 - p.iou_threshold);
        record(&pairs, &mut track_det, &mut det_track);

        // Stage 3: low-score detections for tracks unmatched for at most `low_max_age` frames.
        let low_index = DetIndex::new(&dets, |j| {
            p.second_pass && scores[j] >= p.low_threshold && scores[j] < p.det_threshold
        });
        if p.second_pass {
            // From a detector that thresholds its own output (every score seen so far would pass
            // det_threshold and new_track_threshold as given), nothing is low in ByteTrack's
            // sense: what reaches this pass was held back by the quantile floor alone and
            // extends a track at a smaller overlap.
            let band_iou = if self.scores_seen.thresholded() {
                p.low_iou_threshold.min(p.thresholded_low_iou)
            } else {
                p.low_iou_threshold
            };
            iou_edges(
                &self.tracks,
                &track_det,
                &det_track,
                &low_index,
                &|t| !t.is_lingering() && t.time_since_update <= p.low_max_age,
                &|t| t.predicted,
                band_iou,
                &mut edges,
            );
            let pairs = self.matcher.solve(nt, n, &edges, 1.0 - band_iou);
            record(&pairs, &mut track_det, &mut det_track);
        }

        // Stage 4: recovery by the last observed box (lost confirmed tracks).
        if p.recovery {
            iou_edges(
                &self.tracks,
                &track_det,
                &det_track,
                &index,
                &|t| t.confirmed,
                &|t| t.last_obs,
                p.recovery_iou_threshold,
                &mut edges,
            );
            let pairs = self
                .matcher
                .solve(nt, n, &edges, 1.0 - p.recovery_iou_threshold);
            record(&pairs, &mut track_det, &mut det_track);
        }

        // Stage 5: tentative tracks that missed a frame take the low-score detections left, at
        // the second pass's own overlap. A confident detection left over starts a track of its
        // own instead, as without `tentative_max_age`; from a detector that thresholds its own
        // output every detection is confident, so there this stage takes none.
        if p.tentative_max_age > 0 && p.second_pass && !self.scores_seen.thresholded() {
            iou_edges(
                &self.tracks,
                &track_det,
                &det_track,
                &low_index,
                &|t| t.is_lingering(),
                &|t| t.predicted,
                p.low_iou_threshold,
                &mut edges,
            );
            let pairs = self.matcher.solve(nt, n, &edges, 1.0 - p.low_iou_threshold);
            record(&pairs, &mut track_det, &mut det_track);
        }

        // Unmatched confirmed tracks: occluded, left the image, or neither.
        let mut left_image = vec![false; nt];
        if p.occluded_output > 0 {
            // The people seen this frame: detections matched to tracks and confident ones.
            let scene = Scene::new(
                (0..n)
                    .filter(|&j| det_track[j].is_some() || high(j))
                    .map(|j| dets[j])
                    .collect(),
            );
            for (i, t) in self.tracks.iter_mut().enumerate() {
                t.occluded = false;
                if track_det[i].is_some() || !t.confirmed {
                    continue;
                }
                let (cover, inside) = (p.occlusion_coverage, p.left_image_inside);
                match classify(&t.predicted, &scene, self.image_size, cover, inside) {
                    Unmatched::Occluded => t.occluded = true,
                    Unmatched::LeftImage => left_image[i] = true,
                    Unmatched::Uncovered => {}
                }
            }
        }

        // Update matched tracks, coast the others, drop the dead.
        let horizon = p.output_lost.max(p.occluded_output);
        let adaptive = self.jitter.gain(p.jitter_floor);
        let whole_aspect = if track_det.iter().all(Option::is_some) {
            None
        } else {
            self.crowd_aspect.quantile(p.coast_aspect_quantile)
        };
        for (i, t) in self.tracks.iter_mut().enumerate() {
            match track_det[i] {
                Some(j) => {
                    if t.confirmed {
                        self.lost_report[usize::from(t.gap_occluded)].refound(
                            t.time_since_update,
                            horizon,
                            &t.predicted,
                            &dets[j],
                        );
                    }
                    self.perspective.observe(&dets[j]);
                    self.crowd_aspect.observe(&dets[j]);
                    if t.is_followed() {
                        let (d, pc) = (centre(&dets[j]), t.predicted_centre());
                        self.jitter.observe((d[0] - pc[0]).hypot(d[1] - pc[1]), t.h);
                    }
                    t.apply_match(j, dets[j], scores[j], frame, emb_row(j), adaptive, &p);
                    if !t.confirmed && t.hits >= p.n_init {
                        t.confirmed = true;
                        t.id = self.next_id;
                        self.next_id += 1;
                    }
                }
                None => t.coast(&p, whole_aspect),
            }
        }
        let mut k = 0;
        let lost_report = &mut self.lost_report;
        self.tracks.retain(|t| {
            let keep = match track_det[k] {
                Some(_) => true,
                None => {
                    let age = if t.confirmed {
                        p.max_age
                    } else {
                        p.tentative_max_age
                    };
                    !left_image[k] && t.time_since_update <= age
                }
            };
            if !keep && t.confirmed {
                lost_report[usize::from(t.gap_occluded)].not_refound(t.time_since_update, horizon);
            }
            k += 1;
            keep
        });

        // Deferred re-identification (`reid_newborn`): a young track may take a lost one's id.
        let matched: Vec<bool> = self
            .tracks
            .iter()
            .map(|t| t.time_since_update == 0)
            .collect();
        merge_newborn(&mut self.tracks, &matched, &p);

        // New tracks from unmatched high-score detections.
        for j in 0..n {
            if det_track[j].is_none() && high(j) && scores[j] >= p.new_track_threshold {
                let mut t = Track::new(j, dets[j], scores[j], frame, emb_row(j), p.gallery_size);
                if p.n_init <= 1 {
                    t.confirmed = true;
                    t.id = self.next_id;
                    self.next_id += 1;
                }
                self.tracks.push(t);
                det_track[j] = Some(usize::MAX);
            }
        }

        Ok(self.outputs())
    }

    /// Sets every track's prediction: the crowd steps together through the motion model;
    /// tentative tracks that missed a frame (`tentative_max_age`) are no part of that step and
    /// move by their own preferred velocity, so that they do not move their neighbours'
    /// predictions.
    fn predict(&mut self, p: &TrackerParams, ground: Option<&GroundMap>) {
        let mut held: Vec<(usize, Track)> = Vec::new();
        for i in (0..self.tracks.len()).rev() {
            if self.tracks[i].is_lingering() {
                held.push((i, self.tracks.remove(i)));
            }
        }
        predict(&mut self.tracks, self.model.as_mut(), p, ground);
        for (i, mut t) in held.into_iter().rev() {
            t.set_prediction(t.pref_vel, 1.0);
            self.tracks.insert(i, t);
        }
    }

    fn outputs(&self) -> Vec<TrackOutput> {
        let mut out: Vec<TrackOutput> = self
            .tracks
            .iter()
            .filter(|t| {
                let p = &self.params;
                let lost_shown = t.time_since_update == 0
                    || !p.output_lost_adaptive
                    || self.lost_report[usize::from(t.gap_occluded)]
                        .report(t.time_since_update, p.output_lost_precision);
                t.confirmed
                    && lost_shown
                    && (t.time_since_update == 0 || t.hits >= p.coast_min_hits)
                    && (t.time_since_update <= p.output_lost
                        || (t.occluded && t.time_since_update <= p.occluded_output))
            })
            .map(|t| TrackOutput {
                id: t.id,
                bbox: t.bbox,
                score: t.score,
                det_index: t.det_index,
            })
            .collect();
        out.sort_by_key(|o| o.id);
        if let Some(g) = self
            .perspective
            .ground()
            .filter(|_| self.params.amodal_boxes)
        {
            let seen: Vec<BBox> = out.iter().map(|o| o.bbox).collect();
            for o in &mut out {
                o.bbox = complete(&o.bbox, &seen, &g, self.params.occlusion_coverage);
            }
        }
        // Occluded people reported at the scene's whole width (amodal_width_quantile).
        if let Some(a) = self
            .crowd_aspect
            .quantile(self.params.amodal_width_quantile)
        {
            let mut boxes: Vec<BBox> = out.iter().map(|o| o.bbox).collect();
            let matched: Vec<bool> = out.iter().map(|o| o.det_index.is_some()).collect();
            widen_occluded(&mut boxes, &matched, a, self.params.amodal_width_coverage);
            for (o, b) in out.iter_mut().zip(boxes) {
                o.bbox = b;
            }
        }
        out
    }
}

/// Whether the centre of `b` lies within `r` of `c`.
#[inline]
fn within(c: [f64; 2], b: &BBox, r: f64) -> bool {
    let d = centre(b);
    let (dx, dy) = (d[0] - c[0], d[1] - c[1]);
    dx * dx + dy * dy <= r * r
}

fn record(
    pairs: &[(usize, usize)],
    track_det: &mut [Option<usize>],
    det_track: &mut [Option<usize>],
) {
    for &(i, j) in pairs {
        track_det[i] = Some(j);
        det_track[j] = Some(i);
    }
}
