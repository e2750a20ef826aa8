//! `fracid sim`: simulate a fractional transfer function on a step, a PRBS or a recorded input.

use crate::bad_input;
use crate::plot::{self, Figure};
use anyhow::{Context, Result};
use fracsim::prbs::{Lfsr, Prbs};
use fracsim::{gl, lsim, ApproxSpec, FracTf, Method};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::io::Write;
use std::path::PathBuf;

/// The paper's model in the frequency domain, simulated when no `--model` is given.
pub const DEFAULT_MODEL: &str = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)";

/// Options of `fracid sim`.
#[derive(Debug, clap::Args)]
pub struct SimArgs {
    /// The model, e.g. "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)"; `exp(-0.001 s)` may be a
    /// factor. Default: the paper's PMSM model.
    #[arg(long, default_value = DEFAULT_MODEL)]
    pub model: String,
    /// Step input of this amplitude (the default input, amplitude 1).
    #[arg(long, num_args = 0..=1, default_missing_value = "1.0", group = "source")]
    pub step: Option<f64>,
    /// PRBS input: the paper's experiment (order 7, 3 ms clock), see --prbs-order and --prbs-clock.
    #[arg(long, group = "source")]
    pub prbs: bool,
    /// Recorded input: a CSV (or .mat) file with columns t,u (see --t-col, --u-col; with --dt, no
    /// time column is read).
    #[arg(long, value_name = "FILE", group = "source")]
    pub input: Option<PathBuf>,
    /// Time column of --input.
    #[arg(long, default_value = "t")]
    pub t_col: String,
    /// Input column of --input.
    #[arg(long, default_value = "u")]
    pub u_col: String,
    /// PRBS register order (2..16): the period is 2^order - 1 bits.
    #[arg(long, default_value_t = 7)]
    pub prbs_order: u32,
    /// PRBS bit duration in seconds (a whole multiple of --dt).
    #[arg(long, default_value_t = 0.003)]
    pub prbs_clock: f64,
    /// PRBS amplitude (levels +-amplitude).
    #[arg(long, default_value_t = 1.0)]
    pub prbs_amplitude: f64,
    /// Sampling step in seconds [default: 1e-4]. With --input, the step of a file with no time
    /// column (otherwise its time column sets it).
    #[arg(long)]
    pub dt: Option<f64>,
    /// End time in seconds (default: 0.05 for a step, one period for a PRBS); at most 1e7
    /// samples of --dt.
    #[arg(long)]
    pub t_end: Option<f64>,
    /// Method. refined (default; Xue's refined Oustaloup), oustaloup or trigeassou
    /// (Poinot-Trigeassou): each fractional operator approximated by that rational filter over
    /// --band with --order, and the whole model discretised exactly for the held input (on the
    /// paper's PMSM and PRBS at 0.5 ms, 0.005% / 0.04% / 0.04% of the output swing RMS from the
    /// exact response). gl: the
    /// Grunwald-Letnikov reference at dt/10 and dt/20 with the input held, Richardson-extrapolated
    /// (no approximation band; the whole memory: at most 10000 samples).
    #[arg(long, default_value = "refined")]
    pub method: String,
    /// Approximation band "w_b,w_h" in rad/s (default: 1e-6/dt to 30 x Nyquist).
    #[arg(long, value_name = "W_B,W_H")]
    pub band: Option<String>,
    /// Approximation order N (2N+1 cells).
    #[arg(long, default_value_t = 8, value_parser = crate::cmd::parse_order)]
    pub order: usize,
    /// Write the CSV (t,u,y) here instead of stdout.
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Plot input and output to this PNG or SVG file.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
}

/// Parse "w_b,w_h" (rad/s).
pub fn parse_band(s: &str) -> Result<(f64, f64)> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [a, b] = parts.as_slice() else {
        bad_input!("--band wants two numbers 'w_b,w_h', got '{s}'");
    };
    let (Ok(w_b), Ok(w_h)) = (a.parse::<f64>(), b.parse::<f64>()) else {
        bad_input!("--band wants two numbers 'w_b,w_h', got '{s}'");
    };
    fracsim::approx::check_band(w_b, w_h)?;
    Ok((w_b, w_h))
}

