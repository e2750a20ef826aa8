//! Free responses of a [`Simulator`] from several initial states in one pass
//! ([`Simulator::free_responses`]).
//!
//! With no input a mode is a geometric sequence, `x_(k+i) = phi^i x_k`, so a block of `W = 16`
//! samples of the output is a product of the states with a table of powers,
//! `y_(k+i) = sum_m phi_m^i x_(m,k)` (the real part for a complex mode), and the states move on by
//! `phi^W` once per block. Unlike a simulation, no sample waits for the previous one: the work is
//! fused multiply-adds of a state with a row of the table (two vectors of eight lanes, four of
//! four), in four independent sums. Measured (`free_responses` of two responses against two
//! simulations on zeros, the paper's PMSM at 0.5 ms, 35 real modes and 2 complex pairs, 700 000
//! samples, AVX-512): 5.3 ms against 8.4 ms.

use super::isa::{with_isa, Isa, Simd, WithSimd};
use super::Simulator;
use crate::cx::Cx;
use crate::error::{invalid, Result};

/// Samples per block: the length of a row of the table of powers.
const W: usize = 16;

impl Simulator<f64> {
    /// The free responses (zero input from `t_0 = 0` on) from the states that past held inputs
    /// leave: for each `j`, the input `levels[j]` on the windows `edges` as
    /// [`Simulator::set_past_input`] takes them, then zero. Writes `outs[j][k - skip] = y_k` for
    /// the samples `k` from `skip` to `skip + outs[j].len()` (all of one length): what
    /// `set_past_input(&levels[j], edges)` then [`Simulator::run_into`] on zeros gives, to
    /// rounding, at a fraction of its cost (see the module documentation). The samples that still
    /// read a past input through the input delay are simulated as such. The simulator is left at
    /// rest.
    ///
    /// ```
    /// use fracsim::{ApproxSpec, FracTf, Simulator};
    /// let g: FracTf = "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)".parse().unwrap();
    /// let mut sim = Simulator::<f64>::new(&g, 5e-4, &ApproxSpec::default()).unwrap();
    /// let edges = [0.01, 0.1];
    /// let (mut a, mut b) = (vec![0.0; 500], vec![0.0; 500]);
    /// sim.free_responses(&[vec![1.0, 0.0, 0.0], vec![0.0, 0.0, 1.0]], &edges, 0, &mut [&mut a, &mut b])
    ///     .unwrap();
    /// sim.set_past_input(&[1.0, 0.0, 0.0], &edges).unwrap();
    /// let mut y = vec![0.0; 500];
    /// sim.run_into(&vec![0.0; 500], &mut y);
    /// assert!((a[499] - y[499]).abs() < 1e-12 * 6.82);
    /// ```
    ///
    /// # Errors
    /// [`crate::Error::Invalid`] when `levels` and `outs` differ in number or the outputs in
    /// length, and as [`Simulator::set_past_input`].
    pub fn free_responses(
        &mut self,
        levels: &[Vec<f64>],
        edges: &[f64],
        skip: usize,
        outs: &mut [&mut [f64]],
    ) -> Result<()> {
        self.free_responses_with(Isa::detect(), levels, edges, skip, outs)
    }

    /// [`Simulator::free_responses`] compiled for the instruction set `isa`.
    pub(crate) fn free_responses_with(
        &mut self,
        isa: Isa,
        levels: &[Vec<f64>],
        edges: &[f64],
        skip: usize,
        outs: &mut [&mut [f64]],
    ) -> Result<()> {
        let (head, modes, mut states) = self.free_start(levels, edges, skip, outs)?;
        let n = skip + outs.first().map_or(0, |o| o.len());
        let tail = Tail {
            modes: &modes,
            states: &mut states,
            range: head..n,
            skip,
            outs,
        };
        with_isa!(isa, s => s.vectorize(tail));
        Ok(())
    }

    /// The part of [`Simulator::free_responses`] before the table: the arguments checked, the
    /// samples up to `head` (those that read a past input through the delay) simulated into
    /// `outs`, and the states at `head` of each response; returns `head`, the powers and the
    /// states. The simulator is left at rest.
    fn free_start(
        &mut self,
        levels: &[Vec<f64>],
        edges: &[f64],
        skip: usize,
        outs: &mut [&mut [f64]],
    ) -> Result<(usize, Modes, States)> {
        let len = outs.first().map_or(0, |o| o.len());
        if levels.len() != outs.len() || outs.iter().any(|o| o.len() != len) {
            return invalid(
                "free responses",
                format!(
                    "{} level sets for {} outputs (all of one length)",
                    levels.len(),
                    outs.len()
                ),
            );
        }
        let n = skip + len;
        // From sample m + 1 on, the delayed input (and the feed-through) reads only zeros.
        let head = (self.delay_whole + 1).min(n);
        let mut xr = Vec::with_capacity(levels.len());
        let mut xc = Vec::with_capacity(levels.len());
        // The modes' window weights, once for every level set (of one length: edges + 1).
        let weights = self.past_weights(edges.len() + 1, edges)?;
        for (set, out) in levels.iter().zip(outs.iter_mut()) {
            if set.len() != edges.len() + 1 {
                return invalid(
                    "past input",
                    format!("{} levels for {} edges", set.len(), edges.len()),
                );
            }
            self.set_past_input_weighted(set, edges, &weights);
            for k in 0..head {
                let y = self.step(0.0);
                if k >= skip {
                    out[k - skip] = y;
                }
            }
            xr.push(self.re_x.clone());
            xc.push(self.cx_x.clone());
        }
        self.reset();
        // (The real modes padded to whole lanes of four: inert, zero state.)
        Ok((
            head,
            Modes::of(&self.re_phi, &self.cx_phi),
            States { xr, xc },
        ))
    }
}

