//! The project's demonstration files (red-core's versioned JSON format):
//! read and validated, or validated and written, by the Rust code. Python
//! sees the JSON text and builds its own objects from it.

use std::path::PathBuf;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use red_core::Demos;

use crate::arrays::{core_err, drive_err};

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(read_demos_json, m)?)?;
    m.add_function(wrap_pyfunction!(write_demos_json, m)?)?;
    m.add_function(wrap_pyfunction!(validate_demos_json, m)?)?;
    m.add_function(wrap_pyfunction!(demos_summary, m)?)?;
    m.add("DEMO_FORMAT", red_core::demo::FORMAT_NAME)?;
    m.add("DEMO_FORMAT_VERSION", red_core::demo::FORMAT_VERSION)?;
    Ok(())
}

fn to_json(demos: &Demos) -> PyResult<String> {
    serde_json::to_string(demos).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// Reads and validates a demo file (`Demos::read`; older format versions
/// are upgraded) and returns it as JSON text of the current version.
#[pyfunction]
fn read_demos_json(py: Python<'_>, path: PathBuf) -> PyResult<String> {
    let demos = py.detach(|| Demos::read(&path)).map_err(core_err)?;
    to_json(&demos)
}

/// Validates demo JSON text (`Demos::from_json_str`) and writes it to
/// `path` (`Demos::write`).
#[pyfunction]
fn write_demos_json(py: Python<'_>, text: &str, path: PathBuf) -> PyResult<()> {
    py.detach(|| Demos::from_json_str(text)?.write(&path))
        .map_err(core_err)
}

/// Validates demo JSON text and returns it normalised (current version).
/// For drive demonstrations with a road, the road is checked too.
#[pyfunction]
fn validate_demos_json(py: Python<'_>, text: &str) -> PyResult<String> {
    let demos = py.detach(|| Demos::from_json_str(text)).map_err(core_err)?;
    if demos.env_id == red_drive::ENV_ID {
        red_drive::scenario::road_of(&demos).map_err(drive_err)?;
    }
    to_json(&demos)
}

/// `Demos::summary` of demo JSON text.
#[pyfunction]
fn demos_summary(text: &str) -> PyResult<String> {
    Ok(Demos::from_json_str(text).map_err(core_err)?.summary())
}
