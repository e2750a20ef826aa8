//! `fracid tune MODEL`: a fractional PI/PID (or integer PI/PID) designed on a model for a gain
//! crossover, a phase margin and a flat phase (the `tune` crate); its discrete realisation, its
//! closed loop simulated, the integer PI beside it. Parse, call the library, present.

use crate::bad_input;
use crate::plot::{self, Figure, Line, Look, TimeChart};
use anyhow::{Context, Result};
use fracsim::FracTf;
use plotters::coord::Shift;
use plotters::prelude::*;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::PathBuf;
use tune::closed::InputEffect;
use tune::report::{Report, Runs, SimOptions};
use tune::{Controller, Form, GainBound, Plant, TuneRequest};

/// Options of `fracid tune`.
#[derive(Debug, clap::Args)]
pub struct TuneArgs {
    /// The model: a transfer function such as
    /// "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1) exp(-0.001 s)", or a JSON file written by
    /// `fracid time --json` or `fracid freq --json` (the final model: "diagnosis.model" when the
    /// file has one, else "model").
    pub model: String,
    /// The controller: fopi (kp + ki/s^lambda), fopid (+ kd s^mu), fopd (kp + kd s^mu), pi or
    /// pid.
    #[arg(long, default_value_t = TuneRequest::default().form)]
    pub form: Form,
    /// Gain crossover in rad/s (with --analyse: where to centre the analysis, optional).
    #[arg(long)]
    pub wc: Option<f64>,
    /// Phase margin in degrees (not with --analyse).
    #[arg(long)]
    pub pm: Option<f64>,
    /// Analyse this controller instead of designing one: its text as `fracid tune` prints it,
    /// "(kd s^(lambda+mu) + kp s^lambda + ki)/(s^lambda)" or "kp + ki/s^lambda", or a
    /// `fracid tune --json` report. Stability, margins, Ms, the sampled loop with --dt, the floors
    /// it misses (exit 1 when it misses any, after the report).
    #[arg(long, value_name = "C")]
    pub analyse: Option<String>,
    /// Flat phase at wc (d arg L / d ln w = 0: the overshoot robust to gain changes).
    #[arg(long)]
    pub flat: bool,
    /// |T(j w)| <= DB for every w >= W rad/s (noise rejection over the band above W).
    #[arg(long, value_name = "W,DB", value_parser = parse_bound)]
    pub t_high: Option<GainBound>,
    /// |S(j w)| <= DB for every w <= W rad/s (disturbance rejection over the band below W).
    #[arg(long, value_name = "W,DB", value_parser = parse_bound)]
    pub s_low: Option<GainBound>,
    /// Robustness floor: the largest sensitivity peak Ms accepted (a design above it is refused).
    #[arg(long, default_value_t = TuneRequest::default().max_ms)]
    pub max_ms: f64,
    /// Robustness floor: the smallest gain margin accepted, dB (up, and down for a
    /// conditionally stable loop).
    #[arg(long, default_value_t = TuneRequest::default().min_gm)]
    pub min_gm: f64,
    /// Robustness floor: the smallest integrator order accepted (integral action); 0 accepts a
    /// fractional integrator of any order.
    #[arg(long, default_value_t = TuneRequest::default().min_lambda)]
    pub min_lambda: f64,
    /// A fixed integrator order: a fopi's without --flat, a fopid's (otherwise searched for the
    /// smallest Ms).
    #[arg(long)]
    pub lambda: Option<f64>,
    /// A fixed differentiator order: a fopid's, a fopd's without --flat.
    #[arg(long)]
    pub mu: Option<f64>,
    /// The largest integrator order searched (fopi, fopid).
    #[arg(long)]
    pub max_lambda: Option<f64>,
    /// The largest differentiator order searched (fopid, fopd).
    #[arg(long)]
    pub max_mu: Option<f64>,
    /// Sample period of the loop in seconds: the hold's half-sample delay joins the design, and
    /// the controller's discrete realisation is given.
    #[arg(long)]
    pub dt: Option<f64>,
    /// The reference step of the simulated loop, output units.
    #[arg(long, default_value_t = TuneRequest::default().step)]
    pub step: f64,
    /// The load step at the plant's input, input units (default: the input that holds the
    /// reference step, step / G(0)).
    #[arg(long)]
    pub load: Option<f64>,
    /// The voltage limit on the controller's output in the simulated loops, input units: the
    /// output is clamped there with anti-windup, as the drive does (`fracid drive loop`).
    #[arg(long)]
    pub u_limit: Option<f64>,
    /// Write the report as JSON to stdout instead of text.
    #[arg(long)]
    pub json: bool,
    /// Save a figure (Bode and Nichols of L, the closed-loop reference and load steps, the
    /// integer PI beside the design) to this .png or .svg file.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
}

