//! The power stage: two full H-bridges on TIM1 (phase A) and TIM8 (phase B).
//!
//! embassy-stm32 enables the timer clocks (`timer::low_level::Timer`); the eight
//! output pins go on their alternate functions as its `PwmPin` / `ComplementaryPwmPin`
//! would put them (latch low, then push-pull, very high speed; the channel's AF number
//! from the same pin traits), through [`af_pin`]; the timers themselves are programmed
//! through the PAC (`embassy_stm32::pac`), because the HAL has no notion of motor
//! control:
//!
//! * centre-aligned mode 1, PSC = 0, ARR = [`board::PWM_ARR`] → 40 kHz, CCR preload;
//! * CH1/CH2 PWM mode 1 with complementary outputs and hardware dead time
//!   ([`board::DEAD_TIME_NS`], DTG in units of 1/170 MHz);
//! * break input 1 (pin, active low, filtered) → the timer clears MOE in hardware and
//!   the outputs go to their idle level (all switches off, OSSI = 1, OISx = 0);
//!   AOE = 0, so the break is **latched** until software re-arms ([`rearm`]);
//! * TIM1 CH4 (internal only) PWM mode 2, CCR4 = ARR − lead → OC4REF → TRGO2 → ADC
//!   injected trigger at the PWM centre;
//! * TIM1 TRGO = counter enable; TIM8 in trigger mode on ITR0 (= TIM1), so both
//!   bridges count in step;
//! * BDTR LOCK level 1 afterwards: dead time, break enable/polarity and idle levels
//!   cannot be changed by stray writes until the next reset.
//!
//! The bridges stay **off** (MOE = 0) after [`init`]; [`enable_outputs`] is called by
//! the drive logic when the power stage is to be energised.
//!
//! # Defined gate levels from the first instruction (RM0440, advanced-control timers
//! # TIM1/TIM8/TIM20: "Complementary outputs and dead-time insertion", "Using the
//! # break function", and the table "Output control bits for complementary tim_ocx and
//! # tim_ocxn channels with break feature", Table 265 in Rev 4)
//! 1. [`hold_gates_low`], the start-up task's first statement: the eight gate pins as
//!    GPIO push-pull outputs driven low (all switches off). From reset until then the
//!    pins are floating inputs: the gate-driver inputs need their pull-downs on the
//!    board for those few microseconds.
//! 2. [`init`]: the timers are clocked and fully configured — MOE = 0, OSSI = 1
//!    (idle: the timer keeps driving the outputs at their idle level), OSSR = 1,
//!    OISx = OISxN = 0 (idle level low), CCxE = CCxNE = 1 — *before* the pins are
//!    switched from GPIO-low to the timer's alternate function, so a gate pin is
//!    driven low at every moment: first by the GPIO, then by the timer's off state.
//!    (With OSSI = 0, MOE = 0 would release the outputs to Hi-Z; pins put on their AF
//!    before the timer is configured would float until it is.) The break pins are
//!    on their alternate function before the break is enabled (BKE), so an unconnected
//!    BKIN cannot fire a break at start.
//!
//! # Zero volts at every enable
//! CCR1/CCR2 are preloaded (loaded at the next update event). [`disable_outputs`]
//! writes the centred duty (ARR/2 on both legs: 0 V across the winding) after
//! clearing MOE, and [`enable_outputs`] writes it straight into the active compare
//! registers (preload off for the write, RM0440 "Output compare mode" / OCxPE: with
//! preload off a CCR write takes effect at once) before it sets MOE: the first PWM
//! period after an enable is 0 V whatever duties were left from before, and the
//! current loop's first duty takes over at the next update event.
use core::sync::atomic::{AtomicU8, Ordering};

