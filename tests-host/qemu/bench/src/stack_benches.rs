//! Stack depth of the drive's library paths, measured by painting: the stack below the
//! caller is filled with a pattern, the path runs once, and the deepest word that no
//! longer holds the pattern gives the bytes it used (its own frames and everything it
//! called). Printed as `STACK <name> <bytes>`; `cargo xtask bench` puts the figures
//! into BENCHMARKS.md. Same build as the instruction counts (profile `bench-qemu`, LTO),
//! so the frames are those of optimised code; the board's release build (opt-level
//! "s") inlines differently, which is why the board also paints its stack and reports
//! the peak at run time (docs/board/bring-up.md, "Stack").
//!
//! The paths are the deepest the board runs in each context: the mailbox (SDO upload,
//! SDO information, download) with the whole drive dictionary behind it, the parameter
//! 'save' and the power-up load from flash, the CSP drive cycle, and the current-loop
//! interrupt's step (supervised current loop and motion step).

use core::hint::black_box;

use ecat_slave_stack::esm::{EsmHooks, EsmState};
use ecat_slave_stack::mailbox::MailboxServer;
use ecat_slave_stack::pdo::{self, PdoConfig};
use firmware::cia402::mode;
use firmware::current_supervisor::{CurrentSupervisor, SupervisorConfig};
use firmware::drive::{AxisState, Drive};
use firmware::identity::Variant;
use firmware::motion::Motion;
use firmware::storage::{RamFlash, Scope, Storage};
use foc::angle::Angle;
use foc::current_loop::{AdcSample, CurrentLoop, CurrentLoopConfig, Sense};
use foc::modulation::Modulator;

/// Bytes painted below the caller's stack pointer (far more than any path uses).
#[cfg(target_os = "none")]
const SPAN: usize = 24 * 1024;
#[cfg(target_os = "none")]
const PAINT: u32 = 0x5AC3_A53C;

/// Runs `f` once and prints the stack it used (`STACK <name> <bytes>`).
#[cfg(target_os = "none")]
#[inline(never)]
pub fn stack<R>(name: &str, f: impl FnOnce() -> R) -> R {
    let sp: usize;
    // SAFETY: reads the stack pointer.
    unsafe { core::arch::asm!("mov {}, sp", out(reg) sp, options(nomem, nostack)) };
    // Leave a margin for this function's own calls below `sp` while painting.
    let top = (sp - 64) & !3;
    let bottom = top - SPAN;
    let mut a = bottom;
    while a < top {
        // SAFETY: below the live stack (nothing there is in use; the image has no
        // interrupts), inside the 4 MiB RAM of mps2-an386.
        unsafe { core::ptr::write_volatile(a as *mut u32, PAINT) };
        a += 4;
    }
    let r = call(f);
    let mut a = bottom;
    // SAFETY: as above.
    while a < top && unsafe { core::ptr::read_volatile(a as *const u32) } == PAINT {
        a += 4;
    }
    let used = sp - a;
    if a == bottom {
        qemu_runner::println!("STACK {name} overflowed the {SPAN}-byte painted span");
    } else {
        qemu_runner::println!("STACK {name} {used}");
    }
    r
}

#[cfg(target_os = "none")]
#[inline(never)]
fn call<R>(f: impl FnOnce() -> R) -> R {
    black_box(f())
}

/// On the host: runs `f` (a smoke test; no measurement).
#[cfg(not(target_os = "none"))]
pub fn stack<R>(name: &str, f: impl FnOnce() -> R) -> R {
    println!("STACK {name} -");
    f()
}

/// A 128-byte SM0 buffer: mailbox header (length, type CoE) + `coe`.
fn sm0(counter: u8, coe: &[u8]) -> [u8; 128] {
    let mut f = [0u8; 128];
    let n = coe.len().min(122);
    f[0..2].copy_from_slice(&(n as u16).to_le_bytes());
    f[5] = 0x03 | (counter << 4);
    f[6..6 + n].copy_from_slice(&coe[..n]);
    f
}

