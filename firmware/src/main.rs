//! Board firmware: the drive on the STM32G474RE reference board (see [`board`] for
//! the pinout). Built only with `--features board,esc-lan9252` (or `esc-et1100`)
//! `--target thumbv7em-none-eabihf`; flashed with probe-rs (`cargo flash`, see
//! README.md, section "The board firmware").
//!
//! ## Tasks, interrupts and priorities
//!
//! NVIC priorities: 0 is the most urgent; the G4 implements 4 priority bits. Thread
//! mode (the embassy thread executor) is below every interrupt. Budgets are per
//! activation at 170 MHz; "to be measured" means it needs the board (TP1 + scope or
//! DWT CYCCNT, see the README section) — QEMU has no timing model.
//!
//! | what | runs in | priority | rate | worst-case budget |
//! |---|---|---|---|---|
//! | current loop: ADC1 JEOS → I_A, I_B, V_BUS → encoder update → `foc::current_loop::CurrentLoop::step` → TIM1/TIM8 compare (`hw::control`) | `ADC1_2` ISR | 0 | 40 kHz (PWM centre) | ≤ 12.5 µs (half a PWM period); current step ≈ 320 instructions (QEMU count) ≈ 2-3 µs; to be measured (`ISR max` in the status line) |
//! | motion layer: `firmware::commutation::CommutatedMotion::step` — at the first closed-loop enable after power-up the commutation alignment (`foc::servo::Alignment`, 0.25 s, 0.65 s with the 0x2083 wiggle; offset → encoder), then `firmware::motion::Motion::step` (interpolation, servo / open loop → current reference); index, touch probe 1 (TIM2 CH4 capture) and touch probe 2 (from the task below) → positions (`firmware::latch`); feedback published | same ISR, every 4th period | 0 | 10 kHz | together with the current step ≤ 12.5 µs; to be measured |
//! | over-current: break input → TIM1/TIM8 MOE off | hardware | — | event | break filter ≈ 24 ns + gate driver |
//! | break bookkeeping: other bridge off, latch | `TIM1_BRK_TIM15`, `TIM8_BRK` ISRs | 1 | event | < 1 µs, to be measured |
//! | SPI DMA completion (ESC transfers) | `DMA1_CHANNEL1/2` ISRs (embassy) | 1 | per transfer | < 1 µs, to be measured |
//! | cyclic path: SYNC0 → `Slave::cycle` (SM2 read, `Drive` = CiA 402 cycle, SM3 write) → set-points to the ISR | interrupt executor on `UART4` (vector unused: its pins carry TIM8) | 2 | DC sync rate (≥ 125 µs cycle) | ≤ 50 % of the cycle; SPI ≈ 0.4 µs/byte at 21.25 MHz + CSP cycle (≈ 1.5 k instructions); to be measured |
//! | touch probe 2 (IN2 edge → encoder count + edge direction → `hw::control::PROBE2_RAW`) | interrupt executor `UART4` | 2 | event | < 2 µs latency (the latch error), to be measured |
//! | EXTI1/2/3 wakers (IN2, ESC IRQ, SYNC0) | `EXTI1..3` ISRs (embassy) | 2 | event | < 1 µs |
//! | embassy time driver | `TIM5` ISR | 3 | alarms | < 2 µs |
//! | EtherCAT: ESC IRQ (or every 1 ms) → `Slave::poll` (AL control, ESM, mailbox/SDO, watchdog supervision; the cycle in SM-synchronous / free-run mode), emergencies forwarded | thread executor, holding the priority-ceiling lock | thread (ceiling 2) | ESC IRQ, ≥ 1 kHz | one SDO ≈ 2 × 128-byte SPI transfers + dictionary access; a 'save' adds the record serialisation (≈ 1.7 KiB of dictionary reads); delays the cyclic path by at most this; to be measured |
//! | parameter storage: staged record → flash (erase ≈ 20 ms per 2 KiB page, ≤ 40 ms max; program ≈ 85 µs per 8 bytes) | thread executor, after `poll`, **no lock** | thread | on 'save' / 'load' | ≤ 4 × 40 ms + 20 ms; the cyclic path and the ISRs keep running (bank 2 read-while-write); the thread tasks pause — the watchdog (300 ms) covers it |
//! | 1 ms supervision tick, the drive's own clock: raw inputs → `Drive::tick` (filter, protections, fault 1 / 9 from the board, a failed commutation alignment → following error 0x8611, and — unless a cycle just did it — the control step: PDS, fault reactions, ramps, generators, brake, in every ESM state), outputs + brake from `Drive::outputs`, LEDs (`Drive::leds`, RUN/ERR from the ESM state and AL status code) | interrupt executor `UART4` (so a flash commit in thread mode never stops it; lock held for the drive part) | 2 | 1 kHz | < 20 µs; the control step ≈ 1 k instructions (QEMU count), to be measured |
//! | supervisor: offset self-check at start, watchdog feeding, status line | thread executor | thread | 100 Hz | < 100 µs per tick |
//!
//! ## Who owns what
//! * The **drive state** — `Slave<Esc>` (the ESC and its SPI bus) and `Drive` (the
//!   application: dictionary, CiA 402, faults, parameter store) — is one
//!   [`DriveState`] value in a blocking `Mutex<CyclicCeiling, RefCell<..>>`
//!   ([`hw::lock`]): locking raises BASEPRI to the cyclic priority, so the thread-mode
//!   tasks exclude the cyclic path while they hold it, and the current loop
//!   (priority 0) and the DMA / break interrupts (priority 1) are never delayed by it.
//!   We did not split Slave and Drive: `poll` and `cycle` both need both.
//! * `Slave::poll` runs in **thread mode** (task `ecat`), `Slave::cycle` on the
//!   **interrupt executor** (task `cyclic`, SYNC0; each SYNC0 is run once, by
//!   whichever of the two sees it first, see `cyclic`). A 'save' (0x1010) arrives as an SDO
//!   inside `poll`; the parameter store is `FlashStore<hw::flash::StagedFlash>`: the
//!   record is serialised into a 2 KiB RAM image inside `poll` (the SDO answer reports
//!   the serialisation's result) and the `ecat` task programs it into the flash *after*
//!   releasing the lock ([`hw::flash::commit`]: erase, payload, header last — the
//!   storage's power-loss order). So no flash erase ever runs under the lock and the
//!   cyclic path keeps its timing during a save; a flash error at commit time is
//!   logged and sent as an emergency (0x5530). The fault history's record
//!   (`Drive::persist_history`, polled after `poll` when no 'save' record waits) goes
//!   the same way through the same stage: the fault path only marks it dirty.
//!   A second 'save' while one is being
//!   programmed cannot happen (the same task does both in turn).
//! * The **chip's flash** is one `hw::flash::ChipFlash` (a thread-mode mutex: taking it
//!   masks nothing) shared by the parameter region and the **firmware update**
//!   (`firmware::update`, attached to the drive): FoE in Bootstrap runs inside `poll`,
//!   erasing and programming the DFU partition (bank 2, read-while-write) under the
//!   lock, one 2 KiB page per FoE DATA at most (≈ 20 ms, answered BUSY); the power
//!   stage is off in Bootstrap. After an accepted update, Bootstrap → Init resets the
//!   chip into embassy-boot (`Drive::reset_requested`). A new image confirms itself
//!   (embassy-boot's state partition, bank 1: a stall of the code bank for the page
//!   erase) only with the power stage off, once the offset check passed and Pre-Op was
//!   reached.
//! * The **motor control state** (`CurrentLoop`, `foc::encoder::Encoder`,
//!   `CommutatedMotion` = `Motion` + the commutation alignment) is owned by the ADC
//!   interrupt ([`hw::control`]). It talks to the drive through two lock-free double
//!   buffers: set-points / permission / configuration / offsets in, measurements
//!   (`AxisState` fields, index and touch-probe latches, alignment failures) out.
//! * **Touch probes** (0x60B8-0x60BD): the interrupt publishes the axis position at
//!   each electrical edge of IN1 / IN2 with a sequence number
//!   (`firmware::latch::Edges`); whoever updates the drive (`update_axis`) turns new
//!   ones into rising/falling edges per 0x2154 and hands them to the drive in
//!   `AxisState::probe1/probe2` until a drive step has run (`publish_command` clears
//!   them), exactly as the index pulse.
//! * **Decisions** between the drive and the interrupt — latches pending for a step,
//!   probe polarity, alignment failures → 0x8611, the failed offset check → fault 9,
//!   the power and tune permissions, break latch ↔ fault 1 and its re-arm — are the
//!   library's `firmware::board_glue::BoardGlue` (held in [`DriveState`]), run by host and
//!   QEMU tests and by the simulator (`tests-host`). This file wires tasks to it.
//!
//! ## Watchdog
//! The independent watchdog ([`board::WATCHDOG_TIMEOUT_US`]) is fed by the supervisor
//! only while the current-loop ISR keeps producing samples (its sample counter
//! advanced since the last feed) and the control state is installed. A stuck PWM/ADC
//! chain, a hung interrupt or a starved thread executor all end in a reset; the next
//! start logs the cause.
#![no_std]
#![no_main]
// The self-test build (`--features selftest`) spawns none of the drive's tasks: their
// helpers are compiled but unused there.
#![cfg_attr(feature = "selftest", allow(dead_code, unused_variables))]
#![deny(clippy::undocumented_unsafe_blocks)]

