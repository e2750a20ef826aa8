//! Export of a model's approximation as a state space `(A, B, C, D)`, continuous or discrete with
//! the exact zero-order hold, for control design in other tools (MATLAB's `ss`, scipy's
//! `StateSpace`/`dlti`, python-control's `StateSpace`).
//!
//! The fractional operators are approximated as [`ApproxSpec`] says (refined Oustaloup, `N = 8` by
//! default) and the model taken in pole-residue form, `G~(s) = d + sum_i r_i/(s - lambda_i)`
//! ([`crate::modal::pole_residue`], never multiplied out). Its realisation is real and
//! block-diagonal, one block per mode, each balanced so that its input and output gains have the
//! same size:
//!
//! - a real pole `lambda` with residue `r`: `a = lambda`, `b = k`, `c = r/k`, `k = sqrt(|r|)`;
//! - a complex pair `lambda = sigma + j w` with residue `r` (and their conjugates): the state is
//!   `z = x1 + j x2` with `z' = lambda z + k u`, `y = 2 Re((r/k) z)`, that is
//!   `A = [[sigma, -w], [w, sigma]]`, `B = [k, 0]'`, `C = [2 Re(r/k), -2 Im(r/k)]`,
//!   `k = sqrt(2 |r|)`;
//! - `D = d`.
//!
//! The discrete model (sample period `T`) is the exact equivalent for a held input, `u_k` acting on
//! `[t_k, t_(k+1))` and `y_k = C x_k + D u_k` the output at `t_k`: per mode `e^(lambda T)` and
//! `k T phi1(lambda T)`, `phi1(z) = (e^z - 1)/z` (the matrix exponential of `[[A, B], [0, 0]] T`
//! in modal coordinates, the same discretisation as [`crate::Simulator`], so the two agree to
//! rounding). An input delay `tau = m T + eps` (`0 <= eps < T`) is exact too (the modified
//! z-transform): each mode sees `beta0 u_(k-m) + beta1 u_(k-m-1)`, and the past inputs are extra
//! states, a delay line of `m` (or `m + 1` when `eps > 0`) states placed last, at most
//! [`MAX_DELAY_STATES`]. A model strictly proper before approximation whose approximation feeds
//! through (a relative order below 1: `K/(a s^0.3 + 1)`) feeds the input before the instant,
//! `u_(k-m-1)`, as [`crate::Simulator`] does ([`crate::modal::PoleResidue::strictly_proper`]):
//! one delay state more, and `D = 0`. A continuous model cannot hold `e^(-tau s)` in `(A, B, C, D)`: its delay
//! is given beside it ([`StateSpace::input_delay`]; MATLAB's `'InputDelay'`).
//!
//! ```
//! use fracsim::{export, ApproxSpec, FracTf};
//! let g: FracTf = "1/(0.1 s + 1)".parse().unwrap();
//! let ss = export::discrete(&g, 0.01, &ApproxSpec::default()).unwrap();
//! assert_eq!(ss.order(), 1);
//! // x_(k+1) = e^(-0.1) x_k + ..., and the DC gain C (1 - A)^-1 B + D = 1
//! assert!((ss.a[(0, 0)] - (-0.1f64).exp()).abs() < 1e-15);
//! let dc = ss.c[(0, 0)] * ss.b[(0, 0)] / (1.0 - ss.a[(0, 0)]) + ss.d;
//! assert!((dc - 1.0).abs() < 1e-12);
//! ```

use crate::approx::{ApproxSpec, Method};
use crate::cx::Cx;
use crate::error::{finite, invalid, Result};
use crate::modal::{pole_residue, PoleResidue};
use crate::tf::FracTf;
use nalgebra::DMatrix;

/// The most delay-line states a discrete export adds for an input delay (whole samples).
pub const MAX_DELAY_STATES: usize = 1000;

