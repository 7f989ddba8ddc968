//! Board firmware: the drive on the STM32G474RE reference board (see [`board`] for
//! the pinout). Built only with `--features board,esc-lan9252` (or `esc-et1100`)
//! `--target thumbv7em-none-eabihf`; flashed with probe-rs (`cargo flash`, see
//! `firmware/README-board.md`).
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
//! | current loop: ADC1 JEOS → read I_A, I_B, V_BUS → `firmware::sampling::current_loop_hook` (→ FOC current loop when wired) | `ADC1_2` ISR | 0 | 40 kHz (PWM centre) | ≤ 12.5 µs (half a PWM period) ; today's hook: to be measured, expected < 1 µs |
//! | over-current: break input → TIM1/TIM8 MOE off | hardware | — | event | break filter ≈ 24 ns + gate driver |
//! | break bookkeeping: other bridge off, latch fault 1 | `TIM1_BRK_TIM15`, `TIM8_BRK` ISRs | 1 | event | < 1 µs, to be measured |
//! | SPI DMA completion (ESC transfers) | `DMA1_CHANNEL1/2` ISRs (embassy) | 1 | per transfer | < 1 µs, to be measured |
//! | cyclic path: ESC IRQ / SYNC0 → AL event → (SM2 read, CiA 402 + servo, SM3 write when the slave runtime is wired) | interrupt executor on `UART4` (vector unused: its pins carry TIM8) | 2 | sync rate (≥ 250 µs cycle) | ≤ 50 % of the cycle time; SPI alone ≈ 0.4 µs/byte at 21.25 MHz; to be measured |
//! | touch probe 2 (IN2 edge → encoder count) | interrupt executor `UART4` | 2 | event | < 2 µs latency, to be measured |
//! | EXTI1/2/3 wakers (IN2, ESC IRQ, SYNC0) | `EXTI1..3` ISRs (embassy) | 2 | event | < 1 µs |
//! | embassy time driver | `TIM5` ISR | 3 | alarms | < 2 µs |
//! | supervisor: offset self-check at start, watchdog feeding, status log | thread executor | thread | 100 Hz | < 100 µs per tick |
//! | LEDs (fault flash code, green power) | thread executor | thread | 100 Hz | < 10 µs |
//! | I/O filtering (inputs debounce, outputs, brake) | thread executor | thread | 1 kHz | < 10 µs |
//! | mailbox / SDO: inside `Slave::poll` in the cyclic task (see Ownership) | interrupt executor `UART4` | 2 | on ESC IRQ | one SDO: to be measured; must stay well below the cycle time |
//! | parameter storage: slot check at start-up; save/restore (flash erase ≈ 20 ms per page, blocking) | thread executor | thread | on demand | not time-critical; blocks the thread executor: the watchdog timeout (300 ms) covers erasing a whole 8 KiB slot (4 pages × ≤ 40 ms) |
//!
//! Ownership: the cyclic path (priority 2) owns the ESC (the SPI bus and the driver).
//! State of the wiring: today the cyclic task only reads the AL event register on
//! each ESC IRQ / SYNC0 edge. The slave runtime (`ecat_slave_stack::slave::Slave`)
//! goes into that task: `Slave::cycle` on SYNC0 and `Slave::poll` on the ESC IRQ.
//! `poll` also serves the mailbox inline, so the SDO work that can take long
//! (a 'save' erases flash, ≈ 20 ms per 2 KiB page) must be handed to the thread-mode
//! storage task instead of running at priority 2 — to be decided when the drive
//! application is wired.
//!
//! ## Watchdog
//! The independent watchdog ([`board::WATCHDOG_TIMEOUT_US`]) is fed by the supervisor
//! only while the current-loop ISR keeps producing samples (its sample counter
//! advanced since the last feed). A stuck PWM/ADC chain, a hung interrupt or a
//! starved thread executor all end in a reset; the next start logs the cause.
#![no_std]
#![no_main]

mod board;
mod hw;

use core::sync::atomic::{AtomicU32, AtomicU8, Ordering};

use defmt_rtt as _;
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_futures::select::{select, Either};
use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::gpio::Pull;
use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_stm32::mode::Async;
use embassy_stm32::peripherals::IWDG;
use embassy_stm32::spi::Spi;
use embassy_stm32::time::Hertz;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{bind_interrupts, dma, peripherals, rcc};
use embassy_time::{Duration, Instant, Ticker, Timer};
use firmware::sampling::{OffsetCalibrator, CURRENT_SAMPLES};

