//! The system clock: PLL → 170 MHz from the 24 MHz crystal (or the internal 16 MHz
//! HSI, [`board::CLOCK_FROM_HSE`]), range 1 boost mode, the ADC1/2 kernel clock, and
//! the priority of the DMA completion interrupts.
use embassy_stm32::interrupt::Priority;
use embassy_stm32::rcc;
use embassy_stm32::time::Hertz;

use crate::board;

/// The chip configuration for `embassy_stm32::init`: SYSCLK = [`board::SYSCLK_HZ`]
/// (24 MHz / 6 × 85 / 2 or 16 MHz / 4 × 85 / 2).
pub fn config() -> embassy_stm32::Config {
    use rcc::{Hse, HseMode, Pll, PllMul, PllPreDiv, PllRDiv, PllSource, Sysclk};
    let mut c = embassy_stm32::Config::default();
    c.rcc.pll = Some(if board::CLOCK_FROM_HSE {
        c.rcc.hse = Some(Hse {
            freq: Hertz(board::HSE_HZ),
            mode: HseMode::Oscillator,
        });
        Pll {
            source: PllSource::HSE,
            prediv: PllPreDiv::DIV6,
            mul: PllMul::MUL85,
            divp: None,
            divq: None,
            divr: Some(PllRDiv::DIV2),
        }
    } else {
        Pll {
            source: PllSource::HSI,
            prediv: PllPreDiv::DIV4,
            mul: PllMul::MUL85,
            divp: None,
            divq: None,
            divr: Some(PllRDiv::DIV2),
        }
    });
    c.rcc.sys = Sysclk::PLL1_R;
    // Range 1 boost mode: required above 150 MHz.
    c.rcc.boost = true;
    // ADC1/2 kernel clock = SYSCLK (the driver divides it by 4 → 42.5 MHz).
    c.rcc.mux.adc12sel = rcc::mux::Adcsel::SYS;
    // DMA completion must preempt the cyclic path that waits for it.
    c.bdma_interrupt_priority = Priority::P1;
    c
}
