//! The CI subset and its floors: a fixed list of cases `cargo test` runs (tests/ci.rs) through both
//! fleet paths, failing when a class's right answers or exact effect sets fall below its floor.
//!
//! THE FLOORS ARE THE FIGURES MEASURED ON MAIN'S BINARY (see benches/README.md, "The benchmark
//! zoo"). They are raised as work lands and never lowered silently: a change that lowers one says
//! so, and why, in its commit and in benches/README.md.

use crate::cases::{Class, Sizing};
use crate::score::table::{self, ClassRow};

/// The subset's seed.
pub const SEED: u64 = 4401;
/// The subset: cases 0..50 of the zoo of `SEED` (two per class), short records.
pub const CASES: usize = 50;
/// The subset's record lengths.
pub const SIZING: Sizing = Sizing::CI;

/// A class's floors: right answers on the plain and the diagnosed path, exact effect sets with
/// `--diagnose`, each as a count of the class's cases in the subset.
#[derive(Clone, Copy, Debug)]
pub struct Floor {
    /// The class.
    pub class: Class,
    /// Right answers, plain fit.
    pub plain_right: usize,
    /// Right answers, `--diagnose`.
    pub diagnose_right: usize,
    /// Exact effect sets, `--diagnose`.
    pub diagnose_effects: usize,
}

const fn f(
    class: Class,
    plain_right: usize,
    diagnose_right: usize,
    diagnose_effects: usize,
) -> Floor {
    Floor {
        class,
        plain_right,
        diagnose_right,
        diagnose_effects,
    }
}

/// The floors, one per class: the counts measured on main e364c0a's binary (2026-12-05, `zoo run
/// --ci`; the run is deterministic: two runs gave the same scores case by case). Raised as work
/// lands, never lowered silently (see the module's note).
///
/// Measured again on the truth's third version, whose records differ from the second's by 4e-12 to
/// 4e-8 of the swing: fracid's diagnosis flipped on two cases (saturation 14: power_law -> the
/// right saturation, floors raised to 2 / 2; cell 34: no effect -> a spurious delay, its exact
/// effects floor 1 -> 0). Its decisions move with changes that small: a floor of a class with two
/// cases moves by one on such a flip.
///
/// Raised on main 6231ea7 (the final model's own verdict, `ident::app::verdict`; the subset
/// measured with `zoo run --ci`): feed-through 0/0/1 -> 1/1/1, integrator 0/2/2 -> 2/2/2, cell
/// 0/0/0 -> 1/1/1, sign-blind sensor 0/0/0 -> 0/2/0, two effects 1/1/1 -> 1/2/1.
///
/// Lowered on main b4d3200 (the diagnosis's candidate fits stop on the refits' stall test; the
/// final model's undetermined terms held): lead's exact effect sets 2 -> 1, one of its two cases
/// now keeping a spurious effect while both stay right (issue 47's note).
///
/// Lowered on main after faer became ident's linear algebra, the loop was closed by default and
/// the general structure joined the diagnosis (all three merged together; which one moved these
/// two cases was not measured): integrator's exact effect sets 2 -> 1 (one case keeps a spurious
/// effect, both stay right), saturation's diagnosed right 2 -> 1 and exact effect sets 2 -> 1.
/// The same subset rose elsewhere (lead 2 / 2, feed-through 2 / 2, diffusion 2 / 2, cell 2 / 2,
/// in motion 2 right, two-mass at the motor 1 right, diagnosed), not raised here until a second
/// run confirms them (issue 47's note).
///
/// Raised on main ca1a308 (`zoo run --ci` twice, identical case by case): the rises above
/// confirmed (two-mass at the motor 0/1/1, feed-through 1/2/2, diffusion 1/2/2, lead 0/2/2, cell
/// 1/2/2, in motion 1/2/1) and saturation back to 0/2/2 (the refits' tie rule `REFIT_TIE` decides
/// the static maps' exact ties that rounding decided before). Seen once, not raised yet: dead band
/// exact effects 2, power law exact effects 2.
///
/// Moved with the output drift effect (`output_drift`) and the refits' cap counting only the
/// candidates with evidence (`zoo run --ci` twice, identical case by case): sign-blind sensor
/// exact effects 0 -> 2 (its floor-level candidate no longer pushed out of the four refits), dead
/// band and power law exact effects 1 -> 2 (the rises seen before, seen again); saturation's exact
/// effects lowered 2 -> 1: case 39's PMSM plant has a slow fractional tail that the first order
/// chosen with its saturation lacks, and the drift stands in for it (held-out RMSE 9.26 -> 3.35,
/// the oracle's 0.66; right both times). On the 300 cases of seed 44 the saturation class is
/// unchanged and the drift class's exact effect sets rise 2 -> 8 (issue 47's note).
///
/// Lowered with the simulator's feed-through of a strictly proper model read before the sample
/// instant (`fracsim::modal::PoleResidue::strictly_proper`): feed-through's plain right 1 -> 0.
/// The plain path fits the PMSM, strictly proper, to a plant that responds at once; its
/// approximation's feed-through (the cells above the band) fed `u_k` let it fake the instant
/// response, which the exact model cannot: fed the input before the instant, its fit is
/// honestly wrong. The diagnosed path, which compares the feed-through structure, stays 2 / 2.
pub const FLOORS: &[Floor] = &[
    f(Class::Pmsm, 2, 2, 2),
    f(Class::Integer, 2, 2, 2),
    f(Class::TwoMassMotor, 0, 1, 1),
    f(Class::TwoMassLoad, 2, 2, 2),
    f(Class::MultiMode, 1, 1, 1),
    f(Class::Feedthrough, 0, 2, 2),
    f(Class::Integrator, 2, 2, 1),
    f(Class::Diffusion, 1, 2, 2),
    f(Class::Lead, 0, 2, 2),
    f(Class::Cell, 1, 2, 2),
    f(Class::Delay, 2, 2, 2),
    f(Class::FrictionReversal, 1, 2, 2),
    f(Class::FrictionOneWay, 1, 2, 2),
    f(Class::Deadband, 1, 2, 2),
    f(Class::Saturation, 0, 2, 1),
    f(Class::StaticMapTwoLevel, 1, 2, 2),
    f(Class::Offsets, 2, 2, 2),
    f(Class::Periodic, 0, 1, 1),
    f(Class::AbsSensor, 0, 2, 2),
    f(Class::PowerLaw, 1, 1, 2),
    f(Class::Quantisation, 1, 2, 2),
    f(Class::Drift, 1, 2, 2),
    f(Class::TwoEffects, 1, 2, 1),
    f(Class::ClosedLoop, 2, 2, 2),
    f(Class::InMotion, 1, 2, 1),
];

