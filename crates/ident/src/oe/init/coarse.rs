//! The coarse search of a start ([`coarse_start`]): trial models of each order at corner
//! frequencies over the record's band, the gain by linear least squares, screened with a cheaper
//! approximation and the best few scored again with the model's own; resonant and negative-gain
//! fallbacks when no damped trial has a positive gain.

use super::{sse_of, with_values, MAX_COARSE_SAMPLES, MIN_FALLBACK_EXPLAINED};
use crate::oe::{FracModel, Kind, Structure};
use std::f64::consts::PI;

/// The coarse search's resonant fallback trials: these damping ratios at each of
/// [`RESONANT_CORNERS`] corner frequencies (structures with a second-order denominator only).
const RESONANT_DAMPING: [f64; 2] = [0.05, 0.2];

/// The coarse search's fallbacks run only when the output deviations take each sign in at least
/// this share of the samples.
const MIN_SIGN_SHARE: f64 = 0.1;

/// The number of corner frequencies of the resonant trials, log-spaced over the coarse band (a
/// lightly damped peak is narrow: a finer grid than the damped trials').
const RESONANT_CORNERS: usize = 24;

/// The coarse search: for each commensurate order `q` in `{0.5, 0.7, 0.9}` (`q = 1` for the FOPDT
/// model) and each of 10 corner frequencies `w_c` log-spaced from `2 pi / T` to a quarter of the
/// Nyquist frequency, the model `K / (1 + (s/w_c)^q / 2)^2` (`K / (s/w_c + 1)` for the FOPDT) is
/// simulated, `K` is the linear least-squares gain; the smallest squared error wins. Returns
/// `(sse, values)`. The trials are screened with at most [`COARSE_APPROX_ORDER`] as the
/// approximation's order (each is a model built cold); the best few are simulated again with the
/// model's own approximation, which decides and gives the winner's `K` and `sse`.
///
/// When no trial has a positive least-squares gain (today's search finds no start: the model
/// kept its given values), two fallbacks are tried and the better taken: structures with a
/// second-order denominator (`a2`: the PMSM, commensurate and integer second and third order)
/// try a lightly damped resonance, `K / (s^2/w^2 + 2 z s/w + 1)` at order 1 (the third order
/// times `1/(1 + s/(4 w))`) for `z` in [`RESONANT_DAMPING`] at [`RESONANT_CORNERS`] frequencies
/// `w` over the same band (from a critically damped trial the fit cannot reach a lightly damped
/// mode: its output-error cost has a narrow valley at the resonance); and every trial may keep a
/// negative gain (a torque or sensor measured with the opposite sign: the output falls when the
/// input rises; the caller then frees `K`'s sign). A record any damped trial describes with a
/// positive gain keeps today's start, and so does an output whose deviations keep one sign in all
/// but [`MIN_SIGN_SHARE`] of the samples (a sign-blind sensor's: no sign of the gain to tell).
///
/// The trials are simulated on the leading [`MAX_COARSE_SAMPLES`] samples (all of a shorter
/// record); the corner frequencies span the whole record's band, and the winner's `sse` is that
/// of the record (`u`, `y`: the caller passes the part the starts are scored on).
pub(super) fn coarse_start(
    lin: &FracModel,
    u: &[f64],
    y: &[f64],
    dt: f64,
) -> Option<(f64, Vec<f64>)> {
    let n = u.len();
    let (u_all, y_all) = (u, y);
    let m = n.min(MAX_COARSE_SAMPLES);
    let (u, y) = (&u[..m], &y[..m]);
    let qs: &[f64] = if matches!(lin.kind, Kind::Fopdt | Kind::Integer) {
        &[1.0]
    } else {
        &[0.5, 0.7, 0.9]
    };
    let band = (2.0 * PI / (n as f64 * dt), 0.25 * PI / dt);
    let family = Family::of(lin, dt);
    let trials = Trials { u, y, dt };
    let mut yhat = vec![0.0; m];
    // The damped trials are far apart (no nearby model's poles to start from), so they are
    // screened with fewer approximation cells ([`COARSE_APPROX_ORDER`]) and one model per order,
    // frequency-scaled ([`Trials::screen_damped`]); of each sign of the gain, the best few are
    // scored again with the model's own approximation, which decides.
    let mut cheap = lin.clone();
    cheap.approx.order = cheap.approx.order.min(COARSE_APPROX_ORDER);
    let (pos, neg) = trials.screen_damped(&family, &cheap, qs, band, &mut yhat);
    // (sse, K, unit-gain values): today's best (damped, K > 0), the best resonant one with
    // K > 0, and the best of either kind with K < 0.
    let (mut usual, mut resonance, mut negative): (Best, Best, Best) = (None, None, None);
    trials.rescore(lin, pos, &mut usual, true, &mut yhat);
    if usual.is_none() {
        trials.rescore(lin, neg, &mut negative, false, &mut yhat);
    }
    // The fallbacks only for an output that swings both ways about its operating point: one that
    // keeps one sign (a sign-blind sensor's) tells no sign of the gain, and starts as before.
    let share = |pos: bool| y.iter().filter(|&&v| (v > 0.0) == pos && v != 0.0).count();
    let both_ways = (share(true).min(share(false)) as f64) >= MIN_SIGN_SHARE * m as f64;
    if !both_ways {
        negative = None;
    }
    // The resonant trials only as the fallback (no cost where the damped trials found a start).
    if usual.is_none() && both_ways && lin.index_of("a2").is_some() {
        trials.resonant(&family, band, &mut resonance, &mut negative, &mut yhat);
    }
    let (sse, k, mut v) = choose(usual, resonance, negative, y)?;
    // The gain as fitted, whatever its sign (not clamped into `K`'s positive range: the caller
    // frees it when it is negative).
    if let Some(i) = lin.index_of("K").filter(|&i| lin.params[i].free) {
        v[i] = k;
    }
    if m == n {
        return Some((sse, v));
    }
    let mut buf = vec![0.0; n];
    sse_of(lin, &v, u_all, y_all, dt, 0, &mut buf).map(|s| (s, v))
}

