//! The autotune's report: the probe, every experiment, the identification round by round, the
//! final model, the controller and its step predicted beside measured, and the verdict.

use super::control::{Crossover, Resonance};
use super::design::{Envelope, Purpose};
use super::probe::ProbeReading;
use super::rounds::{EffectValues, RecordError};
use super::AutotuneRequest;
use ident::diagnose::Ambiguity;
use serde::Serialize;

/// One experiment run on the drive.
#[derive(Debug, Clone, Serialize)]
pub struct Experiment {
    /// Its name (the record's, in the rounds).
    pub name: String,
    /// Why it was run.
    pub purpose: Purpose,
    /// What it was, in words (the request's figures).
    pub settings: String,
    /// The request as run (JSON of its request type).
    pub request: serde_json::Value,
    /// Drive time, s.
    pub duration_s: f64,
    /// Samples received.
    pub samples: u64,
    /// The largest voltage magnitude applied, V.
    pub peak_u_v: f64,
    /// The largest speed magnitude measured, rad/s.
    pub peak_speed: f64,
    /// Blocks the drive clamped.
    pub clamped_blocks: u64,
}

/// One identification round.
#[derive(Debug, Clone, Serialize)]
pub struct Round {
    /// The round's number (1: the identification experiment).
    pub round: usize,
    /// The experiment it added.
    pub experiment: String,
    /// What it was to separate (the ambiguity's words), or `identification`.
    pub reason: String,
    /// Each record's error under the model before the round (empty for the first).
    pub before: Vec<RecordError>,
    /// Each record's error under the round's model.
    pub after: Vec<RecordError>,
    /// The round's model in words.
    pub model: String,
    /// For a dwell round: the largest relative error of the model's frequency response at the
    /// points the dwells measured (the drive's zero-order hold on the model), before (the
    /// previous model) and after the round.
    pub frf_before: Option<f64>,
    /// After the round.
    pub frf_after: Option<f64>,
    /// The effects the diagnosis of the new record kept, with their values there.
    pub kept: Vec<EffectValues>,
    /// The effects it tried and rejected on the new record, why.
    pub rejected: Vec<EffectValues>,
    /// What the new record could not separate.
    pub ambiguous: Vec<Ambiguity>,
    /// The round's caveats.
    pub warnings: Vec<String>,
    /// For a resonance of the first model: the structures that hold one, fitted to the record
    /// (the one chosen starts the dwell's joint fit).
    pub structures: Vec<StructureTried>,
}

/// A structure fitted to the identification record for a resonance.
#[derive(Debug, Clone, Serialize)]
pub struct StructureTried {
    /// Its name.
    pub name: String,
    /// The fitted model in words, or why the fit failed.
    pub model: String,
    /// Its held-out RMSE, rad/s (`None`: the fit failed).
    pub rmse: Option<f64>,
    /// Whether it was chosen (within 5% of the first model's RMSE or below; the lowest, or the
    /// fewest free parameters within 2% of it).
    pub chosen: bool,
}

/// The final model's figures a user tunes by.
#[derive(Debug, Clone, Serialize)]
pub struct FinalModel {
    /// The model in words.
    pub text: String,
    /// The linear part with its delay.
    pub tf: String,
    /// Coulomb friction, V (the model's `Vc`), if it has it.
    pub friction_v: Option<f64>,
    /// Input offset, V, if it has one.
    pub input_offset_v: Option<f64>,
    /// Input delay, s.
    pub delay_s: f64,
    /// Its most prominent resonance, if any.
    pub resonance: Option<Resonance>,
    /// Ambiguities left unseparated (the budget ran out, or the experiment did not separate
    /// them).
    pub unresolved: Vec<Ambiguity>,
}

/// Step figures: overshoot (percent), 10-90% rise time and 2% settling time (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StepFigures {
    /// Overshoot, percent of the step.
    pub overshoot_percent: f64,
    /// 10-90% rise time, s.
    pub rise_time_s: Option<f64>,
    /// 2% settling time, s.
    pub settling_time_s: Option<f64>,
}