/// The classes below their floors, one line each (empty: all pass).
pub fn below_floors(rows: &[ClassRow]) -> Vec<String> {
    let mut out = Vec::new();
    for fl in FLOORS {
        let Some(r) = table::find(rows, fl.class) else {
            out.push(format!("{}: no case scored", fl.class.name()));
            continue;
        };
        let checks = [
            ("plain right", r.plain.right, fl.plain_right),
            ("diagnose right", r.diagnose.right, fl.diagnose_right),
            (
                "diagnose effects exact",
                r.diagnose.effects_exact,
                fl.diagnose_effects,
            ),
        ];
        for (what, got, floor) in checks {
            if got < floor {
                out.push(format!(
                    "{}: {what} {got} below its floor {floor}",
                    fl.class.name()
                ));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::score::table::PathStats;

    fn row(class: Class, plain_right: usize, diagnose_right: usize, effects: usize) -> ClassRow {
        ClassRow {
            class: class.name().into(),
            cases: 2,
            identifiable: 2,
            plain: PathStats {
                cases: 2,
                right: plain_right,
                ..PathStats::default()
            },
            diagnose: PathStats {
                cases: 2,
                right: diagnose_right,
                effects_exact: effects,
                ..PathStats::default()
            },
        }
    }

    #[test]
    fn a_class_below_its_floor_is_named_and_one_missing_too() {
        let at: Vec<ClassRow> = FLOORS
            .iter()
            .map(|f| row(f.class, f.plain_right, f.diagnose_right, f.diagnose_effects))
            .collect();
        assert!(below_floors(&at).is_empty());
        let pmsm = FLOORS.iter().find(|f| f.class == Class::Pmsm).unwrap();
        assert!(pmsm.diagnose_right > 0, "the PMSM floor is above 0");
        let mut low = at.clone();
        low[0] = row(
            Class::Pmsm,
            pmsm.plain_right,
            pmsm.diagnose_right - 1,
            pmsm.diagnose_effects,
        );
        let below = below_floors(&low);
        assert_eq!(below.len(), 1);
        assert!(below[0].starts_with("pmsm: diagnose right"), "{below:?}");
        let below = below_floors(&at[1..]);
        assert_eq!(below, ["pmsm: no case scored"]);
        assert_eq!(FLOORS.len(), crate::cases::ALL_CLASSES.len());
    }
}