/// The final model of `text` and its input effects: a JSON report's final model (as
/// [`model_in`](super::model_in) reads it) with the diagnosis's kept effects, or a transfer
/// function.
pub(crate) fn load_model(text: &str) -> Result<(FracTf, Vec<InputEffect>, Vec<String>)> {
    let super::model_in::Loaded { tf: g, report } = super::model_in::load(text)?;
    let diag = report
        .as_ref()
        .and_then(|v| v.get("diagnosis"))
        .filter(|d| d.get("model").is_some());
    let (mut effects, mut left) = (Vec::new(), Vec::new());
    let kept = diag
        .and_then(|d| d.get("effects"))
        .and_then(Value::as_array)
        .cloned()
        .unwrap_or_default();
    for e in &kept {
        let Some(name) = e.get("name").and_then(Value::as_str) else {
            continue;
        };
        let param = |k: &str| {
            e.get("params")
                .and_then(|p| p.get(k))
                .and_then(Value::as_f64)
        };
        let sampled = e.get("sampled").and_then(Value::as_bool).unwrap_or(false);
        match InputEffect::from_report(name, param, sampled)
            .with_context(|| format!("in {text}"))?
        {
            Some(fx) => effects.push(fx),
            None if name == "delay" => {}
            None => left.push(name.to_string()),
        }
    }
    Ok((g, effects, left))
}

/// `W,DB` (rad/s and dB) as a bound, parsed by clap (exit 2 with the reason).
fn parse_bound(s: &str) -> std::result::Result<GainBound, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    match parts.as_slice() {
        [w, db] => match (w.parse::<f64>(), db.parse::<f64>()) {
            (Ok(omega), Ok(db)) => Ok(GainBound { omega, db }),
            _ => Err(format!("must be W,DB (two numbers), got '{s}'")),
        },
        _ => Err(format!("must be W,DB (rad/s and dB), got '{s}'")),
    }
}

/// The request the options ask for (the library checks it).
pub fn request(a: &TuneArgs) -> TuneRequest {
    TuneRequest {
        form: a.form,
        wc: a.wc,
        pm: a.pm,
        flat: a.flat,
        t_high: a.t_high,
        s_low: a.s_low,
        max_ms: a.max_ms,
        min_gm: a.min_gm,
        min_lambda: a.min_lambda,
        lambda: a.lambda,
        mu: a.mu,
        max_lambda: a.max_lambda,
        max_mu: a.max_mu,
        dt: a.dt,
        step: a.step,
        load: a.load,
        u_limit: a.u_limit,
    }
}

/// Run `fracid tune`.
pub fn run(a: TuneArgs) -> Result<()> {
    let model: Vec<_> = super::paths::file_arg(&a.model)
        .map(|p| ("the model", p))
        .into_iter()
        .collect();
    let plot: Vec<_> = a.plot.iter().map(|p| ("--plot", p.as_path())).collect();
    super::paths::check(&model, &plot)?;
    if let Some(p) = &a.plot {
        plot::format_of(p)?;
    }
    let (g, effects, left) = load_model(&a.model)?;
    for name in &left {
        eprintln!(
            "note: the model's effect '{name}' acts on the output, not in the loop: not simulated"
        );
    }
    let req = request(&a);
    if let Some(c) = &a.analyse {
        let opts = req.sim_options(effects)?;
        return run_analysis(&a, &g, &given_controller(c)?, &opts);
    }
    if a.wc.is_none() || a.pm.is_none() {
        bad_input!("a design needs --wc and --pm (or --analyse C to analyse a given controller)");
    }
    let (report, runs) = tune::request::run(&g, &req, effects)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", text(&report));
    }
    if let Some(p) = &a.plot {
        plot::save(
            p,
            (1400, 1000),
            &TuneFigure {
                g: &g,
                r: &report,
                runs: &runs,
            },
        )?;
    }
    Ok(())
}

