//! Association for DensePeds: cost matrices (IoU, cosine), optimal assignment, track bookkeeping
//! and the online [`tracker`].

pub mod error;
pub use error::TrackError;
