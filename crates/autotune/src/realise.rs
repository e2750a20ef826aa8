//! The controller as the drive runs it: the discrete realisation of a `fracid tune` design
//! (`discrete`: `A, B, C, D` at `dt`) turned into the drive's fixed-point parallel first-order
//! sections and delay taps ([`drive::ctrl::FixedCtrl`]), and the figures of a measured step.

use crate::{Error, Result};
use drive::client::{Acquisition, Client, RunInfo, SampleSink};
use drive::ctrl::{FixedCtrl, MAX_REALISATION_STATES};
use drive::protocol::{Configure, StartLoop, MAX_SECTIONS_TAPS, MAX_TAPS};
use num_complex::Complex64;
use serde_json::Value;
use tune::report::DiscreteJson;

/// A discrete controller realisation read from a `fracid tune --json` report.
#[derive(Debug, Clone, PartialEq)]
pub struct Realisation {
    /// Sample period, s.
    pub dt: f64,
    /// `A`, by rows.
    pub a: Vec<Vec<f64>>,
    /// `B`, a column.
    pub b: Vec<f64>,
    /// `C`, a row.
    pub c: Vec<f64>,
    /// `D`.
    pub d: f64,
    /// The continuous controller as text (for messages).
    pub text: String,
}

fn bad(msg: String) -> Error {
    Error::InvalidParam(msg)
}

/// The discrete realisation of a `fracid tune --json` report.
///
/// # Errors
/// Not JSON, no `discrete` realisation (a design without `--dt`), more states than
/// [`MAX_REALISATION_STATES`] (refused before its numbers are read), matrices of the wrong shape
/// or with non-numbers (all bad input, exit 2).
pub fn parse_realisation(text: &str) -> Result<Realisation> {
    let v: Value = serde_json::from_str(text)
        .map_err(|e| bad(format!("not the JSON of `fracid tune --json`: {e}")))?;
    let d = v.get("discrete").filter(|d| !d.is_null()).ok_or_else(|| {
        bad("no discrete realisation (\"discrete\"): design with `fracid tune ... --dt DT --json`, DT the drive's sample period".into())
    })?;
    let num = |x: &Value, what: &str| -> Result<f64> {
        x.as_f64()
            .filter(|v| v.is_finite())
            .ok_or_else(|| bad(format!("discrete.{what}: {x} is not a finite number")))
    };
    let matrix = |name: &str| -> Result<Vec<Vec<f64>>> {
        let rows = d
            .get(name)
            .and_then(Value::as_array)
            .ok_or_else(|| bad(format!("discrete.{name} missing or not an array of rows")))?;
        rows.iter()
            .map(|r| {
                r.as_array()
                    .ok_or_else(|| bad(format!("discrete.{name}: a row is not an array")))?
                    .iter()
                    .map(|x| num(x, name))
                    .collect()
            })
            .collect()
    };
    let dt = num(d.get("dt").unwrap_or(&Value::Null), "dt")?;
    // the size first: the pruning and the conversion grow with its cube
    let n_states = d.get("a").and_then(Value::as_array).map_or(0, Vec::len);
    if n_states > MAX_REALISATION_STATES {
        return Err(bad(format!(
            "the controller has {n_states} states; the drive holds at most {MAX_SECTIONS_TAPS} \
             sections and {MAX_TAPS} delay taps (realisations of up to {MAX_REALISATION_STATES} \
             states are converted): design it with a lower approximation order"
        )));
    }
    let a = matrix("a")?;
    let b: Vec<f64> = matrix("b")?.into_iter().flatten().collect();
    let c: Vec<f64> = matrix("c")?.into_iter().flatten().collect();
    let dm: Vec<f64> = matrix("d")?.into_iter().flatten().collect();
    let n = a.len();
    if !(dt > 0.0)
        || b.len() != n
        || c.len() != n
        || dm.len() != 1
        || a.iter().any(|r| r.len() != n)
    {
        return Err(bad(format!(
            "discrete realisation of inconsistent shape: A {n} rows, B {}, C {}, D {} entries, dt {dt}",
            b.len(),
            c.len(),
            dm.len()
        )));
    }
    let text = v
        .get("controller")
        .and_then(|c| c.get("text"))
        .and_then(Value::as_str)
        .unwrap_or("?")
        .to_string();
    Ok(Realisation {
        dt,
        a,
        b,
        c,
        d: dm[0],
        text,
    })
}

