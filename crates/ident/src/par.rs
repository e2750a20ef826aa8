//! Parallelism as a value. [`Par`] says on how many threads a computation may run; work split in
//! two ([`Par::join`]) gives each side its share of that width, so nested splits never run more
//! threads at once than the width given at the top (scoped threads, no pool to configure).
//!
//! How work is split never depends on the width: [`on_row_halves`] cuts a tall matrix's rows in
//! two by its size alone and runs the halves on one thread or two, so a sum over them is the same
//! sum, to the bit, whatever the width.

use std::num::NonZeroUsize;
use std::ops::Range;

/// On how many threads a computation may run, the calling thread included.
///
/// ```
/// use ident::par::Par;
/// assert_eq!(Par::threads(1), Par::Seq);
/// let (a, b) = Par::threads(3).split();
/// assert_eq!((a.width(), b.width()), (2, 1));
/// let (x, y) = Par::threads(2).join(|_| 1 + 1, |p| p.width());
/// assert_eq!((x, y), (2, 1));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Par {
    /// On the calling thread alone.
    #[default]
    Seq,
    /// On at most this many threads (two or more).
    Threads(NonZeroUsize),
}

impl Par {
    /// At most `n` threads: [`Par::Seq`] for 0 or 1.
    pub fn threads(n: usize) -> Self {
        NonZeroUsize::new(n)
            .filter(|n| n.get() > 1)
            .map_or(Self::Seq, Self::Threads)
    }

    /// As many threads as the machine gives this process (its cores, affinity and quota), asked
    /// once per process: `available_parallelism` reads the affinity mask and the cgroup quota
    /// files (system calls and file reads; it was 8% of a 400-sample fit asking per pass).
    pub fn available() -> Self {
        static WIDTH: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
        Self::threads(
            *WIDTH
                .get_or_init(|| std::thread::available_parallelism().map_or(1, NonZeroUsize::get)),
        )
    }

    /// The number of threads (1 for [`Par::Seq`]).
    pub fn width(self) -> usize {
        match self {
            Self::Seq => 1,
            Self::Threads(n) => n.get(),
        }
    }

    /// The width shared between two parts of the work: the first (run on the calling thread)
    /// gets the larger half, together no more than `self`.
    pub fn split(self) -> (Self, Self) {
        let w = self.width();
        (Self::threads(w - w / 2), Self::threads(w / 2))
    }

    /// `(a(pa), b(pb))` with `(pa, pb)` = [`Self::split`]: `b` on a second thread when the width is
    /// two or more, else both on this one (`a` first). A panic in either is resumed here.
    pub fn join<A, B: Send>(
        self,
        a: impl FnOnce(Self) -> A,
        b: impl FnOnce(Self) -> B + Send,
    ) -> (A, B) {
        let (pa, pb) = self.split();
        if self.width() < 2 {
            return (a(pa), b(pb));
        }
        std::thread::scope(|sc| {
            let second = sc.spawn(move || b(pb));
            let first = a(pa);
            match second.join() {
                Ok(second) => (first, second),
                Err(panic) => std::panic::resume_unwind(panic),
            }
        })
    }
}

