//! The drive's speed controller in fixed point (PROTOCOL.md section 3, "Speed loop"): parallel
//! first-order sections in Q-format, the realisation LOAD_CTRL / LOAD_SECTION carry, and the
//! conversion of a discrete state space (`fracid tune --dt`'s realisation) to it.
//!
//! Per sample, with the error `e = r - y` in raw speed LSB (an integer):
//!
//! ```text
//! s  = sum_i z_i + 2^8 sum_j h_j w_j           (Q32 raw voltage, 64-bit; w_j = e'_(k-j))
//! v  = 2^8 d e + s
//! u  = round(v / 2^32), clamped to +-u_limit  (the voltage limit)
//! e' = e                                      (not clamped)
//!    = (2^32 u - s) / d                       (clamped, d != 0: Hanus' conditioning)
//!    = states frozen if the error pushes further into the clamp, else e  (clamped, d = 0)
//! z_i <- round(a_i z_i / 2^30) + 2^8 g_i e'   (saturated at +-2^56)
//! w_j <- w_(j-1), w_1 <- e'                   (the delay line, format 2)
//! ```
//!
//! `d`, `g_i`, `h_j` are Q24 (raw voltage LSB per raw speed LSB), `a_i` Q30, the states `z_i`
//! 64-bit Q32 raw voltage, the delay line `w_j` the past conditioned errors (raw speed LSB,
//! `|w_j| <= 2^17`).
//!
//! The delay taps (controller format 2) hold what first-order sections cannot: the modes of a
//! derivative's realisation (`kd s^mu` as a fractional integrator followed by backward
//! differences, `tune::realise`), whose fastest poles round to `z = 0` and, followed by a
//! difference (another pole at 0), form a Jordan chain at the origin: a finite impulse response.
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
use crate::protocol::{
    LoadCtrl, LoadSection, CTRL_FORMAT, CTRL_FORMAT_TAPS, MAX_SECTIONS, MAX_SECTIONS_TAPS, MAX_TAPS,
};
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
    /// The delay taps `h_1, h_2, ...` (Q24 raw voltage per raw speed LSB) on the past
    /// conditioned errors `e'_(k-1), e'_(k-2), ...` (controller format 2; empty in format 1).
    pub taps: Vec<i32>,
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
    /// The length of its state vector ([`FixedCtrl::step`]): one per section, one per tap.
    pub fn n_states(&self) -> usize {
        self.sections.len() + self.taps.len()
    }

    /// One sample: the error `e = r - y` (raw speed LSB), the voltage limit (raw, > 0). Returns
    /// the clamped command (raw) and whether it was clamped; updates the states `z`
    /// ([`FixedCtrl::n_states`] of them, 0 at the start): the sections' (Q32), then the delay
    /// line `e'_(k-1), e'_(k-2), ...` (raw). Bit-identical to the C firmware's `fw_ctrl_step`
    /// (tested).
    ///
    /// # Panics
    /// If `z` is shorter than [`FixedCtrl::n_states`].
    pub fn step(&self, z: &mut [i64], e: i32, u_limit: i16) -> (i16, bool) {
        let ns = self.sections.len();
        let (zs, w) = z[..self.n_states()].split_at_mut(ns);
        let zsum: i64 = zs.iter().sum::<i64>()
            + w.iter()
                .zip(&self.taps)
                .map(|(w, h)| *h as i64 * w * 256)
                .sum::<i64>();
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
        for (zi, s) in zs.iter_mut().zip(&self.sections) {
            let p = mul_q30(*zi, s.a_q30) + s.g_q24 as i64 * e_upd * 256;
            *zi = p.clamp(-Z_MAX, Z_MAX);
        }
        if !w.is_empty() {
            w.rotate_right(1);
            w[0] = e_upd;
        }
        (us as i16, clamped)
    }

    /// The controller format it needs: [`CTRL_FORMAT`] (1, which drives of firmware 1.1 run)
    /// without taps and with at most [`MAX_SECTIONS`] sections, else [`CTRL_FORMAT_TAPS`] (2,
    /// firmware 1.2).
    pub fn format(&self) -> u8 {
        if self.taps.is_empty() && self.sections.len() <= MAX_SECTIONS as usize {
            CTRL_FORMAT
        } else {
            CTRL_FORMAT_TAPS
        }
    }

    /// The LOAD_CTRL and LOAD_SECTION payloads that download it: the sections, then the taps.
    pub fn messages(&self) -> (LoadCtrl, Vec<LoadSection>) {
        let ns = self.sections.len();
        let taps = self.taps.iter().map(|&h| Section { a_q30: 0, g_q24: h });
        (
            LoadCtrl {
                format: self.format(),
                n_sections: ns as u8,
                n_taps: self.taps.len() as u8,
                d_q24: self.d_q24,
                dinv_q16: self.dinv_q16,
            },
            self.sections
                .iter()
                .copied()
                .chain(taps)
                .enumerate()
                .map(|(i, s)| LoadSection {
                    index: i as u8,
                    a_q30: s.a_q30,
                    g_q24: s.g_q24,
                })
                .collect(),
        )
    }

    /// The controller from its download (the drive's side of [`FixedCtrl::messages`]): the
    /// first `c.n_sections` of `s` are sections, the rest taps.
    pub fn from_messages(c: &LoadCtrl, s: &[LoadSection]) -> Self {
        let ns = (c.n_sections as usize).min(s.len());
        Self {
            d_q24: c.d_q24,
            dinv_q16: c.dinv_q16,
            sections: s[..ns]
                .iter()
                .map(|s| Section {
                    a_q30: s.a_q30,
                    g_q24: s.g_q24,
                })
                .collect(),
            taps: s[ns..].iter().map(|s| s.g_q24).collect(),
        }
    }

    /// Its frequency response in physical units (V per rad/s) at omega rad/s, sample period
    /// `dt` s, the channel scales `gain_raw = y_lsb / u_lsb` (V/LSB over rad/s/LSB): `(d + sum
    /// g_i / (z - a_i) + sum h_j z^-j) / gain_raw`, `z = e^(j omega dt)`, the coefficients as
    /// quantised.
    pub fn freq_response(&self, omega: f64, dt: f64, gain_raw: f64) -> Complex64 {
        let z = Complex64::from_polar(1.0, omega * dt);
        let fir: Complex64 = self
            .taps
            .iter()
            .enumerate()
            .map(|(j, &h)| h as f64 / Q24 * z.powi(-(j as i32 + 1)))
            .sum();
        let c = fir
            + self
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
    /// with eigenvalues (its diagonal) of modulus at most 1. Each eigenvalue `a_p` is a section,
    /// `a_p`, `g_p = gain_raw (C v_p)(w_p B)` with `v_p`, `w_p` its right and left eigenvectors
    /// by forward and back substitution (`w_p v_p = 1`; its state is the mode's share of the
    /// output), equal eigenvalues (within 1e-9) only between states that do not drive each
    /// other; except the chained fast modes (poles below [`FAST_POLE`] driving or driven by
    /// another: a difference after poles that round to 0, a Jordan chain at the origin), which
    /// are delay taps: the rest of the impulse response ([`fast_taps`]); a single tap is a
    /// section at the origin. Sections whose `g_p` rounds to 0 are left out. The anti-windup is
    /// Hanus' conditioning (`dinv` = `1/d`) when it is stable ([`hanus_is_stable`]), else
    /// conditional integration (`dinv` = 0: the states frozen while the error pushes into the
    /// clamp).
    ///
    /// # Errors
    /// [`Error::InvalidParam`]: inconsistent sizes, non-finite entries, an `A` that is not lower
    /// triangular, coupled repeated slow poles or unstable ones, more than
    /// [`MAX_SECTIONS_TAPS`] sections or [`MAX_TAPS`] taps (more than
    /// [`MAX_REALISATION_STATES`] states are refused before any work), a gain beyond the Q24
    /// range (+-128 raw voltage per raw speed LSB), a controller whose output is always 0.
    /// [`Error::Numerical`]: the zeros for the anti-windup did not converge
    /// ([`hanus_is_stable`]).
    ///
    /// A realisation without states (a pure gain, `u = D e`: a proportional speed loop) is a
    /// controller of no sections, which both controller formats and firmwares run.
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
        if n > MAX_REALISATION_STATES {
            return bad(format!(
                "{n} states: the drive holds at most {MAX_SECTIONS_TAPS} sections and \
                 {MAX_TAPS} delay taps (realisations of up to {MAX_REALISATION_STATES} states \
                 are converted): a lower approximation order"
            ));
        }
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
        let keep = kept_states(a, b, c);
        let lam = triangular_poles(a, &keep)?;
        let m = keep.len();
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
        let sub = |r: usize, s: usize| a[keep[r]][keep[s]];
        // the chained fast modes: poles below FAST_POLE that drive or are driven by another
        // (a difference after poles that round to 0): the delay taps hold them. A fast pole
        // alone (a FOPI's fastest cells) stays a section.
        let fast = |p: usize| lam[p].abs() < FAST_POLE;
        let chained: Vec<bool> = (0..m)
            .map(|p| {
                fast(p)
                    && (0..m).any(|r| r != p && fast(r) && (sub(r, p) != 0.0 || sub(p, r) != 0.0))
            })
            .collect();
        let modes = slow_modes(a, b, c, &keep, &lam, &chained)?;
        let mut sections = Vec::new();
        for &(l, g) in &modes {
            let g = q(gain_raw * g, Q24, "a section's gain")?;
            if g != 0 {
                sections.push(Section {
                    a_q30: (l.clamp(-1.0, 1.0) * (1u64 << 30) as f64).round() as i32,
                    g_q24: g,
                });
            }
        }
        let mut taps = if chained.contains(&true) {
            fast_taps(a, b, c, &keep, &modes, gain_raw, &q)?
        } else {
            Vec::new()
        };
        if taps.len() == 1 {
            // one tap is a section at the origin, `h_1 / z` (bit for bit: `z <- 0 + 2^8 h_1 e'`),
            // which format 1 (firmware 1.1) runs: a FOPI's fast poles
            sections.push(Section {
                a_q30: 0,
                g_q24: taps[0],
            });
            taps.clear();
        }
        if sections.len() > MAX_SECTIONS_TAPS as usize {
            return bad(format!(
                "{} sections (the drive takes at most {MAX_SECTIONS_TAPS}): a lower \
                 approximation order",
                sections.len()
            ));
        }
        let d_raw = gain_raw * d;
        let d_q24 = q(d_raw, Q24, "the feed-through")?;
        // Hanus' conditioning runs the controller's inverse while clamped: unstable with a
        // zero outside the unit circle (a FOPID's derivative puts one near z = -20)
        let hanus = hanus_is_stable(a, b, c, d, &keep)?;
        let dinv_q16 = if hanus && d_raw.abs() >= 2.0 / 65536.0 {
            q(1.0 / d_raw, 65536.0, "1/feed-through").unwrap_or(0)
        } else {
            0
        };
        if d_q24 == 0 && sections.is_empty() && taps.is_empty() {
            return bad(format!(
                "its output is 0 whatever the error (feed-through {d}, no state that reaches \
                 the output, or gains that round to 0 at these channel scales): nothing to run"
            ));
        }
        Ok(Self {
            d_q24,
            dinv_q16,
            sections,
            taps,
        })
    }
}