fn enabled_drive() -> Drive {
    let mut d = Drive::new(Variant::HybridServo, 1);
    for (from, to) in [
        (EsmState::Init, EsmState::PreOp),
        (EsmState::PreOp, EsmState::SafeOp),
        (EsmState::SafeOp, EsmState::Op),
    ] {
        d.on_state_change(from, to);
    }
    d
}

pub fn run() {
    start_up();
    mailbox();
    storage();
    csp_cycle();
    current_interrupt();
}

/// An ESC that answers nothing (the constructors do not touch it).
struct NoEsc;

impl ecat_slave_stack::EscAccess for NoEsc {
    fn read(&mut self, _: u16, _: &mut [u8]) -> Result<(), ecat_slave_stack::EscError> {
        Err(ecat_slave_stack::EscError::Bus)
    }
    fn write(&mut self, _: u16, _: &[u8]) -> Result<(), ecat_slave_stack::EscError> {
        Err(ecat_slave_stack::EscError::Bus)
    }
}

/// The board's start-up builds the drive and the slave runtime by value and moves
/// them into their static slots: the temporaries are on the stack at that moment.
fn start_up() {
    use core::mem::MaybeUninit;
    use ecat_slave_stack::slave::{Slave, SlaveConfig};
    static mut DRIVE: MaybeUninit<Drive> = MaybeUninit::uninit();
    static mut SLAVE: MaybeUninit<Slave<NoEsc>> = MaybeUninit::uninit();
    stack(
        "start-up: Drive built and moved into its static slot",
        || {
            let d = Drive::new(Variant::HybridServo, 1);
            // SAFETY: written once here, never read concurrently (single-threaded image).
            unsafe { (*core::ptr::addr_of_mut!(DRIVE)).write(d) };
        },
    );
    stack(
        "start-up: slave runtime built and moved into its static slot",
        || {
            let s = Slave::new(
                NoEsc,
                SlaveConfig {
                    pdo_defaults: firmware::pdo_defaults::PDO_DEFAULTS,
                    ..SlaveConfig::default()
                },
            );
            // SAFETY: as above.
            unsafe { (*core::ptr::addr_of_mut!(SLAVE)).write(s) };
        },
    );
}

fn mailbox() {
    let mut d = Drive::new(Variant::HybridServo, 1);
    let mut srv = MailboxServer::new(128);
    let mut out = [0u8; 128];
    let mut request = |name: &str, counter: u8, coe: &[u8], d: &mut Drive| {
        let frame = sm0(counter, coe);
        let n = stack(name, || {
            srv.on_request(&frame, d, EsmState::PreOp, 0);
            srv.next_output(&mut out, 0)
        });
        // The measured path is the answering one, not an abort: an SDO response
        // (service 3, not command 0x80) or an SDO information response (service 8,
        // not opcode 7).
        let service = out[7] >> 4;
        assert!(n > 8, "{name}: no answer");
        assert!(
            (service == 3 && out[8] != 0x80) || (service == 8 && out[8] & 0x7F != 0x07),
            "{name}: answered {:02x?}",
            &out[..16]
        );
    };
    // Normal upload of the device name (0x1008, a string).
    request(
        "mailbox: SDO upload 0x1008 (string)",
        1,
        &[0x00, 0x20, 0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0],
        &mut d,
    );
    // Complete access upload of the identity record 0x1018.
    request(
        "mailbox: SDO upload 0x1018 complete access",
        2,
        &[0x00, 0x20, 0x50, 0x18, 0x10, 0x00, 0, 0, 0, 0],
        &mut d,
    );
    // Expedited download of a vendor parameter (0x2000 peak current).
    request(
        "mailbox: SDO download 0x2000",
        3,
        &[0x00, 0x20, 0x2B, 0x00, 0x20, 0x00, 0xD0, 0x07, 0, 0],
        &mut d,
    );
    // SDO information: OD list (all objects), then an entry description with all
    // value info.
    request(
        "mailbox: SDO info OD list",
        4,
        &[0x00, 0x80, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00],
        &mut d,
    );
    request(
        "mailbox: SDO info entry description",
        5,
        &[0x00, 0x80, 0x05, 0x00, 0x00, 0x00, 0x00, 0x20, 0x00, 0x7F],
        &mut d,
    );
    black_box(out);
}

