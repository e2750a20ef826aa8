//! The windows of the initial state's past input, chosen by what the record determines
//! (docs/design.md §5).
//!
//! The state at the first sample is the state a past held input left ([`super::PastInput`]). A
//! fixed set of windows (levels on `[-T/64, 0)`, `[-T/8, -T/64)`, `[-T, -T/8)` and before) is
//! ill-conditioned: the free responses of the older windows are slow tails, nearly collinear with
//! each other and with the output offset (correlations 0.85-0.99 on real records), so the older
//! levels trade off against each other, run to the edges of their range and drag the plant's
//! parameters with them. Here the past starts as one level held since `-inf` (the equilibrium of a
//! plant that rested at another input: determined whenever the step response is not flat over the
//! record) and a window edge is added only while the data pay for it:
//!
//! - at a fitted model the output is linear in the levels, so the sum of squares of each
//!   finer partition is a linear least-squares solve in the windows' free responses (with the
//!   gain's and the output offset's columns, the model's other parameters held);
//! - an edge is kept when the Bayesian information criterion counted in independent residuals
//!   falls, `N_eff ln(SSR_new / SSR) + ln N_eff < 0`, with `N_eff = N (1 - rho)/(1 + rho)` from
//!   the residual's lag-one autocorrelation `rho` (Bartlett's effective sample size: the residual
//!   of a model with a structural error is strongly correlated, and a white-noise BIC would count
//!   its correlated samples as independent evidence);
//! - and when every level stays determined: within its range (the input's, widened by twice its
//!   span, [`super::past_range`]) by two standard errors (the regression's, inflated by
//!   `sqrt(N / N_eff)`).
//!
//! The edges are added greedily (the one that lowers the sum of squares most first) from the
//! candidates [`super::past_edges`]. In a fit ([`refine`]) each candidate is judged by a refit of
//! the whole model, not by the linear screen at the coarser fit (whose plant parameters have
//! bent to the coarser past), and kept only when its levels end determined (none at an edge of
//! its range, every standard error finite); the diagnosis's screen of a record fitted from rest
//! ([`choose`]) uses the linear screen alone, its refit and held-out test deciding after.

use super::fit::{FitOptions, FitReport};
use super::{FracModel, LinearRole, Structure};
use crate::lm::dot;
use crate::{Error, Result};

/// The past input's windows chosen for a record ([`choose`]).
#[derive(Debug, Clone, PartialEq)]
pub struct PastChoice {
    /// Window edges in seconds before the first sample, increasing (empty: one level held since
    /// `-inf`).
    pub edges: Vec<f64>,
    /// Each window's level (newest first, `edges.len() + 1` of them): the linear solution at the
    /// model's other parameters.
    pub levels: Vec<f64>,
    /// The number of independent residuals the criterion counted (`N_eff`).
    pub n_eff: f64,
}

/// The past's windows the record determines, at the model `m` with values `p` on the input and
/// output deviations `u`, `y` (the residuals from sample `skip` on), the edges taken from
/// `candidates` (seconds, increasing), the levels kept within `range`, by the linear screen alone
/// (module documentation; the model's other parameters held). `m` has no past (the record was
/// fitted from rest: the levels start at 0) or a past whose edges are among `candidates` (the
/// windows it has are kept, each level where it is).
///
/// # Errors
/// [`Error::Options`] for a model whose past has an edge that is not a candidate; the
/// simulation's errors.
#[allow(clippy::too_many_arguments)]
pub fn choose(
    m: &FracModel,
    p: &[f64],
    u: &[f64],
    y: &[f64],
    dt: f64,
    skip: usize,
    candidates: &[f64],
    range: (f64, f64),
) -> Result<PastChoice> {
    let Some(screen) = Screen::new(m, p, u, y, dt, skip, candidates, range)? else {
        return Ok(current(m, p));
    };
    let mut chosen = screen.chosen.clone();
    let Some((mut ssr, mut levels)) = screen.solve(&chosen) else {
        return Ok(current(m, p));
    };
    let n_eff = screen.n_eff;
    while n_eff >= 3.0 && chosen.len() < candidates.len() {
        let Some((c, s, l)) = screen.best_next(&chosen) else {
            break;
        };
        if !(s > 0.0 && pays(n_eff, ssr, s)) {
            break;
        }
        (chosen, ssr, levels) = (c, s, l);
    }
    Ok(PastChoice {
        edges: chosen.iter().map(|&e| candidates[e]).collect(),
        levels,
        n_eff,
    })
}

