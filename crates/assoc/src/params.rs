//! Tracker parameters with documented defaults, validated ranges, and access by name (so the
//! Python binding can take them as keyword arguments without a second list of names).

use crate::TrackError;
use frvo::{MotionKind, MotionParams};

/// Every tunable of the tracker. Units: pixels, frames; scores in [0, 1]. Defaults were tuned
/// motion-only on the six dev sequences together (never per sequence; benchmarks/results/
/// tracker.md). The method's pure form (two optimal stages, every detection used, detection
/// sizes as they come, no lost-track output) is [`TrackerParams::pure`].
#[derive(Clone, Debug, PartialEq)]
pub struct TrackerParams {
    /// Motion model predicting each track's next position (`frvo`, `rvo`, `sf`, `cv`).
    pub motion: MotionKind,
    /// Parameters of the motion model (neighbour radius, time horizon, ...).
    pub motion_params: MotionParams,
    /// Matches needed before a tentative track is confirmed (gets an id and is reported). 2.
    pub n_init: u32,
    /// xi: frames a confirmed track survives without a match before it is deleted. 60.
    pub max_age: u32,
    /// lambda: largest cosine distance for an appearance match (stage 1). 0.2.
    pub appearance_threshold: f64,
    /// Embeddings remembered per track (oldest out first), summarised in at most 8 rows (means of
    /// consecutive embeddings); the appearance cost is the smallest distance to a row. 20.
    pub gallery_size: usize,
    /// rho, in units of the track's box height: a detection can match a track only when its
    /// centre is within `gate_radius * height` of the track's predicted centre. `inf` disables. 1.0.
    pub gate_radius: f64,
    /// Smallest IoU between a predicted box and a detection for a motion match (stage 2). 0.3.
    pub iou_threshold: f64,
    /// Detections scoring below this take no part in stages 1-2 and recovery (they may feed the
    /// second pass). Scores are expected in [0, 1] (`densepeds.motio.read_detections` maps det
    /// files into it). 0.3.
    pub det_threshold: f64,
    /// Smallest score that starts a new track (and only detections of at least `det_threshold`
    /// do): low-score detections extend tracks, never start them. 0.3.
    pub new_track_threshold: f64,
    /// ByteTrack-style second pass: tracks still unmatched are matched by IoU to detections
    /// scoring in `[low_threshold, det_threshold)`. On.
    pub second_pass: bool,
    /// Lowest score used by the second pass. 0.05.
    pub low_threshold: f64,
    /// Smallest IoU for a second-pass match. 0.5.
    pub low_iou_threshold: f64,
    /// Tracks unmatched for up to this many frames take part in the second pass (0: only tracks
    /// matched in the previous frame, ByteTrack's rule). 60 (= `max_age`: every live track):
    /// lets low-score detections re-find tracks lost for a few frames, which is where a
    /// sequence with uniformly low scores (ETH-Sunnyday) lost most of its recall.
    pub low_max_age: u32,
    /// OC-SORT-style observation-centric recovery: tracks still unmatched are matched by IoU
    /// between their last observed box and the remaining detections. On by default (tuned on
    /// the dense dev sequences; `false` gives the method's pure two-stage form).
    pub recovery: bool,
    /// Smallest IoU for a recovery match. 0.3.
    pub recovery_iou_threshold: f64,
    /// Weight of the newly observed velocity in the velocity average (1 = no smoothing). 0.5.
    pub velocity_smoothing: f64,
    /// Frames of matched history the preferred velocity is averaged over. 20.
    pub pref_window: usize,
    /// Weight of the previous box size when a match updates it (0 = take the detection's size,
    /// the method's form). 0.5: halves the jitter of detector box sizes.
    pub size_smoothing: f64,
    /// FRVO ellipse: l (extent along the motion, the visible face) = `ellipse_l_scale * box
    /// height`. 0.15 (a face is about 1/7 of a standing person's height).
    pub ellipse_l_scale: f64,
    /// FRVO ellipse: w (extent across the motion) = `ellipse_w_scale * box width`. 0.15: in a
    /// front view, overlapping boxes are occlusion, not collision, so the ellipses are kept small
    /// (0.8, the shoulders, measured worse on the dev sequences).
    pub ellipse_w_scale: f64,
    /// Confirmed tracks are also reported for this many frames after their last match, at their
    /// predicted box (`det_index` none); tracks live at most `max_age` frames unmatched, which
    /// caps it. 5: bridges short misses of the detector with the
    /// motion model's prediction (more recall and HOTA, some more false positives).
    pub output_lost: u32,
}

