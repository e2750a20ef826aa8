//! The band a record excites as a model sees it: the frequencies where the input has power and
//! the model's response to it stands above the fit's error. A record that excites less than half
//! a decade so does not determine the plant: any structure fitted to it is a guess outside that
//! band, however well it predicts the record.
//!
//! Definition (the benchmark zoo's identifiability rule, `benches/zoo/src/cases/band.rs`, with
//! the fitted model in the plant's place and the fit's error in the noise's): the input's
//! periodogram `|U_k|^2 / n` (mean removed, [`fracsim::fft::periodogram`]) is averaged over log-spaced bins, [`PER_DECADE`] per
//! decade, from the record's lowest frequency `1/(n dt)` to `0.45/dt`. A bin is excited when its
//! mean input power is within 40 dB of the strongest bin's, and both the mean of
//! `|G(j w_k)|^2 |U_k|^2` (the model's response to the input) and the mean of the measured
//! output's periodogram `|Y_k|^2 / n` are at least 10 times the power a white error of
//! the fit's estimation RMSE `sigma` puts in a bin: 10 dB signal to noise. The
//! output's own power keeps a model's guess out of the count: a model with an integrator the
//! plant lacks has a large response at frequencies where the record shows none (the zoo's
//! in-motion case 0174, not identifiable: six bins by the model's response alone, two by both,
//! as by the truth). The error holds the model's misfit as well as the noise.

use fracsim::FracTf;

/// Bins per decade.
pub const PER_DECADE: f64 = 6.0;

/// The input power a bin needs, relative to the strongest bin (40 dB).
const INPUT_FLOOR: f64 = 1e-4;

/// The signal-to-noise power a bin needs (10 dB).
const SNR_MIN: f64 = 10.0;

/// The highest frequency counted, in units of the sample rate.
const TOP_FRACTION: f64 = 0.45;

/// The fewest excited bins (half a decade) with which a record determines a plant.
pub const FEWEST: usize = 3;

/// How many bins of the record `u`, `y` (sampled every `dt` seconds) `tf`'s response and the
/// output stand 10 dB above a white error of RMSE `sigma` in (see the module documentation);
/// `None` for a record shorter than 8 samples, an input without power, an output of another
/// length or an error that is not positive and finite.
pub fn excited_bins(tf: &FracTf, (u, y): (&[f64], &[f64]), dt: f64, sigma: f64) -> Option<usize> {
    let n = u.len();
    if n < 8 || y.len() != n || !(sigma > 0.0 && sigma.is_finite()) {
        return None;
    }
    let (su, sy) = (
        fracsim::fft::periodogram(u).1,
        fracsim::fft::periodogram(y).1,
    );
    let df = 1.0 / (n as f64 * dt);
    let f_top = TOP_FRACTION / dt;
    let bins = ((f_top / df).log10() * PER_DECADE).ceil().max(1.0) as usize;
    let edge = |i: usize| df * 10f64.powf(i as f64 / PER_DECADE);
    // (mean input power, the smaller of the mean response and output powers) of each bin that
    // holds a frequency
    let stats: Vec<(f64, f64)> = (0..bins)
        .filter_map(|b| {
            let (lo, hi) = (edge(b), edge(b + 1).min(f_top));
            let k_lo = (lo / df).ceil().max(1.0) as usize;
            let k_hi = ((hi / df).ceil() as usize).min(su.len());
            (k_lo < k_hi).then(|| {
                let count = (k_hi - k_lo) as f64;
                let (input, signal, output) = (k_lo..k_hi).fold((0.0, 0.0, 0.0), |(i, s, o), k| {
                    let g = tf
                        .freq_response(std::f64::consts::TAU * k as f64 * df)
                        .norm_sqr();
                    (i + su[k], s + g * su[k], o + sy[k])
                });
                (input / count, signal.min(output) / count)
            })
        })
        .collect();
    let top = stats.iter().map(|b| b.0).fold(0.0, f64::max);
    if top <= 0.0 {
        return None;
    }
    // a white error's periodogram bin, on average
    let noise = sigma * sigma;
    Some(
        stats
            .iter()
            .filter(|&&(input, signal)| input >= INPUT_FLOOR * top && signal >= SNR_MIN * noise)
            .count(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn first_order() -> FracTf {
        "5/(0.01 s + 1)".parse().unwrap()
    }

    /// `5/(0.01 s + 1)`'s response to `u` held between samples `dt` apart (exact).
    fn respond(u: &[f64], dt: f64) -> Vec<f64> {
        crate::testdata::first_order_held(u, dt, 0.01, 5.0)
    }

    /// A PRBS-like input excites every bin up to the plant's corner and beyond: many bins; a
    /// pure sine one bin; an error as large as the response none; a model that claims a response
    /// the output does not show counts nothing there.
    #[test]
    fn a_broad_input_excites_many_bins_and_a_sine_one() {
        let dt = 1e-3;
        let n = 4000;
        let prbs = crate::testdata::random_binary(n, 1, 0x2545_f491);
        let y = respond(&prbs, dt);
        let wide = excited_bins(&first_order(), (&prbs, &y), dt, 0.05).unwrap();
        assert!(wide >= 10, "{wide}");
        let sine: Vec<f64> = (0..n)
            .map(|k| (std::f64::consts::TAU * 10.0 * k as f64 * dt).sin())
            .collect();
        let ys = respond(&sine, dt);
        let narrow = excited_bins(&first_order(), (&sine, &ys), dt, 0.05).unwrap();
        assert!((1..FEWEST).contains(&narrow), "{narrow}");
        // an error the size of the response: nothing stands 10 dB above it
        assert_eq!(excited_bins(&first_order(), (&prbs, &y), dt, 5.0), Some(0));
        // a model whose response the output does not show (an output a hundred times smaller)
        let small: Vec<f64> = y.iter().map(|v| 0.01 * v).collect();
        assert_eq!(
            excited_bins(&first_order(), (&prbs, &small), dt, 0.05),
            Some(0)
        );
        let flat = [1.0; 100];
        assert_eq!(excited_bins(&first_order(), (&flat, &flat), dt, 0.05), None);
        assert_eq!(excited_bins(&first_order(), (&prbs, &y), dt, 0.0), None);
    }
}
