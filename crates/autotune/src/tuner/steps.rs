//! The autotune's steps on the drive, in order, with the report filled as they go.

use super::control::{self, Resonance};
use super::design::{self, Envelope, Purpose, LIMIT_SHARE};
use super::probe::{self, ProbeReading};
use super::report::{
    AutotuneReport, Control, Experiment, FinalModel, Round, Series, StepFigures, StructureTried,
};
use super::rounds::{self, Named, Outcome};
use super::{AutotuneRequest, Observe};
use crate::acquire::{self, prbs::PrbsRequest, sine::DwellRequest, speed_loop, step::StepRequest};
use crate::{Error, Result};
use drive::client::{Acquisition, Client, NullSink};
use drive::protocol::Configure;
use ident::app::{Preset, Structure};
use ident::diagnose::Ambiguity;
use std::time::Instant;

/// A run in progress.
pub(super) struct Run<'a> {
    client: &'a mut Client,
    conf: Configure,
    fs: f64,
    req: AutotuneRequest,
    env: Envelope,
    started: Instant,
    report: AutotuneReport,
    records: Vec<Named>,
    outcome: Option<Outcome>,
    /// A resonance the first record suggests, with the structure fitted that shows it.
    suspect: Option<(Resonance, Option<rounds::Model>)>,
    /// The frequency response points the dwells measured.
    points: Vec<drive::bode::BodePoint>,
}

/// The largest relative error of `m`'s frequency response at the measured `points`, the
/// drive's zero-order hold at `dt` (half a sample of delay, a sinc droop) put on the model as
/// the measurement has it.
fn frf_error(m: &rounds::Model, points: &[drive::bode::BodePoint], dt: f64) -> Option<f64> {
    let tf = m.tf().ok()?;
    points
        .iter()
        .map(|p| {
            let w = 2.0 * std::f64::consts::PI * p.freq_hz;
            let meas = num_complex::Complex64::from_polar(
                10f64.powf(p.gain_db / 20.0),
                p.phase_deg.to_radians(),
            );
            let model = tf.freq_response(w) * ident::hold::zoh(w, dt);
            (model - meas).norm() / meas.norm()
        })
        .reduce(f64::max)
}

/// The drive time the loop's step is kept for, s.
const LOOP_RESERVE_S: f64 = 1.0;

fn peak(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, x| a.max(x.abs()))
}

impl<'a> Run<'a> {
    pub(super) fn new(client: &'a mut Client, fs_hz: u32, req: &AutotuneRequest) -> Result<Self> {
        let conf = Configure {
            sample_rate_hz: fs_hz,
            u_limit: (req.u_limit_v * 1000.0).round() as i16,
            y_limit: (req.speed_limit_rad_s * 100.0).round() as i16,
            ..Configure::default()
        };
        client.configure(&conf)?;
        let env = Envelope {
            u_max_v: LIMIT_SHARE * req.u_limit_v,
            speed_max: LIMIT_SHARE * req.speed_limit_rad_s,
        };
        Ok(Self {
            client,
            conf,
            fs: f64::from(fs_hz),
            req: req.clone(),
            env,
            started: Instant::now(),
            report: AutotuneReport {
                request: req.clone(),
                sample_rate_hz: fs_hz,
                envelope: env,
                probe: None,
                experiments: vec![],
                rounds: vec![],
                model: None,
                control: None,
                usable: false,
                problems: vec![],
                warnings: vec![],
                drive_time_s: 0.0,
                seconds: 0.0,
                series: Series::default(),
            },
            records: vec![],
            outcome: None,
            suspect: None,
            points: vec![],
        })
    }

    pub(super) fn finish(mut self) -> AutotuneReport {
        self.report.seconds = self.started.elapsed().as_secs_f64();
        self.report
    }

    /// Every step; an unusable experiment or a refused design ends the run with the reason in
    /// the report (not an error).
    pub(super) fn all(&mut self, obs: &mut dyn Observe) -> Result<()> {
        match self.steps(obs) {
            Err(Error::Experiment(why)) => {
                self.report.problems.push(why);
                Ok(())
            }
            Err(Error::Ident(e)) => {
                self.report
                    .problems
                    .push(format!("the identification failed: {e}"));
                Ok(())
            }
            r => r,
        }
    }