/// The input signal and its step.
fn build_input(a: &SimArgs) -> Result<(Vec<f64>, f64)> {
    if let Some(path) = &a.input {
        return input_of(path, a);
    }
    let dt = a.dt.unwrap_or(1e-4);
    if !(dt.is_finite() && dt > 0.0) {
        bad_input!("--dt must be a positive number of seconds, got {dt}");
    }
    if a.prbs {
        let prbs = Prbs {
            order: a.prbs_order,
            clock: a.prbs_clock,
            amplitude: a.prbs_amplitude,
            ..Prbs::paper()
        };
        let n = match a.t_end {
            Some(t) => samples_until(t, dt)?,
            None => {
                let period = Lfsr::new(prbs.order, prbs.seed)?.period();
                at_most_max(
                    "one PRBS period",
                    period as f64 * prbs.samples_per_bit(dt)? as f64,
                )?
            }
        };
        return Ok((prbs.samples(dt, n)?, dt));
    }
    let amp = a.step.unwrap_or(1.0);
    if !amp.is_finite() {
        bad_input!("--step amplitude must be finite");
    }
    let n = samples_until(a.t_end.unwrap_or(0.05), dt)?;
    Ok((vec![amp; n], dt))
}

/// The input signal of a file, read by the library's reader (bounded, `.mat` too; with `--dt`
/// no time column): the input column is also read as the "output" column, which is ignored.
fn input_of(path: &std::path::Path, a: &SimArgs) -> Result<(Vec<f64>, f64)> {
    let read = || -> ident::Result<(Vec<f64>, f64)> {
        if ident::matfile::is_mat(path) {
            let vars = ident::matfile::read(path)?;
            return match a.dt {
                Some(dt) => {
                    let [u] = ident::matfile::columns(&vars, [&a.u_col])?;
                    ident::data::Record::from_samples(&u, &u, dt).map(|r| (r.u, r.dt))
                }
                None => {
                    let [t, u] = ident::matfile::columns(&vars, [&a.t_col, &a.u_col])?;
                    ident::data::check_finite(&a.u_col, &u)?;
                    Ok((u, ident::data::sampling_step(&t)?))
                }
            };
        }
        let text = ident::files::read_text(path)?;
        match a.dt {
            Some(dt) => {
                let (_, [u]) = ident::data::read_columns(&text, [&a.u_col])?;
                ident::data::Record::from_samples(&u, &u, dt).map(|r| (r.u, r.dt))
            }
            None => {
                let (_, [t, u]) = ident::data::read_columns(&text, [&a.t_col, &a.u_col])?;
                let dt = ident::data::sampling_step(&t)?;
                ident::data::check_finite(&a.u_col, &u)?;
                Ok((u, dt))
            }
        }
    };
    read().map_err(|e| match e {
        ident::Error::Io { .. } => anyhow::Error::new(e),
        e => anyhow::Error::new(e).context(format!("in {}", path.display())),
    })
}

fn samples_until(t_end: f64, dt: f64) -> Result<usize> {
    if !(t_end.is_finite() && t_end > 0.0) {
        bad_input!("--t-end must be a positive number of seconds, got {t_end}");
    }
    at_most_max("--t-end/--dt", (t_end / dt).round() + 1.0)
}

/// The most samples `fracid sim` makes: 240 MB of memory and a CSV of about 300 MB, which
/// `fracid time` still reads ([`ident::files::MAX_FILE_BYTES`]); 1e8 took 2.3 GB and 25 s.
pub const MAX_SAMPLES: usize = 10_000_000;

