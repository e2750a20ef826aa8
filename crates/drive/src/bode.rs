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
    /// The spread of the repeats when the point combines several ([`combine_repeats`]).
    pub spread: Option<Spread>,
}

/// The spread of the repeated measurements of one frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    /// Sample standard deviation (n - 1) of the repeats' gains, dB.
    pub gain_db_std: f64,
    /// Sample standard deviation of the repeats' phases, deg (unwrapped to the first repeat).
    pub phase_deg_std: f64,
    /// Repeats measured.
    pub repeats: u32,
    /// Repeats averaged after trimming (`repeats - 2` from 3 repeats on, else `repeats`).
    pub kept: u32,
}

impl Spread {
    /// Standard errors (gain dB, phase deg) of the combined point: `std / sqrt(kept)`. For
    /// normal errors the 10%-trimmed mean of 10 has a variance about 6% above `sigma^2/10`, so
    /// `sigma^2/(n-2)` is on the safe side.
    pub fn std_errors(&self) -> (f64, f64) {
        let k = (self.kept.max(1) as f64).sqrt();
        (self.gain_db_std / k, self.phase_deg_std / k)
    }
}

/// The paper's trimmed mean: sort, drop the largest and the smallest (from 3 values on), average
/// the rest.
///
/// ```
/// assert_eq!(drive::bode::trimmed_mean(&[5.0, 1.0, 2.0, 3.0, 100.0]), 10.0 / 3.0);
/// assert_eq!(drive::bode::trimmed_mean(&[1.0, 2.0]), 1.5);
/// ```
pub fn trimmed_mean(x: &[f64]) -> f64 {
    let mut v = x.to_vec();
    v.sort_by(f64::total_cmp);
    let kept = if v.len() >= 3 {
        &v[1..v.len() - 1]
    } else {
        &v[..]
    };
    kept.iter().sum::<f64>() / kept.len().max(1) as f64
}

fn sample_std(x: &[f64]) -> f64 {
    let n = x.len();
    if n < 2 {
        return 0.0;
    }
    let m = x.iter().sum::<f64>() / n as f64;
    (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1) as f64).sqrt()
}

/// Combine the repeated measurements of one frequency as the paper does: the trimmed mean of the
/// gains in dB (drop the largest and the smallest gain, average the rest) and, independently, of
/// the phases in degrees (each repeat's phase first brought within 180 deg of the first repeat's;
/// the paper trims the gain only and says nothing of the phase, so the phase is trimmed the same
/// way), with the repeats' spread ([`Spread`]). `None` for no repeats.
///
/// ```
/// use drive::bode::{combine_repeats, BodePoint};
/// let p = |g: f64, ph: f64| BodePoint { freq_hz: 10.0, gain_db: g, phase_deg: ph, n_samples: 400, on_drive: true, spread: None };
/// let c = combine_repeats(&[p(1.0, -10.0), p(2.0, 350.0), p(9.0, -20.0)]).unwrap();
/// assert_eq!((c.gain_db, c.phase_deg), (2.0, -10.0));
/// assert_eq!(c.spread.unwrap().kept, 1);
/// ```
pub fn combine_repeats(reps: &[BodePoint]) -> Option<BodePoint> {
    let first = *reps.first()?;
    let gains: Vec<f64> = reps.iter().map(|p| p.gain_db).collect();
    let phases: Vec<f64> = reps
        .iter()
        .map(|p| {
            let d = p.phase_deg - first.phase_deg;
            p.phase_deg - 360.0 * (d / 360.0).round()
        })
        .collect();
    let n = reps.len() as u32;
    Some(BodePoint {
        gain_db: trimmed_mean(&gains),
        phase_deg: trimmed_mean(&phases),
        on_drive: reps.iter().all(|p| p.on_drive),
        spread: Some(Spread {
            gain_db_std: sample_std(&gains),
            phase_deg_std: sample_std(&phases),
            repeats: n,
            kept: if n >= 3 { n - 2 } else { n },
        }),
        ..first
    })
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

/// Exact integer level and ramp sums of `u` and `y` over a sine measurement window of `n` samples,
/// as the drive keeps them (PROTOCOL.md, SINE_RESULT): `level = sum x_k`,
/// `ramp = sum (2k - (n-1)) x_k`, `k = 0..n`. With `|x| < 2^15` and `n <= 2^22`
/// ([`crate::protocol::MAX_DFT_SAMPLES`]) neither overflows 64 bits.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WindowSums {
    /// `sum x_k` of u (index 0) and y (index 1).
    pub level: [i64; 2],
    /// `sum (2k - (n-1)) x_k` of u and y.
    pub ramp: [i64; 2],
}

