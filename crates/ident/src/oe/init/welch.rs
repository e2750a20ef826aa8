//! The frequency response of a record whose input is not periodic (a PRBS not repeated, a random
//! binary sequence, noise): Welch's averaged periodograms and the H1 estimate
//! `H = S_yu / S_uu` (Bendat & Piersol 2010, ch. 9; Pintelon & Schoukens 2012, section 2.6),
//! with the coherence choosing the frequencies it can be trusted at.
//!
//! The record (its leading [`MAX_FRF_SAMPLES`] samples at most) is cut into segments of `L`
//! samples, `L` the largest power of two with at least five half-overlapping segments (between
//! [`MIN_SEGMENT`] and [`MAX_SEGMENT`]): long segments resolve a lightly damped resonance (the
//! Hann window's main lobe is four bins wide), more of them lower the variance. Each segment, its
//! mean removed, is Hann-windowed and transformed by the workspace's one FFT
//! ([`fracsim::fft::rfft`]); at each bin `S_uu = sum |U|^2`, `S_yy = sum |Y|^2`,
//! `S_yu = sum Y conj(U)` over the segments.
//!
//! A bin is kept when it lies up to a quarter of the Nyquist frequency, its input power is at
//! least 1% of the largest (a PRBS's spectral nulls; [`h1_coherent`] keeps less inside a
//! coherent band) and its coherence `g2 = |S_yu|^2 / (S_uu S_yy)` is at least 1/2 (an output
//! signal-to-noise power ratio of at least 1, the rule of the periodic estimate). Its weight is
//! the inverse variance of the estimate, `var H = S_vv / (n_seg S_uu)` with the noise spectrum
//! `S_vv = (1 - g2) S_yy` smoothed by a running median over 9 bins (a few segments give it few
//! degrees of freedom). The input is held over each step, so the sampled response is divided by
//! the hold ([`crate::hold::zoh`]), as for the periodic estimate.

use super::{Frf, MAX_FRACTION_OF_NYQUIST, MAX_FRF_SAMPLES, MIN_HARMONICS};
use crate::{Error, Result};
use num_complex::Complex64;
use std::f64::consts::PI;

/// The shortest segment (64 samples give 16 bins up to a quarter of the Nyquist frequency).
pub const MIN_SEGMENT: usize = 64;

/// The longest segment.
pub const MAX_SEGMENT: usize = 1 << 13;

/// The fewest half-overlapping segments averaged.
pub const MIN_SEGMENTS: usize = 5;

/// [`h1`] leaves out bins with less input power than this fraction of the largest.
pub const MIN_INPUT_POWER: f64 = 0.01;

/// Bins with a coherence below this are left out.
const MIN_COHERENCE: f64 = 0.5;

/// Welch's estimate of the frequency response of deviations `y` over `u` sampled every `dt`
/// seconds (see the module documentation), with a sentence saying how it was made (segments,
/// length, frequencies kept).
///
/// # Errors
/// [`Error::NotEnoughData`] when the record is too short for [`MIN_SEGMENTS`] segments of
/// [`MIN_SEGMENT`] samples, the input has no power, or fewer than 6 frequencies are kept.
pub fn h1(u: &[f64], y: &[f64], dt: f64) -> Result<(Frf, String)> {
    estimate(u, y, dt, MAX_FRACTION_OF_NYQUIST, LowPower::Dropped)
}

/// [`h1`] with the bins of little input power kept inside a coherent band.
///
/// The two-mass start's estimate: an input held over many samples (a PRBS clocked at a tenth of
/// the motor's time constant or slower, a few levels held for a third of it or longer) has most
/// of its power below the motor's corner, and at a drive train's resonance, a decade or more
/// higher, 0.01-1% of its largest; the response there is large and its coherence near 1 (the
/// zoo's PRBS and multi-level records of a two-mass drive: 0.86-0.99 over their resonance at
/// 114-126 Hz, input power 0.05-0.9% of the largest), and the 1% rule of [`h1`] left the whole
/// resonance out. The coherence is the estimate's own test of a bin, and the weight (its inverse
/// variance, `S_uu` over the noise spectrum) already gives a bin of little input power little
/// say. Where the input has little power, though, the output's noise alone gives a bin a
/// coherence above 1/2 now and then (five segments: one bin in sixteen), with a response that is
/// noise: such a bin below 1% of the largest input power is kept only inside a band that is
/// coherent, the median coherence of the [`BAND_BINS`] bins around it at least 1/2 too (on the
/// zoo's multi-level record above, six isolated bins from 169 to 540 Hz, at 1.4-19 times the
/// true response, turned the two-mass start's quartic Levy fit to the order 0.5, whose pair is
/// unstable; without them it fits at the order 1 near the truth). A bin with no input power at
/// all is left out.
///
/// # Errors
/// As [`h1`].
pub fn h1_coherent(u: &[f64], y: &[f64], dt: f64) -> Result<(Frf, String)> {
    estimate(u, y, dt, MAX_FRACTION_OF_NYQUIST, LowPower::InCoherentBand)
}