/// `v`, or zero when it is below the normal range (`|v| < 2.2e-308`): a subnormal operand makes
/// every multiplication with it a micro-coded assist, tens of times slower, and the output
/// changes by less than `1e-307`.
#[inline(always)]
fn flushed(v: f64) -> f64 {
    if v.abs() < f64::MIN_POSITIVE {
        0.0
    } else {
        v
    }
}

/// The powers `phi^0 .. phi^(W-1)` of each mode and `phi^W` (flushed, see [`flushed`]).
struct Modes {
    real: Vec<[f64; W]>,
    real_step: Vec<f64>,
    cx_re: Vec<[f64; W]>,
    cx_im: Vec<[f64; W]>,
    cx_step: Vec<Cx<f64>>,
}

impl Modes {
    fn of(re_phi: &[f64], cx_phi: &[Cx<f64>]) -> Self {
        let mut m = Self {
            real: Vec::with_capacity(re_phi.len()),
            real_step: Vec::with_capacity(re_phi.len()),
            cx_re: Vec::with_capacity(cx_phi.len()),
            cx_im: Vec::with_capacity(cx_phi.len()),
            cx_step: Vec::with_capacity(cx_phi.len()),
        };
        for &phi in re_phi {
            let mut p = [1.0; W];
            for i in 1..W {
                p[i] = flushed(p[i - 1] * phi);
            }
            m.real_step.push(flushed(p[W - 1] * phi));
            m.real.push(p);
        }
        for &phi in cx_phi {
            let mut p = Cx::real(1.0);
            let (mut re, mut im) = ([0.0; W], [0.0; W]);
            for i in 0..W {
                (re[i], im[i]) = (p.re, p.im);
                p = p * phi;
                p = Cx {
                    re: flushed(p.re),
                    im: flushed(p.im),
                };
            }
            m.cx_re.push(re);
            m.cx_im.push(im);
            m.cx_step.push(p);
        }
        m
    }
}

/// The states of each response: real modes (in whole lanes of four), complex modes.
struct States {
    xr: Vec<Vec<f64>>,
    xc: Vec<Vec<Cx<f64>>>,
}

/// Samples `range` of each response into `outs` (`outs[j][k - skip]`, for `k >= skip`), from the
/// states at `range.start`, compiled for a set by [`Simd::vectorize`]: plain Rust that the
/// compiler vectorises for the set's width, its products fused where the set fuses them.
struct Tail<'a, 'b> {
    modes: &'a Modes,
    states: &'a mut States,
    range: std::ops::Range<usize>,
    skip: usize,
    outs: &'a mut [&'b mut [f64]],
}