impl WindowSums {
    /// Add sample `k` (0-based in the window of `n`) with raw `u`, `y`.
    pub fn add(&mut self, k: u32, n: u32, u: i16, y: i16) {
        let k2 = 2 * k as i64 - (n as i64 - 1);
        self.level[0] += u as i64;
        self.level[1] += y as i64;
        self.ramp[0] += k2 * u as i64;
        self.ramp[1] += k2 * y as i64;
    }
}

fn round_div(a: i64, d: i64) -> i64 {
    if a >= 0 {
        (a + d / 2) / d
    } else {
        -((-a + d / 2) / d)
    }
}

/// The level `(1/n) sum x_k` in Q8 raw (256 = one LSB), rounded half away from zero, as the
/// drive computes it.
///
/// ```
/// assert_eq!(drive::bode::q8_mean(3, 2), 384);
/// ```
pub fn q8_mean(sum: i64, n: u32) -> i32 {
    round_div(sum * 256, n.max(1) as i64) as i32
}

/// The ramp moment `(1/n) sum ((2k - (n-1))/n) x_k = ramp_sum / n^2` in Q8 raw, as the drive
/// computes it without a 128-bit product: `t = (s / n) 256 + ((s % n) 256) / n` (truncating),
/// then `t / n` rounded half away from zero. Within one Q8 unit of the exact value.
///
/// ```
/// // a ramp x_k = 2k - (n-1) over n = 4: sum = 9 + 1 + 1 + 9 = 20, 20 * 256 / 16 = 320
/// assert_eq!(drive::bode::q8_ramp(20, 4), 320);
/// ```
pub fn q8_ramp(sum: i64, n: u32) -> i32 {
    let d = n.max(1) as i64;
    let t = (sum / d) * 256 + ((sum % d) * 256) / d;
    round_div(t, d) as i32
}

/// Moments of one channel over a sine measurement window, raw units: the single-bin DFT
/// `(2/n) sum x_k e^(-j theta_k)` as (re, im), the level `(1/n) sum x_k` and the ramp moment
/// `(1/n) sum r_k x_k`, `r_k = (2k - (n-1))/n`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChannelMoments {
    /// Single-bin DFT (re, im).
    pub dft: (f64, f64),
    /// Level.
    pub mean: f64,
    /// Ramp moment.
    pub ramp: f64,
}

impl ChannelMoments {
    /// The moments of samples `x` whose phases (rad) are `phase(k)`, in f64 (the host's DFT of
    /// streamed samples).
    pub fn of(x: &[f64], phase: impl Fn(usize) -> f64) -> Self {
        let n = x.len().max(1) as f64;
        let mut mean = 0.0;
        let mut ramp = 0.0;
        for (k, &v) in x.iter().enumerate() {
            mean += v;
            ramp += (2.0 * k as f64 - (n - 1.0)) / n * v;
        }
        Self {
            dft: single_bin(x, phase),
            mean: mean / n,
            ramp: ramp / n,
        }
    }
}

/// The Gram matrix `(1/n) sum phi_i phi_j` of the regressors `phi = [1, r_k, cos theta_k,
/// sin theta_k]` over a window of `n` samples that starts at run sample `first`, with the drive's
/// phase `theta_k = 2 pi ((first + k) inc mod 2^32) / 2^32`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WindowGram(pub [[f64; 4]; 4]);