use hw::{encoder::Encoder, esc::Esc, flash::ParamFlash, io};

bind_interrupts!(struct Irqs {
    EXTI1 => exti::InterruptHandler<interrupt::typelevel::EXTI1>;
    EXTI2 => exti::InterruptHandler<interrupt::typelevel::EXTI2>;
    EXTI3 => exti::InterruptHandler<interrupt::typelevel::EXTI3>;
    DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
});

/// The interrupt executor of the cyclic path (vector `UART4`, priority 2).
static EXECUTOR_CYCLIC: InterruptExecutor = InterruptExecutor::new();

#[no_mangle]
unsafe extern "C" fn UART4() {
    // SAFETY: the vector is used for nothing else (UART4's pins carry TIM8).
    unsafe { EXECUTOR_CYCLIC.on_interrupt() }
}

/// Latest AL event request register value read by the cyclic path.
static AL_EVENT: AtomicU32 = AtomicU32::new(0);
/// ESC IRQ edges / SYNC0 edges / ESC access errors seen by the cyclic path.
static ESC_IRQS: AtomicU32 = AtomicU32::new(0);
static SYNC0S: AtomicU32 = AtomicU32::new(0);
static ESC_ERRORS: AtomicU32 = AtomicU32::new(0);
/// Debounced inputs IN1..IN5 (bits 0..4) and requested outputs OUT1..OUT3 (bits 0..2).
static INPUTS: AtomicU8 = AtomicU8::new(0);
static OUTPUTS: AtomicU8 = AtomicU8::new(0);
/// Encoder count latched at the last IN2 edge (touch probe 2) and the edge count.
static PROBE2_POS: AtomicU32 = AtomicU32::new(0);
static PROBE2_EDGES: AtomicU32 = AtomicU32::new(0);

defmt::timestamp!("{=u64:us}", Instant::now().as_micros());