impl Default for TrackerParams {
    fn default() -> Self {
        Self {
            motion: MotionKind::Frvo,
            motion_params: MotionParams::default(),
            n_init: 2,
            max_age: 60,
            appearance_threshold: 0.2,
            gallery_size: 20,
            gate_radius: 1.0,
            iou_threshold: 0.3,
            det_threshold: 0.3,
            new_track_threshold: 0.3,
            second_pass: true,
            low_threshold: 0.05,
            low_iou_threshold: 0.5,
            low_max_age: 60,
            recovery: true,
            recovery_iou_threshold: 0.3,
            velocity_smoothing: 0.5,
            pref_window: 20,
            size_smoothing: 0.5,
            ellipse_l_scale: 0.15,
            ellipse_w_scale: 0.15,
            output_lost: 5,
        }
    }
}

/// How a parameter's value is typed (for bindings).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamKind {
    Float,
    Int,
    Bool,
}

/// A parameter value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ParamValue {
    Float(f64),
    Int(i64),
    Bool(bool),
}

/// Names of the numeric/boolean parameters, in a stable order (`motion` is set separately).
pub const PARAM_NAMES: &[&str] = &[
    "n_init",
    "max_age",
    "appearance_threshold",
    "gallery_size",
    "gate_radius",
    "iou_threshold",
    "det_threshold",
    "new_track_threshold",
    "second_pass",
    "low_threshold",
    "low_iou_threshold",
    "low_max_age",
    "recovery",
    "recovery_iou_threshold",
    "velocity_smoothing",
    "pref_window",
    "size_smoothing",
    "ellipse_l_scale",
    "ellipse_w_scale",
    "output_lost",
    "neighbor_radius",
    "max_neighbors",
    "time_horizon",
    "max_speed",
    "polygon_sides",
    "threads",
];

fn bad(name: &str, why: &str) -> TrackError {
    TrackError::InvalidParameter(format!("{name} {why}"))
}

fn to_u32(name: &str, v: i64) -> Result<u32, TrackError> {
    u32::try_from(v).map_err(|_| bad(name, &format!("must be a non-negative integer, got {v}")))
}

fn to_usize(name: &str, v: i64) -> Result<usize, TrackError> {
    usize::try_from(v).map_err(|_| bad(name, &format!("must be a non-negative integer, got {v}")))
}

impl TrackerParams {
    /// The DensePeds paper's plain tracker (appearance then FRVO-predicted IoU, each solved
    /// optimally; no score thresholds, no second pass, no recovery, no size smoothing, only
    /// matched tracks reported). Equivalent to the keyword arguments
    /// `det_threshold=-inf, new_track_threshold=-inf, second_pass=False, recovery=False,
    /// size_smoothing=0, output_lost=0`. Other fields keep their defaults.
    pub fn pure() -> Self {
        Self {
            det_threshold: f64::NEG_INFINITY,
            new_track_threshold: f64::NEG_INFINITY,
            second_pass: false,
            recovery: false,
            size_smoothing: 0.0,
            output_lost: 0,
            ..Self::default()
        }
    }

    /// The type of the named parameter, or `None` for an unknown name.
    pub fn kind_of(name: &str) -> Option<ParamKind> {
        Some(match name {
            "n_init" | "max_age" | "gallery_size" | "pref_window" | "output_lost"
            | "low_max_age" | "max_neighbors" | "polygon_sides" | "threads" => ParamKind::Int,
            "second_pass" | "recovery" => ParamKind::Bool,
            n if PARAM_NAMES.contains(&n) => ParamKind::Float,
            _ => return None,
        })
    }

