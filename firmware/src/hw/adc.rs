//! Phase currents and bus voltage: ADC1/ADC2 injected conversions triggered by TIM1
//! TRGO2 at the PWM centre, and the current-loop interrupt.
//!
//! * ADC1 injected: rank 1 = I_A (IN1, PA0), rank 2 = V_BUS (IN6, PC0).
//! * ADC2 injected: rank 1 = I_B (IN2, PA1) — converted at the same instant as I_A.
//! * Trigger: JEXTSEL = TIM1_TRGO2, rising edge; ADC clock = SYSCLK / 4 = 42.5 MHz
//!   (asynchronous clock from the RCC mux, at most one ADC clock of trigger jitter).
//! * Sampling: currents 24.5 cycles, bus voltage 47.5 cycles (divider impedance).
//!   Each conversion takes 12.5 ADC cycles (12 bits) after its sampling time. ADC1
//!   finishes last: I_A (24.5 + 12.5) then V_BUS (47.5 + 12.5) = 97 ADC cycles / 42.5 MHz
//!   ≈ 2.28 µs after the trigger ([`TIMING`]); ADC2's I_B ends after 37 cycles
//!   (≈ 0.87 µs). So only ADC1's end-of-injected-sequence (JEOS) interrupt is enabled:
//!   `ADC1_2` at `firmware::irq_priority::CURRENT_LOOP`, below only the break interrupts.
//!
//! Power-up, calibration (single-ended and differential) and enabling follow
//! embassy-stm32's `Adc::new` register by register (`power_up`); the injected
//! sequence and trigger are programmed through the PAC afterwards.
//!
//! Order (RM0440, ADC chapter, "ADC common control register (ADCx_CCR)": the clock
//! fields PRESC / CKMODE may be written only while every ADC of the pair is disabled
//! — ADEN = 0 and no calibration or conversion running): the ADC12 clock on (ADC1 and
//! ADC2 share it and its reset), then the common register written **once**, and only
//! then ADC1 and ADC2 powered up, calibrated and enabled.
//!
//! # Sampling instant against the PWM period
//! One PWM period is 2 × ARR = 4250 timer ticks = 25 µs (centre-aligned: the counter
//! peak, at 12.5 µs, is the PWM centre). Figures from the constants ([`TIMING`]):
//!
//! | event | time after the PWM centre |
//! |---|---|
//! | trigger (OC4REF rises at CNT = ARR − `ADC_TRIGGER_LEAD_TICKS` counting up) | −5.9 ns (1 tick early) |
//! | I_A (ADC1) and I_B (ADC2) sampling window, 24.5 ADC cycles at 42.5 MHz | ≈ 0 … 0.58 µs (+ trigger latency) |
//! | middle of that window: the instant the currents stand for | ≈ 0.28 µs (1.1 % of the period) |
//! | V_BUS window (ADC1 rank 2, after I_A's 12.5-cycle conversion) | ≈ 0.87 … 1.99 µs |
//! | ADC1 end of sequence → `ADC1_2` interrupt | ≈ 2.28 µs |
//!
//! The trigger latency of the asynchronous ADC clock (a few ADC cycles, RM0440 ADC
//! chapter, trigger latency) comes on top; TP1 on a scope shows the whole chain
//! (docs/board/bring-up.md, "Measuring interrupt timing"). The window lies at the centre of the
//! period, where the in-line phase current passes its period average (symmetric
//! ripple), and the conversions end far inside the half period (asserted below).
use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::gpio::Flex;
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::InterruptExt;
use embassy_stm32::pac;
use embassy_stm32::pac::adc::vals::{Adcaldif, Difsel, Exten, SampleTime};
use embassy_stm32::pac::adccommon::vals::Presc;
use embassy_stm32::peripherals::{ADC1, ADC2, PA0, PA1, PC0};
use embassy_stm32::{rcc, Peri};
use firmware::sampling::RawSample;

use crate::board;