/// `n` samples, refused (exit 2, naming `what` asks for them) above [`MAX_SAMPLES`].
fn at_most_max(what: &str, n: f64) -> Result<usize> {
    if n > MAX_SAMPLES as f64 {
        bad_input!(
            "{what} asks for {n:.4e} samples: too many (at most {MAX_SAMPLES:.0e}; a longer --dt or a \
             shorter --t-end)"
        );
    }
    Ok(n as usize)
}

/// Run `fracid sim`.
pub fn run(a: SimArgs) -> Result<()> {
    let inputs: Vec<_> = a.input.iter().map(|p| ("--input", p.as_path())).collect();
    let outputs: Vec<_> = [("-o", &a.output), ("--plot", &a.plot)]
        .into_iter()
        .filter_map(|(what, p)| Some((what, p.as_deref()?)))
        .collect();
    super::paths::check(&inputs, &outputs)?;
    let tf: FracTf = a.model.parse().context("bad --model")?;
    tf.check_proper().context("--model cannot be simulated")?;
    // Every output checked before any is written: a bad plot path must not cost the CSV that
    // -o names (it was overwritten, then the plot refused).
    if let Some(p) = &a.plot {
        plot::format_of(p)?;
        drive::client::check_writable(p)
            .with_context(|| format!("cannot write plot {}", p.display()))?;
    }
    if let Some(p) = &a.output {
        drive::client::check_writable(p)
            .with_context(|| format!("cannot create {}", p.display()))?;
    }
    let (u, dt) = build_input(&a)?;
    let y = if a.method.eq_ignore_ascii_case("gl") {
        gl::simulate_held(&tf, &u, dt, gl::HELD_SUBSTEPS)?
    } else {
        let spec = ApproxSpec {
            method: a.method.parse::<Method>()?,
            band: a.band.as_deref().map(parse_band).transpose()?,
            order: a.order,
        };
        lsim(&tf, &u, dt, &spec)?
    };
    // Time stamps rounded to 1e-12 s so that 0.03 prints as 0.03, not 0.030000000000000002.
    let t: Vec<f64> = (0..u.len())
        .map(|k| (k as f64 * dt * 1e12).round() / 1e12)
        .collect();
    let mut out: Box<dyn Write> = match &a.output {
        Some(p) => Box::new(std::io::BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("cannot create {}", p.display()))?,
        )),
        None => Box::new(std::io::BufWriter::new(std::io::stdout().lock())),
    };
    writeln!(out, "# fracid sim: {tf}, method {}, dt {dt} s", a.method)?;
    writeln!(out, "t,u,y")?;
    for k in 0..u.len() {
        writeln!(out, "{},{},{}", t[k], u[k], y[k])?;
    }
    out.flush()?;
    if let Some(p) = &a.plot {
        let fig = SimFigure {
            title: format!("{tf}"),
            t: &t,
            u: &u,
            y: &y,
        };
        plot::save(p, (1000, 700), &fig)?;
        eprintln!("plot written to {}", p.display());
    }
    Ok(())
}

/// Input and output against time, in two panels.
struct SimFigure<'a> {
    title: String,
    t: &'a [f64],
    u: &'a [f64],
    y: &'a [f64],
}

impl Figure for SimFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let root = root.titled(&self.title, ("sans-serif", 20))?;
        let (top, bottom) = root.split_vertically((root.dim_in_pixel().1 as f64 * 0.35) as u32);
        for (area, data, name, color) in [
            (&top, self.u, "input u", BLUE),
            (&bottom, self.y, "output y", RED),
        ] {
            plot::time_series_chart(
                area,
                &plot::TimeChart {
                    title: None,
                    x_desc: "time [s]",
                    y_desc: Some(name),
                    t: self.t,
                    lines: &[plot::Line {
                        label: Some(name),
                        values: data,
                        style: color.stroke_width(2),
                    }],
                    marker: None,
                    look: plot::Look {
                        caption: 20,
                        labels: Some(14),
                        margin: 10,
                        x_area: 40,
                        y_area: 60,
                    },
                },
            )?;
        }
        Ok(())
    }
}