/// A trial's squared error, its gain and its unit-gain values.
type Best = Option<(f64, f64, Vec<f64>)>;

/// Keep `(sse, k, v)` in `best` when it is better.
fn keep(best: &mut Best, sse: f64, k: f64, v: Vec<f64>) {
    if best.as_ref().is_none_or(|b| sse < b.0) {
        *best = Some((sse, k, v));
    }
}

/// (screening sse, unit-gain values) of screened trials.
type Screened = Vec<(f64, Vec<f64>)>;

/// The trial models' values of the coarse search for a structure: the third order as
/// `K / ((1 + s/w_c)(1 + s/(2 w_c))(1 + s/(4 w_c)))` and the integer second order as
/// `K / ((1 + s/(1.5 w_c))(1 + s/(3 w_c)))` (the same `a1 = 1/w_c`; distinct poles: the modal
/// form cannot represent a repeated pole, and `(1 + s/(2 w_c))^2` is one exactly), the others
/// `K / (1 + (s/w_c)^q / 2)^2` (a fractional `q` spreads the approximation's poles).
struct Family<'a> {
    lin: &'a FracModel,
    dt: f64,
    third: bool,
    integer_second: bool,
}

impl<'a> Family<'a> {
    fn of(lin: &'a FracModel, dt: f64) -> Self {
        let third = lin.index_of("a3").is_some();
        Self {
            lin,
            dt,
            third,
            integer_second: lin.kind == Kind::Integer && !third,
        }
    }

    /// The values with these coefficients, order and corner (unit gain).
    fn with(&self, a1: f64, a2: f64, a3: f64, q: f64, wc: f64) -> Vec<f64> {
        with_values(
            self.lin,
            &[
                ("K", 1.0),
                ("a1", a1),
                ("a2", a2),
                ("a3", a3),
                ("q", q),
                ("zeta", q),
                ("theta", q),
                ("T", 1.0 / wc),
                ("tau", self.dt),
            ],
        )
    }

    /// The damped trial of order `q` at the corner `wc`.
    fn damped(&self, q: f64, wc: f64) -> Vec<f64> {
        let a1 = wc.powf(-q);
        if self.third {
            self.with(1.75 * a1, 0.875 * a1 * a1, 0.125 * a1 * a1 * a1, q, wc)
        } else if self.integer_second {
            self.with(a1, a1 * a1 / 4.5, 0.0, q, wc)
        } else {
            self.with(a1, a1 * a1 / 4.0, 0.0, q, wc)
        }
    }

