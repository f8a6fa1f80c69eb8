//! numpy arrays in and out: any array-like of numbers in (converted with `numpy.asarray(x,
//! dtype=float64)`), checked for shape and finiteness; `float64` arrays out.

use nalgebra::Isometry3;
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::value_error;

/// A float64 array's values (row-major) and shape, from any array-like; `name` is the argument's
/// name in messages. Errors (`ValueError`): not numeric, or a NaN/inf value (naming its index).
pub fn f64_array(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<(Vec<f64>, Vec<usize>)> {
    let py = obj.py();
    let np = py.import("numpy")?;
    let arr = np
        .call_method1("ascontiguousarray", (obj, "float64"))
        .map_err(|e| value_error(format!("{name}: not an array of numbers ({e})")))?;
    let arr = arr.cast_into::<PyArrayDyn<f64>>()?;
    let ro = arr.readonly();
    let shape = ro.shape().to_vec();
    let values: Vec<f64> = ro.as_array().iter().copied().collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        let index = unravel(i, &shape);
        return Err(value_error(format!(
            "{name}{index:?}: {} is not finite; NaN and inf cannot be calibrated: remove or re-record the row",
            values[i]
        )));
    }
    Ok((values, shape))
}

/// The multi-index of flat index `i` in `shape` (row-major).
fn unravel(mut i: usize, shape: &[usize]) -> Vec<usize> {
    let mut index = vec![0; shape.len()];
    for (k, &n) in shape.iter().enumerate().rev() {
        if n > 0 {
            index[k] = i % n;
            i /= n;
        }
    }
    index
}

/// Rows of `width` numbers from an `(n, width)` array (or one `(width,)` row, `single` true);
/// `what` says what a row is in the message.
pub fn rows(
    obj: &Bound<'_, PyAny>,
    name: &str,
    width: usize,
    what: &str,
) -> PyResult<(Vec<Vec<f64>>, bool)> {
    let (values, shape) = f64_array(obj, name)?;
    let single = match shape.as_slice() {
        [w] if *w == width => true,
        [_, w] if *w == width => false,
        _ => {
            return Err(value_error(format!(
                "{name}: shape {shape:?}, expected (n, {width}) ({what}) or ({width},)"
            )))
        }
    };
    Ok((values.chunks(width).map(<[f64]>::to_vec).collect(), single))
}

/// `a_from_b` as a 4×4 homogeneous matrix with the translation in mm.
pub fn matrix_mm(a_from_b: &Isometry3<f64>) -> [[f64; 4]; 4] {
    let m = a_from_b.to_homogeneous();
    let mut out = [[0.0; 4]; 4];
    for (r, row) in out.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = m[(r, c)] * if c == 3 && r < 3 { 1e3 } else { 1.0 };
        }
    }
    out
}

/// A (4, 4) array of one pose ([`matrix_mm`]).
pub fn pose_array<'py>(py: Python<'py>, a_from_b: &Isometry3<f64>) -> Bound<'py, PyArray2<f64>> {
    let m = matrix_mm(a_from_b);
    PyArray2::from_owned_array(py, Array2::from_shape_fn((4, 4), |(r, c)| m[r][c]))
}

/// An (n, 4, 4) array of poses ([`matrix_mm`]).
pub fn poses_array<'py>(py: Python<'py>, poses: &[[[f64; 4]; 4]]) -> Bound<'py, PyArray3<f64>> {
    PyArray3::from_owned_array(
        py,
        Array3::from_shape_fn((poses.len(), 4, 4), |(i, r, c)| poses[i][r][c]),
    )
}

/// An (n, k) array from rows of equal length `k`.
pub fn table<'py>(py: Python<'py>, rows: &[Vec<f64>], k: usize) -> Bound<'py, PyArray2<f64>> {
    PyArray2::from_owned_array(
        py,
        Array2::from_shape_fn((rows.len(), k), |(i, j)| rows[i][j]),
    )
}

/// A 1-D array.
pub fn vector<'py>(py: Python<'py>, v: Vec<f64>) -> Bound<'py, PyArray1<f64>> {
    PyArray1::from_owned_array(py, Array1::from_vec(v))
}

/// A serialisable report as a Python object through its JSON (`json.loads`): the dict equals
/// the CLI's `--json` output parsed the same way.
pub fn json_to_py<'py>(py: Python<'py>, json: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (json,))
}
