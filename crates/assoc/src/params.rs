//! Tracker parameters, each declared once in the `tracker_params!` table below: name, type,
//! default, allowed range and a one-line doc. The struct, its `Default`, the list [`PARAMS`],
//! access by name ([`TrackerParams::set`], [`TrackerParams::get`]) and validation are all made
//! from that table, and the Python binding exports it (`densepeds._core.PARAMS`), from which the
//! Python docs and the type stub are generated (`scripts/gen_params.py`).
//!
//! A value outside its range is rejected with [`TrackError::InvalidParameter`]; every value
//! inside it is used as given (nothing is clamped or replaced further down).

use crate::score_scale::{ScoreCuts, ScoreReading};
use crate::TrackError;
use frvo::{MotionKind, MotionParams};

/// How score thresholds are read (see [`crate::score_scale`], which reads them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScoreScale {
    Absolute,
    Range,
    Rank,
}

/// The names a score scale is chosen by, in [`ScoreScale`]'s order.
pub const SCORE_SCALE_NAMES: &[&str] = &["absolute", "range", "rank"];

impl ScoreScale {
    /// The name this scale is chosen by (one of [`SCORE_SCALE_NAMES`]).
    pub fn name(self) -> &'static str {
        match self {
            Self::Absolute => "absolute",
            Self::Range => "range",
            Self::Rank => "rank",
        }
    }
}

impl std::str::FromStr for ScoreScale {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "absolute" => Ok(Self::Absolute),
            "range" => Ok(Self::Range),
            "rank" => Ok(Self::Rank),
            _ => Err(format!(
                "unknown score scale {s:?}; known: {}",
                SCORE_SCALE_NAMES.join(", ")
            )),
        }
    }
}

/// How a parameter's value is typed (for bindings).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamKind {
    Float,
    Int,
    Bool,
    /// One of a fixed set of names (see [`Range::Choice`]).
    Choice,
}

impl ParamKind {
    /// The Python type name of a value of this kind.
    pub fn python_type(self) -> &'static str {
        match self {
            Self::Float => "float",
            Self::Int => "int",
            Self::Bool => "bool",
            Self::Choice => "str",
        }
    }
}

/// A parameter value.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamValue {
    Float(f64),
    Int(i64),
    Bool(bool),
    Choice(String),
}

/// The values a parameter accepts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// A number between `lo` and `hi` (`*_open`: the bound itself excluded); never NaN.
    Float {
        lo: f64,
        lo_open: bool,
        hi: f64,
        hi_open: bool,
    },
    /// An integer in `lo..=hi`.
    Int { lo: i64, hi: i64 },
    /// `true` or `false`.
    Bool,
    /// One of these names.
    Choice(&'static [&'static str]),
}

/// `[lo, hi]`.
const fn closed(lo: f64, hi: f64) -> Range {
    Range::Float {
        lo,
        lo_open: false,
        hi,
        hi_open: false,
    }
}

/// `(lo, hi)`.
const fn open(lo: f64, hi: f64) -> Range {
    Range::Float {
        lo,
        lo_open: true,
        hi,
        hi_open: true,
    }
}

/// `(lo, hi]`.
const fn open_closed(lo: f64, hi: f64) -> Range {
    Range::Float {
        lo,
        lo_open: true,
        hi,
        hi_open: false,
    }
}

/// `[lo, hi)`.
const fn closed_open(lo: f64, hi: f64) -> Range {
    Range::Float {
        lo,
        lo_open: false,
        hi,
        hi_open: true,
    }
}

/// Any number but NaN (`-inf` and `inf` included).
const ANY: Range = closed(f64::NEG_INFINITY, f64::INFINITY);
/// A finite number > 0.
const POSITIVE: Range = open(0.0, f64::INFINITY);
/// A probability-like value in [0, 1].
const UNIT: Range = closed(0.0, 1.0);

/// An integer in `lo..=hi` (`hi` is a `usize` or `u32` bound, kept within `i64`).
const fn ints(lo: i64, hi: u64) -> Range {
    Range::Int {
        lo,
        hi: if hi > i64::MAX as u64 {
            i64::MAX
        } else {
            hi as i64
        },
    }
}

const U32_MAX: u64 = u32::MAX as u64;
const USIZE_MAX: u64 = usize::MAX as u64;