use embassy_stm32::gpio::{AfType, AnyPin, Flex, OutputType, Pull, Speed};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::InterruptExt;
use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals;
use embassy_stm32::peripherals::{PA6, PA7, PA8, PA9, PB0, PC10, PC11, PC6, PC7, PD2, TIM1, TIM8};
use embassy_stm32::timer::low_level::Timer;
use embassy_stm32::timer::{
    AdvancedInstance4Channel, BkIn1, BreakInputPin, Ch1, Ch2, TimerChannel, TimerComplementaryPin,
    TimerPin,
};
use embassy_stm32::Peri;

use crate::board;

/// Peripherals of the power stage.
pub struct PowerStage<'d> {
    pub tim1: Peri<'d, TIM1>,
    pub a1h: Peri<'d, PA8>,
    pub a1l: Peri<'d, PA7>,
    pub a2h: Peri<'d, PA9>,
    pub a2l: Peri<'d, PB0>,
    pub bkin_a: Peri<'d, PA6>,
    pub tim8: Peri<'d, TIM8>,
    pub b1h: Peri<'d, PC6>,
    pub b1l: Peri<'d, PC10>,
    pub b2h: Peri<'d, PC7>,
    pub b2l: Peri<'d, PC11>,
    pub bkin_b: Peri<'d, PD2>,
}

/// Dead-time generator value: DTG[7] = 0 → DT = DTG × t_DTS, t_DTS = 1/170 MHz.
const DTG: u8 = {
    let ticks = (board::DEAD_TIME_NS as u64 * board::SYSCLK_HZ as u64).div_ceil(1_000_000_000);
    assert!(ticks < 128, "dead time needs the coarser DTG encodings");
    ticks as u8
};

/// Bit 0: TIM1 break seen, bit 1: TIM8 break seen (latched until [`rearm`]).
static BREAK_LATCH: AtomicU8 = AtomicU8::new(0);

/// A pin on alternate function `af` for the rest of the program (the driver is not
/// dropped: dropping would reset the pin). `low_first`: the output latch is set low
/// first, in the same critical section (what embassy-stm32's `PwmPin::new` and
/// `ComplementaryPwmPin::new` do). Used for every pin of the power stage and the
/// encoder (`hw::encoder`); not inlined, so they share one copy.
// Measured (cargo xtask size, LAN9252 image): without it, `hw::io::set_output`'s and
// `ticker`'s, the tasks' code grows ≈ +450 B flash.
#[inline(never)]
pub(crate) fn af_pin(pin: Peri<'static, AnyPin>, af: u8, ty: AfType, low_first: bool) {
    let mut f = Flex::new(pin);
    cortex_m::interrupt::free(|_| {
        if low_first {
            f.set_low();
        }
        f.set_as_af_unchecked(af, ty);
    });
    core::mem::forget(f);
}

/// A bridge output on its timer channel (as `PwmPin::new`: low, then alternate
/// function, push-pull, very high speed).
fn pwm_pin<T: AdvancedInstance4Channel, C: TimerChannel>(pin: Peri<'static, impl TimerPin<T, C>>) {
    let af = pin.af_num();
    af_pin(pin.into(), af, PWM_OUT, true);
}

/// A complementary bridge output (as `ComplementaryPwmPin::new`).
fn pwm_pin_n<T: AdvancedInstance4Channel, C: TimerChannel>(
    pin: Peri<'static, impl TimerComplementaryPin<T, C>>,
) {
    let af = pin.af_num();
    af_pin(pin.into(), af, PWM_OUT, true);
}

/// Output type of the bridge outputs.
const PWM_OUT: AfType = AfType::output(OutputType::PushPull, Speed::VeryHigh);

fn break_pin<T: AdvancedInstance4Channel, Pin: BreakInputPin<T, BkIn1>>(pin: Peri<'static, Pin>) {
    let af = pin.af_num();
    af_pin(pin.into(), af, AfType::input(Pull::Up), false);
}

/// The gate pins of both bridges (board pinout, [`board`]): (port, pin numbers).
const GATE_PINS: [(pac::gpio::Gpio, &[usize]); 3] = [
    (pac::GPIOA, &[7, 8, 9]),
    (pac::GPIOB, &[0]),
    (pac::GPIOC, &[6, 7, 10, 11]),
];

