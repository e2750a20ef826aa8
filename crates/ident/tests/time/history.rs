//! A fit through the public `identify` or `fit` does not depend on what ran before on the same
//! thread: the pole cache (`fracsim::modal::RootsCache`), whose hints move the last bits of a
//! fit, is a value its computation owns; it starts empty for each identification, and outside of
//! one nothing is kept.

use fracsim::modal::RootsCache;
use ident::data::Record;
use ident::oe::{fit, identify, FitOptions, FracModel, IdentOptions};

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

/// The whole report of a PMSM fit (the public `fit`, from a given start) of `rec`'s samples, its
/// timing left out.
fn fit_report(rec: &Record) -> String {
    let start = FracModel::pmsm(5.0, 0.006, 3e-5, 0.9, 0.8);
    let mut r = fit(&start, &rec.u, &rec.y, rec.dt, &FitOptions::default()).unwrap();
    r.elapsed = std::time::Duration::ZERO;
    format!("{r:?}")
}

/// The public `fit` outside of a caller's pole cache keeps nothing between calls: A, B, A on one
/// thread give A's report twice to the bit.
/// Inside a cache the caller enters (a request's), `identify` empties it first and leaves its
/// own in it (the diagnosis goes on from there): the same report as alone, after B's fit too.
#[test]
fn fits_keep_nothing_outside_of_a_cache_and_identify_starts_the_callers_afresh() {
    let a = super::roundtrip::paper_record(2e-4, 4, 11);
    let mut b = super::roundtrip::paper_record(2e-4, 4, 12);
    b.y.iter_mut().for_each(|v| *v *= 1.3);
    let first = fit_report(&a);
    let other = fit_report(&b);
    assert_ne!(first, other);
    assert!(fit_report(&a) == first, "A's fit changed after B's fit");
    let alone = report(&a);
    let mut cache = RootsCache::new();
    let (other, again) = cache.enter(|| (report(&b), report(&a)));
    assert_ne!(alone, other);
    assert!(
        again == alone,
        "A's report changed inside a cache B's fit used"
    );
    assert!(
        !cache.is_empty(),
        "identify left nothing in the caller's cache"
    );
}