/// The states a realisation keeps: those observable or feeding another, and driven by the input
/// or another state (repeated until none is dropped).
fn kept_states(a: &[Vec<f64>], b: &[f64], c: &[f64]) -> Vec<usize> {
    let mut keep: Vec<usize> = (0..a.len()).collect();
    loop {
        let before = keep.len();
        let k2 = keep.clone();
        keep.retain(|&i| {
            let feeds = k2.iter().any(|&j| j != i && a[j][i] != 0.0);
            let driven = b[i] != 0.0 || k2.iter().any(|&j| j != i && a[i][j] != 0.0);
            (c[i] != 0.0 || feeds) && driven
        });
        if keep.len() == before {
            return keep;
        }
    }
}

/// The poles (the diagonal) of the kept states' block of `a`, which must be lower triangular
/// (to `1e-12` of its largest entry) with every pole within the unit circle.
///
/// # Errors
/// [`Error::InvalidParam`] when it is not.
fn triangular_poles(a: &[Vec<f64>], keep: &[usize]) -> Result<Vec<f64>> {
    let scale = a.iter().flatten().fold(1.0f64, |s, v| s.max(v.abs()));
    for (p, &i) in keep.iter().enumerate() {
        for &j in &keep[p + 1..] {
            if a[i][j].abs() > 1e-12 * scale {
                return Err(Error::InvalidParam(format!(
                    "controller: A is not lower triangular (A[{i}][{j}] = {}): the drive runs \
                     parallel first-order sections of a triangular realisation",
                    a[i][j]
                )));
            }
        }
    }
    let lam: Vec<f64> = keep.iter().map(|&i| a[i][i]).collect();
    if let Some(l) = lam.iter().find(|l| l.abs() > 1.0 + 1e-12) {
        return Err(Error::InvalidParam(format!(
            "controller: pole {l} outside the unit circle"
        )));
    }
    Ok(lam)
}

