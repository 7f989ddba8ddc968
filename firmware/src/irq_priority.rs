//! The board's NVIC priorities, stated once (0 is the most urgent; the STM32G4
//! implements [`BITS`] priority bits, so a level `n` is the register value
//! `n << (8 - BITS)`, [`register`]). `hw` sets every interrupt from these and nothing
//! else; a host test (`firmware/tests/irq_priorities.rs`) checks the order below and
//! that no `hw` file names a priority of its own.
//!
//! | level | what | why there |
//! |---|---|---|
//! | [`BREAK`] | TIM1 / TIM8 break (`hw::pwm`) | the hardware has taken one bridge off; the other follows at once, even in the middle of a current-loop step |
//! | [`CURRENT_LOOP`] | `ADC1_2`, the current loop and the motion step (`hw::adc`, `hw::control`) | the 40 kHz control path; only the break preempts it |
//! | [`SPI_DMA`] | DMA completion of the ESC transfers | the cyclic path waits for it |
//! | [`CYCLIC`] | the cyclic interrupt executor (`UART4`), the EXTI wakers; the ceiling of the drive-state lock (`hw::lock`) | the EtherCAT cycle and the 1 ms tick |
//! | [`TIME_DRIVER`] | embassy's time driver (`TIM5`) | alarms of the executors |
//!
//! Thread mode (the embassy thread executor) is below every interrupt.

/// Priority bits the STM32G4's NVIC implements.
pub const BITS: u8 = 4;

/// TIM1_BRK_TIM15 and TIM8_BRK: above the current loop.
pub const BREAK: u8 = 0;
/// ADC1_2: the current loop.
pub const CURRENT_LOOP: u8 = 1;
/// The DMA completion interrupts of the ESC's SPI.
pub const SPI_DMA: u8 = 2;
/// The cyclic interrupt executor, the EXTI lines (ESC IRQ, SYNC0, IN2) and the lock
/// ceiling.
pub const CYCLIC: u8 = 3;
/// embassy's time driver.
pub const TIME_DRIVER: u8 = 4;

/// Every level, most urgent first, with its name (for the host test and the docs).
pub const ALL: [(&str, u8); 5] = [
    ("break", BREAK),
    ("current loop", CURRENT_LOOP),
    ("SPI DMA", SPI_DMA),
    ("cyclic", CYCLIC),
    ("time driver", TIME_DRIVER),
];

/// The NVIC register value (and BASEPRI value) of `level`.
pub const fn register(level: u8) -> u8 {
    level << (8 - BITS)
}

const _: () = {
    let mut i = 1;
    while i < ALL.len() {
        assert!(ALL[i - 1].1 < ALL[i].1, "levels strictly ordered");
        i += 1;
    }
    assert!(TIME_DRIVER < 1 << BITS);
};