impl Realisation {
    /// The realisation of a tuner's report (`discrete`), the controller's text for messages.
    pub fn of_discrete(d: &DiscreteJson, text: &str) -> Self {
        Self {
            dt: d.dt(),
            a: d.ss.a.clone(),
            b: d.ss.b.iter().flatten().copied().collect(),
            c: d.ss.c.iter().flatten().copied().collect(),
            d: d.ss
                .d
                .first()
                .and_then(|r| r.first())
                .copied()
                .unwrap_or(0.0),
            text: text.to_string(),
        }
    }
}

/// The states' responses `X(e^(j w dt))` to the error, and the output `C X + D`, of a
/// lower-triangular realisation (forward substitution); `None` if `A` is not lower triangular.
fn responses(r: &Realisation, w: f64) -> Option<(Vec<Complex64>, Complex64)> {
    let z = Complex64::from_polar(1.0, w * r.dt);
    let n = r.a.len();
    if (0..n).any(|i| (i + 1..n).any(|j| r.a[i][j] != 0.0)) {
        return None;
    }
    let mut x = vec![Complex64::new(0.0, 0.0); n];
    for i in 0..n {
        let s: Complex64 = (0..i).map(|j| x[j] * r.a[i][j]).sum();
        x[i] = (s + r.b[i]) / (z - r.a[i][i]);
    }
    let out = x.iter().zip(&r.c).map(|(x, c)| x * c).sum::<Complex64>() + r.d;
    Some((x, out))
}

/// The frequencies the loop runs at and the checks use: 1 rad/s to half Nyquist, 20 a decade.
fn loop_band(dt: f64) -> Vec<f64> {
    let top = 0.5 * std::f64::consts::PI / dt;
    (0..)
        .map(|i| 10f64.powf(i as f64 / 20.0))
        .take_while(|&w| w <= top)
        .collect()
}

/// Relative share below which a state that feeds no other is left out of the drive's
/// controller ([`prune`]).
pub const PRUNE_TOL: f64 = 1e-4;

/// Leave out the states that feed no other state and whose share of the output, `|c_i X_i|`, is
/// below [`PRUNE_TOL`] of `|C|` at every frequency of `loop_band` (1 rad/s to half Nyquist):
/// the approximation's double integrator below its band (`1/s^lambda` with `lambda > 1`
/// approximated with a zero at the origin gives `c1/s + c2/s^2`, `c2/c1` about 4e-6 rad/s for the
/// FOPI of wc = 50 rad/s, a share of 5e-5 at 1 rad/s), which the drive's first-order sections cannot hold (a repeated pole)
/// and no loop run of seconds can see. Returns the pruned realisation and the states left out.
pub fn prune(r: &Realisation) -> (Realisation, Vec<usize>) {
    let mut out = r.clone();
    let mut dropped = Vec::new();
    let band = loop_band(r.dt);
    let mut i = 0;
    while i < out.a.len() {
        let n = out.a.len();
        let leaf = (0..n).all(|j| j == i || out.a[j][i] == 0.0);
        let small = leaf
            && out.c[i] != 0.0
            && band.iter().all(|&w| match responses(&out, w) {
                Some((x, c)) => (x[i] * out.c[i]).norm() < PRUNE_TOL * c.norm(),
                None => false,
            });
        if small {
            out.a.remove(i);
            for row in &mut out.a {
                row.remove(i);
            }
            out.b.remove(i);
            out.c.remove(i);
            dropped.push(i + dropped.len());
        } else {
            i += 1;
        }
    }
    (out, dropped)
}

/// The drive's fixed-point controller of `r` for the configuration `conf` (its rate must be
/// `1/dt`, its channel scales set the raw gains).
///
/// # Errors
/// A sample rate other than `1/dt`; a realisation the drive cannot run (not triangular, coupled
/// repeated slow poles, gains beyond Q24, too many sections or delay taps): bad input, exit 2.
pub fn fixed_controller(r: &Realisation, conf: &Configure) -> Result<FixedCtrl> {
    let fs = conf.sample_rate_hz as f64;
    if (r.dt * fs - 1.0).abs() > 1e-6 {
        return Err(bad(format!(
            "the controller is realised for dt = {} s ({} Hz); the drive samples at {fs} Hz: \
             pass --sample-rate {} or design with --dt {}",
            r.dt,
            1.0 / r.dt,
            (1.0 / r.dt).round(),
            1.0 / fs
        )));
    }
    let b = r.b.clone();
    Ok(FixedCtrl::from_state_space(
        &r.a,
        &b,
        &r.c,
        r.d,
        conf.y_lsb() / conf.u_lsb(),
    )?)
}