/// The slow modes as (pole, gain): section `p` is `lam[p]` with `g = (C v)(w B)`, `v` and `w`
/// its right and left eigenvectors in the triangular block (`v` zero above `p`, `w` zero below,
/// `v_p = w_p = 1`, so `w v = 1`); the `chained` fast modes are left to the delay taps.
///
/// # Errors
/// [`Error::InvalidParam`] for a repeated pole coupled to itself (a double integrator).
fn slow_modes(
    a: &[Vec<f64>],
    b: &[f64],
    c: &[f64],
    keep: &[usize],
    lam: &[f64],
    chained: &[bool],
) -> Result<Vec<(f64, f64)>> {
    let m = keep.len();
    let sub = |r: usize, s: usize| a[keep[r]][keep[s]];
    let repeated = |l: f64| {
        Err(Error::InvalidParam(format!(
            "controller: repeated pole {l} coupled to itself (a double integrator): not a set \
             of first-order sections"
        )))
    };
    let mut modes = Vec::new();
    for p in (0..m).filter(|&p| !chained[p]) {
        let mut v = vec![0.0; m];
        v[p] = 1.0;
        for r in p + 1..m {
            let s: f64 = (p..r).map(|k| sub(r, k) * v[k]).sum();
            if s != 0.0 {
                if (lam[p] - lam[r]).abs() < 1e-9 {
                    return repeated(lam[p]);
                }
                v[r] = s / (lam[p] - lam[r]);
            }
        }
        let mut w = vec![0.0; m];
        w[p] = 1.0;
        for r in (0..p).rev() {
            let s: f64 = (r + 1..=p).map(|k| w[k] * sub(k, r)).sum();
            if s != 0.0 {
                if (lam[p] - lam[r]).abs() < 1e-9 {
                    return repeated(lam[p]);
                }
                w[r] = s / (lam[p] - lam[r]);
            }
        }
        let cv: f64 = (p..m).map(|r| c[keep[r]] * v[r]).sum();
        let wb: f64 = (0..=p).map(|r| w[r] * b[keep[r]]).sum();
        modes.push((lam[p], cv * wb));
    }
    Ok(modes)
}