    fn steps(&mut self, obs: &mut dyn Observe) -> Result<()> {
        obs.stage("probe: a small step from rest");
        let probe = self.probe(obs)?;
        obs.stage("identification experiment");
        let base = self.identification(&probe, obs)?;
        self.separate(&probe, &base, obs)?;
        obs.stage("the controller and its step on the drive");
        self.control(obs)
    }

    fn remaining(&self) -> f64 {
        self.req.budget_s - self.report.drive_time_s
    }

    fn check_cancel(&self, obs: &dyn Observe) -> Result<()> {
        if obs.cancelled() {
            return Err(Error::Interrupted(
                "the autotune was stopped; the drive is stopped".into(),
            ));
        }
        Ok(())
    }

    /// Log an experiment: its drive time joins the budget; an incomplete run or the speed trip
    /// is an unusable experiment.
    fn log(
        &mut self,
        obs: &dyn Observe,
        name: &str,
        purpose: Purpose,
        settings: String,
        request: serde_json::Value,
        acq: &Acquisition,
    ) -> Result<()> {
        let duration_s = acq.total_samples as f64 / self.fs;
        self.report.drive_time_s += duration_s;
        self.report.experiments.push(Experiment {
            name: name.into(),
            purpose,
            settings,
            request,
            duration_s,
            samples: acq.received,
            peak_u_v: peak(&acq.u),
            peak_speed: peak(&acq.y),
            clamped_blocks: acq.clamped_blocks,
        });
        self.check_cancel(obs)?;
        if !acq.complete {
            return Err(Error::Experiment(format!(
                "the {name} experiment is incomplete ({}): the drive was stopped",
                acq.problems.join("; ")
            )));
        }
        Ok(())
    }

    /// The probe: a step of a tenth of the envelope's voltage for 0.3 s, raised (x2.5) until the
    /// speed stands out of the noise and lowered (/3) after a speed beyond the envelope,
    /// lengthened (x3) until it settles; at most six steps.
    fn probe(&mut self, obs: &mut dyn Observe) -> Result<ProbeReading> {
        let mut level = 0.1 * self.env.u_max_v;
        let mut duration = 0.3;
        let floor = 0.01 * self.env.speed_max;
        let mut last = None;
        for k in 0..6 {
            let req = StepRequest {
                level_v: level,
                duration_s: duration,
            };
            let rec = acquire::step::run(self.client, &self.conf, &req, &mut NullSink)?;
            let name = format!("probe{}", k + 1);
            self.log(
                obs,
                &name,
                Purpose::Probe,
                format!("step 0 -> {level:.3} V for {duration:.2} s"),
                serde_json::to_value(&req).unwrap_or_default(),
                &rec.acquisition,
            )?;
            let (t, _, y) = rec.series();
            let Some(p) = probe::read(t, y, level) else {
                return Err(Error::Experiment(format!(
                    "the probe's step of {level:.3} V gave no readable response"
                )));
            };
            last = Some(p);
            if p.peak_speed > self.env.speed_max {
                level /= 3.0;
            } else if !p.visible(floor) && level < self.env.u_max_v {
                level = (2.5 * level).min(self.env.u_max_v);
            } else if !p.settled && duration < 3.0 && self.remaining() > 3.0 * duration {
                duration *= 3.0;
            } else {
                break;
            }
            self.check_cancel(obs)?;
        }
        let p = last.expect("at least one probe");
        if !p.visible(floor) {
            return Err(Error::Experiment(format!(
                "the speed does not respond to {:.3} V (final speed {:.4} rad/s, noise {:.4}): \
                 is the motor connected, the speed measured?",
                p.level_v, p.final_speed, p.noise
            )));
        }
        self.report.probe = Some(p);
        Ok(p)
    }

