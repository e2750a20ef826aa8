//! Records with a known answer for the unit tests.

/// The output of `gain / (tau s + 1)` driven by the held input `u` from rest, exact for the held
/// input (the zero-order-hold discretisation `x[k+1] = a x[k] + gain (1 - a) u[k]`, `a =
/// exp(-dt / tau)`, `y[k] = x[k]`): independent of the simulators under test.
pub(crate) fn first_order_held(u: &[f64], dt: f64, tau: f64, gain: f64) -> Vec<f64> {
    let (a, mut x) = ((-dt / tau).exp(), 0.0);
    u.iter()
        .map(|&v| {
            let o = x;
            x = a * x + gain * (1.0 - a) * v;
            o
        })
        .collect()
}

/// A seeded 64-bit linear congruential generator (Knuth's MMIX constants): each call steps the
/// state and returns it; the tests map its bits to the numbers they need. The same records every
/// run, with no random-number crate.
pub(crate) fn lcg(seed: u64) -> impl FnMut() -> u64 {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        state
    }
}

/// A seeded uniform number in `[-0.5, 0.5)` at each call: the top 31 bits of [`lcg`]'s state.
pub(crate) fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut lcg = lcg(seed);
    move || ((lcg() >> 33) as f64 / (1u64 << 31) as f64) - 0.5
}

/// `n` samples of a seeded random binary sequence of `+-1`, a new level drawn every `hold`
/// samples (the top bit of [`lcg`]'s state: its low bits cycle with short periods).
pub(crate) fn random_binary(n: usize, hold: usize, seed: u64) -> Vec<f64> {
    let mut next = lcg(seed);
    let mut level = 1.0;
    (0..n)
        .map(|k| {
            if k % hold.max(1) == 0 {
                level = if next() >> 63 == 0 { 1.0 } else { -1.0 };
            }
            level
        })
        .collect()
}