/// The motion models, by the names `MotionKind` parses.
pub const MOTION_NAMES: &[&str] = &["frvo", "rvo", "sf", "cv"];

/// Largest `max_speed` (pixels per frame) the motion models work with.
pub const MAX_SPEED: f64 = 1e9;

fn fmt_bound(v: f64) -> String {
    if v == f64::INFINITY {
        "inf".into()
    } else if v == f64::NEG_INFINITY {
        "-inf".into()
    } else {
        format!("{v}")
    }
}

impl Range {
    /// The range as users read it: `[0, 1]`, `(0, inf)`, `1..=4294967295`, `frvo|rvo|sf|cv`.
    pub fn describe(&self) -> String {
        match *self {
            Range::Float {
                lo,
                lo_open,
                hi,
                hi_open,
            } => format!(
                "{}{}, {}{}",
                if lo_open { "(" } else { "[" },
                fmt_bound(lo),
                fmt_bound(hi),
                if hi_open { ")" } else { "]" }
            ),
            Range::Int { lo, hi } if hi == i64::MAX => format!(">= {lo}"),
            Range::Int { lo, hi } => format!("{lo}..={hi}"),
            Range::Bool => "True|False".into(),
            Range::Choice(names) => names.join("|"),
        }
    }

    /// Whether `v` lies in the range (a value of another kind never does).
    pub fn contains(&self, v: &ParamValue) -> bool {
        match (*self, v) {
            (
                Range::Float {
                    lo,
                    lo_open,
                    hi,
                    hi_open,
                },
                ParamValue::Float(x),
            ) => {
                let x = *x;
                !x.is_nan()
                    && (if lo_open { x > lo } else { x >= lo })
                    && (if hi_open { x < hi } else { x <= hi })
            }
            (Range::Int { lo, hi }, ParamValue::Int(i)) => (lo..=hi).contains(i),
            (Range::Bool, ParamValue::Bool(_)) => true,
            (Range::Choice(names), ParamValue::Choice(s)) => names.contains(&s.as_str()),
            _ => false,
        }
    }
}

/// One row of the parameter table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    pub kind: ParamKind,
    pub range: Range,
    /// One line for users (units, meaning).
    pub doc: &'static str,
}

/// A field type the table can hold, converted to and from [`ParamValue`].
trait Field: Sized {
    const KIND: ParamKind;
    fn to_value(&self) -> ParamValue;
    /// The field's value, or `None` when `v` is not of this kind (or out of the type's range).
    fn from_value(v: &ParamValue) -> Option<Self>;
}

impl Field for f64 {
    const KIND: ParamKind = ParamKind::Float;
    fn to_value(&self) -> ParamValue {
        ParamValue::Float(*self)
    }
    fn from_value(v: &ParamValue) -> Option<Self> {
        match *v {
            ParamValue::Float(f) => Some(f),
            _ => None,
        }
    }
}

impl Field for u32 {
    const KIND: ParamKind = ParamKind::Int;
    fn to_value(&self) -> ParamValue {
        ParamValue::Int((*self).into())
    }
    fn from_value(v: &ParamValue) -> Option<Self> {
        match *v {
            ParamValue::Int(i) => i.try_into().ok(),
            _ => None,
        }
    }
}

impl Field for usize {
    const KIND: ParamKind = ParamKind::Int;
    fn to_value(&self) -> ParamValue {
        ParamValue::Int(i64::try_from(*self).unwrap_or(i64::MAX))
    }
    fn from_value(v: &ParamValue) -> Option<Self> {
        match *v {
            ParamValue::Int(i) => i.try_into().ok(),
            _ => None,
        }
    }
}

impl Field for bool {
    const KIND: ParamKind = ParamKind::Bool;
    fn to_value(&self) -> ParamValue {
        ParamValue::Bool(*self)
    }
    fn from_value(v: &ParamValue) -> Option<Self> {
        match *v {
            ParamValue::Bool(b) => Some(b),
            _ => None,
        }
    }
}

impl Field for MotionKind {
    const KIND: ParamKind = ParamKind::Choice;
    fn to_value(&self) -> ParamValue {
        ParamValue::Choice(motion_name(*self).into())
    }
    fn from_value(v: &ParamValue) -> Option<Self> {
        match v {
            ParamValue::Choice(s) => s.parse().ok(),
            _ => None,
        }
    }
}

