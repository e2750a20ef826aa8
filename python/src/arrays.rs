//! Reading numpy arrays (or anything `numpy.asarray` accepts) into checked Rust vectors.

use crate::errors;
use num_complex::Complex64;
use numpy::{AllowTypeChange, PyArrayLike1};
use pyo3::prelude::*;

/// A 1-D float array argument (lists and integer arrays are converted).
pub(crate) type FloatArray<'py> = PyArrayLike1<'py, f64, AllowTypeChange>;
/// A 1-D complex array argument.
pub(crate) type ComplexArray<'py> = PyArrayLike1<'py, Complex64, AllowTypeChange>;

/// The samples of `a`, checked: at least `min_len` of them, all finite.
pub(crate) fn floats(name: &str, a: &FloatArray<'_>, min_len: usize) -> PyResult<Vec<f64>> {
    let v: Vec<f64> = a.as_array().iter().copied().collect();
    if v.len() < min_len {
        return Err(errors::data(if v.is_empty() {
            format!("{name} is empty")
        } else {
            format!("{name} has {} samples (need at least {min_len})", v.len())
        }));
    }
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(errors::data(format!(
            "{name}[{i}] is {} (must be finite)",
            v[i]
        )));
    }
    Ok(v)
}

/// The values of `a`, checked: at least `min_len` of them, all finite.
pub(crate) fn complexes(
    name: &str,
    a: &ComplexArray<'_>,
    min_len: usize,
) -> PyResult<Vec<Complex64>> {
    let v: Vec<Complex64> = a.as_array().iter().copied().collect();
    if v.len() < min_len {
        return Err(errors::data(format!(
            "{name} has {} values (need at least {min_len})",
            v.len()
        )));
    }
    if let Some(i) = v
        .iter()
        .position(|x| !x.re.is_finite() || !x.im.is_finite())
    {
        return Err(errors::data(format!(
            "{name}[{i}] is {} (must be finite)",
            v[i]
        )));
    }
    Ok(v)
}

/// Check that two arrays have the same length.
pub(crate) fn same_len(a: (&str, usize), b: (&str, usize)) -> PyResult<()> {
    if a.1 != b.1 {
        return Err(errors::data(format!(
            "{} has {} samples but {} has {}",
            a.0, a.1, b.0, b.1
        )));
    }
    Ok(())
}

/// Check a positive finite number.
pub(crate) fn positive(name: &str, x: f64) -> PyResult<f64> {
    if !(x.is_finite() && x > 0.0) {
        return Err(errors::data(format!(
            "{name} = {x} must be a positive finite number"
        )));
    }
    Ok(x)
}
