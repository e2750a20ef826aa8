//! Honest results: what makes a fitted model unusable (unstable, no finite static gain where one
//! is expected, parameters the data do not determine, non-finite scores) and what deserves a
//! warning (no convergence, a static gain the record never shows: dynamics slower than the record,
//! as when a model without an integrator follows an integrating output), and a validation window
//! that carries excitation.

use super::{FracModel, Identification};
use crate::data::Record;
use fracsim::Simulator;

/// A model whose unit step response reaches less than this fraction of its static gain within
/// the record has dynamics slower than the record ([`unsettled_gain`]). Half: the record then
/// holds less than the model's own time to half its final value (for a first-order lag, 0.69 of
/// its time constant), so its `G(0)` is extrapolated by a factor of two or more. The clean fits
/// of the test suite reach 99% or more; a fit of the PMSM without an integrator to a position
/// record reached 40% (`tests/time/records.rs`).
const SETTLED_FRACTION: f64 = 0.5;

/// Input changes smaller than this fraction of the input's range are not excitation.
const CHANGE_FRACTION: f64 = 1e-6;

/// The fewest input changes a validation window must hold to score a model on.
const MIN_VALIDATION_CHANGES: usize = 3;

/// A parameter whose standard error is this many times its value is not determined by the data
/// at all (its one-sigma interval spans ten times the value): the result is not usable. Between
/// once and this many times, a warning.
const UNDETERMINED: f64 = 10.0;

/// A static gain that moves the output by more than this many times its spread for the input's
/// spread is not what the data show: the output integrates, or the gain is not identifiable.
const ABSURD_GAIN_RATIO: f64 = 1e3;

/// Indices `k >= from` where `u[k]` differs from `u[k-1]` by more than `tol`
/// ([`change_tolerance`]).
fn changes_from(u: &[f64], tol: f64, from: usize) -> impl Iterator<Item = usize> + '_ {
    (from.max(1)..u.len()).filter(move |&k| (u[k] - u[k - 1]).abs() > tol)
}

/// The smallest input change that counts: [`CHANGE_FRACTION`] of the input's range.
fn change_tolerance(u: &[f64]) -> f64 {
    let (lo, hi) = crate::lm::range_of(u);
    CHANGE_FRACTION * (hi - lo)
}

/// The validation split for `holdout`: the last `holdout` of the record when its input changes
/// at least [`MIN_VALIDATION_CHANGES`] times; otherwise the split is moved earlier so that the
/// validation window holds the last `holdout` fraction of the input's changes (and at least
/// that many), with a warning saying so. Returns `(split, warning)`.
pub(crate) fn validation_split(
    rec: &Record,
    split: usize,
    holdout: f64,
) -> (usize, Option<String>) {
    let n = rec.len();
    if split >= n {
        return (split, None);
    }
    // Enough changes in the validation part are usually found in its first samples.
    let (u, tol) = (&rec.u, change_tolerance(&rec.u));
    let early = changes_from(u, tol, split + 1)
        .take(MIN_VALIDATION_CHANGES)
        .count();
    if early >= MIN_VALIDATION_CHANGES {
        return (split, None);
    }
    let changes: Vec<usize> = changes_from(u, tol, 1).collect();
    let in_val = changes.iter().filter(|&&k| k > split).count();
    if in_val >= MIN_VALIDATION_CHANGES || changes.is_empty() {
        return (split, None);
    }
    let want = ((holdout * changes.len() as f64).ceil() as usize)
        .max(MIN_VALIDATION_CHANGES)
        .min(changes.len());
    // The validation starts a little before the first change it holds (a tenth of the gap to the
    // previous change), so the response to it is scored whole.
    let i = changes.len() - want;
    let prev = if i > 0 { changes[i - 1] } else { 0 };
    let new = changes[i] - (changes[i] - prev) / 10;
    let why = format!(
        "the input has {} change(s) in the last {:.0}% of the record (samples {split}..{n}): \
         validation moved to samples {new}..{n}, which hold {want} of the input's {} changes",
        in_val,
        100.0 * holdout,
        changes.len()
    );
    (new, Some(why))
}

/// Whether the model integrates by design (a denominator with no order-zero term).
fn integrates(m: &FracModel, p: &[f64]) -> bool {
    !m.den
        .iter()
        .any(|(c, o)| o.eval(p) == 0.0 && c.eval(p) != 0.0)
}

/// The standard deviation of `x` (population, over `len(x)`; 0 for an empty `x`), by sums in
/// eight lanes ([`crate::lm::sum_of`]).
pub(super) fn std_dev(x: &[f64]) -> f64 {
    let n = x.len().max(1) as f64;
    let mean = crate::lm::sum_of(x, |v| v) / n;
    (crate::lm::sum_of(x, |v| (v - mean) * (v - mean)) / n).sqrt()
}