/// The name a motion model is chosen by (one of [`MOTION_NAMES`]).
pub fn motion_name(kind: MotionKind) -> &'static str {
    match kind {
        MotionKind::Frvo => "frvo",
        MotionKind::Rvo => "rvo",
        MotionKind::SocialForce => "sf",
        MotionKind::ConstantVelocity => "cv",
    }
}

fn invalid(name: &str, range: &Range, v: &ParamValue) -> TrackError {
    let got = match v {
        ParamValue::Float(f) => fmt_bound(*f),
        ParamValue::Int(i) => i.to_string(),
        ParamValue::Bool(b) => if *b { "True" } else { "False" }.into(),
        ParamValue::Choice(s) => format!("{s:?}"),
    };
    TrackError::InvalidParameter(format!(
        "{name} must be {} in {}, got {got}",
        match range {
            Range::Float { .. } => "a number",
            Range::Int { .. } => "an integer",
            Range::Bool => "a bool",
            Range::Choice(_) => "a name",
        },
        range.describe()
    ))
}

/// `v` checked against the row's range, as the row's kind (an integer for a float is accepted).
fn checked(spec: &ParamSpec, v: ParamValue) -> Result<ParamValue, TrackError> {
    let v = match (spec.kind, v) {
        (ParamKind::Float, ParamValue::Int(i)) => ParamValue::Float(i as f64),
        (_, v) => v,
    };
    if spec.range.contains(&v) {
        Ok(v)
    } else {
        Err(invalid(spec.name, &spec.range, &v))
    }
}

