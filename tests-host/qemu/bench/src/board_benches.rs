//! Board control-path rows of issue 10 (`firmware::commutation`, `firmware::latch`):
//! the servo step through the commutation wrapper once aligned (to compare with the
//! bare "servo step (motion layer)" row), one step of the power-up alignment in its
//! sweep, and the conversion of a latched encoder count into command units (each
//! touch-probe / index edge in the current-loop interrupt); the board's small `memcpy`
//! / `memset` (`firmware::mem`) beside `compiler_builtins`' (what this image and the
//! host use) on the same copies.
use core::hint::black_box;

use firmware::commutation::{CommutatedMotion, Commutation};
use firmware::identity::Variant;
use firmware::latch::units_at_count;
use firmware::params::Params;
use foc::angle::Angle;

pub fn run() {
    control_rows();
    mem_rows();
}

/// The commutated servo step, the alignment step and the latch conversion.
fn control_rows() {
    let p = Params::new(Variant::HybridServo);
    let cfg = crate::setup::servo_config(&p);
    let mut cmd = crate::setup::moving_command();
    let mut fb = crate::setup::AT_REST;

    // Aligned, running at one revolution per second (as the motion-layer row).
    let mut m = CommutatedMotion::new_aligned(cfg, true);
    for k in 0..20 {
        cmd.position = 50 * k;
        m.set_command(&cmd, 0.001);
        for _ in 0..10 {
            let (d, f) = m.motion().demand_counts();
            fb.position = d;
            fb.velocity = 4000.0 + f;
            m.step(&fb, Angle::ZERO);
        }
    }
    cmd.position += 50;
    m.set_command(&cmd, 0.001);
    for _ in 0..4 {
        m.step(&fb, Angle::ZERO);
    }
    let fbb = black_box(fb);
    let out = crate::bench("servo step (commutated motion layer, aligned)", || {
        m.step(&fbb, Angle::ZERO)
    });
    black_box(out);

    // Alignment with the wiggle, in its forward sweep (the encoder follows).
    let mut a = CommutatedMotion::new(cfg, true);
    a.set_command(&cmd, 0.001);
    let mut raw = Angle::ZERO;
    let mut n = 0u32;
    // Ramp (0.05 s) + settle (0.2 s) + a little of the sweep.
    while n < 2600 && a.state() != Commutation::Failed {
        let s = a.step(&fb, raw);
        if let firmware::motion::Frame::Command { angle, .. } = s.reference.frame {
            raw = angle;
        }
        n += 1;
    }
    let r = black_box(raw);
    let out = crate::bench("commutation alignment step (sweep)", || a.step(&fbb, r));
    black_box(out);

    // A touch-probe latch 37 counts back → command units.
    let c = black_box(cfg);
    let out = crate::bench("latched count -> units (probe / index edge)", || {
        units_at_count(&c, black_box(123_456), black_box(37))
    });
    black_box(out);
}

/// The board's `memcpy` / `memset` beside `compiler_builtins`'.
fn mem_rows() {
    // The board's memcpy / memset against compiler_builtins' (`core::ptr`), on a
    // word-aligned 256-byte copy (a struct exchange of the current-loop interrupt is
    // of this kind), a 64-byte copy one byte off alignment (process data at an odd
    // offset) and a 256-byte clear.
    #[repr(align(8))]
    struct Block([u8; 260]);
    let src = black_box(Block([0x5A; 260]));
    let mut dst = Block([0; 260]);
    let (s, d) = (src.0.as_ptr(), dst.0.as_mut_ptr());
    // Every row: `src` and `dst` are distinct 260-byte buffers, and every copy or fill
    // stays inside them (offset 1 + 64 bytes, 256 bytes from the start).
    crate::bench("board memcpy 256 B aligned (firmware::mem)", || {
        // SAFETY: inside `src` / `dst`, which do not overlap (see above).
        unsafe { firmware::mem::copy(d, s, black_box(256)) }
    });
    crate::bench("compiler_builtins memcpy 256 B aligned", || {
        // SAFETY: inside `src` / `dst`, which do not overlap (see above).
        unsafe { core::ptr::copy_nonoverlapping(s, d, black_box(256)) }
    });
    crate::bench("board memcpy 64 B unaligned (firmware::mem)", || {
        // SAFETY: inside `src` / `dst`, which do not overlap (see above).
        unsafe { firmware::mem::copy(d.add(1), s, black_box(64)) }
    });
    crate::bench("compiler_builtins memcpy 64 B unaligned", || {
        // SAFETY: inside `src` / `dst`, which do not overlap (see above).
        unsafe { core::ptr::copy_nonoverlapping(s, d.add(1), black_box(64)) }
    });
    crate::bench("board memset 256 B (firmware::mem)", || {
        // SAFETY: 256 bytes inside `dst` (see above).
        unsafe { firmware::mem::fill(d, 0, black_box(256)) }
    });
    crate::bench("compiler_builtins memset 256 B", || {
        // SAFETY: 256 bytes inside `dst` (see above).
        unsafe { core::ptr::write_bytes(d, 0, black_box(256)) }
    });
    black_box(&dst);
}
