//! Incremental encoder on TIM2 (32-bit): quadrature ×4 on CH1/CH2, the Z index
//! captured on CH3 (rising edge) and the fast input IN1 (touch probe 1) captured on
//! CH4 (both edges).
//!
//! The captures are exact hardware latches of the counter at the edge — no interrupt
//! latency in the measured position. The current-loop interrupt polls the capture
//! flags ([`take_index_capture`], [`take_probe1_capture`]) at the servo rate; IN1's
//! edge direction is the pin level read with the capture (an opto input pulls its
//! pin low while active): the capture register and the pin both hold the state after
//! the latest edge, so of two edges within one servo period (100 µs) the later one is
//! reported, with its right direction. The counter wraps at 2³², which `foc`'s
//! wrapping position arithmetic expects.
use embassy_stm32::gpio::{AfType, Pull};
use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals;
use embassy_stm32::peripherals::{PA15, PB10, PB11, PB3, TIM2};
use embassy_stm32::timer::qei::{Config as QeiConfig, Qei, QeiMode};
use embassy_stm32::timer::{Ch3, Ch4, TimerPin};
use embassy_stm32::Peri;

/// Peripherals of the encoder interface.
pub struct EncoderPins<'d> {
    pub tim2: Peri<'d, TIM2>,
    pub a: Peri<'d, PA15>,
    pub b: Peri<'d, PB3>,
    pub z: Peri<'d, PB10>,
    pub in1: Peri<'d, PB11>,
}

/// Handle to the running encoder timer (register access only; `Copy`).
#[derive(Clone, Copy)]
pub struct Encoder {
    _private: (),
}

fn capture_pin<C: embassy_stm32::timer::TimerChannel, Pin: TimerPin<TIM2, C>>(
    pin: Peri<'static, Pin>,
) {
    let af = pin.af_num();
    crate::hw::pwm::af_pin(pin.into(), af, AfType::input(Pull::None), false);
}

/// Starts the encoder counter and the two captures.
pub fn init(p: EncoderPins<'static>) -> Encoder {
    let cfg = QeiConfig {
        ch1_pull: Pull::Up,
        ch2_pull: Pull::Up,
        mode: QeiMode::Mode3,
        ..Default::default()
    };
    let qei = Qei::new(p.tim2, p.a, p.b, cfg);
    capture_pin::<Ch3, _>(p.z);
    capture_pin::<Ch4, _>(p.in1);
    core::mem::forget(qei);

    let t = pac::TIM2;
    t.cr1().modify(|w| w.set_cen(false));
    t.arr().write_value(u32::MAX);
    // Input filter on A/B: f_DTS/2, N = 6 (≈ 70 ns) against edge ringing.
    t.ccmr_input(0).modify(|w| {
        w.set_icf(0, vals::FilterValue::FDTS_DIV2_N6);
        w.set_icf(1, vals::FilterValue::FDTS_DIV2_N6);
    });
    // CH3 ← TI3 (Z), CH4 ← TI4 (IN1): direct mapping (CCxS = 01).
    t.ccmr_input(1).modify(|w| {
        w.set_ccs(0, vals::CcmrInputCcs::TI4);
        w.set_ccs(1, vals::CcmrInputCcs::TI4);
        w.set_icf(0, vals::FilterValue::FDTS_DIV2_N6);
        w.set_icf(1, vals::FilterValue::FDTS_DIV2_N6);
    });
    // CH3: rising edges of Z; CH4: both edges of IN1 (CC4P = CC4NP = 1).
    t.ccer().modify(|w| {
        w.set_cce(2, true);
        w.set_ccp(2, false);
        w.set_ccnp(2, false);
        w.set_cce(3, true);
        w.set_ccp(3, true);
        w.set_ccnp(3, true);
    });
    t.cnt().write_value(0);
    t.sr().write(|w| w.0 = 0);
    t.cr1().modify(|w| w.set_cen(true));
    Encoder { _private: () }
}

/// The raw counter, for the current-loop interrupt (no handle needed).
#[inline(always)]
pub fn raw_count() -> u32 {
    pac::TIM2.cnt().read()
}

/// The count latched at the last Z rising edge, once per edge (for the current-loop
/// interrupt, which owns the index capture; see `hw::control`).
#[inline(always)]
pub fn take_index_capture() -> Option<u32> {
    Encoder::capture(2)
}

/// IN1 (PB11) is at its active level (pin low).
#[inline(always)]
fn in1_active() -> bool {
    pac::GPIOB.idr().read().idr(11) == pac::gpio::vals::Idr::LOW
}

/// The count latched at the last IN1 edge (touch probe 1) and whether the input
/// became active there (pin low), once per edge (for the current-loop interrupt,
/// which owns this capture). When another edge came while reading, the newer one is
/// taken (at most three tries; of several edges within one servo period only the last
/// is seen).
#[inline(always)]
pub fn take_probe1_capture() -> Option<(u32, bool)> {
    let mut count = Encoder::capture(3)?;
    let mut active = in1_active();
    for _ in 0..2 {
        // A capture after the level was read: its level is the one that counts.
        match Encoder::capture(3) {
            Some(n) => {
                count = n;
                active = in1_active();
            }
            None => break,
        }
    }
    // An over-capture flag (edges lost in between) is left alone: clearing it by a
    // read-modify-write of SR could also clear a Z capture flag set meanwhile.
    Some((count, active))
}

impl Encoder {
    /// Counter value (4 counts per line), wrapping.
    #[inline(always)]
    pub fn position(&self) -> u32 {
        pac::TIM2.cnt().read()
    }

    fn capture(ch: usize) -> Option<u32> {
        let t = pac::TIM2;
        if t.sr().read().ccif(ch) {
            // Reading CCRx clears CCxIF.
            Some(t.ccr(ch).read())
        } else {
            None
        }
    }
}
