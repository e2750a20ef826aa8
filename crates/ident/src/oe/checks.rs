//! Honest results: what makes a fitted model unusable (unstable, no finite static gain where one
//! is expected, parameters the data do not determine, non-finite scores) and what deserves a
//! warning (no convergence, a static gain the record never shows: dynamics slower than the record,
//! as when a model without an integrator follows an integrating output), and a validation window
//! that carries excitation.

use super::{FracModel, Identification};
use crate::data::Record;
use crate::metrics::Fit;
use fracsim::Simulator;

/// A model whose unit step response reaches less than this fraction of its static gain within
/// the record has dynamics slower than the record ([`unsettled_gain`]). Half: the record then
/// holds less than the model's own time to half its final value (for a first-order lag, 0.69 of
/// its time constant), so its `G(0)` is extrapolated by a factor of two or more. The clean fits
/// of the test suite reach 99% or more; a fit of the PMSM without an integrator to a position
/// record reached 40% (`tests/time/records.rs`).
const SETTLED_FRACTION: f64 = 0.5;

/// Input changes smaller than this fraction of the input's range are not excitation
/// ([`changes`]): a percent, under any step a test applies and above a logger's last count.
const CHANGE_FRACTION: f64 = 0.01;

/// The fewest input changes a validation window must hold to score a model on.
const MIN_VALIDATION_CHANGES: usize = 3;

/// A parameter whose standard error is this many times its value is not determined by the data
/// at all (its one-sigma interval spans ten times the value): the result is not usable. Between
/// once and this many times, a warning.
pub(crate) const UNDETERMINED: f64 = 10.0;

/// A fit with a singular covariance and an NRMSE below this (percent: it explains less than a
/// fifth of the output's variance, `1 - 0.9^2`) is not usable.
pub(super) const NO_BETTER_THAN_A_CONSTANT: f64 = 10.0;

/// Orders closer than this (relative, at least absolute) are the same order.
const SAME_ORDER: f64 = 1e-6;

/// A static gain that moves the output by more than this many times its spread for the input's
/// spread is not what the data show: the output integrates, or the gain is not identifiable.
const ABSURD_GAIN_RATIO: f64 = 1e3;

/// The input's changes: the indices `k` where `u[k]` has moved by more than `tol`
/// ([`change_tolerance`]) from its level at the last change counted (`u[0]` at first). A step
/// is one change however many samples its edge takes, and a logger's flicker of a few counts
/// on a held level (the battery tester's 0.00/0.01 A at rest) is none.
fn changes(u: &[f64], tol: f64) -> Vec<usize> {
    let mut level = u.first().copied().unwrap_or(0.0);
    let mut out = vec![];
    for (k, &v) in u.iter().enumerate().skip(1) {
        if (v - level).abs() > tol {
            out.push(k);
            level = v;
        }
    }
    out
}

/// The smallest input change that counts: [`CHANGE_FRACTION`] of the input's range.
fn change_tolerance(u: &[f64]) -> f64 {
    let (lo, hi) = crate::lm::range_of(u);
    CHANGE_FRACTION * (hi - lo)
}

/// How the fitted model was validated on the record it was fitted on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ValidationKind {
    /// A held-out part of the record that holds input changes of its own (a PRBS's last 30%):
    /// an independent check of the dynamics.
    HeldOut,
    /// Only the tail of the response to the input's last change is held out (a step test: its
    /// one change must stay in the estimation part), simulated on with the state carried over:
    /// it checks the settled response (the static gain the fit extrapolates), not the dynamics.
    /// The diagnosis scores on it as on any held-out part.
    ResponseTail,
    /// Nothing held out (`holdout` 0).
    None,
    /// A separate record (`--validate FILE`), scored by the front end.
    File,
    /// Short blocks spread over the record held out ([`Validation::blocks`]), each between
    /// estimation samples: a record whose tail would hold frequencies the rest of it never
    /// excites (a sweep). One simulation of the whole record; the fit's cost leaves the blocks
    /// out.
    HeldOutBlocks,
}

/// How a fit was validated, and in words ([`validation_split`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Validation {
    /// The kind of validation.
    pub kind: ValidationKind,
    /// The held-out samples `first..len` (none when `first == len`; `len` with
    /// [`ValidationKind::HeldOutBlocks`], whose held-out samples are its blocks).
    pub first: usize,
    /// What was validated and how, for the report.
    pub note: String,
    /// With [`ValidationKind::HeldOutBlocks`], the held-out blocks `start..end` (sample
    /// indices, increasing, disjoint); empty otherwise.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub blocks: Vec<(usize, usize)>,
}