    /// Run a PRBS and name its record (from the end of its settling part).
    fn prbs(
        &mut self,
        obs: &dyn Observe,
        name: &str,
        purpose: Purpose,
        req: &PrbsRequest,
        from_settled: bool,
    ) -> Result<Named> {
        let rec = acquire::prbs::run(self.client, &self.conf, req, &mut NullSink)?;
        self.log(
            obs,
            name,
            purpose,
            format!(
                "PRBS order {}, clock {:.0} ms, {:.3} V around {:.3} V after {:.2} s",
                req.order,
                1e3 * req.clock_s,
                req.amplitude_v,
                req.offset_v,
                req.settle_s
            ),
            serde_json::to_value(req).unwrap_or_default(),
            &rec.acquisition,
        )?;
        self.report.warnings.extend(rec.warnings.iter().cloned());
        let from = if from_settled {
            (req.settle_s * self.fs).round() as usize
        } else {
            0
        };
        Ok(Named {
            name: name.into(),
            purpose,
            record: acquire::record_of(&rec.acquisition, from)?,
        })
    }

    fn identification(&mut self, p: &ProbeReading, obs: &mut dyn Observe) -> Result<PrbsRequest> {
        let cap = 0.3 * (self.remaining() - LOOP_RESERVE_S);
        let req = design::identification(
            p,
            &self.env,
            self.req.operating_point_v,
            self.fs,
            cap,
            self.req.seed,
        );
        let named = self.prbs(obs, "prbs", Purpose::Identification, &req, true)?;
        obs.stage("identification and diagnosis of the PRBS record");
        let out = rounds::first(&named)?;
        self.outcome = Some(out.clone());
        let mut tried = vec![];
        self.suspect = self.resonance().map(|r| {
            let (m, t) = self.resonant(&named, &r, &out, obs);
            tried = t;
            (r, m)
        });
        self.records.push(named);
        self.round("identification".into(), vec![], &out);
        if let Some(last) = self.report.rounds.last_mut() {
            last.structures = tried;
        }
        Ok(req)
    }

