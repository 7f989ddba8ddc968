//! Benchmarks of the `firmware` area. Each call to [`crate::bench`] is one row of BENCHMARKS.md.

use core::hint::black_box;
use firmware::cia402::{mode, Cia402, DriveFeedback};

pub fn run() {
    cia402();
}

/// CiA 402 rows: one control cycle of the drive profile from "outputs unpacked" to
/// "inputs packed" — the RxPDO values of the default CSP map stored through their
/// slots, the PDS / mode / supervision cycle with CSP interpolation, and the TxPDO
/// values of the default map read back. The servo step is not included (the lead adds
/// it in the composed drive).
fn cia402() {
    let mut d = Cia402::new();
    d.set_mode(mode::CSP);
    let mut fb = DriveFeedback::default();
    for w in [0x0000u16, 0x0006, 0x0007, 0x000F, 0x000F] {
        d.set_controlword(w);
        d.cycle(&fb, 0.001);
    }
    // Running at a steady speed: the axis follows the previous demand.
    let mut target = 0i32;
    for _ in 0..10 {
        target += 50;
        d.set_rx_raw(0, 0x000F);
        d.set_rx_raw(5, target as u32);
        let c = d.cycle(&fb, 0.001);
        fb.position = c.position;
        fb.velocity = c.velocity as i32;
    }
    target += 50;
    let fb = black_box(fb);
    let target = black_box(target);
    let out = crate::bench("CSP cycle (CiA 402 + interpolation)", || {
        // RxPDO 0x1600: 6040, 607A, 60B0, 60B8.
        d.set_rx_raw(0, 0x000F);
        d.set_rx_raw(5, target as u32);
        d.set_rx_raw(17, 0);
        d.set_rx_raw(19, 0);
        let c = d.cycle(&fb, 0.001);
        // TxPDO 0x1A00: 603F, 6041, 6061, 6064, 60B9, 60BA, 60FD.
        let mut acc = 0u32;
        for slot in [0u8, 1, 2, 5, 10, 11, 17] {
            acc = acc.wrapping_add(d.get_tx_raw(slot));
        }
        (c.position, acc)
    });
    black_box(out);
    black_box(&d);
}
