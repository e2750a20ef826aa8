//! The whole of `fracid tune`'s answer as one serialisable report (the CLI's `--json` and
//! Python's `fracid.tune` give the same document).

use crate::closed::{self, InputEffect, LoopRun, LoopSetup, StepMetrics};
use crate::controller::Controller;
use crate::design::{design, Design};
use crate::error::Result;
use crate::realise;
use crate::spec::Spec;
use crate::{Form, LoopMetrics};
use fracsim::export::StateSpace;
use fracsim::json::{ModelReport, StateSpaceJson};
use fracsim::{ApproxSpec, FracTf};
use serde::Serialize;

/// The discrete realisation `x_(k+1) = A x_k + B e_k`, `u_k = C x_k + D e_k`: the state space
/// as `fracid export` writes it ([`StateSpaceJson`]), and the sampled loop it makes.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiscreteJson {
    /// The realisation (its `model` is the controller's text).
    #[serde(flatten)]
    pub ss: StateSpaceJson,
    /// The sampled loop the drive runs: this realisation with the model discretised for the
    /// held input ([`crate::sampled`]), judged like the continuous one (stability, crossovers,
    /// margins, Ms); the design is refused when it misses the specification or a floor.
    pub sampled_loop: Option<LoopMetrics>,
    /// Caveats of the sampled loop's evaluation.
    pub sampled_note: Option<String>,
}

impl DiscreteJson {
    /// The sample period, s.
    pub fn dt(&self) -> f64 {
        self.ss.dt.unwrap_or(f64::NAN)
    }
}

/// The closed loop's simulated responses, summarised.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepJson {
    /// What was simulated.
    pub setup: LoopSetup,
    /// The reference step's and the load step's figures (`None`: not simulated).
    pub metrics: Option<StepMetrics>,
    /// Why the loop could not be simulated (the simulator's limits on the model, such as more
    /// than one free integrator): the design stands, its simulation is missing.
    pub not_simulated: Option<String>,
}

/// The integer PI for the same `wc` and `pm`, beside the design.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// Its gains (`lambda = 1`).
    pub params: Option<Controller>,
    /// Its loop.
    #[serde(rename = "loop")]
    pub loop_: Option<LoopMetrics>,
    /// Its simulated responses (same setup).
    pub step: Option<StepMetrics>,
    /// Why there is none.
    pub refused: Option<String>,
}

/// The report of `fracid tune`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// The model designed on, in the model JSON's format (`fracsim::json::ModelReport`).
    pub model: ModelReport,
    /// The request.
    pub spec: Spec,
    /// `C(s)` as `{num, den, delay, text}`, the model JSON's format.
    pub controller: ModelReport,
    /// Its gains and orders.
    pub params: Controller,
    /// The continuous loop (with the hold's half-sample delay for `--dt`).
    #[serde(rename = "loop")]
    pub loop_: LoopMetrics,
    /// The discrete realisation (with `--dt`).
    pub discrete: Option<DiscreteJson>,
    /// The closed loop simulated (linear).
    pub step: StepJson,
    /// The input effects of the model's diagnosis, simulated in the loop.
    pub effects: Vec<InputEffect>,
    /// The closed loop simulated with those effects (`None` without effects).
    pub step_with_effects: Option<StepMetrics>,
    /// The integer PI for the same wc and pm.
    pub integer_pi: Comparison,
}

/// The signals behind a report, for plots.
#[derive(Debug, Clone, PartialEq)]
pub struct Runs {
    /// The designed loop's run (`None`: not simulated).
    pub design: Option<LoopRun>,
    /// The designed loop with the model's input effects, if it has any.
    pub with_effects: Option<LoopRun>,
    /// The integer PI's run, if it exists.
    pub pi: Option<LoopRun>,
    /// The integer PI, if it exists.
    pub pi_controller: Option<Controller>,
}

/// What the simulations use beyond the specification.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SimOptions {
    /// The reference step (default 1, output units).
    pub step: Option<f64>,
    /// The load step at the plant's input (default: the input that holds the reference step,
    /// `step / G(0)`; `step` for a model that integrates).
    pub load: Option<f64>,
    /// The model's input effects (from its diagnosis).
    pub effects: Vec<InputEffect>,
    /// The voltage limit on the controller's output in the simulations, input units, with
    /// anti-windup (`None`: none, unless a saturation effect sets one).
    pub u_limit: Option<f64>,
}

