//! Board firmware: the drive on the STM32G474RE reference board (see [`board`] for
//! the pinout). Built only with `--features board,esc-lan9252` (or `esc-et1100`)
//! `--target thumbv7em-none-eabihf`.
//!
//! This file creates the peripherals, builds the drive state and spawns the tasks.
//! Each task calls one function of the drive runtime (`firmware::runtime`), the same
//! functions the simulator and every master test run, and moves the result to the
//! hardware. The tasks, their priorities and budgets, who owns what and the watchdog
//! policy are described in [`hw`].
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

use defmt::intern;
use defmt_rtt as _;
use ecat_slave_stack::slave::Slave;
use embassy_executor::{InterruptExecutor, SendSpawner, SpawnError, SpawnToken, Spawner};
use embassy_futures::select::{select, Either};
use embassy_stm32::exti::{self, ExtiInput};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::InterruptExt;
use embassy_stm32::{bind_interrupts, dma, gpio::Pull, mode::Async, peripherals, spi::Spi};
use embassy_sync::blocking_mutex::Mutex;
use embassy_time::{Duration, Instant, Ticker, Timer};
use firmware::latch::Edges;
use firmware::runtime::{DipBanks, EsmView, Runtime};

use hw::boot::BoardDrive;
use hw::control::{BoardPath, PROBE2_RAW, SAMPLES};
use hw::encoder::Encoder;
use hw::esc::Esc;
use hw::flash::ParamFlash;
use hw::io;
use hw::lock::{CyclicCeiling, CYCLIC_PRIORITY};

/// An EXTI input line of the board (ESC IRQ, SYNC0, IN2).
type Exti = ExtiInput<'static, Async>;

bind_interrupts!(struct Irqs {
    EXTI1 => exti::InterruptHandler<interrupt::typelevel::EXTI1>;
    EXTI2 => exti::InterruptHandler<interrupt::typelevel::EXTI2>;
    EXTI3 => exti::InterruptHandler<interrupt::typelevel::EXTI3>;
    DMA1_CHANNEL1 => dma::InterruptHandler<peripherals::DMA1_CH1>;
    DMA1_CHANNEL2 => dma::InterruptHandler<peripherals::DMA1_CH2>;
});

/// The interrupt executor of the cyclic path (vector `UART4`, `firmware::irq_priority::CYCLIC`).
static EXECUTOR_CYCLIC: InterruptExecutor = InterruptExecutor::new();

/// `#[interrupt]` (cortex-m-rt's, re-exported by embassy-stm32) checks the name
/// against the device's interrupt enum: a misspelt vector does not compile.
#[interrupt]
fn UART4() {
    // SAFETY: `on_interrupt` runs only here, in the handler of UART4, the interrupt
    // `main` starts EXECUTOR_CYCLIC on; the vector serves nothing else
    // (UART4's pins carry TIM8).
    unsafe { EXECUTOR_CYCLIC.on_interrupt() }
}

/// Shared by the cyclic path and the thread-mode tasks ([`hw`], "Who owns what"): the
/// drive, the slave runtime (`None` if no ESC answered; the drive runs on) and the runtime.
struct DriveState {
    drive: &'static mut BoardDrive,
    slave: Option<&'static mut Slave<Esc>>,
    rt: Runtime,
}

impl DriveState {
    /// The ESM as the LEDs show it.
    fn esm(&self) -> EsmView {
        match self.slave.as_deref() {
            Some(sl) => {
                EsmView::from_al_status(sl.state(), sl.esm().status_word(), sl.esm().code())
            }
            None => EsmView::NO_ESC,
        }
    }
}

/// The lock holds a reference to [`DRIVE_STATE_SLOT`] (a `None` reference is all
/// zeros, so the lock lives in .bss).
static DRIVE_STATE: Mutex<CyclicCeiling, RefCell<Option<&'static mut DriveState>>> =
    Mutex::new(RefCell::new(None));
static mut DRIVE_STATE_SLOT: MaybeUninit<DriveState> = MaybeUninit::uninit();

/// Runs `f` on the drive state under the priority-ceiling lock; `None` before the
/// state exists.
fn with_drive_state<R>(f: impl FnOnce(&mut DriveState) -> R) -> Option<R> {
    DRIVE_STATE.lock(|c| c.try_borrow_mut().ok()?.as_deref_mut().map(f))
}

