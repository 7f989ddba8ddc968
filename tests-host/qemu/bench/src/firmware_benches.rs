//! Benchmarks of the `firmware` area. Each call to [`crate::bench`] is one row of BENCHMARKS.md.

pub fn run() {}