/// The largest relative deviation of the fixed-point controller's frequency response from the
/// realisation's (`r`, before [`prune`]) over `loop_band`: what pruning and quantisation do.
pub fn quantisation_error(r: &Realisation, k: &FixedCtrl, conf: &Configure) -> f64 {
    let gain_raw = conf.y_lsb() / conf.u_lsb();
    loop_band(r.dt)
        .into_iter()
        .filter_map(|w| {
            let (_, e) = responses(r, w)?;
            Some((k.freq_response(w, r.dt, gain_raw) - e).norm() / e.norm())
        })
        .fold(0.0, f64::max)
}

/// Download `k` and run the loop `cmd` into `sink`.
///
/// # Errors
/// Those of [`Client::load_controller`] and [`Client::run_loop`].
pub fn run_on(
    client: &mut Client,
    k: &FixedCtrl,
    cmd: &StartLoop,
    sink: &mut dyn SampleSink,
) -> Result<Acquisition> {
    client.load_controller(k)?;
    Ok(client.run_loop(cmd, sink)?)
}

/// The measured step of a loop run.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredStep {
    /// Time from the step, s.
    pub t: Vec<f64>,
    /// Speed, rad/s.
    pub y: Vec<f64>,
    /// Overshoot, percent of the step.
    pub overshoot_percent: f64,
    /// 10-90% rise time, s (`None`: not reached).
    pub rise_time: Option<f64>,
    /// 2% settling time, s (`None`: not within the record).
    pub settling_time: Option<f64>,
}

/// The measured step of a loop run and its figures ([`tune::closed::step_figures`]) against the
/// reference `cmd.r1` (rad/s with `y_lsb`). `None` without samples after the step.
pub fn measured_step(acq: &Acquisition, cmd: &StartLoop, y_lsb: f64) -> Option<MeasuredStep> {
    let first = acq.index.partition_point(|&i| i < cmd.pre_samples as u64);
    if first >= acq.index.len() {
        return None;
    }
    let t0 = cmd.pre_samples as f64 / acq.sample_rate_hz as f64;
    let t: Vec<f64> = acq.t[first..].iter().map(|t| t - t0).collect();
    let y = acq.y[first..].to_vec();
    let (overshoot_percent, rise_time, settling_time) =
        tune::closed::step_figures(&t, &y, cmd.r1 as f64 * y_lsb);
    Some(MeasuredStep {
        t,
        y,
        overshoot_percent,
        rise_time,
        settling_time,
    })
}

/// The figures of the measured step ([`tune::closed::step_figures`]: overshoot, 10-90% rise,
/// 2% settling), computed as the samples arrive, so a long run needs no memory for them: the
/// same numbers as `step_figures` on the whole step (tested).
#[derive(Debug, Clone, Copy)]
pub struct StepFigures {
    /// The step, rad/s.
    a: f64,
    /// Time of the first sample of the step, s (the origin of the step's time).
    t_first: Option<f64>,
    /// The previous sample `(t, y)` of the step.
    prev: Option<(f64, f64)>,
    /// Times at which 10% and 90% of the step were first reached.
    at10: Option<f64>,
    at90: Option<f64>,
    peak: f64,
    /// `Some` once a sample was out of the 2% band: the time (from the step's start) of the
    /// sample after the last one out, if one came.
    settle: Option<Option<f64>>,
}

impl StepFigures {
    /// For a step of `a` rad/s.
    pub fn new(a: f64) -> Self {
        Self {
            a,
            t_first: None,
            prev: None,
            at10: None,
            at90: None,
            peak: f64::NEG_INFINITY,
            settle: None,
        }
    }

    /// The next sample of the step: time from the step (s), speed (rad/s).
    pub fn push(&mut self, t: f64, y: f64) {
        let a = self.a;
        let t0 = *self.t_first.get_or_insert(t);
        let cross = |frac: f64, at: &mut Option<f64>, prev: Option<(f64, f64)>| {
            if at.is_none() && y >= frac * a {
                *at = Some(match prev {
                    None => t,
                    // linear interpolation between the samples around the level
                    Some((t_p, y_p)) => t_p + (t - t_p) * (frac * a - y_p) / (y - y_p),
                });
            }
        };
        cross(0.1, &mut self.at10, self.prev);
        cross(0.9, &mut self.at90, self.prev);
        self.peak = self.peak.max(y);
        if (y - a).abs() > 0.02 * a.abs() {
            self.settle = Some(None);
        } else if self.settle == Some(None) {
            self.settle = Some(Some(t - t0));
        }
        self.prev = Some((t, y));
    }

