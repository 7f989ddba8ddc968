//! Board support for the STM32G474RE reference board (binary only; the library
//! never sees these modules). Each module owns one concern and is the one place to
//! review it:
//!
//! | module | what |
//! |---|---|
//! | [`pwm`] | TIM1/TIM8 centre-aligned complementary PWM, dead time, break input, ADC trigger |
//! | [`adc`] | ADC1/ADC2 injected conversions at the PWM centre and the current-loop ISR |
//! | [`control`] | the current loop + motion layer in the ADC interrupt, lock-free exchange with the cyclic path |
//! | [`encoder`] | TIM2 quadrature encoder with Z and IN1 hardware captures |
//! | [`esc`] | SPI2 with DMA to the EtherCAT slave controller, the ESC driver flavour |
//! | [`lock`] | the priority-ceiling lock of the drive state (cyclic path ↔ thread mode) |
//! | [`io`] | DIP matrix, digital inputs, outputs, brake, LEDs |
//! | [`flash`] | the parameter-record region of the internal flash (NorFlash) |
//! | [`safety`] | emergency stop, panic and HardFault handlers, fault number |
//! | [`stack`] | painted-stack high-water mark |
//! | `selftest` | the checks of the `selftest` build (first power-up), verdicts from `firmware::selftest` |
pub mod adc;
pub mod control;
pub mod encoder;
pub mod esc;
pub mod flash;
pub mod io;
pub mod lock;
pub mod pwm;
pub mod safety;
#[cfg(feature = "selftest")]
pub mod selftest;
pub mod stack;
