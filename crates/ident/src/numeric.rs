//! Vectorised sums and scans over slices (eight interleaved lanes): the dot products, sums of
//! squares, ranges and finiteness checks the solvers, the data checks and the metrics share.

/// `sum_i a_i b_i` over the shorter of `a` and `b`, in eight interleaved partial sums.
///
/// A plain `iter().sum()` is one chain of dependent additions (one add latency per element,
/// about 1 ms per 1e6 terms); eight independent sums let the compiler use vector registers and
/// overlap the additions, about 4x faster on records of 1e5 samples and more. The rounding
/// differs from the sequential sum by the usual `O(n eps)` bound of either order.
///
/// ```
/// let a: Vec<f64> = (0..19).map(f64::from).collect();
/// assert_eq!(ident::numeric::dot(&a, &a), (0..19).map(|k| f64::from(k * k)).sum::<f64>());
/// ```
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    sum_of2(a, b, |x, y| x * y)
}

/// `sum_i r_i^2` ([`dot`] of `r` with itself).
pub fn sumsq(r: &[f64]) -> f64 {
    dot(r, r)
}

/// The Euclidean norm `sqrt(sumsq(v))`.
pub(crate) fn norm(v: &[f64]) -> f64 {
    sumsq(v).sqrt()
}

/// `sum_i f(v_i)` in eight interleaved partial sums (vectorised, as in [`dot`]).
pub(crate) fn sum_of(v: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    const LANES: usize = 8;
    let mut acc = [0.0; LANES];
    let chunks = v.chunks_exact(LANES);
    let tail: f64 = chunks.remainder().iter().map(|&x| f(x)).sum();
    for c in chunks {
        for l in 0..LANES {
            acc[l] += f(c[l]);
        }
    }
    acc.iter().sum::<f64>() + tail
}

pub(crate) use fracsim::lanes::sum_of2;

/// `(min, max)` of `v` (`(inf, -inf)` when empty; NaNs are passed over, as by `f64::min`), in
/// eight lanes (one vectorised pass; a fold of `f64::min` is a chain of dependent operations).
/// Each lane keeps its extreme by a comparison and a select, which compiles to the machine's
/// min and max instructions; `f64::min`'s NaN rules cost three instructions more a vector.
pub(crate) fn range_of(v: &[f64]) -> (f64, f64) {
    const LANES: usize = 8;
    let (mut lo, mut hi) = ([f64::INFINITY; LANES], [f64::NEG_INFINITY; LANES]);
    let chunks = v.chunks_exact(LANES);
    for &x in chunks.remainder() {
        lo[0] = lo[0].min(x);
        hi[0] = hi[0].max(x);
    }
    for c in chunks {
        for l in 0..LANES {
            // (A NaN compares false: the lane keeps its value.)
            lo[l] = if c[l] < lo[l] { c[l] } else { lo[l] };
            hi[l] = if c[l] > hi[l] { c[l] } else { hi[l] };
        }
    }
    (
        lo.iter().fold(f64::INFINITY, |a, &b| a.min(b)),
        hi.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b)),
    )
}

/// Whether every entry of `v` (its value part, for a dual number) is finite: `0 x` is 0 for a
/// finite `x` and NaN otherwise, and a sum of those in eight lanes is one vectorised pass where
/// a search is not.
pub(crate) fn all_finite<T: fracsim::Real>(v: &[T]) -> bool {
    const LANES: usize = 8;
    let chunks = v.chunks_exact(LANES);
    let tail: f64 = chunks.remainder().iter().map(|x| x.re() * 0.0).sum();
    let mut acc = [0.0; LANES];
    for c in chunks {
        for l in 0..LANES {
            acc[l] += c[l].re() * 0.0;
        }
    }
    acc.iter().sum::<f64>() + tail == 0.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lane_sums_and_ranges_equal_plain_folds() {
        for n in [0usize, 1, 7, 8, 9, 17, 1000] {
            let a: Vec<f64> = (0..n)
                .map(|k| ((k * 37 % 101) as f64 - 50.0) * 0.25)
                .collect();
            let b: Vec<f64> = (0..n).map(|k| ((k * 13 % 29) as f64) - 9.5).collect();
            let want: f64 = a.iter().zip(&b).map(|(x, y)| (x - y) * (x - y)).sum();
            let got = sum_of2(&a, &b, |x, y| (x - y) * (x - y));
            assert!((got - want).abs() <= 1e-12 * want.abs().max(1.0), "{n}");
            let lo = a.iter().fold(f64::INFINITY, |m, &v| m.min(v));
            let hi = a.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v));
            assert_eq!(range_of(&a), (lo, hi), "{n}");
            // NaNs anywhere (in the lanes and in the remainder) are passed over.
            let mut with_nan = a.clone();
            for k in (0..n).step_by(3) {
                with_nan[k] = f64::NAN;
            }
            let lo = with_nan.iter().fold(f64::INFINITY, |m, &v| m.min(v));
            let hi = with_nan.iter().fold(f64::NEG_INFINITY, |m, &v| m.max(v));
            assert_eq!(range_of(&with_nan), (lo, hi), "{n} with NaNs");
        }
        // The common length of two slices.
        assert_eq!(sum_of2(&[1.0, 2.0, 3.0], &[1.0], |x, y| x * y), 1.0);
    }
}
