//! Work on two threads where it pays: the halves of a tall matrix's rows, and whether the
//! machine has two cores.

use std::ops::Range;

/// Below this many entries of `J`, the passes over it (`J^T r`, the QR of `[J r]`) run on one
/// thread (a thread costs more than it saves).
pub(crate) const PARALLEL_ENTRIES: usize = 1 << 17;

/// `f` of the rows `0..m` of a `m x n` matrix: of `0..m/2` and `m/2..m` on two threads when
/// the matrix is large and the machine has two cores (the passes over `J` are bound by memory
/// bandwidth, which one core does not use up), else of `0..m` alone.
pub(crate) fn on_row_halves<T: Send>(
    m: usize,
    n: usize,
    f: impl Fn(Range<usize>) -> T + Sync,
) -> Vec<T> {
    if m * n < PARALLEL_ENTRIES || m < 2 || !two_cores() {
        return vec![f(0..m)];
    }
    let half = m / 2;
    std::thread::scope(|sc| {
        let second = sc.spawn(|| f(half..m));
        let first = f(0..half);
        // `f` does not panic here; were the thread lost, its half is computed on this one.
        let second = second.join().unwrap_or_else(|_| f(half..m));
        vec![first, second]
    })
}

/// Whether the machine has at least two cores (the two-thread paths here and in the fit). Asked
/// once per process: `available_parallelism` reads the affinity mask and the cgroup quota files
/// (system calls and file reads; it was 8% of a 400-sample fit asking per pass).
pub(crate) fn two_cores() -> bool {
    static TWO: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *TWO.get_or_init(|| std::thread::available_parallelism().is_ok_and(|c| c.get() >= 2))
}
