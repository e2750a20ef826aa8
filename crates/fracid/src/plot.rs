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
        Some("png") => Ok(Format::Png),
        Some("svg") => Ok(Format::Svg),
        _ => Err(anyhow::Error::new(crate::cmd::BadInput(format!(
            "plot file {} must end in .png or .svg",
            path.display()
        )))),
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
    let ctx = || format!("cannot write plot {}", path.display());
    match format_of(path)? {
        Format::Png => {
            let root = BitMapBackend::new(path, size).into_drawing_area();
            root.fill(&WHITE).with_context(ctx)?;
            fig.draw(&root)?;
            root.present().with_context(ctx)?;
        }
        Format::Svg => {
            let root = SVGBackend::new(path, size).into_drawing_area();
            root.fill(&WHITE).with_context(ctx)?;
            fig.draw(&root)?;
            root.present().with_context(ctx)?;
        }
    }
    Ok(())
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
