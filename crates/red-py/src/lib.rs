//! Python bindings of the red workspace (the `red._red` extension module).
//!
//! Everything here is a thin layer over the Rust crates: arrays in and out,
//! errors turned into Python exceptions, the GIL released around the
//! numerical work. The Python package `red` (in `python/red`) builds the
//! user-facing API (Gymnasium env and wrappers, demo converters) on it.
//!
//! Build and install with `pip install ./crates/red-py` (maturin turns on
//! PyO3's `extension-module` feature, see `pyproject.toml`).

// PyO3's macros expand to unsafe FFI code; the workspace denies it elsewhere.
#![allow(unsafe_code)]

mod arrays;
mod demos;
mod drive;
mod support;

use pyo3::prelude::*;

/// The extension module `red._red`.
#[pymodule]
fn _red(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    support::register(m)?;
    demos::register(m)?;
    drive::register(m)?;
    Ok(())
}
