//! Binding for stepping a whole crowd with a motion model (owned by the frvo work).

use pyo3::prelude::*;

pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
