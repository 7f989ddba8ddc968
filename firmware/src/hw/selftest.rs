//! The board self-test of the `selftest` build (`cargo flash --features selftest`):
//! the peripheral work of each check. What a reading means is decided by
//! `firmware::selftest` (host- and QEMU-tested); this module only takes the readings
//! and prints one `SELFTEST <check>: PASS` / `FAIL (<why>)` line per check and a
//! summary line over defmt.
//!
//! The bridges stay disabled throughout: the current-loop interrupt runs with the
//! power permission withheld (no master, no enable), and nothing here sets MOE. After
//! the summary the green LED is on when every check passed, the red one otherwise;
//! the image then idles. Flash the normal image afterwards.
use embassy_time::{Duration, Instant, Timer};
use firmware::selftest::{self as st, BreakObservation, Summary, Verdict};

use super::{encoder, esc, flash, io, pwm};
use crate::board;

/// Prints the line of one check and counts it.
fn line(sum: &mut Summary, name: &str, v: Verdict) {
    match sum.add(v) {
        Verdict::Pass => defmt::info!("SELFTEST {=str}: PASS", name),
        Verdict::Fail(why) => defmt::error!("SELFTEST {=str}: FAIL ({=str})", name, why),
    }
}

/// What the self-test needs from start-up.
pub struct Parts {
    /// The DIP matrix.
    pub dip: io::Dip<'static>,
    /// The LEDs.
    pub leds: io::Leds<'static>,
    /// The outputs and the brake.
    pub ports: io::Ports<'static>,
    /// The parameter flash (`None` without dual-bank mode).
    pub flash: Option<flash::ParamFlash>,
    /// Encoder counts the shaft must turn by hand: a quarter revolution.
    pub encoder_counts: u32,
}

/// Runs every check in turn; returns the summary.
pub async fn run(mut p: Parts) -> Summary {
    let mut sum = Summary::default();
    defmt::info!("SELFTEST start: bridges stay disabled");

    esc_checks(&mut sum);

    // DIP banks: eight scans 5 ms apart must agree.
    let mut scans = [io::DipBanks { id: 0, function: 0 }; 8];
    for s in scans.iter_mut() {
        *s = p.dip.read();
        Timer::after_millis(5).await;
    }
    defmt::info!("DIP banks: {}", scans[0]);
    line(&mut sum, "DIP banks", st::dip_stable(&scans));

    analog_checks(&mut sum).await;

    // Encoder: turn the shaft by hand within 20 s.
    defmt::info!(
        "SELFTEST encoder: turn the shaft by hand (at least {=u32} counts) within 20 s",
        p.encoder_counts
    );
    let mut turn = st::EncoderTurn::new(encoder::raw_count(), p.encoder_counts);
    let deadline = Instant::now() + Duration::from_secs(20);
    while !turn.update(encoder::raw_count()) && Instant::now() < deadline {
        Timer::after_millis(10).await;
    }
    defmt::info!("encoder moved {=u32} counts", turn.moved());
    line(&mut sum, "encoder", turn.verdict());

    // LEDs, outputs and the brake output: driven high, then low, read at the pad.
    for (name, pin, port, n) in p.leds.pads() {
        line(&mut sum, name, pad_check(pin, port, n).await);
    }
    for (name, pin, port, n) in p.ports.output_pads() {
        line(&mut sum, name, pad_check(pin, port, n).await);
    }

    // A parameter record in the spare slot: the drive's own 'save' of the present
    // parameters, programmed, read back.
    line(&mut sum, "parameter slot", record_check(p.flash.as_mut()));

    // The break input's path.
    line(&mut sum, "break input", st::break_path(force_break()));

    defmt::info!(
        "SELFTEST summary: {=u8} passed, {=u8} failed: {=str}",
        sum.passed,
        sum.failed,
        if sum.all_passed() { "PASS" } else { "FAIL" }
    );
    let ok = sum.all_passed();
    io::set_output(&mut p.leds.green, ok);
    io::set_output(&mut p.leds.red, !ok);
    sum
}

/// ESC identification and a process-RAM word, through the driver the image uses.
fn esc_checks(sum: &mut Summary) {
    let esc_result = crate::with_drive_state(|s| {
        let slave = s.slave.as_mut()?;
        let e = slave.esc_mut();
        Some((
            st::esc_identity(e, esc::ESC_TYPE),
            ecat_slave_stack::EscAccess::read_u8(e, ecat_slave_stack::registers::ESC_TYPE.addr())
                .ok(),
            st::process_ram_word(e, st::SCRATCH_PRAM),
        ))
    })
    .flatten();
    match esc_result {
        Some((id, ty, pram)) => {
            defmt::info!(
                "ESC {=str}: type register {=?}, expected {=u8:#04x}",
                esc::ESC_NAME,
                ty,
                esc::ESC_TYPE
            );
            line(sum, "ESC identity", id);
            line(sum, "process RAM word", pram);
        }
        None => {
            line(
                sum,
                "ESC identity",
                Verdict::Fail("the ESC did not answer at start-up"),
            );
            line(sum, "process RAM word", Verdict::Fail("no ESC"));
        }
    }
}