/// Builds [`TrackerParams`] and everything made from its table. `own` rows are fields of
/// `TrackerParams` (`name: type = default, range, doc`); `motion` rows are the fields of
/// [`frvo::MotionParams`] (held in `motion_params`, defaults from `MotionParams::default()`).
macro_rules! tracker_params {
    (
        own { $( $name:ident : $ty:ty = $default:expr, $range:expr, $doc:literal; )* }
        motion { $( $mname:ident : $mty:ty, $mrange:expr, $mdoc:literal; )* }
    ) => {
        /// Every tunable of the tracker. Units: pixels, frames; scores in [0, 1]. The tracker's
        /// defaults were tuned motion-only on the six dev sequences together (never per sequence;
        /// benchmarks/results/accuracy.md says what each was tuned on, accuracy-loo.md checks it
        /// by leave-one-out). The method's pure form is [`TrackerParams::pure`].
        #[derive(Clone, Debug, PartialEq)]
        pub struct TrackerParams {
            $( #[doc = $doc] pub $name: $ty, )*
            /// The motion model's parameters (the `motion` rows of the table).
            pub motion_params: MotionParams,
        }

        impl Default for TrackerParams {
            fn default() -> Self {
                Self { $( $name: $default, )* motion_params: MotionParams::default() }
            }
        }

        /// Every parameter, in a stable order: the tracker's own, then the motion model's.
        pub const PARAMS: &[ParamSpec] = &[
            $( ParamSpec {
                name: stringify!($name), kind: <$ty as Field>::KIND, range: $range, doc: $doc
            }, )*
            $( ParamSpec {
                name: stringify!($mname), kind: <$mty as Field>::KIND, range: $mrange, doc: $mdoc
            }, )*
        ];

        /// Number of `own` rows at the start of [`PARAMS`]; the rest are the motion model's.
        const OWN_PARAMS: usize = [$( stringify!($name), )*].len();

        impl TrackerParams {
            /// The named parameter's current value, or `None` for an unknown name.
            pub fn get(&self, name: &str) -> Option<ParamValue> {
                $( if name == stringify!($name) { return Some(self.$name.to_value()); } )*
                $( if name == stringify!($mname) {
                    return Some(<$mty as Field>::to_value(&self.motion_params.$mname));
                } )*
                None
            }

            /// Stores an already range-checked value.
            fn store(&mut self, name: &str, v: &ParamValue) -> Option<()> {
                $( if name == stringify!($name) {
                    self.$name = <$ty as Field>::from_value(v)?;
                    return Some(());
                } )*
                $( if name == stringify!($mname) {
                    self.motion_params.$mname = <$mty as Field>::from_value(v)?;
                    return Some(());
                } )*
                None
            }
        }
    };
}

tracker_params! {
    own {
        motion: MotionKind = MotionKind::Frvo, Range::Choice(MOTION_NAMES),
            "motion model predicting each track's next position";
        n_init: u32 = 2, ints(1, U32_MAX),
            "matches before a track is confirmed (gets an id and is reported)";
        max_age: u32 = 120, ints(0, U32_MAX),
            "xi: frames a confirmed track survives unmatched before it is deleted";
        appearance_threshold: f64 = 0.2, closed(0.0, 2.0),
            "lambda: largest cosine distance for an appearance match (stage 1)";
        appearance_apart: f64 = 2.0, closed(0.0, 2.0),
            "largest cosine distance for an appearance match (stage 1) with a detection that does not overlap the track's predicted box (the smaller of this and appearance_threshold applies; 2: off)";
        gallery_size: usize = 20, ints(1, USIZE_MAX),
            "embeddings remembered per track, summarised in at most 8 rows (means of consecutive ones); the appearance cost is the smallest distance to a row";
        gate_radius: f64 = 1.0, open_closed(0.0, f64::INFINITY),
            "rho: a detection matches a track only within this many track box heights (inf: off)";
        iou_threshold: f64 = 0.3, UNIT,
            "smallest IoU between a predicted box and a detection for a motion match (stage 2)";
        det_threshold: f64 = 0.3, ANY,
            "detections scoring below this take no part in stages 1-2 and recovery";
        new_track_threshold: f64 = 0.3, ANY,
            "smallest score that starts a track (only detections >= det_threshold start one)";
        second_pass: bool = true, Range::Bool,
            "ByteTrack-style pass: unmatched tracks vs detections in [low_threshold, det_threshold)";
        low_threshold: f64 = 0.05, ANY,
            "lowest score used by the second pass";
        score_window: usize = 2000, ints(1, USIZE_MAX),
            "scores (the last ones seen) whose quantiles score_quantile_floor and score_quantile_ceiling read";
        score_quantile_floor: f64 = 0.15, UNIT,
            "det_threshold and new_track_threshold are at least this quantile of the last score_window scores, after warm-up (0: off)";
        score_quantile_ceiling: f64 = 0.7, UNIT,
            "where a cut rejects more than this fraction of the last score_window scores (before warm-up: every score seen), det_threshold and new_track_threshold are lowered to at most this quantile and to their place between 0 (or the lowest score, if lower) and the highest score seen, low_threshold to its place there too, so that a detector scoring below the cuts is still tracked (0: off)";
        score_warm_up: usize = 100, ints(0, USIZE_MAX),
            "scores to see before the quantiles of score_quantile_floor and score_quantile_ceiling are used";
        low_iou_threshold: f64 = 0.5, UNIT,
            "smallest IoU for a second-pass match";
        thresholded_low_iou: f64 = 0.3, UNIT,
            "from a detector that thresholds its own output (every score seen so far at or above det_threshold and new_track_threshold as the score scale reads them), a detection that only score_quantile_floor kept out of stages 1-2 is matched in the second pass at the smaller of this IoU and low_iou_threshold (1: low_iou_threshold alone)";
        low_max_age: u32 = 60, ints(0, U32_MAX),
            "tracks unmatched up to this many frames join the second pass (0: ByteTrack's rule)";
        recovery: bool = true, Range::Bool,
            "OC-SORT-style re-match of unmatched tracks by IoU of their last observed box";
        velocity_smoothing: f64 = 0.5, UNIT,
            "weight of the newly observed velocity in the velocity average (1: no smoothing)";
        pref_window: usize = 20, ints(1, USIZE_MAX),
            "frames of matched history the preferred velocity is averaged over";
        position_smoothing: f64 = 0.3, closed_open(0.0, 1.0),
            "weight of the predicted centre in the reported box of a track matched in this frame and the previous one (the track's state keeps the detection's centre; 0: the detection's centre)";
        jitter_floor: f64 = 0.06, closed(0.0, f64::INFINITY),
            "adaptive smoothing: the innovation motion alone explains (distance from a followed track's one-frame prediction to its matched detection, over box height); with the mean innovation over all tracks so far above it, a followed track's matched centre gives weight 1 - (jitter_floor / mean)^2 to the prediction; velocities stay measured on the detections (0: off)";
        jitter_smoothing_state: bool = true, Range::Bool,
            "adaptive smoothing (jitter_floor) moves the track's state, which the next prediction starts from (false: only the reported box, as position_smoothing, the larger weight winning)";
        size_smoothing: f64 = 0.5, closed_open(0.0, 1.0),
            "weight of the previous box size when a match updates it (0: the detection's size)";
        ellipse_l_scale: f64 = 0.15, POSITIVE,
            "FRVO ellipse extent along the motion (the face) = scale * box height";
        ellipse_w_scale: f64 = 0.15, POSITIVE,
            "FRVO ellipse extent across the motion = scale * box width (small: overlap is occlusion)";
        output_lost: u32 = 5, ints(0, U32_MAX),
            "confirmed tracks are also reported, at their prediction, this many frames unmatched";
        output_lost_adaptive: bool = true, Range::Bool,
            "report a lost track at gap t (output_lost, occluded_output) only while, on this sequence so far, lost tracks (occluded and in the open counted apart) were re-found at their predicted box (IoU >= 0.5) at least as often as not";
        occluded_output: u32 = 10, ints(0, U32_MAX),
            "an unmatched track covered by nearer detections is reported up to this many frames; one whose predicted box has less than 90% of its area inside the image (set_image_size) has left it and is deleted (0: off)";
        coast_aspect: bool = true, Range::Bool,
            "an unmatched track's reported box is at least as wide as its matched detections' mean aspect ratio (width over height, over the last 30 matches) makes its height (an occluded person's last boxes are cut narrow)";
        coast_aspect_state: bool = false, Range::Bool,
            "with coast_aspect, the unmatched track's own width widens too, and with it the predicted box it is matched by (not only the reported box)";
        amodal_boxes: bool = false, Range::Bool,
            "a reported box whose lower part is hidden behind a nearer reported box is extended down to the height the fitted perspective expects from its top row (the whole person, as MOTChallenge annotates)";
        tentative_max_age: u32 = 2, ints(0, U32_MAX),
            "frames a tentative track (not yet confirmed by n_init matches) survives unmatched; while it waits it is predicted on its own (not a neighbour in the motion model's step) and matched last, by a detection of the second pass (scored in [low_threshold, det_threshold)) at low_iou_threshold (a confident detection left over starts its own track; from a detector that thresholds its own output, as thresholded_low_iou reads it, every detection is confident), so a person seen once with confidence and then weakly, a frame or two later, is confirmed (0: a tentative track ends at its first miss)";
        coast_aspect_quantile: f64 = 0.0, UNIT,
            "a lost track's reported box is at least as wide as this quantile of the aspect ratios (width over height) of every track's matched detections (the last 2000) makes its height: the width of a person seen whole in this scene (0: off)";
        amodal_width_quantile: f64 = 0.0, UNIT,
            "a matched track's reported box is at least as wide as this quantile of the aspect ratios of every track's matched detections makes its height: a person seen in part, or boxed tighter than the annotation's whole person, reported at the width of one seen whole (reporting only; 0: off)";
        coast_min_hits: u32 = 6, ints(0, U32_MAX),
            "an unmatched track is reported (output_lost, occluded_output) only once it has been matched at least this many times (a young track lost at once is more often a false detection than a person; 0: off)";
        reid_newborn: u32 = 4, ints(0, U32_MAX),
            "deferred re-identification: when a track born while confirmed tracks were lost reaches this many matches (at least n_init), the mean of its embeddings so far is compared with those lost tracks' galleries; the nearest, if within min(appearance_threshold, appearance_apart) and nearer than every other by 0.15, gives the new track its id from that frame on and ends (0: off)";
    }
    motion {
        neighbor_radius: f64, POSITIVE,
            "motion model: only agents closer than this (pixels) constrain each other";
        max_neighbors: usize, ints(1, USIZE_MAX),
            "motion model: at most this many neighbours (nearest first) constrain an agent";
        time_horizon: f64, POSITIVE,
            "motion model: time horizon tau of the velocity obstacles, frames";
        max_speed: f64, open_closed(0.0, MAX_SPEED),
            "motion model: largest speed, pixels per frame";
        polygon_sides: usize, ints(3, frvo::geometry::MAX_SIDES as u64),
            "FRVO: sides of the polygon approximating each ellipse";
        sf_relaxation_time: f64, POSITIVE,
            "social forces: relaxation time toward the preferred velocity, frames";
        sf_strength: f64, closed_open(0.0, f64::INFINITY),
            "social forces: repulsion strength at contact, pixels per frame squared";
        sf_range: f64, POSITIVE,
            "social forces: repulsion range, pixels";
        threads: usize, ints(0, frvo::model::MAX_THREADS as u64),
            "threads for a crowd step (0: every core, from 10,000 agent-neighbour pairs; 1: caller's)";
    }
}

/// The row of the named parameter.
pub fn spec(name: &str) -> Option<&'static ParamSpec> {
    PARAMS.iter().find(|p| p.name == name)
}