/// Peripherals of the analog front end.
pub struct Analog<'d> {
    pub adc1: Peri<'d, ADC1>,
    pub adc2: Peri<'d, ADC2>,
    pub ia: Peri<'d, PA0>,
    pub ib: Peri<'d, PA1>,
    pub vbus: Peri<'d, PC0>,
}

/// Times ADC2 had not finished when ADC1's sequence ended (should stay 0).
static ADC2_LATE: AtomicU32 = AtomicU32::new(0);
/// Longest current-loop ISR body seen, CPU cycles (DWT CYCCNT; excludes the 12-cycle
/// exception entry and the exit).
static ISR_MAX_CYCLES: AtomicU32 = AtomicU32::new(0);

/// Starts the DWT cycle counter used by the ISR timing measurement.
pub fn enable_cycle_counter(
    mut dcb: cortex_m::peripheral::DCB,
    mut dwt: cortex_m::peripheral::DWT,
) {
    dcb.enable_trace();
    dwt.enable_cycle_counter();
}

/// Longest current-loop ISR seen so far, CPU cycles (0 until the counter runs).
pub fn isr_max_cycles() -> u32 {
    ISR_MAX_CYCLES.load(Ordering::Relaxed)
}

/// Calibrates and arms both ADCs for the PWM-centre trigger; enables the
/// current-loop interrupt. The PWM timers may already be running.
pub fn init(p: Analog<'static>) {
    // The clock (shared by ADC1/ADC2: enabled and reset once) and the prescaler, then
    // each ADC in turn, as the HAL's `Adc::new` would (see `power_up`).
    let Analog { adc1, adc2, .. } = p;
    // The peripherals are programmed through the PAC below.
    let _ = (adc1, adc2);
    // Clock of both ADCs (one shared enable and reset; embassy counts the users), then
    // the common register while both are still disabled (module docs), then each ADC.
    rcc::enable_and_reset::<ADC1>();
    rcc::enable_and_reset::<ADC2>();
    debug_assert!(!pac::ADC1.cr().read().aden() && !pac::ADC2.cr().read().aden());
    pac::ADC12_COMMON.ccr().modify(|w| w.set_presc(ADC_PRESC));
    power_up(pac::ADC1);
    power_up(pac::ADC2);
    let mut pins = [Flex::new(p.ia), Flex::new(p.ib), Flex::new(p.vbus)];
    for pin in pins.iter_mut() {
        pin.set_as_analog();
    }
    // Owned by the hardware from here on (dropping would reset them).
    core::mem::forget(pins);

    let a1 = pac::ADC1;
    let a2 = pac::ADC2;
    // Sample times: keep in step with SAMPLE_I_HALF / SAMPLE_VBUS_HALF (TIMING).
    a1.smpr().modify(|w| {
        w.set_smp(usize::from(board::ADC1_CH_IA), SampleTime::CYCLES24_5);
        w.set_smp(usize::from(board::ADC1_CH_VBUS), SampleTime::CYCLES47_5);
    });
    a2.smpr()
        .modify(|w| w.set_smp(usize::from(board::ADC2_CH_IB), SampleTime::CYCLES24_5));
    a1.jsqr().write(|w| {
        w.set_jl(1);
        w.set_jsq(0, board::ADC1_CH_IA);
        w.set_jsq(1, board::ADC1_CH_VBUS);
        w.set_jextsel(board::ADC12_JEXTSEL_TIM1_TRGO2);
        w.set_jexten(Exten::RISING_EDGE);
    });
    a2.jsqr().write(|w| {
        w.set_jl(0);
        w.set_jsq(0, board::ADC2_CH_IB);
        w.set_jextsel(board::ADC12_JEXTSEL_TIM1_TRGO2);
        w.set_jexten(Exten::RISING_EDGE);
    });
    for a in [a1, a2] {
        a.isr().write(|w| {
            w.set_jeos(true);
            w.set_jeoc(true);
            w.set_jqovf(true);
        });
    }
    a1.ier().modify(|w| w.set_jeosie(true));
    interrupt::ADC1_2.set_priority(crate::hw::lock::priority(
        firmware::irq_priority::CURRENT_LOOP,
    ));
    // SAFETY: unmasking ADC1_2 breaks no critical section: its handler (below) uses
    // only the ADC, timer and GPIO registers, atomics, and the state it owns or shares
    // through the lock-free exchange cells (`hw::control`).
    unsafe { interrupt::ADC1_2.enable() };
    for a in [a1, a2] {
        a.cr().modify(|w| w.set_jadstart(true));
    }
}

