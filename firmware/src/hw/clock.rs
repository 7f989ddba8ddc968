//! The system clock: PLL → 170 MHz from the 24 MHz crystal (or the internal 16 MHz
//! HSI, [`board::CLOCK_FROM_HSE`]), range 1 boost mode, the ADC1/2 kernel clock, and
//! the priority of the DMA completion interrupts.
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
    c.bdma_interrupt_priority = crate::hw::lock::priority(firmware::irq_priority::SPI_DMA);
    c
}

/// The chip's set-up after `embassy_stm32::init`, then the first log line.
pub fn start_chip() {
    // While a debugger halts the core: PWM counters stop with the bridges forced off
    // (as if MOE were cleared), and the watchdog pauses.
    embassy_stm32::pac::DBGMCU.apb2fzr().modify(|w| {
        w.set_tim1(true);
        w.set_tim8(true);
    });
    embassy_stm32::pac::DBGMCU
        .apb1lfzr()
        .modify(|w| w.set_iwdg(true));
    if let Some(core) = cortex_m::Peripherals::take() {
        crate::hw::adc::enable_cycle_counter(core.DCB, core.DWT);
    }
    // The time driver defaults to priority 0; keep it below the control path.
    embassy_stm32::interrupt::InterruptExt::set_priority(
        embassy_stm32::interrupt::TIM5,
        crate::hw::lock::priority(firmware::irq_priority::TIME_DRIVER),
    );
    defmt::info!(
        "ECS drive firmware {=str} ({=str}), reset cause: {=istr}",
        env!("CARGO_PKG_VERSION"),
        crate::hw::esc::ESC_NAME,
        crate::hw::safety::take_reset_cause()
    );
}