impl Validation {
    /// The estimation part's figures and the held-out part's (`None` when nothing is held out)
    /// of the output `yhat` against `y` (same length, the whole record), with `split` the first
    /// sample after the estimation part (the record's length with blocks).
    pub fn figures(&self, y: &[f64], yhat: &[f64], split: usize) -> (Fit, Option<Fit>) {
        figures(y, yhat, split, &self.blocks)
    }

    /// The samples of the first `split` the fit's cost uses: `split` less the blocks'.
    pub fn estimation_samples(&self, split: usize) -> usize {
        estimation_samples(split, &self.blocks)
    }
}

/// [`Validation::figures`] with the blocks `held` (the tail after `split` when empty).
pub(crate) fn figures(
    y: &[f64],
    yhat: &[f64],
    split: usize,
    held: &[(usize, usize)],
) -> (Fit, Option<Fit>) {
    if held.is_empty() {
        let out = (split < y.len()).then(|| Fit::of(&y[split..], &yhat[split..]));
        return (Fit::of(&y[..split], &yhat[..split]), out);
    }
    let (ye, yh) = gather(&y[..split], held);
    let (fe, fh) = gather(&yhat[..split], held);
    (
        Fit::of(&ye, &fe),
        (!yh.is_empty()).then(|| Fit::of(&yh, &fh)),
    )
}

/// The samples of the first `split` outside the blocks `held` ([`Validation::estimation_samples`]).
pub(crate) fn estimation_samples(split: usize, held: &[(usize, usize)]) -> usize {
    split - held_count(held, split)
}

/// How many samples below `n` the blocks `held` hold.
pub(crate) fn held_count(held: &[(usize, usize)], n: usize) -> usize {
    held.iter().map(|&(a, b)| b.min(n).saturating_sub(a)).sum()
}

/// `x` parted by the blocks `held`: the samples outside them (in order) and those inside.
pub(crate) fn gather(x: &[f64], held: &[(usize, usize)]) -> (Vec<f64>, Vec<f64>) {
    let (mut out, mut inside) = (Vec::with_capacity(x.len()), vec![]);
    let mut k = 0;
    for &(a, b) in held {
        let (a, b) = (a.min(x.len()), b.min(x.len()));
        out.extend_from_slice(&x[k.min(a)..a]);
        inside.extend_from_slice(&x[a..b]);
        k = b;
    }
    out.extend_from_slice(&x[k.min(x.len())..]);
    (out, inside)
}

/// The number of blocks a record whose tail fails the coverage test holds out
/// ([`held_blocks`]): each then holds a tenth of the held-out share (3% of the record with the
/// default 30%) between two stretches of estimation data of more than twice its length, so a
/// sweep's band in a block is swept just before and just after it in estimation.
const HELD_BLOCKS: usize = 10;

/// The shortest block (samples): fewer blocks on a short record.
const MIN_BLOCK: usize = 32;

/// `HELD_BLOCKS` blocks totalling `held` of the `n` samples, each centred in its tenth of the
/// record (estimation data before the first and after the last); fewer blocks when they would
/// be shorter than [`MIN_BLOCK`]; `None` when fewer than two fit.
pub(crate) fn held_blocks(n: usize, held: usize) -> Option<Vec<(usize, usize)>> {
    let count = HELD_BLOCKS.min(held / MIN_BLOCK);
    if count < 2 || held >= n {
        return None;
    }
    let len = held / count;
    let seg = n as f64 / count as f64;
    let blocks = (0..count)
        .map(|i| {
            let a = (i as f64 * seg + 0.5 * (seg - len as f64)).round() as usize;
            (a, (a + len).min(n))
        })
        .collect();
    Some(blocks)
}

