//! `fracid compare MODEL_A MODEL_B`: two models side by side, as the reference paper compares its
//! time- and frequency-domain models (Fig. 5): one Bode plot with both, the largest gain and phase
//! differences over a band and where they are, and the coefficients term by term when the
//! structures match (`ident::compare`).

use crate::cmd::model_in;
use crate::plot::{self, Figure};
use anyhow::Result;
use fracsim::FracTf;
use ident::compare::Comparison;
use plotters::coord::Shift;
use plotters::prelude::*;
use serde::Serialize;
use serde_json::Value;
use std::path::PathBuf;

/// Options of `fracid compare`.
#[derive(Debug, clap::Args)]
pub struct CompareArgs {
    /// Model A: a transfer function as text (`"6.82/(0.00002655 s^1.7452 + 0.0059 s^0.92 + 1)"`),
    /// or a file holding one, or the JSON written by `fracid time --json` / `fracid freq --json`
    /// (its final model: the diagnosis's refit if any, else the refined model, else `model`).
    pub model_a: String,
    /// Model B, as model A.
    pub model_b: String,
    /// Band, Hz: `LOW,HIGH`.
    #[arg(long, value_delimiter = ',', default_values_t = [0.1, 100.0])]
    pub band: Vec<f64>,
    /// Log-spaced frequencies evaluated over the band (2 to 100000).
    #[arg(long, default_value_t = 2000)]
    pub points: usize,
    /// Names of the two models in the text and the plot.
    #[arg(long, value_delimiter = ',', default_values_t = ["A".to_string(), "B".to_string()])]
    pub names: Vec<String>,
    /// Bode plot of both models (PNG or SVG by the extension).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Run `fracid compare`.
pub fn run(a: CompareArgs) -> Result<()> {
    let models: Vec<_> = [("model A", &a.model_a), ("model B", &a.model_b)]
        .into_iter()
        .filter_map(|(what, m)| Some((what, super::paths::file_arg(m)?)))
        .collect();
    let plot: Vec<_> = a.plot.iter().map(|p| ("--plot", p.as_path())).collect();
    super::paths::check(&models, &plot)?;
    if a.band.len() != 2 {
        crate::bad_input!("--band wants LOW,HIGH in Hz, got {} values", a.band.len());
    }
    if a.names.len() != 2 {
        crate::bad_input!("--names wants NAME_A,NAME_B, got {} names", a.names.len());
    }
    let ga = model_in::load(&a.model_a)?.tf;
    let gb = model_in::load(&a.model_b)?.tf;
    let c = ident::compare::compare(&ga, &gb, (a.band[0], a.band[1]), a.points)?;
    let names = (a.names[0].as_str(), a.names[1].as_str());
    if let Some(p) = &a.plot {
        plot::format_of(p)?;
    }
    let out = if a.json {
        serde_json::to_string_pretty(&to_json(&ga, &gb, &c, names)?)? + "\n"
    } else {
        text(&ga, &gb, &c, names)
    };
    if let Some(p) = &a.plot {
        plot::save(p, (1000, 800), &CompareFigure { c: &c, names })?;
    }
    use std::io::Write;
    match std::io::stdout().lock().write_all(out.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}

/// The comparison as text (also the demo's report section).
pub fn text(ga: &FracTf, gb: &FracTf, c: &Comparison, names: (&str, &str)) -> String {
    let (na, nb) = names;
    let mut s = format!(
        "{na}: {ga}\n{nb}: {gb}\nover {}-{} Hz ({} log-spaced points), differences {nb} - {na}:\n",
        c.band_hz.0,
        c.band_hz.1,
        c.freq_hz.len()
    );
    s += &format!(
        "  largest gain difference   {:+.4} dB at {:.4} Hz\n",
        c.gain.value, c.gain.freq_hz
    );
    s += &format!(
        "  largest phase difference  {:+.4} deg at {:.4} Hz\n",
        c.phase.value, c.phase.freq_hz
    );
    s += &format!(
        "  largest |{nb} - {na}|/|{na}|     {:.4} % at {:.4} Hz\n",
        100.0 * c.complex_rel.value,
        c.complex_rel.freq_hz
    );
    match &c.coefficients {
        Some(rows) => {
            s += &format!(
                "coefficients (terms paired by decreasing order):\n  {:<30} {:>14} {:>14} {:>10}\n",
                "", na, nb, "rel. diff"
            );
            for r in rows {
                let d = r
                    .rel_diff
                    .map(|d| format!("{:+.2} %", 100.0 * d))
                    .unwrap_or_else(|| "-".into());
                s += &format!("  {:<30} {:>14.6e} {:>14.6e} {:>10}\n", r.name, r.a, r.b, d);
            }
        }
        None => s += "coefficients: the structures differ (numbers of terms), no table\n",
    }
    s
}

/// One model of the comparison: its name and its text.
#[derive(Serialize)]
struct NamedJson<'a> {
    name: &'a str,
    model: String,
}

/// A largest difference and where.
#[derive(Serialize)]
struct LargestJson {
    value: f64,
    freq_hz: f64,
}

impl From<&ident::compare::Largest> for LargestJson {
    fn from(l: &ident::compare::Largest) -> Self {
        Self {
            value: l.value,
            freq_hz: l.freq_hz,
        }
    }
}

/// One coefficient of both models.
#[derive(Serialize)]
struct CoefJson<'a> {
    name: &'a str,
    a: f64,
    b: f64,
    rel_diff: Option<f64>,
}

