//! The drive's speed controller in fixed point (PROTOCOL.md section 3, "Speed loop"): parallel
//! first-order sections in Q-format, the realisation LOAD_CTRL / LOAD_SECTION carry, and the
//! conversion of a discrete state space (`fracid tune --dt`'s realisation) to it.
//!
//! Per sample, with the error `e = r - y` in raw speed LSB (an integer):
//!
//! ```text
//! v  = 2^8 d e + sum_i z_i                    (Q32 raw voltage, 64-bit)
//! u  = round(v / 2^32), clamped to +-u_limit  (the voltage limit)
//! e' = e                                      (not clamped)
//!    = (2^32 u - sum z_i) / d                 (clamped, d != 0: Hanus' conditioning)
//!    = 0 (states frozen) if the error pushes further into the clamp, else e  (clamped, d = 0)
//! z_i <- round(a_i z_i / 2^30) + 2^8 g_i e'   (saturated at +-2^56)
//! ```
//!
//! `d`, `g_i` are Q24 (raw voltage LSB per raw speed LSB), `a_i` Q30, the states `z_i` 64-bit
//! Q32 raw voltage.
//!
//! Why parallel first-order sections (the modal, diagonal state space) rather than a dense state
//! space or a cascade of biquads, on a fixed-point C28x:
//!
//! - each pole is one Q30 coefficient `a_i = e^(p_i dt)`: its quantisation moves that pole alone
//!   by at most 2^-31, where a biquad's `a1 ~ -2`, `a2 ~ 1` place two poles near `z = 1` with an
//!   error amplified by their distance (the fractional integrator's poles sit from 1e-3 rad/s
//!   up, `1 - a ~ 1e-6` at 1 kHz);
//! - no scaling between sections and no overflow analysis per section: each state is that
//!   mode's share of the output, in 64 bits with 32 fractional bits. The shares of a fractional
//!   integrator of order above 1 cancel each other (`1/s` times the poles of `s^(1-lambda)`: the
//!   integrator's share is 100 times the output at 100 rad/s for the FOPI of wc = 50 rad/s on
//!   the paper's PMSM), which 32-bit states cannot hold; 64-bit states hold +-2^24 raw (16 kV at
//!   1 mV per LSB) at 2^-32 LSB, and the C28x adds 64 bits in two instructions;
//! - per section one 32x64-bit product (two 32x32 -> 64, C28x `IMPYL`/`QMPYL`) and one 32x32,
//!   no division (the anti-windup's `1/d` is sent precomputed);
//! - the anti-windup is exact: with the output clamped, the states are updated with the error
//!   that would have produced the clamped output, so they stay those of the applied input.
//!
//! The rounding of `a_i z_i` leaves a dead band of `0.5 / (1 - a_i)` 2^-32 LSB on the slowest
//! modes (1e-4 raw LSB for a pole at 1e-3 rad/s at 1 kHz).

use crate::error::{Error, Result};
use crate::protocol::{LoadCtrl, LoadSection, CTRL_FORMAT, MAX_SECTIONS};
use num_complex::Complex64;

/// One first-order section: `z <- a z + g e`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Section {
    /// Pole, Q30.
    pub a_q30: i32,
    /// Input gain, Q24 raw voltage per raw speed LSB.
    pub g_q24: i32,
}

/// Saturation of the states, Q32: +-2^24 raw voltage LSB.
pub const Z_MAX: i64 = 1 << 56;

/// The controller as the drive runs it.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct FixedCtrl {
    /// Feed-through, Q24 raw voltage per raw speed LSB.
    pub d_q24: i32,
    /// `1/d`, Q16 raw speed per raw voltage LSB (0: no feed-through).
    pub dinv_q16: i32,
    /// The sections.
    pub sections: Vec<Section>,
}

const Q24: f64 = (1u64 << 24) as f64;

/// `round(p / 2^s)`, half away from zero (as the C firmware: no shift of a negative number).
fn round_shift(p: i64, s: u32) -> i64 {
    let h = 1i64 << (s - 1);
    if p >= 0 {
        (p + h) >> s
    } else {
        -((-p + h) >> s)
    }
}