    /// The resonant trial `s^2/w^2 + 2 z s/w + 1`, times `1 + s/(4 w)` for the third order.
    fn resonant(&self, w: f64, z: f64) -> Vec<f64> {
        if self.third {
            let (a1, a2, a3) = (
                2.0 * z / w + 0.25 / w,
                (1.0 + 0.5 * z) / (w * w),
                0.25 / w.powi(3),
            );
            self.with(a1, a2, a3, 1.0, w)
        } else {
            self.with(2.0 * z / w, 1.0 / (w * w), 0.0, 1.0, w)
        }
    }
}

/// The data the trials are simulated on and scored against.
struct Trials<'a> {
    u: &'a [f64],
    y: &'a [f64],
    dt: f64,
}

impl Trials<'_> {
    /// A trial's unit-gain output `yhat` scored: `(sse, K)` with `K` by linear least squares
    /// (the sums in interleaved partial sums, `fracsim::lanes`: vectorised).
    fn score(&self, yhat: &[f64]) -> Option<(f64, f64)> {
        let y = self.y;
        let gg = crate::lm::dot(yhat, yhat);
        if !(gg > 0.0 && gg.is_finite()) {
            return None;
        }
        let k = crate::lm::dot(yhat, y) / gg;
        let sse = fracsim::lanes::sum_of2(yhat, y, |a, b| (b - k * a) * (b - k * a));
        sse.is_finite().then_some((sse, k))
    }

    /// A trial with values `v` simulated by `model` at unit gain (into `yhat`) and scored.
    fn trial(&self, model: &FracModel, v: &[f64], yhat: &mut [f64]) -> Option<(f64, f64)> {
        model.simulate(v, self.u, self.dt, yhat).ok()?;
        self.score(yhat)
    }

    /// The damped trials of each order `qs` at ten corners log-spaced over `band`, screened by
    /// `cheap` (the model with fewer cells), split by the sign of their gain.
    ///
    /// The damped trials of one order are one system at ten corners, `G(s/w_c)`: each is screened
    /// as the trial at the middle corner `w_ref` (approximated over the model's band) with its
    /// frequency axis scaled by `w_c/w_ref` ([`fracsim::modal::PoleResidue::frequency_scaled`]),
    /// its cells placed about its corner as the reference's are about `w_ref`: one eigenvalue
    /// problem for the ten (each built cold, they were most of the start's cost on a short
    /// record). A structure whose trials are not one system scaled (checked on their terms)
    /// builds each.
    fn screen_damped(
        &self,
        family: &Family<'_>,
        cheap: &FracModel,
        qs: &[f64],
        (w_lo, w_hi): (f64, f64),
        yhat: &mut [f64],
    ) -> (Screened, Screened) {
        let (u, dt) = (self.u, self.dt);
        let (mut pos, mut neg): (Screened, Screened) = (vec![], vec![]);
        let w_ref = (w_lo * w_hi).sqrt();
        let mut screen_out = vec![0.0; u.len()];
        for &q in qs {
            let reference = Screening::of(cheap, &family.damped(q, w_ref), dt);
            for i in 0..10 {
                let wc = w_lo * (w_hi / w_lo).powf(i as f64 / 9.0);
                let v = family.damped(q, wc);
                let scored = match &reference {
                    Some(r) if r.scales_to(cheap, &v, wc / w_ref) => r
                        .simulate(wc / w_ref, u, dt, &mut screen_out)
                        .and_then(|()| self.score(&screen_out)),
                    _ => self.trial(cheap, &v, yhat),
                };
                if let Some((sse, k)) = scored {
                    if k > 0.0 { &mut pos } else { &mut neg }.push((sse, v));
                }
            }
        }
        (pos, neg)
    }

    /// The best `screened` trials scored again by `lin` (the model's own approximation): at
    /// most [`COARSE_RESCORED`], those within [`COARSE_RESCORE_WITHIN`] of the best screening
    /// error (the first always); the best with a gain of the sign `positive` kept in `best`.
    fn rescore(
        &self,
        lin: &FracModel,
        mut screened: Screened,
        best: &mut Best,
        positive: bool,
        yhat: &mut [f64],
    ) {
        // Stable: equal screening errors keep the trials' order.
        screened.sort_by(|a, b| a.0.total_cmp(&b.0));
        let first = screened.first().map_or(0.0, |t| t.0);
        for (rescored, (s_cheap, v)) in screened.into_iter().enumerate() {
            let near = s_cheap <= COARSE_RESCORE_WITHIN * first;
            if rescored >= COARSE_RESCORED || (!near && best.is_some()) {
                break;
            }
            if let Some((sse, k)) = self.trial(lin, &v, yhat) {
                if (k > 0.0) == positive {
                    keep(best, sse, k, v);
                }
            }
        }
    }

    /// The resonant fallback trials ([`RESONANT_DAMPING`] at [`RESONANT_CORNERS`] corners over
    /// `band`), the best of positive gain into `resonance`, of negative gain into `negative`.
    fn resonant(
        &self,
        family: &Family<'_>,
        (w_lo, w_hi): (f64, f64),
        resonance: &mut Best,
        negative: &mut Best,
        yhat: &mut [f64],
    ) {
        for i in 0..RESONANT_CORNERS {
            let w = w_lo * (w_hi / w_lo).powf(i as f64 / (RESONANT_CORNERS - 1) as f64);
            for z in RESONANT_DAMPING {
                let v = family.resonant(w, z);
                if let Some((sse, k)) = self.trial(family.lin, &v, yhat) {
                    let best = if k > 0.0 {
                        &mut *resonance
                    } else {
                        &mut *negative
                    };
                    keep(best, sse, k, v);
                }
            }
        }
    }
}