/// The validation split for `holdout` (`split` = the first held-out sample of the plain split).
///
/// - At least `2 x` [`MIN_VALIDATION_CHANGES`] input changes (a PRBS, a multi-step sequence): the
///   last `holdout` of the record when its input changes at least [`MIN_VALIDATION_CHANGES`]
///   times there; otherwise the split is moved earlier so that the validation window holds the
///   last `holdout` fraction of the input's changes (at least [`MIN_VALIDATION_CHANGES`], and the
///   estimation part keeps at least as many), with a warning saying so
///   ([`ValidationKind::HeldOut`]). With 4 or 5 changes (a staircase) the same, holding out at
///   least one change (its last step(s)) while the estimation part keeps 3.
/// - At most [`MIN_VALIDATION_CHANGES`] changes (a step, a doublet, a pulse; or none: a step at
///   the first sample): the validation never takes excitation from the estimation part. The
///   estimation part holds every change and the first `1 - holdout` of the response after the
///   last one; the rest of that response is held out, simulated on from the estimation part with
///   the state carried over ([`ValidationKind::ResponseTail`]), with a warning that says what it
///   checks.
///
/// A held-out part whose input puts [`super::coverage::BEYOND_SHARE`] or more of its power at
/// frequencies the estimation part does not excite (a sweep's last frequencies) gets a warning
/// saying that its figure tests the model beyond the band it was fitted on
/// ([`super::coverage::beyond_estimation_band`]).
///
/// Returns `(split, validation, warning)`.
pub(crate) fn validation_split(
    rec: &Record,
    split: usize,
    holdout: f64,
) -> (usize, Validation, Option<String>) {
    let (split, v, warning) = split_by_changes(rec, split, holdout);
    if v.kind != ValidationKind::HeldOut {
        return (split, v, warning);
    }
    let beyond = super::coverage::beyond_estimation_band(&rec.u[..split], &rec.u[split..], rec.dt);
    if beyond.is_some() {
        if let Some(b) = blocked(rec, holdout) {
            return b;
        }
    }
    let beyond = beyond.map(|b| beyond_warning(&b, "a sweep holds out its last frequencies"));
    let warning = match (warning, beyond) {
        (Some(a), Some(b)) => Some(format!("{a}; {b}")),
        (a, b) => a.or(b),
    };
    (split, v, warning)
}

/// The warning of a held-out part excited beyond the estimation part's band (`why`: the likely
/// cause).
fn beyond_warning(b: &super::coverage::Beyond, why: &str) -> String {
    format!(
        "the held-out part's input puts {:.0}% of its power at frequencies the estimation \
         part hardly excites (it excites about {:.3e} to {:.3e} Hz; beyond, 20 dB below \
         its strongest): the held-out figure tests the model beyond the band it was \
         fitted on ({why}); to fit the whole band, --holdout 0, and score the model on another \
         record with --validate FILE",
        100.0 * b.share,
        b.band_hz.0,
        b.band_hz.1
    )
}

/// The validation by blocks ([`held_blocks`]) of a record whose tail holds frequencies its
/// first part does not excite: the split is the record's length, the blocks are the held-out
/// part; a warning when the blocks still fail the coverage test. `None` when the record is too
/// short for two blocks.
fn blocked(rec: &Record, holdout: f64) -> Option<(usize, Validation, Option<String>)> {
    let n = rec.len();
    let held = (holdout * n as f64).round() as usize;
    let blocks = held_blocks(n, held)?;
    let (est, inside) = gather(&rec.u, &blocks);
    let warning = super::coverage::beyond_estimation_band(&est, &inside, rec.dt)
        .map(|b| beyond_warning(&b, "the held-out blocks"));
    let list: Vec<String> = blocks.iter().map(|(a, b)| format!("{a}..{b}")).collect();
    let note = format!(
        "{} blocks of {} samples held out, spread over the record (samples {}; {:.0}% of the \
         record): its last {:.0}% holds frequencies the rest does not excite (a sweep), so each \
         block lies between estimation samples that excite its band; the model is simulated over \
         the whole record and fitted on the samples outside the blocks",
        blocks.len(),
        blocks[0].1 - blocks[0].0,
        list.join(", "),
        100.0 * held_count(&blocks, n) as f64 / n as f64,
        100.0 * holdout
    );
    let v = Validation {
        kind: ValidationKind::HeldOutBlocks,
        first: n,
        note,
        blocks,
    };
    Some((n, v, warning))
}

