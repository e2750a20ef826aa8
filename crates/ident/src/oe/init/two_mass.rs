//! The automatic start of the two-mass drive train ([`FracModel::two_mass`]): the motor and the
//! coupling's resonant pair found on the measured frequency response.
//!
//! 1. The whole response by one commensurate Levy fit with two numerator and four denominator
//!    terms, `(b0 + b1 x + b2 x^2)/(1 + a1 x + .. + a4 x^4)`, `x = s^q`, for each `q` of the grid
//!    `0.50, 0.51, .., 1` (the best by the weighted error). Its denominator is factored (the roots
//!    of the quartic in `x`): the complex pair with the least damping ratio is the resonance, the
//!    other two roots the motor `K/(a2 x^2 + a1 x + 1)`, `zeta = theta = q`; the numerator is the
//!    anti-resonance. The pair's `x^2` terms are turned into the structure's `s^2` at their own
//!    frequency (`c2 = w_r^-2`, `w_r = c2'^(-1/(2q))`), its `x` terms kept (`mu = q`).
//! 2. From that motor (or, when step 1 fails, from the commensurate Levy start of the motor alone,
//!    [`super::levy_start`]), alternately: the pair by Levy's least squares at order 1 on
//!    `H / G_m` (weights times `|G_m|^2`, the variance of the ratio), then the motor by the
//!    commensurate Levy start on `H / R` (weights times `|R|^2`), [`ROUNDS`] times.
//!
//! The pair's two damping coefficients, fitted apart, start the structure's one `d` at their
//! geometric mean. Each is a candidate start (the caller keeps the one whose simulated output fits best). A start
//! that cannot hold a resonance fails at once, before any time-domain simulation: no candidate
//! whose pair has positive coefficients, poles damped below [`MAX_PAIR_DAMPING`] and a resonance
//! inside the measured band ("no resonance in the frequency response"). The structure comparison
//! then drops the structure at the cost of a few Levy solves.
//!
//! The response is the periodic estimate when the input is periodic, else ([`aperiodic`]) Welch's
//! H1 estimate ([`super::welch`]). That one is noisier and smears a sharp peak over the window's
//! main lobe, so on it the structure must also earn its place: a candidate's weighted error on
//! the response must be below [`EVIDENCE_RATIO`] times that of its own motor alone (the pair, not
//! a better motor, explains the response), else the start fails as above, still before any
//! simulation.
//!
//! When all of this fails, [`fallback`] tries once more on Welch's estimate up to half the Nyquist
//! frequency: a negative gain (the sign from the lowest frequency), the resonance at a peak of the
//! response, two resonant modes (the motor's pair at a second peak), each start placed in the time
//! domain and kept only when its pair explains a share of the output's variance.

use super::{frf_error, levy_start, with_values, Candidate, Frf, SK_ITERATIONS};
use crate::levy;
use crate::oe::FracModel;
use crate::par::Par;
use crate::{Error, Result};
use fracsim::FracTf;
use num_complex::Complex64;

/// Rounds of the alternation (each gives a candidate).
pub const ROUNDS: usize = 2;

/// On Welch's estimate a two-mass candidate must fit the response with less than this fraction
/// of the weighted error of its own motor alone: the evidence of a resonance that the estimate's
/// noise and leakage alone do not give (a pair whose zeros nearly cancel its poles adds nothing).
pub const EVIDENCE_RATIO: f64 = 0.5;

/// The frequency response the two-mass start uses when [`super::periodic_frf`] failed with `why`:
/// Welch's H1 estimate ([`super::welch::h1_coherent`]: the bins its coherence trusts, a
/// resonance included where the input has little power) of deviations `y` over `u`, with a
/// sentence saying how it was made. Other structures keep their coarse start: for them `why` is
/// returned.
///
/// # Errors
/// `why` for structures other than the two-mass; the errors of [`super::welch::h1_coherent`]
/// (with `why` said first).
pub fn aperiodic(
    lin: &FracModel,
    u: &[f64],
    y: &[f64],
    dt: f64,
    why: Error,
) -> Result<(Frf, String)> {
    if lin.kind != crate::oe::Kind::TwoMass {
        return Err(why);
    }
    // The reasons' own words, without the variant's prefix twice.
    let plain = |e: Error| match e {
        Error::NotEnoughData(s) => s,
        e => e.to_string(),
    };
    super::welch::h1_coherent(u, y, dt)
        .map_err(|e| Error::NotEnoughData(joined(&plain(why), &plain(e))))
}

/// A pair whose poles' damping ratio `c1 / (2 sqrt(c2))` exceeds this has no resonance peak
/// (`1/sqrt(2)` is where the peak of a second-order pole pair vanishes).
pub const MAX_PAIR_DAMPING: f64 = std::f64::consts::FRAC_1_SQRT_2;

/// The pair `(b1, b2, c1, c2)` (numerator normalised to 1 at `s = 0`) and its numerator's
/// constant, fitted to `ratio` by Levy at order 1.
fn pair_of(omega: &[f64], ratio: &[Complex64], weight: &[f64]) -> Result<([f64; 4], f64)> {
    let fit = levy::levy_fixed_q(omega, ratio, 1.0, 2, 2, weight, SK_ITERATIONS)?;
    let (b, a) = (&fit.b, &fit.a);
    let b1 = one_d(b[1], a[0] * b[0]);
    if !([b[0], b1, b[2]]
        .iter()
        .chain(a)
        .all(|&c| c > 0.0 && c.is_finite()))
    {
        return Err(Error::Numerical(
            "the resonant pair's Levy fit has a coefficient that is not positive".into(),
        ));
    }
    Ok(([b1 / b[0], b[2] / b[0], a[0], a[1]], b[0]))
}

/// Whether the pair's poles make a resonance inside the measured band `[w_lo, w_hi]`.
fn resonant(pair: &[f64; 4], w_lo: f64, w_hi: f64) -> bool {
    let [_, _, c1, c2] = *pair;
    let w_r = c2.powf(-0.5);
    let damping = c1 / (2.0 * c2.sqrt());
    damping < MAX_PAIR_DAMPING && w_r >= w_lo && w_r <= w_hi
}

