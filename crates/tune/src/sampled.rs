//! The sampled loop judged with the sampled model: the controller's discrete realisation
//! ([`crate::realise::discrete`]) in series with the model discretised exactly for the held
//! input (`fracsim::export::discrete`, its delay as states), `L_d(e^(j w dt)) = C_d P_d` for
//! `w` up to the Nyquist frequency `pi/dt`.
//!
//! Below `w_s = 0.01/dt` the two discretisations agree with the continuous loop with the hold's
//! half-sample delay to `O((w dt)^2)` (1e-4), and the fractional operators' approximations stop
//! being exact below their band: there the loop is the continuous one
//! ([`crate::analysis::loop_response`]). Crossovers, margins and the sensitivity peak are those of
//! this loop on the frequencies of [`crate::analysis::loop_grid`] up to `pi/dt` (refined around
//! the model's lightly damped poles and their aliases). Stability is the Nyquist criterion on the
//! unit circle indented outside `z = 1`, the image of the D contour under `z = e^(s dt)`: with
//! `Delta` the change of `arg(1 + L)` from `w = 0+` to `pi/dt` along that loop and `L ~ K s^-n`
//! near the origin, the closed loop has `P + (n pi - 2 Delta)/(2 pi)` poles outside the unit
//! circle, `P` the model's unstable poles (an exact hold maps them outside; counted on the
//! continuous model, [`crate::analysis::plant_unstable`]).

use crate::analysis::{self, LoopMetrics};
use crate::controller::Controller;
use crate::error::Result;
use crate::plant::Plant;
use fracsim::export::{self, StateSpace};
use fracsim::{ApproxSpec, FracTf};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::f64::consts::PI;

/// A discrete single-input single-output system reduced once to upper Hessenberg form
/// (`A = Q H Q^T`), so that each `C (z I - A)^-1 B + D` costs `O(n^2)` (Laub, "Efficient
/// multivariable frequency response computations", IEEE TAC 26 (1981)).
pub struct FastResponse {
    h: DMatrix<f64>,
    b: DVector<f64>,
    c: DVector<f64>,
    d: f64,
    dt: f64,
}

impl FastResponse {
    /// From a discrete state space.
    pub fn new(ss: &StateSpace) -> Self {
        let n = ss.a.nrows();
        let dt = ss.dt.unwrap_or(1.0);
        if n == 0 {
            return Self {
                h: DMatrix::zeros(0, 0),
                b: DVector::zeros(0),
                c: DVector::zeros(0),
                d: ss.d,
                dt,
            };
        }
        let hess = nalgebra::linalg::Hessenberg::new(ss.a.clone());
        let q = hess.q();
        let h = hess.h();
        let b = q.transpose() * ss.b.column(0);
        let c = q.transpose() * ss.c.row(0).transpose();
        Self {
            h,
            b,
            c,
            d: ss.d,
            dt,
        }
    }

    /// The response at `omega` rad/s, `z = e^(j omega dt)`.
    pub fn at(&self, omega: f64) -> Complex64 {
        let n = self.b.len();
        if n == 0 {
            return Complex64::new(self.d, 0.0);
        }
        let z = Complex64::from_polar(1.0, omega * self.dt);
        // (z I - H) x = b, H upper Hessenberg: elimination of the subdiagonal with row swaps
        let mut m: Vec<Complex64> = (0..n * n)
            .map(|k| {
                let (i, j) = (k / n, k % n);
                let a = Complex64::new(-self.h[(i, j)], 0.0);
                if i == j {
                    a + z
                } else {
                    a
                }
            })
            .collect();
        let mut x: Vec<Complex64> = self.b.iter().map(|&v| Complex64::new(v, 0.0)).collect();
        for k in 0..n.saturating_sub(1) {
            if m[(k + 1) * n + k].norm() > m[k * n + k].norm() {
                for j in k..n {
                    m.swap(k * n + j, (k + 1) * n + j);
                }
                x.swap(k, k + 1);
            }
            let p = m[k * n + k];
            if p.norm() == 0.0 {
                continue;
            }
            let f = m[(k + 1) * n + k] / p;
            if f.norm() != 0.0 {
                for j in k..n {
                    let v = m[k * n + j];
                    m[(k + 1) * n + j] -= f * v;
                }
                let v = x[k];
                x[k + 1] -= f * v;
            }
        }
        for k in (0..n).rev() {
            let mut s = x[k];
            for j in k + 1..n {
                s -= m[k * n + j] * x[j];
            }
            x[k] = s / m[k * n + k];
        }
        (0..n).fold(Complex64::new(self.d, 0.0), |acc, k| acc + x[k] * self.c[k])
    }
}

/// The sampled loop of a controller on a model, every `dt` seconds.
pub struct SampledLoop {
    plant: Plant,
    c: Controller,
    ctrl: FastResponse,
    /// The model's held-input discretisation (`None` when it cannot be made: the loop is then
    /// the continuous model with the hold's half-sample delay, and `note` says so).
    model_d: Option<FastResponse>,
    dt: f64,
    /// Caveats of the evaluation.
    pub note: Option<String>,
}