/// The controller of `--analyse`: a `fracid tune --json` report's `params`, or a transfer
/// function of the form `fracid tune` prints (`tune::Controller::from_tf`), as text or in a file.
fn given_controller(arg: &str) -> Result<Controller> {
    let super::model_in::Loaded { tf, report } = super::model_in::load(arg)?;
    if let Some(p) = report.as_ref().and_then(|v| v.get("params")) {
        match serde_json::from_value::<Controller>(p.clone()) {
            Ok(c) => return Ok(c),
            Err(e) => bad_input!("{arg}: \"params\" is not a controller: {e}"),
        }
    }
    match Controller::from_tf(&tf) {
        Some(c) => Ok(c),
        None => bad_input!(
            "--analyse {arg:?}: not a controller (kd s^(lambda+mu) + kp s^lambda + ki)/s^lambda \
             with 0 < lambda < 2"
        ),
    }
}

/// `--analyse`: the given controller's loop on the model, in words or JSON; exit 1 (after the
/// report) when it misses stability or a floor.
fn run_analysis(a: &TuneArgs, g: &FracTf, c: &Controller, opts: &SimOptions) -> Result<()> {
    let design_only = [a.lambda, a.mu, a.max_lambda, a.max_mu, a.pm];
    if design_only.iter().any(Option::is_some)
        || a.flat
        || a.t_high.is_some()
        || a.s_low.is_some()
        || a.plot.is_some()
    {
        bad_input!("--analyse takes --wc, --dt, the floors and the simulation's options only");
    }
    let floors = request(a).floors();
    let (r, _) = tune::given::analyse_given(g, c, a.wc, a.dt, floors, opts)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        let mut o = String::new();
        let _ = writeln!(o, "model:      {}", r.model.text);
        let _ = writeln!(o, "controller: C(s) = {}", r.controller.text);
        let _ = writeln!(o, "            {}", params_line(&r.params));
        let _ = write!(o, "{}", loop_lines(&r.loop_));
        if let Some(d) = &r.discrete {
            let _ = write!(o, "{}", discrete_line(d));
        }
        let _ = write!(o, "{}", step_line(&r.step));
        let _ = writeln!(
            o,
            "verdict:    {}",
            if r.misses.is_empty() {
                "stable, every floor met".to_string()
            } else {
                r.misses.join("; ")
            }
        );
        print!("{o}");
    }
    if r.misses.is_empty() {
        Ok(())
    } else {
        Err(tune::Error::Unsafe(r.misses.join("; ")).into())
    }
}

fn params_line(c: &Controller) -> String {
    if c.ki == 0.0 {
        return format!("kp = {:.6e}, kd = {:.6e}, mu = {:.4}", c.kp, c.kd, c.mu);
    }
    let mut s = format!(
        "kp = {:.6e}, ki = {:.6e}, lambda = {:.4}",
        c.kp, c.ki, c.lambda
    );
    if c.kd != 0.0 {
        let _ = write!(s, ", kd = {:.6e}, mu = {:.4}", c.kd, c.mu);
    }
    s
}

fn opt(v: Option<f64>, unit: &str) -> String {
    v.map_or("-".into(), |v| format!("{v:.4}{unit}"))
}

