//! Several records of one plant fitted jointly: one model, each record with its own operating
//! point, output offset and initial state (MATLAB's multi-experiment `iddata` with `oe`).

use super::fit::{fit_in, past_edges, IdentOptions, InitialState};
use super::{FracModel, Param, Structure};
use crate::data::{Offsets, Record};
use crate::metrics::Fit;
use crate::{Error, Result};
use fracsim::{FracTf, Real};

/// The records end to end as one [`Structure`]: the plant's parameters shared, the record's own
/// (`y_offset`, the initial-state levels) repeated per record.
struct Joint {
    /// Per record: the model with its operating point, and where its parameters live.
    parts: Vec<(FracModel, Vec<usize>)>,
    /// Per record: its samples `a..b` in the concatenation.
    ranges: Vec<(usize, usize)>,
    params: Vec<Param>,
}

impl Structure for Joint {
    fn params(&self) -> &[Param] {
        &self.params
    }

    fn simulate<T: Real>(&self, p: &[T], u: &[f64], dt: f64, y: &mut [T]) -> Result<()> {
        for ((m, map), &(a, b)) in self.parts.iter().zip(&self.ranges) {
            let ps: Vec<T> = map.iter().map(|&j| p[j]).collect();
            m.simulate(&ps, &u[a..b], dt, &mut y[a..b])?;
        }
        Ok(())
    }
}

/// The result of [`identify_joint`].
#[derive(Debug, Clone)]
pub struct JointIdentification {
    /// The model with the fitted values and the first record's own parameters.
    pub model: FracModel,
    /// The fitted linear part.
    pub tf: FracTf,
    /// The fit report over all records (parameters: the plant's, then each further record's own).
    pub report: super::FitReport,
    /// Per record: its operating point, its fit, its model output (absolute scale).
    pub records: Vec<(Offsets, Fit, Vec<f64>)>,
    /// Why the model cannot be used (empty when it can): the rules of a single record's fit
    /// ([`super::Identification::problems`]) on the model and the plant's parameters, judged by
    /// the record it fits worst.
    pub problems: Vec<String>,
}

/// Fit one model to several records of the same plant (same sampling step): the start is the
/// model [`super::identify`] fits to the first record; then every record is simulated from its own
/// initial state ([`InitialState`]) with its own output offset, and the plant's parameters are
/// fitted to all of them at once. Each record is used whole (validate on another record with
/// [`super::score`]).
///
/// # Errors
/// [`Error::Data`] for no record or different sampling steps; errors of [`super::identify`]'s
/// start and of the fit.
pub fn identify_joint(
    recs: &[Record],
    model: &FracModel,
    opts: &IdentOptions,
) -> Result<JointIdentification> {
    // From an empty pole cache, as [`super::identify`]: the joint fit goes on from the first
    // record's.
    fracsim::modal::RootsCache::afresh(|| identify_joint_afresh(recs, model, opts))
}

/// [`identify_joint`] in the pole cache it starts.
fn identify_joint_afresh(
    recs: &[Record],
    model: &FracModel,
    opts: &IdentOptions,
) -> Result<JointIdentification> {
    let Some(first) = recs.first() else {
        return Err(Error::Data("no record to fit".into()));
    };
    if let Some(r) = recs.iter().find(|r| (r.dt / first.dt - 1.0).abs() > 1e-6) {
        return Err(Error::Data(format!(
            "the records are sampled at different steps ({} s and {} s)",
            first.dt, r.dt
        )));
    }
    // One initial-state rule for all: `auto` is rest only when every record rests, else every
    // record gets its past input estimated (a record's own past levels would otherwise be
    // parameters that another record's rest leaves unused).
    let rests = |r: &Record| opts.initial.resolve(r, opts.offsets) == InitialState::Rest;
    let opts = &IdentOptions {
        initial: if opts.initial == InitialState::Auto && !recs.iter().all(rests) {
            InitialState::Estimate
        } else {
            opts.initial
        },
        ..opts.clone()
    };
    // The start: the model fitted to the first record alone, whole.
    let one = IdentOptions {
        holdout: 0.0,
        ..opts.clone()
    };
    let base = super::identify(first, model, &one)?.model;
    let (joint, u, y) = Joint::of(recs, &base, opts);
    let report = fit_in(&joint, &u, &y, first.dt, &opts.fit, &mut |_, _| {})?;
    let mut records = vec![];
    for ((m, map), &(a, b)) in joint.parts.iter().zip(&joint.ranges) {
        let ps: Vec<f64> = map.iter().map(|&j| report.values[j]).collect();
        let mut yd = vec![0.0; b - a];
        m.simulate(&ps, &u[a..b], first.dt, &mut yd)?;
        let op = m.operating_point;
        let yhat: Vec<f64> = yd.iter().map(|v| v + op.y0).collect();
        let ymeas: Vec<f64> = y[a..b].iter().map(|v| v + op.y0).collect();
        records.push((op, Fit::of(&ymeas, &yhat), yhat));
    }
    let (mut model, map0) = joint.parts[0].clone();
    for (p, &j) in model.params.iter_mut().zip(&map0) {
        p.value = report.values[j];
    }
    let tf = model.tf(&model.values())?;
    let problems = problems(&model, &tf, &report, &records, first);
    Ok(JointIdentification {
        model,
        tf,
        report,
        records,
        problems,
    })
}

