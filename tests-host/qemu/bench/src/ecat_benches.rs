//! Benchmarks of the `ecat` area. Each call to [`crate::bench`] is one row of BENCHMARKS.md.

mod coe_rows;
mod escdrv_rows;
mod esm_rows;
mod foe_rows;

pub fn run() {
    esm_rows::run();
    coe_rows::run();
    escdrv_rows::run();
    foe_rows::run();
}
