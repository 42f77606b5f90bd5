//! The one place where Rust errors become Python exceptions.

use assoc::TrackError;
use pyo3::exceptions::PyValueError;
use pyo3::PyErr;

pub fn track_error(e: TrackError) -> PyErr {
    PyValueError::new_err(e.to_string())
}
