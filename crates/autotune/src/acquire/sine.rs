//! A sine sweep (`fracid drive sine`): the request, its check and its run.

use crate::error::invalid;
use crate::Result;
use drive::bode::BodePoint;
use drive::client::{Client, SineSweep, SweepEvent};
use drive::protocol::Configure;
use serde::{Deserialize, Serialize};

/// The most frequencies of one sweep (`points`, `freqs_hz`).
pub const MAX_SWEEP_FREQUENCIES: usize = 1000;

/// A sweep of sines around an operating point, each measured after its settling cycles.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SineRequest {
    /// Lowest frequency, Hz.
    pub f_min_hz: f64,
    /// Highest frequency, Hz.
    pub f_max_hz: f64,
    /// Number of log-spaced frequencies.
    pub points: usize,
    /// Explicit frequencies, Hz (override `f_min_hz`, `f_max_hz`, `points`).
    pub freqs_hz: Option<Vec<f64>>,
    /// Amplitude, V.
    pub amplitude_v: f64,
    /// Operating point, V.
    pub offset_v: f64,
    /// Measured cycles per frequency.
    pub cycles: u16,
    /// Settling cycles per frequency (at least `min_settle_s`).
    pub settle_cycles: u16,
    /// Minimum settling time, s.
    pub min_settle_s: f64,
    /// Stream the samples too (the host's DFT if the drive's is lost).
    pub stream: bool,
    /// Measurements per frequency, combined by the paper's trimmed mean (3: the fewest that
    /// drop the extremes and still give a spread).
    pub repeats: u32,
}

impl Default for SineRequest {
    fn default() -> Self {
        Self {
            f_min_hz: 1.0,
            f_max_hz: 100.0,
            points: 15,
            freqs_hz: None,
            amplitude_v: 1.0,
            offset_v: 6.0,
            cycles: 4,
            settle_cycles: 2,
            min_settle_s: 0.2,
            stream: false,
            repeats: 3,
        }
    }
}

impl SineRequest {
    /// The frequencies asked, checked: a range in order, at most [`MAX_SWEEP_FREQUENCIES`], all
    /// positive and below Nyquist; explicit frequencies sorted and each measured once (a
    /// warning says so).
    fn frequencies(&self, conf: &Configure) -> Result<(Vec<f64>, Vec<String>)> {
        if self.freqs_hz.is_none()
            && (self.f_min_hz > self.f_max_hz || self.f_min_hz == self.f_max_hz && self.points > 1)
        {
            return invalid(format!(
                "--f-min {} Hz must be below --f-max {} Hz (a table of {} frequencies)",
                self.f_min_hz, self.f_max_hz, self.points
            ));
        }
        if self.freqs_hz.is_none() && self.points == 0 {
            return invalid("--points must be at least 1");
        }
        // Each frequency is seconds of the drive's time: a sweep of more is a typing error,
        // refused before the table is even made (1e8 of them took 2.3 GB).
        let asked = self.freqs_hz.as_ref().map_or(self.points, Vec::len);
        if asked > MAX_SWEEP_FREQUENCIES {
            return invalid(format!(
                "{asked} frequencies (--points or --freqs): at most {MAX_SWEEP_FREQUENCIES} in one sweep"
            ));
        }
        let mut freqs = match &self.freqs_hz {
            Some(f) => f.clone(),
            None => SineSweep::log(self.f_min_hz, self.f_max_hz, self.points).freqs_hz,
        };
        if freqs.is_empty() || freqs.iter().any(|f| !(f.is_finite() && *f > 0.0)) {
            return invalid("frequencies must be positive");
        }
        let asked = freqs.clone();
        freqs.sort_by(f64::total_cmp);
        freqs.dedup();
        let mut warnings = vec![];
        if freqs != asked {
            warnings.push(format!(
                "--freqs sorted into increasing order{}: {}",
                if freqs.len() < asked.len() {
                    ", repeated frequencies measured once"
                } else {
                    ""
                },
                freqs
                    .iter()
                    .map(f64::to_string)
                    .collect::<Vec<_>>()
                    .join(",")
            ));
        }
        let nyq = conf.sample_rate_hz as f64 / 2.0;
        if let Some(f) = freqs.iter().find(|&&f| f >= nyq) {
            return invalid(format!(
                "{f} Hz is at or above Nyquist ({nyq} Hz at --sample-rate {})",
                conf.sample_rate_hz
            ));
        }
        Ok((freqs, warnings))
    }