/// The named blocks: each crowd extension (or the motion model's tuning) and its parameters,
/// the first being its switch. A parameter in no block is a core one. The blocks are measured
/// on and off in `benchmarks/results/blocks.md`; `docs/tracker.md` describes them.
pub const BLOCKS: &[(&str, &[&str])] = &[
    (
        "second pass",
        &[
            "second_pass",
            "low_threshold",
            "low_iou_threshold",
            "low_max_age",
        ],
    ),
    (
        "score calibration",
        &[
            "score_quantile_floor",
            "score_quantile_ceiling",
            "thresholded_low_iou",
            "score_window",
            "score_warm_up",
        ],
    ),
    ("recovery", &["recovery"]),
    ("occlusion-aware coasting", &["occluded_output"]),
    ("adaptive lost reports", &["output_lost_adaptive"]),
    ("young lost tracks hidden", &["coast_min_hits"]),
    ("tentative tracks", &["tentative_max_age"]),
    (
        "jitter smoothing",
        &["jitter_floor", "jitter_smoothing_state"],
    ),
    ("position smoothing", &["position_smoothing"]),
    (
        "lost-box aspect",
        &[
            "coast_aspect",
            "coast_aspect_state",
            "coast_aspect_quantile",
        ],
    ),
    ("amodal boxes", &["amodal_boxes"]),
    ("amodal widths", &["amodal_width_quantile"]),
    ("appearance apart", &["appearance_apart"]),
    ("newborn re-ID", &["reid_newborn"]),
    (
        "motion model",
        &[
            "ellipse_l_scale",
            "ellipse_w_scale",
            "neighbor_radius",
            "max_neighbors",
            "time_horizon",
            "max_speed",
            "polygon_sides",
            "sf_relaxation_time",
            "sf_strength",
            "sf_range",
            "threads",
        ],
    ),
];