/// [`validation_split`] by the input's changes alone, with no test of the held-out part's band
/// (for a caller that needs the split only).
pub(crate) fn split_by_changes(
    rec: &Record,
    split: usize,
    holdout: f64,
) -> (usize, Validation, Option<String>) {
    let n = rec.len();
    if split >= n {
        return validation_split_none(n);
    }
    let held_out = |first: usize, note: String| Validation {
        kind: ValidationKind::HeldOut,
        first,
        note,
        blocks: vec![],
    };
    let plain = |first: usize| {
        held_out(
            first,
            format!(
                "the last {:.0}% of the record (samples {first}..{n}) held out, with input \
                 changes of its own",
                100.0 * holdout
            ),
        )
    };
    let changes = changes(&rec.u, change_tolerance(&rec.u));
    let in_val = changes.iter().filter(|&&k| k > split).count();
    if in_val >= MIN_VALIDATION_CHANGES && changes.len() - in_val >= MIN_VALIDATION_CHANGES {
        return (split, plain(split), None);
    }
    if changes.len() <= MIN_VALIDATION_CHANGES {
        return response_tail(n, split, holdout, changes.last().copied().unwrap_or(0));
    }
    // A multi-step test (4 or 5 changes) holds out its last step(s); a PRBS at least 3 changes.
    let least = if changes.len() >= 2 * MIN_VALIDATION_CHANGES {
        MIN_VALIDATION_CHANGES
    } else {
        1
    };
    if in_val >= least && changes.len() - in_val >= MIN_VALIDATION_CHANGES {
        return (split, plain(split), None);
    }
    let want = ((holdout * changes.len() as f64).ceil() as usize)
        .max(least)
        .min(changes.len() - MIN_VALIDATION_CHANGES);
    // The validation starts a little before the first change it holds (a tenth of the gap to the
    // previous change), so the response to it is scored whole.
    let i = changes.len() - want;
    let prev = changes[i - 1];
    let new = changes[i] - (changes[i] - prev) / 10;
    let why = format!(
        "the input has {} change(s) in the last {:.0}% of the record (samples {split}..{n}): \
         validation moved to samples {new}..{n}, which hold {want} of the input's {} changes",
        in_val,
        100.0 * holdout,
        changes.len()
    );
    let note = format!(
        "samples {new}..{n} held out: the last {want} of the input's {} changes",
        changes.len()
    );
    (new, held_out(new, note), Some(why))
}

/// [`validation_split`] for a record with few input changes, the last at `last` (0 for none):
/// the tail of the response after it.
fn response_tail(
    n: usize,
    split: usize,
    holdout: f64,
    last: usize,
) -> (usize, Validation, Option<String>) {
    let after = n - last;
    let new = split.max(last + ((1.0 - holdout) * after as f64).round() as usize);
    let new = new.min(n);
    if new >= n {
        return validation_split_none(n);
    }
    let note = format!(
        "the input changes too rarely to hold changes out (a step test): only the tail of the \
         response to its last change (samples {new}..{n}) is held out, simulated on with the \
         state carried over; it checks the settled response, not the dynamics: give --validate \
         FILE to score the model on another record"
    );
    let v = Validation {
        kind: ValidationKind::ResponseTail,
        first: new,
        note: note.clone(),
        blocks: vec![],
    };
    (new, v, Some(format!("validation: {note}")))
}

/// No held-out part.
fn validation_split_none(n: usize) -> (usize, Validation, Option<String>) {
    let note = "no held-out part: no independent validation; give --validate FILE to score the \
                model on another record"
        .to_string();
    let v = Validation {
        kind: ValidationKind::None,
        first: n,
        note,
        blocks: vec![],
    };
    (n, v, None)
}

/// The warning for initial-state levels ([`super::PastInput`]) that ended at an edge of their
/// range (the input's range widened by twice its span on each side): no past input the drive could
/// have applied explains the record's first samples; it starts in motion from another cause, or
/// the structure lacks a mode slower than the record. `None` when no level is at an edge.
pub(crate) fn levels_at_bound(m: &FracModel, params: &[super::ParamEstimate]) -> Option<String> {
    let levels: Vec<String> = params
        .iter()
        .filter(|p| p.at_bound && m.index_of(&p.name).is_some_and(|i| m.is_initial_state(i)))
        .map(|p| format!("{} = {:.4e}", p.name, p.value))
        .collect();
    (!levels.is_empty()).then(|| {
        format!(
            "the initial state's past-input level(s) {} ended at the edge of their range (the \
             input's range widened by twice its span): no past held input within reach explains \
             the record's first samples (it starts in motion from another cause, or the \
             structure lacks a mode slower than the record); the fit of the first samples is \
             not evidence for the plant",
            levels.join(", ")
        )
    })
}

/// Two terms of the numerator (or the denominator) that ended at the same order, both with a
/// fitted coefficient: only their sum is determined by any data (the fit of a structure too rich
/// for the record, such as `--integrator` on an output that does not integrate).
fn same_order_terms(m: &FracModel, p: &[f64]) -> Vec<String> {
    let mut out = vec![];
    for (side, terms) in [("numerator", &m.num), ("denominator", &m.den)] {
        // A coefficient that is a product, or has a parameter another term's coefficient also
        // has, is tied to other terms (a product multiplied out): not the case meant here.
        let fitted = |c: &super::Expr| {
            let alone = |i: usize| terms.iter().filter(|(d, _)| d.has(i)).count() == 1;
            c.factors.is_empty()
                && c.terms.iter().any(|&(i, _)| m.params[i].free)
                && c.terms.iter().all(|&(i, _)| alone(i))
        };
        for i in 0..terms.len() {
            for j in i + 1..terms.len() {
                let (oi, oj) = (terms[i].1.eval(p), terms[j].1.eval(p));
                if (oi - oj).abs() <= SAME_ORDER * oi.abs().max(1.0)
                    && fitted(&terms[i].0)
                    && fitted(&terms[j].0)
                {
                    out.push(format!(
                        "two {side} terms ended at the same order {oi:.4}: their coefficients \
                         are not separately determined (the structure is too rich for these data)"
                    ));
                }
            }
        }
    }
    out
}

