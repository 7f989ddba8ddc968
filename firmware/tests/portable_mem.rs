#![cfg_attr(target_os = "none", no_std, no_main)]
//! The board's `memcpy` / `memset` routines (`firmware::mem`): every alignment of
//! destination and source, every length up to 80 bytes (the word and 16-byte paths
//! and their byte tails), against a byte-by-byte model; guard bytes around the target
//! must stay untouched. Under QEMU this runs the Thumb-2 routines themselves.
use firmware::mem::{copy, fill};

const GUARD: u8 = 0xA5;
const N: usize = 80;

/// A source pattern with no two equal neighbours (a shifted copy shows).
fn pattern() -> [u8; N + 8] {
    let mut p = [0u8; N + 8];
    for (i, b) in p.iter_mut().enumerate() {
        *b = (i as u8).wrapping_mul(37).wrapping_add(11);
    }
    p
}

/// A word-aligned buffer of guard bytes; `op` writes `n` bytes at `4 + d_off`, which
/// must then hold `want(k)` for byte `k` while every other byte is still the guard.
fn check(d_off: usize, n: usize, op: impl FnOnce(*mut u8), want: impl Fn(usize) -> u8) {
    #[repr(align(8))]
    struct Buf([u8; N + 16]);
    let mut dst = Buf([GUARD; N + 16]);
    let at = 4 + d_off;
    assert!(at + n + 4 <= dst.0.len());
    // SAFETY: `at + n <= dst.len()` (checked above).
    op(unsafe { dst.0.as_mut_ptr().add(at) });
    for (i, &b) in dst.0.iter().enumerate() {
        let w = if (at..at + n).contains(&i) {
            want(i - at)
        } else {
            GUARD
        };
        assert_eq!(b, w, "dst+{d_off} n {n} byte {i}");
    }
}

qemu_runner::tests! {
    fn copy_every_alignment_and_length() {
        let src = pattern();
        for so in 0..4 {
            for d_off in 0..4 {
                for n in 0..=N {
                    // SAFETY: `so + n <= src.len()`; `check` gives `n` writable bytes
                    // of another buffer.
                    check(d_off, n, |d| unsafe { copy(d, src.as_ptr().add(so), n) }, |k| src[so + k]);
                }
            }
        }
    }

    fn fill_every_alignment_length_and_value() {
        for value in [0u8, 0x01, 0x7F, 0x80, 0xFF] {
            for d_off in 0..4 {
                for n in 0..=N {
                    // SAFETY: `check` gives `n` writable bytes.
                    check(d_off, n, |d| unsafe { fill(d, value, n) }, |_| value);
                }
            }
        }
    }

    fn guard_value_equal_to_the_fill_still_shows_the_bounds() {
        // With the fill value equal to the guard byte the check above cannot see an
        // overrun; a distinct guard here.
        for d_off in 0..4 {
            for n in [0usize, 1, 3, 4, 5, 15, 16, 17, 63, 64, 65] {
                let mut dst = [0u8; N + 16];
                let at = 4 + d_off;
                // SAFETY: `at + n + 4 <= dst.len()`.
                unsafe { fill(dst.as_mut_ptr().add(at), GUARD, n) };
                assert_eq!(dst.iter().filter(|&&b| b == GUARD).count(), n);
                assert!(dst[at..at + n].iter().all(|&b| b == GUARD));
            }
        }
    }
}