impl WindowGram {
    /// The Gram matrix of the window.
    pub fn new(n: u32, first: u32, inc: u32) -> Self {
        let mut g = [[0.0; 4]; 4];
        let nf = n.max(1) as f64;
        for k in 0..n {
            let p = ((first as u64 + k as u64).wrapping_mul(inc as u64)) as u32;
            let th = p as f64 / 4294967296.0 * std::f64::consts::TAU;
            let phi = [1.0, (2.0 * k as f64 - (nf - 1.0)) / nf, th.cos(), th.sin()];
            for (row, pi) in g.iter_mut().zip(phi) {
                for (v, pj) in row.iter_mut().zip(phi) {
                    *v += pi * pj;
                }
            }
        }
        for row in &mut g {
            for v in row.iter_mut() {
                *v /= nf;
            }
        }
        Self(g)
    }
}

/// The sine's phasor with the operating-point level and its drift removed: the least-squares fit
/// `x_k ~ a + b r_k + c cos theta_k + d sin theta_k` over the window (the normal equations
/// `G p = m` from the moments), returned as `X = c - j d` (so `x ~ Re(X e^(j theta))`, the
/// convention of the plain DFT). Over whole cycles the level is orthogonal to the sine and the DFT
/// alone ignores it; the ramp is not (its DFT is `~ 2b/(e^(-j w) - 1)`), so the joint fit is what
/// removes a drifting operating point. Reference: the four-parameter sine fit of IEEE Std 1057
/// (here with the frequency known and a linear trend in place of a constant).
///
/// ```
/// use drive::bode::{fit_phasor, ChannelMoments, WindowGram};
/// let (n, inc) = (100u32, 1u32 << 28); // 16 samples per cycle, not whole cycles in 100
/// let th = |k: usize| ((k as u64 * inc as u64) as u32) as f64 / 4294967296.0 * std::f64::consts::TAU;
/// let x: Vec<f64> = (0..n as usize).map(|k| 40.0 + 0.3 * k as f64 + 2.0 * (th(k) + 0.5).cos()).collect();
/// let m = ChannelMoments::of(&x, th);
/// let (re, im) = fit_phasor(&m, &WindowGram::new(n, 0, inc)).unwrap();
/// assert!((re - 2.0 * 0.5f64.cos()).abs() < 1e-9 && (im - 2.0 * 0.5f64.sin()).abs() < 1e-9);
/// ```
pub fn fit_phasor(m: &ChannelMoments, g: &WindowGram) -> Option<(f64, f64)> {
    let mut a = g.0;
    let mut b = [m.mean, m.ramp, m.dft.0 / 2.0, -m.dft.1 / 2.0];
    // Gaussian elimination with partial pivoting
    for c in 0..4 {
        let piv = (c..4).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[piv][c].abs() <= 1e-12 || a[piv][c].is_nan() {
            return None;
        }
        a.swap(c, piv);
        b.swap(c, piv);
        let (pivot_row, pivot_b) = (a[c], b[c]);
        for (row, br) in a.iter_mut().zip(b.iter_mut()).skip(c + 1) {
            let f = row[c] / pivot_row[c];
            for (v, pv) in row.iter_mut().zip(pivot_row).skip(c) {
                *v -= f * pv;
            }
            *br -= f * pivot_b;
        }
    }
    let mut p = [0.0; 4];
    for c in (0..4).rev() {
        let s: f64 = a[c].iter().zip(p).skip(c + 1).map(|(x, y)| x * y).sum();
        p[c] = (b[c] - s) / a[c][c];
    }
    p.iter().all(|v| v.is_finite()).then_some((p[2], -p[3]))
}