/// The controller and its step on the drive.
#[derive(Debug, Clone, Serialize)]
pub struct Control {
    /// `C(s)`.
    pub text: String,
    /// The filter in series with it for a resonance (the drive runs the filter, then `C`).
    pub filter: Option<tune::filter::Filter>,
    /// The filter in words.
    pub filter_text: Option<String>,
    /// Proportional gain.
    pub kp: f64,
    /// Integral gain.
    pub ki: f64,
    /// Integrator order.
    pub lambda: f64,
    /// The crossover as chosen and why.
    pub crossover: Crossover,
    /// The crossover the design was made at (lower than chosen after refusals).
    pub wc_used: f64,
    /// The tuner's refusals on the way.
    pub refusals: Vec<String>,
    /// The loop's sensitivity peak.
    pub ms: f64,
    /// Its phase margin, deg.
    pub pm_deg: f64,
    /// Its gain margin, dB.
    pub gm_db: f64,
    /// Fixed-point sections on the drive.
    pub sections: usize,
    /// The fixed-point controller's largest relative deviation from the realisation.
    pub quantisation_error: f64,
    /// The reference step, rad/s.
    pub step_rad_s: f64,
    /// The tuner's prediction on the final model.
    pub predicted: Option<StepFigures>,
    /// As measured on the drive.
    pub measured: Option<StepFigures>,
    /// The measured speed's oscillation at the resonance after the step settled: the RMS of
    /// the speed about its mean over the last third of the record, rad/s.
    pub residual_oscillation: f64,
}

/// The report of [`super::run`].
#[derive(Debug, Clone, Serialize)]
pub struct AutotuneReport {
    /// The request as run.
    pub request: AutotuneRequest,
    /// Sample rate, Hz.
    pub sample_rate_hz: u32,
    /// The levels the designs keep within.
    pub envelope: Envelope,
    /// The probe's reading.
    pub probe: Option<ProbeReading>,
    /// Every experiment, in order.
    pub experiments: Vec<Experiment>,
    /// The identification round by round.
    pub rounds: Vec<Round>,
    /// The final model.
    pub model: Option<FinalModel>,
    /// The controller and its step.
    pub control: Option<Control>,
    /// Whether the controller can be used: tuned, run on the drive, the step measured.
    pub usable: bool,
    /// Why not.
    pub problems: Vec<String>,
    /// Caveats.
    pub warnings: Vec<String>,
    /// Drive time of all experiments, s.
    pub drive_time_s: f64,
    /// Wall time, s.
    pub seconds: f64,
    /// The signals behind the plots (not serialised).
    #[serde(skip)]
    pub series: Series,
}

/// A record beside the final model, for plots.
#[derive(Debug, Clone, Default)]
pub struct RecordSeries {
    /// The record's name.
    pub name: String,
    /// Time, s.
    pub t: Vec<f64>,
    /// Input, V.
    pub u: Vec<f64>,
    /// Speed, rad/s.
    pub y: Vec<f64>,
    /// The final model's output, rad/s.
    pub yhat: Vec<f64>,
}

/// The signals of a run, for plots.
#[derive(Debug, Clone, Default)]
pub struct Series {
    /// Per record, beside the final model.
    pub records: Vec<RecordSeries>,
    /// The step: time from it (s), predicted and measured speed (rad/s).
    pub step: Option<(Vec<f64>, Vec<f64>, Vec<f64>)>,
}

fn opt_s(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{:.4} s", v))
}