/// Why `pair` (`(b1, b2, c1, c2)`) is no resonance inside `[w_lo, w_hi]` rad/s, in words for a
/// report (no coefficient vectors): a coefficient that is not positive, or its poles' frequency
/// and damping ratio against the rule of [`resonant`].
fn pair_words(pair: &[f64; 4], w_lo: f64, w_hi: f64) -> String {
    let [_, _, c1, c2] = *pair;
    if !pair.iter().all(|&c| c > 0.0 && c.is_finite()) {
        return "no resonant pair (a coefficient of its pair is not positive)".into();
    }
    let hz = |w: f64| w / (2.0 * std::f64::consts::PI);
    format!(
        "no resonant pair (poles at {:.3} Hz with damping ratio {:.2}; a resonance needs below \
         {MAX_PAIR_DAMPING:.2}, inside {:.3}-{:.3} Hz)",
        hz(c2.powf(-0.5)),
        c1 / (2.0 * c2.sqrt()),
        hz(w_lo),
        hz(w_hi)
    )
}

/// The reasons `a` then `b` (each `"; "`-separated clauses) with the clauses `a` has already left
/// out of `b`: a start that failed twice on the same estimate says so once.
fn joined(a: &str, b: &str) -> String {
    let mut parts: Vec<&str> = a.split("; ").filter(|p| !p.is_empty()).collect();
    for p in b.split("; ") {
        if !p.is_empty() && !parts.contains(&p) {
            parts.push(p);
        }
    }
    parts.join("; ")
}

/// `(b2 s^2 + b1 s + 1)/(c2 s^2 + c1 s + 1)`.
fn pair_tf(pair: &[f64; 4]) -> Result<FracTf> {
    let [b1, b2, c1, c2] = *pair;
    Ok(format!("({b2:e} s^2 + {b1:e} s + 1)/({c2:e} s^2 + {c1:e} s + 1)").parse::<FracTf>()?)
}

/// `frf` with each response divided by `by(omega)`, its weights times `|by|^2`.
fn divided(frf: &Frf, by: &FracTf) -> Frf {
    let mut out = frf.clone();
    for ((h, w), &om) in out.h.iter_mut().zip(&mut out.weight).zip(&frf.omega) {
        let d = by.freq_response(om);
        *h /= d;
        *w *= d.norm_sqr();
    }
    out
}

/// The roots of `sum_k p[k] x^k` (`p` of degree 4, `p[4] != 0`) by the Durand-Kerner iteration.
fn quartic_roots(p: &[f64; 5]) -> Option<[Complex64; 4]> {
    let lead = p[4];
    let eval = |x: Complex64| {
        p.iter()
            .rev()
            .fold(Complex64::new(0.0, 0.0), |a, &c| a * x + c / lead)
    };
    let scale = p
        .iter()
        .take(4)
        .map(|c| (c / lead).abs())
        .fold(1.0, f64::max);
    let mut z: [Complex64; 4] =
        std::array::from_fn(|k| Complex64::from_polar(scale, 0.4 + k as f64 * 1.3));
    for _ in 0..500 {
        let mut moved = 0.0f64;
        for i in 0..4 {
            let mut d = Complex64::new(1.0, 0.0);
            for j in 0..4 {
                if j != i {
                    d *= z[i] - z[j];
                }
            }
            let step = eval(z[i]) / d;
            z[i] -= step;
            moved = moved.max(step.norm() / z[i].norm().max(1e-300));
        }
        if moved < 1e-14 {
            break;
        }
    }
    z.iter()
        .all(|v| v.re.is_finite() && v.im.is_finite())
        .then_some(z)
}

/// Sanathanan-Koerner iterations of the quartic Levy fit (step 1; they stop sooner once
/// converged). Levy's first solve weights the response by the denominator's `|D|^2`, which over
/// a quartic spans many decades, and the reweightings take a while to undo it: on Welch's
/// estimate of a zoo record (PRBS, resonance at 125 Hz) the best order's weighted error was
/// 0.058 after 3 iterations (the motor and pair fitted as unstable roots), 0.0033 after 8 and
/// 0.0025 (the truth's on that estimate) from 12 on.
pub const QUARTIC_SK_ITERATIONS: usize = 20;

/// The numerator's damping coefficient `b1` of a fitted pair, or the poles' `c1` when `b1` is
/// not positive: a lightly damped anti-resonance on a noisy estimate is often fitted with its
/// zeros on or across the imaginary axis, and the structure damps zeros and poles with one `d`
/// (the geometric mean of the two, [`levy_candidates`]), which the poles then give alone.
fn one_d(b1: f64, c1: f64) -> f64 {
    if b1 > 0.0 {
        b1
    } else {
        c1
    }
}

/// Step 1 of the module documentation: `(motor [K, a1, a2, q], pair [b1, b2, c1, c2], mu)`.
fn from_quartic(frf: &Frf) -> Result<([f64; 4], [f64; 4], f64)> {
    let mut best: Option<(f64, Vec<f64>, Vec<f64>, f64)> = None;
    levy::levy_orders(
        &frf.omega,
        &frf.h,
        (2, 4),
        &frf.weight,
        QUARTIC_SK_ITERATIONS,
        (50..=100).map(|i| i as f64 * 0.01),
        |q, b, a, e| {
            if e.is_finite() && best.as_ref().is_none_or(|x| e < x.0) {
                best = Some((e, b.to_vec(), a.to_vec(), q));
            }
        },
    )?;
    let (_, b, a, q) = best.ok_or_else(|| Error::Numerical("no quartic Levy fit".into()))?;
    let roots = quartic_roots(&[1.0, a[0], a[1], a[2], a[3]])
        .ok_or_else(|| Error::Numerical("the quartic's roots did not converge".into()))?;
    // The complex root (upper half) of least damping ratio -Re/|x| is the resonance.
    let r = roots
        .iter()
        .filter(|x| x.im > 1e-9 * x.norm())
        .min_by(|x, y| (-x.re / x.norm()).total_cmp(&(-y.re / y.norm())))
        .copied()
        .ok_or_else(|| Error::Numerical("the quartic has no complex pair".into()))?;
    // Quadratic 1 + c1 x + c2 x^2 with roots r, conj(r): c2 = 1/|r|^2, c1 = -2 Re r / |r|^2.
    let (c2x, c1x) = (1.0 / r.norm_sqr(), -2.0 * r.re / r.norm_sqr());
    // The other two roots (a pair, or two real ones).
    let mut rest: Vec<Complex64> = roots
        .iter()
        .copied()
        .filter(|x| (x - r).norm() > 1e-9 * r.norm() && (x - r.conj()).norm() > 1e-9 * r.norm())
        .collect();
    if rest.len() != 2 {
        return Err(Error::Numerical(
            "the quartic's roots are not two pairs".into(),
        ));
    }
    let (p, s) = (rest[0] * rest[1], rest.remove(0) + rest[0]);
    // 1 + a1 x + a2 x^2 = (1 - x/x1)(1 - x/x2): a2 = 1/(x1 x2), a1 = -(x1 + x2)/(x1 x2).
    let (a2m, a1m) = ((1.0 / p).re, (-s / p).re);
    let k = b[0];
    let w_r = c2x.powf(-0.5 / q);
    let w_a = (b[2] / b[0]).powf(-0.5 / q);
    Ok((
        [k, a1m, a2m, q],
        [one_d(b[1] / b[0], c1x), w_a.powi(-2), c1x, w_r.powi(-2)],
        q,
    ))
}

