//! The one place where Rust errors become Python exceptions. Every bad input or parameter is a
//! `ValueError` (the Python wrapper refines them into densepeds.errors types).

use assoc::TrackError;
use pyo3::exceptions::PyValueError;
use pyo3::PyErr;

pub fn track_error(e: TrackError) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// Bad array shape, dtype or value detected in the glue itself.
pub fn input_error(msg: impl Into<String>) -> PyErr {
    track_error(TrackError::InvalidInput(msg.into()))
}

/// Bad keyword parameter detected in the glue itself.
pub fn parameter_error(msg: impl Into<String>) -> PyErr {
    track_error(TrackError::InvalidParameter(msg.into()))
}