/// A single-input single-output state space `x' = A x + B u`, `y = C x + D u` (continuous), or
/// `x_(k+1) = A x_k + B u_k`, `y_k = C x_k + D u_k` (discrete, sample period [`StateSpace::dt`]).
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpace {
    /// `A`, `n x n`.
    pub a: DMatrix<f64>,
    /// `B`, `n x 1`.
    pub b: DMatrix<f64>,
    /// `C`, `1 x n`.
    pub c: DMatrix<f64>,
    /// `D`, the feed-through.
    pub d: f64,
    /// The sample period in seconds (`None`: continuous).
    pub dt: Option<f64>,
    /// The input delay in seconds that the matrices do not hold: a continuous model's
    /// `e^(-tau s)`; 0 for a discrete model (its delay is in the delay-line states).
    pub input_delay: f64,
    /// How many of the last states are the input delay line (discrete only).
    pub delay_states: usize,
    /// The approximation band `[w_b, w_h]` in rad/s.
    pub band: (f64, f64),
    /// The approximation.
    pub spec: ApproxSpec,
}

/// One mode of the block-diagonal realisation: its state indices are `start..start + dim`.
struct Block {
    start: usize,
    /// Real pole and residue, or a complex pole (positive imaginary part) and its residue.
    lam: Cx<f64>,
    r: Cx<f64>,
    complex: bool,
}

fn blocks(pr: &PoleResidue<f64>) -> (Vec<Block>, usize) {
    let mut out = Vec::with_capacity(pr.real.len() + pr.complex.len());
    let mut n = 0;
    for &(lam, r) in &pr.real {
        out.push(Block {
            start: n,
            lam: Cx::real(lam),
            r: Cx::real(r),
            complex: false,
        });
        n += 1;
    }
    for &(lam, r) in &pr.complex {
        out.push(Block {
            start: n,
            lam,
            r,
            complex: true,
        });
        n += 2;
    }
    (out, n)
}

impl Block {
    /// The input gain `k` that balances the block (1 for a zero residue).
    fn k(&self) -> f64 {
        let m = if self.complex { 2.0 } else { 1.0 } * self.r.val().norm();
        if m > 0.0 {
            m.sqrt()
        } else {
            1.0
        }
    }

    /// Write `C` for this block.
    fn write_c(&self, c: &mut DMatrix<f64>) {
        let ck = self.r.scale(1.0 / self.k());
        if self.complex {
            c[(0, self.start)] = 2.0 * ck.re;
            c[(0, self.start + 1)] = -2.0 * ck.im;
        } else {
            c[(0, self.start)] = ck.re;
        }
    }

    /// Write the dynamics `z -> e z` (continuous: `lambda`; discrete: `e^(lambda T)`).
    fn write_a(&self, a: &mut DMatrix<f64>, e: Cx<f64>) {
        let i = self.start;
        if self.complex {
            a[(i, i)] = e.re;
            a[(i, i + 1)] = -e.im;
            a[(i + 1, i)] = e.im;
            a[(i + 1, i + 1)] = e.re;
        } else {
            a[(i, i)] = e.re;
        }
    }

    /// Write the input column `g` (complex `z`-coordinates) into column `col` of `m`.
    fn write_in(&self, m: &mut DMatrix<f64>, col: usize, g: Cx<f64>) {
        m[(self.start, col)] = g.re;
        if self.complex {
            m[(self.start + 1, col)] = g.im;
        }
    }
}

/// The pole-residue form of `tf` (its delay left aside) over `band`.
fn modal(tf: &FracTf, band: (f64, f64), spec: &ApproxSpec) -> Result<PoleResidue<f64>> {
    let pairs =
        |t: &[crate::Term]| -> Vec<(f64, f64)> { t.iter().map(|t| (t.coef, t.order)).collect() };
    let whole = pole_residue(&pairs(&tf.num), &pairs(&tf.den), band, spec);
    // A product whose multiplied-out form fails: factor by factor (as `Simulator::new`).
    match (whole, tf.factors()) {
        (Err(e), fs) if !fs.is_empty() => {
            let mut out: Option<PoleResidue<f64>> = None;
            for f in fs {
                let m = pole_residue(&pairs(&f.num), &pairs(&f.den), band, spec)
                    .map_err(|_| e.clone())?;
                out = Some(match out {
                    None => m,
                    Some(o) => o.product(&m).map_err(|_| e.clone())?,
                });
            }
            out.ok_or(e)
        }
        (r, _) => r,
    }
}