/// A fit whose covariance is singular (no free plant parameter has a standard error: parameters
/// held at a bound are not counted) and that predicts hardly better than a constant: NRMSE below
/// [`NO_BETTER_THAN_A_CONSTANT`] on the held-out part (the estimation part without one). A
/// singular covariance alone is not enough (a good fit whose initial-state levels are
/// collinear has one: the UNAL record's FOPDT, 96.5%); with a fit that explains almost nothing,
/// nothing in it is determined. Seen: `--integrator` on an output that does not integrate (0.6%),
/// a written model left at its start (-101%).
fn singular_and_no_better_than_a_constant(ev: &Evidence<'_>) -> Option<String> {
    let plant: Vec<usize> = plant_indices(ev).collect();
    let singular = !plant.is_empty() && plant.iter().all(|&i| ev.params[i].std_error.is_none());
    let fit = ev.validation.unwrap_or(ev.estimation).nrmse_percent;
    (singular && !(fit >= NO_BETTER_THAN_A_CONSTANT)).then(|| {
        format!(
            "the covariance is singular and the model fits only {fit:.1}% (below \
             {NO_BETTER_THAN_A_CONSTANT}%: hardly better than a constant): its parameters are not \
             determined by these data (another structure, or a record with more excitation)"
        )
    })
}

/// The free plant parameters (not the initial state's levels nor the output offset) whose
/// standard error is [`UNDETERMINED`] times their value or more, and those whose standard error
/// exceeds their value, each as `name = value +- se`.
fn weak_parameters(ev: &Evidence<'_>) -> (Vec<String>, Vec<String>) {
    let (mut undetermined, mut poor) = (Vec::new(), Vec::new());
    for (i, e) in ev.params.iter().enumerate() {
        if !free_plant(ev.model, i, e) {
            continue;
        }
        let said = |se: f64| format!("{} = {:.4e} +- {se:.2e}", e.name, e.value);
        match e.std_error {
            Some(se) if not_determined(e) => undetermined.push(said(se)),
            Some(se) if se > e.value.abs() => poor.push(said(se)),
            _ => {}
        }
    }
    (undetermined, poor)
}

/// Whether parameter `i` of `model`, estimated as `e`, is a free plant parameter (not one of
/// the initial state's levels nor the output offset): those the verdict judges determined or
/// not.
pub(crate) fn free_plant(model: &FracModel, i: usize, e: &super::ParamEstimate) -> bool {
    e.free && !model.is_initial_state(i) && e.name != "y_offset"
}

/// Whether the standard error of `e` is [`UNDETERMINED`] times its value or more: the data do
/// not determine it at all.
pub(crate) fn not_determined(e: &super::ParamEstimate) -> bool {
    e.std_error
        .is_some_and(|se| se > UNDETERMINED * e.value.abs())
}

/// "1 parameter is" / "3 parameters are".
fn are(n: usize) -> String {
    if n == 1 {
        "1 parameter is".into()
    } else {
        format!("{n} parameters are")
    }
}

/// A model that predicts a held-out part with input changes of its own
/// ([`ValidationKind::HeldOut`]) worse than that part's own mean (NRMSE below 0): it does not
/// describe the dynamics these data show, whatever its estimation fit. (A step test's settled
/// tail, [`ValidationKind::ResponseTail`], is exempt: there `||y - mean(y)||` is only noise.)
fn worse_than_the_mean_held_out(ev: &Evidence<'_>) -> Option<String> {
    let v = ev.validation?;
    (ev.kind == ValidationKind::HeldOut && v.nrmse_percent < 0.0).then(|| {
        format!(
            "the model predicts the held-out part worse than its mean (NRMSE {:.1}%, RMSE \
             {:.4e}): it does not describe these data (another structure, a delay: try --diagnose)",
            v.nrmse_percent, v.rmse
        )
    })
}

