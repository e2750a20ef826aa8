//! The exact start of a fit whose free parameters are all record parameters: the output offset
//! and the initial state's past-input levels, the plant held (what `fracid score --as-fitted`
//! and the diagnosis's final polish estimate). The output is then affine in them,
//! `yhat = y0 + S w` ([`crate::oe::LinearRole`]), and the least-squares estimate within their
//! ranges is a box-constrained linear least-squares problem, convex: solved here from one
//! simulation of the columns `S`. The fit then starts at that minimum (it stops at once, with
//! its covariance and report); from the given values it took tens of iterations on a long
//! record and could stop short with a level at the wrong edge of its range (the
//! motor/generator record: held-out RMSE 511.78 where the minimum gives 505.04).

use crate::oe::{Bounds, FracModel, LinearRole, Structure};

/// Set the free parameters of `m` to the box-constrained least-squares estimate on `u`, `y`
/// (the estimation part, operating point removed) with the first `skip` samples left out, when
/// every free parameter is an output offset or an initial-state level and no effect acts on the
/// input (the output then affine in them); each value kept strictly inside its range. Returns
/// whether it applied; otherwise (or when the columns are numerically dependent or a
/// simulation fails) `m` is unchanged.
pub(super) fn exact_start(m: &mut FracModel, u: &[f64], y: &[f64], dt: f64, skip: usize) -> bool {
    let free: Vec<usize> = (0..m.params.len()).filter(|&j| m.params[j].free).collect();
    let record_param = |j: usize| {
        matches!(
            m.linear_role(j),
            Some(LinearRole::Offset | LinearRole::Level)
        )
    };
    let n = y.len();
    if free.is_empty()
        || m.integrator
        || skip >= n
        || m.effects.iter().any(|e| e.is_input())
        || !free.iter().all(|&j| record_param(j))
    {
        return false;
    }
    let mut p0 = m.values();
    for &j in &free {
        p0[j] = 0.0;
    }
    // The output with the record parameters at 0, and their columns after `skip`.
    let mut base = vec![0.0; n];
    let mut cols = vec![vec![0.0; n - skip]; free.len()];
    {
        let mut out: Vec<&mut [f64]> = cols.iter_mut().map(|c| c.as_mut_slice()).collect();
        if m.simulate_with_linear(&p0, &free, u, dt, &mut base, skip, &mut out)
            .is_err()
        {
            return false;
        }
    }
    let r: Vec<f64> = (skip..n).map(|k| y[k] - base[k]).collect();
    let bounds: Vec<Bounds> = free.iter().map(|&j| m.params[j].bounds).collect();
    let Some(w) = box_least_squares(&cols, &r, &bounds) else {
        return false;
    };
    for (&j, &v) in free.iter().zip(&w) {
        m.params[j].value = m.params[j].bounds.clamp_inside(v);
    }
    true
}

