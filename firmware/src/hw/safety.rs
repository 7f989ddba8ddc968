//! What happens when things go wrong.
//!
//! * Over-current: the break inputs switch the affected bridge off in hardware
//!   within the break filter time (≈ 24 ns + gate driver), independent of software;
//!   the break interrupt then switches the other bridge off and latches the fault
//!   (see `hw::pwm`).
//! * Panic and HardFault ([`fatal_stop`]): interrupts masked (PRIMASK) and the
//!   current-loop interrupt disabled in the NVIC, the sticky halted state entered
//!   ([`HALT`], `firmware::power_gate::Halt`: `hw::pwm::enable_outputs` refuses MOE
//!   from then on), [`emergency_stop`] — both bridges off (MOE = 0, duties centred),
//!   brake engaged, red LED on — then one defmt line; then the independent watchdog
//!   (not fed any more) resets the chip, or, when the fault came before the watchdog
//!   was started, a system reset is requested at once. The next start logs the reset
//!   cause. All of it goes straight to registers, so it works whatever state the
//!   drivers were in.
//! * NMI ([`NonMaskableInt`]): a double ECC error of the flash (FLASH_ECCR.ECCD)
//!   while reading the record region is a failed read of that record
//!   (`firmware::storage::ecc`): noted in [`ECC_RECORD_ERROR`] for the read in
//!   progress (`hw::flash::MappedRegion`), ECCD cleared, and the handler returns —
//!   the storage takes the record for corrupt and uses the other one. Any other NMI
//!   (an ECC error in program flash or the update partitions, a clock failure) goes
//!   the HardFault way: bridges off, halt, watchdog reset. Never the default
//!   handler's endless loop with the bridges as they were.
//! * Faults found by the board code (the current-sensor check at start-up,
//!   over-current) go to the
//!   drive's fault module (main.rs: `over_current`, `offset_self_check`), which
//!   drives the PDS fault, the emergency and the red LED. [`raise_fault`] /
//!   [`active_fault`] keep the most severe such fault since reset (status line).
use core::sync::atomic::{AtomicBool, AtomicU8, Ordering};

use cortex_m_rt::{exception, ExceptionFrame};

use embassy_stm32::pac;
use embassy_stm32::pac::iwdg::vals::{Key, Pr};
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::Peri;

use embassy_stm32::interrupt;
use embassy_stm32::interrupt::InterruptExt;
use firmware::faults::FaultKind;
use firmware::power_gate::{Halt, HaltExit};

use crate::board;
use crate::hw::{io, pwm};

/// The drive's halted state (see the module docs): set by a panic or HardFault,
/// cleared only by a reset.
pub static HALT: Halt = Halt::new();

/// The independent watchdog (IWDG, clocked by the 32 kHz LSI): prescaler and reload
/// for [`board::WATCHDOG_TIMEOUT_US`] worked out at compile time with the rule of
/// embassy-stm32's `IndependentWatchdog::new` (the smallest prescaler 4..256 whose
/// longest period covers the timeout), so the registers get the same values without
/// its run-time arithmetic.
pub struct Watchdog {
    _iwdg: Peri<'static, IWDG>,
}

const LSI_HZ: u32 = 32_000;

/// (PR, RL) for a timeout in µs.
const fn iwdg_setting(timeout_us: u32) -> (u8, u16) {
    let mut power = 2;
    while power <= 8 {
        let psc = 1u32 << power;
        // Longest period at this prescaler (reload 0xFFF), µs.
        if timeout_us <= 1_000_000 * 4096 / (LSI_HZ / psc) {
            let rl = (timeout_us / psc * LSI_HZ / 1_000_000) as u16 - 1;
            return ((power - 2) as u8, rl);
        }
        power += 1;
    }
    panic!("watchdog timeout longer than the IWDG allows");
}

/// 300 ms: PR = 0 (÷ 4), RL = 2399.
const IWDG_SETTING: (u8, u16) = iwdg_setting(board::WATCHDOG_TIMEOUT_US);

impl Watchdog {
    /// Programs prescaler and reload (the watchdog does not run yet: [`Watchdog::unleash`]).
    pub fn new(iwdg: Peri<'static, IWDG>) -> Self {
        let r = pac::IWDG;
        r.kr().write(|w| w.set_key(Key::ENABLE));
        r.pr().write(|w| w.set_pr(Pr::from_bits(IWDG_SETTING.0)));
        r.rlr().write(|w| w.set_rl(IWDG_SETTING.1));
        Watchdog { _iwdg: iwdg }
    }

    /// Starts the watchdog (it cannot be stopped again).
    pub fn unleash(&mut self) {
        pac::IWDG.kr().write(|w| w.set_key(Key::START));
        HALT.watchdog_started();
    }

    /// Reloads the counter.
    pub fn pet(&mut self) {
        pac::IWDG.kr().write(|w| w.set_key(Key::RESET));
    }
}

/// The most severe fault raised so far: its [`FaultKind`] number + 1 (0 = none).
/// Lower kind numbers are more severe (the fault table is ordered that way).
static ACTIVE_FAULT: AtomicU8 = AtomicU8::new(0);

/// Raises `kind`; keeps the most severe one.
pub fn raise_fault(kind: FaultKind) {
    let n = kind as u8 + 1;
    let _ = ACTIVE_FAULT.fetch_update(Ordering::AcqRel, Ordering::Acquire, |cur| {
        if cur == 0 || n < cur {
            Some(n)
        } else {
            None
        }
    });
}