mod board;
mod hw;

use core::cell::RefCell;
use core::mem::MaybeUninit;
use core::sync::atomic::Ordering;

use defmt_rtt as _;
use ecat_slave_stack::leds::{ErrCondition, StatusLeds};
use ecat_slave_stack::slave::Slave;
use embassy_executor::{InterruptExecutor, SendSpawner, SpawnError, SpawnToken, Spawner};
use embassy_futures::select::{select, Either};
use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::gpio::Pull;
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::mode::Async;
use embassy_stm32::spi::Spi;
use embassy_stm32::{bind_interrupts, dma, peripherals};
use embassy_sync::blocking_mutex::Mutex;
use embassy_time::{Duration, Instant, Ticker, Timer};
use firmware::board_glue::BoardGlue;
use firmware::current_supervisor::SupervisorConfig;
use firmware::drive::{Drive, FlashStore, NoRuntime};
use firmware::identity::Variant;
use firmware::motion::{MotionConfig, SERVO_TS};
use firmware::sampling::OffsetCalibrator;

use firmware::latch::Edges;
use hw::control::{ControlCommand, COMMAND, PROBE2_RAW, SAMPLES};
use hw::encoder::Encoder;
use hw::esc::Esc;
use hw::flash::{ParamFlash, Stage, StagedFlash};
use hw::io;
use hw::lock::{CyclicCeiling, CYCLIC_PRIORITY};

bind_interrupts!(struct Irqs {
    EXTI1 => exti::InterruptHandler<interrupt::typelevel::EXTI1>;
    EXTI2 => exti::InterruptHandler<interrupt::typelevel::EXTI2>;
    EXTI3 => exti::InterruptHandler<interrupt::typelevel::EXTI3>;
    DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
});