/// The candidate starts of the two-mass model `lin` from the response `frf` (see the module
/// documentation), each labelled with its round, the resonance and anti-resonance (Hz) and the
/// weighted error of `G_m R` on the response. Returns them with the motor's last commensurate
/// order.
///
/// # Errors
/// [`Error::NotEnoughData`] ("no resonance in the frequency response") when no round gives a
/// resonant pair inside the band; the errors of the first motor fit.
pub fn candidates(lin: &FracModel, frf: &Frf, dt: f64, par: Par) -> Result<(Vec<Candidate>, f64)> {
    let (out, q) = levy_candidates(lin, frf, dt, par)?;
    if frf.period.is_none() {
        evidence(lin, frf, &out)?;
    }
    Ok((out, q))
}

/// Steps 1 and 2 of the module documentation, without the evidence rule.
fn levy_candidates(lin: &FracModel, frf: &Frf, dt: f64, par: Par) -> Result<(Vec<Candidate>, f64)> {
    let w_lo = frf.omega.first().copied().unwrap_or(0.0);
    let w_hi = frf.omega.last().copied().unwrap_or(0.0);
    let hz = |c: f64| c.powf(-0.5) / (2.0 * std::f64::consts::PI);
    let mut out = vec![];
    let mut why = vec![];
    let push = |motor: [f64; 4], pair: [f64; 4], mu: f64, what: &str, out: &mut Vec<Candidate>| {
        let [k, a1, a2, q] = motor;
        let [b1, b2, c1, c2] = pair;
        // The coupling damps both with one `d`: the geometric mean of the pair's two.
        let d = (b1 * c1).sqrt();
        let whole = FracModel::two_mass([k, a1, a2, q, q], [b2, c2, d, mu]);
        let err = whole
            .tf(&whole.values())
            .map_or(f64::NAN, |g| frf_error(frf, &g));
        out.push((
            start_values(lin, [k, a1, a2, q], [b2, c2, d, mu], dt),
            format!(
                "{what}: motor q = {q:.3}, resonance {:.2} Hz, anti-resonance {:.2} Hz \
                 (weighted error {err:.2e})",
                hz(c2),
                hz(b2)
            ),
        ));
    };
    let usable = |m: &[f64; 4], pair: &[f64; 4]| {
        m.iter().chain(pair).all(|&c| c > 0.0 && c.is_finite()) && resonant(pair, w_lo, w_hi)
    };
    // Step 1: the quartic.
    let mut motor: Option<[f64; 4]> = None;
    match from_quartic(frf) {
        Ok((m, pair, mu)) if usable(&m, &pair) => {
            push(m, pair, mu, "quartic Levy fit factored", &mut out);
            motor = Some(m);
        }
        Ok((m, pair, _)) => {
            why.push(format!(
                "the quartic Levy fit has {}",
                pair_words(&pair, w_lo, w_hi)
            ));
            if m.iter().all(|&c| c > 0.0 && c.is_finite()) {
                motor = Some(m);
            }
        }
        Err(e) => why.push(format!("quartic Levy fit: {e}")),
    }
    // Step 2: the alternation.
    let mut motor = match motor {
        Some(m) => m,
        None => {
            let (f, _) = levy_start(frf, true, par)?;
            [f.b[0], f.a[0], f.a[1], f.q]
        }
    };
    for round in 1..=ROUNDS {
        let [k, a1, a2, q] = motor;
        let g_m = levy::commensurate_tf(q, &[k], &[a1, a2])?;
        let ratio = divided(frf, &g_m);
        let (pair, b0) = match pair_of(&ratio.omega, &ratio.h, &ratio.weight) {
            Ok(p) => p,
            Err(e) => {
                why.push(e.to_string());
                break;
            }
        };
        let m = [k * b0, a1, a2, q];
        if !usable(&m, &pair) {
            why.push(format!(
                "the pair fitted has {}",
                pair_words(&pair, w_lo, w_hi)
            ));
            break;
        }
        push(
            m,
            pair,
            1.0,
            &format!("motor and pair apart, round {round}"),
            &mut out,
        );
        let rest = divided(frf, &pair_tf(&pair)?);
        motor = match levy_start(&rest, true, par) {
            Ok((f, _)) => [f.b[0], f.a[0], f.a[1], f.q],
            Err(_) => break,
        };
    }
    if out.is_empty() {
        return Err(Error::NotEnoughData(format!(
            "no resonance in the frequency response: {}",
            why.join("; ")
        )));
    }
    Ok((out, motor[3]))
}

/// The evidence rule on Welch's estimate (see the module documentation): `Ok` when one of
/// `cands` fits `frf` with less than [`EVIDENCE_RATIO`] times the weighted error of its own motor
/// alone (the candidate without its pair): the resonant pair, not a better motor, explains the
/// response.
fn evidence(lin: &FracModel, frf: &Frf, cands: &[Candidate]) -> Result<()> {
    let at = |v: &[f64], n: &str| lin.index_of(n).map_or(f64::NAN, |i| v[i]);
    // (error, its motor's error) of the candidate whose pair lowers the error most.
    let mut best = (f64::INFINITY, f64::INFINITY);
    let mut ratio = f64::INFINITY;
    for (v, _) in cands {
        let Ok(whole) = lin.tf(v) else { continue };
        let Ok(motor) = FracTf::pmsm(
            at(v, "K"),
            at(v, "a1"),
            at(v, "a2"),
            at(v, "zeta"),
            at(v, "theta"),
        ) else {
            continue;
        };
        let (e, m) = (frf_error(frf, &whole), frf_error(frf, &motor));
        if e.is_finite() && m > 0.0 && m.is_finite() && e / m < ratio {
            (best, ratio) = ((e, m), e / m);
        }
    }
    if ratio < EVIDENCE_RATIO {
        return Ok(());
    }
    Err(Error::NotEnoughData(format!(
        "no resonance in the frequency response: on Welch's estimate the two-mass start's \
         weighted error is {:.2e}, its motor's alone {:.2e} (the resonant pair must bring it \
         below {EVIDENCE_RATIO} times that)",
        best.0, best.1
    )))
}