/// The `loop:` and `stability:` lines.
fn loop_lines(l: &tune::LoopMetrics) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "loop:       wc = {:.4} rad/s, pm = {:.3} deg, gm = {}{}, Ms = {:.4} (at {:.1} rad/s), \
         d arg L/d ln w at wc = {:.2e} rad",
        l.wc,
        l.pm_deg,
        l.gm_db.map_or("inf".into(), |g| format!("{g:.2} dB")),
        l.gm_low_db
            .map_or(String::new(), |g| format!(" (down: {g:.2} dB)")),
        l.ms,
        l.ms_omega,
        l.phase_slope
    );
    let _ = writeln!(
        o,
        "stability:  {}; the model has {}",
        match (&l.stability_note, l.unstable_poles) {
            (Some(n), _) => format!("not counted ({n})"),
            (None, k) =>
                format!("{k} closed-loop poles in the right half-plane (characteristic equation)"),
        },
        match l.plant_unstable_poles {
            0 => "none of its own".to_string(),
            n if n > 0 => format!("{n} of its own"),
            _ => "an uncounted number of its own".to_string(),
        }
    );
    if l.crossovers > 1 {
        let _ = writeln!(
            o,
            "            {} crossovers: {}",
            l.crossovers,
            l.crossover_omegas
                .iter()
                .map(|w| format!("{w:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    o
}

/// The `discrete:` line (and its note).
fn discrete_line(d: &tune::report::DiscreteJson) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "discrete:   {} states at dt = {} s ({} N = {}, band [{:.3e}, {:.3e}] rad/s); \
         sampled loop: {}",
        d.ss.states,
        d.dt(),
        d.ss.approximation.method,
        d.ss.approximation.order,
        d.ss.approximation.band[0],
        d.ss.approximation.band[1],
        d.sampled_loop
            .as_ref()
            .map_or("not evaluated".into(), |m| format!(
                "wc = {:.3} rad/s, pm = {:.2} deg, gm = {}, Ms = {:.4}, {} closed-loop poles \
                 outside the unit circle",
                m.wc,
                m.pm_deg,
                m.gm_db.map_or("inf".into(), |g| format!("{g:.2} dB")),
                m.ms,
                m.unstable_poles
            ))
    );
    if let Some(n) = &d.sampled_note {
        let _ = writeln!(o, "            note: {n}");
    }
    o
}

/// The `step:` line.
fn step_line(st: &tune::report::StepJson) -> String {
    match (&st.metrics, &st.not_simulated) {
        (Some(m), _) => format!(
            "step:       overshoot {:.2}%, rise (10-90%) {} s, settling (2%) {} s; load step {} \
             at t = {:.4} s: peak {:.4}, left {:.2e}\n",
            m.overshoot_percent,
            opt(m.rise_time, ""),
            opt(m.settling_time, ""),
            st.setup.load,
            st.setup.t_load,
            m.load_peak,
            m.load_residual
        ),
        (None, why) => format!(
            "step:       not simulated ({})\n",
            why.as_deref().unwrap_or("-")
        ),
    }
}

/// The report in words.
pub fn text(r: &Report) -> String {
    let mut o = String::new();
    let s = &r.spec;
    let _ = writeln!(o, "model:      {}", r.model.text);
    let _ = writeln!(
        o,
        "spec:       {} for wc = {} rad/s, pm = {} deg{}{}",
        s.form.name(),
        s.wc,
        s.pm_deg,
        if s.flat { ", flat phase" } else { "" },
        s.dt.map_or(String::new(), |dt| format!(
            ", sampled every {dt} s (hold delay dt/2 in the design)"
        ))
    );
    let _ = writeln!(o, "controller: C(s) = {}", r.controller.text);
    let _ = writeln!(o, "            {}", params_line(&r.params));
    let _ = write!(o, "{}", loop_lines(&r.loop_));
    if let Some(d) = &r.discrete {
        let _ = write!(o, "{}", discrete_line(d));
    }
    let _ = write!(o, "{}", step_line(&r.step));
    if let Some(m) = &r.step_with_effects {
        let names: Vec<String> = r.effects.iter().map(|e| format!("{e:?}")).collect();
        let _ = writeln!(
            o,
            "effects:    {}: overshoot {:.2}%, rise {} s, settling {} s; load peak {:.4}, left {:.2e}",
            names.join(", "),
            m.overshoot_percent,
            opt(m.rise_time, ""),
            opt(m.settling_time, ""),
            m.load_peak,
            m.load_residual
        );
    }
    match (
        &r.integer_pi.params,
        &r.integer_pi.loop_,
        &r.integer_pi.step,
    ) {
        (Some(c), Some(l), None) => {
            let _ = writeln!(
                o,
                "integer PI: {}; Ms = {:.4}, gm = {} (not simulated)",
                params_line(c),
                l.ms,
                l.gm_db.map_or("inf".into(), |g| format!("{g:.2} dB")),
            );
        }
        (Some(c), Some(l), Some(m)) => {
            let _ = writeln!(
                o,
                "integer PI: {}; Ms = {:.4}, gm = {}; overshoot {:.2}%, rise {} s, load peak {:.4}",
                params_line(c),
                l.ms,
                l.gm_db.map_or("inf".into(), |g| format!("{g:.2} dB")),
                m.overshoot_percent,
                opt(m.rise_time, ""),
                m.load_peak
            );
        }
        _ => {
            let _ = writeln!(
                o,
                "integer PI: none ({})",
                r.integer_pi.refused.as_deref().unwrap_or("-")
            );
        }
    }
    o
}

/// The figure of `--plot`.
struct TuneFigure<'a> {
    g: &'a FracTf,
    r: &'a Report,
    runs: &'a Runs,
}

