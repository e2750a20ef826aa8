//! The scoreboard's floors over one run (issue 47's): on the diagnosed path (what `fracid time`
//! does by default), over the identifiable cases, the exact effect set on at least 95%, a spurious
//! effect on at most 2%, a frequency-response error of at most 5% on at least 95%, a held-out
//! RMSE within 10% of the oracle's on at least 95%; and every case that cannot be identified
//! answered right (no exit 0 with a guess).
//!
//! Figures of one seed are a sample of the zoo's distribution: a change judged on one seed only
//! is tuned to it (the floors that seed 44 meets are missed on seeds 45 and 46, `benches/README.md`).

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use super::{Outcome, Path};

/// The share of identifiable cases with the exact effect set, the FRF error within
/// [`FRF_TIGHT`], and the held-out RMSE within [`WITHIN`] of the oracle's, each at least.
pub const SHARE: f64 = 0.95;
/// The largest share of identifiable cases with a spurious effect.
pub const SPURIOUS_SHARE: f64 = 0.02;
/// The frequency-response error the floor counts (5%).
pub const FRF_TIGHT: f64 = 0.05;
/// The held-out RMSE over the oracle's the floor counts (within 10%).
pub const WITHIN: f64 = 1.1;

/// The counts of one run's diagnosed path.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Floors {
    /// Identifiable cases.
    pub identifiable: usize,
    /// Of those, with the exact effect set.
    pub exact: usize,
    /// Of those, with a spurious effect.
    pub spurious: usize,
    /// Of those, with a frequency-response error of at most [`FRF_TIGHT`].
    pub frf: usize,
    /// Of those, with a held-out RMSE at most [`WITHIN`] times the oracle's.
    pub within: usize,
    /// Cases that cannot be identified.
    pub unidentifiable: usize,
    /// Of those, answered right.
    pub unidentifiable_right: usize,
}

/// The floors' counts over the diagnosed path of `outcomes`.
pub fn floors(outcomes: &[Outcome]) -> Floors {
    let mut f = Floors::default();
    for o in outcomes.iter().filter(|o| o.path == Path::Diagnose) {
        if !o.identifiable {
            f.unidentifiable += 1;
            f.unidentifiable_right += usize::from(o.right);
            continue;
        }
        f.identifiable += 1;
        f.exact += usize::from(o.effects_exact());
        f.spurious += usize::from(!o.spurious.is_empty());
        f.frf += usize::from(o.frf_error.is_some_and(|e| e <= FRF_TIGHT));
        f.within += usize::from(o.heldout_ratio().is_some_and(|r| r <= WITHIN));
    }
    f
}

impl Floors {
    /// Each floor: its name, count, share of its cases, the floor, and whether it is met.
    pub fn rows(&self) -> Vec<(&'static str, usize, f64, String, bool)> {
        let share = |k: usize, n: usize| if n == 0 { 1.0 } else { k as f64 / n as f64 };
        let n = self.identifiable;
        let at_least = |name, k| {
            let s = share(k, n);
            (name, k, s, format!(">= {:.0}%", 100.0 * SHARE), s >= SHARE)
        };
        let spurious = share(self.spurious, n);
        let right = share(self.unidentifiable_right, self.unidentifiable);
        vec![
            at_least("effects exact", self.exact),
            (
                "spurious effect",
                self.spurious,
                spurious,
                format!("<= {:.0}%", 100.0 * SPURIOUS_SHARE),
                spurious <= SPURIOUS_SHARE,
            ),
            at_least("FRF error <= 5%", self.frf),
            at_least("held-out within 10% of the oracle", self.within),
            (
                "cannot be identified: right",
                self.unidentifiable_right,
                right,
                "all".into(),
                self.unidentifiable_right == self.unidentifiable,
            ),
        ]
    }

    /// Whether every floor is met.
    pub fn met(&self) -> bool {
        self.rows().iter().all(|r| r.4)
    }

    /// The floors as a markdown table.
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "Floors, `--diagnose` path ({} identifiable cases, {} that cannot be identified):\n\n\
             | figure | cases | share | floor | met |\n|---|---|---|---|---|\n",
            self.identifiable, self.unidentifiable
        );
        for (name, k, share, floor, met) in self.rows() {
            let _ = writeln!(
                s,
                "| {name} | {k} | {:.1}% | {floor} | {} |",
                100.0 * share,
                if met { "yes" } else { "no" }
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cases::Class;

    fn outcome(path: Path, identifiable: bool) -> Outcome {
        Outcome {
            name: "c".into(),
            class: Class::Pmsm,
            path,
            identifiable,
            exit_code: Some(0),
            kept: vec![],
            spurious: vec![],
            missed: vec![],
            named_ambiguous: vec![],
            frf_error: Some(0.01),
            heldout_rmse: Some(1.0),
            oracle_rmse: Some(1.0),
            seconds: None,
            model: None,
            right: true,
        }
    }

    /// Counts over the diagnosed path only, each floor at its edge: 19 of 20 (95%) exact, FRF
    /// and within 10% meet theirs, one spurious of 20 (5%) does not; the plain path's cases are
    /// not counted.
    #[test]
    fn the_floors_count_the_diagnosed_path_at_their_edges() {
        let mut v: Vec<Outcome> = (0..20).map(|_| outcome(Path::Diagnose, true)).collect();
        v[0].spurious = vec!["delay".into()];
        v[1].frf_error = Some(0.0501);
        v[2].heldout_rmse = Some(1.1001);
        v.push(outcome(Path::Diagnose, false));
        let mut plain = outcome(Path::Plain, true);
        plain.missed = vec!["delay".into()];
        v.push(plain);
        let f = floors(&v);
        assert_eq!(
            (f.identifiable, f.exact, f.spurious, f.frf, f.within),
            (20, 19, 1, 19, 19)
        );
        assert_eq!((f.unidentifiable, f.unidentifiable_right), (1, 1));
        let met: Vec<bool> = f.rows().iter().map(|r| r.4).collect();
        assert_eq!(met, [true, false, true, true, true]);
        assert!(!f.met());
        v[0].spurious.clear();
        let f = floors(&v);
        assert_eq!(f.spurious, 0);
        assert!(f.met(), "{}", f.markdown());
        v[20].right = false;
        assert!(!floors(&v).met());
    }
}