/// The fallback start looks for resonance peaks on Welch's estimate up to this fraction of the
/// Nyquist frequency (the Levy start's band is a quarter of it, [`super::MAX_FRACTION_OF_NYQUIST`]):
/// a drive train's second mode may lie above a quarter (the flexible robot arm of
/// `data/slicot_robot_arm`: 0.126 cycles/sample, at the quarter's edge). The input is divided by
/// the hold ([`crate::hold::zoh`]), which is exact for a held input at any frequency; aliasing of
/// a response that does not roll off is the error left, a start's concern only.
pub const PEAK_FRACTION_OF_NYQUIST: f64 = 0.5;

/// A peak of `|H|` is a resonance when it is at least this many times the higher of the two
/// troughs beside it (the least `|H|` between it and the neighbouring peak, or the band's edge, on
/// either side: its topographic prominence): 3 dB, the half-power rule of a resonance peak.
pub const MIN_PEAK_PROMINENCE: f64 = std::f64::consts::SQRT_2;

/// The damping ratio the peak starts give each resonance (lightly damped; the fit refines it).
pub const PEAK_DAMPING: f64 = 0.05;

/// The fallback start of the two-mass structure, when the Levy start ([`candidates`]) failed with
/// `why`: on Welch's estimate up to [`PEAK_FRACTION_OF_NYQUIST`] of the Nyquist frequency
/// ([`super::welch::h1_up_to`]: the 1% input-power rule kept; with the bins of little input
/// power that [`super::welch::h1_coherent`] adds, the flexible robot arm's peak starts explained
/// 3.7% of its output and its start failed),
///
/// 1. the sign of the gain from the response at the lowest frequency kept (a static gain's phase
///    is near 0 or 180 degrees; a torque or sensor measured with the opposite sign gives 180): a
///    negative one is fitted on `-H` (the Levy fits want positive coefficients);
/// 2. the Levy candidates on `-H` (negative gain only: on `H` they failed already);
/// 3. the peak candidates ([`peak_candidates`]): the resonance at a peak of `|H|`, the
///    anti-resonance at the trough below it, the motor either a second resonance at another peak
///    (two resonant modes: the motor's `a2 s^(zeta+theta) + a1 s^zeta + 1` at
///    `zeta = theta = 1` is a lightly damped pair) or Levy's commensurate fit of `H / R`;
///
/// each then placed in the time domain ([`time_refined`]: the frequencies of its modes within
/// a bin or two of Welch's estimate, the gain with its sign by least squares) and kept only when
/// its pair, not its motor, explains the output (a share of its variance beyond the motor alone).
/// The FRF's own evidence rule does not apply: up to half the Nyquist frequency Welch's estimate
/// of a lightly damped record is too coarse at its peaks (the robot arm's: 8 ms bins of 128
/// samples, the peaks' own bins below the coherence rule). Returns the candidates, the motor's
/// order, the estimate and how it was made.
///
/// # Errors
/// [`Error::NotEnoughData`] ("no resonance in the frequency response"), with `why` first, when no
/// candidate passes; the errors of Welch's estimate.
pub fn fallback(
    lin: &FracModel,
    u: &[f64],
    y: &[f64],
    dt: f64,
    why: Error,
    par: Par,
) -> Result<(Frf, Vec<Candidate>, f64, String)> {
    let plain = |e: &Error| match e {
        Error::NotEnoughData(s) => s.clone(),
        e => e.to_string(),
    };
    let (frf, how) = super::welch::h1_up_to(u, y, dt, PEAK_FRACTION_OF_NYQUIST).map_err(|e| {
        Error::NotEnoughData(format!(
            "no frequency response to start from: {}",
            joined(&plain(&why), &plain(&e))
        ))
    })?;
    let h0 = frf.h[0];
    if h0.re.abs() < h0.im.abs() {
        return Err(Error::NotEnoughData(format!(
            "no resonance in the frequency response: the sign of the gain is not determined \
             (phase {:.0} degrees at the lowest frequency of Welch's estimate)",
            h0.arg().to_degrees()
        )));
    }
    let negative = h0.re < 0.0;
    let mut pos = frf.clone();
    if negative {
        pos.h.iter_mut().for_each(|h| *h = -*h);
    }
    let mut out = vec![];
    let mut q = 1.0;
    if negative {
        if let Ok((c, qm)) = levy_candidates(lin, &pos, dt, par) {
            out.extend(c);
            q = qm;
        }
    }
    out.extend(peak_candidates(lin, &pos, dt, par));
    // The Levy start failed already (`why`): the fallback's own reason is the one to give.
    if out.is_empty() {
        return Err(Error::NotEnoughData(
            "no resonance in the frequency response: neither the Levy fits nor any peak of \
             Welch's estimate (up to half the Nyquist frequency) give a resonant pair"
                .into(),
        ));
    }
    let out = time_refined(lin, out, u, y, dt)?;
    Ok((
        frf,
        out,
        q,
        format!("{how} up to half the Nyquist frequency"),
    ))
}

/// The peaks of `|H|` that are resonances ([`MIN_PEAK_PROMINENCE`]), most prominent first, at
/// most two: `(peak index, index of the trough below it)`.
fn peaks(mag: &[f64]) -> Vec<(usize, usize)> {
    let n = mag.len();
    let tops: Vec<usize> = (1..n.saturating_sub(1))
        .filter(|&i| mag[i] > mag[i - 1] && mag[i] > mag[i + 1])
        .collect();
    let lowest = |a: usize, b: usize| (a..b).min_by(|&x, &y| mag[x].total_cmp(&mag[y]));
    let mut found = vec![];
    for (j, &i) in tops.iter().enumerate() {
        let left = lowest(if j == 0 { 0 } else { tops[j - 1] }, i);
        let right = lowest(i + 1, tops.get(j + 1).map_or(n, |&t| t + 1));
        let (Some(l), Some(r)) = (left, right) else {
            continue;
        };
        let prominence = mag[i] / mag[l].max(mag[r]).max(f64::MIN_POSITIVE);
        if prominence >= MIN_PEAK_PROMINENCE {
            found.push((prominence, i, l));
        }
    }
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    found.into_iter().take(2).map(|(_, i, t)| (i, t)).collect()
}