defmt::timestamp!("{=u64:us}", Instant::now().as_micros());

fn now_us() -> u64 {
    Instant::now().as_micros()
}

/// `Ticker::every`, for the 1 ms tick and the supervisor (not inlined: both tasks
/// share one copy of the time-driver read).
// Measured (cargo xtask size, LAN9252 image): see `hw::pwm::af_pin`.
#[inline(never)]
fn ticker(period: Duration) -> Ticker {
    Ticker::every(period)
}

/// Start-up: the thread executor's first task. It sets up every peripheral, builds
/// the drive state in place and spawns the other tasks.
#[embassy_executor::main]
async fn main(spawner: Spawner) {
    // Gate pins driven low before anything else (`hw::pwm`, "Defined gate levels").
    hw::pwm::hold_gates_low();
    hw::stack::paint();
    let p = embassy_stm32::init(hw::clock::config());
    hw::clock::start_chip();

    let r = board::split(p);
    // Power stage first: the gate-driver inputs get defined (off) levels at once.
    hw::pwm::init(r.power);
    let enc = hw::encoder::init(r.encoder);
    let (leds, ports, mut dip) = io::init(r.io);
    let banks = dip.read();

    let (esc, esc_irq, sync0) = start_esc(r.esc);
    let in2 = ExtiInput::new(r.in2.0, r.in2.1, Pull::None, Irqs);
    for irq in [interrupt::EXTI1, interrupt::EXTI2, interrupt::EXTI3] {
        irq.set_priority(CYCLIC_PRIORITY);
    }

    let (flash, has_slave) = place_drive_state(r.flash, esc, banks);
    hw::adc::init(r.analog);

    let thread_spawner = spawner.make_send();
    // The self-test build: the checks instead of the drive's tasks (bridges off).
    #[cfg(feature = "selftest")]
    {
        let _ = (sync0, esc_irq, in2, enc, r.iwdg, has_slave);
        let parts = hw::selftest::Parts {
            dip,
            leds,
            ports,
            flash,
            encoder_counts: with_drive_state(|s| s.rt.command().motion.counts_per_rev / 4)
                .unwrap_or(0),
        };
        spawn(thread_spawner, selftest(parts), intern!("selftest"));
    }
    #[cfg(not(feature = "selftest"))]
    {
        // Cyclic path, tick and touch probe on the interrupt executor, so a flash
        // commit in thread mode never stops the drive's own clock.
        interrupt::UART4.set_priority(CYCLIC_PRIORITY);
        let cyclic_spawner = EXECUTOR_CYCLIC.start(interrupt::UART4);
        if has_slave {
            spawn(cyclic_spawner, cyclic(sync0), intern!("cyclic"));
            spawn(thread_spawner, ecat(esc_irq, flash), intern!("ecat"));
        }
        spawn(
            cyclic_spawner,
            touch_probe2(in2, enc),
            intern!("touch_probe2"),
        );
        let mut wdg = hw::safety::Watchdog::new(r.iwdg);
        wdg.unleash();
        spawn(cyclic_spawner, tick(leds, ports, dip), intern!("tick"));
        spawn(thread_spawner, supervisor(wdg, enc), intern!("supervisor"));
    }
}

/// The EtherCAT slave controller (`None` when it does not answer: the drive then runs
/// locally), its IRQ line and SYNC0.
fn start_esc(e: board::EscPins) -> (Option<Esc>, Exti, Exti) {
    let spi = Spi::new(
        e.spi,
        e.sck,
        e.mosi,
        e.miso,
        e.tx_dma,
        e.rx_dma,
        Irqs,
        hw::esc::spi_config(),
    );
    let mut esc = hw::esc::new_esc(hw::esc::EscSpi::new(spi, hw::esc::cs_pin(e.cs)));
    let esc_ok = hw::esc::probe_logged(&mut esc);
    let esc_irq = ExtiInput::new(e.irq, e.irq_exti, Pull::Up, Irqs);
    let sync0 = ExtiInput::new(e.sync0, e.sync0_exti, hw::esc::SYNC0_IDLE_PULL, Irqs);
    (esc_ok.then_some(esc), esc_irq, sync0)
}

