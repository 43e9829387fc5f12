//! numpy arrays in and out, and Rust errors as Python exceptions.

use ndarray::{Array2, ArrayViewD, Ix2};
use numpy::{PyArrayDyn, PyArrayMethods};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;

/// A 2-D float matrix from any numpy array of float32 or float64 (C or
/// Fortran order, strided views included) or anything `numpy.asarray`
/// accepts. `cols` is the expected number of columns, if known.
///
/// # Errors
/// `ValueError` naming `what`, the expected shape and the shape given.
pub(crate) fn matrix(
    obj: &Bound<'_, PyAny>,
    what: &str,
    cols: Option<usize>,
) -> PyResult<Array2<f64>> {
    if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
        let r = a.readonly();
        return to_matrix(r.as_array(), what, cols, |v| v);
    }
    if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        let r = a.readonly();
        return to_matrix(r.as_array(), what, cols, f64::from);
    }
    // Lists, integer arrays, float16 ...: let numpy convert them.
    let np = obj.py().import("numpy")?;
    let converted = np.call_method1("asarray", (obj, "float64")).map_err(|e| {
        PyValueError::new_err(format!(
            "{what} must be a float array of shape {}, and this could not be converted: {e}",
            expected(cols)
        ))
    })?;
    let a = converted.cast::<PyArrayDyn<f64>>()?;
    let r = a.readonly();
    to_matrix(r.as_array(), what, cols, |v| v)
}

fn expected(cols: Option<usize>) -> String {
    match cols {
        Some(c) => format!("(n, {c})"),
        None => "(n, d)".into(),
    }
}

fn to_matrix<T: Copy>(
    a: ArrayViewD<'_, T>,
    what: &str,
    cols: Option<usize>,
    f: impl Fn(T) -> f64,
) -> PyResult<Array2<f64>> {
    let shape = a.shape().to_vec();
    let bad = |hint: &str| {
        PyValueError::new_err(format!(
            "{what} must be a 2-D array of shape {} (float32 or float64), got shape {}{hint}",
            expected(cols),
            shape_str(&shape)
        ))
    };
    let m = match a.into_dimensionality::<Ix2>() {
        Ok(m) => m,
        Err(_) if shape.len() == 1 => {
            return Err(bad(&format!(
                "; for a single row pass {what}[None, :] (shape (1, {}))",
                shape[0]
            )));
        }
        Err(_) => return Err(bad("")),
    };
    if let Some(c) = cols
        && m.ncols() != c
    {
        return Err(bad(""));
    }
    // `mapv` walks any memory order and returns a C-order array.
    Ok(m.mapv(f))
}

fn shape_str(shape: &[usize]) -> String {
    match shape {
        [n] => format!("({n},)"),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(usize::to_string)
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Checks that a batch of states and a batch of actions have as many rows.
pub(crate) fn same_rows(s: &Array2<f64>, a: &Array2<f64>) -> PyResult<()> {
    if s.nrows() != a.nrows() {
        return Err(PyValueError::new_err(format!(
            "obs and act must have the same number of rows (one state-action pair per row), got {} and {}",
            s.nrows(),
            a.nrows()
        )));
    }
    Ok(())
}

/// `red_support::Error` as a Python exception: bad input is a
/// `ValueError`, a file that cannot be read or written an `OSError`.
pub(crate) fn support_err(e: red_support::Error) -> PyErr {
    use red_support::Error as E;
    match e {
        E::Io { .. } => PyOSError::new_err(e.to_string()),
        E::Numerical { .. } | E::Nets(_) => PyRuntimeError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// `red_core::Error` as a Python exception.
pub(crate) fn core_err(e: red_core::Error) -> PyErr {
    use red_core::Error as E;
    match e {
        E::Io { .. } => PyOSError::new_err(e.to_string()),
        E::Env { .. } | E::NeedsReset { .. } => PyRuntimeError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// `red_drive::Error` as a Python exception.
pub(crate) fn drive_err(e: red_drive::Error) -> PyErr {
    match e {
        red_drive::Error::Core(c) => core_err(c),
        red_drive::Error::Render { .. } => PyRuntimeError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}