/// The interrupt executor of the cyclic path (vector `UART4`, priority 2).
static EXECUTOR_CYCLIC: InterruptExecutor = InterruptExecutor::new();

/// `#[interrupt]` (cortex-m-rt's, re-exported by embassy-stm32) checks the name
/// against the device's interrupt enum: a misspelt vector does not compile.
#[interrupt]
fn UART4() {
    // SAFETY: `on_interrupt` runs only here, in the handler of UART4, the interrupt
    // `spawn_drive_tasks` starts EXECUTOR_CYCLIC on; the vector serves nothing else
    // (UART4's pins carry TIM8).
    unsafe { EXECUTOR_CYCLIC.on_interrupt() }
}

/// The product variant this board runs (hybrid servo: encoder on TIM2).
const VARIANT: Variant = firmware::identity::BOARD_VARIANT;
/// The ESC of this build, as update images name it.
#[cfg(not(feature = "esc-et1100"))]
const BOARD_ESC: efw::Esc = efw::Esc::Lan9252;
#[cfg(feature = "esc-et1100")]
const BOARD_ESC: efw::Esc = efw::Esc::Et1100;

/// The drive with its parameter store of this board.
type BoardDrive = Drive<FlashStore<StagedFlash>>;

/// The drive state shared by the cyclic path and the thread-mode tasks (see the
/// module docs, "Who owns what").
///
/// Built with one struct literal at start-up (a field added here and not given a
/// value there does not compile). The two large parts live in static slots of their
/// own, each written whole by its constructor ([`new_drive`]: `Drive::init_in`;
/// [`new_slave`]), so no 5 KiB value is built on the stack and moved.
struct DriveState {
    drive: Placed<BoardDrive>,
    /// `None` when the ESC did not answer at start-up (the drive still runs locally).
    slave: Option<Placed<Slave<Esc>>>,
    /// The glue between the drive and the current-loop interrupt (the last command
    /// published, latches pending for a drive step, board faults):
    /// `firmware::board_glue`.
    glue: BoardGlue,
}

/// A value built in its own static slot (the one reference to it): the drive state
/// reaches it as if it were a field.
struct Placed<T: 'static>(&'static mut T);

impl<T> core::ops::Deref for Placed<T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.0
    }
}

impl<T> core::ops::DerefMut for Placed<T> {
    fn deref_mut(&mut self) -> &mut T {
        self.0
    }
}

/// The lock holds a reference to [`DRIVE_STATE_SLOT`] (a `None` reference is all zeros, so
/// the lock lives in .bss).
static DRIVE_STATE: Mutex<CyclicCeiling, RefCell<Option<&'static mut DriveState>>> =
    Mutex::new(RefCell::new(None));
/// RAM image of a parameter record being saved (see `hw::flash::StagedFlash`).
static mut STAGE_MEM: Stage = Stage::new();
/// The chip's flash, shared by the records and the update (`hw::flash::ChipFlash`).
static mut CHIP_FLASH_MEM: MaybeUninit<hw::flash::ChipFlash> = MaybeUninit::uninit();
/// embassy-boot's aligned state buffer and the firmware update's slot.
static mut UPDATE_ALIGNED: embassy_boot::AlignedBuffer<8> = embassy_boot::AlignedBuffer([0; 8]);
static mut UPDATE_MEM: MaybeUninit<hw::flash::BoardUpdate> = MaybeUninit::uninit();
static mut DRIVE_STATE_SLOT: MaybeUninit<DriveState> = MaybeUninit::uninit();
/// The drive application's slot (written whole by `Drive::init_in`).
static mut DRIVE_MEM: MaybeUninit<BoardDrive> = MaybeUninit::uninit();
/// The slave runtime's slot (written whole by [`new_slave`] when the ESC answered).
static mut SLAVE_MEM: MaybeUninit<Slave<Esc>> = MaybeUninit::uninit();

/// Runs `f` on the drive state under the priority-ceiling lock; `None` before the
/// state exists.
fn with_drive_state<R>(f: impl FnOnce(&mut DriveState) -> R) -> Option<R> {
    DRIVE_STATE.lock(|c| match c.try_borrow_mut() {
        Ok(mut g) => g.as_deref_mut().map(f),
        Err(_) => None,
    })
}

defmt::timestamp!("{=u64:us}", Instant::now().as_micros());

fn now_us() -> u64 {
    Instant::now().as_micros()
}

/// `Ticker::every`, for the 1 ms tick and the supervisor (not inlined: both tasks
/// share one copy of the time-driver read).
#[inline(never)]
fn ticker(period: Duration) -> Ticker {
    Ticker::every(period)
}

fn now_ms() -> u32 {
    Instant::now().as_millis() as u32
}

/// The parameter-record store in the flash region (offsets relative to the region;
/// the layout of `firmware::storage::region`: parameters, then the fault history).
const PARAM_STORE: firmware::storage::Storage = firmware::storage::region::PARAMS;
const _: () = assert!(firmware::storage::region::SIZE == board::PARAM_FLASH_SIZE);

fn motion_config(d: &BoardDrive) -> MotionConfig {
    MotionConfig::from_params(&d.params, d.variant, &board::MOTOR, SERVO_TS)
}

/// Current-loop supervision (power-up auto-tune 0x2013, its test current from 0x2000).
/// Out of line: start-up and the 10 ms parameter check share it.
#[inline(never)]
fn supervisor_config(d: &BoardDrive) -> SupervisorConfig {
    SupervisorConfig::from_params(&d.params, 1.0 / board::PWM_HZ as f32, board::PWM_ARR)
}