/// The drive state built in place (flash, drive, slave, power-up, motor control) and
/// put under the lock: the parameter flash for `ecat`, and whether there is a slave.
fn place_drive_state(
    flash: embassy_stm32::Peri<'static, peripherals::FLASH>,
    esc: Option<Esc>,
    banks: io::DipBanks,
) -> (Option<ParamFlash>, bool) {
    let (chip, flash, staged) = hw::boot::start_flash(flash);
    let (drive, mut slave) = hw::boot::place_drive_and_slave(chip, staged, esc);
    let mut rt = Runtime::new(board::SPEC, drive);
    let io::DipBanks { id, function } = banks;
    let dips = DipBanks { id, function };
    let up = match slave.as_deref_mut() {
        Some(s) => rt.power_up(
            drive,
            dips,
            &mut s.runtime_objects(firmware::dictionary::OBJECTS),
        ),
        None => rt.power_up(drive, dips, &mut firmware::drive::NoRuntime),
    };
    hw::log::power_up(&up, banks);
    if let Some(s) = slave.as_deref_mut() {
        s.set_station_alias(up.alias);
        hw::esc::init_logged(s);
    }
    // Motor control in the current-loop interrupt, then the ADCs (which enable it).
    hw::boot::start_control(&rt, drive);
    let has_slave = slave.is_some();
    // SAFETY: start-up runs once, and nothing else takes a reference to
    // DRIVE_STATE_SLOT: this one is unique; afterwards the value is reached only
    // through the lock.
    let slot = unsafe { &mut *core::ptr::addr_of_mut!(DRIVE_STATE_SLOT) };
    let state: &'static mut DriveState = slot.write(DriveState { drive, slave, rt });
    DRIVE_STATE.lock(|c| *c.borrow_mut() = Some(state));
    (flash, has_slave)
}

/// Spawns a task, or logs why it could not.
fn spawn<S: Send>(spawner: SendSpawner, task: Result<SpawnToken<S>, SpawnError>, name: defmt::Str) {
    match task {
        Ok(t) => spawner.spawn(t),
        Err(e) => defmt::error!("spawn {=istr}: {}", name, e),
    }
}

/// The cyclic path (DC mode): one `Slave::cycle` per SYNC0 pulse, between the
/// runtime's `before_step` and `after_step`. In DC mode the ESC IRQ also signals
/// SYNC0, so a thread-mode `poll` that read the AL event just after a SYNC0 edge has
/// already run that cycle (`last_cycle` moved since this task's last call): the edge
/// is then skipped, so every SYNC0 is handled exactly once. Outside DC mode `poll`
/// runs the cycles.
#[embassy_executor::task]
async fn cyclic(mut sync0: Exti) {
    let mut mine: Option<u64> = None;
    loop {
        hw::esc::sync0_edge(&mut sync0).await;
        hw::log::SYNC0S.fetch_add(1, Ordering::Relaxed);
        let now = now_us();
        with_drive_state(|s| {
            s.rt.before_step(s.drive, &mut BoardPath);
            if let Some(slave) = s.slave.as_deref_mut() {
                let sync = slave.sync();
                let dc = sync.mode == ecat_slave_stack::sync::SyncMode::DcSync0;
                if dc && sync.last_cycle == mine && slave.cycle(&mut *s.drive, now).is_err() {
                    hw::log::ESC_ERRORS.fetch_add(1, Ordering::Relaxed);
                }
                mine = slave.sync().last_cycle;
            }
            s.rt.after_step(s.drive, &mut BoardPath);
        });
    }
}