    /// `(overshoot %, rise time, settling time)` as [`tune::closed::step_figures`] gives them;
    /// `None` without samples.
    pub fn figures(&self) -> Option<(f64, Option<f64>, Option<f64>)> {
        self.t_first?;
        let rise = match (self.at10, self.at90) {
            (Some(a), Some(b)) => Some(b - a),
            _ => None,
        };
        let overshoot = (100.0 * (self.peak - self.a) / self.a).max(0.0);
        Some((overshoot, rise, self.settle.flatten()))
    }
}

/// A loop run's sink that takes the step's figures as the samples arrive ([`StepFigures`]) and
/// passes every sample on to `inner` (the record's file, [`drive::client::LoopCsvSink`], or nothing).
pub struct StepSink<S: SampleSink> {
    inner: S,
    step: StepFigures,
    /// The step's first sample and its time, s.
    pre_samples: u64,
    t0: f64,
}

impl<S: SampleSink> StepSink<S> {
    /// For the run of `cmd`, every sample passed to `inner`, speeds scaled by `y_lsb` (rad/s per
    /// LSB), at `sample_rate_hz`.
    pub fn new(inner: S, cmd: StartLoop, y_lsb: f64, sample_rate_hz: u32) -> Self {
        Self {
            inner,
            step: StepFigures::new(cmd.r1 as f64 * y_lsb),
            pre_samples: cmd.pre_samples as u64,
            t0: cmd.pre_samples as f64 / sample_rate_hz as f64,
        }
    }

    /// The inner sink and the step's figures.
    pub fn into_inner(self) -> (S, StepFigures) {
        (self.inner, self.step)
    }
}

impl<S: SampleSink> SampleSink for StepSink<S> {
    fn begin(&mut self, info: &RunInfo) -> std::io::Result<()> {
        self.inner.begin(info)
    }
    fn sample(&mut self, index: u64, t: f64, u: f64, y: f64, i: f64) -> std::io::Result<()> {
        if index >= self.pre_samples {
            self.step.push(t - self.t0, y);
        }
        self.inner.sample(index, t, u, y, i)
    }
    fn finish(&mut self, acq: &Acquisition) -> std::io::Result<()> {
        self.inner.finish(acq)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The figures taken as the samples arrive are those of `tune::closed::step_figures` on the
    /// whole step, bit for bit: steps that overshoot or not, settle or not, start above the
    /// levels, stay in the band throughout, or end out of it.
    #[test]
    fn streamed_step_figures_equal_step_figures() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut cases: Vec<(Vec<f64>, f64)> = vec![
            (vec![], 1.0),
            (vec![1.0; 10], 1.0),
            (vec![2.0, 1.0, 1.0], 1.0),
            (vec![0.0, 0.5, 1.3, 0.99, 1.0, 1.5], 1.0),
            (vec![0.0, -0.5, -1.2, -1.0], -1.0),
        ];
        for k in 0..200 {
            let n = 1 + (rnd() * 400.0) as usize;
            let (wn, zeta) = (5.0 + 50.0 * rnd(), 0.1 + rnd());
            let a = 10.0 + 90.0 * rnd();
            let noise = if k % 2 == 0 { 0.0 } else { 0.05 * a };
            let y: Vec<f64> = (0..n)
                .map(|i| {
                    let t = i as f64 * 1e-3;
                    let wd = wn * (1.0 - zeta * zeta).abs().sqrt();
                    a * (1.0 - (-zeta * wn * t).exp() * (wd * t).cos()) + noise * (rnd() - 0.5)
                })
                .collect();
            cases.push((y, a));
        }
        for (y, a) in cases {
            let t: Vec<f64> = (0..y.len())
                .map(|i| (i + 100) as f64 / 1000.0 - 0.1)
                .collect();
            let mut f = StepFigures::new(a);
            for (t, y) in t.iter().zip(&y) {
                f.push(*t, *y);
            }
            match f.figures() {
                None => assert!(y.is_empty()),
                Some(got) => {
                    let want = tune::closed::step_figures(&t, &y, a);
                    assert_eq!(format!("{got:?}"), format!("{want:?}"), "{y:?}");
                }
            }
        }
    }
}
