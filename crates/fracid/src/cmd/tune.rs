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
use tune::{Controller, GainBound, Plant, Spec};

/// Options of `fracid tune`.
#[derive(Debug, clap::Args)]
pub struct TuneArgs {
    /// The model: a transfer function such as
    /// "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1) exp(-0.001 s)", or a JSON file written by
    /// `fracid time --json` or `fracid freq --json` (the final model: "diagnosis.model" when the
    /// file has one, else "model").
    pub model: String,
    /// The controller: fopi (kp + ki/s^lambda), fopid (+ kd s^mu), pi or pid.
    #[arg(long, default_value = "fopi")]
    pub form: String,
    /// Gain crossover in rad/s.
    #[arg(long)]
    pub wc: f64,
    /// Phase margin in degrees.
    #[arg(long)]
    pub pm: f64,
    /// Flat phase at wc (d arg L / d ln w = 0: the overshoot robust to gain changes).
    #[arg(long)]
    pub flat: bool,
    /// |T(j w)| <= DB at a high frequency W rad/s (noise rejection).
    #[arg(long, value_name = "W,DB")]
    pub t_high: Option<String>,
    /// |S(j w)| <= DB at a low frequency W rad/s (disturbance rejection).
    #[arg(long, value_name = "W,DB")]
    pub s_low: Option<String>,
    /// A fixed integrator order for a fopi without --flat (otherwise the smallest Ms is chosen).
    #[arg(long)]
    pub lambda: Option<f64>,
    /// Sample period of the loop in seconds: the hold's half-sample delay joins the design, and
    /// the controller's discrete realisation is given.
    #[arg(long)]
    pub dt: Option<f64>,
    /// The reference step of the simulated loop, output units.
    #[arg(long, default_value_t = 1.0)]
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
        match InputEffect::from_report(name, param).with_context(|| format!("in {text}"))? {
            Some(fx) => effects.push(fx),
            None if name == "delay" => {}
            None => left.push(name.to_string()),
        }
    }
    Ok((g, effects, left))
}

fn parse_bound(name: &str, s: &str) -> Result<GainBound> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    match parts.as_slice() {
        [w, db] => match (w.parse::<f64>(), db.parse::<f64>()) {
            (Ok(omega), Ok(db)) => Ok(GainBound { omega, db }),
            _ => bad_input!("--{name} must be W,DB (two numbers), got '{s}'"),
        },
        _ => bad_input!("--{name} must be W,DB (rad/s and dB), got '{s}'"),
    }
}

/// The specification the options ask for.
pub fn spec_of(a: &TuneArgs) -> Result<Spec> {
    Ok(Spec {
        form: a.form.parse()?,
        wc: a.wc,
        pm_deg: a.pm,
        flat: a.flat,
        t_high: a
            .t_high
            .as_deref()
            .map(|s| parse_bound("t-high", s))
            .transpose()?,
        s_low: a
            .s_low
            .as_deref()
            .map(|s| parse_bound("s-low", s))
            .transpose()?,
        dt: a.dt,
        lambda: a.lambda,
    })
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
    let spec = spec_of(&a)?;
    let opts = SimOptions {
        step: Some(a.step),
        load: a.load,
        effects,
        u_limit: a.u_limit,
    };
    if a.u_limit.is_some_and(|v| !(v.is_finite() && v > 0.0)) {
        crate::bad_input!("--u-limit must be a positive number, got {:?}", a.u_limit);
    }
    let (report, runs) = tune::report::tune(&g, &spec, &opts)?;
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

fn params_line(c: &Controller) -> String {
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
    let l = &r.loop_;
    let _ = writeln!(
        o,
        "loop:       wc = {:.4} rad/s, pm = {:.3} deg, gm = {}, Ms = {:.4} (at {:.1} rad/s), \
         d arg L/d ln w at wc = {:.2e} rad",
        l.wc,
        l.pm_deg,
        l.gm_db.map_or("inf".into(), |g| format!("{g:.2} dB")),
        l.ms,
        l.ms_omega,
        l.phase_slope
    );
    if let Some(d) = &r.discrete {
        let _ = writeln!(
            o,
            "discrete:   {} states at dt = {} s ({} N = {}, band [{:.3e}, {:.3e}] rad/s); \
             sampled loop: {}",
            d.states,
            d.dt,
            d.approximation.method,
            d.approximation.order,
            d.approximation.band[0],
            d.approximation.band[1],
            d.sampled_loop
                .map_or("no crossover near wc".into(), |m| format!(
                    "wc = {:.3} rad/s, pm = {:.2} deg",
                    m.wc, m.pm_deg
                ))
        );
    }
    match (&r.step.metrics, &r.step.not_simulated) {
        (Some(m), _) => {
            let _ = writeln!(
                o,
                "step:       overshoot {:.2}%, rise (10-90%) {} s, settling (2%) {} s; load step {} \
                 at t = {:.4} s: peak {:.4}, left {:.2e}",
                m.overshoot_percent,
                opt(m.rise_time, ""),
                opt(m.settling_time, ""),
                r.step.setup.load,
                r.step.setup.t_load,
                m.load_peak,
                m.load_residual
            );
        }
        (None, why) => {
            let _ = writeln!(
                o,
                "step:       not simulated ({})",
                why.as_deref().unwrap_or("-")
            );
        }
    }
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
