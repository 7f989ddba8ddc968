//! Digital I/O of the reference board: the two DIP banks (4 × 4 diode matrix), the
//! five opto inputs, three outputs, the brake, the four LEDs and the timing test
//! point TP1.
use embassy_stm32::gpio::{AnyPin, Input, Level, Output, OutputOpenDrain, Pull, Speed};
use embassy_stm32::pac;
use embassy_stm32::peripherals::{
    PA10, PA11, PA12, PA4, PA5, PB2, PB4, PB5, PB6, PB7, PB9, PC1, PC12, PC13, PC14, PC15, PC4,
    PC5, PC8, PC9,
};
use embassy_stm32::Peri;

use crate::board;

/// Pins of the digital I/O.
pub struct IoPins<'d> {
    pub dip_rows: (Peri<'d, PA4>, Peri<'d, PA5>, Peri<'d, PB4>, Peri<'d, PB5>),
    pub dip_cols: (Peri<'d, PC4>, Peri<'d, PC5>, Peri<'d, PB2>, Peri<'d, PC12>),
    pub in3: Peri<'d, PC13>,
    pub in4: Peri<'d, PC14>,
    pub in5: Peri<'d, PC15>,
    pub out1: Peri<'d, PA10>,
    pub out2: Peri<'d, PA11>,
    pub out3: Peri<'d, PA12>,
    pub brake: Peri<'d, PB9>,
    pub led_green: Peri<'d, PC8>,
    pub led_red: Peri<'d, PC9>,
    pub led_run: Peri<'d, PB6>,
    pub led_err: Peri<'d, PB7>,
    pub tp1: Peri<'d, PC1>,
}

/// The four LEDs.
pub struct Leds<'d> {
    pub green: Output<'d>,
    pub red: Output<'d>,
    pub run: Output<'d>,
    pub err: Output<'d>,
}