/// The START_SINE frequency (millihertz) nearest `freq_hz` at which `cycles` cycles fill a whole
/// number of samples at `sample_rate_hz`: `n = round(cycles fs / f)` samples (at least
/// `2 cycles + 1`, below Nyquist) and `freq_mhz = round(1000 cycles fs / n)`; of `n - 2..=n + 2`
/// the nearest to `freq_hz` whose window, as the drive counts it, is the intended `n` samples. The measurement window then holds the cycles to within the millihertz grid, so
/// neither the operating point nor the negative-frequency image of the sine leaks into the DFT.
/// `None` for a frequency outside `(0, fs/2)` or no cycles.
///
/// ```
/// // 73.6 Hz, 4 cycles at 1 kHz: 54.35 samples -> 54 samples, 74.074 Hz
/// assert_eq!(drive::bode::whole_cycle_mhz(73.6, 4, 1000), Some(74_074));
/// assert_eq!(drive::bode::whole_cycle_mhz(20.0, 4, 1000), Some(20_000));
/// ```
pub fn whole_cycle_mhz(freq_hz: f64, cycles: u16, sample_rate_hz: u32) -> Option<u32> {
    let fs = sample_rate_hz as f64;
    if !(freq_hz > 0.0 && freq_hz < fs / 2.0) || cycles == 0 {
        return None;
    }
    let c = cycles as f64;
    let n0 = (c * fs / freq_hz).round();
    // (window not the intended one, distance to the request, freq_mhz)
    let mut best: Option<(bool, f64, u32)> = None;
    for dn in -2..=2 {
        let n = n0 + dn as f64;
        if n < 2.0 * c + 1.0 {
            continue;
        }
        let mhz = (1000.0 * c * fs / n).round();
        if !(1.0..=u32::MAX as f64).contains(&mhz) {
            continue;
        }
        let cmd = crate::protocol::StartSine {
            freq_mhz: mhz as u32,
            amplitude: 0,
            offset: 0,
            settle_cycles: 0,
            cycles,
            flags: 0,
        };
        let Some((_, measure)) = cmd.sample_counts(sample_rate_hz) else {
            continue;
        };
        let key = (measure as f64 != n, (mhz / 1000.0 - freq_hz).abs());
        if best.is_none_or(|(m, d, _)| key < (m, d)) {
            best = Some((key.0, key.1, mhz as u32));
        }
    }
    best.map(|b| b.2)
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

/// Write `freq_hz,gain_db,phase_deg` (with `#` comment lines first). When a point carries the
/// spread of repeats, three more columns: `gain_db_std,phase_deg_std,repeats` (the sample standard
/// deviations of the repeats, dB and deg, and their number; see [`Spread`]). `fracid freq` reads
/// them back and weights the points by them.
pub fn write_csv(mut w: impl Write, points: &[BodePoint], comment: &str) -> std::io::Result<()> {
    for line in comment.lines() {
        writeln!(w, "# {line}")?;
    }
    let spread = points.iter().any(|p| p.spread.is_some());
    write_csv_columns(&mut w, spread)?;
    for p in points {
        write_csv_row(&mut w, p, spread)?;
    }
    Ok(())
}

/// The column line of a Bode table ([`write_csv`]): with the spread columns or without.
pub fn write_csv_columns(mut w: impl Write, spread: bool) -> std::io::Result<()> {
    if spread {
        writeln!(
            w,
            "freq_hz,gain_db,phase_deg,gain_db_std,phase_deg_std,repeats"
        )
    } else {
        writeln!(w, "freq_hz,gain_db,phase_deg")
    }
}

/// One row of a Bode table ([`write_csv`]); with `spread`, a point without one is a single
/// measurement (standard deviations 0, 1 repeat).
pub fn write_csv_row(mut w: impl Write, p: &BodePoint, spread: bool) -> std::io::Result<()> {
    write!(w, "{},{:.6},{:.6}", p.freq_hz, p.gain_db, p.phase_deg)?;
    if spread {
        let s = p.spread.unwrap_or(Spread {
            gain_db_std: 0.0,
            phase_deg_std: 0.0,
            repeats: 1,
            kept: 1,
        });
        write!(
            w,
            ",{:.6},{:.6},{}",
            s.gain_db_std, s.phase_deg_std, s.repeats
        )?;
    }
    writeln!(w)
}

/// The header of the file of single repeats written as they are measured
/// ([`write_repeat_line`]).
pub const REPEATS_HEADER: &str = "freq_hz,repeat,gain_db,phase_deg";

/// One repeat as a line of the repeats file: `freq_hz,repeat,gain_db,phase_deg` (repeat from 1).
pub fn write_repeat_line(mut w: impl Write, p: &BodePoint, repeat: u32) -> std::io::Result<()> {
    writeln!(
        w,
        "{},{},{:.6},{:.6}",
        p.freq_hz, repeat, p.gain_db, p.phase_deg
    )
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