/// The gain of the unit-gain model `g` on `frf` that matches its magnitude in the weighted
/// geometric mean, `ln K = sum w (ln|H| - ln|G|) / sum w`: a mode a little off its peak errs
/// both ways on a log scale, where a least-squares gain would shrink to avoid the mismatch
/// (`None` unless finite).
fn gain_on(frf: &Frf, g: &FracTf) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for ((&om, h), &w) in frf.omega.iter().zip(&frf.h).zip(&frf.weight) {
        let r = g.freq_response(om).norm();
        if h.norm() > 0.0 && r > 0.0 {
            num += w * (h.norm().ln() - r.ln());
            den += w;
        }
    }
    let k = (num / den).exp();
    (k > 0.0 && k.is_finite()).then_some(k)
}

/// The peak starts on a response of positive gain (see [`fallback`]): for each resonance peak
/// ([`peaks`]) the pair `(b2 s^2 + d s + 1)/(c2 s^2 + d s + 1)` with `c2 = w_r^-2` at the peak,
/// `b2 = w_a^-2` at the trough below it (`w_r / sqrt 2`, equal inertias, when the trough is the
/// band's first frequency) and `d = 2 PEAK_DAMPING / w_r`; the motor either the other peak's
/// resonance (`zeta = theta = 1`, `a2 = w^-2`, `a1 = 2 PEAK_DAMPING / w`) or the commensurate
/// Levy fit of `H / R`; `K` by least squares on the response ([`gain_on`]).
fn peak_candidates(lin: &FracModel, frf: &Frf, dt: f64, par: Par) -> Vec<Candidate> {
    let mag: Vec<f64> = frf.h.iter().map(|h| h.norm()).collect();
    let found = peaks(&mag);
    let hz = |w: f64| w / (2.0 * std::f64::consts::PI);
    let mut out = vec![];
    for (j, &(p, t)) in found.iter().enumerate() {
        let w_r = frf.omega[p];
        let w_a = if t == 0 {
            w_r / std::f64::consts::SQRT_2
        } else {
            frf.omega[t]
        };
        let (b2, c2, d) = (w_a.powi(-2), w_r.powi(-2), 2.0 * PEAK_DAMPING / w_r);
        let Ok(pair) = pair_tf(&[d, b2, d, c2]) else {
            continue;
        };
        let mut motors: Vec<([f64; 4], String)> = vec![];
        if let Some(&(other, _)) = found.get(1 - j.min(1)).filter(|_| found.len() == 2) {
            let w = frf.omega[other];
            motors.push((
                [1.0, 2.0 * PEAK_DAMPING / w, w.powi(-2), 1.0],
                format!("motor resonance {:.4} Hz", hz(w)),
            ));
        }
        if let Ok((f, _)) = levy_start(&divided(frf, &pair), true, par) {
            motors.push(([1.0, f.a[0], f.a[1], f.q], format!("motor q = {:.3}", f.q)));
        }
        for ([_, a1, a2, q], what) in motors {
            let whole = FracModel::two_mass([1.0, a1, a2, q, q], [b2, c2, d, 1.0]);
            let Some(k) = whole
                .tf(&whole.values())
                .ok()
                .and_then(|g| gain_on(frf, &g))
            else {
                continue;
            };
            out.push((
                start_values(lin, [k, a1, a2, q], [b2, c2, d, 1.0], dt),
                format!(
                    "peak of Welch's estimate: resonance {:.4} Hz, anti-resonance {:.4} Hz, {what}",
                    hz(w_r),
                    hz(w_a)
                ),
            ));
        }
    }
    out
}

/// The factors a mode's frequency is scaled by in the time-domain placement ([`time_refined`]):
/// Welch's bins on a short record are coarse (the robot arm's second mode, 0.126 cycles/sample,
/// shows at 0.109, its own bins below the coherence rule).
pub const PEAK_SCALES: [f64; 5] = [0.85, 0.92, 1.0, 1.08, 1.17];