/// The block a parameter belongs to, `"core"` for the core parameters.
pub fn group(name: &str) -> &'static str {
    BLOCKS
        .iter()
        .find(|(_, names)| names.contains(&name))
        .map_or("core", |(block, _)| block)
}

fn unknown(name: &str) -> TrackError {
    let known: Vec<&str> = PARAMS.iter().map(|p| p.name).collect();
    TrackError::InvalidParameter(format!(
        "unknown parameter {name:?}; known: {}",
        known.join(", ")
    ))
}

impl TrackerParams {
    /// The DensePeds paper's plain tracker (appearance then FRVO-predicted IoU, each solved
    /// optimally; no score thresholds, no second pass, no recovery, no size, position or
    /// adaptive smoothing, only matched tracks reported).
    /// Equivalent to the keyword arguments `det_threshold=-inf, new_track_threshold=-inf,
    /// second_pass=False, recovery=False, size_smoothing=0, position_smoothing=0,
    /// jitter_floor=0, thresholded_low_iou=1, output_lost=0, occluded_output=0,
    /// score_quantile_floor=0, score_quantile_ceiling=0,
    /// coast_aspect=False, coast_aspect_quantile=0,
    /// coast_min_hits=0, tentative_max_age=0, reid_newborn=0`. Other fields keep their defaults.
    pub fn pure() -> Self {
        Self {
            score_quantile_floor: 0.0,
            score_quantile_ceiling: 0.0,
            det_threshold: f64::NEG_INFINITY,
            new_track_threshold: f64::NEG_INFINITY,
            second_pass: false,
            recovery: false,
            size_smoothing: 0.0,
            position_smoothing: 0.0,
            jitter_floor: 0.0,
            thresholded_low_iou: 1.0,
            output_lost: 0,
            occluded_output: 0,
            coast_aspect: false,
            coast_aspect_quantile: 0.0,
            coast_min_hits: 0,
            tentative_max_age: 0,
            reid_newborn: 0,
            ..Self::default()
        }
    }

