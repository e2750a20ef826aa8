//! A fit through the public `identify` does not depend on what ran before on the same thread:
//! the pole cache (`fracsim::modal::RootsCache`), whose hints move the last bits of a fit, starts
//! empty for each identification.

use ident::data::Record;
use ident::oe::{identify, FracModel, IdentOptions};

/// The whole report of a PMSM fit of `rec`, its timing left out (floats printed shortest-exact,
/// so equal text is equal bits).
fn report(rec: &Record) -> String {
    let model = FracModel::pmsm(5.0, 0.01, 1e-4, 0.9, 0.9);
    let mut id = identify(rec, &model, &IdentOptions::default()).unwrap();
    id.report.elapsed = std::time::Duration::ZERO;
    format!("{id:?}")
}

/// Records A (the paper's PMSM at 0.2 ms, noise seed 11) and B (the same plant, another noise
/// draw, 1.3 times the output: a nearby model, whose solved poles hint A's) fitted A, B, A on
/// one thread: A's two reports are equal to the bit. (Without the empty cache at the start of
/// `identify`, A's second report differed in the last bits, as A fitted twice in a row did.)
#[test]
fn a_record_fitted_after_another_gives_the_same_report() {
    let a = super::roundtrip::paper_record(2e-4, 4, 11);
    let mut b = super::roundtrip::paper_record(2e-4, 4, 12);
    b.y.iter_mut().for_each(|v| *v *= 1.3);
    let first = report(&a);
    let other = report(&b);
    let again = report(&a);
    assert_ne!(first, other);
    assert!(first == again, "A's report changed after B's fit");
    assert!(report(&a) == first, "A's report changed after A's fit");
}
