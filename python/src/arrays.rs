//! Reading numpy arrays (or anything `numpy.asarray` accepts) into checked Rust vectors.

use crate::errors;
use num_complex::Complex64;
use numpy::{AllowTypeChange, Element, PyArrayLike1};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;

/// A 1-D array argument of `T` (lists and integer arrays are converted). One that is not 1-D, or
/// not numbers, raises a `TypeError` that says the shape or the type found (pyo3 prefixes the
/// argument's name): "argument 'u': expected a 1-D array of real numbers, got an array of shape
/// (3, 2)".
pub(crate) struct Array1<'py, T: Element>(PyArrayLike1<'py, T, AllowTypeChange>);

/// A 1-D float array argument.
pub(crate) type FloatArray<'py> = Array1<'py, f64>;
/// A 1-D complex array argument.
pub(crate) type ComplexArray<'py> = Array1<'py, Complex64>;

impl<'py, T: Element> std::ops::Deref for Array1<'py, T> {
    type Target = PyArrayLike1<'py, T, AllowTypeChange>;
    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl<'py, T> FromPyObject<'py> for Array1<'py, T>
where
    T: Element + 'py,
    Vec<T>: FromPyObject<'py>,
{
    fn extract_bound(ob: &Bound<'py, PyAny>) -> PyResult<Self> {
        refuse_lossy::<T>(ob)?;
        match ob.extract::<PyArrayLike1<'py, T, AllowTypeChange>>() {
            Ok(a) => Ok(Self(a)),
            Err(e) => Err(explain(ob).unwrap_or(e)),
        }
    }
}

/// Refuse (a `TypeError`, named by pyo3 after the argument) an array whose conversion would
/// lose something without a word: complex values where real ones are wanted (numpy would drop
/// their imaginary parts with only a `ComplexWarning`), and a masked array with masked values
/// (numpy's conversion ignores the mask: the masked samples would be fitted). The mask is refused
/// rather than honoured: dropping samples leaves a time record unevenly sampled, a different
/// record than the one given; the caller fills or cuts it knowingly. A list needs no check (numpy
/// refuses to turn complex numbers into floats), so only objects with a `dtype` are looked at.
fn refuse_lossy<T: Element>(ob: &Bound<'_, PyAny>) -> PyResult<()> {
    let py = ob.py();
    let Ok(dtype) = ob.getattr("dtype") else {
        return Ok(());
    };
    let kind = |d: &Bound<'_, PyAny>| -> PyResult<String> { d.getattr("kind")?.extract() };
    let wanted = T::get_dtype(py);
    if kind(&dtype)? == "c" && kind(wanted.as_any())? != "c" {
        return Err(PyTypeError::new_err(format!(
            "expected a 1-D array of real numbers, got complex values (dtype {}): their imaginary \
             part would be dropped; pass the real part (x.real) if it is only rounding noise",
            dtype.str()?
        )));
    }
    let ma = py.import("numpy")?.getattr("ma")?;
    if ma.call_method1("isMaskedArray", (ob,))?.is_truthy()? {
        let masked: usize = ma.call_method1("count_masked", (ob,))?.extract()?;
        if masked > 0 {
            return Err(PyTypeError::new_err(format!(
                "expected a plain array, got a masked array with {masked} masked value(s): the \
                 mask would be ignored and the masked samples used; fill them (x.filled(v)) or \
                 cut the record where the data are valid"
            )));
        }
    }
    Ok(())
}

/// Why `ob` is not a 1-D numeric array, in words: its shape or its type.
fn explain(ob: &Bound<'_, PyAny>) -> Option<PyErr> {
    let np = ob.py().import("numpy").ok()?;
    let what = "a 1-D array of numbers";
    let arr = match np.call_method1("asarray", (ob,)) {
        Ok(a) => a,
        Err(_) => {
            let ty = ob.get_type().name().ok()?.to_string();
            return Some(PyTypeError::new_err(format!(
                "expected {what}, got a {ty} that is not an array"
            )));
        }
    };
    let shape = arr.getattr("shape").ok()?;
    let ndim: usize = arr.getattr("ndim").ok()?.extract().ok()?;
    if ndim != 1 {
        return Some(PyTypeError::new_err(format!(
            "expected {what}, got an array of shape {} ({ndim}-D){}",
            shape.str().ok()?,
            if ndim == 2 {
                ": pass one row or column, e.g. a[:, 0]"
            } else {
                ""
            }
        )));
    }
    let dtype = arr.getattr("dtype").ok()?.str().ok()?.to_string();
    Some(PyTypeError::new_err(format!(
        "expected {what}, got an array of dtype {dtype}"
    )))
}

/// A count argument taken as a Python int: negative values raise a `DataError` naming `name`
/// (not a bare `OverflowError`).
pub(crate) fn count(name: &str, v: i64) -> PyResult<usize> {
    usize::try_from(v)
        .map_err(|_| errors::data(format!("{name} = {v} must be a non-negative integer")))
}

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
