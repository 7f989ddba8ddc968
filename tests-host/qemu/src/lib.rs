//! One test source, two machines.
//!
//! Test files of the logic crates (`ecat-slave-stack`, `foc`, `firmware`) that must run
//! on the host *and* on a Cortex-M4F are written once with the [`tests!`] macro and
//! declared in the crate's `Cargo.toml` as `[[test]] harness = false` with a name
//! starting with `portable`:
//!
//! ```text
//! #![cfg_attr(target_os = "none", no_std, no_main)]
//! qemu_runner::tests! {
//!     fn pi_output_is_limited() { assert!(...); }
//! }
//! ```
//!
//! * On the host the macro generates `fn main` that runs every test under
//!   `catch_unwind`, prints one line per test and a libtest-style summary, and exits
//!   non-zero if any test failed.
//! * On `thumbv7em-none-eabihf` it generates the bare-metal `main` called by this
//!   crate's start-up code. Output goes through ARM semihosting; a panic prints the
//!   failing test and message and ends QEMU with exit code 101, a HardFault with 102.
//!   A bare-metal image cannot unwind, so the first failure ends the run — which is
//!   exactly what makes the QEMU run fail.
//!
//! Both sides print `test result: ok. N passed; M failed` so `cargo xtask test`
//! counts them the same way.
#![cfg_attr(target_os = "none", no_std)]
#![deny(clippy::undocumented_unsafe_blocks)]

#[cfg(target_os = "none")]
pub mod target;

#[cfg(not(target_os = "none"))]
pub mod host;

/// One test: its name and body.
pub type TestFn = (&'static str, fn());

/// Defines portable tests and the `main` that runs them (see the crate docs).
#[macro_export]
macro_rules! tests {
    ($( $(#[$meta:meta])* fn $name:ident() $body:block )*) => {
        $( $(#[$meta])* fn $name() $body )*

        const __PORTABLE_TESTS: &[$crate::TestFn] = &[$( (stringify!($name), $name) ),*];

        #[cfg(not(target_os = "none"))]
        fn main() {
            ::std::process::exit($crate::host::run(module_path!(), __PORTABLE_TESTS));
        }

        #[cfg(target_os = "none")]
        #[no_mangle]
        pub extern "C" fn main() -> ! {
            $crate::target::run(module_path!(), __PORTABLE_TESTS)
        }
    };
}

/// Instruction-count markers for `cargo xtask bench`.
///
/// The QEMU plugin counts the guest instructions executed between the entry of
/// [`bench::start`] and the entry of [`bench::stop`]. The two functions have different
/// bodies so the linker can never fold them into one address. Their `#[inline(never)]`
/// (and those of the stack benches) stay whatever the flash size says: an inlined
/// marker has no entry to count from, so they delimit what is measured.
pub mod bench {
    use core::sync::atomic::{AtomicU32, Ordering};

    static MARK: AtomicU32 = AtomicU32::new(0);

    /// Start marker: counting begins at this function's first instruction.
    #[inline(never)]
    #[no_mangle]
    pub extern "C" fn bench_start() {
        MARK.store(1, Ordering::Relaxed);
    }

    /// Stop marker: counting ends at this function's first instruction.
    #[inline(never)]
    #[no_mangle]
    pub extern "C" fn bench_stop() {
        MARK.store(2, Ordering::SeqCst);
        MARK.fetch_add(1, Ordering::SeqCst);
    }

    /// Runs `f` between the markers and returns its result (kept opaque to the optimiser).
    #[inline(never)]
    pub fn measure<R>(f: impl FnOnce() -> R) -> R {
        bench_start();
        let r = f();
        bench_stop();
        core::hint::black_box(r)
    }
}