    /// The structures that hold a resonance, fitted to the identification record with its
    /// delay: the PMSM times a resonant pair at the load ([`rounds::load_resonance`], started
    /// from the resonance `r` the first model shows and the PMSM fitted to the record with its
    /// input through that resonance, [`rounds::behind_pair`]: a PMSM fitted to the record as it
    /// is bends to mimic the resonance, a start the fit may not leave), the two-mass drive train
    /// (the same start, the anti-resonance ten times above the resonance)
    /// and the general structure sized by the data ([`ident::diagnose::general`], started from
    /// the record's frequency response). Among those that fit at least as well as the first
    /// round's model (within 5%), the one of lowest held-out RMSE, or of fewest free parameters
    /// among those within [`ident::diagnose::structures::TIE`] of it: the structure the dwell's
    /// joint fit starts from.
    fn resonant(
        &mut self,
        named: &Named,
        r: &Resonance,
        out: &Outcome,
        obs: &mut dyn Observe,
    ) -> (Option<rounds::Model>, Vec<StructureTried>) {
        obs.stage("the structures of a resonance on the PRBS record");
        let base = out.errors.first().map_or(f64::INFINITY, |e| e.rmse);
        let mut fits: Vec<(&str, Result<(rounds::Model, f64)>)> = vec![];
        // the motor's start fitted behind the resonance (the record's input through it), or to
        // the record as it is
        let motor = rounds::behind_pair(named, r.freq_hz, r.damping)
            .and_then(|b| {
                rounds::fit_structure(&b, Structure::Named(Preset::Pmsm), Default::default())
            })
            .or_else(|_| {
                rounds::fit_structure(named, Structure::Named(Preset::Pmsm), Default::default())
            });
        if let Ok((pmsm, _)) = motor {
            if let Some(m) = rounds::load_resonance(&pmsm.spec, r.freq_hz, r.damping) {
                fits.push(("load-side resonance", rounds::fit_given(named, &m)));
            }
            let wr = 2.0 * std::f64::consts::PI * r.freq_hz;
            let mut start: std::collections::BTreeMap<String, f64> =
                ["K", "a1", "a2", "zeta", "theta"]
                    .iter()
                    .filter_map(|n| Some((n.to_string(), pmsm.param(n)?)))
                    .collect();
            start.insert("c2".into(), wr.powi(-2));
            start.insert("b2".into(), (10.0 * wr).powi(-2));
            start.insert("d".into(), 2.0 * r.damping / wr);
            start.insert("mu".into(), 1.0);
            fits.push((
                "two-mass",
                rounds::fit_structure(named, Structure::Named(Preset::TwoMass), start),
            ));
        }
        fits.push((
            "general",
            rounds::fit_structure(named, Structure::General(None), Default::default()),
        ));
        let mut ok: Vec<(usize, rounds::Model, f64)> = vec![];
        let mut tried = vec![];
        for (k, (name, fit)) in fits.into_iter().enumerate() {
            let (model, rmse) = match fit {
                Ok((m, rmse)) => {
                    obs.stage(&format!(
                        "{name}: {} ({rmse:.4} rad/s against {base:.4})",
                        m.text
                    ));
                    let text = m.text.clone();
                    if rmse <= 1.05 * base {
                        ok.push((k, m, rmse));
                    }
                    (text, Some(rmse))
                }
                Err(e) => {
                    obs.stage(&format!("the {name} fit failed: {e}"));
                    (format!("the fit failed: {e}"), None)
                }
            };
            tried.push(StructureTried {
                name: name.into(),
                model,
                rmse,
                chosen: false,
            });
        }
        // the structure comparison's rule: within TIE of the lowest RMSE, the fewest parameters
        let low = ok.iter().map(|c| c.2).fold(f64::INFINITY, f64::min);
        let free = |m: &rounds::Model| m.spec.params.iter().filter(|p| p.free).count();
        let best = ok
            .into_iter()
            .filter(|c| c.2 <= (1.0 + ident::diagnose::structures::TIE) * low)
            .min_by(|a, b| free(&a.1).cmp(&free(&b.1)).then(a.2.total_cmp(&b.2)));
        if let Some((k, _, _)) = &best {
            tried[*k].chosen = true;
        }
        (best.map(|b| b.1), tried)
    }

    fn round(&mut self, reason: String, before: Vec<rounds::RecordError>, out: &Outcome) {
        let n = self.report.rounds.len() + 1;
        self.report.rounds.push(Round {
            round: n,
            experiment: self
                .records
                .last()
                .map(|r| r.name.clone())
                .unwrap_or_default(),
            reason,
            before,
            after: out.errors.clone(),
            model: out.model.text.clone(),
            frf_before: None,
            frf_after: None,
            kept: out.kept.clone(),
            rejected: out.rejected.clone(),
            ambiguous: out.ambiguous.clone(),
            warnings: out.warnings.clone(),
            structures: vec![],
        });
    }

    /// The next experiment: for the first ambiguity not yet addressed, else a resonance of the
    /// model not yet dwelt on, else a longer record if the probe did not settle.
    fn next(
        &self,
        p: &ProbeReading,
        base: &PrbsRequest,
        done: &[Purpose],
    ) -> Option<(Purpose, String)> {
        let out = self.outcome.as_ref()?;
        if !done.contains(&Purpose::Dwell) {
            if let Some((r, _)) = &self.suspect {
                return Some((
                    Purpose::Dwell,
                    format!(
                        "a resonance near {:.1} Hz (damping {:.3})",
                        r.freq_hz, r.damping
                    ),
                ));
            }
        }
        for a in &out.ambiguous {
            let purpose = match a.name.as_str() {
                "coulomb_friction" => Purpose::Reversals,
                "saturation" | "deadzone" | "power_law" => Purpose::MultiLevel,
                _ => continue,
            };
            if !done.contains(&purpose) {
                return Some((purpose, format!("{} against {}", a.name, a.confused_with)));
            }
        }
        if !p.settled && !done.contains(&Purpose::Longer) {
            let _ = base;
            return Some((
                Purpose::Longer,
                "a slow mode: the probe did not settle".into(),
            ));
        }
        None
    }

