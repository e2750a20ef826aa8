//! The band a record excites: where the input has power and the plant's response to it stands
//! above the noise. The frequency-response error is scored over this band alone.
//!
//! Definition: the periodograms of the input `U_k` (mean removed) and of the noise `N_k` (the
//! noisy record minus the noise-free truth, quantisation included) are averaged over log-spaced
//! bins, six per decade, from the record's lowest frequency `1/(n dt)` to `0.45/dt`. A bin is in
//! the band when (a) its mean input power is within 40 dB of the strongest bin's and (b) the mean of
//! `|G(j w_k)|^2 |U_k|^2` (the plant's linear response to the input) is at least 10 times the
//! noise's mean power `|N_k|^2` (10 dB signal to noise). The band's frequencies are the bins'
//! geometric-mean frequencies [rad/s].

use realfft::RealFftPlanner;

use crate::truth::Plant;

/// Bins per decade.
const PER_DECADE: f64 = 6.0;
/// The input power a bin needs, relative to the strongest bin (40 dB).
const INPUT_FLOOR: f64 = 1e-4;
/// The signal-to-noise power a bin needs (10 dB).
const SNR_MIN: f64 = 10.0;
/// The highest frequency scored, in units of the sample rate.
const TOP_FRACTION: f64 = 0.45;

fn power_spectrum(x: &[f64]) -> Vec<f64> {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let mut buf: Vec<f64> = x.iter().map(|v| v - mean).collect();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut spec = fft.make_output_vec();
    // The buffers have the lengths the plan made: the transform cannot fail.
    fft.process(&mut buf, &mut spec)
        .expect("FFT buffers of the planned length");
    spec.iter().map(|c| c.norm_sqr()).collect()
}

/// The band's frequencies [rad/s] (empty when nothing is excited above the noise).
pub fn excited(plant: &Plant, u: &[f64], noise: &[f64], dt: f64) -> Vec<f64> {
    let n = u.len();
    if n < 8 || noise.len() != n {
        return Vec::new();
    }
    let su = power_spectrum(u);
    let sn = power_spectrum(noise);
    let df = 1.0 / (n as f64 * dt);
    let f_top = TOP_FRACTION / dt;
    let decades = (f_top / df).log10();
    let bins = (decades * PER_DECADE).ceil().max(1.0) as usize;
    let edge = |i: usize| df * 10f64.powf(i as f64 / PER_DECADE);
    struct Bin {
        input: f64,
        signal: f64,
        noise: f64,
        log_f: f64,
    }
    let mut stats = Vec::with_capacity(bins);
    for b in 0..bins {
        let (lo, hi) = (edge(b), edge(b + 1).min(f_top));
        let k_lo = (lo / df).ceil().max(1.0) as usize;
        let k_hi = ((hi / df).ceil() as usize).min(su.len());
        if k_lo >= k_hi {
            continue;
        }
        let count = (k_hi - k_lo) as f64;
        let (mut input, mut signal, mut noise_p, mut log_f) = (0.0, 0.0, 0.0, 0.0);
        for k in k_lo..k_hi {
            let f = k as f64 * df;
            let g = plant.response(std::f64::consts::TAU * f).norm_sqr();
            input += su[k];
            signal += g * su[k];
            noise_p += sn[k];
            log_f += f.ln();
        }
        stats.push(Bin {
            input: input / count,
            signal: signal / count,
            noise: noise_p / count,
            log_f: log_f / count,
        });
    }
    let top = stats.iter().map(|b| b.input).fold(0.0, f64::max);
    stats
        .iter()
        .filter(|b| b.input >= INPUT_FLOOR * top && b.input > 0.0 && b.signal >= SNR_MIN * b.noise)
        .map(|b| std::f64::consts::TAU * b.log_f.exp())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::truth::Term;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn first_order() -> Plant {
        Plant {
            num: vec![Term {
                coef: 5.0,
                order: 0.0,
            }],
            den: vec![
                Term {
                    coef: 0.01,
                    order: 1.0,
                },
                Term {
                    coef: 1.0,
                    order: 0.0,
                },
            ],
            delay_s: 0.0,
        }
    }

    #[test]
    fn a_prbs_excites_around_the_corner_and_heavy_noise_hides_it() {
        let mut rng = StdRng::seed_from_u64(1);
        let n = 4000;
        let mut u = Vec::with_capacity(n);
        let mut level = 1.0;
        while u.len() < n {
            if rng.gen_bool(0.5) {
                level = -level;
            }
            u.extend([level; 5]);
        }
        u.truncate(n);
        let noise = |sigma: f64, rng: &mut StdRng| -> Vec<f64> {
            (0..n)
                .map(|_| sigma * rng.gen_range(-1.0_f64..1.0) * 3f64.sqrt())
                .collect()
        };
        let dt = 1e-3;
        let quiet = noise(0.05, &mut rng);
        let band = excited(&first_order(), &u, &quiet, dt);
        // The corner (100 rad/s) is inside, the band spans more than a decade.
        assert!(band.len() >= 6, "{band:?}");
        assert!(band[0] < 100.0 && *band.last().unwrap() > 100.0, "{band:?}");
        assert!(band.iter().all(|w| *w <= std::f64::consts::TAU * 0.45 / dt));
        // Noise far above the response everywhere: no band.
        let loud = noise(1e3, &mut rng);
        assert!(excited(&first_order(), &u, &loud, dt).is_empty());
    }
}
