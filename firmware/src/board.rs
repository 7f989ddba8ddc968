//! The reference board: one consistent pinout and the electrical constants of an
//! STM32G474RET6 (LQFP64) drive with a LAN9252 or ET1100 EtherCAT slave controller.
//!
//! We have no board yet; this table is the design the firmware is written for. Every
//! alternate function below is checked by the compiler: the drivers in `hw/` take the
//! pins through embassy-stm32's pin traits (`TimerPin<TIM1, Ch1>`, `MisoPin<SPI2>`,
//! `BreakInputPin<BkIn1>`, `AdcChannel<ADC1>` …), which exist only for the pins and
//! AF numbers the chip's LQFP64 package really has.
//!
//! ## Pinout (STM32G474RET6, LQFP64)
//!
//! | function | pin | AF / mode | notes |
//! |---|---|---|---|
//! | bridge A leg 1 high, TIM1_CH1 | PA8 | AF6 | bridge A = motor phase A |
//! | bridge A leg 1 low, TIM1_CH1N | PA7 | AF6 | complementary, dead time in hardware |
//! | bridge A leg 2 high, TIM1_CH2 | PA9 | AF6 | |
//! | bridge A leg 2 low, TIM1_CH2N | PB0 | AF6 | |
//! | bridge B leg 1 high, TIM8_CH1 | PC6 | AF4 | bridge B = motor phase B |
//! | bridge B leg 1 low, TIM8_CH1N | PC10 | AF4 | |
//! | bridge B leg 2 high, TIM8_CH2 | PC7 | AF4 | |
//! | bridge B leg 2 low, TIM8_CH2N | PC11 | AF4 | |
//! | /OC_A over-current, TIM1_BKIN | PA6 | AF6, active low | comparator of bridge A → TIM1 outputs off in hardware |
//! | /OC_B over-current, TIM8_BKIN | PD2 | AF4, active low | comparator of bridge B → TIM8 outputs off in hardware |
//! | ESC SPI SCK, SPI2_SCK | PB13 | AF5 | mode 3, 21.25 MHz |
//! | ESC SPI MISO, SPI2_MISO | PB14 | AF5 | |
//! | ESC SPI MOSI, SPI2_MOSI | PB15 | AF5 | |
//! | ESC SPI /CS | PB12 | GPIO out, idle high | software chip select |
//! | ESC IRQ (PDI interrupt) | PC2 | EXTI2, falling edge | active low, open drain on the ESC side, pull-up |
//! | ESC SYNC0 | PC3 | EXTI3, rising edge, pull-down | ESC drives it push-pull active high (SII 0x0151 = `firmware::identity::SYNC_LATCH_CONFIG`; the edge is `firmware::identity::SYNC0_ACTIVE_EDGE`, derived from it) |
//! | phase A current I_A | PA0 | ADC1_IN1 | injected rank 1 of ADC1 |
//! | phase B current I_B | PA1 | ADC2_IN2 | injected rank 1 of ADC2 (same instant as I_A) |
//! | DC-bus voltage V_BUS | PC0 | ADC1_IN6 | injected rank 2 of ADC1 |
//! | encoder A, TIM2_CH1 | PA15 | AF1 | TIM2 32-bit encoder mode (×4) |
//! | encoder B, TIM2_CH2 | PB3 | AF1 | (SWO is not used: defmt goes over RTT) |
//! | encoder Z, TIM2_CH3 | PB10 | AF1 | input capture latches the count at the index |
//! | IN1 (fast, touch probe 1), TIM2_CH4 | PB11 | AF1 | input capture (both edges) latches the encoder count |
//! | IN2 (fast, touch probe 2) | PB1 | EXTI1, both edges | software latch |
//! | IN3 | PC13 | input | opto, filtered in software |
//! | IN4 | PC14 | input | (LSE not used) |
//! | IN5 | PC15 | input | |
//! | OUT1 (alarm) | PA10 | GPIO out | open collector via driver transistor, high = on |
//! | OUT2 (ready / in position) | PA11 | GPIO out | (USB not used) |
//! | OUT3 (general) | PA12 | GPIO out | |
//! | BRAKE release | PB9 | GPIO out | high = brake released; low on reset and on any fault |
//! | green LED (power) | PC8 | GPIO out | high = on |
//! | red LED (fault) | PC9 | GPIO out | high = on |
//! | EtherCAT RUN LED | PB6 | GPIO out | high = on |
//! | EtherCAT ERR LED | PB7 | GPIO out | high = on |
//! | DIP row 0 (ID bank S1-S4) | PA4 | GPIO open drain | 4 × 4 diode matrix, rows driven low one at a time |
//! | DIP row 1 (ID bank S5-S8) | PA5 | GPIO open drain | |
//! | DIP row 2 (function bank SW1-SW4) | PB4 | GPIO open drain | |
//! | DIP row 3 (function bank SW5-SW8) | PB5 | GPIO open drain | |
//! | DIP column 0..3 | PC4, PC5, PB2, PC12 | input, pull-up | switch ON = column reads low while its row is low |
//! | TP1 timing test point | PC1 | GPIO out | high while the current-loop ISR runs (scope) |
//! | service port TX / RX, USART2 | PA2 / PA3 | AF7 | TTL RS-232, reserved (not initialised yet) |
//! | SWDIO / SWCLK | PA13 / PA14 | AF0 | debug probe (probe-rs), RTT for defmt |
//! | HSE crystal 24 MHz | PF0 / PF1 | OSC_IN / OSC_OUT | PLL → 170 MHz |
//! | BOOT0 | PB8 | 10 kΩ to GND | boot from main flash |
//! | NRST | PG10 | | ESC reset (RST#) is driven by the same supervisor |
//!
//! The two 8-way DIP banks are read through a 4 × 4 matrix (rows PA4/PA5/PB4/PB5,
//! columns PC4/PC5/PB2/PC12) because the LQFP64 package has no sixteen spare pins
//! left after the power stage, encoder, ESC and I/O; each switch has a series diode
//! (cathode to the row) so pressed switches in other rows cannot ghost.
//!
//! EXTI lines used: 1 (IN2), 2 (ESC IRQ), 3 (SYNC0) — each with its own vector.
//!
//! ## Timers
//! * TIM1 (bridge A) and TIM8 (bridge B): centre-aligned mode 1 at 40 kHz
//!   (ARR = 2125 at 170 MHz), complementary outputs, dead time [`DEAD_TIME_NS`],
//!   break input active low (latched: MOE stays off until software re-arms).
//!   TIM1 is the master (TRGO = enable); TIM8 starts on TIM1's enable (ITR0), so both
//!   bridges switch in phase.
//! * TIM1 CH4 (no pin) in PWM mode 2 with CCR4 = ARR − [`ADC_TRIGGER_LEAD_TICKS`]:
//!   OC4REF rises just before the counter peak → TRGO2 → injected conversions of ADC1
//!   and ADC2 at the PWM centre (the middle of the low-side conduction interval).
//! * TIM2: 32-bit quadrature encoder (×4), CH3 capture of Z, CH4 capture of IN1 (both edges).
//! * TIM5: embassy time driver. TIM15 is left alone because its vector is shared
//!   with TIM1's break interrupt.