/// ADC prescaler: the ADC1/2 kernel clock is SYSCLK (`hw::clock::config`); the
/// HAL's rule — the smallest division keeping it at most 60 MHz — gives 4 (42.5 MHz).
const ADC_PRESC: Presc = Presc::DIV4;
const _: () = assert!((board::SYSCLK_HZ - 1) / 60_000_000 == 2);

/// Timing of the injected conversions against the PWM period (module docs), in ns
/// after the PWM centre (negative: before).
pub struct Timing {
    pub trigger: i32,
    pub current_window: (i32, i32),
    pub vbus_window: (i32, i32),
    pub end_of_sequence: i32,
}

/// ADC clock, Hz (SYSCLK / 4).
const ADC_HZ: u32 = board::SYSCLK_HZ / 4;
/// Time of `half_cycles` / 2 ADC clock cycles, ns (sample times end in .5 cycles).
const fn adc_half_cycles_ns(half_cycles: u32) -> i32 {
    (half_cycles as u64 * 1_000_000_000 / (2 * ADC_HZ as u64)) as i32
}
/// Sampling (24.5 / 47.5 cycles) and conversion (12.5 cycles, 12 bits) in half cycles.
const SAMPLE_I_HALF: u32 = 49;
const SAMPLE_VBUS_HALF: u32 = 95;
const CONVERT_HALF: u32 = 25;

/// The sampling instants of this configuration (without the trigger latency).
pub const TIMING: Timing = {
    let trigger =
        -((board::ADC_TRIGGER_LEAD_TICKS as u64 * 1_000_000_000 / board::SYSCLK_HZ as u64) as i32);
    let i_end = trigger + adc_half_cycles_ns(SAMPLE_I_HALF);
    let v_start = i_end + adc_half_cycles_ns(CONVERT_HALF);
    let v_end = v_start + adc_half_cycles_ns(SAMPLE_VBUS_HALF);
    Timing {
        trigger,
        current_window: (trigger, i_end),
        vbus_window: (v_start, v_end),
        end_of_sequence: v_end + adc_half_cycles_ns(CONVERT_HALF),
    }
};
/// Half a PWM period, ns.
const HALF_PERIOD_NS: i32 = (500_000_000 / board::PWM_HZ) as i32;
// The whole ADC1 sequence ends within a fifth of the half period after the centre
// (the current-loop ISR then has the rest of the period), and the currents are
// sampled within 0.6 µs of the centre.
const _: () = assert!(TIMING.end_of_sequence < HALF_PERIOD_NS / 5);
const _: () = assert!(TIMING.current_window.1 < 600 && TIMING.trigger <= 0);
const _: () = assert!(TIMING.trigger > -100);
const _: () = assert!(TIMING.vbus_window.0 > TIMING.current_window.1);

