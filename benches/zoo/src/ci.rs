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

/// The floors, one per class (measured on main, see the module's note).
pub const FLOORS: &[Floor] = &[
    f(Class::Pmsm, 0, 0, 0),
    f(Class::Integer, 0, 0, 0),
    f(Class::TwoMassMotor, 0, 0, 0),
    f(Class::TwoMassLoad, 0, 0, 0),
    f(Class::MultiMode, 0, 0, 0),
    f(Class::Feedthrough, 0, 0, 0),
    f(Class::Integrator, 0, 0, 0),
    f(Class::Diffusion, 0, 0, 0),
    f(Class::Lead, 0, 0, 0),
    f(Class::Cell, 0, 0, 0),
    f(Class::Delay, 0, 0, 0),
    f(Class::FrictionReversal, 0, 0, 0),
    f(Class::FrictionOneWay, 0, 0, 0),
    f(Class::Deadband, 0, 0, 0),
    f(Class::Saturation, 0, 0, 0),
    f(Class::StaticMapTwoLevel, 0, 0, 0),
    f(Class::Offsets, 0, 0, 0),
    f(Class::Periodic, 0, 0, 0),
    f(Class::AbsSensor, 0, 0, 0),
    f(Class::PowerLaw, 0, 0, 0),
    f(Class::Quantisation, 0, 0, 0),
    f(Class::Drift, 0, 0, 0),
    f(Class::TwoEffects, 0, 0, 0),
    f(Class::ClosedLoop, 0, 0, 0),
    f(Class::InMotion, 0, 0, 0),
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
