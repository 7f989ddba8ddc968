//! Board support for the STM32G474RE reference board (binary only; the library
//! never sees these modules). Each module owns one concern and is the one place to
//! review it:
//!
//! | module | what |
//! |---|---|
//! | [`pwm`] | TIM1/TIM8 centre-aligned complementary PWM, dead time, break input, ADC trigger |
//! | [`clock`] | the system clock (PLL → 170 MHz), the ADC kernel clock, the DMA interrupt priority |
//! | [`adc`] | ADC1/ADC2 injected conversions at the PWM centre and the current-loop ISR |
//! | [`control`] | the current loop + motion layer in the ADC interrupt, lock-free exchange with the cyclic path |
//! | [`encoder`] | TIM2 quadrature encoder with Z and IN1 hardware captures |
//! | [`esc`] | SPI2 with DMA to the EtherCAT slave controller, the ESC driver flavour |
//! | [`lock`] | the priority-ceiling lock of the drive state (cyclic path ↔ thread mode) |
//! | [`io`] | DIP matrix, digital inputs, outputs, brake, LEDs |
//! | [`flash`] | the internal flash: the parameter-record region and the firmware update's partitions |
//! | [`log`] | log texts of the board's errors, the parameter-slot report, event counters and the status line |
//! | [`safety`] | emergency stop, panic and HardFault handlers, fault number |
//! | [`stack`] | painted-stack high-water mark |
//! | `selftest` | the checks of the `selftest` build (first power-up), verdicts from `firmware::selftest` |
pub mod adc;
pub mod clock;
pub mod control;
pub mod encoder;
pub mod esc;
pub mod flash;
pub mod io;
pub mod lock;
pub mod log;
pub mod pwm;
pub mod safety;
#[cfg(feature = "selftest")]
pub mod selftest;
pub mod stack;