    /// How the score thresholds are read (the `score_*` parameters).
    pub fn score_reading(&self) -> ScoreReading {
        ScoreReading {
            window: self.score_window,
            warm_up: self.score_warm_up,
            quantile_floor: self.score_quantile_floor,
            quantile_ceiling: self.score_quantile_ceiling,
        }
    }

    /// The score thresholds as given (`det_threshold`, `new_track_threshold`, `low_threshold`).
    pub fn score_thresholds(&self) -> ScoreCuts {
        ScoreCuts {
            det: self.det_threshold,
            new_track: self.new_track_threshold,
            low: self.low_threshold,
        }
    }

    /// The type of the named parameter, or `None` for an unknown name.
    pub fn kind_of(name: &str) -> Option<ParamKind> {
        spec(name).map(|s| s.kind)
    }

    /// Sets one parameter by name; an unknown name, a value of the wrong kind or one outside
    /// the parameter's range is an error naming the range (and changes nothing).
    pub fn set(&mut self, name: &str, value: ParamValue) -> Result<(), TrackError> {
        let spec = spec(name).ok_or_else(|| unknown(name))?;
        let v = checked(spec, value)?;
        self.store(name, &v)
            .ok_or_else(|| invalid(name, &spec.range, &v))
    }

    /// Checks every value against its range; the error names the parameter and its range.
    pub fn validate(&self) -> Result<(), TrackError> {
        for spec in PARAMS {
            let v = self.get(spec.name).expect("every row has a field");
            checked(spec, v)?;
        }
        Ok(())
    }