    fn resonance(&self) -> Option<Resonance> {
        let tf = self.outcome.as_ref()?.model.tf().ok()?;
        control::resonance(&tf, 0.9 * std::f64::consts::PI * self.fs)
    }

    fn separate(
        &mut self,
        p: &ProbeReading,
        base: &PrbsRequest,
        obs: &mut dyn Observe,
    ) -> Result<()> {
        let mut done = vec![];
        for _ in 0..self.req.max_rounds {
            let Some((purpose, reason)) = self.next(p, base, &done) else {
                break;
            };
            done.push(purpose);
            let span = (0.25 * (self.remaining() - LOOP_RESERVE_S)).min(2.0);
            if span < 0.2 {
                self.report.warnings.push(format!(
                    "{reason}: not separated, the budget is spent ({:.2} s left)",
                    self.remaining()
                ));
                break;
            }
            obs.stage(&format!("round {}: {reason}", self.report.rounds.len() + 1));
            let named = match purpose {
                Purpose::Reversals => {
                    let mut r = design::reversals(p, &self.env, self.fs, span, self.req.seed);
                    r.settle_s = 0.05;
                    self.prbs(obs, "reversals", purpose, &r, false)?
                }
                Purpose::Longer => {
                    let r = design::longer(base, self.fs, span);
                    self.prbs(obs, "longer", purpose, &r, true)?
                }
                Purpose::MultiLevel => self.multi_level(p, obs)?,
                Purpose::Dwell => match self.suspect.clone() {
                    Some((r, _)) => self.dwell(&r, base, obs)?,
                    None => continue,
                },
                _ => continue,
            };
            let prev = self.outcome.as_ref().expect("a first round").model.clone();
            self.records.push(named);
            obs.stage("the records fitted jointly");
            let before = rounds::errors(&prev.spec, &self.records)?;
            let target = match (purpose, &self.suspect) {
                (Purpose::Reversals, _) => rounds::Target::Friction(0.05 * self.env.u_max_v),
                (Purpose::Dwell, Some((_, Some(m)))) => {
                    rounds::Target::Start(Box::new(m.spec.clone()))
                }
                (Purpose::Dwell, _) => rounds::Target::Start(Box::new(prev.spec.clone())),
                _ => rounds::Target::Diagnosed,
            };
            let out = rounds::later(&self.records, &prev.spec, target)?;
            self.round(reason, before, &out);
            if purpose == Purpose::Dwell {
                let last = self.report.rounds.last_mut().expect("a round");
                last.frf_before = frf_error(&prev, &self.points, 1.0 / self.fs);
                last.frf_after = frf_error(&out.model, &self.points, 1.0 / self.fs);
            }
            self.outcome = Some(out);
            self.check_cancel(obs)?;
        }
        Ok(())
    }

    /// A slow sine over most of the envelope's voltage for the speed (every level in between):
    /// a static input map against a gain and an offset.
    fn multi_level(&mut self, p: &ProbeReading, obs: &dyn Observe) -> Result<Named> {
        let top = self.env.u_for_speed(p.gain);
        let f = (p.bandwidth_rad_s() / (2.0 * std::f64::consts::PI) / 10.0).clamp(0.5, 20.0);
        let req = DwellRequest {
            freq_hz: f,
            amplitude_v: 0.45 * top,
            offset_v: 0.5 * top,
            settle_cycles: 1,
            cycles: 3,
        };
        self.dwell_run(obs, "levels", Purpose::MultiLevel, &req)
    }