/// The continuous state space of `tf`'s approximation over `band` (rad/s); its delay is carried
/// in [`StateSpace::input_delay`].
///
/// # Errors
/// A bad band ([`crate::Error::Band`]) and the errors of [`crate::modal::pole_residue`]
/// (improper model, repeated poles...).
pub fn continuous(tf: &FracTf, band: (f64, f64), spec: &ApproxSpec) -> Result<StateSpace> {
    crate::approx::check_band(band.0, band.1)?;
    let pr = modal(tf, band, spec)?;
    let (blocks, n) = blocks(&pr);
    let mut ss = StateSpace {
        a: DMatrix::zeros(n, n),
        b: DMatrix::zeros(n, 1),
        c: DMatrix::zeros(1, n),
        d: pr.direct,
        dt: None,
        input_delay: tf.delay,
        delay_states: 0,
        band,
        spec: *spec,
    };
    for bl in &blocks {
        bl.write_a(&mut ss.a, bl.lam);
        bl.write_in(&mut ss.b, 0, Cx::real(bl.k()));
        bl.write_c(&mut ss.c);
    }
    Ok(ss)
}

/// The discrete state space of `tf`'s approximation, exact for an input held over each period
/// `dt` (seconds), over `spec.band_for(dt)` (the band [`crate::Simulator`] uses), its delay as
/// extra states (see the module documentation).
///
/// # Errors
/// A bad step or band, a negative delay or one that needs more than [`MAX_DELAY_STATES`]
/// states, and the errors of [`crate::modal::pole_residue`].
pub fn discrete(tf: &FracTf, dt: f64, spec: &ApproxSpec) -> Result<StateSpace> {
    let band = spec.band_for(dt)?;
    let tau = finite("delay", tf.delay)?;
    if tau < 0.0 {
        return invalid("delay", format!("{tau} s is negative"));
    }
    let samples = tau / dt;
    if samples >= MAX_DELAY_STATES as f64 {
        return invalid(
            "delay",
            format!(
                "{tau} s is {samples:.0} samples: a discrete export holds at most \
                 {MAX_DELAY_STATES} delay states"
            ),
        );
    }
    let pr = modal(tf, band, spec)?;
    let m = samples.floor() as usize;
    let eps = tau - m as f64 * dt;
    let frac = eps > 0.0;
    // The feed-through of a strictly proper model sees the input before the instant (as
    // `Simulator`'s): one sample further back.
    let prev = frac || (pr.strictly_proper && pr.direct != 0.0);
    let (blocks, n_modes) = blocks(&pr);
    let n_delay = m + usize::from(prev);
    let n = n_modes + n_delay;
    let mut ss = StateSpace {
        a: DMatrix::zeros(n, n),
        b: DMatrix::zeros(n, 1),
        c: DMatrix::zeros(1, n),
        d: 0.0,
        dt: Some(dt),
        input_delay: 0.0,
        delay_states: n_delay,
        band,
        spec: *spec,
    };
    // The delay line: state n_modes + j - 1 holds u_(k-j), j = 1..n_delay.
    let w = |j: usize| n_modes + j - 1;
    if n_delay > 0 {
        ss.b[(w(1), 0)] = 1.0;
        for j in 1..n_delay {
            ss.a[(w(j + 1), w(j))] = 1.0;
        }
    }
    let rest = dt - eps;
    for bl in &blocks {
        let k = bl.k();
        bl.write_a(&mut ss.a, bl.lam.scale(dt).exp());
        bl.write_c(&mut ss.c);
        // beta0 acts on u_(k-m), beta1 on u_(k-m-1) (the modified z-transform).
        let beta0 = bl.lam.scale(rest).phi1().scale(rest * k);
        if m == 0 {
            bl.write_in(&mut ss.b, 0, beta0);
        } else {
            bl.write_in(&mut ss.a, w(m), beta0);
        }
        if frac {
            let beta1 = bl.lam.scale(rest).exp() * bl.lam.scale(eps).phi1().scale(eps * k);
            bl.write_in(&mut ss.a, w(m + 1), beta1);
        }
    }
    // The feed-through sees u(t_k - tau): u_(k-m-1) when eps > 0 or the model is strictly
    // proper (the input before the instant), else u_(k-m).
    match (prev, m) {
        (true, _) => ss.c[(0, w(m + 1))] = pr.direct,
        (false, 0) => ss.d = pr.direct,
        (false, _) => ss.c[(0, w(m))] = pr.direct,
    }
    Ok(ss)
}