impl SampledLoop {
    /// The loop of `c` (realised as [`crate::realise::discrete`] with `approx`) and `model`.
    ///
    /// # Errors
    /// Those of the controller's realisation.
    pub fn new(model: &FracTf, c: &Controller, dt: f64, approx: &ApproxSpec) -> Result<Self> {
        let ctrl = FastResponse::new(&crate::realise::discrete(c, dt, approx)?);
        let (model_d, note) = match export::discrete(model, dt, approx) {
            Ok(ss) => (Some(FastResponse::new(&ss)), None),
            Err(e) => (
                None,
                Some(format!(
                    "the model could not be discretised ({e}): the sampled loop uses its \
                     continuous response with the hold's half-sample delay"
                )),
            ),
        };
        Ok(Self {
            plant: Plant::new(model.clone(), Some(dt)),
            c: *c,
            ctrl,
            model_d,
            dt,
            note,
        })
    }

    /// Below this frequency the loop is the continuous one (module documentation).
    fn w_s(&self) -> f64 {
        0.01 / self.dt
    }

    /// `L` at `omega` rad/s (module documentation).
    pub fn at(&self, omega: f64) -> Complex64 {
        if omega < self.w_s() {
            return analysis::loop_response(&self.plant, &self.c, omega);
        }
        let p = match &self.model_d {
            Some(m) => m.at(omega),
            None => self.plant.freq_response(omega),
        };
        self.ctrl.at(omega) * p
    }

    /// The loop's frequencies: the continuous analysis's grid up to `pi/dt`, with the aliases
    /// of the model's narrow features that lie above it.
    fn grid(&self, wc: f64) -> Vec<f64> {
        let nyq = PI / self.dt;
        let mut g: Vec<f64> = analysis::loop_grid(&self.plant, &self.c, wc)
            .into_iter()
            .filter(|&w| w < nyq)
            .collect();
        let ws = 2.0 * PI / self.dt;
        for w in analysis::resonances(&self.plant, &self.c, wc) {
            if w > nyq {
                let a = (w - ws * (w / ws).round()).abs();
                if a > 0.0 && a < nyq {
                    g.push(a);
                }
            }
        }
        g.push(nyq);
        g.push(self.w_s());
        g.sort_by(f64::total_cmp);
        g.dedup();
        g
    }

    /// The sampled loop's metrics around the intended crossover `wc` (the phase slope by a
    /// central difference of `arg L` in `ln omega`).
    pub fn analyse(&self, wc_design: f64) -> LoopMetrics {
        let omega = self.grid(wc_design);
        let sw = analysis::sweep(&omega, |w| self.at(w));
        let h = 1e-4;
        let slope =
            |wc: f64| (self.at(wc * f64::exp(h)) / self.at(wc * f64::exp(-h))).arg() / (2.0 * h);
        let plant_unstable = analysis::plant_unstable(&self.plant, wc_design);
        let stability = match &plant_unstable {
            Ok(p) => match self.nyquist(&omega) {
                Ok(n) if n + i64::from(*p) >= 0 => (n + i64::from(*p), None),
                Ok(n) => (
                    -1,
                    Some(format!(
                        "the Nyquist count of the sampled loop is inconsistent ({n} with {p} \
                         unstable model poles)"
                    )),
                ),
                Err(e) => (-1, Some(e)),
            },
            Err(e) => (
                -1,
                Some(format!("the model's poles could not be counted: {e}")),
            ),
        };
        LoopMetrics::of_sweep(
            sw,
            |w| self.at(w),
            slope,
            stability,
            plant_unstable.map_or(-1, i64::from),
        )
    }

    /// `(n pi - 2 Delta) / (2 pi)` (module documentation): the encirclements, to which the
    /// model's unstable poles add.
    fn nyquist(&self, omega: &[f64]) -> std::result::Result<i64, String> {
        let one = Complex64::new(1.0, 0.0);
        let f = |w: f64| one + self.at(w);
        let n = self.plant.low_order() + if self.c.ki != 0.0 { self.c.lambda } else { 0.0 };
        let mut budget = 2_000_000usize;
        let mut delta = 0.0;
        let mut prev = (omega[0], f(omega[0]));
        for &w in &omega[1..] {
            let cur = (w, f(w));
            delta += turn(&f, prev, cur, &mut budget)?;
            prev = cur;
        }
        let z = (n * PI - 2.0 * delta) / (2.0 * PI);
        let r = z.round();
        if (z - r).abs() > 0.1 {
            return Err(format!(
                "the sampled loop's winding number {z:.3} is not an integer (a closed-loop pole \
                 on the unit circle)"
            ));
        }
        Ok(r as i64)
    }
}

/// The change of `arg f` from `a` to `b`, subdivided until each part turns less than 0.2 rad and
/// agrees with its halves.
fn turn(
    f: &impl Fn(f64) -> Complex64,
    a: (f64, Complex64),
    b: (f64, Complex64),
    budget: &mut usize,
) -> std::result::Result<f64, String> {
    if *budget == 0 {
        return Err("the sampled loop's Nyquist count took too many evaluations".into());
    }
    *budget -= 1;
    let m = (a.0 * b.0).sqrt();
    let fm = f(m);
    let whole = (b.1 / a.1).arg();
    let (d1, d2) = ((fm / a.1).arg(), (b.1 / fm).arg());
    let small = d1.abs() < 0.2 && d2.abs() < 0.2;
    if (small && (d1 + d2 - whole).abs() < 1e-9) || b.0 / a.0 - 1.0 < 1e-13 {
        if !small {
            return Err(format!(
                "1 + L passes through 0 near {m:.4e} rad/s: a closed-loop pole on the unit circle"
            ));
        }
        return Ok(d1 + d2);
    }
    Ok(turn(f, a, (m, fm), budget)? + turn(f, (m, fm), b, budget)?)
}
