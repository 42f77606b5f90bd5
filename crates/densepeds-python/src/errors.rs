//! The one place where Rust errors become Python exceptions: each [`TrackError`] by its kind,
//! `InvalidInput` as `densepeds.errors.InputError`, `InvalidParameter` as
//! `densepeds.errors.ParameterError` (a `ValueError`), and a tracker used by two threads at once as
//! `RuntimeError`. The rest of the binding builds a `TrackError` and calls [`track_error`]; no
//! other module names a Python exception type.

use assoc::TrackError;
use pyo3::exceptions::PyRuntimeError;
use pyo3::PyErr;

pyo3::import_exception!(densepeds.errors, InputError);
pyo3::import_exception!(densepeds.errors, ParameterError);

/// The Python exception for `e`, carrying its message without the kind prefix.
pub fn track_error(e: TrackError) -> PyErr {
    match e {
        TrackError::InvalidInput(msg) => InputError::new_err(msg),
        TrackError::InvalidParameter(msg) => ParameterError::new_err(msg),
    }
}

/// Bad array shape, dtype or value detected in the glue itself.
pub fn input_error(msg: impl Into<String>) -> PyErr {
    track_error(TrackError::InvalidInput(msg.into()))
}

/// Bad keyword parameter detected in the glue itself.
pub fn parameter_error(msg: impl Into<String>) -> PyErr {
    track_error(TrackError::InvalidParameter(msg.into()))
}

/// A tracker used by a second thread while one is updating it: frames of two sequences (or two
/// threads' frames of one) must not be mixed into one tracker's state.
pub fn busy_error() -> PyErr {
    PyRuntimeError::new_err(
        "this Tracker is being updated by another thread: use one Tracker per thread \
         (or serialise the calls with a lock)",
    )
}