/// The approximation's name as the CLI and Python spell it.
pub fn method_name(m: Method) -> &'static str {
    m.name()
}

impl StateSpace {
    /// The number of states.
    pub fn order(&self) -> usize {
        self.a.nrows()
    }

    /// The rows of `A` (for writers).
    pub fn a_rows(&self) -> Vec<Vec<f64>> {
        rows(&self.a)
    }

    /// `B` as a column (one value per state).
    pub fn b_col(&self) -> Vec<f64> {
        self.b.column(0).iter().copied().collect()
    }

    /// `C` as a row (one value per state).
    pub fn c_row(&self) -> Vec<f64> {
        self.c.row(0).iter().copied().collect()
    }

    /// A MATLAB script that builds this model as `sys = ss(A, B, C, D)` (with `'InputDelay'` for
    /// a continuous model's delay) or `sys = ss(A, B, C, D, T)`, and `G = tf(sys)`. `model` is
    /// written in the header comment (the model the approximation stands for). Numbers are
    /// written in the shortest form that reads back to the same `f64`.
    ///
    /// ```
    /// use fracsim::{export, ApproxSpec, FracTf};
    /// let g: FracTf = "2/(0.5 s + 1)".parse().unwrap();
    /// let m = export::continuous(&g, (1e-2, 1e3), &ApproxSpec::default()).unwrap()
    ///     .to_matlab("2/(0.5 s + 1)");
    /// assert!(m.contains("A = [-2e0];") && m.contains("sys = ss(A, B, C, D);"));
    /// ```
    pub fn to_matlab(&self, model: &str) -> String {
        let mut s = String::new();
        let model = model.replace(['\n', '\r'], " ");
        s.push_str(&format!("% fracid export of {model}\n"));
        s.push_str(&format!(
            "% approximation: {} N = {} over [{:e}, {:e}] rad/s; {} states; real block-diagonal \
             (modal) realisation\n",
            method_name(self.spec.method),
            self.spec.order,
            self.band.0,
            self.band.1,
            self.order()
        ));
        match self.dt {
            Some(dt) => {
                s.push_str(&format!(
                    "% discrete, exact zero-order hold, T = {dt:e} s: u(k) held over [kT, (k+1)T), \
                     y(k) the output at kT\n"
                ));
                if self.delay_states > 0 {
                    s.push_str(&format!(
                        "% the last {} states are the input delay line\n",
                        self.delay_states
                    ));
                }
            }
            None => s.push_str("% continuous\n"),
        }
        s.push_str(&format!("A = {};\n", matlab_matrix(&self.a)));
        s.push_str(&format!("B = {};\n", matlab_matrix(&self.b)));
        s.push_str(&format!("C = {};\n", matlab_matrix(&self.c)));
        s.push_str(&format!("D = {:e};\n", self.d));
        match self.dt {
            Some(dt) => {
                s.push_str(&format!("T = {dt:e};\n"));
                s.push_str("sys = ss(A, B, C, D, T);\n");
            }
            None if self.input_delay > 0.0 => {
                s.push_str(&format!("tau = {:e};\n", self.input_delay));
                s.push_str("sys = ss(A, B, C, D, 'InputDelay', tau);\n");
            }
            None => s.push_str("sys = ss(A, B, C, D);\n"),
        }
        s.push_str(
            "% the transfer function: its polynomials are ill-conditioned at high order, \
             prefer sys for design\n",
        );
        s.push_str("G = tf(sys);\n");
        s
    }
}