/// An output that does not vary at all over the record (its spread zero, so the NRMSE
/// `100 (1 - ||y - yhat|| / ||y - mean(y)||)` says nothing: 100% for an exact fit, `-inf`
/// otherwise): the record holds no response to identify, and any model, whatever its RMSE, says
/// nothing about the plant (a sensor not connected, the wrong column). Every model is judged by
/// this rule, the plain fit, each candidate structure and a diagnosis's final model alike (a
/// candidate that fitted a constant output exactly, RMSE 0, was usable by every other rule).
fn no_output_spread(sy: f64) -> Option<String> {
    (sy == 0.0).then(|| {
        "the output does not vary over the record (its spread is 0): there is no response to \
         identify, and no model's fit of it says anything about the plant (check that the \
         output column is the plant's measured output)"
            .to_string()
    })
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
fn unsettled_gain(reached: f64, dc: f64, rec: &Record) -> Option<String> {
    let n = rec.len();
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

/// The fraction of its static gain `dc` the model's unit step response (its own, from rest,
/// delay included) reaches at the record's last sample, in closed form (not a simulation);
/// `None` for an empty record or a fraction that is not finite.
fn settled_fraction(sim: &Simulator<f64>, dc: f64, rec: &Record) -> Option<f64> {
    let reached = sim.step_response_at(rec.len().checked_sub(1)?) / dc;
    reached.is_finite().then_some(reached)
}

/// What the verdict on a time-domain model is made of: the model with its fitted values, its
/// parameters as estimated (standard errors where the covariance gave them), the values it
/// started from, and its own figures. [`Identification`] gives one ([`Evidence::of`]); a joint
/// fit gives another ([`super::joint`]).
pub(crate) struct Evidence<'a> {
    /// The model (its structure, effects and operating point).
    pub model: &'a FracModel,
    /// Its fitted values.
    pub values: &'a [f64],
    /// Its parameters as estimated.
    pub params: &'a [super::ParamEstimate],
    /// The values the fit started from.
    pub start: &'a [f64],
    /// Its linear part.
    pub tf: &'a fracsim::FracTf,
    /// Its fit on the estimation part.
    pub estimation: crate::metrics::Fit,
    /// Its fit on the held-out part, if any.
    pub validation: Option<crate::metrics::Fit>,
    /// How it was validated on the record.
    pub kind: ValidationKind,
    /// Whether its output is finite everywhere.
    pub output_finite: bool,
    /// Whether its fit converged, why it stopped, after how many iterations.
    pub converged: (bool, &'a str, usize),
    /// Whether it was evaluated at given values rather than fitted (no iteration allowed: a
    /// report's model judged at its values), so that its start says nothing of the data.
    pub evaluated: bool,
}

impl<'a> Evidence<'a> {
    /// The evidence of an identification.
    pub(crate) fn of(id: &'a Identification) -> Self {
        Self {
            model: &id.model,
            values: &id.report.values,
            params: &id.report.params,
            start: &id.start,
            tf: &id.tf,
            estimation: id.estimation,
            validation: id.validation,
            kind: id.validated_by.kind,
            output_finite: crate::lm::all_finite(&id.yhat),
            converged: (
                id.report.converged,
                id.report.stop_reason(),
                id.report.iterations,
            ),
            evaluated: id.report.evaluated,
        }
    }
}

/// The reasons the identified model cannot be used (empty when it can), and warnings.
pub(crate) fn assess(id: &Identification, rec: &Record) -> (Vec<String>, Vec<String>) {
    assess_evidence(&Evidence::of(id), rec)
}

/// The dynamics' largest departure from the static gain over the record's band, relative to it:
/// `max |G(j w) - G(0)| / |G(0)|` for `w` from `2 pi / T` to the Nyquist frequency `pi / dt`
/// (64 frequencies spaced logarithmically; `T` the record's duration). `None` when `G(0)` is not
/// finite and nonzero.
fn dynamics_over_the_band(tf: &fracsim::FracTf, rec: &Record) -> Option<f64> {
    let g0 = tf.dc_gain();
    if !(g0.is_finite() && g0 != 0.0) || rec.len() < 2 {
        return None;
    }
    let (lo, hi) = (
        2.0 * std::f64::consts::PI / (rec.len() as f64 * rec.dt),
        std::f64::consts::PI / rec.dt,
    );
    let n = 64;
    let worst = (0..n)
        .map(|i| lo * (hi / lo).powf(i as f64 / (n - 1) as f64))
        .map(|w| (tf.freq_response(w) - g0).norm() / g0.abs())
        .fold(0.0f64, f64::max);
    Some(worst)
}

/// A fitted model whose response departs from its static gain by less than this fraction over
/// the whole band the record covers has no dynamics there ([`static_gain_only`]).
const STATIC_ONLY: f64 = 1e-3;

/// A model with free dynamics (orders or coefficients fitted) whose response over the record's
/// band is its static gain to within [`STATIC_ONLY`]: the record shows no dynamics (an output
/// that is the input times a constant, a plant far faster than the sampling), so the orders and
/// coefficients fitted mean nothing (they are not determined: the fit ran them where they do not
/// matter). A drive engineer asking for the plant's dynamics is told that the record shows a
/// static gain, and its value, instead of being given dynamics that are not there.
fn static_gain_only(ev: &Evidence<'_>, rec: &Record) -> Option<String> {
    // A free parameter in a term of nonzero order (its coefficient or its order), or the delay.
    let (m, p) = (ev.model, ev.values);
    let shapes = |i: usize| {
        m.num
            .iter()
            .chain(&m.den)
            .any(|(c, o)| o.eval(p) != 0.0 && (c.has(i) || o.has(i)))
    };
    let dynamics_free =
        (0..m.params.len()).any(|i| m.params[i].free && (shapes(i) || m.delay == Some(i)));
    let dev = dynamics_over_the_band(ev.tf, rec)?;
    (dynamics_free && dev < STATIC_ONLY).then(|| {
        let g0 = ev.tf.dc_gain();
        format!(
            "the record shows no dynamics: the fitted model is a static gain G(0) = {g0:.4e} over \
             the whole band the record covers ({:.3e} to {:.3e} rad/s; its response departs from \
             G(0) by at most {dev:.1e} of it), so its orders and coefficients are not determined \
             by these data ({})",
            2.0 * std::f64::consts::PI / (rec.len() as f64 * rec.dt),
            std::f64::consts::PI / rec.dt,
            static_ratio_text(ev.tf, rec),
        )
    })
}

/// What the record itself says of a static gain fitted to it ([`static_gain_only`]): the
/// output's least-squares ratio to the input at the same instants (deviations from their means),
/// and whether the model's `G(0)` reproduces it (within 5%). A strictly proper model (no instant
/// response) cannot follow an output that moves with the input at once: its `G(0)` is then off
/// from that ratio, and the text says so.
fn static_ratio_text(tf: &fracsim::FracTf, rec: &Record) -> String {
    let n = rec.len().max(1) as f64;
    let (mu, my) = (rec.u.iter().sum::<f64>() / n, rec.y.iter().sum::<f64>() / n);
    let (suy, suu) = rec.u.iter().zip(&rec.y).fold((0.0, 0.0), |(a, b), (u, y)| {
        (a + (u - mu) * (y - my), b + (u - mu) * (u - mu))
    });
    let ratio = suy / suu;
    let advice = "sample faster, or check that the output is the plant's";
    if !ratio.is_finite() {
        return advice.to_string();
    }
    let said = format!("the output is the input times {ratio:.4e} at the same instants");
    if (ratio - tf.dc_gain()).abs() <= 0.05 * ratio.abs() {
        format!("{said}: {advice}")
    } else if tf.is_strictly_proper() {
        format!(
            "{said}, which this model does not reproduce: it has no instant response (the loop \
             closed compares structures that feed the input through; --structure feedthrough); \
             else {advice}"
        )
    } else {
        format!("{said}, which this model does not reproduce; else {advice}")
    }
}

/// A record whose input excites fewer than [`super::band::FEWEST`] bins (half a decade) where
/// the model `id`'s response and the output stand 10 dB above its error
/// ([`super::band::excited_bins`]): the plant is not determined there, and the model is a guess
/// outside that band however well it predicts the record. Judged on the model a report leads
/// with and its base fit (`crate::app::time`), not in [`assess`]: a base fit compared without the
/// record's effects has an error its missing effect swells, and so too few bins (on the zoo's
/// delay case 0235 every base fit but one had two, their final models many more).
pub(crate) fn narrow_band(id: &Identification, rec: &Record) -> Option<String> {
    let bins = super::band::excited_bins(&id.tf, (&rec.u, &rec.y), rec.dt, id.estimation.rmse)?;
    (bins < super::band::FEWEST).then(|| {
        format!(
            "the input excites {bins} frequency band(s) of a sixth of a decade where the model's \
             response and the output stand 10 dB above its error, fewer than {} (half a decade): \
             the record does not determine the plant, and the model is a guess outside that band \
             (a record with a wider excitation: a PRBS, a sweep, steps)",
            super::band::FEWEST
        )
    })
}

/// A fit whose free plant parameters all ended where they started (relative change under
/// `1e-9`) with a singular covariance: the data moved nothing and determine nothing, so its
/// figures are those of the values given, not a result of these data.
fn never_moved(ev: &Evidence<'_>) -> Option<String> {
    let plant: Vec<usize> = plant_indices(ev).collect();
    let singular = !plant.is_empty() && plant.iter().all(|&i| ev.params[i].std_error.is_none());
    let unmoved = plant.iter().all(|&i| {
        let (v, s) = (ev.values[i], ev.start.get(i).copied().unwrap_or(f64::NAN));
        (v - s).abs() <= 1e-9 * v.abs().max(s.abs())
    });
    (singular && unmoved && !ev.evaluated).then(|| {
        "the fit never moved its parameters from their start and the covariance is singular: \
         these data determine none of them (the figures are those of the values given; another \
         structure, other start values or a record with more excitation)"
            .to_string()
    })
}

/// The free plant parameters' indices (not the initial state's levels nor the output offset),
/// those held at a bound of their range left out.
fn plant_indices<'b>(ev: &'b Evidence<'_>) -> impl Iterator<Item = usize> + 'b {
    ev.params.iter().enumerate().filter_map(move |(i, e)| {
        (e.free && !e.at_bound && !ev.model.is_initial_state(i) && e.name != "y_offset")
            .then_some(i)
    })
}

/// [`assess`] of any [`Evidence`]: the one set of rules every time-domain model is judged by.
pub(crate) fn assess_evidence(ev: &Evidence<'_>, rec: &Record) -> (Vec<String>, Vec<String>) {
    let (mut problems, mut warnings) = (vec![], vec![]);
    let m = ev.model;
    let p = ev.values;
    if !ev.estimation.rmse.is_finite()
        || ev.validation.is_some_and(|v| !v.rmse.is_finite())
        || !ev.output_finite
    {
        problems.push("the model output or its error is not finite".into());
    }
    // Stability of the approximated model: every pole in the open left half-plane (a pole at
    // 0 only when the structure integrates by design).
    let mut simulator = None;
    match m.simulator::<f64>(p, rec.dt) {
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
    let dc = ev.tf.dc_gain();
    let by_design = integrates(m, p);
    if !dc.is_finite() && !by_design {
        problems.push("the model has no finite static gain".into());
    } else if dc.is_finite() && dc < 0.0 {
        warnings.push(format!(
            "the static gain G(0) = {dc:.4e} is negative: the output falls when the input rises"
        ));
    }
    let settles = simulator
        .as_ref()
        .filter(|_| dc.is_finite() && dc != 0.0 && !by_design)
        .map(|sim| settled_fraction(sim, dc, rec));
    let (su, sy) = (std_dev(&rec.u), std_dev(&rec.y));
    if dc.is_finite() && !by_design && dc.abs() * su > ABSURD_GAIN_RATIO * sy.max(f64::MIN_POSITIVE)
    {
        let said = format!(
            "the static gain G(0) = {dc:.4e} is absurd for these data (the output's spread is \
             {sy:.3e} for the input's {su:.3e}): the output may integrate the input, try the \
             structure with an integrator (--integrator)"
        );
        // A gain the record never reaches (the model's dynamics slower than the record) is an
        // extrapolation, not a claim of the data: a plant whose physics has a large or infinite
        // static gain (an integrator, a feed-through with an integrator) is fitted so. Only a
        // model that settles within the record, and so shows that gain on these data, is ruled
        // out by it.
        match settles {
            Some(Some(reached)) if reached < SETTLED_FRACTION => warnings.push(said),
            _ => problems.push(said),
        }
    }
    if let Some(Some(reached)) = settles {
        if let Some(w) = unsettled_gain(reached, dc, rec) {
            warnings.push(w);
        }
    }
    let (undetermined, poor) = weak_parameters(ev);
    if !undetermined.is_empty() {
        problems.push(format!(
            "{} not determined by these data (standard error {UNDETERMINED} times the value or \
             more): {}",
            are(undetermined.len()),
            undetermined.join(", ")
        ));
    }
    if !poor.is_empty() {
        warnings.push(format!(
            "{} poorly identifiable from these data (standard error larger than the value): {}",
            are(poor.len()),
            poor.join(", ")
        ));
    }
    problems.extend(same_order_terms(m, p));
    match singular_and_no_better_than_a_constant(ev) {
        Some(p) => problems.push(p),
        None => problems.extend(never_moved(ev)),
    }
    problems.extend(static_gain_only(ev, rec));
    problems.extend(no_output_spread(sy));
    problems.extend(worse_than_the_mean_held_out(ev));
    let (converged, why, iterations) = ev.converged;
    if !converged && !ev.evaluated {
        warnings.push(format!(
            "the fit did not converge ({why}, {iterations} iterations): the parameters may not be \
             at the optimum (raise --max-iter)"
        ));
    }
    (problems, warnings)
}