/// Each candidate of [`fallback`] placed in the time domain on deviations `u`, `y`: its gain `K`
/// by linear least squares on its unit-gain output (the sign of the gain is the data's), then,
/// one after the other, the pair's frequencies (`b2`, `c2` over `s^2`, `d` over `s`: the
/// anti-resonance, resonance and damping ratios kept) and, for a resonant motor
/// (`zeta = theta = 1`), the motor's (`a2` over `s^2`, `a1` over `s`) scaled by the factor `s`
/// of [`PEAK_SCALES`] that fits best. A candidate is kept when it explains at least
/// [`super::MIN_FALLBACK_EXPLAINED`] of the output's variance (about its mean) and its pair as
/// much beyond its motor alone (`b2 = c2`: the pair cancels, the gain refitted): the coarse
/// search's rule for its fallback trials (the motor/generator record's best peak start fitted
/// -340% without the first condition). The errors are of outputs simulated from rest, which on a record in motion
/// (the arm's) carry the initial transient in both: a ratio of the two errors would drown the
/// pair's share in it (measured on the arm: the best start's error 0.54 of its motor's alone,
/// 45% of the variance explained beyond it).
///
/// # Errors
/// [`Error::NotEnoughData`] ("no resonance in the frequency response") when no candidate is kept.
fn time_refined(
    lin: &FracModel,
    cands: Vec<Candidate>,
    u: &[f64],
    y: &[f64],
    dt: f64,
) -> Result<Vec<Candidate>> {
    use crate::oe::Structure;
    let m = u.len().min(y.len()).min(super::MAX_COARSE_SAMPLES);
    let (u, y) = (&u[..m], &y[..m]);
    let mut buf = vec![0.0; m];
    let at = |n: &str| lin.index_of(n);
    let (Some(ik), Some(ib2), Some(ic2), Some(id), Some(ia1), Some(ia2)) =
        (at("K"), at("b2"), at("c2"), at("d"), at("a1"), at("a2"))
    else {
        return Err(Error::NotEnoughData("not a two-mass structure".into()));
    };
    // (sse, K) of `v` at its least-squares gain.
    let mut fitted = |v: &mut Vec<f64>| -> Option<f64> {
        v[ik] = 1.0;
        lin.simulate(v, u, dt, &mut buf).ok()?;
        let gg: f64 = buf.iter().map(|a| a * a).sum();
        if !(gg > 0.0 && gg.is_finite()) {
            return None;
        }
        let k = buf.iter().zip(y).map(|(a, b)| a * b).sum::<f64>() / gg;
        v[ik] = k;
        let sse: f64 = buf.iter().zip(y).map(|(a, b)| (b - k * a).powi(2)).sum();
        sse.is_finite().then_some(sse)
    };
    let mut out = vec![];
    let mut best_gain = f64::NEG_INFINITY;
    let mut best_explained = f64::NEG_INFINITY;
    let sst = {
        let mean = y.iter().sum::<f64>() / m as f64;
        y.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>()
    };
    for (v0, label) in cands {
        let resonant_motor = ["zeta", "theta"]
            .iter()
            .all(|n| at(n).is_some_and(|i| v0[i] == 1.0));
        let mut v = v0;
        let Some(mut sse) = fitted(&mut v) else {
            continue;
        };
        let mut modes: Vec<Vec<(usize, i32)>> = vec![vec![(ib2, 2), (ic2, 2), (id, 1)]];
        if resonant_motor {
            modes.push(vec![(ia2, 2), (ia1, 1)]);
        }
        for mode in modes {
            let mut best = (sse, v.clone());
            for s in PEAK_SCALES {
                let mut t = v.clone();
                for &(i, p) in &mode {
                    t[i] = v[i] / s.powi(p);
                }
                if let Some(e) = fitted(&mut t) {
                    if e < best.0 {
                        best = (e, t);
                    }
                }
            }
            (sse, v) = best;
        }
        let mut motor = v.clone();
        motor[ib2] = motor[ic2];
        let alone = fitted(&mut motor).unwrap_or(f64::INFINITY);
        // The share of the output's variance the pair explains beyond its motor alone.
        let gain = (alone - sse) / sst;
        best_gain = best_gain.max(gain);
        best_explained = best_explained.max(1.0 - sse / sst);
        let explains = sse <= (1.0 - super::MIN_FALLBACK_EXPLAINED) * sst;
        if explains && gain >= super::MIN_FALLBACK_EXPLAINED {
            let sign = if v[ik] < 0.0 { "negative gain, " } else { "" };
            out.push((
                v,
                format!(
                    "{label}; placed in the time domain ({sign}the pair explains {:.1}% of the \
                     output's variance beyond its motor alone)",
                    100.0 * gain
                ),
            ));
        }
    }
    if out.is_empty() {
        return Err(Error::NotEnoughData(format!(
            "no resonance in the frequency response: no peak start explains the output (the \
             best explains {:.1}% of its variance, the best pair {:.1}% beyond its motor alone; \
             {:.0}% of each needed)",
            100.0 * best_explained,
            100.0 * best_gain,
            100.0 * super::MIN_FALLBACK_EXPLAINED
        )));
    }
    Ok(out)
}

