//! Whether the held-out part of a record is excited within the band its estimation part excites.
//!
//! A sine sweep holds its last frequencies in its last samples: held out, they test the model
//! where it was never fitted (on the benchmark zoo's sweeps, a two-mass resonance swept only in
//! the held-out part left every structure at 15 times the noise floor there, while the whole
//! sweep fitted gives the two-mass model at the noise floor). The held-out figure then measures
//! extrapolation, not the fit: [`beyond_estimation_band`] says so.
//!
//! The test compares the input's averaged periodograms (Welch: Hann windows, half overlap, the
//! same segment length on both parts, so that their bins match): the held-out input's power in
//! the bins where the estimation part's input power is below [`UNEXCITED`] of its strongest bin.

use super::init::welch;

/// A bin whose power is below this fraction of the strongest bin's is not excited (20 dB down:
/// a Hann window's leakage from an excited bin falls below it within a few bins).
pub const UNEXCITED: f64 = 1e-2;

/// The share of the held-out input's power outside the estimation part's band above which the
/// held-out figure is said to test the model beyond that band.
pub const BEYOND_SHARE: f64 = 0.2;

/// The shortest segment the periodograms are averaged over (samples); a held-out part shorter
/// than this is not tested.
const MIN_SEGMENT: usize = 64;

/// The longest segment (samples): enough bins to tell a sweep's bands apart.
const MAX_SEGMENT: usize = 1024;

/// Welch's averaged periodogram of `x` (at least `len` samples) on segments of `len` samples,
/// half overlap, each its mean removed and Hann-windowed as Welch's estimate does
/// ([`super::init::welch`]): `len / 2 + 1` bins, in arbitrary units (only ratios are used).
fn welch_power(x: &[f64], len: usize) -> Vec<f64> {
    let window = welch::hann(len);
    let mut power = vec![0.0; len / 2 + 1];
    let mut seg = vec![0.0; len];
    // Half-overlapping segments, and one ending at the last sample (a sweep's last frequencies
    // are in its last samples).
    let mut starts: Vec<usize> = (0..=x.len() - len).step_by(len / 2).collect();
    if starts.last() != Some(&(x.len() - len)) {
        starts.push(x.len() - len);
    }
    for start in starts {
        welch::windowed(&x[start..start + len], &window, &mut seg);
        for (p, c) in power.iter_mut().zip(&fracsim::fft::rfft(&seg)) {
            *p += c.norm_sqr();
        }
    }
    power
}

/// A held-out input excited beyond the estimation part's band ([`beyond_estimation_band`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beyond {
    /// The share of the held-out input's power at frequencies the estimation part does not excite.
    pub share: f64,
    /// The lowest and the highest frequency (Hz) the estimation part excites.
    pub band_hz: (f64, f64),
}

/// The held-out input (`u_held`) and the estimation part's (`u_est`), sampled every `dt`
/// seconds: [`Beyond`] when [`BEYOND_SHARE`] or more of the held-out input's power lies at
/// frequencies the estimation part does not excite; `None` otherwise, or when the held-out part
/// is shorter than [`MIN_SEGMENT`] samples. The constant (bin 0) is left out.
pub fn beyond_estimation_band(u_est: &[f64], u_held: &[f64], dt: f64) -> Option<Beyond> {
    let shorter = u_est.len().min(u_held.len());
    if shorter < MIN_SEGMENT {
        return None;
    }
    let len = (1usize << shorter.ilog2()).min(MAX_SEGMENT);
    let (pe, ph) = (welch_power(u_est, len), welch_power(u_held, len));
    let peak = pe[1..].iter().copied().fold(0.0, f64::max);
    let total: f64 = ph[1..].iter().sum();
    if !(peak > 0.0 && total > 0.0) {
        return None;
    }
    let unexcited = |k: usize| pe[k] < UNEXCITED * peak;
    let outside: f64 = (1..ph.len()).filter(|&k| unexcited(k)).map(|k| ph[k]).sum();
    let share = outside / total;
    if share < BEYOND_SHARE {
        return None;
    }
    let lowest = (1..pe.len()).find(|&k| !unexcited(k))?;
    let highest = (1..pe.len()).rev().find(|&k| !unexcited(k))?;
    let hz = |k: usize| k as f64 / (len as f64 * dt);
    Some(Beyond {
        share,
        band_hz: (hz(lowest), hz(highest)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear sweep from 1 to 200 Hz over 2 s at 1 kHz: its last 30% lies beyond what its first
    /// 70% excites; a random binary sequence's two parts excite the same band.
    #[test]
    fn a_sweeps_last_frequencies_lie_beyond_its_first_ones() {
        let (n, dt) = (2000, 1e-3);
        let t_end = n as f64 * dt;
        let sweep: Vec<f64> = (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                let phase = 2.0 * std::f64::consts::PI * (t + 199.0 * t * t / (2.0 * t_end));
                phase.sin()
            })
            .collect();
        let split = 1400;
        let b = beyond_estimation_band(&sweep[..split], &sweep[split..], dt).expect("a sweep");
        assert!(b.share > 0.8, "{b:?}");
        // the first 70% sweeps 1 to 1 + 199 * 0.7 = 140 Hz (its last samples tapered by the
        // window of the segment that ends there)
        assert!(
            b.band_hz.0 < 5.0 && (125.0..=150.0).contains(&b.band_hz.1),
            "{b:?}"
        );
        let prbs = crate::testdata::random_binary(n, 5, 0x2545_f491_4f6c_dd1d);
        assert_eq!(
            beyond_estimation_band(&prbs[..split], &prbs[split..], dt),
            None
        );
        // too short a held-out part is not tested
        assert_eq!(
            beyond_estimation_band(&sweep[..1960], &sweep[1960..], dt),
            None
        );
    }
}