/// Current-sensor offsets and the bus voltage from the running ADC chain.
async fn analog_checks(sum: &mut Summary) {
    let mut cal = firmware::sampling::OffsetCalibrator::new(board::OFFSET_SAMPLES);
    let mut last = None;
    let mut vbus_counts = 0u16;
    let deadline = Instant::now() + Duration::from_millis(100);
    while !cal.is_complete() && Instant::now() < deadline {
        Timer::after_micros(50).await;
        if let Some((seq, s)) = crate::hw::control::latest_sample() {
            if last != Some(seq) {
                last = Some(seq);
                cal.add(s);
                vbus_counts = s.vbus;
            }
        }
    }
    let offsets = cal.finish(&board::ANALOG);
    if let Ok(o) = &offsets {
        defmt::info!(
            "current-sensor offsets: A {=f32} B {=f32} counts",
            o.ia,
            o.ib
        );
    }
    line(sum, "current-sensor offsets", st::current_offsets(&offsets));
    let mv = (board::ANALOG.volts(vbus_counts) * 1000.0) as u32;
    let limits = firmware::faults::FaultConfig::DEFAULT;
    defmt::info!("bus voltage: {=u32} mV", mv);
    line(
        sum,
        "bus voltage",
        st::bus_voltage(mv, limits.under_voltage_mv, limits.over_voltage_mv),
    );
}

/// Drives `pin` high for 300 ms (an LED is seen lit), reads its pad, then low.
async fn pad_check(
    pin: &mut embassy_stm32::gpio::Output<'static>,
    port: embassy_stm32::pac::gpio::Gpio,
    n: usize,
) -> Verdict {
    io::set_output(pin, true);
    Timer::after_millis(300).await;
    let high = io::pad_high(port, n);
    io::set_output(pin, false);
    Timer::after_millis(20).await;
    st::pin_follows(high, io::pad_high(port, n))
}

/// The parameter-slot check ([`st::record_probe`], the drive's 'save', commit,
/// [`st::record_check`]).
fn record_check(flash: Option<&mut flash::ParamFlash>) -> Verdict {
    use ecat_slave_stack::od::{Dictionary, ObjectKey};
    let Some(flash) = flash else {
        return Verdict::Fail("no parameter flash (option byte DBANK = 0)");
    };
    let save = u32::from_le_bytes(*b"save").to_le_bytes();
    let staged = crate::with_drive_state(|s| {
        let probe = st::record_probe(
            &crate::hw::boot::PARAM_STORE,
            &mut s.drive.store_mut()?.flash,
        );
        let result = match s.slave.as_mut() {
            Some(slave) => {
                let mut rt = slave.runtime_objects(firmware::dictionary::OBJECTS);
                s.drive.write_with_runtime(
                    ObjectKey::new(0x1010, 1),
                    &save,
                    ecat_slave_stack::esm::EsmState::PreOp,
                    &mut rt,
                )
            }
            None => s.drive.write_with_runtime(
                ObjectKey::new(0x1010, 1),
                &save,
                ecat_slave_stack::esm::EsmState::PreOp,
                &mut firmware::drive::NoRuntime,
            ),
        };
        let stage = s.drive.store_mut()?.flash.take_ready();
        Some((probe, result, stage))
    })
    .flatten();
    let Some((probe, result, stage)) = staged else {
        return Verdict::Fail("no parameter store");
    };
    if result.is_err() {
        return Verdict::Fail("the drive refused the save");
    }
    let Some(stage) = stage else {
        return Verdict::Fail("the save staged no record");
    };
    let programmed = flash::commit(flash, stage);
    crate::with_drive_state(|s| {
        let st_flash = &mut s.drive.store_mut()?.flash;
        st_flash.give_back(stage);
        Some(match programmed {
            Ok(()) => st::record_check(&crate::hw::boot::PARAM_STORE, st_flash, probe),
            Err(_) => Verdict::Fail("programming the flash failed"),
        })
    })
    .flatten()
    .unwrap_or(Verdict::Fail("no parameter store"))
}

/// The break check: the pins' rest level and latch, a software break event (TIM1 and
/// TIM8 EGR.BG, RM0440 advanced-control timers, TIMx_EGR: the same break logic
/// as the pin) with MOE off, and
/// the re-arm. The break pins are active low (`pwm::configure`); PA6 is TIM1's
/// BKIN, PD2 TIM8's.
fn force_break() -> BreakObservation {
    use embassy_stm32::pac;
    let active_at_rest =
        !io::pad_high(pac::GPIOA, 6) || !io::pad_high(pac::GPIOD, 2) || pwm::break_latched() != 0;
    for t in [pac::TIM1, pac::TIM8] {
        t.egr().write(|w| w.set_bg(0, true));
    }
    // The break interrupts (above everything else) run at once; give them a few cycles.
    cortex_m::asm::delay(1000);
    let outputs_off_after_force = [pac::TIM1, pac::TIM8]
        .iter()
        .all(|t| !t.bdtr().read().moe());
    let latched_after_force = pwm::break_latched() == 0b11;
    let rearmed = pwm::rearm() && pwm::break_latched() == 0;
    // The break handler raised the over-current fault for the red LED: that is the
    // forced break, not a fault of the board.
    super::safety::clear_fault_after_selftest();
    BreakObservation {
        active_at_rest,
        outputs_off_after_force,
        latched_after_force,
        rearmed,
    }
}
