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
use crate::lost_report::{LostReport, REPORT_PRECISION};
use crate::occlusion::{
    classify, complete, Scene, Unmatched, LEFT_IMAGE_INSIDE, OCCLUSION_COVERAGE,
};
use crate::params::TrackerParams;
use crate::perspective::Perspective;
use crate::predict::predict;
use crate::reid::merge_newborn;
use crate::score_scale::{ScoreCuts, ScoreScaler};
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
    /// The candidate pairs of the stage being solved (kept to reuse its memory).
    edges: Vec<Edge>,
    /// Image size `[width, height]` when the caller gave it.
    image_size: Option<[f64; 2]>,
    /// The scores seen, from which each frame's score cuts are read.
    scores_seen: ScoreScaler,
    /// How lost tracks' gaps ended, for `output_lost_adaptive`: gaps that began in the open
    /// (`[0]`) and gaps that began occluded (`[1]`), counted apart.
    lost_report: [LostReport; 2],
    /// The perspective seen so far (the ground plane, for `amodal_boxes`).
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

/// One frame's detections as the stages read them.
struct Frame<'a> {
    dets: Vec<BBox>,
    scores: &'a [f64],
    /// Unit-norm embedding rows and their dimension.
    emb: Option<(Vec<f32>, usize)>,
    /// The raw score cuts of this frame ([`ScoreScaler::cuts`]).
    cuts: ScoreCuts,
    /// Whether the detector thresholds its own output ([`ScoreScaler::thresholded`]).
    thresholded: bool,
}

impl Frame<'_> {
    fn emb_row(&self, j: usize) -> Option<&[f32]> {
        self.emb.as_ref().map(|(data, d)| &data[j * d..(j + 1) * d])
    }

    /// Confident: matched in every stage.
    fn high(&self, j: usize) -> bool {
        self.scores[j] >= self.cuts.det
    }

    /// In the second pass's band `[low, det)`.
    fn low(&self, j: usize) -> bool {
        self.scores[j] >= self.cuts.low && self.scores[j] < self.cuts.det
    }
}

/// Who matched whom so far this frame.
struct Matches {
    track_det: Vec<Option<usize>>,
    det_track: Vec<Option<usize>>,
}

impl Matches {
    fn new(tracks: usize, dets: usize) -> Self {
        Self {
            track_det: vec![None; tracks],
            det_track: vec![None; dets],
        }
    }

    fn tracks(&self) -> usize {
        self.track_det.len()
    }

    fn dets(&self) -> usize {
        self.det_track.len()
    }