/// The start's values of `lin` (the two-mass structure): the motor `[K, a1, a2, q]` with both
/// orders `zeta = theta = q`, the pair `[b2, c2, d, mu]`, the delay's start `tau = dt`.
fn start_values(lin: &FracModel, motor: [f64; 4], pair: [f64; 4], dt: f64) -> Vec<f64> {
    let [k, a1, a2, q] = motor;
    let [b2, c2, d, mu] = pair;
    with_values(
        lin,
        &[
            ("K", k),
            ("a1", a1),
            ("a2", a2),
            ("zeta", q),
            ("theta", q),
            ("b2", b2),
            ("c2", c2),
            ("d", d),
            ("mu", mu),
            ("tau", dt),
        ],
    )
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quartic_roots_are_the_roots() {
        // (1 + x/2)(1 + x/5)(1 + 0.1 x + 0.04 x^2): roots -2, -5 and a lightly damped pair.
        let mul = |a: &[f64], b: &[f64]| {
            let mut c = vec![0.0; a.len() + b.len() - 1];
            for (i, x) in a.iter().enumerate() {
                for (j, y) in b.iter().enumerate() {
                    c[i + j] += x * y;
                }
            }
            c
        };
        let p = mul(&mul(&[1.0, 0.5], &[1.0, 0.2]), &[1.0, 0.1, 0.04]);
        let r = quartic_roots(&[p[0], p[1], p[2], p[3], p[4]]).unwrap();
        for want in [
            Complex64::new(-2.0, 0.0),
            Complex64::new(-5.0, 0.0),
            Complex64::new(-1.25, 4.841229182759271),
            Complex64::new(-1.25, -4.841229182759271),
        ] {
            let best = r.iter().map(|x| (x - want).norm()).fold(f64::MAX, f64::min);
            assert!(best < 1e-10 * want.norm(), "{want}: {r:?}");
        }
    }

    /// On the exact response of a two-mass drive train (integer damping, `mu = 1`, the motor
    /// commensurate at `q = 0.89`, as the alternation assumes) the start finds the resonance and
    /// the anti-resonance within 1% and fits the response closely; on a plain PMSM's response it
    /// finds no resonance and fails at once.
    #[test]
    fn the_start_finds_the_resonance_or_says_there_is_none() {
        let w_hz = |c: f64| c.powf(-0.5) / (2.0 * std::f64::consts::PI);
        let inv_w2 = |hz: f64| (2.0 * std::f64::consts::PI * hz).powi(-2);
        let truth = FracModel::two_mass(
            [6.77, 0.0064, 2.8e-5, 0.89, 0.89],
            [inv_w2(28.0), inv_w2(40.0), 4e-4, 1.0],
        );
        let g = truth.tf(&truth.values()).unwrap();
        let omega: Vec<f64> = (0..150)
            .map(|i| 2.0 * std::f64::consts::PI * 10f64.powf(i as f64 / 75.0))
            .collect();
        let frf = |g: &FracTf| Frf {
            h: g.bode(&omega),
            weight: vec![1.0; omega.len()],
            omega: omega.clone(),
            period: None,
            periods_averaged: 0,
            periods_available: 0,
        };
        let lin = crate::diagnose::structures::two_mass();
        let (cands, _) = candidates(&lin, &frf(&g), 1e-3, Par::Seq).unwrap();
        let best = cands
            .iter()
            .map(|(v, _)| {
                let mut m = lin.clone();
                for (p, x) in m.params.iter_mut().zip(v) {
                    p.value = *x;
                }
                let t = m.tf(&m.values()).unwrap();
                (frf_error(&frf(&g), &t), m)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap();
        let (err, m) = best;
        let at = |n: &str| m.params[m.index_of(n).unwrap()].value;
        assert!(
            (w_hz(at("c2")) / 40.0 - 1.0).abs() < 0.01,
            "{}",
            w_hz(at("c2"))
        );
        assert!(
            (w_hz(at("b2")) / 28.0 - 1.0).abs() < 0.01,
            "{}",
            w_hz(at("b2"))
        );
        // Measured 4.2e-3 (weighted relative error squared: about 6% in amplitude, from the
        // order grid's step and the one `d` for two damping coefficients): a start near the
        // truth, which the time-domain fit then refines.
        assert!(err < 1e-2, "{err}");
        let pmsm = FracTf::pmsm(6.77, 0.0064, 2.8e-5, 0.89, 0.89).unwrap();
        let e = candidates(&lin, &frf(&pmsm), 1e-3, Par::Seq).unwrap_err();
        assert!(e.to_string().contains("no resonance"), "{e}");
    }

    /// The evidence rule on Welch's estimate: on a two-mass response its own values pass; on a
    /// plain PMSM's response a candidate whose pair nearly cancels (zeros 0.1% from its poles)
    /// adds nothing to its motor and is refused, and so is one with a real pair (which only
    /// spoils the fit).
    #[test]
    fn the_evidence_rule_wants_a_pair_that_explains_the_response() {
        let inv_w2 = |hz: f64| (2.0 * std::f64::consts::PI * hz).powi(-2);
        let lin = crate::diagnose::structures::two_mass();
        let omega: Vec<f64> = (0..120)
            .map(|i| 2.0 * std::f64::consts::PI * 10f64.powf(i as f64 / 60.0))
            .collect();
        let frf = |g: &FracTf| Frf {
            h: g.bode(&omega),
            weight: vec![1.0; omega.len()],
            omega: omega.clone(),
            period: None,
            periods_averaged: 0,
            periods_available: 0,
        };
        let cand = |b2: f64, c2: f64, d: f64| -> Candidate {
            let v = with_values(
                &lin,
                &[
                    ("K", 6.77),
                    ("a1", 0.0064),
                    ("a2", 2.8e-5),
                    ("zeta", 0.89),
                    ("theta", 0.89),
                    ("b2", b2),
                    ("c2", c2),
                    ("d", d),
                    ("mu", 1.0),
                ],
            );
            (v, String::new())
        };
        let real = cand(inv_w2(28.0), inv_w2(40.0), 4e-4);
        let g = lin.tf(&real.0).unwrap();
        evidence(&lin, &frf(&g), std::slice::from_ref(&real)).unwrap();
        let pmsm = FracTf::pmsm(6.77, 0.0064, 2.8e-5, 0.89, 0.89).unwrap();
        let cancelling = cand(1.001 * inv_w2(40.0), inv_w2(40.0), 4e-4);
        for c in [cancelling, real] {
            let e = evidence(&lin, &frf(&pmsm), &[c]).unwrap_err();
            assert!(e.to_string().contains("no resonance"), "{e}");
        }
    }

    /// A random binary sequence (8192 samples at 1 ms, a 2 ms clock, never repeated) through
    /// `truth`, plus white noise of standard deviation 0.05 (the outputs swing about +-7).
    fn aperiodic_record(truth: &FracModel) -> (Vec<f64>, Vec<f64>) {
        binary_record(truth, 8192, 2, 1e-3, 0.05)
    }

    /// A random binary sequence of `n` samples every `dt` seconds, each level held for `clock`
    /// samples (never repeated), through `truth`, plus uniform white noise of standard deviation
    /// `noise_std`.
    fn binary_record(
        truth: &FracModel,
        n: usize,
        clock: usize,
        dt: f64,
        noise_std: f64,
    ) -> (Vec<f64>, Vec<f64>) {
        use crate::oe::Structure;
        let mut lcg = crate::testdata::lcg(7);
        let mut next = || (lcg() >> 11) as f64 / (1u64 << 53) as f64;
        let mut u = vec![0.0; n];
        for chunk in u.chunks_mut(clock) {
            let b = if next() < 0.5 { -1.0 } else { 1.0 };
            chunk.fill(b);
        }
        let mut y = vec![0.0; u.len()];
        truth.simulate(&truth.values(), &u, dt, &mut y).unwrap();
        for v in &mut y {
            *v += noise_std * 12f64.sqrt() * (next() - 0.5);
        }
        (u, y)
    }

    /// A drive train measured at the motor as the zoo's `two_mass_motor` class makes them: a
    /// rigid body of time constant 30 ms (its corner at 5.3 Hz), the anti-resonance at 40 Hz and
    /// the resonance at 110 Hz (damping ratio 0.06 there), sampled at 0.5 ms and driven by a
    /// random binary sequence clocked at a third of the time constant (10 ms, 20 samples; 4096
    /// samples, 0.2% noise). The input's power near the resonance is 0.01-1% of its largest (the
    /// sequence's first spectral null at 100 Hz), the response's coherence there near 1: the
    /// start's estimate keeps those bins by their coherence (measured: 20 bins within 90-130 Hz,
    /// where the 1% input-power rule of [`super::super::welch::h1`] keeps 6) and the start finds
    /// the resonance within 5% (measured 109.67 Hz, the start fitting 88%).
    #[test]
    fn a_slow_binary_input_still_shows_the_resonance() {
        let w = |hz: f64| 2.0 * std::f64::consts::PI * hz;
        let (w_a, w_r) = (w(40.0), w(110.0));
        let truth = FracModel::two_mass(
            [1.3, 0.03, 1e-8, 1.0, 1.0],
            [w_a.powi(-2), w_r.powi(-2), 2.0 * 0.06 / w_r, 1.0],
        );
        let (u, y) = binary_record(&truth, 4096, 20, 5e-4, 0.002 * 1.3);
        let (frf, _) = super::super::welch::h1(&u, &y, 5e-4).unwrap();
        let near = |f: &Frf| {
            f.omega
                .iter()
                .filter(|&&o| o > w(90.0) && o < w(130.0))
                .count()
        };
        let (coherent, _) = super::super::welch::h1_coherent(&u, &y, 5e-4).unwrap();
        eprintln!(
            "bins within 90-130 Hz: {} by the 1% input-power rule, {} by the coherence alone",
            near(&frf),
            near(&coherent)
        );
        assert!(
            near(&coherent) > near(&frf) + 5,
            "{} {}",
            near(&coherent),
            near(&frf)
        );
        let mut m = crate::diagnose::structures::two_mass();
        let r = super::super::auto_start(&mut m, &u, &y, 5e-4, Par::Seq).unwrap();
        let at = |n: &str| m.params[m.index_of(n).unwrap()].value;
        let f_r = at("c2").powf(-0.5) / (2.0 * std::f64::consts::PI);
        eprintln!("{}; fit {:?}; resonance {f_r:.2} Hz", r.note, r.fit_percent);
        assert!((f_r / 110.0 - 1.0).abs() < 0.05, "resonance {f_r} Hz");
        assert!(r.fit_percent.unwrap() > 80.0, "{r:?}");
    }

    /// Without a periodic input the two-mass start comes from Welch's estimate: on a two-mass
    /// drive train (resonance 40 Hz, anti-resonance 28 Hz) it starts near the resonance and says
    /// how it was made; on a plain PMSM it fails with "no resonance" from the Levy fits on the
    /// estimate, before any candidate is simulated (that error is raised before the candidates
    /// are returned to be simulated). Other structures get no Welch start: their coarse start is
    /// unchanged.
    #[test]
    fn an_aperiodic_record_starts_from_welchs_estimate() {
        let inv_w2 = |hz: f64| (2.0 * std::f64::consts::PI * hz).powi(-2);
        let truth = FracModel::two_mass(
            [6.77, 0.0064, 2.8e-5, 0.89, 0.89],
            [inv_w2(28.0), inv_w2(40.0), 4e-4, 1.0],
        );
        let (u, y) = aperiodic_record(&truth);
        assert_eq!(super::super::periodic_part(&u), None);
        let mut m = crate::diagnose::structures::two_mass();
        let r = super::super::auto_start(&mut m, &u, &y, 1e-3, Par::Seq).unwrap();
        assert!(r.note.contains("Welch's estimate"), "{}", r.note);
        let c2 = m.params[m.index_of("c2").unwrap()].value;
        let f_r = c2.powf(-0.5) / (2.0 * std::f64::consts::PI);
        eprintln!("{}; fit {:?}; resonance {f_r:.2} Hz", r.note, r.fit_percent);
        assert!((f_r / 40.0 - 1.0).abs() < 0.05, "resonance {f_r} Hz");
        assert!(r.fit_percent.unwrap() > 90.0, "{r:?}");

        let pmsm = FracModel::pmsm(6.77, 0.0064, 2.8e-5, 0.89, 0.89);
        let (u, y) = aperiodic_record(&pmsm);
        let mut m = crate::diagnose::structures::two_mass();
        let t0 = std::time::Instant::now();
        let e = super::super::auto_start(&mut m, &u, &y, 1e-3, Par::Seq).unwrap_err();
        eprintln!("{:.1} ms: {e}", 1e3 * t0.elapsed().as_secs_f64());
        assert!(e.to_string().contains("no resonance"), "{e}");
        // Other structures: the coarse search, as before.
        let mut m = FracModel::pmsm(1.0, 1.0, 1.0, 1.0, 1.0);
        let r = super::super::auto_start(&mut m, &u, &y, 1e-3, Par::Seq).unwrap();
        assert_eq!(r.method, super::super::StartMethod::Coarse, "{r:?}");
        assert!(r.note.contains("not periodic"), "{}", r.note);
    }

    /// The fallback on a negative gain: the two-mass drive train of the test above seen through a
    /// sensor of the opposite sign (`-y`, aperiodic input) has no Levy start (its coefficients
    /// would be negative); the fallback takes the sign from the lowest frequency and the resonance
    /// from the peak, and starts with `K < 0` and the resonance within 10% of 40 Hz (Welch's bins
    /// are 1.95 Hz apart at 512 samples, the time-domain placement scales by 8%). The plain PMSM
    /// with the opposite sign has no resonance: the fallback refuses it too.
    #[test]
    fn a_negative_gain_starts_from_the_resonance_peak() {
        let inv_w2 = |hz: f64| (2.0 * std::f64::consts::PI * hz).powi(-2);
        let truth = FracModel::two_mass(
            [6.77, 0.0064, 2.8e-5, 0.89, 0.89],
            [inv_w2(28.0), inv_w2(40.0), 4e-4, 1.0],
        );
        let (u, y) = aperiodic_record(&truth);
        let y: Vec<f64> = y.iter().map(|v| -v).collect();
        let mut m = crate::diagnose::structures::two_mass();
        let r = super::super::auto_start(&mut m, &u, &y, 1e-3, Par::Seq).unwrap();
        let at = |n: &str| m.params[m.index_of(n).unwrap()].value;
        let f_r = at("c2").powf(-0.5) / (2.0 * std::f64::consts::PI);
        let f_m = (at("a2").powf(-0.5 / at("zeta"))) / (2.0 * std::f64::consts::PI);
        eprintln!(
            "{}; fit {:?}; resonance {f_r:.2} Hz, motor {f_m:.2} Hz",
            r.note, r.fit_percent
        );
        assert!(at("K") < 0.0, "{}", r.note);
        assert!(r.note.contains("half the Nyquist"), "{}", r.note);
        assert!((f_r / 40.0 - 1.0).abs() < 0.1, "resonance {f_r} Hz");
        assert!(r.fit_percent.unwrap() > 50.0, "{r:?}");

        let pmsm = FracModel::pmsm(6.77, 0.0064, 2.8e-5, 0.89, 0.89);
        let (u, y) = aperiodic_record(&pmsm);
        let y: Vec<f64> = y.iter().map(|v| -v).collect();
        let mut m = crate::diagnose::structures::two_mass();
        let e = super::super::auto_start(&mut m, &u, &y, 1e-3, Par::Seq).unwrap_err();
        assert!(e.to_string().contains("no resonance"), "{e}");
    }

    /// The peaks: a resonance is a local maximum 3 dB above the higher trough beside it (between
    /// it and the neighbouring local maximum, or the edge); the trough below is returned with it;
    /// a ripple (4% up) is not one, nor is a falling response.
    #[test]
    fn peaks_are_prominent_local_maxima() {
        let mag = [1.0, 0.9, 0.2, 3.0, 1.5, 1.2, 1.3, 1.25, 1.8, 0.1, 0.05];
        // 3.0 at 3: troughs 0.2 (left) and 1.2 (right): 2.5x. 1.3 at 6: 1.2 and 1.25: no.
        // 1.8 at 8: troughs 1.25 (after the ripple at 6) and 0.05: 1.44x.
        assert_eq!(peaks(&mag), vec![(3, 2), (8, 7)]);
        assert!(peaks(&[3.0, 2.0, 1.0, 0.5]).is_empty());
    }
}