/// Powers up, calibrates (single-ended, then differential) and enables one ADC with
/// single conversions and no regular trigger: the register sequence of
/// embassy-stm32's `Adc::new` for the G4 with the default `AdcConfig`, one routine for
/// both ADCs (the clock is set up once, in [`init`]).
fn power_up(a: pac::adc::Adc) {
    // 20 µs (regulator start-up, between the calibrations and before enabling).
    let wait = || cortex_m::asm::delay(board::SYSCLK_HZ / 1_000_000 * 20);
    a.cr().modify(|w| {
        w.set_deeppwd(false);
        w.set_advregen(true);
    });
    wait();
    a.difsel().modify(|w| {
        for n in 0..18 {
            w.set_difsel(n, Difsel::SINGLE_ENDED);
        }
    });
    for dif in [Adcaldif::SINGLE_ENDED, Adcaldif::DIFFERENTIAL] {
        a.cr().modify(|w| w.set_adcaldif(dif));
        a.cr().modify(|w| w.set_adcal(true));
        while a.cr().read().adcal() {}
        wait();
    }
    while a.cr().read().addis() {}
    if !a.cr().read().aden() {
        a.isr().modify(|w| w.set_adrdy(true));
        a.cr().modify(|w| w.set_aden(true));
        while !a.isr().read().adrdy() {}
    }
    a.cfgr().modify(|w| {
        w.set_cont(false);
        w.set_exten(Exten::DISABLED);
    });
}

/// Times the ADC2 result was not ready at ADC1's end of sequence.
pub fn adc2_late_count() -> u32 {
    ADC2_LATE.load(Ordering::Relaxed)
}

/// The current-loop interrupt: ADC1 end of injected sequence, once per PWM period.
/// TP1 (PC1) is high while it runs, for a scope. The vector name is checked by
/// `#[interrupt]` against the device's interrupt enum.
#[interrupt]
fn ADC1_2() {
    let t0 = cortex_m::peripheral::DWT::cycle_count();
    crate::hw::io::tp1_high();
    let a1 = pac::ADC1;
    let a2 = pac::ADC2;
    if a1.isr().read().jeos() {
        if !a2.isr().read().jeos() {
            ADC2_LATE.fetch_add(1, Ordering::Relaxed);
        }
        let s = RawSample {
            ia: a1.jdr(0).read().jdata(),
            vbus: a1.jdr(1).read().jdata(),
            ib: a2.jdr(0).read().jdata(),
        };
        for a in [a1, a2] {
            a.isr().write(|w| {
                w.set_jeos(true);
                w.set_jeoc(true);
            });
        }
        crate::hw::control::on_sample(s);
    } else {
        // Not ours (e.g. a stray flag): clear everything injected so it cannot repeat.
        a1.isr().write(|w| {
            w.set_jeoc(true);
            w.set_jqovf(true);
        });
    }
    crate::hw::io::tp1_low();
    let dt = cortex_m::peripheral::DWT::cycle_count().wrapping_sub(t0);
    ISR_MAX_CYCLES.fetch_max(dt, Ordering::Relaxed);
}

/// The offsets of the current sensors with the bridges off (`None`: the check
/// failed: the current-sensing fault).
pub async fn offset_self_check(wdg: &mut crate::hw::safety::Watchdog) -> Option<(f32, f32)> {
    let mut cal = firmware::sampling::OffsetCalibrator::new(crate::board::OFFSET_SAMPLES);
    let mut last = crate::hw::control::SAMPLES.sequence();
    let mut idle = 0u32;
    // New samples arrive every 25 µs; give up after 10 ms without one.
    while !cal.is_complete() && idle < 200 {
        embassy_time::Timer::after_micros(50).await;
        match crate::hw::control::latest_sample() {
            Some((seq, s)) if seq != last => {
                last = seq;
                idle = 0;
                cal.add(s);
            }
            _ => idle += 1,
        }
        wdg.pet();
    }
    match cal.finish(&crate::board::ANALOG) {
        Ok(o) => {
            defmt::info!(
                "current-sensor offsets: A {=f32} B {=f32} counts",
                o.ia,
                o.ib
            );
            Some((o.ia, o.ib))
        }
        Err(e) => {
            crate::hw::safety::raise_fault(firmware::sampling::OffsetFault::KIND);
            defmt::error!("current-sensor self-check failed: {}", e);
            None
        }
    }
}