/// The motor the current-loop gains and the servo's base gains are computed for
/// (the vendor parameters 0x2020/0x2021 take over once auto-tune or the user has set
/// a plausible inductance).
pub const MOTOR: firmware::motion::MotorConstants = firmware::motion::ECN57_20;
/// Phase resistance of [`MOTOR`] used while 0x2021 holds no plausible value, Ω
/// (datasheet class value of a NEMA 23 hybrid stepper; to be measured).
pub const MOTOR_R_OHM: f32 = 0.5;
/// Phase inductance of [`MOTOR`] used while 0x2021 holds no plausible value, H.
pub const MOTOR_L_H: f32 = 1.6e-3;

/// System clock (PLL from the 24 MHz HSE: 24 / 6 × 85 / 2), Hz.
pub const SYSCLK_HZ: u32 = 170_000_000;
/// HSE crystal, Hz.
pub const HSE_HZ: u32 = 24_000_000;
/// Clock source of the PLL: the 24 MHz crystal (`true`, 24 / 6 × 85 / 2) or the
/// internal 16 MHz HSI (`false`, 16 / 4 × 85 / 2) for boards without a crystal.
pub const CLOCK_FROM_HSE: bool = true;

/// PWM frequency of both bridges, Hz (the current-loop rate).
pub const PWM_HZ: u32 = 40_000;
/// Auto-reload of TIM1/TIM8 in centre-aligned mode: one period = 2 × ARR ticks.
pub const PWM_ARR: u16 = (SYSCLK_HZ / (2 * PWM_HZ)) as u16;
/// Dead time between a leg's high- and low-side switch, ns.
pub const DEAD_TIME_NS: u32 = 500;
/// Timer ticks the ADC trigger precedes the counter peak (≈ half the sampling
/// window would centre it exactly; trim on the board with a scope).
pub const ADC_TRIGGER_LEAD_TICKS: u16 = 1;