/// The coarse search's choice: today's start (`usual`) when there is one; else (no damped trial
/// with a positive gain: none at all before the fallbacks) the better of the resonant
/// positive-gain trials and the trials of negative gain, each only when it explains at least
/// [`MIN_FALLBACK_EXPLAINED`] of the variance of `y` (a record no linear trial describes, say a
/// sign-blind sensor's |y| about a moving operating point, swings both ways, yet its best
/// negative gain explains next to nothing: it starts as before). The fallbacks change no start
/// the damped trials make.
fn choose(usual: Best, resonance: Best, negative: Best, y: &[f64]) -> Best {
    let m = y.len();
    let sst = {
        let mean = y.iter().sum::<f64>() / m as f64;
        y.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>()
    };
    let explains = |b: &Best| {
        b.as_ref()
            .is_some_and(|t| t.0 <= (1.0 - MIN_FALLBACK_EXPLAINED) * sst)
    };
    let resonance = if explains(&resonance) {
        resonance
    } else {
        None
    };
    let negative = if explains(&negative) { negative } else { None };
    match (usual, resonance, negative) {
        (Some(a), _, _) => Some(a),
        (None, Some(b), Some(c)) => Some(if b.0 <= c.0 { b } else { c }),
        (None, b, c) => b.or(c),
    }
}

/// `(coefficient, order)` terms of a transfer function's numerator or denominator.
type Terms = Vec<(f64, f64)>;

/// A coarse trial's approximated model at a reference corner, for the trials that are the same
/// system at other corners (`G(s/c)`, see [`coarse_start`]).
struct Screening {
    /// Its `(coefficient, order)` terms, numerator and denominator.
    num: Terms,
    den: Terms,
    /// Its input delay (s), which a corner does not scale.
    delay: f64,
    /// Its pole-residue form.
    model: fracsim::modal::PoleResidue<f64>,
}

impl Screening {
    /// The terms and delay of `m` at `v`, when its linear part is one rational-in-operators
    /// transfer function with nothing else (no series factors, effects or initial state).
    fn terms(m: &FracModel, v: &[f64]) -> Option<(Terms, Terms, f64)> {
        if !m.series.is_empty() || !m.effects.is_empty() || m.past.is_some() {
            return None;
        }
        let eval = |t: &[(crate::oe::Expr, crate::oe::Expr)]| -> Terms {
            t.iter().map(|(c, o)| (c.eval(v), o.eval(v))).collect()
        };
        Some((eval(&m.num), eval(&m.den), m.delay.map_or(0.0, |i| v[i])))
    }

    /// `m` at `v`, approximated over its band for `dt` (`None` when it does not build or is not
    /// one transfer function).
    fn of(m: &FracModel, v: &[f64], dt: f64) -> Option<Self> {
        let (num, den, delay) = Self::terms(m, v)?;
        let band = m.approx.band_for(dt).ok()?;
        let model = fracsim::modal::pole_residue(&num, &den, band, &m.approx).ok()?;
        Some(Self {
            num,
            den,
            delay,
            model,
        })
    }

