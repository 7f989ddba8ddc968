//! Harness self-test: this image contains a test that fails on purpose.
//! `cargo xtask test` runs it on the host and under QEMU and passes only if both
//! runs report the failure with a non-zero exit code.
#![cfg_attr(target_os = "none", no_std, no_main)]

qemu_runner::tests! {
    fn arithmetic_still_works() {
        assert_eq!(core::hint::black_box(2) + 2, 4);
    }
    fn deliberately_failing() {
        assert_eq!(core::hint::black_box(2) + 2, 5, "this failure is expected");
    }
}