/// [`h1`] with the bins kept up to `fraction` of the Nyquist frequency (instead of
/// [`MAX_FRACTION_OF_NYQUIST`]): the two-mass start's fallback looks for resonance peaks up to
/// half the Nyquist frequency ([`super::two_mass::PEAK_FRACTION_OF_NYQUIST`]) on it.
///
/// # Errors
/// As [`h1`].
pub fn h1_up_to(u: &[f64], y: &[f64], dt: f64, fraction: f64) -> Result<(Frf, String)> {
    estimate(u, y, dt, fraction, LowPower::Dropped)
}

/// The bins around a bin (itself in the middle) whose median coherence decides whether
/// [`h1_coherent`] keeps a bin of little input power.
pub const BAND_BINS: usize = 5;

/// What becomes of a bin with less input power than [`MIN_INPUT_POWER`] times the largest.
#[derive(Clone, Copy, PartialEq, Eq)]
enum LowPower {
    /// Left out ([`h1`]).
    Dropped,
    /// Kept inside a coherent band ([`h1_coherent`]).
    InCoherentBand,
}

/// Welch's estimate with the bins kept up to `fraction` of the Nyquist frequency whose coherence
/// is at least [`MIN_COHERENCE`] and whose input power is positive and at least
/// [`MIN_INPUT_POWER`] times the largest, or, by `low_power`, inside a coherent band.
fn estimate(
    u: &[f64],
    y: &[f64],
    dt: f64,
    fraction: f64,
    low_power: LowPower,
) -> Result<(Frf, String)> {
    let n = u.len().min(y.len()).min(MAX_FRF_SAMPLES);
    // Segments of l samples every l/2: (n - l)/(l/2) + 1 >= MIN_SEGMENTS.
    let fits = |l: usize| l <= n && (n - l) / (l / 2) + 1 >= MIN_SEGMENTS;
    if !fits(MIN_SEGMENT) {
        return Err(Error::NotEnoughData(format!(
            "{n} samples: too few for {MIN_SEGMENTS} segments of {MIN_SEGMENT} (Welch's estimate)"
        )));
    }
    let mut l = MIN_SEGMENT;
    while l < MAX_SEGMENT && fits(2 * l) {
        l *= 2;
    }
    let hop = l / 2;
    let segments = (n - l) / hop + 1;
    let win = hann(l);
    let top = ((fraction * l as f64 / 2.0).floor() as usize).min(l / 2);
    let mut suu = vec![0.0; top + 1];
    let mut syy = vec![0.0; top + 1];
    let mut syu = vec![Complex64::new(0.0, 0.0); top + 1];
    let mut seg = vec![0.0; l];
    for s in 0..segments {
        let r = s * hop..s * hop + l;
        windowed(&u[r.clone()], &win, &mut seg);
        let uf = fracsim::fft::rfft(&seg);
        windowed(&y[r], &win, &mut seg);
        let yf = fracsim::fft::rfft(&seg);
        for k in 1..=top {
            suu[k] += uf[k].norm_sqr();
            syy[k] += yf[k].norm_sqr();
            syu[k] += yf[k] * uf[k].conj();
        }
    }
    let umax = suu.iter().copied().fold(0.0, f64::max);
    if !(umax > 0.0 && umax.is_finite()) {
        return Err(Error::NotEnoughData(
            "the input has no excitation (Welch's estimate)".into(),
        ));
    }
    let bins = kept_bins((&suu, &syy, &syu), umax, low_power);
    // The noise spectrum smoothed by a running median over 9 neighbouring bins.
    let smooth: Vec<f64> = (0..bins.len())
        .map(|i| {
            let mut w: Vec<f64> = bins[i.saturating_sub(4)..(i + 5).min(bins.len())]
                .iter()
                .map(|b| b.noise)
                .collect();
            w.sort_by(f64::total_cmp);
            w[w.len() / 2]
        })
        .collect();
    let floor = 1e-12 * syy.iter().copied().fold(0.0, f64::max);
    let mut frf = Frf {
        omega: vec![],
        h: vec![],
        weight: vec![],
        period: None,
        periods_averaged: 0,
        periods_available: 0,
    };
    for (b, &noise) in bins.iter().zip(&smooth) {
        if b.coherence < MIN_COHERENCE {
            continue;
        }
        let w = 2.0 * PI * b.k as f64 / (l as f64 * dt);
        frf.omega.push(w);
        frf.h.push(b.h / crate::hold::zoh(w, dt));
        frf.weight
            .push(b.suu / noise.max(floor).max(f64::MIN_POSITIVE));
    }
    if frf.omega.len() < MIN_HARMONICS {
        return Err(Error::NotEnoughData(format!(
            "{} frequencies with a coherence of at least {MIN_COHERENCE} in Welch's estimate \
             ({segments} segments of {l} samples; need {MIN_HARMONICS})",
            frf.omega.len()
        )));
    }
    let mean = frf.weight.iter().sum::<f64>() / frf.weight.len() as f64;
    for w in &mut frf.weight {
        *w /= mean;
    }
    let how = format!(
        "Welch's estimate (the input is not periodic): {segments} half-overlapping Hann segments \
         of {l} samples, {} frequencies with a coherence of at least {MIN_COHERENCE}",
        frf.omega.len()
    );
    Ok((frf, how))
}

