//! Benchmarks of the `foc` area. Each call to [`crate::bench`] is one row of BENCHMARKS.md.

pub fn run() {}
