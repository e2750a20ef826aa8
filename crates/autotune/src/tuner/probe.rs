//! The probe: a small voltage step from rest, read for the plant's gain, delay, time constant
//! and whether it settles (a first-order-plus-delay reading of the step: Smith's two-point
//! method at 28.3% and 63.2%).

use serde::Serialize;

/// What a step from rest says of the plant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ProbeReading {
    /// The step's level, V.
    pub level_v: f64,
    /// The final speed (mean of the last 15% of the record), rad/s.
    pub final_speed: f64,
    /// Static gain, (rad/s)/V (the final speed over the level: friction lowers it).
    pub gain: f64,
    /// Apparent delay, s (Smith: `t63 - T`, at least 0).
    pub delay_s: f64,
    /// Apparent time constant, s (Smith: `1.5 (t63 - t28)`).
    pub time_constant_s: f64,
    /// The speed's noise: the standard deviation of the last 15% about its trend, rad/s.
    pub noise: f64,
    /// Whether the response settled: its last 15% moves by less than 3% of the final speed
    /// beyond the noise.
    pub settled: bool,
    /// The largest speed reached, rad/s.
    pub peak_speed: f64,
}

impl ProbeReading {
    /// The bandwidth the reading suggests, rad/s (`1/T`).
    pub fn bandwidth_rad_s(&self) -> f64 {
        1.0 / self.time_constant_s.max(1e-6)
    }

    /// The time the plant takes to settle after a change, s (delay plus four time constants).
    pub fn settling_s(&self) -> f64 {
        self.delay_s + 4.0 * self.time_constant_s
    }

    /// Whether the response stands out of the noise (the final speed over 20 noise levels and
    /// over `floor`).
    pub fn visible(&self, floor: f64) -> bool {
        self.final_speed.abs() > (20.0 * self.noise).max(floor)
    }
}

/// Read a step from rest of `level_v` volts: `t` from the step (s), `y` the speed (rad/s).
/// `None` for fewer than 20 samples or a zero level.
pub fn read(t: &[f64], y: &[f64], level_v: f64) -> Option<ProbeReading> {
    let n = t.len().min(y.len());
    if n < 20 || level_v == 0.0 {
        return None;
    }
    let tail = (n * 15 / 100).max(5);
    let last = &y[n - tail..n];
    let mean = last.iter().sum::<f64>() / tail as f64;
    // the tail's trend (least squares line) and the scatter about it
    let tt = &t[n - tail..n];
    let tm = tt.iter().sum::<f64>() / tail as f64;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (ti, yi) in tt.iter().zip(last) {
        sxy += (ti - tm) * (yi - mean);
        sxx += (ti - tm) * (ti - tm);
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let noise = (last
        .iter()
        .zip(tt)
        .map(|(yi, ti)| (yi - mean - slope * (ti - tm)).powi(2))
        .sum::<f64>()
        / tail as f64)
        .sqrt();
    let drift = (slope * (tt[tail - 1] - tt[0])).abs();
    let settled = drift <= 0.03 * mean.abs() + 3.0 * noise;
    let t0 = t[0];
    let cross = |frac: f64| -> Option<f64> {
        let lvl = frac * mean;
        let k = y.iter().position(|v| (v - lvl) * mean.signum() >= 0.0)?;
        if k == 0 {
            return Some(0.0);
        }
        let (ya, yb) = (y[k - 1], y[k]);
        let w = if yb != ya {
            (lvl - ya) / (yb - ya)
        } else {
            1.0
        };
        Some(t[k - 1] - t0 + w * (t[k] - t[k - 1]))
    };
    let dt = (t[n - 1] - t0) / (n - 1) as f64;
    let (t28, t63) = (cross(0.283)?, cross(0.632)?);
    let time_constant_s = (1.5 * (t63 - t28)).max(dt);
    let delay_s = (t63 - time_constant_s).max(0.0);
    Some(ProbeReading {
        level_v,
        final_speed: mean,
        gain: mean / level_v,
        delay_s,
        time_constant_s,
        noise,
        settled,
        peak_speed: y.iter().fold(0.0f64, |a, v| a.max(v.abs())),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A first-order step with a delay is read back: gain, delay and time constant (Smith's
    /// method is exact for a first order plus delay, up to the sampling).
    #[test]
    fn reads_a_first_order_plus_delay() {
        let (k, tau, delay, dt) = (5.0, 0.02, 0.003, 1e-3);
        let t: Vec<f64> = (0..400).map(|i| i as f64 * dt).collect();
        let y: Vec<f64> = t
            .iter()
            .map(|&t| {
                if t < delay {
                    0.0
                } else {
                    2.0 * k * (1.0 - (-(t - delay) / tau).exp())
                }
            })
            .collect();
        let r = read(&t, &y, 2.0).unwrap();
        assert!((r.gain - k).abs() < 1e-3 * k, "{r:?}");
        assert!((r.time_constant_s - tau).abs() < 0.05 * tau, "{r:?}");
        assert!((r.delay_s - delay).abs() < 1.0e-3, "{r:?}");
        assert!(r.settled && r.visible(0.1));
        // a ramp has not settled
        let ramp: Vec<f64> = t.iter().map(|t| 10.0 * t).collect();
        assert!(!read(&t, &ramp, 1.0).unwrap().settled);
    }
}