/// Drives the eight gate pins low as GPIO outputs (see the module docs, step 1).
/// Register access through the PAC: it runs before `embassy_stm32::init` hands out
/// the pins (embassy's GPIO set-up only enables the port clocks, it does not touch
/// the pins). Idempotent.
pub fn hold_gates_low() {
    use pac::gpio::vals::{Moder, Ot};
    pac::RCC.ahb2enr().modify(|w| {
        w.set_gpioaen(true);
        w.set_gpioben(true);
        w.set_gpiocen(true);
    });
    for (port, pins) in GATE_PINS {
        // Output latch low first, then push-pull, then output mode.
        port.bsrr().write(|w| {
            for &n in pins {
                w.set_br(n, true);
            }
        });
        port.otyper().modify(|w| {
            for &n in pins {
                w.set_ot(n, Ot::PUSH_PULL);
            }
        });
        port.moder().modify(|w| {
            for &n in pins {
                w.set_moder(n, Moder::OUTPUT);
            }
        });
    }
}

/// Configures both bridges (outputs off) and starts the counters. Call once, after
/// [`hold_gates_low`].
pub fn init(p: PowerStage<'static>) {
    // Timer clocks (enabled and reset) and the break pins first, then every timer
    // register (`configure`: the off state with defined idle levels, MOE = 0), and
    // only then the gate pins from GPIO-low to their alternate function (module docs).
    // `configure` programs every timer register the HAL's `ComplementaryPwm` would
    // set, with PSC = 0 and ARR = PWM_ARR as constants, and leaves MOE off throughout.
    hold_gates_low();
    let tim_a = Timer::new(p.tim1);
    let tim_b = Timer::new(p.tim8);
    break_pin::<TIM1, _>(p.bkin_a);
    break_pin::<TIM8, _>(p.bkin_b);
    // The timers and pins stay configured for the life of the program; the drivers
    // are not dropped (dropping would reset the pins and stop the timer clocks).
    core::mem::forget((tim_a, tim_b));

    let t1 = pac::TIM1;
    let t8 = pac::TIM8;
    for t in [t1, t8] {
        configure(t);
    }
    pwm_pin::<TIM1, Ch1>(p.a1h);
    pwm_pin_n::<TIM1, Ch1>(p.a1l);
    pwm_pin::<TIM1, Ch2>(p.a2h);
    pwm_pin_n::<TIM1, Ch2>(p.a2l);
    pwm_pin::<TIM8, Ch1>(p.b1h);
    pwm_pin_n::<TIM8, Ch1>(p.b1l);
    pwm_pin::<TIM8, Ch2>(p.b2h);
    pwm_pin_n::<TIM8, Ch2>(p.b2l);
    // TIM1: TRGO = enable (starts TIM8), TRGO2 = OC4REF (ADC injected trigger).
    t1.cr2().modify(|w| {
        w.set_mms(vals::Mms::ENABLE);
        w.set_mms2(vals::Mms2::COMPARE_OC4);
    });
    t1.smcr().modify(|w| w.set_msm(vals::Msm::SYNC));
    // TIM8: start on TIM1's trigger output (ITR0).
    t8.smcr().modify(|w| {
        w.set_ts(vals::Ts::ITR0);
        w.set_sms(vals::Sms::TRIGGER_MODE);
    });

    // Break interrupts: the hardware has already switched the bridge off; the ISR
    // switches the *other* bridge off too and latches the fault.
    for t in [t1, t8] {
        t.sr().write(|w| w.0 = 0);
        t.dier().modify(|w| w.set_bie(true));
    }
    // Above the current loop: a break in the middle of its step takes the other
    // bridge off at once.
    let level = crate::hw::lock::priority(firmware::irq_priority::BREAK);
    interrupt::TIM1_BRK_TIM15.set_priority(level);
    interrupt::TIM8_BRK.set_priority(level);
    // SAFETY: unmasking the break interrupts breaks no critical section: their
    // handlers (below) touch only the TIM1/TIM8 registers and atomics.
    unsafe {
        interrupt::TIM1_BRK_TIM15.enable();
        interrupt::TIM8_BRK.enable();
    }

    // Go: TIM8 follows TIM1's enable.
    t1.cr1().modify(|w| w.set_cen(true));
}