/// Clears the fault the self-test's forced break raised (over-current from the break
/// interrupt): that break was the test's, not the board's.
#[cfg(feature = "selftest")]
pub fn clear_fault_after_selftest() {
    ACTIVE_FAULT.store(0, Ordering::Release);
}

/// The red-LED flash count of the most severe fault raised (0 = none).
pub fn active_fault() -> u8 {
    FaultKind::from_number(ACTIVE_FAULT.load(Ordering::Acquire).wrapping_sub(1))
        .and_then(FaultKind::flashes)
        .unwrap_or(0)
}

/// Bridges off, brake engaged, red LED on. Callable from any context.
#[inline(always)]
pub fn emergency_stop() {
    pwm::disable_outputs();
    io::emergency_indicators();
}

/// The first steps of a panic or HardFault: nothing may run or switch the bridges on
/// again. Interrupts masked (PRIMASK: every configurable priority, so the
/// current-loop interrupt too; defmt's critical sections restore the masked state),
/// the current-loop interrupt also disabled in the NVIC, the halted state entered
/// before the bridges go off (an enable racing with us sees it), the bridges off.
#[inline(always)]
fn fatal_stop() -> HaltExit {
    cortex_m::interrupt::disable();
    let exit = HALT.halt();
    emergency_stop();
    interrupt::ADC1_2.disable();
    exit
}

/// The end of a panic or HardFault: wait for the watchdog reset (or a debugger), or
/// reset now when no watchdog runs.
fn fatal_end(exit: HaltExit) -> ! {
    match exit {
        HaltExit::AwaitWatchdog => loop {
            cortex_m::asm::nop();
        },
        HaltExit::ResetNow => cortex_m::peripheral::SCB::sys_reset(),
    }
}

/// Set by the first panic: a panic inside the panic's own log line (defmt-rtt panics
/// on a nested log) must not log again, or the handler would re-enter itself until
/// the stack runs out (the static stack report, `cargo xtask size`, found that loop).
static PANICKED: AtomicBool = AtomicBool::new(false);

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    let exit = fatal_stop();
    if !PANICKED.swap(true, Ordering::Relaxed) {
        // Location and the message when it is a plain text: formatting the message's
        // arguments would pull `core::fmt` into the image for this one path.
        let (file, line) = info.location().map_or(("?", 0), |l| (l.file(), l.line()));
        match info.message().as_str() {
            Some(msg) => defmt::error!("panic at {=str}:{=u32}: {=str}", file, line, msg),
            None => defmt::error!("panic at {=str}:{=u32}", file, line),
        }
    }
    fatal_end(exit)
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    let exit = fatal_stop();
    defmt::error!(
        "HardFault: pc {=u32:#010x} lr {=u32:#010x}",
        ef.pc(),
        ef.lr()
    );
    fatal_end(exit)
}

/// Set by [`NonMaskableInt`] for a double ECC error in the record region; cleared
/// and checked around each record read (`hw::flash::MappedRegion`).
pub static ECC_RECORD_ERROR: AtomicBool = AtomicBool::new(false);

#[exception]
unsafe fn NonMaskableInt() {
    use firmware::storage::ecc::{ecc_offset, nmi_action, NmiAction};
    let eccr = pac::FLASH.eccr().read();
    // ADDR_ECC: the failing double word's byte address in its bank (RM0440,
    // FLASH_ECCR), BK_ECC its bank.
    let offset = ecc_offset(
        eccr.bk_ecc(),
        eccr.addr_ecc(),
        firmware::flash_layout::BANK_SIZE,
    );
    let records = board::PARAM_FLASH_OFFSET..board::PARAM_FLASH_OFFSET + board::PARAM_FLASH_SIZE;
    match nmi_action(eccr.eccd(), offset, records) {
        NmiAction::RecordReadError => {
            ECC_RECORD_ERROR.store(true, Ordering::Release);
            // ECCD is cleared by writing 1 (the NMI would come again at once).
            pac::FLASH.eccr().modify(|w| w.set_eccd(true));
        }
        NmiAction::Stop => {
            let exit = fatal_stop();
            defmt::error!(
                "NMI: flash ECC {=bool} at {=u32:#010x}",
                eccr.eccd(),
                offset
            );
            fatal_end(exit)
        }
    }
}

/// Why the chip last reset, from RCC_CSR (read once at start-up, then cleared). The
/// text is interned by defmt (`{=istr}`: in the ELF for the decoder, not in flash).
// The `intern!` expansions look alike to clippy; the texts differ.
#[allow(clippy::if_same_then_else)]
pub fn take_reset_cause() -> defmt::Str {
    let rcc = embassy_stm32::pac::RCC;
    let csr = rcc.csr().read();
    let cause = if csr.iwdgrstf() {
        defmt::intern!("independent watchdog")
    } else if csr.wwdgrstf() {
        defmt::intern!("window watchdog")
    } else if csr.sftrstf() {
        defmt::intern!("software")
    } else if csr.borrstf() {
        defmt::intern!("brown-out / power-on")
    } else if csr.pinrstf() {
        defmt::intern!("reset pin")
    } else if csr.lpwrrstf() {
        defmt::intern!("low-power")
    } else {
        defmt::intern!("unknown")
    };
    rcc.csr().modify(|w| w.set_rmvf(true));
    cause
}