/// Start-up: the thread executor's first task (`#[embassy_executor::main]` provides
/// the entry point, the executor and the spawn of this task). It sets up every
/// peripheral, builds the drive state in place and spawns the other tasks.
#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // Gate pins driven low before anything else (`hw::pwm`, "Defined gate levels").
    hw::pwm::hold_gates_low();
    hw::stack::paint();
    let p = embassy_stm32::init(hw::clock::config());
    start_chip();

    // Power stage first: the gate-driver inputs get defined (off) levels at once.
    hw::pwm::init(hw::pwm::PowerStage {
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
    });
    let enc = hw::encoder::init(hw::encoder::EncoderPins {
        tim2: p.TIM2,
        a: p.PA15,
        b: p.PB3,
        z: p.PB10,
        in1: p.PB11,
    });
    let (leds, ports, mut dip) = io::init(io::IoPins {
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
    });
    let dip_cfg = read_dip_banks(&mut dip);

    // EtherCAT slave controller.
    let spi = Spi::new(
        p.SPI2,
        p.PB13,
        p.PB15,
        p.PB14,
        p.DMA1_CH2,
        p.DMA1_CH1,
        Irqs,
        hw::esc::spi_config(),
    );
    let mut esc = hw::esc::new_esc(hw::esc::EscSpi::new(spi, hw::esc::cs_pin(p.PB12)));
    let esc_ok = probe_esc(&mut esc);
    let esc_irq = ExtiInput::new(p.PC2, p.EXTI2, Pull::Up, Irqs);
    let sync0 = ExtiInput::new(p.PC3, p.EXTI3, hw::esc::SYNC0_IDLE_PULL, Irqs);
    let in2 = ExtiInput::new(p.PB1, p.EXTI1, Pull::None, Irqs);
    for irq in [interrupt::EXTI1, interrupt::EXTI2, interrupt::EXTI3] {
        irq.set_priority(CYCLIC_PRIORITY);
    }

    let (chip, flash, staged) = start_flash(p.FLASH);
    // SAFETY: `main` runs once and is the only place that takes references to
    // DRIVE_MEM and SLAVE_MEM: these are unique.
    let slots = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(DRIVE_MEM),
            &mut *core::ptr::addr_of_mut!(SLAVE_MEM),
        )
    };
    let (drive, slave) = new_drive_and_slave(slots, chip, staged, esc, esc_ok, dip_cfg.address);
    // Motor control in the current-loop interrupt, then the ADCs (which enable it).
    let ctl = start_control(drive);
    let has_slave = slave.is_some();
    install_drive_state(drive, slave, ctl);
    hw::adc::init(hw::adc::Analog {
        adc1: p.ADC1,
        adc2: p.ADC2,
        ia: p.PA0,
        ib: p.PA1,
        vbus: p.PC0,
    });

    let thread_spawner = spawner.make_send();
    // The self-test build: the checks instead of the drive's tasks (bridges off).
    #[cfg(feature = "selftest")]
    {
        let _ = (sync0, esc_irq, in2, enc, p.IWDG);
        let parts = hw::selftest::Parts {
            dip,
            leds,
            ports,
            flash,
            encoder_counts: ctl.motion.counts_per_rev / 4,
        };
        spawn(thread_spawner, selftest(parts), defmt::intern!("selftest"));
    }
    #[cfg(not(feature = "selftest"))]
    spawn_drive_tasks(
        thread_spawner,
        (sync0, esc_irq, in2),
        enc,
        flash,
        (leds, ports),
        p.IWDG,
        has_slave,
    );
}

/// The chip's set-up after `embassy_stm32::init`, then the first log line.
fn start_chip() {
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
        hw::adc::enable_cycle_counter(core.DCB, core.DWT);
    }
    // The time driver defaults to priority 0; keep it below the control path.
    interrupt::TIM5.set_priority(Priority::P3);
    defmt::info!(
        "ECS drive firmware {=str} ({=str}), reset cause: {=istr}",
        env!("CARGO_PKG_VERSION"),
        hw::esc::ESC_NAME,
        hw::safety::take_reset_cause()
    );
}

/// Reads both DIP banks once (power-up) and logs them; the station address and the
/// function switches they select.
fn read_dip_banks(dip: &mut io::Dip<'static>) -> firmware::dip::DipConfig {
    let dips = dip.read();
    let dip_cfg =
        firmware::dip::power_up(firmware::dip::Board::TwoBanks, dips.id, dips.function, 0);
    defmt::info!(
        "DIP banks: ID {=u8:#010b} (station address {=u16}), function {=u8:#010b}",
        dips.id,
        dip_cfg.address,
        dips.function
    );
    dip_cfg
}

/// Whether the ESC answers ([`hw::esc::probe`]); logs why not.
fn probe_esc(esc: &mut Esc) -> bool {
    match hw::esc::probe(esc) {
        Ok(()) => true,
        Err(e) => {
            defmt::error!(
                "ESC {=str} not answering: {=istr}",
                hw::esc::ESC_NAME,
                hw::log::esc_error(e)
            );
            false
        }
    }
}

