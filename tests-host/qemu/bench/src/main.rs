//! Benchmark image: each benchmark runs its hot path once between the instruction-count
//! markers of `qemu_runner::bench`. `cargo xtask bench` runs this image under QEMU with
//! the counting plugin and pairs the printed `BENCH <name>` lines with the counts.
//! On the host the same binary runs the benchmarks natively (a smoke test, no counts).
#![cfg_attr(target_os = "none", no_std, no_main)]
#![deny(clippy::undocumented_unsafe_blocks)]

mod board_benches;
mod ecat_benches;
mod faults_benches;
mod firmware_benches;
mod foc_benches;
mod stack_benches;

/// Prints the benchmark name, then runs `f` once between the markers.
pub fn bench<R>(name: &str, f: impl FnOnce() -> R) -> R {
    #[cfg(target_os = "none")]
    qemu_runner::println!("BENCH {name}");
    #[cfg(not(target_os = "none"))]
    println!("BENCH {name}");
    qemu_runner::bench::measure(f)
}

/// Set-up shared by the motion-layer rows (built outside the measured closures).
pub mod setup {
    use firmware::cia402::{DriveCommand, SetpointKind};
    use firmware::identity::Variant;
    use firmware::motion::{Feedback, MotionConfig, ECN57_20, SERVO_TS};
    use firmware::params::Params;
    use foc::angle::Angle;

    /// The motion configuration of a hybrid servo with its default parameters.
    pub fn servo_config(p: &Params) -> MotionConfig {
        MotionConfig::from_params(p, Variant::HybridServo, &ECN57_20, SERVO_TS)
    }

    /// An enabled position command moving at 50 000 units/s (one revolution per
    /// second), from position 0.
    pub fn moving_command() -> DriveCommand {
        DriveCommand {
            power_stage: true,
            drive_enabled: true,
            kind: SetpointKind::Position,
            position: 0,
            velocity: 50_000.0,
            acceleration: 0.0,
            torque_limit: 1000,
            current_limit: 1000,
            torque: 0,
            brake_release: true,
        }
    }

    /// Feedback of an axis at rest at position 0.
    pub const AT_REST: Feedback = Feedback {
        position: 0,
        velocity: 0.0,
        electrical_angle: Angle::ZERO,
        voltage_limited: false,
        v_dq: foc::transforms::Dq { d: 0.0, q: 0.0 },
        i_dq: foc::transforms::Dq { d: 0.0, q: 0.0 },
    };
}

/// Name of the calibration row: an empty closure between the markers. Its count (the
/// cost of the markers themselves) is subtracted from every other row.
pub const OVERHEAD: &str = "(marker overhead)";

fn run_all() {
    bench(OVERHEAD, || ());
    foc_benches::run();
    ecat_benches::run();
    firmware_benches::run();
    faults_benches::run();
    board_benches::run();
    // Stack depths last: they print STACK lines, no instruction counts.
    stack_benches::run();
}

#[cfg(target_os = "none")]
#[no_mangle]
pub extern "C" fn main() -> ! {
    run_all();
    qemu_runner::println!("BENCH-END");
    qemu_runner::target::exit(0)
}

#[cfg(not(target_os = "none"))]
fn main() {
    run_all();
    println!("BENCH-END");
}
