//! Benchmark crate: see the `[[bench]]` targets.