    /// The client's sweep for `conf`, and the warnings of the check.
    ///
    /// # Errors
    /// [`Error::InvalidParam`](crate::Error::InvalidParam) for anything out of range (the
    /// frequencies, the amplitude and the operating point, the cycles, repeats, every level
    /// beyond the clamp), and for two frequencies the drive would measure as one.
    pub fn sweep(&self, conf: &Configure) -> Result<(SineSweep, Vec<String>)> {
        let (freqs, mut warnings) = self.frequencies(conf)?;
        let raw = |v: f64, name: &str| -> Result<i32> {
            let r = (v / conf.u_lsb()).round();
            if !(r.is_finite() && r.abs() <= 32767.0) {
                return invalid(format!("{name} {v} V is out of the command range"));
            }
            Ok(r as i32)
        };
        let (amp, off) = (
            raw(self.amplitude_v, "--amplitude")?,
            raw(self.offset_v, "--offset")?,
        );
        if amp <= 0 {
            return invalid("--amplitude must be > 0 V");
        }
        if !(self.min_settle_s.is_finite() && self.min_settle_s >= 0.0) {
            return invalid("--min-settle must be a finite number of seconds >= 0");
        }
        if self.cycles == 0 {
            return invalid("--cycles must be at least 1");
        }
        if self.repeats == 0 {
            return invalid("--repeats must be at least 1");
        }
        warnings.extend(super::check_levels(
            &[("crest", off + amp), ("trough", off - amp)],
            conf,
        )?);
        let sweep = SineSweep {
            freqs_hz: freqs,
            amplitude_v: self.amplitude_v,
            offset_v: self.offset_v,
            cycles: self.cycles,
            settle_cycles: self.settle_cycles,
            min_settle_s: self.min_settle_s,
            stream: self.stream,
            repeats: self.repeats,
            ..SineSweep::log(1.0, 1.0, 1)
        };
        applied(&sweep, conf)?;
        Ok((sweep, warnings))
    }
}

/// The frequencies the drive applies (the whole-cycle frequency nearest each request), as
/// `requested -> applied` for those it moves.
///
/// # Errors
/// Two requests the drive would measure at one frequency.
pub fn applied(sweep: &SineSweep, conf: &Configure) -> Result<Vec<(f64, f64)>> {
    let applied = sweep.applied_freqs_hz(conf.sample_rate_hz);
    for (k, w) in applied.windows(2).enumerate() {
        if let [Some(x), Some(y)] = w {
            if (x - y).abs() <= 1e-9 * x.abs() {
                return invalid(format!(
                    "{} Hz and {} Hz are both measured at {x} Hz (the nearest frequency with whole \
                     cycles in the window): drop one",
                    sweep.freqs_hz[k],
                    sweep.freqs_hz[k + 1]
                ));
            }
        }
    }
    Ok(sweep
        .freqs_hz
        .iter()
        .zip(&applied)
        .filter_map(|(f, fa)| fa.filter(|fa| (fa - f).abs() > 1e-6).map(|fa| (*f, fa)))
        .collect())
}

/// A sweep as measured.
#[derive(Debug, Clone)]
pub struct SineRecord {
    /// The points measured, in increasing frequency.
    pub points: Vec<BodePoint>,
    /// What went wrong on the way (a frequency lost, ...).
    pub problems: Vec<String>,
}

impl SineRecord {
    /// The requested frequencies (Hz) of `sweep` with no point measured.
    pub fn unmeasured(&self, sweep: &SineSweep, conf: &Configure) -> Vec<f64> {
        let applied = sweep.applied_freqs_hz(conf.sample_rate_hz);
        sweep
            .freqs_hz
            .iter()
            .zip(&applied)
            .filter(|(_, fa)| {
                !fa.is_some_and(|fa| {
                    self.points
                        .iter()
                        .any(|p| (p.freq_hz - fa).abs() <= 1e-9 * fa)
                })
            })
            .map(|(f, _)| *f)
            .collect()
    }
}