/// The chip's flash, shared by the parameter storage and the firmware update (`None`
/// without dual-bank mode); the parameter region (`None` likewise); the drive's view
/// of the region, which reads straight from it and stages saves in RAM.
fn start_flash(
    flash: embassy_stm32::Peri<'static, peripherals::FLASH>,
) -> (
    Option<&'static hw::flash::ChipFlash>,
    Option<ParamFlash>,
    StagedFlash,
) {
    // SAFETY: `main` calls this once, and nothing else takes a reference to
    // CHIP_FLASH_MEM: this one is unique.
    let chip_slot = unsafe { &mut *core::ptr::addr_of_mut!(CHIP_FLASH_MEM) };
    let chip = hw::flash::chip_flash(flash, chip_slot);
    let param_flash = chip.and_then(hw::flash::param_flash);
    if param_flash.is_none() {
        defmt::error!(
            "flash is not in dual-bank mode (option byte DBANK = 0): parameter storage off"
        );
    }
    // SAFETY: `main` calls this once, and nothing else takes a reference to STAGE_MEM:
    // this one is unique.
    let stage: &'static mut Stage = unsafe { &mut *core::ptr::addr_of_mut!(STAGE_MEM) };
    let mut staged = StagedFlash::new(hw::flash::ecc_region(), stage, param_flash.is_some());
    if param_flash.is_some() {
        hw::log::param_region(&PARAM_STORE, &mut staged);
    }
    (chip, param_flash, staged)
}

/// The drive and, when the ESC answered, the slave runtime, each built in its static
/// slot; stored parameters (drive objects and the PDO mapping) are loaded before the
/// ESC leaves Init.
///
/// Built in place: the drive state is ≈ 5 KiB, and building it in `main`'s frame and
/// moving it in would add that (twice) to the stack peak.
fn new_drive_and_slave(
    (drive_slot, slave_slot): (
        &'static mut MaybeUninit<BoardDrive>,
        &'static mut MaybeUninit<Slave<Esc>>,
    ),
    chip: Option<&'static hw::flash::ChipFlash>,
    staged: StagedFlash,
    esc: Esc,
    esc_ok: bool,
    dip_address: u16,
) -> (&'static mut BoardDrive, Option<&'static mut Slave<Esc>>) {
    let serial = firmware::identity::serial_from_unique_id(&embassy_stm32::uid::uid());
    let drive = new_drive(drive_slot, serial, staged);
    if let Some(chip) = chip {
        attach_update(drive, chip);
    }
    let mut slave = esc_ok.then(|| new_slave(slave_slot, esc));
    let report = match slave.as_mut() {
        Some(s) => drive.power_up(&mut s.runtime_objects(firmware::dictionary::OBJECTS)),
        None => drive.power_up(&mut NoRuntime),
    };
    defmt::info!(
        "parameters: {=u16} applied, {=u16} skipped, from slot {}",
        report.applied,
        report.skipped,
        report.source.map(|(slot, seq)| (slot as u8, seq))
    );
    if let Some(s) = slave.as_mut() {
        start_slave(s, drive, dip_address);
    }
    (drive, slave)
}

/// Firmware update over FoE; embassy-boot's state tells whether this image is on
/// trial (confirmed once the start-up checks passed and Pre-Op is reached).
fn attach_update(drive: &mut BoardDrive, chip: &'static hw::flash::ChipFlash) {
    // SAFETY: called once, from start-up, and nothing else takes a reference to
    // UPDATE_ALIGNED or UPDATE_MEM: these are unique.
    let (aligned, update_slot) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(UPDATE_ALIGNED),
            &mut *core::ptr::addr_of_mut!(UPDATE_MEM),
        )
    };
    let update = hw::flash::board_update(chip, aligned, update_slot, BOARD_ESC);
    defmt::info!(
        "firmware: boot state {=u8} (0 confirmed, 1 trial, 2 reverted), header version {}",
        firmware::update::FirmwareUpdate::boot_state(update) as u8,
        firmware::update::FirmwareUpdate::running_version(update)
    );
    drive.attach_update(update);
}

/// The station alias (DIP bank `dip_address` or 0x2150/0x2151, after the stored
/// parameters were loaded), then `Slave::init`.
fn start_slave(slave: &mut Slave<Esc>, drive: &BoardDrive, dip_address: u16) {
    let active = drive.params.active();
    let (alias, source) =
        firmware::dip::station_alias(active.alias_source, active.alias_value, dip_address, 0);
    // SII source: keep what the ESC loaded from SII word 4.
    slave.set_station_alias((source != firmware::dip::AliasSource::Sii).then_some(alias));
    match slave.init() {
        Ok(info) => defmt::info!(
            "slave runtime: ESC type {=u8:#04x}, {=u8} SMs, {=u8} KiB RAM, alias {=u16} ({})",
            info.esc_type,
            info.sync_managers,
            info.ram_kib,
            alias,
            source
        ),
        Err(e) => {
            hw::log::ESC_ERRORS.fetch_add(1, Ordering::Relaxed);
            defmt::error!("slave init: {=istr}", hw::log::esc_error(e));
        }
    }
}

/// The current-loop interrupt's control state from the drive's parameters, and the
/// first command published to it (power not allowed yet).
fn start_control(drive: &BoardDrive) -> ControlCommand {
    let mcfg = motion_config(drive);
    let wiggle = align_wiggle(drive);
    let scfg = supervisor_config(drive);
    let motor = firmware::control_core::LoopMotor::from_params(
        &drive.params,
        (board::MOTOR_R_OHM, board::MOTOR_L_H),
        board::MOTOR.kt,
        mcfg.counts_per_rev / 4,
    );
    hw::control::init(mcfg, wiggle, scfg, motor);
    let ctl = ControlCommand {
        cycle: 0,
        command: *drive.command(),
        cycle_s: 1e-3,
        power_allowed: false,
        config: 0,
        motion: mcfg,
        align_wiggle: wiggle,
        offsets: None,
        supervisor: scfg,
        tune_allowed: false,
        trace: false,
    };
    send_command(&ctl);
    ctl
}