fn clock_config() -> embassy_stm32::Config {
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

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    hw::stack::paint();
    let p = embassy_stm32::init(clock_config());
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
        "ECS drive firmware {=str} ({=str}), reset cause: {=str}",
        env!("CARGO_PKG_VERSION"),
        hw::esc::ESC_NAME,
        hw::safety::take_reset_cause()
    );

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
    hw::adc::init(hw::adc::Analog {
        adc1: p.ADC1,
        adc2: p.ADC2,
        ia: p.PA0,
        ib: p.PA1,
        vbus: p.PC0,
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
    let dips = dip.read();
    defmt::info!(
        "DIP banks: ID {=u8:#010b}, function {=u8:#010b}",
        dips.id,
        dips.function
    );

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
    let esc_ok = match hw::esc::probe(&mut esc) {
        Ok(()) => true,
        Err(e) => {
            defmt::error!(
                "ESC {=str} not answering: {}",
                hw::esc::ESC_NAME,
                defmt::Debug2Format(&e)
            );
            false
        }
    };
    let esc_irq = ExtiInput::new(p.PC2, p.EXTI2, Pull::Up, Irqs);
    let sync0 = ExtiInput::new(p.PC3, p.EXTI3, Pull::None, Irqs);
    let in2 = ExtiInput::new(p.PB1, p.EXTI1, Pull::None, Irqs);
    for irq in [interrupt::EXTI1, interrupt::EXTI2, interrupt::EXTI3] {
        irq.set_priority(Priority::P2);
    }

    let flash = hw::flash::param_flash(p.FLASH);
    if flash.is_none() {
        defmt::error!(
            "flash is not in dual-bank mode (option byte DBANK = 0): parameter storage off"
        );
    }

    // Cyclic path on the interrupt executor.
    interrupt::UART4.set_priority(Priority::P2);
    let cyclic_spawner = EXECUTOR_CYCLIC.start(interrupt::UART4);
    if esc_ok {
        match cyclic(esc, esc_irq, sync0) {
            Ok(t) => cyclic_spawner.spawn(t),
            Err(e) => defmt::error!("spawn cyclic: {}", e),
        }
    }
    match touch_probe2(in2, enc) {
        Ok(t) => cyclic_spawner.spawn(t),
        Err(e) => defmt::error!("spawn touch_probe2: {}", e),
    }

    // Thread-mode tasks.
    let mut wdg = IndependentWatchdog::new(p.IWDG, board::WATCHDOG_TIMEOUT_US);
    wdg.unleash();
    match led_task(leds) {
        Ok(t) => spawner.spawn(t),
        Err(e) => defmt::error!("spawn leds: {}", e),
    }
    match io_task(ports) {
        Ok(t) => spawner.spawn(t),
        Err(e) => defmt::error!("spawn io: {}", e),
    }
    match supervisor(wdg, flash, enc) {
        Ok(t) => spawner.spawn(t),
        Err(e) => defmt::error!("spawn supervisor: {}", e),
    }
}

/// The cyclic path: woken by the ESC's PDI interrupt or SYNC0. Reads the AL event
/// request register; the slave runtime (SM2/SM3 exchange, ESM, mailbox hand-off)
/// plugs in here.
#[embassy_executor::task]
async fn cyclic(
    mut esc: Esc,
    mut irq: ExtiInput<'static, Async>,
    mut sync0: ExtiInput<'static, Async>,
) {
    use ecat_slave_stack::EscAccess;
    loop {
        match select(irq.wait_for_falling_edge(), sync0.wait_for_falling_edge()).await {
            Either::First(()) => ESC_IRQS.fetch_add(1, Ordering::Relaxed),
            Either::Second(()) => SYNC0S.fetch_add(1, Ordering::Relaxed),
        };
        match esc.al_event() {
            Ok(ev) => AL_EVENT.store(ev, Ordering::Relaxed),
            Err(_) => {
                ESC_ERRORS.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
}

/// Touch probe 2: latches the encoder count at each IN2 edge (software latch; the
/// EXTI-to-task latency is the error, to be measured on the board). Touch probe 1
/// (IN1) is latched by TIM2 CH4 in hardware.
#[embassy_executor::task]
async fn touch_probe2(mut in2: ExtiInput<'static, Async>, enc: Encoder) {
    loop {
        in2.wait_for_any_edge().await;
        PROBE2_POS.store(enc.position(), Ordering::Relaxed);
        PROBE2_EDGES.fetch_add(1, Ordering::Relaxed);
    }
}

/// Start-up current-sensor check (bridges off, so the currents are zero), then the
/// watchdog policy and a status line every second.
#[embassy_executor::task]
async fn supervisor(
    mut wdg: IndependentWatchdog<'static, IWDG>,
    flash: Option<ParamFlash>,
    enc: Encoder,
) {
    offset_self_check(&mut wdg).await;
    if let Some(mut f) = flash {
        report_param_region(&mut f);
    }

    let mut ticker = Ticker::every(Duration::from_millis(10));
    let mut last_samples = CURRENT_SAMPLES.count();
    let mut ticks: u32 = 0;
    loop {
        ticker.next().await;
        let n = CURRENT_SAMPLES.count();
        if n != last_samples {
            wdg.pet();
            last_samples = n;
        }
        if let Some(z) = enc.index_capture() {
            defmt::info!("encoder index at count {=u32}", z);
        }
        if let Some(pos) = enc.probe1_capture() {
            defmt::info!("touch probe 1 at count {=u32}", pos);
        }
        ticks = ticks.wrapping_add(1);
        if ticks.is_multiple_of(100) {
            status_line(&enc);
        }
    }
}

async fn offset_self_check(wdg: &mut IndependentWatchdog<'static, IWDG>) {
    let mut cal = OffsetCalibrator::new(board::OFFSET_SAMPLES);
    let mut last = CURRENT_SAMPLES.count();
    let mut idle = 0u32;
    // New samples arrive every 25 µs; give up after 10 ms without one.
    while !cal.is_complete() && idle < 200 {
        Timer::after_micros(50).await;
        match CURRENT_SAMPLES.latest() {
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
        Ok(o) => defmt::info!(
            "current-sensor offsets: A {=f32} B {=f32} counts ({=u32} samples)",
            o.ia,
            o.ib,
            cal.count()
        ),
        Err(e) => {
            hw::safety::raise_fault(hw::safety::FAULT_CURRENT_SENSING);
            defmt::error!(
                "fault 9, current-sensor self-check: {}",
                defmt::Debug2Format(&e)
            );
        }
    }
}

/// The parameter-record store in the flash region: two slots of half the region
/// each (offsets relative to [`ParamFlash`]).
const PARAM_STORE: firmware::storage::Storage =
    firmware::storage::Storage::new(0, board::PARAM_FLASH_SIZE / 2);

/// Validates both record slots at start-up (magic, version, CRC) and logs what they
/// hold. Applying the newest record to the object dictionary (`Storage::load`) needs
/// the drive's dictionary and is wired with it.
fn report_param_region(f: &mut ParamFlash) {
    use firmware::storage::SlotStatus;
    if let Err(e) = PARAM_STORE.check(f) {
        defmt::error!("parameter store layout: {}", defmt::Debug2Format(&e));
        return;
    }
    let (slots, newest) = PARAM_STORE.scan(f);
    for (i, s) in slots.iter().enumerate() {
        let at = board::PARAM_FLASH_OFFSET + PARAM_STORE.slot_address(i);
        match *s {
            SlotStatus::Erased => {
                defmt::info!("parameter slot {=usize} @ {=u32:#x}: erased", i, at)
            }
            SlotStatus::Valid {
                sequence,
                payload_len,
            } => defmt::info!(
                "parameter slot {=usize} @ {=u32:#x}: record {=u32}, {=u32} bytes",
                i,
                at,
                sequence,
                payload_len
            ),
            SlotStatus::Corrupt => {
                defmt::warn!("parameter slot {=usize} @ {=u32:#x}: corrupt", i, at)
            }
        }
    }
    match newest {
        Some((slot, seq, _)) => defmt::info!(
            "parameters: newest record {=u32} in slot {=usize}",
            seq,
            slot
        ),
        None => defmt::info!("parameters: no saved record, defaults apply"),
    }
}

fn status_line(enc: &Encoder) {
    let (used, avail) = hw::stack::high_water();
    match CURRENT_SAMPLES.latest() {
        Some((n, s)) => defmt::info!(
            "samples {=u32}: I_A {=u16} I_B {=u16} V_BUS {=f32} V | enc {=u32} | AL event {=u32:#x} irq {=u32} sync0 {=u32} err {=u32} | in {=u8:#07b} | fault {=u8} break {=u8} adc2-late {=u32} | ISR max {=u32} cycles | stack {=usize}/{=usize} B",
            n,
            s.ia,
            s.ib,
            board::ANALOG.volts(s.vbus),
            enc.position(),
            AL_EVENT.load(Ordering::Relaxed),
            ESC_IRQS.load(Ordering::Relaxed),
            SYNC0S.load(Ordering::Relaxed),
            ESC_ERRORS.load(Ordering::Relaxed),
            INPUTS.load(Ordering::Relaxed),
            hw::safety::active_fault(),
            hw::pwm::break_latched(),
            hw::adc::adc2_late_count(),
            hw::adc::isr_max_cycles(),
            used,
            avail
        ),
        None => defmt::warn!("no current samples (PWM/ADC chain not running)"),
    }
    let probes = PROBE2_EDGES.load(Ordering::Relaxed);
    if probes != 0 {
        defmt::info!(
            "touch probe 2: {=u32} edges, last at {=u32}",
            probes,
            PROBE2_POS.load(Ordering::Relaxed)
        );
    }
}

/// Green: on while powered. Red: the active fault number as a flash code
/// (`firmware::fault_led`: N pulses of 150 ms, repeating every 3 s). RUN/ERR follow
/// the EtherCAT state machine (ETG.1300) once the slave runtime is wired; off until then.
#[embassy_executor::task]
async fn led_task(mut leds: io::Leds<'static>) {
    leds.green.set_high();
    leds.run.set_low();
    leds.err.set_low();
    let mut red = firmware::fault_led::FaultLed::new();
    let mut ticker = Ticker::every(Duration::from_millis(10));
    loop {
        ticker.next().await;
        let now_ms = Instant::now().as_millis() as u32;
        let code = hw::safety::active_fault();
        leds.red.set_level(red.update(Some(code), now_ms).into());
    }
}

/// Inputs sampled every millisecond, accepted after 3 equal samples; outputs and the
/// brake written from the requested state (brake engaged while a fault is active).
#[embassy_executor::task]
async fn io_task(mut ports: io::Ports<'static>) {
    let mut ticker = Ticker::every(Duration::from_millis(1));
    let mut history = [0u8; 3];
    let mut i = 0usize;
    loop {
        ticker.next().await;
        history[i] = ports.read_inputs();
        i = (i + 1) % history.len();
        if history.iter().all(|&h| h == history[0]) {
            INPUTS.store(history[0], Ordering::Relaxed);
        }
        ports.write_outputs(OUTPUTS.load(Ordering::Relaxed));
        if hw::safety::active_fault() != 0 {
            ports.set_brake_released(false);
        }
    }
}
