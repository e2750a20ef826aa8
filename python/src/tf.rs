//! `fracid.FracTf`: fractional transfer functions, their frequency response and simulation;
//! PRBS generation.

use crate::arrays::{count, floats, positive, FloatArray};
use crate::errors;
use fracsim::prbs::Prbs;
use fracsim::{gl, lsim, ApproxSpec, FracTf, Method, Term};
use num_complex::Complex64;
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A fractional transfer function
/// `G(s) = sum_i b_i s^beta_i / sum_j a_j s^alpha_j * exp(-delay s)` (a Python `FracTf`).
#[pyclass(name = "FracTf", module = "fracid", frozen, eq)]
#[derive(Debug, Clone, PartialEq)]
pub struct PyFracTf {
    /// The Rust model.
    pub(crate) inner: FracTf,
}

impl From<FracTf> for PyFracTf {
    fn from(inner: FracTf) -> Self {
        Self { inner }
    }
}

/// Two float arrays (magnitude and phase).
type ArrayPair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);
/// The constructor arguments `(num, den, delay)`.
type TfArgs = (Vec<(f64, f64)>, Vec<(f64, f64)>, f64);

fn terms(t: &[(f64, f64)]) -> Vec<Term> {
    t.iter().map(|&(c, o)| Term::new(c, o)).collect()
}

fn pairs(t: &[Term]) -> Vec<(f64, f64)> {
    t.iter().map(|t| (t.coef, t.order)).collect()
}

/// The approximation spec from the Python keywords.
pub(crate) fn approx_spec(
    method: &str,
    band: Option<(f64, f64)>,
    order: usize,
) -> PyResult<ApproxSpec> {
    let method: Method = method.parse().map_err(errors::sim)?;
    if let Some((w_b, w_h)) = band {
        fracsim::approx::check_band(w_b, w_h).map_err(errors::sim)?;
    }
    fracsim::approx::check_order(order).map_err(|e| errors::data(e.to_string()))?;
    Ok(ApproxSpec {
        method,
        band,
        order,
    })
}

/// The model as the docs/design.md §7 JSON object, the reports' own
/// ([`fracsim::json::ModelReport`]: `num`, `den` (lists of `{coef, order}`), `delay`, `text`,
/// `effects`, empty for a transfer function).
pub(crate) fn model_dict<'py>(py: Python<'py>, g: &FracTf) -> PyResult<Bound<'py, PyDict>> {
    Ok(crate::time::to_py(py, &fracsim::json::ModelReport::from(g))?.downcast_into::<PyDict>()?)
}

/// Magnitude (dB) and unwrapped phase (degrees) of a frequency response.
pub(crate) fn mag_phase(h: &[Complex64]) -> (Vec<f64>, Vec<f64>) {
    let mag = h.iter().map(|z| 20.0 * z.norm().log10()).collect();
    let mut phase: Vec<f64> = Vec::with_capacity(h.len());
    for z in h {
        let mut p = z.arg().to_degrees();
        if let Some(&prev) = phase.last() {
            while p - prev > 180.0 {
                p -= 360.0;
            }
            while p - prev < -180.0 {
                p += 360.0;
            }
        }
        phase.push(p);
    }
    (mag, phase)
}

#[pymethods]
impl PyFracTf {
    /// Build from numerator and denominator terms `[(coef, order), ...]` and a delay in seconds.
    #[new]
    #[pyo3(signature = (num, den, delay = 0.0))]
    fn new(num: Vec<(f64, f64)>, den: Vec<(f64, f64)>, delay: f64) -> PyResult<Self> {
        FracTf::new(terms(&num), terms(&den), delay)
            .map(Self::from)
            .map_err(errors::sim)
    }

    /// Parse a model such as `"6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)"`.
    #[staticmethod]
    fn parse(text: &str) -> PyResult<Self> {
        text.parse::<FracTf>().map(Self::from).map_err(errors::sim)
    }

    /// The PMSM structure `k / (a2 s^(zeta+theta) + a1 s^zeta + 1)` (paper eq. 10).
    #[staticmethod]
    fn pmsm(k: f64, a1: f64, a2: f64, zeta: f64, theta: f64) -> PyResult<Self> {
        FracTf::pmsm(k, a1, a2, zeta, theta)
            .map(Self::from)
            .map_err(errors::sim)
    }

    /// Numerator terms `[(coef, order), ...]`, decreasing order.
    #[getter]
    fn num(&self) -> Vec<(f64, f64)> {
        pairs(&self.inner.num)
    }

    /// Denominator terms `[(coef, order), ...]`, decreasing order.
    #[getter]
    fn den(&self) -> Vec<(f64, f64)> {
        pairs(&self.inner.den)
    }

    /// Input delay in seconds.
    #[getter]
    fn delay(&self) -> f64 {
        self.inner.delay
    }

    /// The static gain `G(0)`.
    fn dc_gain(&self) -> f64 {
        self.inner.dc_gain()
    }

    /// The same model with another delay.
    fn with_delay(&self, delay: f64) -> PyResult<Self> {
        self.inner
            .clone()
            .with_delay(delay)
            .map(Self::from)
            .map_err(errors::sim)
    }