/// `round(a z / 2^30)`, half away from zero, `|a| <= 2^30`, `|z| <= 2^56`: two 32x32 -> 64
/// products of the magnitudes, as the C firmware computes it.
fn mul_q30(z: i64, a: i32) -> i64 {
    let m = z.unsigned_abs();
    let aa = a.unsigned_abs() as u64;
    let r = (aa * (m >> 32)) * 4 + ((aa * (m & 0xFFFF_FFFF) + (1 << 29)) >> 30);
    if (z < 0) != (a < 0) {
        -(r as i64)
    } else {
        r as i64
    }
}

impl FixedCtrl {
    /// One sample: the error `e = r - y` (raw speed LSB), the voltage limit (raw, > 0). Returns
    /// the clamped command (raw) and whether it was clamped; updates the states `z` (one per
    /// section, Q32). Bit-identical to the C firmware's `fw_ctrl_step` (tested).
    pub fn step(&self, z: &mut [i64], e: i32, u_limit: i16) -> (i16, bool) {
        let zsum: i64 = z.iter().sum();
        let v = self.d_q24 as i64 * e as i64 * 256 + zsum;
        let u = round_shift(v, 32);
        let lim = u_limit.max(1) as i64;
        let clamped = u > lim || u < -lim;
        let us = u.clamp(-lim, lim);
        let e_upd = if !clamped {
            e as i64
        } else if self.dinv_q16 != 0 {
            let diff = round_shift(us * (1i64 << 32) - zsum, 16)
                .clamp(-(i32::MAX as i64), i32::MAX as i64);
            round_shift(diff * self.dinv_q16 as i64, 32).clamp(-131_072, 131_072)
        } else if (u > lim && e > 0) || (u < -lim && e < 0) {
            return (us as i16, true); // conditional integration: the sections are frozen
        } else {
            e as i64
        };
        for (zi, s) in z.iter_mut().zip(&self.sections) {
            let p = mul_q30(*zi, s.a_q30) + s.g_q24 as i64 * e_upd * 256;
            *zi = p.clamp(-Z_MAX, Z_MAX);
        }
        (us as i16, clamped)
    }

    /// The LOAD_CTRL and LOAD_SECTION payloads that download it.
    pub fn messages(&self) -> (LoadCtrl, Vec<LoadSection>) {
        (
            LoadCtrl {
                format: CTRL_FORMAT,
                n_sections: self.sections.len() as u8,
                d_q24: self.d_q24,
                dinv_q16: self.dinv_q16,
            },
            self.sections
                .iter()
                .enumerate()
                .map(|(i, s)| LoadSection {
                    index: i as u8,
                    a_q30: s.a_q30,
                    g_q24: s.g_q24,
                })
                .collect(),
        )
    }

    /// The controller from its download (the drive's side of [`FixedCtrl::messages`]).
    pub fn from_messages(c: &LoadCtrl, s: &[LoadSection]) -> Self {
        Self {
            d_q24: c.d_q24,
            dinv_q16: c.dinv_q16,
            sections: s
                .iter()
                .map(|s| Section {
                    a_q30: s.a_q30,
                    g_q24: s.g_q24,
                })
                .collect(),
        }
    }

    /// Its frequency response in physical units (V per rad/s) at omega rad/s, sample period
    /// `dt` s, the channel scales `gain_raw = y_lsb / u_lsb` (V/LSB over rad/s/LSB): `(d + sum
    /// g_i / (z - a_i)) / gain_raw`, `z = e^(j omega dt)`, the coefficients as quantised.
    pub fn freq_response(&self, omega: f64, dt: f64, gain_raw: f64) -> Complex64 {
        let z = Complex64::from_polar(1.0, omega * dt);
        let c = self
            .sections
            .iter()
            .fold(Complex64::new(self.d_q24 as f64 / Q24, 0.0), |acc, s| {
                acc + (s.g_q24 as f64 / Q24) / (z - s.a_q30 as f64 / (1u64 << 30) as f64)
            });
        c / gain_raw
    }