/// Design, realise, simulate and compare: the report and its signals.
///
/// # Errors
/// Those of [`design`], of the realisation and of the simulation.
pub fn tune(model: &FracTf, spec: &Spec, opts: &SimOptions) -> Result<(Report, Runs)> {
    let approx = ApproxSpec::default();
    let Design {
        controller: c,
        metrics,
        sampled,
        sampled_note,
    } = design(model, spec)?;
    let discrete = match spec.dt {
        Some(dt) => Some(DiscreteJson {
            sampled_loop: sampled,
            sampled_note,
            ..discrete_json(&realise::discrete(&c, dt, &approx)?, &c)?
        }),
        None => None,
    };
    let setup = setup_of(model, spec.wc, spec.dt, opts)?;
    let (step, run, with_effects) = simulate_loop(model, &c, &setup, opts)?;
    let pi_spec = Spec {
        form: Form::Pi,
        flat: false,
        lambda: None,
        t_high: None,
        s_low: None,
        ..spec.clone()
    };
    let (integer_pi, pi_run, pi_c) = match design(model, &pi_spec) {
        Ok(d) => {
            let (r, _) = tolerate(closed::simulate(model, &d.controller, &setup, &approx, &[]))?;
            (
                Comparison {
                    params: Some(d.controller),
                    loop_: Some(d.metrics),
                    step: r.as_ref().map(|r| closed::metrics(r, &setup)),
                    refused: None,
                },
                r,
                Some(d.controller),
            )
        }
        Err(e) => (
            Comparison {
                params: None,
                loop_: None,
                step: None,
                refused: Some(e.to_string()),
            },
            None,
            None,
        ),
    };
    let report = Report {
        model: model.into(),
        spec: spec.clone(),
        controller: (&c.tf()?).into(),
        params: c,
        loop_: metrics,
        discrete,
        step,
        effects: opts.effects.clone(),
        step_with_effects: with_effects.as_ref().map(|r| closed::metrics(r, &setup)),
        integer_pi,
    };
    Ok((
        report,
        Runs {
            design: run,
            with_effects,
            pi: pi_run,
            pi_controller: pi_c,
        },
    ))
}

/// The closed-loop simulation's setup for a crossover `wc` (module docs of [`closed`]), with the
/// options' steps.
///
/// # Errors
/// A step that is not finite and nonzero, a load that is not finite.
pub fn setup_of(model: &FracTf, wc: f64, dt: Option<f64>, opts: &SimOptions) -> Result<LoopSetup> {
    let mut setup = LoopSetup::for_crossover(wc, dt);
    setup.step = opts.step.unwrap_or(1.0);
    setup.u_limit = opts.u_limit;
    let k0 = model.dc_gain();
    setup.load = opts.load.unwrap_or(if k0.is_finite() && k0 != 0.0 {
        setup.step / k0
    } else {
        setup.step
    });
    if !(setup.step.is_finite() && setup.step != 0.0 && setup.load.is_finite()) {
        return crate::error::invalid(
            "step",
            format!(
                "the reference step ({}) must be finite and nonzero, the load ({}) finite",
                setup.step, setup.load
            ),
        );
    }
    Ok(setup)
}

/// The loop of `c` simulated alone and with the options' effects: the summary and the runs.
///
/// # Errors
/// Those of the simulation but the simulator's limits on the model (see `tolerate`).
pub fn simulate_loop(
    model: &FracTf,
    c: &Controller,
    setup: &LoopSetup,
    opts: &SimOptions,
) -> Result<(StepJson, Option<LoopRun>, Option<LoopRun>)> {
    let approx = ApproxSpec::default();
    let (run, not_simulated) = tolerate(closed::simulate(model, c, setup, &approx, &[]))?;
    let with_effects = if opts.effects.is_empty() || run.is_none() {
        None
    } else {
        Some(closed::simulate(model, c, setup, &approx, &opts.effects)?)
    };
    let step = StepJson {
        setup: *setup,
        metrics: run.as_ref().map(|r| closed::metrics(r, setup)),
        not_simulated,
    };
    Ok((step, run, with_effects))
}

/// A simulation the simulator cannot run on this model (its errors, not a bad request) leaves the
/// design standing: the run is `None` with the reason.
fn tolerate(r: Result<LoopRun>) -> Result<(Option<LoopRun>, Option<String>)> {
    match r {
        Ok(r) => Ok((Some(r), None)),
        Err(crate::Error::Sim(e)) => Ok((None, Some(e.to_string()))),
        Err(e) => Err(e),
    }
}

pub(crate) fn discrete_json(ss: &StateSpace, c: &Controller) -> Result<DiscreteJson> {
    Ok(DiscreteJson {
        ss: ss.to_json(&c.tf()?.to_string()),
        sampled_loop: None,
        sampled_note: None,
    })
}