/// Inputs IN3..IN5 (IN1 and IN2 are read from the input data register: IN1's pin
/// belongs to the encoder timer's capture, IN2's to the touch-probe EXTI) and the
/// outputs.
pub struct Ports<'d> {
    in3_5: [Input<'d>; 3],
    outputs: [Output<'d>; 3],
    /// Keeps PB9 configured as an output (low: engaged); the current-loop interrupt
    /// writes it through the register ([`set_brake_released`]), the self-test reads
    /// it back.
    #[cfg_attr(not(feature = "selftest"), allow(dead_code))]
    brake: Output<'d>,
}

/// The DIP matrix.
pub struct Dip<'d> {
    rows: [OutputOpenDrain<'d>; board::DIP_ROWS],
    cols: [Input<'d>; board::DIP_COLS],
}

/// Both DIP banks as read at power-up: bit i = switch i+1 is ON.
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub struct DipBanks {
    /// ID bank (E5 S1..S8).
    pub id: u8,
    /// Function bank (EST-584 SW1..SW8).
    pub function: u8,
}

/// Splits the I/O pins into their drivers. Outputs and brake start low (off /
/// brake engaged), LEDs off, TP1 low.
pub fn init(p: IoPins<'static>) -> (Leds<'static>, Ports<'static>, Dip<'static>) {
    let out = |pin: Peri<'static, AnyPin>| Output::new(pin, Level::Low, Speed::Low);
    let leds = Leds {
        green: Output::new(p.led_green, Level::Low, Speed::Low),
        red: Output::new(p.led_red, Level::Low, Speed::Low),
        run: Output::new(p.led_run, Level::Low, Speed::Low),
        err: Output::new(p.led_err, Level::Low, Speed::Low),
    };
    let ports = Ports {
        in3_5: [
            Input::new(p.in3, Pull::None),
            Input::new(p.in4, Pull::None),
            Input::new(p.in5, Pull::None),
        ],
        outputs: [out(p.out1.into()), out(p.out2.into()), out(p.out3.into())],
        brake: Output::new(p.brake, Level::Low, Speed::Low),
    };
    let od = |pin: Peri<'static, AnyPin>| OutputOpenDrain::new(pin, Level::High, Speed::Low);
    let dip = Dip {
        rows: [
            od(p.dip_rows.0.into()),
            od(p.dip_rows.1.into()),
            od(p.dip_rows.2.into()),
            od(p.dip_rows.3.into()),
        ],
        cols: [
            Input::new(p.dip_cols.0, Pull::Up),
            Input::new(p.dip_cols.1, Pull::Up),
            Input::new(p.dip_cols.2, Pull::Up),
            Input::new(p.dip_cols.3, Pull::Up),
        ],
    };
    let tp1 = Output::new(p.tp1, Level::Low, Speed::VeryHigh);
    core::mem::forget(tp1);
    (leds, ports, dip)
}

/// Drives an output high (`true`) or low. Not inlined: the 1 ms tick's LEDs, outputs
/// and brake share it.
// Measured (cargo xtask size, LAN9252 image): see `hw::pwm::af_pin`.
#[inline(never)]
pub fn set_output(pin: &mut Output<'_>, high: bool) {
    pin.set_level(Level::from(high));
}

impl<'d> Ports<'d> {
    /// IN1..IN5 as bits 0..4, 1 = input active (opto conducting pulls the pin low).
    pub fn read_inputs(&self) -> u8 {
        let idr = pac::GPIOB.idr().read();
        let low = |n: usize| u8::from(idr.idr(n) == pac::gpio::vals::Idr::LOW);
        let mut bits = low(11) | (low(1) << 1);
        for (i, pin) in self.in3_5.iter().enumerate() {
            bits |= u8::from(pin.is_low()) << (i + 2);
        }
        bits
    }

    /// Sets OUT1..OUT3 from bits 0..2.
    pub fn write_outputs(&mut self, bits: u8) {
        for (i, pin) in self.outputs.iter_mut().enumerate() {
            set_output(pin, bits & (1 << i) != 0);
        }
    }

    /// OUT1..OUT3 and the brake output, with the pad each drives (port, pin as typed
    /// in [`IoPins`]), for the self-test's read-back.
    #[cfg(feature = "selftest")]
    pub fn output_pads(&mut self) -> [(&'static str, &mut Output<'d>, pac::gpio::Gpio, usize); 4] {
        let [o1, o2, o3] = &mut self.outputs;
        [
            ("OUT1 (PA10)", o1, pac::GPIOA, 10),
            ("OUT2 (PA11)", o2, pac::GPIOA, 11),
            ("OUT3 (PA12)", o3, pac::GPIOA, 12),
            ("brake (PB9)", &mut self.brake, pac::GPIOB, 9),
        ]
    }
}

/// Releases (true) or engages (false) the holding brake (PB9), straight through the
/// register: the current-loop interrupt's one write
/// (`firmware::power_gate::BrakeOut`, from `hw::control::BoardHw`). The [`Ports`]
/// driver keeps the pin configured as an output.
#[inline(always)]
pub fn set_brake_released(released: bool) {
    pac::GPIOB.bsrr().write(|w| {
        if released {
            w.set_bs(9, true)
        } else {
            w.set_br(9, true)
        }
    });
}

#[cfg(feature = "selftest")]
impl Leds<'static> {
    /// Each LED with the pad it drives (port, pin as typed in [`IoPins`]), for the
    /// self-test's read-back.
    pub fn pads(&mut self) -> [(&'static str, &mut Output<'static>, pac::gpio::Gpio, usize); 4] {
        [
            ("LED green (PC8)", &mut self.green, pac::GPIOC, 8),
            ("LED red (PC9)", &mut self.red, pac::GPIOC, 9),
            ("LED RUN (PB6)", &mut self.run, pac::GPIOB, 6),
            ("LED ERR (PB7)", &mut self.err, pac::GPIOB, 7),
        ]
    }
}

/// The level at pad `n` of port `g` (input data register: what the pin is at, whatever
/// drives it).
#[cfg(feature = "selftest")]
pub fn pad_high(g: pac::gpio::Gpio, n: usize) -> bool {
    g.idr().read().idr(n) == pac::gpio::vals::Idr::HIGH
}

impl Dip<'_> {
    /// Scans the matrix: each row low in turn, columns read after a settling delay.
    /// A closed switch (ON) pulls its column low.
    pub fn read(&mut self) -> DipBanks {
        let mut rows = [0u8; board::DIP_ROWS];
        for (r, row) in self.rows.iter_mut().enumerate() {
            row.set_low();
            // ≈ 10 µs at 170 MHz for the pull-ups to recharge the column lines.
            cortex_m::asm::delay(board::SYSCLK_HZ / 100_000);
            for (c, col) in self.cols.iter().enumerate() {
                rows[r] |= u8::from(col.is_low()) << c;
            }
            row.set_high();
        }
        decode_matrix(rows)
    }
}

/// Rows 0/1 carry the ID bank's switches 1-4 / 5-8, rows 2/3 the function bank's.
fn decode_matrix(rows: [u8; board::DIP_ROWS]) -> DipBanks {
    DipBanks {
        id: (rows[0] & 0x0F) | ((rows[1] & 0x0F) << 4),
        function: (rows[2] & 0x0F) | ((rows[3] & 0x0F) << 4),
    }
}

/// TP1 high (BSRR write: one store, usable from any interrupt).
#[inline(always)]
pub fn tp1_high() {
    pac::GPIOC.bsrr().write(|w| w.set_bs(1, true));
}

/// TP1 low.
#[inline(always)]
pub fn tp1_low() {
    pac::GPIOC.bsrr().write(|w| w.set_br(1, true));
}

/// Red LED on and brake engaged, straight through the registers (panic and fault
/// handlers; works whatever state the drivers are in).
pub fn emergency_indicators() {
    pac::GPIOC.bsrr().write(|w| w.set_bs(9, true));
    pac::GPIOB.bsrr().write(|w| w.set_br(9, true));
}

/// Drives the outputs and the LEDs to the levels the runtime's tick chose (the brake
/// pin is the current-loop interrupt's: [`set_brake_released`]).
pub fn write_pins(leds: &mut Leds<'_>, ports: &mut Ports<'_>, pins: &firmware::runtime::Pins) {
    ports.write_outputs(pins.outputs);
    set_output(&mut leds.green, pins.green);
    set_output(&mut leds.red, pins.red);
    set_output(&mut leds.run, pins.run);
    set_output(&mut leds.err, pins.err);
}