/// `fracid compare --json`'s document.
#[derive(Serialize)]
struct CompareJson<'a> {
    a: NamedJson<'a>,
    b: NamedJson<'a>,
    band_hz: [f64; 2],
    points: usize,
    difference: &'static str,
    largest_gain_diff_db: LargestJson,
    largest_phase_diff_deg: LargestJson,
    largest_complex_rel_diff: LargestJson,
    coefficients: Option<Vec<CoefJson<'a>>>,
}

/// The comparison as JSON, its keys in the order a JSON object map sorts them (as always).
fn to_json(ga: &FracTf, gb: &FracTf, c: &Comparison, names: (&str, &str)) -> Result<Value> {
    Ok(serde_json::to_value(CompareJson {
        a: NamedJson {
            name: names.0,
            model: ga.to_string(),
        },
        b: NamedJson {
            name: names.1,
            model: gb.to_string(),
        },
        band_hz: [c.band_hz.0, c.band_hz.1],
        points: c.freq_hz.len(),
        difference: "B - A",
        largest_gain_diff_db: (&c.gain).into(),
        largest_phase_diff_deg: (&c.phase).into(),
        largest_complex_rel_diff: (&c.complex_rel).into(),
        coefficients: c.coefficients.as_ref().map(|rows| {
            rows.iter()
                .map(|r| CoefJson {
                    name: &r.name,
                    a: r.a,
                    b: r.b,
                    rel_diff: r.rel_diff,
                })
                .collect()
        }),
    })?)
}

/// Both models' Bode magnitude and phase over the band, and their differences.
pub struct CompareFigure<'a> {
    /// The comparison.
    pub c: &'a Comparison,
    /// Names of A and B.
    pub names: (&'a str, &'a str),
}

impl Figure for CompareFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static,
    {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow::anyhow!("drawing failed: {e}");
        let c = self.c;
        let (top, bottom) = root.split_vertically(400);
        let (lo, hi) = c.band_hz;
        let font = ("sans-serif", 20);
        let label_font = ("sans-serif", 16);
        let panels = [
            (&top, "Bode magnitude (dB)", &c.a_mag_db, &c.b_mag_db),
            (&bottom, "Bode phase (deg)", &c.a_phase_deg, &c.b_phase_deg),
        ];
        for (i, (area, title, ya, yb)) in panels.into_iter().enumerate() {
            let (ylo, yhi) = plot::range_of(ya.iter().chain(yb.iter()));
            let mut chart = ChartBuilder::on(area)
                .caption(title, font)
                .margin(12)
                .x_label_area_size(45)
                .y_label_area_size(70)
                .build_cartesian_2d((lo..hi).log_scale(), ylo..yhi)
                .map_err(e)?;
            chart
                .configure_mesh()
                .x_desc("frequency (Hz)")
                .label_style(label_font)
                .axis_desc_style(label_font)
                .draw()
                .map_err(e)?;
            let (ca, cb) = (RGBColor(31, 119, 180), RGBColor(214, 39, 40));
            let pa: Vec<(f64, f64)> = c.freq_hz.iter().copied().zip(ya.iter().copied()).collect();
            let pb: Vec<(f64, f64)> = c.freq_hz.iter().copied().zip(yb.iter().copied()).collect();
            chart
                .draw_series(LineSeries::new(pa, ca.stroke_width(2)))
                .map_err(e)?
                .label(self.names.0)
                .legend(plot::line_legend(ca.stroke_width(2), 24));
            chart
                .draw_series(DashedLineSeries::new(pb, 8, 5, cb.stroke_width(2)))
                .map_err(e)?
                .label(self.names.1)
                .legend(plot::line_legend(cb.stroke_width(2), 24));
            let (f, d) = if i == 0 {
                (
                    c.gain.freq_hz,
                    format!("largest gain difference {:+.3} dB", c.gain.value),
                )
            } else {
                (
                    c.phase.freq_hz,
                    format!("largest phase difference {:+.3} deg", c.phase.value),
                )
            };
            chart
                .draw_series(std::iter::once(PathElement::new(
                    vec![(f, ylo), (f, yhi)],
                    BLACK.mix(0.4).stroke_width(1),
                )))
                .map_err(e)?
                .label(format!("{d} at {f:.3} Hz"))
                .legend(plot::line_legend(BLACK.mix(0.4).into(), 24));
            plot::boxed_legend(&mut chart, SeriesLabelPosition::LowerLeft)?;
        }
        Ok(())
    }
}