/// A bin of Welch's estimate: its index, `H = S_yu / S_uu`, `S_uu`, the noise spectrum
/// `(1 - g2) S_yy` and the coherence `g2`.
struct Bin {
    k: usize,
    h: Complex64,
    suu: f64,
    noise: f64,
    coherence: f64,
}

/// The bins `1..` of the spectra with input and output power, the input's at least
/// [`MIN_INPUT_POWER`] of the largest (`umax`) or (`low_power`) the median coherence of the [`BAND_BINS`]
/// bins around at least [`MIN_COHERENCE`] (the coherence rule of each bin itself is applied
/// later, after the noise is smoothed over its neighbours).
fn kept_bins(
    (suu, syy, syu): (&[f64], &[f64], &[Complex64]),
    umax: f64,
    low_power: LowPower,
) -> Vec<Bin> {
    let top = suu.len() - 1;
    let coherence: Vec<f64> = (0..=top)
        .map(|k| {
            if k > 0 && suu[k] > 0.0 && syy[k] > 0.0 {
                (syu[k].norm_sqr() / (suu[k] * syy[k])).min(1.0)
            } else {
                0.0
            }
        })
        .collect();
    let in_band = |k: usize| {
        let half = BAND_BINS / 2;
        let mut c = coherence[k.saturating_sub(half).max(1)..=(k + half).min(top)].to_vec();
        c.sort_by(f64::total_cmp);
        c[c.len() / 2] >= MIN_COHERENCE
    };
    (1..=top)
        .filter(|&k| suu[k] > 0.0 && syy[k] > 0.0)
        .filter(|&k| {
            suu[k] >= MIN_INPUT_POWER * umax
                || (low_power == LowPower::InCoherentBand && in_band(k))
        })
        .map(|k| Bin {
            k,
            h: syu[k] / suu[k],
            suu: suu[k],
            noise: (1.0 - coherence[k]) * syy[k],
            coherence: coherence[k],
        })
        .collect()
}

/// The Hann window of `l` samples (periodic: `0.5 - 0.5 cos(2 pi k / l)`).
pub(crate) fn hann(l: usize) -> Vec<f64> {
    (0..l)
        .map(|k| 0.5 - 0.5 * (2.0 * PI * k as f64 / l as f64).cos())
        .collect()
}