/// Puts the drive state into its slot and hands it to the lock: from here on it is
/// reached only through [`with_drive_state`].
fn install_drive_state(
    drive: &'static mut BoardDrive,
    slave: Option<&'static mut Slave<Esc>>,
    ctl: ControlCommand,
) {
    // SAFETY: called once, from start-up, and nothing else takes a reference to
    // DRIVE_STATE_SLOT: this one is unique; afterwards the value is reached only
    // through the lock.
    let slot = unsafe { &mut *core::ptr::addr_of_mut!(DRIVE_STATE_SLOT) };
    let state: &'static mut DriveState = slot.write(DriveState {
        drive: Placed(drive),
        slave: slave.map(Placed),
        glue: BoardGlue::new(ctl),
    });
    DRIVE_STATE.lock(|c| *c.borrow_mut() = Some(state));
}

/// The self-test build's one task (`hw::selftest`).
#[cfg(feature = "selftest")]
#[embassy_executor::task]
async fn selftest(parts: hw::selftest::Parts) {
    hw::selftest::run(parts).await;
}

/// The drive's tasks: the cyclic path, the supervision tick and the touch probe on the
/// interrupt executor; the ESC's mailbox/ESM task and the supervisor in thread mode.
#[cfg(not(feature = "selftest"))]
fn spawn_drive_tasks(
    thread_spawner: SendSpawner,
    (sync0, esc_irq, in2): (
        ExtiInput<'static, Async>,
        ExtiInput<'static, Async>,
        ExtiInput<'static, Async>,
    ),
    enc: Encoder,
    flash: Option<ParamFlash>,
    (leds, ports): (io::Leds<'static>, io::Ports<'static>),
    iwdg: embassy_stm32::Peri<'static, embassy_stm32::peripherals::IWDG>,
    has_slave: bool,
) {
    // Cyclic path on the interrupt executor.
    interrupt::UART4.set_priority(CYCLIC_PRIORITY);
    let cyclic_spawner = EXECUTOR_CYCLIC.start(interrupt::UART4);
    if has_slave {
        spawn(cyclic_spawner, cyclic(sync0), defmt::intern!("cyclic"));
        spawn(thread_spawner, ecat(esc_irq, flash), defmt::intern!("ecat"));
    }
    spawn(
        cyclic_spawner,
        touch_probe2(in2, enc),
        defmt::intern!("touch_probe2"),
    );

    // Thread-mode tasks.
    let mut wdg = hw::safety::Watchdog::new(iwdg);
    wdg.unleash();
    // The supervision tick runs on the interrupt executor: a flash commit (which
    // blocks thread mode for up to ~180 ms) never stops the drive's own clock.
    spawn(cyclic_spawner, tick(leds, ports), defmt::intern!("tick"));
    spawn(
        thread_spawner,
        supervisor(wdg, enc),
        defmt::intern!("supervisor"),
    );
}

/// Spawns a task, or logs why it could not. The thread executor's tasks go through
/// its `SendSpawner` too (the same enqueue as `Spawner::spawn`).
fn spawn<S: Send>(spawner: SendSpawner, task: Result<SpawnToken<S>, SpawnError>, name: defmt::Str) {
    match task {
        Ok(t) => spawner.spawn(t),
        Err(e) => defmt::error!("spawn {=istr}: {}", name, e),
    }
}

/// The drive at its power-up defaults with the board's parameter store, written whole
/// into `slot` (not inlined: start-up code that runs once).
#[inline(never)]
fn new_drive(
    slot: &'static mut MaybeUninit<BoardDrive>,
    serial: u32,
    staged: StagedFlash,
) -> &'static mut BoardDrive {
    let d = Drive::init_in(
        slot,
        VARIANT,
        serial,
        FlashStore {
            storage: PARAM_STORE,
            history: Some(firmware::storage::region::HISTORY),
            flash: staged,
        },
    );
    // 0x6076 (rated torque) from the board's motor.
    d.cia402.set_torque_constant(board::MOTOR.kt);
    d
}