/// EtherCAT in thread mode: `Slave::poll` on each ESC IRQ edge and at least every
/// millisecond, between the runtime's `before_poll` and `after_poll`; a staged flash
/// record is programmed after the lock is released.
#[embassy_executor::task]
async fn ecat(mut irq: Exti, mut flash: Option<ParamFlash>) {
    loop {
        if irq.is_high() {
            let timeout = Timer::after(Duration::from_millis(1));
            if let Either::First(()) = select(irq.wait_for_falling_edge(), timeout).await {
                hw::log::ESC_IRQS.fetch_add(1, Ordering::Relaxed);
            }
        } else {
            // The IRQ line is still asserted: events are pending; let the other
            // thread tasks run once, then poll again.
            embassy_futures::yield_now().await;
        }
        let now = now_us();
        let staged = with_drive_state(|s| {
            s.rt.before_step(s.drive, &mut BoardPath);
            let slave = s.slave.as_deref_mut()?;
            s.rt.before_poll(s.drive, &mut |e| {
                slave.emergency(e.code, e.register, e.data)
            });
            let ok = slave.poll(&mut *s.drive, now).is_ok();
            if !ok {
                hw::log::ESC_ERRORS.fetch_add(1, Ordering::Relaxed);
            }
            let work = s.rt.after_poll(s.drive, &mut BoardPath, ok, now);
            if work.confirmed {
                defmt::info!("firmware: the new image confirmed itself");
            }
            if work.reset {
                defmt::info!("firmware update accepted: reset into the bootloader");
                cortex_m::peripheral::SCB::sys_reset();
            }
            hw::records::next_staged(s.drive)
        })
        .flatten();
        if let Some(stage) = staged {
            let failed = hw::records::commit_logged(flash.as_mut(), stage);
            with_drive_state(|s| {
                if let Some(slave) = s.slave.as_deref_mut() {
                    s.rt.record_committed(s.drive, !failed, &mut |e| {
                        slave.emergency(e.code, e.register, e.data)
                    });
                }
                if let Some(st) = s.drive.store_mut() {
                    st.flash.give_back(stage);
                }
            });
        }
    }
}

/// Touch probe 2: latches the encoder count at each IN2 edge with the edge's
/// direction and hands it to the current-loop interrupt ([`PROBE2_RAW`]). Touch probe
/// 1 (IN1) is latched by TIM2 CH4 in hardware (`hw::control`).
#[embassy_executor::task]
async fn touch_probe2(mut in2: Exti, enc: Encoder) {
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

/// The 1 ms tick, the drive's own clock: [`Runtime::tick`] with the raw inputs and
/// the DIP bank, then the pins it chose.
#[embassy_executor::task]
async fn tick(
    mut leds: io::Leds<'static>,
    mut ports: io::Ports<'static>,
    mut dip: io::Dip<'static>,
) {
    let single_bank = matches!(board::SPEC.dip, firmware::dip::Board::SingleBank(_));
    let mut ticker = ticker(Duration::from_millis(1));
    loop {
        ticker.next().await;
        let raw = ports.read_inputs();
        let dip_bits = if single_bank { dip.read().function } else { 0 };
        let pins = with_drive_state(|s| {
            let esm = s.esm();
            s.rt.tick(s.drive, &mut BoardPath, now_us(), raw, dip_bits, Some(esm))
        });
        if let Some(pins) = pins {
            io::write_pins(&mut leds, &mut ports, &pins);
        }
    }
}

/// Start-up current-sensor check (bridges off, so the currents are zero), then the
/// watchdog policy of the runtime and a status line every second.
#[embassy_executor::task]
async fn supervisor(mut wdg: hw::safety::Watchdog, enc: Encoder) {
    let offsets = hw::adc::offset_self_check(&mut wdg).await;
    with_drive_state(|s| s.rt.offsets_checked(s.drive, &mut BoardPath, offsets));
    let mut ticker = ticker(Duration::from_millis(10));
    let mut ticks: u32 = 0;
    loop {
        ticker.next().await;
        let samples = SAMPLES.sequence();
        let ready = hw::control::ready();
        if with_drive_state(|s| s.rt.feed_watchdog(samples, ready)) == Some(true) {
            wdg.pet();
        }
        ticks = ticks.wrapping_add(1);
        if ticks.is_multiple_of(100) {
            let link =
                with_drive_state(|s| hw::log::link_status(s.slave.as_deref())).unwrap_or_default();
            hw::log::status_line(
                hw::control::latest_sample(),
                enc.position(),
                link,
                hw::control::feedback().map(|(_, f)| f),
            );
        }
    }
}

/// The self-test build's one task (`hw::selftest`).
#[cfg(feature = "selftest")]
#[embassy_executor::task]
async fn selftest(parts: hw::selftest::Parts) {
    hw::selftest::run(parts).await;
}