/// Whether Hanus' conditioning is stable for the realisation's kept states: the states updated
/// with the error `(u_clamped - C x) / D` evolve as `x <- (A - B C / D) x + B u_clamped / D`,
/// whose eigenvalues are the controller's zeros; the conditioning is right when they are within
/// the unit circle (spectral radius at most `1 + 1e-6`: a FOPI's zeros near `z = 1`), wrong
/// (the states run away, the command chatters between the limits) otherwise. `false` without
/// feed-through.
///
/// The eigenvalues come from the QR iteration of [`fracsim::eig`] after balancing, which gives up
/// after `100 n` double-shift steps (nalgebra's has no limit and never ends on some matrices
/// with eigenvalues on the unit circle, such as those of poles at `z = -1`). Without kept states
/// (a pure gain) there is nothing to condition: `true`.
///
/// # Errors
/// [`Error::Numerical`]: the iteration did not converge, or the matrix is not finite.
pub fn hanus_is_stable(
    a: &[Vec<f64>],
    b: &[f64],
    c: &[f64],
    d: f64,
    keep: &[usize],
) -> Result<bool> {
    if d == 0.0 || !d.is_finite() {
        return Ok(false);
    }
    let n = keep.len();
    if n == 0 {
        return Ok(true);
    }
    let mut m = nalgebra::DMatrix::from_fn(n, n, |i, j| {
        a[keep[i]][keep[j]] - b[keep[i]] * c[keep[j]] / d
    });
    if m.iter().any(|v| !v.is_finite()) {
        return Err(Error::Numerical(
            "controller: its closed realisation `A - B C / D` is not finite".into(),
        ));
    }
    nalgebra::linalg::balancing::balance_parlett_reinsch(&mut m);
    let zeros = fracsim::eig::eigenvalues_only(m, 100 * n).ok_or_else(|| {
        Error::Numerical(format!(
            "controller: the zeros of its {n}-state realisation (for the anti-windup) did not \
             converge in {} QR steps",
            100 * n
        ))
    })?;
    Ok(zeros.iter().all(|z| z.norm() <= 1.0 + 1e-6))
}