/// ESC SPI clock, Hz (170 MHz / 8; both LAN9252 and ET1100 accept it).
pub const ESC_SPI_HZ: u32 = 21_250_000;

/// ADC1 channel of the phase A current (PA0).
pub const ADC1_CH_IA: u8 = 1;
/// ADC1 channel of the bus voltage (PC0).
pub const ADC1_CH_VBUS: u8 = 6;
/// ADC2 channel of the phase B current (PA1).
pub const ADC2_CH_IB: u8 = 2;
/// JEXTSEL code of TIM1_TRGO2 for ADC1/ADC2 injected conversions (RM0440 ADC12
/// injected trigger table, jext_trg8).
pub const ADC12_JEXTSEL_TIM1_TRGO2: u8 = 8;

/// Analog front end of the reference design: bipolar current sensors at mid-supply
/// (3.3 V / 2) with 0.132 V/A (±12.5 A full scale), a 1:20 bus divider (66 V full
/// scale), 12-bit conversions.
pub const ANALOG: firmware::sampling::AnalogScale = firmware::sampling::AnalogScale {
    amps_per_count: 3.3 / 4096.0 / 0.132,
    volts_per_count: 3.3 / 4096.0 * 20.0,
    offset_nominal: 2048,
    // ±5 % of full scale for the sensor's zero and the reference.
    offset_tolerance: 205,
    // Peak-to-peak noise allowed at zero current: ±0.25 A.
    noise_tolerance: 82,
};
/// Samples averaged by the start-up offset check (at 40 kHz: 25.6 ms).
pub const OFFSET_SAMPLES: u32 = 1024;

/// First byte of the parameter record region (flash offset; the last 16 KiB of the
/// 512 KiB flash, outside every partition an update touches: `firmware::flash_layout`).
pub const PARAM_FLASH_OFFSET: u32 = firmware::flash_layout::RECORDS.offset;
/// Size of the record region: parameters and fault history, laid out as
/// `firmware::storage::region` says.
pub const PARAM_FLASH_SIZE: u32 = firmware::flash_layout::RECORDS.size;

/// Independent watchdog timeout, µs. It must cover the longest blocking thread-mode
/// operation: erasing one 4 KiB record slot = 2 pages × ≤ 40 ms (datasheet maximum;
/// typically ≈ 22 ms), while the supervisor task cannot run.
pub const WATCHDOG_TIMEOUT_US: u32 = 300_000;

/// Number of DIP matrix rows and columns.
pub const DIP_ROWS: usize = 4;
/// See [`DIP_ROWS`].
pub const DIP_COLS: usize = 4;