/// Run `sweep` (from [`SineRequest::sweep`]) on the configured drive behind `client`, each
/// repeat and each point to `on_event` as measured.
///
/// # Errors
/// The drive's errors, and those `on_event` returns (the sweep stops at the first).
pub fn run(
    client: &mut Client,
    sweep: &SineSweep,
    on_event: &mut dyn FnMut(SweepEvent<'_>) -> std::io::Result<()>,
) -> Result<SineRecord> {
    let (points, problems) = client.run_sine_sweep_with(sweep, on_event)?;
    Ok(SineRecord { points, problems })
}

/// One sine held at a frequency with its samples streamed: a time record (a dwell around a
/// resonance, a slow sine for many input levels) and the drive's measurement of the point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DwellRequest {
    /// Frequency, Hz (the drive applies the nearest with whole cycles in its window).
    pub freq_hz: f64,
    /// Amplitude, V.
    pub amplitude_v: f64,
    /// Operating point, V.
    pub offset_v: f64,
    /// Cycles before the measurement window (recorded too).
    pub settle_cycles: u16,
    /// Cycles in the measurement window.
    pub cycles: u16,
}

impl Default for DwellRequest {
    fn default() -> Self {
        Self {
            freq_hz: 10.0,
            amplitude_v: 1.0,
            offset_v: 0.0,
            settle_cycles: 2,
            cycles: 4,
        }
    }
}

impl DwellRequest {
    /// The START_SINE (streamed, with the drive's DFT).
    ///
    /// # Errors
    /// Out of range: a frequency not below Nyquist, levels beyond the command range or all
    /// beyond the clamp, no cycles.
    pub fn command(&self, conf: &Configure) -> Result<drive::protocol::StartSine> {
        let nyq = conf.sample_rate_hz as f64 / 2.0;
        if !(self.freq_hz > 0.0 && self.freq_hz < nyq) {
            return invalid(format!(
                "a dwell at {} Hz: the frequency must be in (0, {nyq}) Hz",
                self.freq_hz
            ));
        }
        if self.cycles == 0 {
            return invalid("a dwell needs at least one measured cycle");
        }
        let raw = |v: f64| (v / conf.u_lsb()).round();
        let (amp, off) = (raw(self.amplitude_v), raw(self.offset_v));
        if !(amp > 0.0 && amp.abs() <= 32767.0 && off.abs() <= 32767.0) {
            return invalid(format!(
                "a dwell of {} V around {} V is out of the command range",
                self.amplitude_v, self.offset_v
            ));
        }
        super::check_levels(
            &[
                ("crest", (off + amp) as i32),
                ("trough", (off - amp) as i32),
            ],
            conf,
        )?;
        Ok(drive::protocol::StartSine {
            freq_mhz: (self.freq_hz * 1000.0).round() as u32,
            amplitude: amp as i16,
            offset: off as i16,
            settle_cycles: self.settle_cycles,
            cycles: self.cycles,
            flags: drive::protocol::SINE_STREAM | drive::protocol::SINE_DFT,
        })
    }

    /// The drive time of the dwell, s.
    pub fn duration_s(&self) -> f64 {
        f64::from(self.settle_cycles + self.cycles) / self.freq_hz
    }
}

/// A dwell as acquired: its samples and the point measured.
#[derive(Debug, Clone)]
pub struct DwellRecord {
    /// The request.
    pub request: DwellRequest,
    /// The run (its samples).
    pub acquisition: drive::client::Acquisition,
    /// The frequency response point, if measured.
    pub point: Option<BodePoint>,
}

/// Run `req` on the drive behind `client`, configured with `conf`.
///
/// # Errors
/// [`DwellRequest::command`]; the drive's errors.
pub fn dwell(
    client: &mut Client,
    conf: &Configure,
    req: &DwellRequest,
    sink: &mut dyn drive::client::SampleSink,
) -> Result<DwellRecord> {
    let cmd = req.command(conf)?;
    let acquisition = client.run_sine(&cmd, sink)?;
    let point = drive::client::sine_point(&acquisition, &cmd, conf);
    Ok(DwellRecord {
        request: req.clone(),
        acquisition,
        point,
    })
}