/// `|L|` in dB and its phase in degrees, unwrapped along the grid.
fn loop_curves(p: &Plant, c: &Controller, omega: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut mag = Vec::with_capacity(omega.len());
    let mut ph = Vec::with_capacity(omega.len());
    let mut prev: Option<(num_complex::Complex64, f64)> = None;
    for &w in omega {
        let l = tune::analysis::loop_response(p, c, w);
        let phase = match prev {
            None => p.phase_unwrapped(w) + (c.freq_response(w)).arg(),
            Some((lp, php)) => php + (l / lp).arg(),
        };
        prev = Some((l, phase));
        mag.push(20.0 * l.norm().log10());
        ph.push(phase.to_degrees());
    }
    (mag, ph)
}

/// One controller's open loop on the frequency grid: its name, `|L|` (dB) and `arg L` (deg), and
/// its line style.
struct LoopCurve {
    name: String,
    mag_db: Vec<f64>,
    phase_deg: Vec<f64>,
    style: ShapeStyle,
}

impl TuneFigure<'_> {
    /// The designed controller's loop, then the integer PI's when there is one.
    fn loop_curves(&self, omega: &[f64]) -> Vec<LoopCurve> {
        let plant = Plant::new(self.g.clone(), self.r.spec.dt);
        let curve = |name: String, c: &Controller, style: ShapeStyle| {
            let (mag_db, phase_deg) = loop_curves(&plant, c, omega);
            LoopCurve {
                name,
                mag_db,
                phase_deg,
                style,
            }
        };
        let mut curves = vec![curve(
            self.r.spec.form.name().to_uppercase(),
            &self.r.params,
            BLUE.stroke_width(2),
        )];
        if let Some(c) = &self.runs.pi_controller {
            curves.push(curve("integer PI".into(), c, RED.stroke_width(2)));
        }
        curves
    }

    /// The Bode magnitude (`is_mag`) or phase of the loops, with the 0 dB / -180 deg guide.
    fn bode_panel<DB: DrawingBackend>(
        area: &DrawingArea<DB, Shift>,
        is_mag: bool,
        omega: &[f64],
        curves: &[LoopCurve],
    ) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("drawing failed: {e}");
        fn ys(c: &LoopCurve, is_mag: bool) -> &[f64] {
            if is_mag {
                &c.mag_db
            } else {
                &c.phase_deg
            }
        }
        let (lo, hi) = plot::range_of(curves.iter().flat_map(|c| ys(c, is_mag).iter()));
        let (title, guide) = if is_mag {
            ("|L(jw)| (dB)", 0.0)
        } else {
            ("arg L(jw) (deg)", -180.0)
        };
        let (w_lo, w_hi) = (omega[0], omega[omega.len() - 1]);
        let mut ch = ChartBuilder::on(area)
            .caption(title, FONT)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d((w_lo..w_hi).log_scale(), lo..hi)
            .map_err(e)?;
        ch.configure_mesh()
            .x_desc("omega (rad/s)")
            .label_style(SMALL)
            .draw()
            .map_err(e)?;
        if guide > lo && guide < hi {
            ch.draw_series(std::iter::once(PathElement::new(
                vec![(w_lo, guide), (w_hi, guide)],
                BLACK.mix(0.4),
            )))
            .map_err(e)?;
        }
        for c in curves {
            ch.draw_series(LineSeries::new(
                omega.iter().copied().zip(ys(c, is_mag).iter().copied()),
                c.style,
            ))
            .map_err(e)?
            .label(c.name.as_str())
            .legend(plot::line_legend(c.style, 20));
        }
        ch.configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(SMALL)
            .draw()
            .map_err(e)?;
        Ok(())
    }

    /// The Nichols chart: the loops' gain against their phase, and the critical point.
    fn nichols_panel<DB: DrawingBackend>(
        area: &DrawingArea<DB, Shift>,
        curves: &[LoopCurve],
    ) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("drawing failed: {e}");
        let (plo, phi) = plot::range_of(curves.iter().flat_map(|c| c.phase_deg.iter()));
        let (mlo, mhi) = plot::range_of(curves.iter().flat_map(|c| c.mag_db.iter()));
        let mut ch = ChartBuilder::on(area)
            .caption("Nichols: |L| (dB) against arg L (deg)", FONT)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(plo.max(-540.0)..phi, mlo.max(-60.0)..mhi.min(60.0))
            .map_err(e)?;
        ch.configure_mesh()
            .x_desc("arg L (deg)")
            .label_style(SMALL)
            .draw()
            .map_err(e)?;
        for c in curves {
            ch.draw_series(LineSeries::new(
                c.phase_deg.iter().copied().zip(c.mag_db.iter().copied()),
                c.style,
            ))
            .map_err(e)?
            .label(c.name.as_str())
            .legend(plot::line_legend(c.style, 20));
        }
        ch.draw_series(std::iter::once(Circle::new(
            (-180.0, 0.0),
            5,
            BLACK.filled(),
        )))
        .map_err(e)?;
        Ok(())
    }

    /// The closed loop: the reference step then the load step, for the design (alone and with
    /// the model's effects) and the integer PI. Nothing when there is no design run.
    fn step_panel<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let Some(run) = &self.runs.design else {
            return Ok(());
        };
        let mut lines = vec![
            Line {
                label: Some("reference"),
                values: &run.r,
                style: BLACK.mix(0.5).stroke_width(1),
            },
            Line {
                label: Some("y, design"),
                values: &run.y,
                style: BLUE.stroke_width(2),
            },
        ];
        if let Some(fx) = &self.runs.with_effects {
            lines.push(Line {
                label: Some("y, design with the model's effects"),
                values: &fx.y,
                style: BLUE.mix(0.5).stroke_width(1),
            });
        }
        if let Some(pi) = &self.runs.pi {
            lines.push(Line {
                label: Some("y, integer PI"),
                values: &pi.y,
                style: RED.stroke_width(2),
            });
        }
        plot::time_series_chart(
            area,
            &TimeChart {
                title: Some("closed loop: reference step, then load step"),
                x_desc: "t (s)",
                y_desc: None,
                t: &run.t,
                lines: &lines,
                marker: Some((self.r.step.setup.t_load, "load step", GREEN.stroke_width(1))),
                look: Look {
                    caption: 20,
                    labels: Some(15),
                    margin: 12,
                    x_area: 40,
                    y_area: 60,
                },
            },
        )
    }
}