/// The initial state's past of `m` set up for a fit that estimates it on a record whose levels
/// are kept within `range` ([`super::past_range`]): a model without a past starts with one level
/// held since before the record (returns `true`: its finer windows are then chosen by
/// [`refine`] after the fit); a model that comes with a past (a saved report's, a fit's to be
/// rescored) keeps its windows, the levels restarting at 0 within `range` (returns `false`).
/// Every fit that estimates a record's initial state starts here: [`super::identify`],
/// [`super::score`], [`super::identify_joint`].
///
/// # Errors
/// None in practice ([`FracModel::with_past_windows`] with one value per window).
pub fn prepare(m: &mut FracModel, range: (f64, f64)) -> Result<bool> {
    let edges = m.past.as_ref().map(|p| p.edges.clone());
    let chosen = edges.is_none();
    let edges = edges.unwrap_or_default();
    let zeros = vec![0.0; edges.len() + 1];
    m.with_past_windows(edges, &zeros, range)?;
    Ok(chosen)
}

/// Whether a sum of squares `ssr_new` with one parameter more than `ssr` lowers the Bayesian
/// information criterion counted in `n_eff` independent residuals.
fn pays(n_eff: f64, ssr: f64, ssr_new: f64) -> bool {
    n_eff * (ssr_new / ssr).ln() + n_eff.ln() < 0.0
}

/// The past `m` has, as a choice (its values at `p`); one level at 0 when it has none.
fn current(m: &FracModel, p: &[f64]) -> PastChoice {
    match &m.past {
        None => PastChoice {
            edges: vec![],
            levels: vec![0.0],
            n_eff: 0.0,
        },
        Some(past) => PastChoice {
            edges: past.edges.clone(),
            levels: past.levels.iter().map(|&i| p[i]).collect(),
            n_eff: 0.0,
        },
    }
}

/// The linear screen of finer windows at a fitted model: the finest windows' free responses, the
/// other linear parameters' columns, the residual and its effective number of samples.
struct Screen {
    /// Free responses of the finest windows (unit level each), newest first.
    windows: Vec<Vec<f64>>,
    /// The gain's and the output offset's columns.
    extra: Vec<Vec<f64>>,
    r: Vec<f64>,
    /// Each finest window's current level.
    at: Vec<f64>,
    /// The candidate edges the model's past has (indices, increasing).
    chosen: Vec<usize>,
    n_eff: f64,
    range: (f64, f64),
}

impl Screen {
    /// `None` when there is nothing to screen (too few samples, no candidate, a zero or
    /// non-finite residual or free response).
    #[allow(clippy::too_many_arguments)]
    fn new(
        m: &FracModel,
        p: &[f64],
        u: &[f64],
        y: &[f64],
        dt: f64,
        skip: usize,
        candidates: &[f64],
        range: (f64, f64),
    ) -> Result<Option<Self>> {
        let nw = candidates.len() + 1;
        let (chosen, at) = match &m.past {
            None => (vec![], vec![0.0; nw]),
            Some(past) => {
                let chosen: Vec<usize> = past
                    .edges
                    .iter()
                    .map(|e| candidates.iter().position(|c| c == e))
                    .collect::<Option<_>>()
                    .ok_or_else(|| {
                        Error::Options("the past's edges are not among the candidates".into())
                    })?;
                let groups = groups_of(&chosen, nw);
                let mut at = vec![0.0; nw];
                for (g, &i) in groups.iter().zip(&past.levels) {
                    g.iter().for_each(|&w| at[w] = p[i]);
                }
                (chosen, at)
            }
        };
        let n = u.len().min(y.len());
        let rows = n.saturating_sub(skip);
        if rows < 4 || candidates.is_empty() {
            return Ok(None);
        }
        let mut yhat = vec![0.0; n];
        m.simulate(p, &u[..n], dt, &mut yhat)?;
        let r: Vec<f64> = y[skip..n]
            .iter()
            .zip(&yhat[skip..])
            .map(|(a, b)| a - b)
            .collect();
        let units: Vec<Vec<f64>> = (0..nw)
            .map(|i| (0..nw).map(|j| f64::from(u8::from(i == j))).collect())
            .collect();
        let mut windows = vec![vec![0.0; rows]; nw];
        {
            let mut outs: Vec<&mut [f64]> = windows.iter_mut().map(|c| c.as_mut_slice()).collect();
            m.simulator::<f64>(p, dt)?
                .free_responses(&units, candidates, skip, &mut outs)?;
        }
        let which: Vec<usize> = (0..m.params.len())
            .filter(|&j| {
                m.params[j].free
                    && matches!(
                        m.linear_role(j),
                        Some(LinearRole::Gain) | Some(LinearRole::Offset)
                    )
            })
            .collect();
        let mut extra = vec![vec![0.0; rows]; which.len()];
        if !which.is_empty() {
            let mut outs: Vec<&mut [f64]> = extra.iter_mut().map(|c| c.as_mut_slice()).collect();
            m.linear_sensitivities(p, &which, &u[..n], dt, &yhat, skip, &mut outs)?;
        }
        let rr = dot(&r, &r);
        if !(rr > 0.0 && rr.is_finite()) || windows.iter().flatten().any(|v| !v.is_finite()) {
            return Ok(None);
        }
        let rho = (r.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / rr).clamp(0.0, 1.0);
        let n_eff = (rows as f64 * (1.0 - rho) / (1.0 + rho)).clamp(1.0, rows as f64);
        Ok(Some(Self {
            windows,
            extra,
            r,
            at,
            chosen,
            n_eff,
            range,
        }))
    }

