//! Plotting helpers shared by the subcommands: PNG or SVG by the file extension, an embedded font
//! (DejaVu Sans, see `assets/DejaVuSans-LICENSE.txt`) so that no system font library is needed.

use anyhow::{Context, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Once;

static FONT: Once = Once::new();

/// Register the embedded font as the "sans-serif" family used by every chart.
pub fn init_font() {
    FONT.call_once(|| {
        // The font is a constant asset shipped in the binary: failing to register it is a bug.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            include_bytes!("../assets/DejaVuSans.ttf"),
        );
    });
}

/// Output format chosen from the file name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Portable network graphics.
    Png,
    /// Scalable vector graphics.
    Svg,
}

/// The format of `path` from its extension (`.png` or `.svg`).
///
/// # Errors
/// Any other extension.
pub fn format_of(path: &Path) -> Result<Format> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .as_deref()
    {
        Some("png") => check_dir(path).map(|()| Format::Png),
        Some("svg") => check_dir(path).map(|()| Format::Svg),
        _ => Err(anyhow::Error::new(crate::bad_input::BadInput(format!(
            "plot file {} must end in .png or .svg",
            path.display()
        )))),
    }
}

/// The directory of a plot file must exist, so that a bad path fails before the work (exit 3,
/// an I/O error in words).
fn check_dir(path: &Path) -> Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(anyhow::Error::new(std::io::Error::new(
            std::io::ErrorKind::NotFound,
            format!(
                "cannot write plot {}: no directory {}",
                path.display(),
                dir.display()
            ),
        )));
    }
    Ok(())
}

/// A plotters error as an I/O error in words (the backends fail only on writing the file): exit
/// 3, not `ImageError(IoError(...))` and exit 1.
fn plot_io<E: std::fmt::Debug>(path: &Path) -> impl FnOnce(E) -> anyhow::Error + '_ {
    move |e| {
        let dbg = format!("{e:?}");
        // the innermost message: plotters nests the io::Error's Debug
        let reason = dbg
            .rsplit_once("message: \"")
            .and_then(|(_, r)| r.split_once('"'))
            .map_or(dbg.clone(), |(m, _)| m.to_string());
        anyhow::Error::new(std::io::Error::other(format!(
            "cannot write plot {}: {reason}",
            path.display()
        )))
    }
}

/// Something that draws itself on any plotters backend.
pub trait Figure {
    /// Draw on `root` (already filled white).
    ///
    /// # Errors
    /// A drawing error.
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<()>
    where
        DB::ErrorType: 'static;
}

/// Render `fig` to a PNG or SVG file of `size` pixels at `path`, with the embedded font registered.
///
/// # Errors
/// A bad extension, a drawing error, or a file that cannot be written.
pub fn save(path: &Path, size: (u32, u32), fig: &impl Figure) -> Result<()> {
    init_font();
    let format = format_of(path)?;
    // Open the file first: a path that cannot be written fails with the system's words.
    std::fs::File::create(path).with_context(|| format!("cannot write plot {}", path.display()))?;
    match format {
        Format::Png => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            root.fill(&WHITE).map_err(plot_io(path))?;
            fig.draw(&root)?;
            root.present().map_err(plot_io(path))?;
        }
        Format::Svg => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            root.fill(&WHITE).map_err(plot_io(path))?;
            fig.draw(&root)?;
            root.present().map_err(plot_io(path))?;
        }
    }
    Ok(())
}

/// A legend entry for a line: a `len_px`-pixel stroke in `style`.
pub fn line_legend(
    style: ShapeStyle,
    len_px: i32,
) -> impl Fn((i32, i32)) -> PathElement<(i32, i32)> {
    move |(x, y)| PathElement::new(vec![(x, y), (x + len_px, y)], style)
}

/// The figures' boxed legend at `position`: white at 85%, a black border, 15-pixel labels.
///
/// # Errors
/// A drawing error.
pub fn boxed_legend<'a, DB, CT>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> Result<()>
where
    DB: DrawingBackend + 'a,
    DB::ErrorType: 'static,
    CT: CoordTranslate,
{
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 15))
        .draw()
        .map_err(|e| anyhow::anyhow!("drawing failed: {e}"))
}

/// Padded (min, max) of the finite values, never an empty range.
pub fn range_of<'a>(values: impl IntoIterator<Item = &'a f64>) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &v in values {
        if v.is_finite() {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = if hi > lo {
        0.05 * (hi - lo)
    } else {
        0.5 * lo.abs().max(1.0)
    };
    (lo - pad, hi + pad)
}

/// Sizes of a chart's text and frame, in pixels.
#[derive(Debug, Clone, Copy)]
pub struct Look {
    /// Caption font size.
    pub caption: u32,
    /// Tick-label and legend font size (`None`: plotters' defaults).
    pub labels: Option<u32>,
    /// Margin around the chart.
    pub margin: u32,
    /// Height of the x label area.
    pub x_area: u32,
    /// Width of the y label area.
    pub y_area: u32,
}

/// One curve of a [`TimeChart`].
pub struct Line<'a> {
    /// Legend entry (`None`: not in the legend).
    pub label: Option<&'a str>,
    /// One value per time stamp.
    pub values: &'a [f64],
    /// Line style, also used for the legend entry.
    pub style: ShapeStyle,
}

