//! Sums over slices in eight interleaved partial sums.
//!
//! A plain `iter().sum()` is one chain of dependent additions (one add latency per element);
//! eight independent sums let the compiler use vector registers and overlap the additions, on
//! every target (no CPU-specific code). The rounding differs from the sequential sum by the
//! usual `O(n eps)` bound of either order.

const LANES: usize = 8;

/// `sum_i f(a_i, b_i)` over the common length of `a` and `b`, in eight interleaved partial sums.
///
/// ```
/// let d = fracsim::lanes::sum_of2(&[1.0, 2.0, 3.0], &[1.0, 1.0], |x, y| (x - y) * (x - y));
/// assert_eq!(d, 1.0);
/// ```
pub fn sum_of2(a: &[f64], b: &[f64], f: impl Fn(f64, f64) -> f64) -> f64 {
    let n = a.len().min(b.len());
    let (ca, cb) = (a[..n].chunks_exact(LANES), b[..n].chunks_exact(LANES));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(&x, &y)| f(x, y))
        .sum();
    let mut acc = [0.0; LANES];
    for (x, y) in ca.zip(cb) {
        for l in 0..LANES {
            acc[l] += f(x[l], y[l]);
        }
    }
    acc.iter().sum::<f64>() + tail
}

/// The dot product `sum_i a_i b_i` over the common length of `a` and `b` ([`sum_of2`]).
///
/// ```
/// let a: Vec<f64> = (0..19).map(f64::from).collect();
/// assert_eq!(fracsim::lanes::dot(&a, &a), (0..19).map(|k| f64::from(k * k)).sum::<f64>());
/// ```
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    sum_of2(a, b, |x, y| x * y)
}
