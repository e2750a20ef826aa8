//! `fracid time FILE` (the loop closed, the default) against `fracid time FILE --plain` (the named
//! structure fitted once), in process through the use case both run (`ident::app::time::run`),
//! on every time-domain record in `data/` (issue 47: the default's cost at most 10x the plain
//! fit's). Divan measures wall time: the closed loop's candidates run on all cores, so its CPU
//! time is higher than shown here; the CPU ratio per record (user + system, whole process) is
//! measured with `getrusage` beside the zoo table (benches/README.md).
//!
//! `cargo bench -p fracid-benches --bench default`

use divan::{black_box, Bencher};
use fracid_benches::{real_record, TIME_RECORDS};
use ident::app::observe::Quiet;
use ident::app::time::{run, TimeData, TimeRequest};

fn main() {
    divan::main();
}

fn data(name: &str) -> TimeData {
    TimeData {
        record: real_record(name),
        validation: None,
        joint: vec![],
        reader_warnings: vec![],
    }
}

/// `--plain`: the named structure (pmsm) fitted once.
#[divan::bench(args = TIME_RECORDS, sample_count = 5, sample_size = 1)]
fn plain(b: Bencher<'_, '_>, name: &str) {
    let d = data(name);
    let req = TimeRequest {
        plain: true,
        ..TimeRequest::default()
    };
    b.bench(|| run(&req, black_box(&d), &mut Quiet).ok());
}

/// The default: the structures compared, the best diagnosed, its final model leading.
#[divan::bench(args = TIME_RECORDS, sample_count = 3, sample_size = 1)]
fn default(b: Bencher<'_, '_>, name: &str) {
    let d = data(name);
    let req = TimeRequest::default();
    assert!(!req.plain, "the default closes the loop");
    b.bench(|| run(&req, black_box(&d), &mut Quiet).ok());
}
