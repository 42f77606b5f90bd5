//! `densepeds._core`: thin PyO3 glue over the pure Rust crates. Errors are mapped to Python
//! exceptions in `errors.rs` only.

use pyo3::prelude::*;

mod crowd;
mod errors;
mod tracker;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    crowd::register(m)?;
    tracker::register(m)?;
    Ok(())
}