/// The warning for a static gain the record never shows: the model's unit step response (its
/// own, from rest, delay included) reaches less than [`SETTLED_FRACTION`] of `G(0)` within the
/// record's duration `T = N dt`. Such a model has dynamics slower than the whole record, so the
/// data constrain its `G(0)` only by extrapolation; and a model without an integrator makes one
/// when it follows a drift of the output (an output that integrates the input, a position, with
/// an input offset or a mean input) with a mode slower than the record: it fits the record
/// tolerably, and that mode, not the plant, sets its static gain.
fn unsettled_gain(sim: &Simulator<f64>, dc: f64, rec: &Record) -> Option<String> {
    let n = rec.len();
    // The step response at the record's last sample, in closed form (not a simulation of it).
    let reached = sim.step_response_at(n.checked_sub(1)?) / dc;
    (reached.is_finite() && reached < SETTLED_FRACTION).then(|| {
        format!(
            "the model's step response reaches only {:.0}% of its static gain G(0) = {dc:.4e} \
             within the record ({:.4} s): it has dynamics slower than the record, and its G(0) \
             is an extrapolation; if the output drifts because it integrates the input (a \
             position), fit the structure with an integrator (--integrator), else record longer",
            100.0 * reached,
            n as f64 * rec.dt
        )
    })
}

/// The reasons the identified model cannot be used (empty when it can), and warnings.
pub(crate) fn assess(id: &Identification, rec: &Record) -> (Vec<String>, Vec<String>) {
    let (mut problems, mut warnings) = (vec![], vec![]);
    let m = &id.model;
    let p = &id.report.values;
    if !id.estimation.rmse.is_finite()
        || id.validation.is_some_and(|v| !v.rmse.is_finite())
        || !crate::lm::all_finite(&id.yhat)
    {
        problems.push("the model output or its error is not finite".into());
    }
    // Stability of the approximated model: every pole in the open left half-plane (a pole at
    // 0 only when the structure integrates by design).
    let mut simulator = None;
    match Simulator::<f64>::new(&id.tf, rec.dt, &m.approx) {
        Ok(sim) => {
            let pr = sim.model();
            let worst = pr
                .real
                .iter()
                .map(|&(l, _)| num_complex::Complex64::new(l, 0.0))
                .chain(pr.complex.iter().map(|&(l, _)| l.val()))
                .fold(None::<num_complex::Complex64>, |a, l| match a {
                    Some(a) if a.re >= l.re => Some(a),
                    _ => Some(l),
                });
            if let Some(l) = worst {
                if l.re > 1e-9 * l.norm().max(1.0) {
                    problems.push(format!(
                        "the model is unstable: a pole at {:.4e}{:+.4e}j rad/s in the right half-plane",
                        l.re, l.im
                    ));
                }
            }
            if problems.is_empty() {
                simulator = Some(sim);
            }
        }
        Err(e) => problems.push(format!("the model cannot be simulated: {e}")),
    }
    let dc = id.tf.dc_gain();
    let by_design = integrates(m, p);
    if !dc.is_finite() && !by_design {
        problems.push("the model has no finite static gain".into());
    } else if dc.is_finite() && dc < 0.0 {
        warnings.push(format!(
            "the static gain G(0) = {dc:.4e} is negative: the output falls when the input rises"
        ));
    }
    let (su, sy) = (std_dev(&rec.u), std_dev(&rec.y));
    if dc.is_finite() && !by_design && dc.abs() * su > ABSURD_GAIN_RATIO * sy.max(f64::MIN_POSITIVE)
    {
        problems.push(format!(
            "the static gain G(0) = {dc:.4e} is absurd for these data (the output's spread is \
             {sy:.3e} for the input's {su:.3e}): the output may integrate the input, try the \
             structure with an integrator (--integrator)"
        ));
    }
    if let Some(sim) = simulator
        .as_ref()
        .filter(|_| dc.is_finite() && dc != 0.0 && !by_design)
    {
        if let Some(w) = unsettled_gain(sim, dc, rec) {
            warnings.push(w);
        }
    }
    for (i, e) in id.report.params.iter().enumerate() {
        if !e.free || m.is_initial_state(i) || e.name == "y_offset" {
            continue;
        }
        match e.std_error {
            Some(se) if se > UNDETERMINED * e.value.abs() => problems.push(format!(
                "{} = {:.4e} +- {se:.2e} is not determined by these data (standard error \
                 {UNDETERMINED} times the value or more)",
                e.name, e.value
            )),
            Some(se) if se > e.value.abs() => warnings.push(format!(
                "{} = {:.4e} +- {se:.2e} is poorly identifiable from these data (standard error \
                 larger than the value)",
                e.name, e.value
            )),
            _ => {}
        }
    }
    if !id.report.converged {
        warnings.push(format!(
            "the fit did not converge ({}, {} iterations): the parameters may not be at the \
             optimum (raise --max-iter)",
            id.report.stop_reason(),
            id.report.iterations
        ));
    }
    (problems, warnings)
}