/// This board as the runtime sees it: the one place the board variant is chosen
/// (DIP layout, motor, loop periods).
pub const SPEC: firmware::runtime::BoardSpec = firmware::runtime::BoardSpec {
    dip: firmware::dip::Board::TwoBanks,
    motor: MOTOR,
    servo_ts: firmware::motion::SERVO_TS,
    pwm_ts: 1.0 / PWM_HZ as f32,
    pwm_arr: PWM_ARR,
};

use embassy_stm32::peripherals as pp;
use embassy_stm32::Peri;

/// The EtherCAT slave controller's pins: SPI2 with its DMA channels, chip select, the
/// IRQ and SYNC0 lines.
pub struct EscPins {
    pub spi: Peri<'static, pp::SPI2>,
    pub sck: Peri<'static, pp::PB13>,
    pub mosi: Peri<'static, pp::PB15>,
    pub miso: Peri<'static, pp::PB14>,
    pub tx_dma: Peri<'static, pp::DMA1_CH2>,
    pub rx_dma: Peri<'static, pp::DMA1_CH1>,
    pub cs: Peri<'static, pp::PB12>,
    pub irq: Peri<'static, pp::PC2>,
    pub irq_exti: Peri<'static, pp::EXTI2>,
    pub sync0: Peri<'static, pp::PC3>,
    pub sync0_exti: Peri<'static, pp::EXTI3>,
}

/// The chip's peripherals split by concern ([`split`]).
pub struct Resources {
    pub power: crate::hw::pwm::PowerStage<'static>,
    pub encoder: crate::hw::encoder::EncoderPins<'static>,
    pub io: crate::hw::io::IoPins<'static>,
    pub esc: EscPins,
    /// IN2 (touch probe 2) and its EXTI line.
    pub in2: (Peri<'static, pp::PB1>, Peri<'static, pp::EXTI1>),
    pub analog: crate::hw::adc::Analog<'static>,
    pub flash: Peri<'static, pp::FLASH>,
    pub iwdg: Peri<'static, pp::IWDG>,
}

/// The pinout: the one table of which pin does what on the reference board (embassy's
/// `assign_resources!` idea, written out). Every driver takes its pins from here.
pub fn split(p: embassy_stm32::Peripherals) -> Resources {
    Resources {
        power: crate::hw::pwm::PowerStage {
            tim1: p.TIM1,
            a1h: p.PA8,
            a1l: p.PA7,
            a2h: p.PA9,
            a2l: p.PB0,
            bkin_a: p.PA6,
            tim8: p.TIM8,
            b1h: p.PC6,
            b1l: p.PC10,
            b2h: p.PC7,
            b2l: p.PC11,
            bkin_b: p.PD2,
        },
        encoder: crate::hw::encoder::EncoderPins {
            tim2: p.TIM2,
            a: p.PA15,
            b: p.PB3,
            z: p.PB10,
            in1: p.PB11,
        },
        io: crate::hw::io::IoPins {
            dip_rows: (p.PA4, p.PA5, p.PB4, p.PB5),
            dip_cols: (p.PC4, p.PC5, p.PB2, p.PC12),
            in3: p.PC13,
            in4: p.PC14,
            in5: p.PC15,
            out1: p.PA10,
            out2: p.PA11,
            out3: p.PA12,
            brake: p.PB9,
            led_green: p.PC8,
            led_red: p.PC9,
            led_run: p.PB6,
            led_err: p.PB7,
            tp1: p.PC1,
        },
        esc: EscPins {
            spi: p.SPI2,
            sck: p.PB13,
            mosi: p.PB15,
            miso: p.PB14,
            tx_dma: p.DMA1_CH2,
            rx_dma: p.DMA1_CH1,
            cs: p.PB12,
            irq: p.PC2,
            irq_exti: p.EXTI2,
            sync0: p.PC3,
            sync0_exti: p.EXTI3,
        },
        in2: (p.PB1, p.EXTI1),
        analog: crate::hw::adc::Analog {
            adc1: p.ADC1,
            adc2: p.ADC2,
            ia: p.PA0,
            ib: p.PA1,
            vbus: p.PC0,
        },
        flash: p.FLASH,
        iwdg: p.IWDG,
    }
}