    /// Dwells around a resonance: the frequencies of [`design::dwell_frequencies`] at the
    /// operating point of the identification PRBS, each a frequency response point; the one at
    /// the resonance, the longest, is the record the joint fit gets (each record brings its own
    /// initial state: the fit's parameters allow one).
    fn dwell(&mut self, r: &Resonance, base: &PrbsRequest, obs: &dyn Observe) -> Result<Named> {
        let freqs = design::dwell_frequencies(r.freq_hz, self.fs);
        // the amplitude that keeps the peak speed within the envelope at the resonance's gain
        let g = self
            .outcome
            .as_ref()
            .and_then(|o| o.model.tf().ok())
            .map(|tf| {
                tf.freq_response(2.0 * std::f64::consts::PI * r.freq_hz)
                    .norm()
            })
            .unwrap_or(1.0);
        let level = (base.offset_v * self.report.probe.map_or(0.0, |p| p.gain)).abs();
        let room = self.env.speed_max - level;
        let amp = (0.5 * room / g.max(1e-9)).min(base.amplitude_v).max(0.05);
        let mut at_peak = None;
        for (k, f) in freqs.iter().enumerate() {
            let peak = (f / r.freq_hz - 1.0).abs() < 1e-9;
            let req = DwellRequest {
                freq_hz: *f,
                amplitude_v: amp,
                offset_v: base.offset_v,
                settle_cycles: 8,
                cycles: if peak { 24 } else { 8 },
            };
            let named = self.dwell_run(obs, &format!("dwell{}", k + 1), Purpose::Dwell, &req)?;
            if peak {
                at_peak = Some(named);
            }
        }
        at_peak.ok_or_else(|| {
            Error::Experiment("no dwell frequency below a quarter of the rate".into())
        })
    }

    fn dwell_run(
        &mut self,
        obs: &dyn Observe,
        name: &str,
        purpose: Purpose,
        req: &DwellRequest,
    ) -> Result<Named> {
        let rec = acquire::sine::dwell(self.client, &self.conf, req, &mut NullSink)?;
        self.points.extend(rec.point);
        self.log(
            obs,
            name,
            purpose,
            format!(
                "sine {:.2} Hz, {:.3} V around {:.3} V, {}+{} cycles",
                req.freq_hz, req.amplitude_v, req.offset_v, req.settle_cycles, req.cycles
            ),
            serde_json::to_value(req).unwrap_or_default(),
            &rec.acquisition,
        )?;
        Ok(Named {
            name: name.into(),
            purpose,
            record: acquire::record_of(&rec.acquisition, 0)?,
        })
    }

    fn final_model(&mut self) -> Result<rounds::Model> {
        let out = self.outcome.as_ref().expect("a first round");
        let model = out.model.clone();
        let tf = model.tf()?;
        let resonance = control::resonance(&tf, 0.9 * std::f64::consts::PI * self.fs);
        let addressed: Vec<&str> = self
            .report
            .rounds
            .iter()
            .skip(1)
            .map(|r| r.reason.as_str())
            .collect();
        let unresolved: Vec<Ambiguity> = out
            .ambiguous
            .iter()
            .filter(|a| {
                !addressed.iter().any(|r| r.starts_with(&a.name)) || self.report.rounds.len() == 1
            })
            .cloned()
            .collect();
        self.report.model = Some(FinalModel {
            text: model.text.clone(),
            tf: tf.to_string(),
            friction_v: model.param("Vc"),
            input_offset_v: model.param("u_offset"),
            delay_s: tf.delay,
            resonance,
            unresolved,
        });
        if !out.usable {
            self.report
                .warnings
                .push("the identification called the final model not usable".into());
        }
        for r in &self.records {
            if let Ok(s) = ident::oe::score(
                &model.spec,
                &r.record,
                ident::data::OffsetMode::Initial,
                ident::oe::InitialState::Auto,
            ) {
                self.report
                    .series
                    .records
                    .push(super::report::RecordSeries {
                        name: r.name.clone(),
                        t: r.record.t.clone(),
                        u: r.record.u.clone(),
                        y: r.record.y.clone(),
                        yhat: s.yhat,
                    });
            }
        }
        Ok(model)
    }