    /// Whether `m` at `v` is this system with its frequency axis scaled by `c`: the same orders
    /// and delay, each coefficient of order `alpha` this one's times `c^-alpha` (to 1e-9).
    fn scales_to(&self, m: &FracModel, v: &[f64], c: f64) -> bool {
        let Some((num, den, delay)) = Self::terms(m, v) else {
            return false;
        };
        let same = |a: &[(f64, f64)], b: &[(f64, f64)]| {
            a.len() == b.len()
                && a.iter().zip(b).all(|(&(ca, oa), &(cb, ob))| {
                    oa == ob && (cb - ca * c.powf(-oa)).abs() <= 1e-9 * cb.abs().max(ca.abs())
                })
        };
        delay == self.delay && same(&self.num, &num) && same(&self.den, &den)
    }

    /// The unit-gain output of the system scaled by `c` for the input `u` from rest, into `y`.
    fn simulate(&self, c: f64, u: &[f64], dt: f64, y: &mut [f64]) -> Option<()> {
        let model = self.model.frequency_scaled(c).ok()?;
        let mut sim = fracsim::Simulator::from_pole_residue(model, self.delay, dt).ok()?;
        sim.run_into(u, y);
        y.iter().all(|v| v.is_finite()).then_some(())
    }
}

/// The approximation order `N` the coarse search screens its trials with (at most the model's):
/// `2N + 1` cells per operator, the eigenvalue problem of a trial's model about an eighth of
/// the default `N = 8`'s. Its error (a few percent of the response near the band's cells) is far
/// below the differences between the trials (corner frequencies a factor 1.9 apart, orders 0.2).
const COARSE_APPROX_ORDER: usize = 4;

/// The coarse search scores again with the model's own approximation the screened trials whose
/// screening error is within this factor of the best one's, at most [`COARSE_RESCORED`] of them
/// (the best one always).
const COARSE_RESCORE_WITHIN: f64 = 1.25;

/// See [`COARSE_RESCORE_WITHIN`].
const COARSE_RESCORED: usize = 3;

#[cfg(test)]
mod tests {
    use super::*;

    /// A damped trial screened as the reference trial frequency-scaled ([`Screening`]) is the
    /// trial itself approximated over the band scaled alike and built cold (the truth: its own
    /// eigenvalue problem; the refined Oustaloup cells and gain scale with the band): the
    /// outputs agree to 1e-9 of the output's range (rounding in the poles, residues and the
    /// discretisation), for the three orders the coarse search tries. A trial of another order is
    /// not the reference's system scaled, nor is a trial of the same order off the damped family.
    #[test]
    fn a_scaled_screening_model_is_the_trial_approximated_on_the_scaled_band() {
        let dt = 1e-4;
        let n = 3000;
        let u: Vec<f64> = (0..n)
            .map(|k| if (k * 7919 / 13) % 5 < 2 { 1.0 } else { -1.0 })
            .collect();
        let mut cheap = FracModel::pmsm(1.0, 0.01, 1e-4, 0.9, 0.9);
        cheap.approx.order = COARSE_APPROX_ORDER;
        let damped = |q: f64, wc: f64, a2_factor: f64| {
            let a1 = wc.powf(-q);
            with_values(
                &cheap,
                &[
                    ("K", 1.0),
                    ("a1", a1),
                    ("a2", a1 * a1 * a2_factor),
                    ("zeta", q),
                    ("theta", q),
                ],
            )
        };
        let (w_ref, wc) = (400.0, 3000.0);
        let c = wc / w_ref;
        let band = cheap.approx.band_for(dt).unwrap();
        for q in [0.5, 0.7, 0.9] {
            let reference = Screening::of(&cheap, &damped(q, w_ref, 0.25), dt).unwrap();
            let v = damped(q, wc, 0.25);
            assert!(reference.scales_to(&cheap, &v, c));
            let mut fast = vec![0.0; n];
            reference.simulate(c, &u, dt, &mut fast).unwrap();
            let mut on_scaled_band = cheap.clone();
            on_scaled_band.approx.band = Some((band.0 * c, band.1 * c));
            let mut truth = vec![0.0; n];
            on_scaled_band.simulate(&v, &u, dt, &mut truth).unwrap();
            let (lo, hi) = crate::lm::range_of(&truth);
            let worst = fast
                .iter()
                .zip(&truth)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst <= 1e-9 * (hi - lo), "q {q}: {worst:e} of {}", hi - lo);
            assert!(!reference.scales_to(&cheap, &damped(q + 0.05, wc, 0.25), c));
            assert!(!reference.scales_to(&cheap, &damped(q, wc, 0.3), c));
        }
    }
}