/// Curves against time on one panel: the y range covers every curve, the x range the time stamps.
pub struct TimeChart<'a> {
    /// Caption (`None`: no caption and no room kept for one).
    pub title: Option<&'a str>,
    /// Text of the time axis.
    pub x_desc: &'a str,
    /// Text of the value axis.
    pub y_desc: Option<&'a str>,
    /// Time stamps.
    pub t: &'a [f64],
    /// The curves, drawn in order.
    pub lines: &'a [Line<'a>],
    /// A labelled vertical line at a time (such as where validation starts), drawn after the curves.
    pub marker: Option<(f64, &'a str, ShapeStyle)>,
    /// Sizes.
    pub look: Look,
}

/// Draw `c` on `area`, with a legend when a curve or the marker has a label.
///
/// # Errors
/// A drawing error.
pub fn time_series_chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    c: &TimeChart<'_>,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let look = c.look;
    let t0 = c.t.first().copied().unwrap_or(0.0);
    let t1 = c.t.last().copied().unwrap_or(1.0);
    let t1 = if t1 > t0 { t1 } else { t0 + 1e-12 };
    let (lo, hi) = range_of(c.lines.iter().flat_map(|l| l.values));
    let mut builder = ChartBuilder::on(area);
    builder
        .margin(look.margin)
        .x_label_area_size(look.x_area)
        .y_label_area_size(look.y_area);
    if let Some(title) = c.title {
        builder.caption(title, ("sans-serif", look.caption));
    }
    let mut ch = builder.build_cartesian_2d(t0..t1, lo..hi)?;
    let mut mesh = ch.configure_mesh();
    mesh.x_desc(c.x_desc);
    if let Some(y) = c.y_desc {
        mesh.y_desc(y);
    }
    if let Some(size) = look.labels {
        mesh.label_style(("sans-serif", size));
    }
    mesh.draw()?;
    for l in c.lines {
        let s = ch.draw_series(LineSeries::new(
            c.t.iter().copied().zip(l.values.iter().copied()),
            l.style,
        ))?;
        if let Some(label) = l.label {
            s.label(label).legend(line_legend(l.style, 20));
        }
    }
    if let Some((at, label, style)) = c.marker {
        ch.draw_series(std::iter::once(PathElement::new(
            vec![(at, lo), (at, hi)],
            style,
        )))?
        .label(label)
        .legend(line_legend(style, 20));
    }
    if c.marker.is_some() || c.lines.iter().any(|l| l.label.is_some()) {
        let mut labels = ch.configure_series_labels();
        labels.background_style(WHITE.mix(0.8)).border_style(BLACK);
        if let Some(size) = look.labels {
            labels.label_font(("sans-serif", size));
        }
        labels.draw()?;
    }
    Ok(())
}

/// Correlation coefficients as bars against the lag (the first bar at lag `first`), with the
/// confidence band `+-bound` in red; the value axis spans at least `1.5 bound`, at most 1.05.
///
/// # Errors
/// A drawing error.
pub fn correlation_chart<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    title: &str,
    first: i32,
    values: &[f64],
    bound: f64,
    look: Look,
) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let ymax = values
        .iter()
        .fold(bound * 1.5, |m, v| m.max(v.abs()))
        .min(1.05);
    let last = first + values.len() as i32 - 1;
    let mut c = ChartBuilder::on(area)
        .caption(title, ("sans-serif", look.caption))
        .margin(look.margin)
        .x_label_area_size(look.x_area)
        .y_label_area_size(look.y_area)
        .build_cartesian_2d((first - 1)..(last + 1), -ymax..ymax)?;
    let mut mesh = c.configure_mesh();
    mesh.x_desc("lag [samples]");
    if let Some(size) = look.labels {
        mesh.label_style(("sans-serif", size));
    }
    mesh.draw()?;
    c.draw_series(values.iter().enumerate().map(|(i, v)| {
        let x = first + i as i32;
        PathElement::new(vec![(x, 0.0), (x, *v)], BLACK.stroke_width(2))
    }))?;
    for s in [bound, -bound] {
        c.draw_series(std::iter::once(PathElement::new(
            vec![(first - 1, s), (last + 1, s)],
            RED,
        )))?;
    }
    Ok(())
}
