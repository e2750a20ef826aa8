//! `--diagnose` for `fracid time` and `fracid freq`: the readable report, the docs/design.md §7
//! `diagnosis` JSON object, and the residual before/after plot. The subcommands call these.

use crate::plot::{self, Figure};
use anyhow::Result;
use ident::data::Record;
use ident::diagnose::freq::BodeDiagnosis;
use ident::diagnose::structures::StructureChoice;
use ident::diagnose::Diagnosis;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Write;
use std::path::{Path, PathBuf};

fn fit_row(f: &ident::metrics::Fit) -> String {
    format!("RMSE {:.4e}, fit {:.2}%", f.rmse, f.nrmse_percent)
}

/// The structure comparison in words: of the final models (`diagnosed`, `--diagnose`) or of the
/// base fits (`--structure auto`).
pub fn structures_text(c: &StructureChoice, diagnosed: bool) -> String {
    let part = if c.held_out { "held-out" } else { "estimation" };
    let mut o = if diagnosed {
        format!(
            "\nstructures compared (each fitted and diagnosed; {part} RMSE before -> after, BIC \
             after):\n"
        )
    } else {
        format!("\nstructures compared (each fitted; {part} RMSE, BIC):\n")
    };
    for (i, s) in c.scores.iter().enumerate() {
        let mark = if i == c.chosen { "*" } else { " " };
        let nums = match (s.rmse, s.rmse_after, s.bic_after) {
            _ if s.failed.is_some() => "no result".into(),
            (Some(r), Some(_), Some(b)) if !diagnosed => {
                format!("RMSE {r:.4e}, BIC {b:.1}, {} free", s.free_params)
            }
            (Some(r), Some(a), Some(b)) => format!(
                "RMSE {r:.4e} -> {a:.4e} with {}, BIC {b:.1}, {} free",
                if s.effects.is_empty() {
                    "no effect".to_string()
                } else {
                    s.effects.join(", ")
                },
                s.free_params
            ),
            _ => "not diagnosed".into(),
        };
        let _ = writeln!(o, "  {mark} {:<22} {nums}", s.name);
        if !s.model.is_empty() {
            let _ = writeln!(o, "      {}", s.model);
        }
        if let Some(f) = &s.failed {
            let _ = writeln!(o, "      failed: {f}");
        }
        if !s.problems.is_empty() {
            let _ = writeln!(o, "      base fit not usable: {}", s.problems.join("; "));
        }
    }
    let _ = writeln!(o, "  {}", c.reason);
    o
}

/// The readable report of a time-domain diagnosis.
pub fn text(d: &Diagnosis) -> String {
    let mut o = String::from("\nresidual diagnosis (docs/design.md §6):\n");
    let _ = writeln!(
        o,
        "  estimation: before {} -> after {}",
        fit_row(&d.estimation.before),
        fit_row(&d.estimation.after)
    );
    if let Some(v) = &d.validation {
        let _ = writeln!(
            o,
            "  validation: before {} -> after {}",
            fit_row(&v.before),
            fit_row(&v.after)
        );
    }
    let r = &d.residual_before;
    let _ = writeln!(
        o,
        "  base residual: Ljung-Box Q = {:.1} ({} lags, p = {:.2e}), {} autocorrelation and {} \
         cross-correlation lags with the prewhitened input ({} with its changes) outside +-{:.3}, \
         {} spectral peak(s)",
        r.ljung_box_q,
        r.lags,
        r.ljung_box_p,
        r.auto_outside,
        r.cross_outside,
        r.change_outside,
        r.bound,
        r.peaks.len()
    );
    if let Some(q) = &d.quantization {
        let _ = writeln!(
            o,
            "  quantization (not fitted): {} output levels, step {:.4e}: noise floor {:.4e} RMS",
            q.levels, q.step, q.noise_floor_rms
        );
    }
    if d.effects.is_empty() {
        let _ = writeln!(o, "  no effect kept");
    }
    for e in &d.effects {
        let p: Vec<String> = e
            .params
            .iter()
            .map(|(k, v)| format!("{k} = {v:.4e}"))
            .collect();
        let _ = writeln!(
            o,
            "  kept {}: {} (removes {:.1}% of the residual sum of squares, RMSE {:+.1}%)\n      evidence: {}",
            e.name,
            p.join(", "),
            e.ssr_removed_percent,
            e.rmse_change_percent,
            e.evidence
        );
    }
    for a in &d.ambiguous {
        let _ = writeln!(
            o,
            "  ambiguous {} (cannot be told from {}): {}",
            a.name, a.confused_with, a.reason
        );
    }
    for r in &d.rejected {
        let _ = writeln!(o, "  rejected {}: {}", r.name, r.reason);
    }
    let _ = writeln!(o, "  final model: {}", d.final_model);
    let _ = writeln!(
        o,
        "  unexplained structure: {}",
        if d.unexplained { "yes" } else { "no" }
    );
    for r in &d.remaining {
        let _ = writeln!(o, "    - {r}");
    }
    o
}