fn configure(t: pac::timer::TimAdv) {
    t.cr1().modify(|w| w.set_cen(false));
    t.bdtr().modify(|w| {
        w.set_moe(false);
        w.set_aoe(false);
        w.set_ossi(vals::Ossi::IDLE_LEVEL);
        w.set_ossr(vals::Ossr::IDLE_LEVEL);
        w.set_dtg(DTG);
        w.set_bke(0, true);
        w.set_bkp(0, vals::Bkp::ACTIVE_LOW);
        w.set_bkf(0, vals::FilterValue::FCK_INT_N4);
    });
    t.cr1().modify(|w| {
        w.set_cms(vals::Cms::CENTER_ALIGNED1);
        w.set_arpe(true);
        w.set_ckd(vals::Ckd::DIV1);
    });
    t.psc().write_value(0);
    t.arr().write(|w| w.set_arr(board::PWM_ARR));
    t.rcr().write(|w| w.set_rep(0));
    t.ccmr_output(0).modify(|w| {
        for ch in 0..2 {
            w.set_ocm(ch, vals::Ocm::PWM_MODE1);
            w.set_ocpe(ch, true);
        }
    });
    t.ccmr_output(1).modify(|w| {
        w.set_ocm(0, vals::Ocm::FROZEN);
        w.set_ocpe(0, true);
        w.set_ocm(1, vals::Ocm::PWM_MODE2);
        w.set_ocpe(1, true);
    });
    let half = board::PWM_ARR / 2;
    t.ccr(0).write(|w| w.set_ccr(half));
    t.ccr(1).write(|w| w.set_ccr(half));
    t.ccr(2).write(|w| w.set_ccr(0));
    t.ccr(3)
        .write(|w| w.set_ccr(board::PWM_ARR - board::ADC_TRIGGER_LEAD_TICKS));
    t.cr2().modify(|w| {
        for ch in 0..4 {
            w.set_ois(ch, false);
            w.set_oisn(ch, false);
        }
    });
    t.ccer().write(|w| {
        for ch in 0..2 {
            w.set_cce(ch, true);
            w.set_ccne(ch, true);
            w.set_ccp(ch, false);
            w.set_ccnp(ch, false);
        }
    });
    t.cnt().write(|w| w.set_cnt(0));
    // Load the preloaded ARR/CCR values now.
    t.egr().write(|w| w.set_ug(true));
    t.sr().write(|w| w.0 = 0);
    t.bdtr().modify(|w| w.set_lock(vals::Lock::LEVEL1));
}

/// Energises both bridges (MOE = 1) at zero volts (duties centred in the active
/// compare registers first, module docs), unless a break is latched or the drive is
/// halted (`hw::safety::HALT`: a panic or HardFault). Returns whether the outputs are
/// on. Called only by the current-loop interrupt, rarely (at an enable): out of line.
// Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path attributes
// the image grew 1184 B; the current-loop interrupt took it (+592 B there with
// `Scale::to_units`).
#[inline(never)]
pub fn enable_outputs() -> bool {
    let half = board::PWM_ARR / 2;
    for t in [pac::TIM1, pac::TIM8] {
        // MOE is 0 here, so writing the active registers cannot glitch an output.
        t.ccmr_output(0).modify(|w| {
            w.set_ocpe(0, false);
            w.set_ocpe(1, false);
        });
        t.ccr(0).write(|w| w.set_ccr(half));
        t.ccr(1).write(|w| w.set_ccr(half));
        t.ccmr_output(0).modify(|w| {
            w.set_ocpe(0, true);
            w.set_ocpe(1, true);
        });
    }
    // The break interrupts run above the current loop that calls this: the latch
    // check and the MOE writes are one step for them (PRIMASK for a few cycles; the
    // hardware break switches its bridge off regardless), so a break never finds the
    // other bridge switched on again after it. A HardFault in here never returns to
    // us: its handler sets the halted state and clears MOE.
    cortex_m::interrupt::free(|_| {
        if BREAK_LATCH.load(Ordering::Acquire) != 0 || crate::hw::safety::HALT.is_halted() {
            return false;
        }
        for t in [pac::TIM1, pac::TIM8] {
            t.bdtr().modify(|w| w.set_moe(true));
        }
        true
    })
}