    /// `G(j omega)` at each omega (rad/s), complex.
    fn freq_response<'py>(
        &self,
        py: Python<'py>,
        omega: FloatArray<'py>,
    ) -> PyResult<Bound<'py, PyArray1<Complex64>>> {
        let w = floats("omega", &omega, 0)?;
        Ok(self.inner.bode(&w).into_pyarray(py))
    }

    /// Magnitude in dB and unwrapped phase in degrees at each omega (rad/s).
    fn bode<'py>(&self, py: Python<'py>, omega: FloatArray<'py>) -> PyResult<ArrayPair<'py>> {
        let w = floats("omega", &omega, 0)?;
        let (m, p) = mag_phase(&self.inner.bode(&w));
        Ok((m.into_pyarray(py), p.into_pyarray(py)))
    }

    /// Simulate from rest on input `u` sampled every `dt` seconds.
    #[pyo3(signature = (u, dt, method = "refined", band = None, order = 8))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        u: FloatArray<'py>,
        dt: f64,
        method: &str,
        band: Option<(f64, f64)>,
        order: i64,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let order = count("order", order)?;
        let u = floats("u", &u, 1)?;
        let dt = positive("dt", dt)?;
        self.inner.check_proper().map_err(errors::sim)?;
        let tf = self.inner.clone();
        let y = if method.eq_ignore_ascii_case("gl") || method.eq_ignore_ascii_case("grunwald") {
            py.allow_threads(|| gl::simulate_held(&tf, &u, dt, gl::HELD_SUBSTEPS))
        } else {
            let spec = approx_spec(method, band, order)?;
            py.allow_threads(|| lsim(&tf, &u, dt, &spec))
        }
        .map_err(errors::sim)?;
        Ok(y.into_pyarray(py))
    }

    /// The approximation as a state space (`fracsim::export`): continuous (`dt=None`, or
    /// `continuous=True`), or discrete with the exact zero-order hold of period `dt`, the delay
    /// as extra states. Returns a `fracid.StateSpace` (numpy `a, b, c, d`).
    #[pyo3(signature = (dt = None, method = "refined", band = None, order = 8, continuous = false))]
    fn to_state_space<'py>(
        &self,
        py: Python<'py>,
        dt: Option<f64>,
        method: &str,
        band: Option<(f64, f64)>,
        order: usize,
        continuous: bool,
    ) -> PyResult<Bound<'py, PyAny>> {
        let spec = approx_spec(method, band, order)?;
        let dt = dt.map(|t| positive("dt", t)).transpose()?;
        let g = &self.inner;
        let ss = match (dt, continuous) {
            (Some(t), false) => fracsim::export::discrete(g, t, &spec),
            (Some(t), true) => spec
                .band_for(t)
                .and_then(|b| fracsim::export::continuous(g, b, &spec)),
            (None, _) => match band {
                Some(b) => fracsim::export::continuous(g, b, &spec),
                None => {
                    return Err(errors::data(
                        "a continuous state space needs band=(w_b, w_h) in rad/s, or dt for \
                         the discrete model (its default band is [1e-6/dt, 30 pi/dt])",
                    ))
                }
            },
        }
        .map_err(errors::sim)?;
        // the one JSON form of a state space (`fracsim::json`), as `fracid export` writes it
        let doc = serde_json::to_string(&ss.to_json(&g.to_string()))
            .map_err(|e| errors::data(e.to_string()))?;
        py.import("fracid._export")?
            .getattr("StateSpace")?
            .call_method1("_from_json", (doc,))
    }

    /// The model as a dict, the reports' model object: `num`, `den` (lists of `{coef, order}`),
    /// `delay`, `text`, `effects` (empty).
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        model_dict(py, &self.inner)
    }

    fn __str__(&self) -> String {
        self.inner.to_string()
    }

    fn __repr__(&self) -> String {
        format!("FracTf.parse({:?})", self.inner.to_string())
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, TfArgs)> {
        let g = &slf.get().inner;
        Ok((
            slf.get_type().into_any(),
            (pairs(&g.num), pairs(&g.den), g.delay),
        ))
    }
}

/// Grunwald-Letnikov simulation (the implicit reference scheme with the whole memory, at most 2e5 samples).
#[pyfunction]
pub(crate) fn gl_simulate<'py>(
    py: Python<'py>,
    tf: &PyFracTf,
    u: FloatArray<'py>,
    dt: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let u = floats("u", &u, 1)?;
    let dt = positive("dt", dt)?;
    tf.inner.check_proper().map_err(errors::sim)?;
    let g = tf.inner.clone();
    let y = py
        .allow_threads(|| gl::simulate(&g, &u, dt))
        .map_err(errors::sim)?;
    Ok(y.into_pyarray(py))
}

/// A sampled PRBS (maximum-length sequence) signal.
#[pyfunction]
#[pyo3(signature = (dt, order = 7, clock = 0.003, amplitude = 1.0, offset = 0.0, periods = 1, seed = 1))]
pub(crate) fn prbs<'py>(
    py: Python<'py>,
    dt: f64,
    order: i64,
    clock: f64,
    amplitude: f64,
    offset: f64,
    periods: i64,
    seed: i64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let periods = count("periods", periods)?;
    let order = u32::try_from(order)
        .map_err(|_| errors::data(format!("order = {order} must be in 2..=16")))?;
    let seed = u32::try_from(seed)
        .map_err(|_| errors::data(format!("seed = {seed} must be an integer in 1..2^order")))?;
    if periods == 0 {
        return Err(errors::data("periods must be at least 1"));
    }
    let p = Prbs {
        order,
        clock,
        amplitude,
        offset,
        periods,
        seed,
    };
    let u = p.signal(dt).map_err(errors::sim)?;
    Ok(u.into_pyarray(py))
}