/// The panels' caption font.
const FONT: (&str, u32) = ("sans-serif", 20);
/// The panels' label font.
const SMALL: (&str, u32) = ("sans-serif", 15);

impl Figure for TuneFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let wc = self.r.spec.wc;
        let omega: Vec<f64> = (0..=400)
            .map(|i| wc * 10f64.powf(-2.0 + 4.0 * i as f64 / 400.0))
            .collect();
        let curves = self.loop_curves(&omega);
        let panels = root.split_evenly((2, 2));
        Self::bode_panel(&panels[0], true, &omega, &curves)?;
        Self::bode_panel(&panels[1], false, &omega, &curves)?;
        Self::nichols_panel(&panels[2], &curves)?;
        self.step_panel(&panels[3])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args_from(argv: &[&str]) -> std::result::Result<TuneArgs, clap::Error> {
        #[derive(clap::Parser)]
        struct Words {
            #[command(flatten)]
            args: TuneArgs,
        }
        use clap::Parser as _;
        Words::try_parse_from(argv).map(|w| w.args)
    }

    #[test]
    fn the_flags_defaults_are_the_requests() {
        let a = args_from(&["tune", "1/(s + 1)", "--wc", "3", "--pm", "60"]).unwrap();
        assert_eq!(
            request(&a),
            TuneRequest {
                wc: Some(3.0),
                pm: Some(60.0),
                ..TuneRequest::default()
            }
        );
    }

    #[test]
    fn bounds_and_forms_are_parsed_at_the_edge() {
        let a = args_from(&[
            "tune",
            "M",
            "--form",
            "FOPID",
            "--t-high",
            "3000, -10",
            "--u-limit",
            "24",
        ])
        .unwrap();
        let r = request(&a);
        assert_eq!(r.form, Form::Fopid);
        assert_eq!(
            r.t_high,
            Some(GainBound {
                omega: 3000.0,
                db: -10.0
            })
        );
        assert_eq!(r.u_limit, Some(24.0));
        for bad in [["--t-high", "3000"], ["--s-low", "a,b"], ["--form", "pd"]] {
            let e = args_from(&["tune", "M", bad[0], bad[1]]).unwrap_err();
            assert_eq!(e.exit_code(), 2, "{bad:?}: {e}");
        }
    }
}