/// Switches both bridges off (outputs to idle level: all switches off), then centres
/// the preloaded duties (0 V for whatever enables next). Safe to call from any
/// context, also before [`init`] (writes to an unclocked timer are ignored).
#[inline(always)]
pub fn disable_outputs() {
    for t in [pac::TIM1, pac::TIM8] {
        t.bdtr().modify(|w| w.set_moe(false));
    }
    let half = board::PWM_ARR / 2;
    for t in [pac::TIM1, pac::TIM8] {
        t.ccr(0).write(|w| w.set_ccr(half));
        t.ccr(1).write(|w| w.set_ccr(half));
    }
}

/// The latched break inputs (bit 0: bridge A / TIM1, bit 1: bridge B / TIM8).
pub fn break_latched() -> u8 {
    BREAK_LATCH.load(Ordering::Acquire)
}

/// Clears a latched break once both break inputs are inactive again. The outputs stay
/// off; the drive logic enables them explicitly. Returns `false` while a break input
/// is still active.
pub fn rearm() -> bool {
    for t in [pac::TIM1, pac::TIM8] {
        t.sr().write(|w| {
            w.0 = !0;
            w.set_bif(0, false);
        });
    }
    let still = pac::TIM1.sr().read().bif(0) || pac::TIM8.sr().read().bif(0);
    if still {
        return false;
    }
    BREAK_LATCH.store(0, Ordering::Release);
    for t in [pac::TIM1, pac::TIM8] {
        t.dier().modify(|w| w.set_bie(true));
    }
    true
}

/// Writes the four compare values (TIM1 CH1/CH2 = bridge A legs 1/2, TIM8 CH1/CH2 =
/// bridge B legs 1/2), as `foc::modulation::Duties` gives them. Takes effect at the
/// next update event (preload).
#[inline(always)]
pub fn set_compare(a1: u16, a2: u16, b1: u16, b2: u16) {
    pac::TIM1.ccr(0).write(|w| w.set_ccr(a1));
    pac::TIM1.ccr(1).write(|w| w.set_ccr(a2));
    pac::TIM8.ccr(0).write(|w| w.set_ccr(b1));
    pac::TIM8.ccr(1).write(|w| w.set_ccr(b2));
}

fn on_break(bit: u8, t: pac::timer::TimAdv) {
    // The hardware has already cleared this timer's MOE; take the other bridge down too.
    disable_outputs();
    BREAK_LATCH.fetch_or(bit, Ordering::AcqRel);
    // One interrupt per break event: the input may stay active; rearm() re-enables.
    t.dier().modify(|w| w.set_bie(false));
    t.sr().write(|w| {
        w.0 = !0;
        w.set_bif(0, false);
    });
    crate::hw::safety::raise_fault(firmware::faults::FaultKind::OverCurrent);
}

// Vector names checked by `#[interrupt]` against the device's interrupt enum.
#[interrupt]
fn TIM1_BRK_TIM15() {
    on_break(1, pac::TIM1);
}

#[interrupt]
fn TIM8_BRK() {
    on_break(2, pac::TIM8);
}