    /// The sum of squares of the windows `chosen` (edge indices, increasing) and their levels
    /// (the current ones plus the linear solution's steps); `None` when a level is not determined
    /// (two standard errors, inflated by `sqrt(N / N_eff)`, reach outside the range) or the
    /// columns are singular.
    fn solve(&self, chosen: &[usize]) -> Option<(f64, Vec<f64>)> {
        let rows = self.r.len();
        let groups = groups_of(chosen, self.windows.len());
        let mut cols: Vec<Vec<f64>> = groups
            .iter()
            .map(|g| {
                let mut c = vec![0.0; rows];
                for &w in g {
                    c.iter_mut()
                        .zip(&self.windows[w])
                        .for_each(|(a, b)| *a += b);
                }
                c
            })
            .collect();
        cols.extend(self.extra.iter().cloned());
        let (x, ssr, var) = least_squares(&cols, &self.r)?;
        let dof = rows.checked_sub(cols.len()).filter(|&d| d > 0)? as f64;
        let sigma2 = ssr / dof * rows as f64 / self.n_eff;
        let levels: Vec<f64> = groups
            .iter()
            .enumerate()
            .map(|(g, w)| self.at[w[0]] + x[g])
            .collect();
        let (lo, hi) = self.range;
        let determined = levels.iter().enumerate().all(|(g, &w)| {
            let se = (sigma2 * var[g]).sqrt();
            se.is_finite() && w - 2.0 * se > lo && w + 2.0 * se < hi
        });
        determined.then_some((ssr, levels))
    }

    /// The current levels of the windows `chosen` (a window split keeps its level on both sides).
    fn current_levels(&self, chosen: &[usize]) -> Vec<f64> {
        groups_of(chosen, self.windows.len())
            .iter()
            .map(|g| self.at[g[0]])
            .collect()
    }

    /// The window edge not in `chosen` whose addition lowers the sum of squares most with every
    /// level determined: the edges with it, the sum of squares and the levels.
    fn best_next(&self, chosen: &[usize]) -> Option<(Vec<usize>, f64, Vec<f64>)> {
        let mut best: Option<(Vec<usize>, f64, Vec<f64>)> = None;
        for e in (0..self.windows.len() - 1).filter(|e| !chosen.contains(e)) {
            let mut c = chosen.to_vec();
            c.push(e);
            c.sort_unstable();
            if let Some((s, l)) = self.solve(&c) {
                if best.as_ref().is_none_or(|b| s < b.1) {
                    best = Some((c, s, l));
                }
            }
        }
        best
    }
}

/// The finest windows `0..nw` (newest first) grouped by the chosen edges (indices of the edges
/// between window `e` and `e + 1`, increasing).
fn groups_of(chosen: &[usize], nw: usize) -> Vec<Vec<usize>> {
    let mut groups = vec![];
    let mut start = 0;
    for &e in chosen {
        groups.push((start..=e).collect());
        start = e + 1;
    }
    groups.push((start..nw).collect());
    groups
}