impl Par {
    /// `f` of each item, in order, on at most [`Par::width`] new threads at once (scoped; each
    /// takes the next item when it is done with one), each item's panic caught as its `Err`.
    /// New threads, also for [`Par::Seq`] (one): a computation that starts on a thread of its own
    /// (a candidate structure's fit, from no pole cache) starts the same wherever it runs.
    pub fn each_on_new_threads<T: Sync, R: Send>(
        self,
        items: &[T],
        f: impl Fn(&T) -> R + Sync,
    ) -> Vec<std::thread::Result<R>> {
        let next = std::sync::atomic::AtomicUsize::new(0);
        let workers = self.width().min(items.len());
        let done: Vec<Vec<(usize, std::thread::Result<R>)>> = std::thread::scope(|sc| {
            let handles: Vec<_> = (0..workers)
                .map(|_| {
                    sc.spawn(|| {
                        let mut mine = vec![];
                        loop {
                            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                            let Some(item) = items.get(i) else {
                                return mine;
                            };
                            let r =
                                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| f(item)));
                            mine.push((i, r));
                        }
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| h.join().unwrap_or_default())
                .collect()
        });
        let mut out: Vec<Option<std::thread::Result<R>>> = (0..items.len()).map(|_| None).collect();
        for (i, r) in done.into_iter().flatten() {
            out[i] = Some(r);
        }
        out.into_iter()
            .map(|r| r.unwrap_or_else(|| Err(Box::new("a worker thread was lost"))))
            .collect()
    }
}

/// Below this many entries of `J`, the passes over it (`J^T r`, the QR of `[J r]`) take its rows
/// whole (a thread costs more than it saves).
pub(crate) const PARALLEL_ENTRIES: usize = 1 << 17;

/// `f` of the rows `0..m` of a `m x n` matrix: of `0..m/2` and `m/2..m` when the matrix has
/// [`PARALLEL_ENTRIES`] or more (the passes over `J` are bound by memory bandwidth, which one
/// core does not use up), on two threads when `par` allows, else of `0..m` alone. The cut
/// depends on the size only: the results are the same for every `par`.
pub(crate) fn on_row_halves<T: Send>(
    par: Par,
    m: usize,
    n: usize,
    f: impl Fn(Range<usize>) -> T + Sync,
) -> Vec<T> {
    if m * n < PARALLEL_ENTRIES || m < 2 {
        return vec![f(0..m)];
    }
    let half = m / 2;
    let (first, second) = par.join(|_| f(0..half), |_| f(half..m));
    vec![first, second]
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Nested joins never run more threads at once than the width at the top: each leaf counts
    /// the threads running, and the largest count is the width (and 1 for `Seq`).
    #[test]
    fn nested_joins_stay_within_the_width() {
        fn tree(par: Par, depth: usize, running: &AtomicUsize, most: &AtomicUsize) {
            if depth == 0 {
                let now = running.fetch_add(1, Ordering::SeqCst) + 1;
                most.fetch_max(now, Ordering::SeqCst);
                std::thread::sleep(std::time::Duration::from_millis(20));
                running.fetch_sub(1, Ordering::SeqCst);
                return;
            }
            par.join(
                |p| tree(p, depth - 1, running, most),
                |p| tree(p, depth - 1, running, most),
            );
        }
        for width in [1, 2, 3, 4] {
            let (running, most) = (AtomicUsize::new(0), AtomicUsize::new(0));
            tree(Par::threads(width), 4, &running, &most);
            assert_eq!(most.load(Ordering::SeqCst), width, "width {width}");
        }
    }

    /// Every item once, in order, whatever the width; never more threads at once than the width;
    /// a panicking item is its own `Err`.
    #[test]
    fn each_on_new_threads_keeps_the_order_and_the_width() {
        let (running, most) = (AtomicUsize::new(0), AtomicUsize::new(0));
        let items: Vec<usize> = (0..7).collect();
        for width in [1, 2, 3] {
            let got = Par::threads(width).each_on_new_threads(&items, |&i| {
                let now = running.fetch_add(1, Ordering::SeqCst) + 1;
                most.fetch_max(now, Ordering::SeqCst);
                std::thread::sleep(std::time::Duration::from_millis(10));
                running.fetch_sub(1, Ordering::SeqCst);
                assert!(i != 5, "item 5 panics");
                i * 10
            });
            assert!(got[5].is_err());
            let ok: Vec<usize> = got.into_iter().filter_map(Result::ok).collect();
            assert_eq!(ok, vec![0, 10, 20, 30, 40, 60]);
            assert_eq!(most.swap(0, Ordering::SeqCst), width, "width {width}");
        }
    }

    /// The halves are cut by the size alone: the same parts for every width.
    #[test]
    fn row_halves_do_not_depend_on_the_width() {
        let m = PARALLEL_ENTRIES;
        for par in [Par::Seq, Par::threads(2), Par::threads(5)] {
            assert_eq!(on_row_halves(par, m, 1, |r| r), vec![0..m / 2, m / 2..m]);
            assert_eq!(on_row_halves(par, 100, 1, |r| r), vec![0..100]);
        }
    }
}