impl WithSimd for Tail<'_, '_> {
    type Output = ();
    #[inline(always)]
    fn with_simd<S: Simd>(self, _: S) {
        let Self {
            modes,
            states,
            range,
            skip,
            outs,
        } = self;
        let fma = |a: f64, b: f64, c: f64| if S::FUSED { a.mul_add(b, c) } else { a * b + c };
        let mut k = range.start;
        while k < range.end {
            let w = (range.end - k).min(W);
            if k + w > skip {
                for (j, out) in outs.iter_mut().enumerate() {
                    // Four sums, a mode to each in turn (the real modes come in whole lanes of
                    // four): the additions of one do not wait for the others'.
                    let (mut s0, mut s1, mut s2, mut s3) = ([0.0; W], [0.0; W], [0.0; W], [0.0; W]);
                    for (p, x) in modes.real.chunks_exact(4).zip(states.xr[j].chunks_exact(4)) {
                        for i in 0..W {
                            s0[i] = fma(x[0], p[0][i], s0[i]);
                            s1[i] = fma(x[1], p[1][i], s1[i]);
                            s2[i] = fma(x[2], p[2][i], s2[i]);
                            s3[i] = fma(x[3], p[3][i], s3[i]);
                        }
                    }
                    for ((pr, pi), x) in modes.cx_re.iter().zip(&modes.cx_im).zip(&states.xc[j]) {
                        for i in 0..W {
                            s0[i] = fma(x.re, pr[i], s0[i]);
                            s1[i] = fma(-x.im, pi[i], s1[i]);
                        }
                    }
                    let mut acc = [0.0; W];
                    for i in 0..W {
                        acc[i] = (s0[i] + s1[i]) + (s2[i] + s3[i]);
                    }
                    if k >= skip && w == W {
                        out[k - skip..k - skip + W].copy_from_slice(&acc);
                    } else {
                        for (i, &v) in acc.iter().enumerate().take(w) {
                            if k + i >= skip {
                                out[k + i - skip] = v;
                            }
                        }
                    }
                }
            }
            for (xr, xc) in states.xr.iter_mut().zip(&mut states.xc) {
                for (x, s) in xr.iter_mut().zip(&modes.real_step) {
                    *x = flushed(*x * s);
                }
                for (x, &s) in xc.iter_mut().zip(&modes.cx_step) {
                    let v = *x * s;
                    *x = Cx {
                        re: flushed(v.re),
                        im: flushed(v.im),
                    };
                }
            }
            k += W;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ApproxSpec, FracTf};

    /// A way to fill the outputs.
    type Run<'a> = dyn Fn(&mut Simulator<f64>, &mut [&mut [f64]]) + 'a;

    /// Each response against its own simulation (`set_past_input`, then `run_into` on zeros):
    /// models with real and complex modes, with a whole and a fractional delay, with a
    /// feed-through; `skip` before, inside and after the delayed head; lengths that are not a
    /// multiple of the block, and shorter than the head. In every instruction set the CPU runs,
    /// the portable one included. 1e-12 of the largest output: the two round differently (a
    /// power table against one step at a time), both to a few ulps per thousand samples.
    #[test]
    fn free_responses_equal_their_simulations() {
        let models = [
            "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)",
            "2/(0.001 s^2 + 0.01 s + 1)",
            "(0.5 s^0.5 + 1)/(0.2 s^0.9 + 1)",
        ];
        let edges = [0.003, 0.02, 0.2];
        let sets = vec![
            vec![1.0, 0.0, 0.0, 0.0],
            vec![0.0, 1.0, 0.0, 0.0],
            vec![0.0, 0.0, 0.0, 1.0],
            vec![0.3, -1.0, 2.0, 0.5],
        ];
        let dt = 5e-4;
        for src in models {
            for delay in [0.0, 3.0 * dt, 2.4 * dt] {
                let mut g: FracTf = src.parse().unwrap();
                g.delay = delay;
                let mut sim = Simulator::<f64>::new(&g, dt, &ApproxSpec::default()).unwrap();
                for (skip, len) in [(0, 1001), (2, 37), (7, 1), (40, 2000), (0, 2)] {
                    let n = skip + len;
                    let want: Vec<Vec<f64>> = sets
                        .iter()
                        .map(|s| {
                            sim.set_past_input(s, &edges).unwrap();
                            let mut y = vec![0.0; n];
                            sim.run_into(&vec![0.0; n], &mut y);
                            y[skip..].to_vec()
                        })
                        .collect();
                    let scale = want
                        .iter()
                        .flatten()
                        .fold(1e-300, |m: f64, v| m.max(v.abs()));
                    let mut check = |label: &str, run: &Run<'_>| {
                        let mut got = vec![vec![f64::NAN; len]; sets.len()];
                        let mut outs: Vec<&mut [f64]> =
                            got.iter_mut().map(|v| v.as_mut_slice()).collect();
                        run(&mut sim, &mut outs);
                        for (j, (g, w)) in got.iter().zip(&want).enumerate() {
                            for (k, (a, b)) in g.iter().zip(w).enumerate() {
                                assert!(
                                    (a - b).abs() <= 1e-12 * scale,
                                    "{src} delay {delay} skip {skip} len {len} {label}: set {j} \
                                     sample {k}: {a} vs {b}"
                                );
                            }
                        }
                        // Left at rest.
                        assert!(sim.re_x.iter().all(|&x| x == 0.0));
                    };
                    check("kernel", &|s, o| {
                        s.free_responses(&sets, &edges, skip, o).unwrap()
                    });
                    for isa in Isa::available() {
                        check(isa.name(), &|s, o| {
                            s.free_responses_with(isa, &sets, &edges, skip, o).unwrap()
                        });
                    }
                }
            }
        }
    }

    #[test]
    fn mismatched_outputs_are_refused() {
        let g: FracTf = "1/(0.1 s + 1)".parse().unwrap();
        let mut sim = Simulator::<f64>::new(&g, 1e-3, &ApproxSpec::default()).unwrap();
        let (mut a, mut b) = (vec![0.0; 5], vec![0.0; 4]);
        let sets = vec![vec![1.0, 0.0], vec![0.0, 1.0]];
        assert!(sim
            .free_responses(&sets, &[0.01], 0, &mut [&mut a, &mut b])
            .is_err());
        assert!(sim
            .free_responses(&sets, &[0.01], 0, &mut [&mut a])
            .is_err());
        // A bad edge list is set_past_input's error.
        let mut c = vec![0.0; 5];
        assert!(sim
            .free_responses(&sets, &[-1.0], 0, &mut [&mut a, &mut c])
            .is_err());
    }
}