fn rows(m: &DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

fn matlab_matrix(m: &DMatrix<f64>) -> String {
    if m.nrows() == 0 || m.ncols() == 0 {
        return format!("zeros({}, {})", m.nrows(), m.ncols());
    }
    let body: Vec<String> = m
        .row_iter()
        .map(|r| {
            r.iter()
                .map(|v| format!("{v:e}"))
                .collect::<Vec<_>>()
                .join(", ")
        })
        .collect();
    if body.len() == 1 {
        format!("[{}]", body[0])
    } else {
        format!("[\n  {}\n]", body.join(";\n  "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Simulator;
    use nalgebra::DVector;
    use num_complex::Complex64;

    const PMSM: &str = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)";

    /// `C (s I - A)^-1 B + D` by a complex LU solve, independent of the modal form.
    fn ss_response(ss: &StateSpace, omega: f64) -> Complex64 {
        let n = ss.order();
        let s = Complex64::new(0.0, omega);
        let m = DMatrix::<Complex64>::from_fn(n, n, |i, j| {
            let a = Complex64::new(-ss.a[(i, j)], 0.0);
            if i == j {
                a + s
            } else {
                a
            }
        });
        let b = DVector::<Complex64>::from_fn(n, |i, _| Complex64::new(ss.b[(i, 0)], 0.0));
        let x = m.lu().solve(&b).expect("s I - A is regular off its poles");
        let mut y = Complex64::new(ss.d, 0.0);
        for i in 0..n {
            y += ss.c[(0, i)] * x[i];
        }
        y
    }

    /// The step response of a discrete state space by its own recursion.
    fn ss_step(ss: &StateSpace, u: &[f64]) -> Vec<f64> {
        let mut x = DVector::<f64>::zeros(ss.order());
        let mut y = Vec::with_capacity(u.len());
        for &uk in u {
            y.push((&ss.c * &x)[(0, 0)] + ss.d * uk);
            x = &ss.a * &x + &ss.b * uk;
        }
        y
    }

    fn max_rel(a: &[f64], b: &[f64]) -> f64 {
        let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        a.iter()
            .zip(b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs() / scale))
    }

    /// The continuous state space's frequency response, by a linear solve, equals the
    /// approximation's (each operator's rational cells evaluated directly at `j omega`).
    #[test]
    fn continuous_response_equals_the_approximation() {
        for (model, spec) in [
            (PMSM, ApproxSpec::default()),
            (
                "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)",
                ApproxSpec {
                    method: Method::Oustaloup,
                    order: 5,
                    band: None,
                },
            ),
            (
                "(0.3 s^0.5 + 2)/(0.01 s^1.3 + 0.2 s^0.6 + 1)",
                ApproxSpec::default(),
            ),
            ("1/(s (0.01 s^0.8 + 1))", ApproxSpec::default()),
        ] {
            let g: FracTf = model.parse().unwrap();
            let band = (1e-3, 1e5);
            let ss = continuous(&g, band, &spec).unwrap();
            let approx = |w: f64| {
                let op = |t: &crate::Term| {
                    let r = crate::approx::approximate(t.order, band, &spec).unwrap();
                    r.freq_response(w) * t.coef
                };
                let n: Complex64 = g.num.iter().map(op).sum();
                let d: Complex64 = g.den.iter().map(op).sum();
                n / d
            };
            for k in 0..=40 {
                let w = 10f64.powf(-2.0 + 7.0 * k as f64 / 40.0);
                let (h, want) = (ss_response(&ss, w), approx(w));
                assert!(
                    (h - want).norm() <= 1e-9 * want.norm(),
                    "{model} at {w} rad/s: {h} vs {want}"
                );
            }
        }
    }

    /// The discrete state space's step response equals the Simulator's, and its matrices equal
    /// the matrix exponential of `[[A, B], [0, 0]] T` of the continuous one (nalgebra's `exp`).
    #[test]
    fn discrete_equals_the_simulator_and_the_matrix_exponential() {
        let dt = 1e-4;
        let spec = ApproxSpec::default();
        for model in [
            PMSM,
            "1/(s (0.01 s^0.8 + 1))",
            "(0.3 s^0.5 + 2)/(0.01 s^1.3 + 1)",
        ] {
            let g: FracTf = model.parse().unwrap();
            let ss = discrete(&g, dt, &spec).unwrap();
            let u = vec![1.0; 500];
            let mut sim = Simulator::<f64>::new(&g, dt, &spec).unwrap();
            let want = sim.simulate(&u);
            let got = ss_step(&ss, &u);
            assert!(
                max_rel(&got, &want) < 1e-9,
                "{model}: {}",
                max_rel(&got, &want)
            );

            let c = continuous(&g, spec.band_for(dt).unwrap(), &spec).unwrap();
            let n = c.order();
            let mut aug = DMatrix::<f64>::zeros(n + 1, n + 1);
            aug.view_mut((0, 0), (n, n)).copy_from(&(&c.a * dt));
            aug.view_mut((0, n), (n, 1)).copy_from(&(&c.b * dt));
            let e = aug.exp();
            let (ad, bd) = (e.view((0, 0), (n, n)), e.view((0, n), (n, 1)));
            let tol = |m: f64| 1e-9 * m.max(1.0);
            assert!((ad - &ss.a).amax() < tol(ss.a.amax()), "{model}: A");
            assert!((bd - &ss.b).amax() < tol(ss.b.amax()), "{model}: B");
            assert_eq!(c.c, ss.c);
        }
    }

    /// Delays: whole and fractional samples as extra states, the same output as the Simulator.
    #[test]
    fn discrete_delays_are_exact() {
        let dt = 1e-3;
        let spec = ApproxSpec::default();
        let u: Vec<f64> = (0..400).map(|k| ((k * 7919) % 13) as f64 - 6.0).collect();
        for (model, states) in [
            // Strictly proper with a feed-through: the input before the instant, one more.
            ("6.77/(0.0064 s^0.89 + 1)", 1),
            ("6.77/(0.0064 s^0.89 + 1) exp(-0.003 s)", 4),
            ("6.77/(0.0064 s^0.89 + 1) exp(-0.0034 s)", 4),
            ("6.77/(0.0064 s^0.89 + 1) exp(-0.0004 s)", 1),
            ("(2 s^0.5 + 1)/(0.0064 s^0.5 + 1) exp(-0.0025 s)", 3),
        ] {
            let g: FracTf = model.parse().unwrap();
            let ss = discrete(&g, dt, &spec).unwrap();
            assert_eq!(ss.delay_states, states, "{model}");
            let want = Simulator::<f64>::new(&g, dt, &spec).unwrap().simulate(&u);
            let got = ss_step(&ss, &u);
            assert!(
                max_rel(&got, &want) < 1e-9,
                "{model}: {}",
                max_rel(&got, &want)
            );
        }
        let far: FracTf = "1/(s + 1) exp(-2 s)".parse().unwrap();
        assert!(discrete(&far, dt, &spec).is_err());
    }

    #[test]
    fn continuous_keeps_the_delay_beside_the_matrices() {
        let g: FracTf = "1/(0.1 s + 1) exp(-0.02 s)".parse().unwrap();
        let ss = continuous(&g, (1e-2, 1e4), &ApproxSpec::default()).unwrap();
        assert_eq!(ss.input_delay, 0.02);
        assert!(ss.to_matlab("x").contains("'InputDelay', tau"));
        assert!(continuous(&g, (1.0, 0.5), &ApproxSpec::default()).is_err());
    }

    #[test]
    fn matlab_script_reads_back_the_same_numbers() {
        let g: FracTf = PMSM.parse().unwrap();
        let ss = discrete(&g, 1e-4, &ApproxSpec::default()).unwrap();
        let m = ss.to_matlab(PMSM);
        let a_text = m.split("A = [").nth(1).unwrap().split("];").next().unwrap();
        let vals: Vec<f64> = a_text
            .split([',', ';', '\n'])
            .map(str::trim)
            .filter(|t| !t.is_empty())
            .map(|t| t.parse().unwrap())
            .collect();
        assert_eq!(vals.len(), ss.order() * ss.order());
        let want: Vec<f64> = ss.a_rows().concat();
        assert_eq!(vals, want);
        assert!(m.contains("sys = ss(A, B, C, D, T);") && m.contains("T = 1e-4;"));
    }
}
