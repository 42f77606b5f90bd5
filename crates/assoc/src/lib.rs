//! Association for DensePeds: cost matrices (IoU, cosine), optimal assignment, track bookkeeping
//! and the online [`tracker`].

pub mod amodal_width;
pub mod cost;
pub mod crowd_aspect;
pub mod error;
pub mod jitter;
pub mod lap;
pub mod lost_report;
pub mod occlusion;
pub mod params;
pub mod perspective;
mod predict;
mod reid;
pub mod score_scale;
mod track;
pub mod tracker;

pub use error::TrackError;
pub use lap::{linear_sum_assignment, Edge, LapWorkspace, SparseMatcher, DENSE_COMPONENT_MAX};
pub use params::{ParamKind, ParamSpec, ParamValue, Range, TrackerParams, PARAMS};
pub use score_scale::{ScoreCuts, ScoreReading, ScoreScaler};
pub use tracker::{Embeddings, TrackOutput, Tracker};