    /// Checks a motion model's parameters against the `motion` rows of the table (for callers
    /// that step a crowd without a tracker).
    pub fn validate_motion(m: &MotionParams) -> Result<(), TrackError> {
        let p = Self {
            motion_params: *m,
            ..Self::default()
        };
        for spec in &PARAMS[OWN_PARAMS..] {
            checked(spec, p.get(spec.name).expect("every row has a field"))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values just outside a row's range (none for a bool), and its bounds that are inside it.
    fn probes(range: &Range) -> (Vec<ParamValue>, Vec<ParamValue>) {
        use ParamValue::{Float, Int};
        let step = |x: f64, up: bool| {
            if x.is_infinite() {
                x
            } else if up {
                x + x.abs().max(1.0) * 1e-9
            } else {
                x - x.abs().max(1.0) * 1e-9
            }
        };
        match *range {
            Range::Float {
                lo,
                lo_open,
                hi,
                hi_open,
            } => {
                let mut outside = vec![Float(f64::NAN)];
                let mut inside = vec![];
                if lo_open {
                    outside.push(Float(lo));
                    inside.push(Float(step(lo, true)));
                } else if lo.is_finite() {
                    outside.push(Float(step(lo, false)));
                    inside.push(Float(lo));
                } else {
                    inside.push(Float(lo));
                }
                if hi_open {
                    outside.push(Float(hi));
                    inside.push(Float(if hi.is_infinite() {
                        1e300
                    } else {
                        step(hi, false)
                    }));
                } else if hi.is_finite() {
                    outside.push(Float(step(hi, true)));
                    inside.push(Float(hi));
                } else {
                    inside.push(Float(hi));
                }
                (outside, inside)
            }
            Range::Int { lo, hi } => {
                let mut outside = vec![Int(lo - 1)];
                if hi < i64::MAX {
                    outside.push(Int(hi + 1));
                }
                (outside, vec![Int(lo), Int(hi)])
            }
            Range::Bool => (
                vec![],
                vec![ParamValue::Bool(false), ParamValue::Bool(true)],
            ),
            Range::Choice(names) => (
                vec![ParamValue::Choice("nope".into())],
                names
                    .iter()
                    .map(|n| ParamValue::Choice((*n).into()))
                    .collect(),
            ),
        }
    }

    #[test]
    fn every_row_has_a_field_a_valid_default_and_a_doc() {
        let d = TrackerParams::default();
        d.validate().unwrap();
        let mut names: Vec<&str> = PARAMS.iter().map(|p| p.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), PARAMS.len(), "a name declared twice");
        for spec in PARAMS {
            let v = d.get(spec.name).unwrap();
            assert!(spec.range.contains(&v), "{}: default {v:?}", spec.name);
            assert!(!spec.doc.is_empty() && !spec.doc.contains('\n'));
            assert_eq!(TrackerParams::kind_of(spec.name), Some(spec.kind));
        }
        assert_eq!(d.get("nope"), None);
        assert_eq!(d.motion_params, MotionParams::default());
    }

    #[test]
    fn values_outside_a_range_are_rejected_and_change_nothing() {
        for spec in PARAMS {
            let (outside, inside) = probes(&spec.range);
            for v in outside {
                let mut p = TrackerParams::default();
                let err = p.set(spec.name, v.clone()).unwrap_err();
                assert!(
                    matches!(&err, TrackError::InvalidParameter(m) if m.starts_with(spec.name)),
                    "{}: {err}",
                    spec.name
                );
                assert_eq!(p, TrackerParams::default(), "{} = {v:?}", spec.name);
            }
            for v in inside {
                let mut p = TrackerParams::default();
                p.set(spec.name, v.clone()).unwrap();
                assert_eq!(p.get(spec.name), Some(v), "{}", spec.name);
                p.validate().unwrap();
            }
        }
    }

    /// Every motion value the table accepts reaches the motion model as given: the model's own
    /// check accepts it and its sanitising leaves it unchanged (nothing silently replaced).
    #[test]
    fn motion_values_in_range_are_used_as_given() {
        for spec in &PARAMS[OWN_PARAMS..] {
            for v in probes(&spec.range).1 {
                let mut p = TrackerParams::default();
                p.set(spec.name, v.clone()).unwrap();
                let m = p.motion_params;
                assert_eq!(m.validate(), Ok(()), "{} = {v:?}", spec.name);
                assert_eq!(m.sanitized(), m, "{} = {v:?}", spec.name);
                TrackerParams::validate_motion(&m).unwrap();
            }
        }
    }

    #[test]
    fn values_the_motion_model_would_replace_are_rejected() {
        use ParamValue::{Float, Int};
        for (name, v) in [
            ("time_horizon", Float(f64::INFINITY)),
            ("max_speed", Float(f64::INFINITY)),
            ("max_speed", Float(2e9)),
            ("polygon_sides", Int(1000)),
            ("neighbor_radius", Float(f64::INFINITY)),
            ("threads", Int(-1)),
        ] {
            let mut p = TrackerParams::default();
            assert!(p.set(name, v.clone()).is_err(), "{name} = {v:?}");
        }
        let m = MotionParams {
            time_horizon: f64::INFINITY,
            ..MotionParams::default()
        };
        assert!(TrackerParams::validate_motion(&m).is_err());
    }

    #[test]
    fn every_block_names_declared_parameters_and_the_core_is_small() {
        for (block, names) in BLOCKS {
            for name in *names {
                assert!(spec(name).is_some(), "{block}: {name}");
                assert_eq!(group(name), *block, "{name} in two blocks");
            }
        }
        let core = PARAMS.iter().filter(|s| group(s.name) == "core").count();
        assert!(core <= 15, "{core} core parameters");
    }

    #[test]
    fn kinds_are_checked() {
        let mut p = TrackerParams::default();
        assert!(p.set("n_init", ParamValue::Float(2.0)).is_err());
        assert!(p.set("recovery", ParamValue::Int(1)).is_err());
        assert!(p.set("iou_threshold", ParamValue::Bool(true)).is_err());
        p.set("iou_threshold", ParamValue::Int(1)).unwrap();
        assert_eq!(p.iou_threshold, 1.0);
        p.set("motion", ParamValue::Choice("cv".into())).unwrap();
        assert_eq!(p.motion, MotionKind::ConstantVelocity);
        let err = p.set("nope", ParamValue::Int(1)).unwrap_err().to_string();
        assert!(err.contains("known: motion, n_init"), "{err}");
    }
}