    fn record(&mut self, pairs: &[(usize, usize)]) {
        for &(i, j) in pairs {
            self.track_det[i] = Some(j);
            self.det_track[j] = Some(i);
        }
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
            edges: Vec::new(),
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
    /// box has less than [`LEFT_IMAGE_INSIDE`] of its area inside the image is deleted (it left); without it,
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
    ///
    /// The stages, in order, each a method below: read the frame (score cuts, embeddings),
    /// predict, associate by appearance, by IoU, the second pass, recovery, tentative tracks;
    /// classify the unmatched, update / coast / delete, newborn re-ID, births, report.
    pub fn update(
        &mut self,
        boxes: &[f64],
        scores: &[f64],
        embeddings: Option<Embeddings<'_>>,
    ) -> Result<Vec<TrackOutput>, TrackError> {
        let n = self.validate(boxes, scores, embeddings)?;
        self.frame += 1;
        let f = self.read_frame(boxes, scores, embeddings);
        self.predict();

        let mut m = Matches::new(self.tracks.len(), n);
        let high = DetIndex::new(&f.dets, |j| f.high(j));
        let low = DetIndex::new(&f.dets, |j| self.params.second_pass && f.low(j));
        self.match_appearance(&f, &high, &mut m);
        self.match_motion(&f, &high, &mut m);
        self.match_low_scores(&f, &low, &mut m);
        self.recover_lost(&f, &high, &mut m);
        self.match_tentative(&f, &low, &mut m);

        let left_image = self.classify_unmatched(&f, &m);
        self.update_tracks(&f, &m);
        self.delete_dead(&m, &left_image);
        self.reid_newborn();
        self.births(&f, &m);
        Ok(self.outputs())
    }

    /// The frame as the stages read it: the score cuts (observing its scores first), the boxes
    /// and the embeddings normalised to unit rows.
    fn read_frame<'a>(
        &mut self,
        boxes: &[f64],
        scores: &'a [f64],
        embeddings: Option<Embeddings<'_>>,
    ) -> Frame<'a> {
        let reading = self.params.score_reading();
        let cuts = self
            .scores_seen
            .cuts(&reading, self.params.score_thresholds(), scores);
        let emb = embeddings.map(|e| {
            let mut data = e.data.to_vec();
            normalise_rows(&mut data, e.dim);
            (data, e.dim)
        });
        if let Some((_, d)) = emb {
            self.emb_dim = Some(d);
        }
        Frame {
            dets: boxes
                .chunks_exact(4)
                .map(|b| [b[0], b[1], b[2], b[3]])
                .collect(),
            scores,
            emb,
            cuts,
            thresholded: self.scores_seen.thresholded(),
        }
    }

    /// Stage 1, appearance: cosine distance to each track's gallery (at most
    /// `appearance_threshold`; at most `appearance_apart` too for a detection that does not
    /// overlap the predicted box), among the confident detections within `gate_radius` track
    /// heights of the predicted centre. Only with embeddings.
    fn match_appearance(&mut self, f: &Frame<'_>, index: &DetIndex, m: &mut Matches) {
        if f.emb.is_none() {
            return;
        }
        let p = &self.params;
        self.edges.clear();
        for (i, t) in self.tracks.iter().enumerate() {
            if !t.has_gallery() || t.is_lingering() {
                continue;
            }
            let c = t.predicted_centre();
            let r = p.gate_radius * t.h;
            for j in index.near(c[0], r) {
                if !within(c, &f.dets[j], r) {
                    continue;
                }
                let d = t.appearance_distance(f.emb_row(j).expect("embeddings present"));
                let limit = if iou(&t.predicted, &f.dets[j]) > 0.0 {
                    p.appearance_threshold
                } else {
                    p.appearance_threshold.min(p.appearance_apart)
                };
                if d <= limit {
                    self.edges.push(Edge {
                        row: i,
                        col: j,
                        cost: d,
                    });
                }
            }
        }
        let pairs = self
            .matcher
            .solve(m.tracks(), m.dets(), &self.edges, p.appearance_threshold);
        m.record(&pairs);
    }

    /// Stage 2, motion: IoU of the predicted boxes with the confident detections left
    /// (at least `iou_threshold`).
    fn match_motion(&mut self, f: &Frame<'_>, index: &DetIndex, m: &mut Matches) {
        let min_iou = self.params.iou_threshold;
        self.match_iou(f, index, m, |t| !t.is_lingering(), |t| t.predicted, min_iou);
    }

    /// Stage 3, ByteTrack's second pass: detections scored in `[low_threshold, det_threshold)`
    /// extend (never start) tracks unmatched for at most `low_max_age` frames, at
    /// `low_iou_threshold`. From a detector that thresholds its own output, nothing is low in
    /// ByteTrack's sense: what reaches this pass was held back by the quantile floor alone and
    /// extends a track at the smaller overlap `thresholded_low_iou`.
    fn match_low_scores(&mut self, f: &Frame<'_>, low: &DetIndex, m: &mut Matches) {
        let p = &self.params;
        if !p.second_pass {
            return;
        }
        let min_iou = if f.thresholded {
            p.low_iou_threshold.min(p.thresholded_low_iou)
        } else {
            p.low_iou_threshold
        };
        let max_gap = p.low_max_age;
        let use_track = |t: &Track| !t.is_lingering() && t.time_since_update <= max_gap;
        self.match_iou(f, low, m, use_track, |t| t.predicted, min_iou);
    }

    /// Stage 4, OC-SORT's recovery (`recovery`): lost confirmed tracks by the IoU of their last
    /// observed box with the confident detections left (at least `iou_threshold`).
    fn recover_lost(&mut self, f: &Frame<'_>, index: &DetIndex, m: &mut Matches) {
        if self.params.recovery {
            let min_iou = self.params.iou_threshold;
            self.match_iou(f, index, m, |t| t.confirmed, |t| t.last_obs, min_iou);
        }
    }

    /// Stage 5, tentative tracks that missed a frame (`tentative_max_age`): the low-score
    /// detections left, at the second pass's own overlap, after every other track has had its
    /// choice. A confident detection left over starts a track of its own instead; from a
    /// detector that thresholds its own output every detection is confident, so there this
    /// stage takes none.
    fn match_tentative(&mut self, f: &Frame<'_>, low: &DetIndex, m: &mut Matches) {
        let p = &self.params;
        if p.tentative_max_age > 0 && p.second_pass && !f.thresholded {
            let min_iou = p.low_iou_threshold;
            self.match_iou(f, low, m, |t| t.is_lingering(), |t| t.predicted, min_iou);
        }
    }

    /// One IoU stage: the unmatched tracks that `use_track` admits against the unmatched
    /// detections of `index`, by the IoU of `track_box` with the detection (at least `min_iou`,
    /// centres within `gate_radius` track heights), solved optimally.
    fn match_iou(
        &mut self,
        f: &Frame<'_>,
        index: &DetIndex,
        m: &mut Matches,
        use_track: impl Fn(&Track) -> bool,
        track_box: impl Fn(&Track) -> BBox,
        min_iou: f64,
    ) {
        self.edges.clear();
        for (i, t) in self.tracks.iter().enumerate() {
            if m.track_det[i].is_some() || !use_track(t) {
                continue;
            }
            let tb = track_box(t);
            let c = centre(&tb);
            let r = self.params.gate_radius * t.h;
            let half = (0.5 * (tb[2] - tb[0]) + index.max_half_w).min(r);
            for j in index.near(c[0], half) {
                if m.det_track[j].is_some() || !within(c, &f.dets[j], r) {
                    continue;
                }
                let o = iou(&tb, &f.dets[j]);
                if o > 0.0 && o >= min_iou {
                    self.edges.push(Edge {
                        row: i,
                        col: j,
                        cost: 1.0 - o,
                    });
                }
            }
        }
        let pairs = self
            .matcher
            .solve(m.tracks(), m.dets(), &self.edges, 1.0 - min_iou);
        m.record(&pairs);
    }

    /// Unmatched confirmed tracks, classified from the people seen this frame (the matched
    /// detections and the confident ones; `occluded_output` > 0): occluded ones are marked, and
    /// those that left the image are returned (`true`) for deletion.
    fn classify_unmatched(&mut self, f: &Frame<'_>, m: &Matches) -> Vec<bool> {
        let p = &self.params;
        let mut left_image = vec![false; self.tracks.len()];
        if p.occluded_output == 0 {
            return left_image;
        }
        let scene = Scene::new(
            (0..f.dets.len())
                .filter(|&j| m.det_track[j].is_some() || f.high(j))
                .map(|j| f.dets[j])
                .collect(),
        );
        for (i, t) in self.tracks.iter_mut().enumerate() {
            t.occluded = false;
            if m.track_det[i].is_some() || !t.confirmed {
                continue;
            }
            let (cover, inside) = (OCCLUSION_COVERAGE, LEFT_IMAGE_INSIDE);
            match classify(&t.predicted, &scene, self.image_size, cover, inside) {
                Unmatched::Occluded => t.occluded = true,
                Unmatched::LeftImage => left_image[i] = true,
                Unmatched::Uncovered => {}
            }
        }
        left_image
    }

    /// Matched tracks take their detection (confirmed after `n_init` matches, feeding the
    /// scene's statistics: lost-report, ground plane, aspect ratios, jitter); the others coast.
    fn update_tracks(&mut self, f: &Frame<'_>, m: &Matches) {
        let p = &self.params;
        let horizon = p.output_lost.max(p.occluded_output);
        let adaptive = self.jitter.gain(p.jitter_floor);
        let whole_aspect = if m.track_det.iter().all(Option::is_some) {
            None
        } else {
            self.crowd_aspect.quantile(p.coast_aspect_quantile)
        };
        for (i, t) in self.tracks.iter_mut().enumerate() {
            let Some(j) = m.track_det[i] else {
                t.coast(p, whole_aspect);
                continue;
            };
            let det = f.dets[j];
            if t.confirmed {
                let report = &mut self.lost_report[usize::from(t.gap_occluded)];
                report.refound(t.time_since_update, horizon, &t.predicted, &det);
            }
            self.perspective.observe(&det);
            self.crowd_aspect.observe(&det);
            if t.is_followed() {
                let (d, pc) = (centre(&det), t.predicted_centre());
                self.jitter.observe((d[0] - pc[0]).hypot(d[1] - pc[1]), t.h);
            }
            t.apply_match(j, det, f.scores[j], self.frame, f.emb_row(j), adaptive, p);
            if !t.confirmed && t.hits >= p.n_init {
                t.confirmed = true;
                t.id = self.next_id;
                self.next_id += 1;
            }
        }
    }

    /// Deletes the unmatched tracks past their age (`max_age`; `tentative_max_age` for tentative
    /// ones) and those that left the image, recording how confirmed ones' gaps ended.
    fn delete_dead(&mut self, m: &Matches, left_image: &[bool]) {
        let p = &self.params;
        let horizon = p.output_lost.max(p.occluded_output);
        let lost_report = &mut self.lost_report;
        let mut k = 0;
        self.tracks.retain(|t| {
            let age = if t.confirmed {
                p.max_age
            } else {
                p.tentative_max_age
            };
            let keep = m.track_det[k].is_some() || (!left_image[k] && t.time_since_update <= age);
            if !keep && t.confirmed {
                lost_report[usize::from(t.gap_occluded)].not_refound(t.time_since_update, horizon);
            }
            k += 1;
            keep
        });
    }

    /// Deferred re-identification (`reid_newborn`): a young track may take a lost one's id.
    fn reid_newborn(&mut self) {
        let matched: Vec<bool> = self
            .tracks
            .iter()
            .map(|t| t.time_since_update == 0)
            .collect();
        merge_newborn(&mut self.tracks, &matched, &self.params);
    }

    /// New tracks from the unmatched detections at or above both `det_threshold` and
    /// `new_track_threshold` (confirmed at once when `n_init` is 1).
    fn births(&mut self, f: &Frame<'_>, m: &Matches) {
        for j in 0..f.dets.len() {
            if m.det_track[j].is_some() || !f.high(j) || f.scores[j] < f.cuts.new_track {
                continue;
            }
            let emb = f.emb_row(j);
            let mut t = Track::new(
                j,
                f.dets[j],
                f.scores[j],
                self.frame,
                emb,
                self.params.gallery_size,
            );
            if self.params.n_init <= 1 {
                t.confirmed = true;
                t.id = self.next_id;
                self.next_id += 1;
            }
            self.tracks.push(t);
        }
    }

    /// Sets every track's prediction: the crowd steps together through the motion model;
    /// tentative tracks that missed a frame (`tentative_max_age`) are no part of that step and
    /// move by their own preferred velocity, so that they do not move their neighbours'
    /// predictions.
    fn predict(&mut self) {
        let mut held: Vec<(usize, Track)> = Vec::new();
        for i in (0..self.tracks.len()).rev() {
            if self.tracks[i].is_lingering() {
                held.push((i, self.tracks.remove(i)));
            }
        }
        predict(&mut self.tracks, self.model.as_mut(), &self.params);
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
                        .report(t.time_since_update, REPORT_PRECISION);
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
                o.bbox = complete(&o.bbox, &seen, &g, OCCLUSION_COVERAGE);
            }
        }
        // Occluded people reported at the scene's whole width (amodal_width_quantile).
        if let Some(a) = self
            .crowd_aspect
            .quantile(self.params.amodal_width_quantile)
        {
            let mut boxes: Vec<BBox> = out.iter().map(|o| o.bbox).collect();
            let matched: Vec<bool> = out.iter().map(|o| o.det_index.is_some()).collect();
            widen_occluded(&mut boxes, &matched, a, 0.0);
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