    fn control(&mut self, obs: &dyn Observe) -> Result<()> {
        let model = self.final_model()?;
        let tf = model.tf()?;
        let res = self.report.model.as_ref().and_then(|m| m.resonance);
        let g0 = tf.freq_response(1e-3).norm();
        let step = (0.3 * self.env.speed_max).min(0.4 * self.env.u_max_v * g0);
        let dt = 1.0 / self.fs;
        let control::Chosen {
            report: rep,
            runs,
            crossover: xo,
            wc_used,
            refusals,
            filter,
        } = control::choose(&model, &tf, res.as_ref(), &self.req, self.fs, step)?;
        let (k, qerr, _) = control::fixed(&rep, filter.as_ref(), &self.conf)?;
        let predicted_m = if rep.effects.is_empty() {
            rep.step.metrics
        } else {
            rep.step_with_effects.or(rep.step.metrics)
        };
        let settle = predicted_m
            .and_then(|m| m.settling_time)
            .unwrap_or(10.0 / wc_used);
        let lreq = speed_loop::LoopRequest {
            step_rad_s: step,
            pre_s: 0.1,
            duration_s: 0.1 + (3.0 * settle).clamp(0.3, 2.0),
        };
        let rec = speed_loop::run(self.client, &self.conf, &k, &lreq, &mut NullSink)?;
        self.log(
            obs,
            "loop",
            Purpose::LoopStep,
            format!(
                "speed loop, step 0 -> {step:.2} rad/s after {:.2} s",
                lreq.pre_s
            ),
            serde_json::to_value(&lreq).unwrap_or_default(),
            &rec.acquisition,
        )?;
        let fig = |(o, r, s): (f64, Option<f64>, Option<f64>)| StepFigures {
            overshoot_percent: o,
            rise_time_s: r,
            settling_time_s: s,
        };
        let measured = rec.figures.map(fig);
        let predicted =
            predicted_m.map(|m| fig((m.overshoot_percent, m.rise_time, m.settling_time)));
        let m = realise::measured_step(&rec.acquisition, &rec.command, self.conf.y_lsb());
        let residual = m.as_ref().map_or(f64::NAN, |m| {
            let tail = &m.y[2 * m.y.len() / 3..];
            let mean = tail.iter().sum::<f64>() / tail.len().max(1) as f64;
            (tail.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / tail.len().max(1) as f64).sqrt()
        });
        if let (Some(m), Some(run)) = (&m, runs.with_effects.as_ref().or(runs.design.as_ref())) {
            let every = (dt / rep.step.setup.h).round().max(1.0) as usize;
            let pred: Vec<f64> = (0..m.t.len())
                .map(|i| run.y.get(i * every).copied().unwrap_or(f64::NAN))
                .collect();
            self.report.series.step = Some((m.t.clone(), pred, m.y.clone()));
        }
        self.report.control = Some(Control {
            text: rep.controller.text.clone(),
            filter,
            filter_text: filter.as_ref().map(control::filter_text),
            kp: rep.params.kp,
            ki: rep.params.ki,
            lambda: rep.params.lambda,
            crossover: xo,
            wc_used,
            refusals,
            ms: rep.loop_.ms,
            pm_deg: rep.loop_.pm_deg,
            gm_db: rep.loop_.gm_db.unwrap_or(f64::INFINITY),
            sections: k.sections.len(),
            quantisation_error: qerr,
            step_rad_s: step,
            predicted,
            measured,
            residual_oscillation: residual,
        });
        self.verdict(step, residual, measured.as_ref());
        Ok(())
    }

    fn verdict(&mut self, step: f64, residual: f64, measured: Option<&StepFigures>) {
        let noise = self.report.probe.map_or(0.0, |p| p.noise);
        match measured {
            None => self
                .report
                .problems
                .push("the loop's step was not measured".into()),
            Some(m) if m.rise_time_s.is_none() => self
                .report
                .problems
                .push("the measured step never reached 90% of the reference".into()),
            Some(_) => {}
        }
        if !(residual <= 0.02 * step.abs() + 3.0 * noise) {
            self.report.problems.push(format!(
                "the loop oscillates: {residual:.4} rad/s RMS about its mean over the last third \
                 of the step (more than 2% of the step plus three noise levels)"
            ));
        }
        self.report.usable = self.report.problems.is_empty();
    }
}

use crate::realise;