/// The slave runtime over the ESC with the product's default PDO mapping, written
/// whole into `slot` (not inlined, as [`new_drive`]).
#[inline(never)]
fn new_slave(slot: &'static mut MaybeUninit<Slave<Esc>>, esc: Esc) -> &'static mut Slave<Esc> {
    slot.write(Slave::new(esc, firmware::identity::slave_config()))
}

/// 0x2083: the power-up alignment sweeps the field (wiggle) and checks the encoder.
#[inline(never)]
fn align_wiggle(d: &BoardDrive) -> bool {
    d.params.get(firmware::params::P::PowerUpWiggle) != 0
}

/// Hands the interrupt's latest measurements to the drive (before a cycle / tick):
/// [`BoardGlue::update_axis`].
fn update_axis(s: &mut DriveState) {
    if let Some((seq, fb)) = hw::control::feedback() {
        s.glue
            .update_axis(&mut s.drive, seq, &fb, hw::pwm::break_latched() != 0);
    }
}

/// Publishes a command to the current-loop interrupt (not inlined: one copy of the
/// volatile write for every caller).
#[inline(never)]
fn send_command(c: &ControlCommand) {
    // SAFETY: every caller holds the drive's lock (or runs at start-up before the
    // tasks exist): one writer at a time.
    unsafe { COMMAND.write(Some(*c)) };
}

/// Publishes the drive's set-points to the current-loop interrupt
/// ([`BoardGlue::publish`]: a new interpolation segment per drive step, the power
/// permission, the tune permission).
fn publish_command(s: &mut DriveState) {
    send_command(s.glue.publish(&s.drive));
}

/// The cyclic path (DC mode): one `Slave::cycle` per SYNC0 pulse (its leading edge,
/// [`hw::esc::sync0_edge`]).
///
/// In DC mode the ESC IRQ also signals SYNC0 (the runtime puts it in the event
/// mask), so a thread-mode `poll` that read the AL event register just after a SYNC0
/// edge, while this task waited for the lock, has already run that cycle (the
/// runtime's `last_cycle` moved since this task's last call): the edge is then
/// skipped, so every SYNC0 is handled exactly once. Outside DC mode (SM-synchronous,
/// free run) SYNC0 edges are ignored and `poll` runs the cycles.
#[embassy_executor::task]
async fn cyclic(mut sync0: ExtiInput<'static, Async>) {
    let mut mine: Option<u64> = None;
    loop {
        hw::esc::sync0_edge(&mut sync0).await;
        hw::log::SYNC0S.fetch_add(1, Ordering::Relaxed);
        let now = now_us();
        with_drive_state(|s| {
            update_axis(s);
            if let Some(slave) = s.slave.as_mut() {
                let sync = slave.sync();
                let dc = sync.mode == ecat_slave_stack::sync::SyncMode::DcSync0;
                let taken_by_poll = sync.last_cycle != mine;
                if dc && !taken_by_poll && slave.cycle(&mut *s.drive, now).is_err() {
                    hw::log::ESC_ERRORS.fetch_add(1, Ordering::Relaxed);
                }
                mine = slave.sync().last_cycle;
            }
            publish_command(s);
        });
    }
}

/// EtherCAT in thread mode: `Slave::poll` on each ESC IRQ edge and at least every
/// millisecond (process-data watchdog supervision, missed edges); emergencies of the
/// drive are forwarded first; a staged parameter record is programmed into the
/// flash after the lock is released.
#[embassy_executor::task]
async fn ecat(mut irq: ExtiInput<'static, Async>, mut flash: Option<ParamFlash>) {
    loop {
        if irq.is_high() {
            if let Either::First(()) = select(
                irq.wait_for_falling_edge(),
                Timer::after(Duration::from_millis(1)),
            )
            .await
            {
                hw::log::ESC_IRQS.fetch_add(1, Ordering::Relaxed);
            }
        } else {
            // The IRQ line is still asserted: events are pending; let the other
            // thread tasks run once, then poll again.
            embassy_futures::yield_now().await;
        }
        let now = now_us();
        let staged = with_drive_state(|s| {
            update_axis(s);
            let slave = s.slave.as_mut()?;
            while let Some(e) = s.drive.pop_emergency() {
                slave.emergency(e.code, e.register, e.data);
            }
            if slave.poll(&mut *s.drive, now).is_err() {
                hw::log::ESC_ERRORS.fetch_add(1, Ordering::Relaxed);
            }
            publish_command(s);
            // A new image on trial confirms itself here, in thread mode (the flash).
            if s.drive.confirm_update() {
                defmt::info!("firmware: the new image confirmed itself");
            }
            if s.drive.reset_requested() {
                // An update was accepted and the master took the drive Bootstrap →
                // Init (AL status Init is written): reset into embassy-boot, which
                // swaps the partitions and starts the new image on trial.
                defmt::info!("firmware update accepted: reset into the bootloader");
                cortex_m::peripheral::SCB::sys_reset();
            }
            // A staged 'save' first, else a changed fault history (serialised here under
            // the lock, programmed below without it): `Drive::next_staged_record`.
            let (staged, history_error) = s.drive.next_staged_record();
            if let Some(e) = history_error {
                hw::log::FLASH_ERRORS.fetch_add(1, Ordering::Relaxed);
                defmt::error!(
                    "fault history: not staged: {=istr}",
                    hw::log::storage_error(e)
                );
            }
            staged
        })
        .flatten();
        if let Some(stage) = staged {
            let result = match flash.as_mut() {
                Some(f) => hw::flash::commit(f, stage),
                None => Ok(()),
            };
            let failed = result.is_err();
            match result {
                Ok(()) => defmt::info!("flash record programmed (parameters or fault history)"),
                Err(e) => {
                    hw::log::FLASH_ERRORS.fetch_add(1, Ordering::Relaxed);
                    defmt::error!(
                        "flash record: programming failed: {=istr}",
                        hw::log::region_error(&e)
                    );
                }
            }
            with_drive_state(|s| {
                if failed {
                    let reg = s.drive.faults.error_register() | 1;
                    if let Some(slave) = s.slave.as_mut() {
                        slave.emergency(firmware::storage::EMCY_RECORD_CORRUPT, reg, [0; 5]);
                    }
                }
                if let Some(st) = s.drive.store_mut() {
                    st.flash.give_back(stage);
                }
            });
        }
    }
}

/// Touch probe 2: latches the encoder count at each IN2 edge (software latch; the
/// EXTI-to-task latency is the error, to be measured on the board) with the edge's
/// direction (the pin level after the wake-up: an IN2 pulse must outlast that
/// latency), and hands it to the current-loop interrupt ([`PROBE2_RAW`]), which
/// converts it to command units for the drive's touch probe. Touch probe 1 (IN1) is
/// latched by TIM2 CH4 in hardware (`hw::control`).
#[embassy_executor::task]
async fn touch_probe2(mut in2: ExtiInput<'static, Async>, enc: Encoder) {
    let mut edges: Edges<u32> = Edges::default();
    loop {
        in2.wait_for_any_edge().await;
        let count = enc.position();
        // Opto input: active while the pin is low.
        edges.record(in2.is_low(), count);
        // SAFETY: this task is the one writer of PROBE2_RAW.
        unsafe { PROBE2_RAW.write(edges) };
    }
}

/// The 1 ms tick: board faults → drive, `Drive::tick` with the raw inputs (the drive
/// filters them), outputs and brake from the drive, LEDs, parameter changes → motion
/// configuration of the interrupt.
#[embassy_executor::task]
async fn tick(mut leds: io::Leds<'static>, mut ports: io::Ports<'static>) {
    let mut ticker = ticker(Duration::from_millis(1));
    let mut status = StatusLeds::new();
    let mut n: u32 = 0;
    loop {
        ticker.next().await;
        n = n.wrapping_add(1);
        let raw = ports.read_inputs();
        let now = now_ms();
        let out = with_drive_state(|s| {
            over_current(s);
            update_axis(s);
            // Board faults: failed offset check (fault 9), failed alignment (0x8611).
            s.glue.raise_board_faults(&mut s.drive, now);
            hw::control::drain_trace(|p| s.drive.scope_servo_point(p));
            s.drive.tick(now_us(), raw);
            // Parameter writes that change the motion layer (every 10 ms).
            if n.is_multiple_of(10) {
                let (m, w) = (motion_config(&s.drive), align_wiggle(&s.drive));
                s.glue.configure(m, w, supervisor_config(&s.drive));
            }
            publish_command(s);
            let (state, err) = match s.slave.as_ref() {
                Some(sl) => (
                    sl.state(),
                    ErrCondition::from_al_status(sl.esm().status_word(), sl.esm().code()),
                ),
                None => (
                    ecat_slave_stack::esm::EsmState::Init,
                    ErrCondition::BootingError,
                ),
            };
            status.update(state, err, now);
            (s.drive.leds(now), s.drive.outputs())
        });
        let Some((drive_leds, (outputs, brake))) = out else {
            continue;
        };
        ports.write_outputs(outputs);
        ports.set_brake_released(brake && hw::pwm::break_latched() == 0);
        let (run, err) = status.levels(now);
        io::set_output(&mut leds.green, drive_leds.green);
        io::set_output(&mut leds.red, drive_leds.red);
        io::set_output(&mut leds.run, run);
        io::set_output(&mut leds.err, err);
    }
}

/// Break latch (hardware over-current) ↔ drive fault 1
/// ([`BoardGlue::over_current`]): once the drive holds the fault, the command that
/// withdraws the power permission is published (the ISR reads COMMAND) before the
/// latch is re-armed; a re-armed latch is the condition gone, so a fault reset clears
/// the fault.
fn over_current(s: &mut DriveState) {
    if let Some(c) = s
        .glue
        .over_current(&mut s.drive, hw::pwm::break_latched() != 0)
    {
        send_command(c);
        if hw::pwm::rearm() {
            s.glue.break_rearmed(&mut s.drive);
        }
    }
}

/// Start-up current-sensor check (bridges off, so the currents are zero), then the
/// watchdog policy and a status line every second.
#[embassy_executor::task]
async fn supervisor(mut wdg: hw::safety::Watchdog, enc: Encoder) {
    offset_self_check(&mut wdg).await;

    let mut ticker = ticker(Duration::from_millis(10));
    let mut last_samples = SAMPLES.sequence();
    let mut ticks: u32 = 0;
    loop {
        ticker.next().await;
        let n = SAMPLES.sequence();
        if n != last_samples && hw::control::ready() {
            wdg.pet();
            last_samples = n;
        }
        ticks = ticks.wrapping_add(1);
        if ticks.is_multiple_of(100) {
            status_line(&enc);
        }
    }
}

async fn offset_self_check(wdg: &mut hw::safety::Watchdog) {
    let mut cal = OffsetCalibrator::new(board::OFFSET_SAMPLES);
    let mut last = SAMPLES.sequence();
    let mut idle = 0u32;
    // New samples arrive every 25 µs; give up after 10 ms without one.
    while !cal.is_complete() && idle < 200 {
        Timer::after_micros(50).await;
        match hw::control::latest_sample() {
            Some((seq, s)) if seq != last => {
                last = seq;
                idle = 0;
                cal.add(s);
            }
            _ => idle += 1,
        }
        wdg.pet();
    }
    match cal.finish(&board::ANALOG) {
        Ok(o) => {
            defmt::info!(
                "current-sensor offsets: A {=f32} B {=f32} counts ({=u32} samples)",
                o.ia,
                o.ib,
                cal.count()
            );
            with_drive_state(|s| {
                s.glue.offsets_passed(o.ia, o.ib);
                // A new image on trial may confirm itself once Pre-Op is reached too.
                s.drive.startup_checks_done(true);
                publish_command(s);
            });
        }
        Err(e) => {
            hw::safety::raise_fault(hw::safety::FAULT_CURRENT_SENSING);
            with_drive_state(|s| {
                s.glue.offset_check_failed();
                s.drive.startup_checks_done(false);
            });
            defmt::error!("fault 9, current-sensor self-check: {}", e);
        }
    }
}

/// The status line ([`hw::log::status_line`]) with the drive state's ESM figures.
fn status_line(enc: &Encoder) {
    let link = with_drive_state(|s| {
        let (al_status, al_code) = s
            .slave
            .as_ref()
            .map_or((0, 0), |sl| (sl.esm().status_word(), sl.esm().code()));
        hw::log::LinkStatus {
            al_status,
            al_code,
            bridges_on: hw::control::feedback().is_some_and(|(_, f)| f.bridges_on),
        }
    })
    .unwrap_or_default();
    hw::log::status_line(
        hw::control::latest_sample(),
        enc.position(),
        link,
        hw::control::feedback().map(|(_, f)| f),
    );
}