    /// Sets one parameter by name. Values are range-checked by [`TrackerParams::validate`].
    pub fn set(&mut self, name: &str, value: ParamValue) -> Result<(), TrackError> {
        let kind = Self::kind_of(name).ok_or_else(|| {
            TrackError::InvalidParameter(format!(
                "unknown parameter {name:?}; known: motion, {}",
                PARAM_NAMES.join(", ")
            ))
        })?;
        let f = match value {
            ParamValue::Float(f) => f,
            ParamValue::Int(i) => i as f64,
            ParamValue::Bool(b) => f64::from(u8::from(b)),
        };
        let i = match (kind, value) {
            (ParamKind::Int, ParamValue::Int(i)) => i,
            (ParamKind::Int, _) => return Err(bad(name, "must be an integer")),
            (ParamKind::Bool, ParamValue::Bool(b)) => i64::from(b),
            (ParamKind::Bool, _) => return Err(bad(name, "must be a boolean")),
            (ParamKind::Float, ParamValue::Bool(_)) => return Err(bad(name, "must be a number")),
            _ => 0,
        };
        let p = self;
        match name {
            "n_init" => p.n_init = to_u32(name, i)?,
            "max_age" => p.max_age = to_u32(name, i)?,
            "appearance_threshold" => p.appearance_threshold = f,
            "gallery_size" => p.gallery_size = to_usize(name, i)?,
            "gate_radius" => p.gate_radius = f,
            "iou_threshold" => p.iou_threshold = f,
            "det_threshold" => p.det_threshold = f,
            "new_track_threshold" => p.new_track_threshold = f,
            "second_pass" => p.second_pass = i != 0,
            "low_threshold" => p.low_threshold = f,
            "low_iou_threshold" => p.low_iou_threshold = f,
            "low_max_age" => p.low_max_age = to_u32(name, i)?,
            "recovery" => p.recovery = i != 0,
            "recovery_iou_threshold" => p.recovery_iou_threshold = f,
            "velocity_smoothing" => p.velocity_smoothing = f,
            "pref_window" => p.pref_window = to_usize(name, i)?,
            "size_smoothing" => p.size_smoothing = f,
            "ellipse_l_scale" => p.ellipse_l_scale = f,
            "ellipse_w_scale" => p.ellipse_w_scale = f,
            "output_lost" => p.output_lost = to_u32(name, i)?,
            "neighbor_radius" => p.motion_params.neighbor_radius = f,
            "max_neighbors" => p.motion_params.max_neighbors = to_usize(name, i)?,
            "time_horizon" => p.motion_params.time_horizon = f,
            "max_speed" => p.motion_params.max_speed = f,
            "polygon_sides" => p.motion_params.polygon_sides = to_usize(name, i)?,
            "threads" => p.motion_params.threads = to_usize(name, i)?,
            _ => unreachable!("kind_of accepted {name}"),
        }
        Ok(())
    }