impl AutotuneReport {
    /// The report as text, round by round.
    pub fn text(&self) -> String {
        let mut s = String::new();
        let mut line = |l: String| {
            s.push_str(&l);
            s.push('\n');
        };
        line(format!(
            "autotune at {} Hz: voltage within +-{:.2} V, speed within +-{:.1} rad/s, {:.2} s of \
             drive time used of {:.1} s",
            self.sample_rate_hz,
            self.envelope.u_max_v,
            self.envelope.speed_max,
            self.drive_time_s,
            self.request.budget_s
        ));
        if let Some(p) = &self.probe {
            line(format!(
                "probe: step of {:.3} V -> {:.3} rad/s: gain {:.4} (rad/s)/V, time constant {:.2} \
                 ms, delay {:.2} ms, bandwidth {:.1} rad/s{}",
                p.level_v,
                p.final_speed,
                p.gain,
                1e3 * p.time_constant_s,
                1e3 * p.delay_s,
                p.bandwidth_rad_s(),
                if p.settled { "" } else { " (not settled)" }
            ));
        }
        for e in &self.experiments {
            line(format!(
                "experiment {} ({:?}): {}; {:.3} s, {} samples, |u| <= {:.3} V, |y| <= {:.2} rad/s{}",
                e.name,
                e.purpose,
                e.settings,
                e.duration_s,
                e.samples,
                e.peak_u_v,
                e.peak_speed,
                if e.clamped_blocks > 0 {
                    format!(", {} blocks clamped", e.clamped_blocks)
                } else {
                    String::new()
                }
            ));
        }
        for r in &self.rounds {
            round_lines(r, &mut line);
        }
        if let Some(m) = &self.model {
            line(format!("final model: {}", m.text));
            if let Some(v) = m.friction_v {
                line(format!("  Coulomb friction {v:.4} V"));
            }
            if let Some(r) = &m.resonance {
                line(format!(
                    "  resonance {:.2} Hz, damping {:.3}",
                    r.freq_hz, r.damping
                ));
            }
            for a in &m.unresolved {
                line(format!("  unresolved: {} with {}", a.name, a.confused_with));
            }
        }
        if let Some(c) = &self.control {
            control_lines(c, &mut line);
        }
        for w in &self.warnings {
            line(format!("warning: {w}"));
        }
        for p in &self.problems {
            line(format!("problem: {p}"));
        }
        line(format!(
            "{} ({:.2} s)",
            if self.usable {
                "usable controller"
            } else {
                "no usable controller"
            },
            self.seconds
        ));
        s
    }
}

/// A round in lines: the errors before and after, the model, what was kept, rejected and left
/// ambiguous.
fn round_lines(r: &Round, line: &mut impl FnMut(String)) {
    line(format!(
        "round {} ({}, {}):",
        r.round, r.experiment, r.reason
    ));
    let fmt = |v: &[RecordError]| {
        v.iter()
            .map(|e| format!("{} {:.4} rad/s ({:.2}%)", e.record, e.rmse, e.nrmse_percent))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if !r.before.is_empty() {
        line(format!("  error before: {}", fmt(&r.before)));
    }
    line(format!("  error after:  {}", fmt(&r.after)));
    line(format!("  model: {}", r.model));
    if let (Some(b), Some(a)) = (r.frf_before, r.frf_after) {
        line(format!(
            "  frequency response at the dwells' points: largest error {:.2}% before, {:.2}% after",
            100.0 * b,
            100.0 * a
        ));
    }
    for k in &r.kept {
        line(format!(
            "  kept on {}: {} {:?}",
            r.experiment, k.name, k.params
        ));
    }
    for k in &r.rejected {
        line(format!("  rejected on {}: {}", r.experiment, k.name));
    }
    for a in &r.ambiguous {
        line(format!(
            "  ambiguous: {} with {}: {}",
            a.name, a.confused_with, a.reason
        ));
    }
    for t in &r.structures {
        line(format!(
            "  structure for the resonance: {}{}: {}{}",
            t.name,
            t.rmse.map_or(String::new(), |e| format!(" ({e:.4} rad/s)")),
            t.model,
            if t.chosen { " [chosen]" } else { "" }
        ));
    }
    for w in &r.warnings {
        line(format!("  warning: {w}"));
    }
}

/// The controller and its step, predicted beside measured, in lines.
fn control_lines(c: &Control, line: &mut impl FnMut(String)) {
    line(format!(
        "controller: C(s) = {} at wc {:.2} rad/s, pm {:.1} deg (Ms {:.2}, gm {:.1} dB); \
             {} sections, within {:.1e} of the realisation",
        c.text, c.wc_used, c.pm_deg, c.ms, c.gm_db, c.sections, c.quantisation_error
    ));
    if let Some(f) = &c.filter_text {
        line(format!("  in series: {f}, on the drive before C(s)"));
    }
    line(format!("  crossover: {}", c.crossover.reasons.join("; ")));
    for r in &c.refusals {
        line(format!("  refused: {r}"));
    }
    let show = |name: &str, f: &Option<StepFigures>| match f {
        Some(f) => format!(
            "  {name}: overshoot {:.2}%, rise {}, settling {}",
            f.overshoot_percent,
            opt_s(f.rise_time_s),
            opt_s(f.settling_time_s)
        ),
        None => format!("  {name}: -"),
    };
    line(format!("step of {:.2} rad/s:", c.step_rad_s));
    line(show("predicted", &c.predicted));
    line(show("measured ", &c.measured));
    line(format!(
        "  residual oscillation (last third): {:.4} rad/s RMS",
        c.residual_oscillation
    ));
}
