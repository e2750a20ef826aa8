//! Frequency-response points from sine tests, and the Bode CSV `freq_hz,gain_db,phase_deg`.

use std::io::Write;

/// One point of a measured frequency response.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodePoint {
    /// Frequency, Hz.
    pub freq_hz: f64,
    /// Gain |Y/U| in dB (physical units, (rad/s)/V).
    pub gain_db: f64,
    /// Phase of Y/U in degrees, (-360, 0] unwrapped along the sweep.
    pub phase_deg: f64,
    /// Samples in the measurement window.
    pub n_samples: u32,
    /// Whether the point came from the drive's DFT (true) or from streamed samples (false).
    pub on_drive: bool,
}

/// Complex ratio Y/U from (re, im) pairs, as (gain, phase_rad).
pub fn ratio(u: (f64, f64), y: (f64, f64)) -> Option<(f64, f64)> {
    let den = u.0 * u.0 + u.1 * u.1;
    if den <= 0.0 || !den.is_finite() {
        return None;
    }
    let re = (y.0 * u.0 + y.1 * u.1) / den;
    let im = (y.1 * u.0 - y.0 * u.1) / den;
    Some(((re * re + im * im).sqrt(), im.atan2(re)))
}

/// Single-bin DFT `(2/n) sum x_k exp(-j phase_k)` of a record, with phases given.
pub fn single_bin(x: &[f64], phase: impl Fn(usize) -> f64) -> (f64, f64) {
    let n = x.len().max(1) as f64;
    let (mut re, mut im) = (0.0, 0.0);
    for (k, &v) in x.iter().enumerate() {
        let p = phase(k);
        re += v * p.cos();
        im -= v * p.sin();
    }
    (2.0 * re / n, 2.0 * im / n)
}

/// Unwrap phases (degrees) along the sweep so consecutive points differ by less than 180.
pub fn unwrap_deg(points: &mut [BodePoint]) {
    let mut prev: Option<f64> = None;
    for p in points.iter_mut() {
        if let Some(q) = prev {
            while p.phase_deg - q > 180.0 {
                p.phase_deg -= 360.0;
            }
            while p.phase_deg - q < -180.0 {
                p.phase_deg += 360.0;
            }
        }
        prev = Some(p.phase_deg);
    }
}

/// Write `freq_hz,gain_db,phase_deg` (with a `#` comment line first).
pub fn write_csv(mut w: impl Write, points: &[BodePoint], comment: &str) -> std::io::Result<()> {
    for line in comment.lines() {
        writeln!(w, "# {line}")?;
    }
    writeln!(w, "freq_hz,gain_db,phase_deg")?;
    for p in points {
        writeln!(w, "{},{:.6},{:.6}", p.freq_hz, p.gain_db, p.phase_deg)?;
    }
    Ok(())
}

/// The comment line that states the convention of a table measured through the drive's sampled,
/// held loop: the ratio of the DFTs of the sampled output and the held input is the discrete
/// response `G_d(e^(j w T))`, which for a continuous plant `G` is `G(j w) (1 - e^(-j w T))/(j w T)`
/// (the zero-order hold: half a sample of delay and a sinc droop) plus aliases of `G` around
/// multiples of the sampling frequency. `fracid freq` reads this line and divides the hold out.
///
/// ```
/// assert_eq!(drive::bode::hold_line(1e-3), "hold: zero-order, sample period 0.001 s");
/// ```
pub fn hold_line(sample_period_s: f64) -> String {
    format!("hold: zero-order, sample period {sample_period_s} s")
}