fn storage() {
    static ST: Storage = Storage::new(0, 4096);
    let mut flash = RamFlash::<8192>::new();
    let mut d = Drive::new(Variant::HybridServo, 1);
    let saved = stack("parameter save (all objects, RAM flash)", || {
        ST.save(&mut flash, &mut d, Scope::All).is_ok()
    });
    assert!(saved, "the measured save must succeed");
    let mut d = Drive::new(Variant::HybridServo, 1);
    stack("parameter load at power-up (RAM flash)", || {
        ST.load(&mut flash, &mut d)
    });
}

fn csp_cycle() {
    let mut d = enabled_drive();
    let cfg = PdoConfig::new(firmware::pdo_defaults::PDO_DEFAULTS);
    let Ok(plan) = cfg.compile(&d, firmware::dictionary::OBJECTS) else {
        return;
    };
    d.cia402.set_mode(mode::CSP);
    let mcfg = crate::setup::servo_config(&d.params);
    let mut m = Motion::new(mcfg);
    let mut inputs = [0u8; 64];
    let tx_len = (plan.tx.bytes() as usize).min(inputs.len());
    let fb = crate::setup::AT_REST;
    let mut target = 0i32;
    let mut now_us = 0u64;
    for cw in [0x0000u16, 0x0006, 0x0007, 0x000F, 0x000F, 0x000F] {
        now_us += 1000;
        let mut out = [0u8; 12];
        out[0..2].copy_from_slice(&cw.to_le_bytes());
        target += 50;
        out[2..6].copy_from_slice(&target.to_le_bytes());
        let out = black_box(out);
        stack("CSP drive cycle (unpack, Drive, motion, pack)", || {
            pdo::unpack(&plan.rx, &out, &mut d);
            let cmd = d.run_cycle(0.001);
            m.set_command(&cmd, 0.001);
            let r = m.step(&fb);
            pdo::pack(&plan.tx, &d, &mut inputs[..tx_len]);
            d.set_axis(AxisState {
                position: target,
                ..AxisState::default()
            });
            d.tick(now_us, 0);
            r
        });
    }
    black_box(inputs);
}

fn current_interrupt() {
    const TS: f32 = 25e-6;
    let wc = 2.0 * core::f32::consts::PI / (20.0 * TS);
    let (kp, ki) = CurrentLoopConfig::gains_for(0.4, 1.8e-3, wc);
    let mut cl = CurrentLoop::new(CurrentLoopConfig {
        ts: TS,
        kp,
        ki,
        inductance: 1.8e-3,
        ke: 0.283,
        latency: 1.5,
        sense: Sense {
            amps_per_count: 20.0 / 4096.0,
            offset_a: 2048.0,
            offset_b: 2048.0,
            volts_per_count: 60.0 / 4096.0,
        },
        modulator: Modulator::new(2125),
    });
    let p = firmware::params::Params::new(Variant::HybridServo);
    let mut sup = CurrentSupervisor::new(SupervisorConfig::from_params(&p, TS, 2125));
    let d = Drive::new(Variant::HybridServo, 1);
    let mcfg = crate::setup::servo_config(&d.params);
    let mut m = Motion::new(mcfg);
    let fb = crate::setup::AT_REST;
    let adc = black_box(AdcSample {
        ia: 2100,
        ib: 1990,
        vbus: 3277,
    });
    stack(
        "current-loop interrupt (motion step + supervised current step)",
        || {
            let r = m.step(&fb);
            cl.iq_ref = r.iq;
            sup.run_step(&mut cl, &adc, Angle(0x1234_5678), 900.0)
        },
    );
    sup.permit_tune(true);
    stack("current-loop interrupt (auto-tune step)", || {
        sup.tune_step(&mut cl, &adc)
    });
}