/// Where the residual plot goes: next to `plot`, with `_diagnosis` added to the stem.
pub fn residual_plot_path(plot: &Path) -> PathBuf {
    let stem = plot.file_stem().and_then(|s| s.to_str()).unwrap_or("plot");
    let ext = plot.extension().and_then(|s| s.to_str()).unwrap_or("png");
    plot.with_file_name(format!("{stem}_diagnosis.{ext}"))
}

struct TimeResidual<'a> {
    rec: &'a Record,
    d: &'a Diagnosis,
}

impl Figure for TimeResidual<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let (rec, d) = (self.rec, self.d);
        let before: Vec<f64> = rec
            .y
            .iter()
            .zip(&d.yhat_before)
            .map(|(a, b)| a - b)
            .collect();
        let after: Vec<f64> = rec
            .y
            .iter()
            .zip(&d.yhat_after)
            .map(|(a, b)| a - b)
            .collect();
        let kept: Vec<&str> = d.effects.iter().map(|e| e.name.as_str()).collect();
        let title = format!(
            "residual y - yhat: before (RMSE {:.3e}) and after (RMSE {:.3e}){}",
            d.before.rmse,
            d.after.rmse,
            if kept.is_empty() {
                String::from(", no effect kept")
            } else {
                format!(" with {}", kept.join(", "))
            }
        );
        let ts = rec.t[d.split.min(rec.len() - 1)];
        plot::time_series_chart(
            root,
            &plot::TimeChart {
                title: Some(&title),
                x_desc: "t [s]",
                y_desc: Some("residual"),
                t: &rec.t,
                lines: &[
                    plot::Line {
                        label: Some("before (base model)"),
                        values: &before,
                        style: RED.mix(0.6).into(),
                    },
                    plot::Line {
                        label: Some("after (with the kept effects)"),
                        values: &after,
                        style: BLUE.mix(0.8).into(),
                    },
                ],
                marker: Some((ts, "validation starts", BLACK.mix(0.5).into())),
                look: plot::Look {
                    caption: 22,
                    labels: Some(15),
                    margin: 15,
                    x_area: 45,
                    y_area: 80,
                },
            },
        )?;
        Ok(())
    }
}

/// Draw the time-domain residual before and after to `path` (.png or .svg).
///
/// # Errors
/// A bad extension, a drawing or file error.
pub fn plot_time(path: &Path, rec: &Record, d: &Diagnosis) -> Result<()> {
    plot::save(path, (1400, 600), &TimeResidual { rec, d })
}

struct BodeResidual<'a> {
    d: &'a BodeDiagnosis,
}

impl Figure for BodeResidual<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let d = self.d;
        let (top, bottom) = root.split_vertically(root.dim_in_pixel().1 / 2);
        let w: Vec<f64> = d.residual_before.iter().map(|r| r.0).collect();
        let wl = w.iter().copied().fold(f64::INFINITY, f64::min) * 0.8;
        let wh = w.iter().copied().fold(0.0, f64::max) * 1.25;
        for (area, idx, unit) in [
            (&top, 1usize, "magnitude residual [dB]"),
            (&bottom, 2, "phase residual [deg]"),
        ] {
            let get = |r: &(f64, f64, f64)| if idx == 1 { r.1 } else { r.2 };
            let vals: Vec<f64> = d
                .residual_before
                .iter()
                .chain(&d.residual_after)
                .map(get)
                .collect();
            let (lo, hi) = plot::range_of(&vals);
            let mut ch = ChartBuilder::on(area)
                .caption(
                    if idx == 1 {
                        format!(
                            "Bode residual H/Hhat: J before {:.3e}, after {:.3e}",
                            d.before.j, d.after.j
                        )
                    } else {
                        String::new()
                    },
                    ("sans-serif", 20),
                )
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d((wl..wh).log_scale(), lo..hi)?;
            ch.configure_mesh()
                .x_desc("w [rad/s]")
                .y_desc(unit)
                .label_style(("sans-serif", 14))
                .draw()?;
            for (res, color, label) in [
                (&d.residual_before, RED, "before"),
                (&d.residual_after, BLUE, "after"),
            ] {
                ch.draw_series(LineSeries::new(res.iter().map(|r| (r.0, get(r))), color))?
                    .label(label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
                ch.draw_series(
                    res.iter()
                        .map(|r| Circle::new((r.0, get(r)), 4, color.filled())),
                )?;
            }
            ch.configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .draw()?;
        }
        Ok(())
    }
}

/// Draw the frequency-domain residual (magnitude and phase of `H/Hhat`) before and after.
///
/// # Errors
/// A bad extension, a drawing or file error.
pub fn plot_bode(path: &Path, d: &BodeDiagnosis) -> Result<()> {
    plot::save(path, (1200, 800), &BodeResidual { d })
}