impl Joint {
    /// The records `recs` end to end with the model `base` (fitted to the first), each with its
    /// operating point and, for [`InitialState::Estimate`], its past input: the structure and
    /// the deviations `u`, `y` end to end.
    fn of(recs: &[Record], base: &FracModel, opts: &IdentOptions) -> (Self, Vec<f64>, Vec<f64>) {
        let own = |m: &FracModel, i: usize| m.is_initial_state(i) || m.params[i].name == "y_offset";
        let mut params = base.params.clone();
        // the first record's initial-state levels start afresh like the others'; the start's own
        // fit may leave a parameter at the very edge of its open range (a commensurate order at
        // 1), which the joint fit would refuse as a start: it starts just inside
        for (i, p) in params.iter_mut().enumerate() {
            if base.is_initial_state(i) {
                p.value = 0.0;
            }
            p.value = p.bounds.clamp_inside(p.value);
        }
        let (mut parts, mut ranges, mut u, mut y) = (vec![], vec![], vec![], vec![]);
        for (r, rec) in recs.iter().enumerate() {
            let op = rec.offsets(opts.offsets, rec.len());
            let mut m = base.clone();
            m.operating_point = op;
            if opts.initial == InitialState::Estimate {
                m.with_past_input(
                    past_edges(rec.len() as f64 * rec.dt),
                    super::past_range(&rec.u, op.u0),
                );
            }
            let map: Vec<usize> = (0..m.params.len())
                .map(|i| {
                    if r > 0 && own(&m, i) {
                        let mut p = m.params[i].clone();
                        p.name = format!("{}@{}", p.name, r + 1);
                        p.value = 0.0;
                        params.push(p);
                        params.len() - 1
                    } else {
                        i
                    }
                })
                .collect();
            ranges.push((u.len(), u.len() + rec.len()));
            u.extend(rec.u.iter().map(|v| v - op.u0));
            y.extend(rec.y.iter().map(|v| v - op.y0));
            parts.push((m, map));
        }
        let joint = Joint {
            parts,
            ranges,
            params,
        };
        (joint, u, y)
    }
}

/// Why the jointly fitted `model` cannot be used: the rules of a single record's fit on the
/// model and the plant's parameters, judged by the record it fits worst, and any record it fits
/// hardly better than a constant.
fn problems(
    model: &FracModel,
    tf: &FracTf,
    report: &super::FitReport,
    records: &[(Offsets, Fit, Vec<f64>)],
    first: &Record,
) -> Vec<String> {
    let n = model.params.len();
    let worst = records
        .iter()
        .map(|(_, f, _)| *f)
        .min_by(|a, b| a.nrmse_percent.total_cmp(&b.nrmse_percent))
        .unwrap_or(records[0].1);
    let stop = report.stop_reason();
    let ev = super::checks::Evidence {
        model,
        values: &report.values[..n],
        params: &report.params[..n],
        start: &report.start[..n],
        tf,
        estimation: worst,
        validation: None,
        kind: super::ValidationKind::None,
        output_finite: records
            .iter()
            .all(|(_, _, yhat)| crate::lm::all_finite(yhat)),
        converged: (report.converged, stop, report.iterations),
        evaluated: false,
    };
    let (mut problems, _) = super::checks::assess_evidence(&ev, first);
    // Each record is used whole: no held-out part shows that the model describes the data, so
    // one that fits a record it was fitted to hardly better than a constant (two records of
    // noise: 0.2% and -0.2%) does not.
    let floor = super::checks::NO_BETTER_THAN_A_CONSTANT;
    let poorly = records
        .iter()
        .enumerate()
        .filter(|(_, (_, f, _))| !(f.nrmse_percent >= floor));
    problems.extend(poorly.map(|(r, (_, f, _))| {
        format!(
            "the model fits record {} of the joint fit only {:.1}% (below {floor}%: hardly \
             better than a constant, and no part of it is held out): it does not describe these \
             data",
            r + 1,
            f.nrmse_percent
        )
    }));
    problems
}