/// The minimiser of `|r - sum_j w_j cols[j]|^2` over the box `bounds` (a convex problem): among
/// the unconstrained solutions of every choice of the bounded variables held at one of their
/// edges (the others free), the one inside the box with the smallest sum of squares; the
/// minimiser is one of them (its free variables solve their normal equations). `None` when no
/// normal matrix can be factored (columns numerically dependent). The columns are scaled to unit
/// norm before the Gram matrix is formed.
fn box_least_squares(cols: &[Vec<f64>], r: &[f64], bounds: &[Bounds]) -> Option<Vec<f64>> {
    let c = cols.len();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let norms: Vec<f64> = cols.iter().map(|v| dot(v, v).sqrt()).collect();
    if norms.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return None;
    }
    let mut g = vec![0.0; c * c];
    for i in 0..c {
        for j in 0..=i {
            let v = dot(&cols[i], &cols[j]) / (norms[i] * norms[j]);
            g[i * c + j] = v;
            g[j * c + i] = v;
        }
    }
    let b: Vec<f64> = (0..c).map(|i| dot(&cols[i], r) / norms[i]).collect();
    let rr = dot(r, r);
    // Each variable's choices: free, or held at a finite edge (scaled: w_j norms[j]).
    let edges: Vec<Vec<Option<f64>>> = bounds
        .iter()
        .zip(&norms)
        .map(|(bd, &s)| match *bd {
            Bounds::Free => vec![None],
            Bounds::Positive => vec![None, Some(0.0)],
            Bounds::Interval(lo, hi) => vec![None, Some(lo * s), Some(hi * s)],
        })
        .collect();
    let inside = |j: usize, v: f64| match bounds[j] {
        Bounds::Free => true,
        Bounds::Positive => v >= 0.0,
        Bounds::Interval(lo, hi) => v >= lo && v <= hi,
    };
    let combos: usize = edges.iter().map(Vec::len).product();
    let mut best: Option<(f64, Vec<f64>)> = None;
    let mut factored = false;
    for mut code in 0..combos {
        let mut x = vec![0.0; c];
        let mut held = vec![false; c];
        for j in 0..c {
            let k = code % edges[j].len();
            code /= edges[j].len();
            if let Some(v) = edges[j][k] {
                x[j] = v;
                held[j] = true;
            }
        }
        let fr: Vec<usize> = (0..c).filter(|&j| !held[j]).collect();
        if !fr.is_empty() {
            let f = fr.len();
            let a = crate::lm::Mat::<f64>::from_fn(f, f, |i, k| g[fr[i] * c + fr[k]]);
            let rhs: Vec<f64> = (0..f)
                .map(|i| {
                    b[fr[i]]
                        - (0..c)
                            .filter(|&k| held[k])
                            .map(|k| g[fr[i] * c + k] * x[k])
                            .sum::<f64>()
                })
                .collect();
            let Some(sol) = crate::linalg::cholesky_solve(&a, &rhs) else {
                continue;
            };
            factored = true;
            for (i, &j) in fr.iter().enumerate() {
                x[j] = sol[i];
            }
        }
        let w: Vec<f64> = (0..c).map(|j| x[j] / norms[j]).collect();
        if !(0..c).all(|j| w[j].is_finite() && inside(j, w[j])) {
            continue;
        }
        // |r - S x|^2 = r.r - 2 b.x + x' G x (scaled columns).
        let gx: f64 = (0..c)
            .map(|i| x[i] * (0..c).map(|k| g[i * c + k] * x[k]).sum::<f64>())
            .sum();
        let ssr = rr - 2.0 * dot(&b, &x) + gx;
        if best.as_ref().is_none_or(|(s, _)| ssr < *s) {
            best = Some((ssr, w));
        }
    }
    factored.then_some(())?;
    best.map(|(_, w)| w)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PMSM with a 3-edge past input and an output offset, the plant held, on a record
    /// simulated at known record parameters (noise free): the exact start recovers them (1e-8:
    /// a well-conditioned 5-column least squares); with the range (-0.5, 5) the level -1.1 is
    /// outside and the estimate ends at its edge (within the 1e-6-of-the-range margin
    /// `clamp_inside` keeps) with a sum of squares no feasible point nearby
    /// beats (coordinate steps of 1e-3 and 1e-2, and the true values clamped into the box); with
    /// the gain free as well it does not apply (the output is then bilinear).
    #[test]
    fn the_exact_start_is_the_held_plant_minimum() {
        let (n, dt) = (3000, 2e-4);
        let u: Vec<f64> = (0..n)
            .map(|k| if (k / 37) % 3 == 0 { 1.0 } else { -0.5 })
            .collect();
        let truth = [0.7, -1.1, 0.4, 0.2, 0.3];
        let model = |range: (f64, f64)| {
            let mut m = FracModel::pmsm(6.8, 0.006, 2.7e-5, 0.9, 0.8);
            m.with_past_input(vec![0.01, 0.1, 0.5], range);
            m.with_output_offset(0.0);
            for p in &mut m.params {
                p.free = false;
            }
            let rec: Vec<usize> = m.past.clone().unwrap().levels;
            let rec: Vec<usize> = rec.into_iter().chain(m.index_of("y_offset")).collect();
            for &j in &rec {
                m.params[j].free = true;
            }
            (m, rec)
        };
        let (m, rec) = model((-5.0, 5.0));
        let mut p = m.values();
        for (&j, &v) in rec.iter().zip(&truth) {
            p[j] = v;
        }
        let mut y = vec![0.0; n];
        m.simulate(&p, &u, dt, &mut y).unwrap();
        let ssr = |m: &FracModel, p: &[f64]| -> f64 {
            let mut yh = vec![0.0; n];
            m.simulate(p, &u, dt, &mut yh).unwrap();
            y.iter().zip(&yh).map(|(a, b)| (a - b).powi(2)).sum()
        };
        let mut free_m = m.clone();
        assert!(exact_start(&mut free_m, &u, &y, dt, 0));
        for (&j, &v) in rec.iter().zip(&truth) {
            assert!(
                (free_m.params[j].value - v).abs() < 1e-8,
                "{j}: {}",
                free_m.params[j].value
            );
        }
        let (mut boxed, _) = model((-0.5, 5.0));
        assert!(exact_start(&mut boxed, &u, &y, dt, 0));
        let at = boxed.values();
        assert!((at[rec[1]] + 0.5).abs() < 1e-5, "{:?}", at);
        let best = ssr(&boxed, &at);
        let mut clamped = at.clone();
        for (&j, &v) in rec.iter().zip(&truth) {
            clamped[j] = boxed.params[j].bounds.clamp_inside(v);
        }
        assert!(ssr(&boxed, &clamped) > best);
        for &j in &rec {
            for step in [-1e-2, -1e-3, 1e-3, 1e-2] {
                let mut q = at.clone();
                q[j] += step;
                if q[j] < -0.5 || q[j] > 5.0 {
                    continue;
                }
                assert!(ssr(&boxed, &q) >= best * (1.0 - 1e-12), "{j} {step}");
            }
        }
        let mut gain_free = m.clone();
        gain_free.params[0].free = true;
        assert!(!exact_start(&mut gain_free, &u, &y, dt, 0));
    }

    /// The box least squares against a brute-force grid: `r = 2 a + 0.5 b - 3 c` plus a small
    /// perturbation, `w_c` bounded to `[-1, 1]` (the unconstrained `-3` outside), the others
    /// free or positive; the exact minimiser has `w_c = -1` and beats every point of a fine grid
    /// around it (to 1e-12 relative), and the unconstrained case returns the generating values
    /// (1e-10).
    #[test]
    fn the_box_least_squares_is_the_constrained_minimum() {
        let n = 200;
        let a: Vec<f64> = (0..n).map(|k| (k as f64 * 0.1).sin()).collect();
        let b: Vec<f64> = (0..n).map(|k| 1.0 + (k as f64 * 0.037).cos()).collect();
        let c: Vec<f64> = (0..n).map(|k| (k as f64 / n as f64).powi(2)).collect();
        let r: Vec<f64> = (0..n)
            .map(|k| 2.0 * a[k] + 0.5 * b[k] - 3.0 * c[k])
            .collect();
        let cols = vec![a.clone(), b.clone(), c.clone()];
        let free = [Bounds::Free, Bounds::Positive, Bounds::Free];
        let w = box_least_squares(&cols, &r, &free).unwrap();
        for (got, want) in w.iter().zip([2.0, 0.5, -3.0]) {
            assert!((got - want).abs() < 1e-10, "{w:?}");
        }
        let boxed = [Bounds::Free, Bounds::Positive, Bounds::Interval(-1.0, 1.0)];
        let w = box_least_squares(&cols, &r, &boxed).unwrap();
        assert!((w[2] + 1.0).abs() < 1e-12, "{w:?}");
        let ssr = |w: &[f64]| -> f64 {
            (0..n)
                .map(|k| (r[k] - w[0] * a[k] - w[1] * b[k] - w[2] * c[k]).powi(2))
                .sum()
        };
        let best = ssr(&w);
        for i in -5..=5 {
            for j in -5..=5 {
                for l in 0..=5 {
                    let v = [
                        w[0] + 0.01 * i as f64,
                        (w[1] + 0.01 * j as f64).max(0.0),
                        (w[2] + 0.01 * l as f64).min(1.0),
                    ];
                    assert!(ssr(&v) >= best * (1.0 - 1e-12), "{v:?} beats {w:?}");
                }
            }
        }
    }
}