/// The most states a realisation may have for [`FixedCtrl::from_state_space`]: twice what the
/// drive holds ([`MAX_SECTIONS_TAPS`] sections and [`MAX_TAPS`] taps), room for the states the
/// conversion drops (unobservable, undriven, negligible). Checked before any work that grows
/// with the size (the pruning and the conversion are cubic in it): a controller of 1,600 states
/// took two minutes before the drive refused it.
pub const MAX_REALISATION_STATES: usize = 2 * (MAX_SECTIONS_TAPS as usize + MAX_TAPS as usize);

/// Poles of modulus below this that drive or are driven by another such pole (a chain) are the
/// fast modes the delay taps hold ([`fast_taps`]).
pub const FAST_POLE: f64 = 1e-3;

/// The delay taps of the chained fast modes: the impulse response of the kept states' system,
/// `C A^(k-1) B` (its Markov parameters), less the sections' `sum g_p lam_p^(k-1)` (`modes`), in
/// raw Q24, for `k = 1..=MAX_TAPS + 4`; trailing taps that round to 0 are dropped. A chain of `n`
/// states at the origin ends after `n` samples, a pole below [`FAST_POLE`] falls by 1e-3 a
/// sample: the taps past the last kept one round to 0 (checked up to `MAX_TAPS + 4`).
fn fast_taps(
    a: &[Vec<f64>],
    b: &[f64],
    c: &[f64],
    keep: &[usize],
    modes: &[(f64, f64)],
    gain_raw: f64,
    q: &dyn Fn(f64, f64, &str) -> Result<i32>,
) -> Result<Vec<i32>> {
    let n_check = MAX_TAPS as usize + 4;
    let mut x: Vec<f64> = keep.iter().map(|&i| b[i]).collect();
    let mut taps = Vec::with_capacity(n_check);
    for k in 1..=n_check {
        let h: f64 = keep.iter().zip(&x).map(|(&i, x)| c[i] * x).sum();
        let slow: f64 = modes.iter().map(|(l, g)| g * l.powi(k as i32 - 1)).sum();
        taps.push(q(gain_raw * (h - slow), Q24, "a delay tap")?);
        x = keep
            .iter()
            .map(|&i| keep.iter().zip(&x).map(|(&j, x)| a[i][j] * x).sum())
            .collect();
    }
    while taps.last() == Some(&0) {
        taps.pop();
    }
    if taps.len() > MAX_TAPS as usize {
        return Err(Error::InvalidParam(format!(
            "controller: its fast modes (poles below {FAST_POLE}) need {} delay taps (the drive \
             takes at most {MAX_TAPS})",
            taps.len()
        )));
    }
    Ok(taps)
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

    /// `C (zI - A)^-1 B + D` of a lower-triangular `A` by forward substitution.
    fn ss_response(a: &[Vec<f64>], b: &[f64], c: &[f64], d: f64, z: Complex64) -> Complex64 {
        let mut x = vec![Complex64::new(0.0, 0.0); a.len()];
        for i in 0..a.len() {
            let s: Complex64 = (0..i).map(|j| x[j] * a[i][j]).sum();
            x[i] = (s + b[i]) / (z - a[i][i]);
        }
        x.iter().zip(c).map(|(x, c)| x * c).sum::<Complex64>() + d
    }

    /// A FOPID-like realisation: an integrator, then `s^-(1-mu)`'s modes (a slow pole, a fast
    /// one at 1e-20 and one exactly 0) followed by a backward difference (another pole at 0,
    /// driven by the fast ones: a Jordan chain at the origin). First-order sections alone
    /// refused it; now the fast modes are delay taps and the response is the realisation's.
    #[test]
    fn difference_after_fast_poles_becomes_delay_taps() {
        let dt = 1e-3;
        let (c1, c2, c3, dr) = (0.3, 2.0, 0.7, 0.05);
        // x0 integrator; x1 (0.9), x2 (1e-20), x3 (0): the modes; x4: the difference's state
        let a = vec![
            vec![1.0, 0.0, 0.0, 0.0, 0.0],
            vec![0.0, 0.9, 0.0, 0.0, 0.0],
            vec![0.0, 0.0, 1e-20, 0.0, 0.0],
            vec![0.0, 0.0, 0.0, 0.0, 0.0],
            vec![0.0, c1, c2, c3, 0.0],
        ];
        let b = [dt, 0.1, 1.0, 0.5, dr];
        let c = [20.0, c1 / dt, c2 / dt, c3 / dt, -1.0 / dt];
        let d = 0.4 + dr / dt;
        let gain_raw = 0.02;
        let k = FixedCtrl::from_state_space(&a, &b, &c, d, gain_raw).unwrap();
        assert_eq!(k.sections.len(), 2, "{k:?}");
        assert!(k.sections.iter().all(|s| s.a_q30 != 0));
        assert_eq!(k.taps.len(), 2, "{k:?}");
        assert_eq!(k.format(), CTRL_FORMAT_TAPS);
        for w in [1.0, 30.0, 300.0, 3000.0] {
            let z = Complex64::from_polar(1.0, w * dt);
            let want = ss_response(&a, &b, &c, d, z);
            let got = k.freq_response(w, dt, gain_raw);
            // the integrator's gain, 4e-4 raw, is 6711 in Q24: its rounding is 7.5e-5 of it
            assert!(
                (got - want).norm() < 2e-4 * want.norm(),
                "{w}: {got} {want}"
            );
        }
        // in time: the impulse response of the fixed-point controller (an error of 100 LSB,
        // then 0) against the realisation's, within a raw LSB
        let mut z = vec![0; k.n_states()];
        let mut x = [0.0; 5];
        for n in 0..40 {
            let e = if n == 0 { 100.0 } else { 0.0 };
            let want: f64 = (0..5).map(|i| c[i] * x[i]).sum::<f64>() + d * e;
            let (u, _) = k.step(&mut z, e as i32, i16::MAX);
            assert!(
                (u as f64 - gain_raw * want).abs() <= 1.0,
                "sample {n}: {u} vs {}",
                gain_raw * want
            );
            let prev = x;
            for i in 0..5 {
                x[i] = (0..5).map(|j| a[i][j] * prev[j]).sum::<f64>() + b[i] * e;
            }
        }
    }

    /// The delay line holds the conditioned errors: with the output clamped, a tap sees the
    /// error that gave the clamped output (Hanus), not the error itself.
    #[test]
    fn delay_line_takes_the_conditioned_error() {
        let k = FixedCtrl {
            d_q24: 2 << 24,
            dinv_q16: 1 << 15,
            sections: vec![],
            taps: vec![1 << 24, -(1 << 24)],
        };
        let mut z = vec![0; 2];
        // u = 2 e_k + w_1 - w_2: 2 * 100 = 200 > 150: clamped, e' = 150 / 2 = 75
        assert_eq!(k.step(&mut z, 100, 150), (150, true));
        assert_eq!(z, [75, 0]);
        // u = 2 * 10 + 75 - 0 = 95, not clamped: the line shifts the error in
        assert_eq!(k.step(&mut z, 10, 150), (95, false));
        assert_eq!(z, [10, 75]);
        assert_eq!(k.step(&mut z, 0, 150), (10 - 75, false));
        assert_eq!(z, [0, 10]);
    }

    /// A fast pole alone (a FOPI's fastest cells, `e^(p dt)` ~ 1e-20, fed by the error only)
    /// stays a section (at the origin once quantised): no taps, format 1, which firmware 1.1
    /// runs.
    #[test]
    fn an_unchained_fast_pole_stays_a_section() {
        let a = [
            vec![1.0, 0.0, 0.0],
            vec![0.0, 0.5, 0.0],
            vec![0.0, 0.0, 1e-20],
        ];
        let (b, c) = ([1e-3, 0.2, 0.3], [30.0, 2.0, -4.0]);
        let k = FixedCtrl::from_state_space(&a, &b, &c, 0.7, 1.0).unwrap();
        assert!(k.taps.is_empty(), "{k:?}");
        assert_eq!(k.sections.len(), 3);
        assert_eq!(k.sections[2].a_q30, 0);
        assert_eq!(k.format(), CTRL_FORMAT);
        for w in [1.0, 100.0, 3000.0] {
            let z = Complex64::from_polar(1.0, w * 1e-3);
            let want = ss_response(&a, &b, &c, 0.7, z);
            let got = k.freq_response(w, 1e-3, 1.0);
            assert!(
                (got - want).norm() < 1e-6 * want.norm(),
                "{w}: {got} {want}"
            );
        }
    }

    /// A zero outside the unit circle (`0.1 + 2/(z - 0.5)`: zero at `z = -19.5`) makes Hanus'
    /// conditioning unstable: conditional integration (`dinv` 0) instead; the same form with a
    /// zero inside (`0.1 + 0.02/(z - 0.5)`: `z = 0.3`) keeps Hanus.
    #[test]
    fn hanus_only_with_the_zeros_inside_the_unit_circle() {
        let k = FixedCtrl::from_state_space(&[vec![0.5]], &[1.0], &[2.0], 0.1, 1.0).unwrap();
        assert_eq!((k.d_q24 != 0, k.dinv_q16), (true, 0));
        let k = FixedCtrl::from_state_space(&[vec![0.5]], &[1.0], &[0.02], 0.1, 1.0).unwrap();
        assert_eq!(k.dinv_q16, 655_360);
    }

    /// Issue 46, item 5: a realisation without states (a pure gain, a proportional speed loop)
    /// panicked in nalgebra's Schur decomposition of the empty closed realisation. It is a
    /// controller of no sections: `u = d e`, Hanus' `1/d` (nothing to condition).
    #[test]
    fn a_pure_gain_is_a_controller_of_no_sections() {
        let k = FixedCtrl::from_state_space(&[], &[], &[], 0.5, 10.0).unwrap();
        assert!(k.sections.is_empty() && k.taps.is_empty(), "{k:?}");
        assert_eq!((k.d_q24, k.dinv_q16), (5 << 24, 65536 / 5));
        assert_eq!(k.format(), CTRL_FORMAT);
        let mut z: Vec<i64> = vec![];
        assert_eq!(k.step(&mut z, 100, 30000), (500, false));
        assert_eq!(k.step(&mut z, -7000, 30000), (-30000, true));
        // so is one whose states are all dropped (none reaches the output)
        let k = FixedCtrl::from_state_space(&[vec![0.5]], &[1.0], &[0.0], 0.5, 10.0).unwrap();
        assert!(k.sections.is_empty(), "{k:?}");
        // but a controller whose output is always 0 is refused, in words
        let e = FixedCtrl::from_state_space(&[], &[], &[], 0.0, 10.0).unwrap_err();
        assert!(e.to_string().contains("nothing to run"), "{e}");
        let e = FixedCtrl::from_state_space(&[vec![0.5]], &[1.0], &[0.0], 0.0, 10.0).unwrap_err();
        assert!(e.to_string().contains("nothing to run"), "{e}");
    }

    /// Issue 46, item 6: poles at `z = -1` and a chain at the origin whose closed realisation
    /// `A - B C / D` nalgebra's QR iteration never finishes (it has no iteration limit): the
    /// conversion hung forever. Now it ends at once, with an error if the iteration does not
    /// converge. (Found by a search over small realisations with entries in {-1, 0, 1}.)
    #[test]
    fn poles_at_minus_one_end_in_an_answer_not_a_hang() {
        let a = vec![
            vec![-1.0, 0.0, 0.0, 0.0],
            vec![1.0, 0.0, 0.0, 0.0],
            vec![-1.0, -1.0, 0.0, 0.0],
            vec![0.0, 0.0, -1.0, 0.0],
        ];
        let (b, c, d) = (vec![-1.0, 0.0, -1.0, 0.0], vec![1.0, 0.0, 0.0, -1.0], 1.0);
        // the matrix is one nalgebra's Schur does not reduce in 10^5 steps
        let m = nalgebra::DMatrix::from_fn(4, 4, |i, j| a[i][j] - b[i] * c[j] / d);
        assert!(nalgebra::linalg::Schur::try_new(m, f64::EPSILON, 100_000).is_none());
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let t0 = std::time::Instant::now();
            let r = FixedCtrl::from_state_space(&a, &b, &c, d, 1.0);
            let _ = tx.send((r, t0.elapsed()));
        });
        let (r, took) = rx
            .recv_timeout(std::time::Duration::from_secs(20))
            .expect("the conversion hangs");
        assert!(took.as_secs_f64() < 1.0, "{took:?}");
        match r {
            Err(Error::Numerical(m)) => assert!(m.contains("did not converge"), "{m}"),
            other => panic!("{other:?}"),
        }
    }

    /// Issue 46, item 4: more states than [`MAX_REALISATION_STATES`] are refused before any work
    /// (1,600 took minutes in the cubic steps before the section count was checked).
    #[test]
    fn an_oversized_realisation_is_refused_at_once() {
        let n = 1600;
        let a: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..n).map(|j| if i == j { 0.5 } else { 0.0 }).collect())
            .collect();
        let t0 = std::time::Instant::now();
        let e =
            FixedCtrl::from_state_space(&a, &vec![1.0; n], &vec![1.0; n], 0.1, 1.0).unwrap_err();
        assert!(t0.elapsed().as_secs_f64() < 0.5, "{:?}", t0.elapsed());
        assert!(e.to_string().contains("1600 states"), "{e}");
        // the limit itself is converted (a diagonal realisation of distinct poles, too many
        // sections for the drive: refused for that, after the work)
        let n = MAX_REALISATION_STATES;
        let a: Vec<Vec<f64>> = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        if i == j {
                            0.9 * i as f64 / n as f64
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect();
        let e =
            FixedCtrl::from_state_space(&a, &vec![1.0; n], &vec![1.0; n], 0.1, 1.0).unwrap_err();
        assert!(
            e.to_string().contains("sections (the drive takes at most"),
            "{e}"
        );
    }
}