/// The segment `x` with its mean removed, times the window `win`, into `out`.
pub(crate) fn windowed(x: &[f64], win: &[f64], out: &mut [f64]) {
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    for ((o, &v), &w) in out.iter_mut().zip(x).zip(win) {
        *o = (v - mean) * w;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A noise-free record of a known discrete-time system `y_k = 0.6 y_(k-1) + 0.5 u_(k-1)`
    /// (`G(z) = 0.5 z^-1 / (1 - 0.6 z^-1)`) driven by a random binary sequence: the estimate (with
    /// the hold multiplied back) is `G(e^(j w dt))` at every kept frequency, within the leakage of
    /// a 2048-sample Hann window on this smooth response (measured 5.3e-3; bound 1e-2), and every
    /// frequency up to a quarter of the Nyquist one is kept (coherence 1 but for leakage).
    #[test]
    fn h1_is_the_response_of_a_known_system() {
        let dt = 1e-3;
        let mut lcg = crate::testdata::lcg(12345);
        let u: Vec<f64> = (0..8192)
            .map(|_| if lcg() >> 63 == 1 { 1.0 } else { -1.0 })
            .collect();
        let mut y = vec![0.0; u.len()];
        for k in 1..u.len() {
            y[k] = 0.6 * y[k - 1] + 0.5 * u[k - 1];
        }
        let (frf, how) = h1(&u, &y, dt).unwrap();
        assert!(how.contains("of 2048 samples"), "{how}");
        assert_eq!(frf.omega.len(), 256, "{how}");
        let mut worst = 0.0f64;
        for (&w, &h) in frf.omega.iter().zip(&frf.h) {
            let z1 = Complex64::from_polar(1.0, -w * dt);
            let g = 0.5 * z1 / (1.0 - 0.6 * z1);
            worst = worst.max((h * crate::hold::zoh(w, dt) - g).norm() / g.norm());
        }
        eprintln!("largest relative error {worst:.2e}");
        assert!(worst < 1e-2, "{worst}");
    }

    /// Output noise lowers the coherence where the output is small: with white noise much larger
    /// than the response of a low-pass system at high frequencies, only the low ones are kept,
    /// and a short record or an input without excitation is refused.
    #[test]
    fn the_coherence_chooses_the_frequencies() {
        let dt = 1e-3;
        let mut lcg = crate::testdata::lcg(99);
        let mut next = || (lcg() >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        let u: Vec<f64> = (0..8192)
            .map(|_| if next() > 0.0 { 1.0 } else { -1.0 })
            .collect();
        let mut y = vec![0.0; u.len()];
        // A sharp low-pass (pole at 0.99: corner near 1.6 Hz), then noise of std 0.3.
        for k in 1..u.len() {
            y[k] = 0.99 * y[k - 1] + 0.01 * u[k - 1];
        }
        let clean = y.clone();
        for v in &mut y {
            *v += 0.3 * 12f64.sqrt() * next();
        }
        let (noisy, _) = h1(&u, &y, dt).unwrap();
        let (exact, _) = h1(&u, &clean, dt).unwrap();
        // Signal-to-noise power ratio 1 near 5 Hz: all bins up to 2 Hz kept (ratio above 4),
        // above 30 Hz (ratio below 0.03) only the few whose coherence estimate from 7 segments
        // exceeds 1/2 by chance.
        let hz = |f: &Frf| -> Vec<f64> { f.omega.iter().map(|w| w / (2.0 * PI)).collect() };
        let (fa, fn_) = (hz(&exact), hz(&noisy));
        let count = |f: &[f64], p: &dyn Fn(f64) -> bool| f.iter().filter(|&&x| p(x)).count();
        assert_eq!(count(&fn_, &|x| x <= 2.0), count(&fa, &|x| x <= 2.0));
        let high = count(&fn_, &|x| x > 30.0);
        eprintln!(
            "kept {} of {} bins, {high} of {} above 30 Hz",
            fn_.len(),
            fa.len(),
            count(&fa, &|x| x > 30.0)
        );
        assert!(
            high * 20 < count(&fa, &|x| x > 30.0),
            "{high} bins above 30 Hz kept"
        );
        assert!(h1(&u[..300], &y[..300], dt).is_err());
        assert!(h1(&vec![1.0; 4096], &y[..4096], dt).is_err());
    }
}