    /// The named parameter's current value.
    pub fn get(&self, name: &str) -> Option<ParamValue> {
        use ParamValue::{Bool, Float, Int};
        let p = self;
        Some(match name {
            "n_init" => Int(p.n_init.into()),
            "max_age" => Int(p.max_age.into()),
            "appearance_threshold" => Float(p.appearance_threshold),
            "gallery_size" => Int(p.gallery_size as i64),
            "gate_radius" => Float(p.gate_radius),
            "iou_threshold" => Float(p.iou_threshold),
            "det_threshold" => Float(p.det_threshold),
            "new_track_threshold" => Float(p.new_track_threshold),
            "second_pass" => Bool(p.second_pass),
            "low_threshold" => Float(p.low_threshold),
            "low_iou_threshold" => Float(p.low_iou_threshold),
            "low_max_age" => Int(p.low_max_age.into()),
            "recovery" => Bool(p.recovery),
            "recovery_iou_threshold" => Float(p.recovery_iou_threshold),
            "velocity_smoothing" => Float(p.velocity_smoothing),
            "pref_window" => Int(p.pref_window as i64),
            "size_smoothing" => Float(p.size_smoothing),
            "ellipse_l_scale" => Float(p.ellipse_l_scale),
            "ellipse_w_scale" => Float(p.ellipse_w_scale),
            "output_lost" => Int(p.output_lost.into()),
            "neighbor_radius" => Float(p.motion_params.neighbor_radius),
            "max_neighbors" => Int(p.motion_params.max_neighbors as i64),
            "time_horizon" => Float(p.motion_params.time_horizon),
            "max_speed" => Float(p.motion_params.max_speed),
            "polygon_sides" => Int(p.motion_params.polygon_sides as i64),
            "threads" => Int(p.motion_params.threads as i64),
            _ => return None,
        })
    }

    /// Checks every range; the error names the parameter and its allowed range.
    pub fn validate(&self) -> Result<(), TrackError> {
        let p = self;
        let unit = |name: &str, v: f64| {
            if (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err(bad(name, &format!("must be in [0, 1], got {v}")))
            }
        };
        let positive = |name: &str, v: f64| {
            if v > 0.0 && !v.is_nan() {
                Ok(())
            } else {
                Err(bad(name, &format!("must be > 0, got {v}")))
            }
        };
        let not_nan = |name: &str, v: f64| {
            if v.is_nan() {
                Err(bad(name, "must not be NaN"))
            } else {
                Ok(())
            }
        };
        if p.n_init < 1 {
            return Err(bad("n_init", "must be >= 1"));
        }
        if p.gallery_size < 1 {
            return Err(bad("gallery_size", "must be >= 1"));
        }
        if p.pref_window < 1 {
            return Err(bad("pref_window", "must be >= 1"));
        }
        if !(0.0..=2.0).contains(&p.appearance_threshold) {
            return Err(bad(
                "appearance_threshold",
                &format!("must be in [0, 2], got {}", p.appearance_threshold),
            ));
        }
        positive("gate_radius", p.gate_radius)?;
        unit("iou_threshold", p.iou_threshold)?;
        unit("low_iou_threshold", p.low_iou_threshold)?;
        unit("recovery_iou_threshold", p.recovery_iou_threshold)?;
        unit("velocity_smoothing", p.velocity_smoothing)?;
        if !(0.0..1.0).contains(&p.size_smoothing) {
            return Err(bad(
                "size_smoothing",
                &format!("must be in [0, 1), got {}", p.size_smoothing),
            ));
        }
        not_nan("det_threshold", p.det_threshold)?;
        not_nan("new_track_threshold", p.new_track_threshold)?;
        not_nan("low_threshold", p.low_threshold)?;
        positive("ellipse_l_scale", p.ellipse_l_scale)?;
        positive("ellipse_w_scale", p.ellipse_w_scale)?;
        if !p.ellipse_l_scale.is_finite() || !p.ellipse_w_scale.is_finite() {
            return Err(bad("ellipse_l_scale/ellipse_w_scale", "must be finite"));
        }
        let m = &p.motion_params;
        positive("neighbor_radius", m.neighbor_radius)?;
        positive("time_horizon", m.time_horizon)?;
        positive("max_speed", m.max_speed)?;
        if m.max_neighbors < 1 {
            return Err(bad("max_neighbors", "must be >= 1"));
        }
        if m.polygon_sides < 3 {
            return Err(bad("polygon_sides", "must be >= 3"));
        }
        if m.threads > frvo::model::MAX_THREADS {
            let why = format!(
                "must be in 0..={} (0: every core), got {}",
                frvo::model::MAX_THREADS,
                m.threads
            );
            return Err(bad("threads", &why));
        }
        Ok(())
    }
}