    /// The fixed-point controller of the discrete state space `x_(k+1) = A x_k + B e_k`, `u_k =
    /// C x_k + D e_k` (e in rad/s, u in V), for channel scales `gain_raw = y_lsb / u_lsb`.
    ///
    /// States that do not reach the output and feed nothing, or that nothing drives, are
    /// dropped; `A` must then be lower triangular (the realisations of `tune::realise` are)
    /// with eigenvalues (its diagonal) of modulus at most 1, equal ones (within 1e-9) only
    /// between states that do not drive each other: the modes are found by
    /// forward substitution, `A = V diag(a) V^-1` with `V` unit lower triangular, and section
    /// `i` is `a_i`, `g_i = gain_raw (C V)_i (V^-1 B)_i` (its state is the mode's share of the
    /// output). Sections whose `g_i` rounds to 0 are left out.
    ///
    /// # Errors
    /// [`Error::InvalidParam`]: inconsistent sizes, non-finite entries, an `A` that is not lower
    /// triangular, coupled repeated poles or unstable ones, more than [`MAX_SECTIONS`]
    /// sections, a gain beyond the Q24 range (+-128 raw voltage per raw speed LSB).
    pub fn from_state_space(
        a: &[Vec<f64>],
        b: &[f64],
        c: &[f64],
        d: f64,
        gain_raw: f64,
    ) -> Result<Self> {
        fn bad<T>(m: String) -> Result<T> {
            Err(Error::InvalidParam(format!("controller: {m}")))
        }
        let n = a.len();
        if b.len() != n || c.len() != n || a.iter().any(|r| r.len() != n) {
            return bad(format!(
                "A is {n}x?, B has {}, C has {} entries: sizes differ",
                b.len(),
                c.len()
            ));
        }
        let all = a.iter().flatten().chain(b).chain(c).chain([&d, &gain_raw]);
        if all.clone().any(|v| !v.is_finite()) || !(gain_raw > 0.0) {
            return bad("non-finite entries or channel scales".into());
        }
        // drop states that are unobservable and feed nothing, or driven by nothing
        let mut keep: Vec<usize> = (0..n).collect();
        loop {
            let before = keep.len();
            let k2 = keep.clone();
            keep.retain(|&i| {
                let feeds = k2.iter().any(|&j| j != i && a[j][i] != 0.0);
                let driven = b[i] != 0.0 || k2.iter().any(|&j| j != i && a[i][j] != 0.0);
                (c[i] != 0.0 || feeds) && driven
            });
            if keep.len() == before {
                break;
            }
        }
        let m = keep.len();
        let scale = a.iter().flatten().fold(1.0f64, |s, v| s.max(v.abs()));
        for (p, &i) in keep.iter().enumerate() {
            for &j in &keep[p + 1..] {
                if a[i][j].abs() > 1e-12 * scale {
                    return bad(format!(
                        "A is not lower triangular (A[{i}][{j}] = {}): the drive runs parallel \
                         first-order sections of a triangular realisation",
                        a[i][j]
                    ));
                }
            }
        }
        let lam: Vec<f64> = keep.iter().map(|&i| a[i][i]).collect();
        if let Some(l) = lam.iter().find(|l| l.abs() > 1.0 + 1e-12) {
            return bad(format!("pole {l} outside the unit circle"));
        }
        // V: column p is the eigenvector of lam[p] (unit at p, zero above)
        let sub = |r: usize, s: usize| a[keep[r]][keep[s]];
        let mut v = vec![vec![0.0; m]; m];
        for p in 0..m {
            v[p][p] = 1.0;
            for r in p + 1..m {
                let s: f64 = (p..r).map(|k| sub(r, k) * v[k][p]).sum();
                if s == 0.0 {
                    continue; // not coupled: equal poles are two sections
                }
                if (lam[p] - lam[r]).abs() < 1e-9 {
                    return bad(format!(
                        "repeated pole {} coupled to itself (a double integrator, or a \
                         difference after a pole that rounds to 0): not a set of first-order \
                         sections",
                        lam[p]
                    ));
                }
                v[r][p] = s / (lam[p] - lam[r]);
            }
        }
        // w = V^-1 B by forward substitution (V unit lower triangular)
        let mut w = vec![0.0; m];
        for r in 0..m {
            w[r] = b[keep[r]] - (0..r).map(|k| v[r][k] * w[k]).sum::<f64>();
        }
        let cv: Vec<f64> = (0..m)
            .map(|p| (p..m).map(|r| c[keep[r]] * v[r][p]).sum())
            .collect();
        let q = |x: f64, scale: f64, what: &str| -> Result<i32> {
            let q = (x * scale).round();
            if q.abs() > i32::MAX as f64 {
                return bad(format!(
                    "{what} = {x} raw LSB per raw LSB is beyond its range (+-{}): other \
                     channel scales",
                    i32::MAX as f64 / scale
                ));
            }
            Ok(q as i32)
        };
        let mut sections = Vec::new();
        for p in 0..m {
            let g = q(gain_raw * cv[p] * w[p], Q24, "a section's gain")?;
            if g != 0 {
                sections.push(Section {
                    a_q30: (lam[p].clamp(-1.0, 1.0) * (1u64 << 30) as f64).round() as i32,
                    g_q24: g,
                });
            }
        }
        if sections.len() > MAX_SECTIONS as usize {
            return bad(format!(
                "{} sections (the drive takes at most {MAX_SECTIONS}): a lower approximation order",
                sections.len()
            ));
        }
        let d_raw = gain_raw * d;
        let d_q24 = q(d_raw, Q24, "the feed-through")?;
        let dinv_q16 = if d_raw.abs() >= 2.0 / 65536.0 {
            q(1.0 / d_raw, 65536.0, "1/feed-through").unwrap_or(0)
        } else {
            0
        };
        Ok(Self {
            d_q24,
            dinv_q16,
            sections,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A PI `kp + ki dt/(z - 1)` in raw units: the conversion gives one integrator section.
    #[test]
    fn pi_becomes_one_integrator_section() {
        let (kp, ki, dt) = (0.5, 20.0, 1e-3);
        let k = FixedCtrl::from_state_space(&[vec![1.0]], &[dt], &[ki], kp, 10.0).unwrap();
        assert_eq!(k.sections.len(), 1);
        assert_eq!(k.sections[0].a_q30, 1 << 30);
        assert_eq!(k.sections[0].g_q24, (10.0 * ki * dt * Q24).round() as i32);
        assert_eq!(k.d_q24, 5 << 24);
        assert_eq!(k.dinv_q16, 65536 / 5);
        // a constant error of 100 LSB: u = 5*100 + 0.2*100*k (raw)
        let mut z = vec![0i64];
        for step in 0..10 {
            let (u, c) = k.step(&mut z, 100, 30000);
            assert!(!c);
            assert_eq!(u as i64, 500 + 20 * step);
        }
    }

    #[test]
    fn clamped_output_holds_states_consistent_with_the_limit() {
        let k = FixedCtrl::from_state_space(&[vec![1.0]], &[1e-3], &[20.0], 0.5, 10.0).unwrap();
        let mut z = vec![0i64];
        for _ in 0..1000 {
            let (u, c) = k.step(&mut z, 10_000, 1000);
            assert_eq!(u, 1000);
            assert!(c);
        }
        // Hanus: d e' + z = limit, so z = limit - d e_(next) stays bounded, not wound up
        let zr = z[0] as f64 / 4294967296.0;
        assert!(zr.abs() <= 1000.0 + 5.0, "z = {zr}");
        // the error reverses: the output leaves the limit at once (no windup to unwind)
        let (u, _) = k.step(&mut z, -100, 1000);
        assert!(u < 1000, "u = {u}");
    }

    #[test]
    fn coupled_triangular_state_space_is_diagonalised() {
        // x1 integrator, x2 a pole at 0.5 driven by x1 and e: distinct poles 1 and 0.5
        let a = [vec![1.0, 0.0], vec![0.3, 0.5]];
        let (b, c, d) = ([0.01, 0.2], [1.0, 2.0], 0.1);
        let k = FixedCtrl::from_state_space(&a, &b, &c, d, 1.0).unwrap();
        for w in [0.3, 3.0, 300.0] {
            let z = Complex64::from_polar(1.0, w * 1e-3);
            // C (zI - A)^-1 B + D by hand for the 2x2 lower-triangular A
            let x1 = b[0] / (z - 1.0);
            let x2 = (b[1] + 0.3 * x1) / (z - 0.5);
            let want = c[0] * x1 + c[1] * x2 + d;
            let got = k.freq_response(w, 1e-3, 1.0);
            assert!(
                (got - want).norm() < 1e-3 * want.norm(),
                "{w}: {got} {want}"
            );
        }
        assert!(
            FixedCtrl::from_state_space(&[vec![1.0, 0.2], vec![0.0, 0.5]], &b, &c, d, 1.0).is_err()
        );
        assert!(
            FixedCtrl::from_state_space(&[vec![1.0, 0.0], vec![0.3, 1.0]], &b, &c, d, 1.0).is_err()
        );
    }
}