/// Least squares `min |b - A x|` for the columns `cols` of `A` (normal equations of the columns
/// scaled to unit norm, Cholesky): `x`, the sum of squares, and the diagonal of `(A^T A)^-1`;
/// `None` when a column is zero or (numerically) in the span of the others.
fn least_squares(cols: &[Vec<f64>], b: &[f64]) -> Option<(Vec<f64>, f64, Vec<f64>)> {
    let c = cols.len();
    let norms: Vec<f64> = cols.iter().map(|a| dot(a, a).sqrt()).collect();
    if norms.iter().any(|&s| !(s > 0.0 && s.is_finite())) {
        return None;
    }
    // G = D A^T A D with D = diag(1/norms); its Cholesky factor L (lower, row-major).
    let mut l = vec![0.0; c * c];
    for i in 0..c {
        for j in 0..=i {
            let g = dot(&cols[i], &cols[j]) / (norms[i] * norms[j]);
            let s = g - (0..j).map(|k| l[i * c + k] * l[j * c + k]).sum::<f64>();
            if i == j {
                if !(s > 1e-13) {
                    return None;
                }
                l[i * c + i] = s.sqrt();
            } else {
                l[i * c + j] = s / l[j * c + j];
            }
        }
    }
    let solve = |rhs: &[f64]| -> Vec<f64> {
        let mut z = rhs.to_vec();
        for i in 0..c {
            z[i] = (z[i] - (0..i).map(|k| l[i * c + k] * z[k]).sum::<f64>()) / l[i * c + i];
        }
        for i in (0..c).rev() {
            z[i] = (z[i] - (i + 1..c).map(|k| l[k * c + i] * z[k]).sum::<f64>()) / l[i * c + i];
        }
        z
    };
    let atb: Vec<f64> = cols
        .iter()
        .zip(&norms)
        .map(|(a, s)| dot(a, b) / s)
        .collect();
    let xs = solve(&atb);
    let x: Vec<f64> = xs.iter().zip(&norms).map(|(v, s)| v / s).collect();
    let mut res = b.to_vec();
    for (a, &xi) in cols.iter().zip(&x) {
        res.iter_mut().zip(a).for_each(|(r, v)| *r -= xi * v);
    }
    let var: Vec<f64> = (0..c)
        .map(|i| {
            let mut e = vec![0.0; c];
            e[i] = 1.0;
            solve(&e)[i] / (norms[i] * norms[i])
        })
        .collect();
    Some((x, dot(&res, &res), var))
}

/// After a fit of `m` with a past of one level (`report`), finer windows while they pay: each
/// edge not yet chosen is tried by a refit of the whole model (`fit`; each window starting at the
/// linear screen's level, [`Screen::solve`]), and the best refit is kept when its sum of squares
/// lowers the criterion counted in independent residuals ([`pays`]) and its levels end
/// determined (none at an edge of the range, every standard error finite). A refit and not the
/// screen decides: a fit with too coarse a past has bent the plant's parameters to what the past
/// left, which a screen at those parameters does not see. At most `c + (c - 1) + ...` refits for
/// `c` candidate edges (6 for the three of [`super::past_edges`]), each from a fit's optimum; `m`
/// and the report returned are the fit kept.
///
/// # Errors
/// Those of [`choose`]'s screen (a refit that fails keeps the fit before it).
#[allow(clippy::too_many_arguments)]
pub(super) fn refine(
    m: &mut FracModel,
    mut report: FitReport,
    u: &[f64],
    y: &[f64],
    dt: f64,
    opts: &FitOptions,
    candidates: &[f64],
    range: (f64, f64),
    fit: &mut dyn FnMut(&FracModel) -> Result<FitReport>,
) -> Result<FitReport> {
    loop {
        let Some(screen) = Screen::new(m, &report.values, u, y, dt, opts.skip, candidates, range)?
        else {
            return Ok(report);
        };
        if screen.n_eff < 3.0 {
            return Ok(report);
        }
        // Each edge not yet chosen, refitted (the screen's level as the start); the best that
        // pays is kept.
        let mut best: Option<(FracModel, FitReport)> = None;
        for e in (0..candidates.len()).filter(|e| !screen.chosen.contains(e)) {
            let mut chosen = screen.chosen.clone();
            chosen.push(e);
            chosen.sort_unstable();
            let levels = screen
                .solve(&chosen)
                .map_or_else(|| screen.current_levels(&chosen), |(_, l)| l);
            let mut finer = m.clone();
            for (q, v) in finer.params.iter_mut().zip(&report.values) {
                q.value = *v;
            }
            let edges = chosen.iter().map(|&e| candidates[e]).collect();
            finer.with_past_windows(edges, &levels, range)?;
            let Ok(rep) = fit(&finer) else {
                continue;
            };
            let held = finer
                .past
                .as_ref()
                .map(|p| p.levels.clone())
                .unwrap_or_default();
            let determined = held.iter().all(|&i| {
                let e = &rep.params[i];
                !finer.params[i].bounds.at_edge(e.value) && e.std_error.is_some_and(f64::is_finite)
            });
            let ssr = |r: &FitReport| r.rmse * r.rmse;
            if determined
                && ssr(&rep) > 0.0
                && pays(screen.n_eff, ssr(&report), ssr(&rep))
                && best.as_ref().is_none_or(|(_, b)| rep.rmse < b.rmse)
            {
                best = Some((finer, rep));
            }
        }
        let Some((finer, rep)) = best else {
            return Ok(report);
        };
        *m = finer;
        report = rep;
    }
}
