extern crate std;

use std::vec::Vec;

use super::*;
use crate::dictionary;
use crate::drive::{AxisState, NoRuntime, NoStore};
use crate::identity::Variant;
use ecat_slave_stack::esm::EsmHooks;
use ecat_slave_stack::od::{self, ObjectKey, SdoAbort};

const SPEC: BoardSpec = BoardSpec {
    dip: dip::Board::TwoBanks,
    motor: crate::motion::ECN57_20,
    servo_ts: crate::motion::SERVO_TS,
    pwm_ts: 25e-6,
    pwm_arr: 2125,
};

/// A control path that measures what the test sets and keeps what it is sent.
#[derive(Default)]
struct FakePath {
    axis: AxisState,
    seq: u32,
    latched: bool,
    rearm_ok: bool,
    sent: Vec<ControlCommand>,
    rearms: u32,
    /// The bridges do not switch on (a power stage that fails to start).
    bridges_dead: bool,
    /// The bridges went off since the last measurements (a trip between them).
    tripped_between: bool,
}

impl ControlPath for FakePath {
    fn feedback(&mut self) -> Option<(u32, Feedback)> {
        self.seq += 1;
        Some((
            self.seq,
            Feedback {
                axis: self.axis,
                bridges_on: !self.bridges_dead
                    && self.sent.last().is_some_and(|c| c.permits_power()),
                ..Feedback::default()
            },
        ))
    }
    fn break_latched(&self) -> bool {
        self.latched
    }
    fn bridges_on_now(&self) -> bool {
        !self.bridges_dead
            && !self.tripped_between
            && self.sent.last().is_some_and(|c| c.permits_power())
    }
    fn send(&mut self, command: &ControlCommand) {
        self.sent.push(*command);
    }
    fn rearm_break(&mut self) -> bool {
        self.rearms += 1;
        if self.rearm_ok {
            self.latched = false;
        }
        self.rearm_ok
    }
    fn drain_trace(&mut self, _wanted: bool, _sink: &mut dyn FnMut(&ServoPoint)) {}
}

fn sdo_write(d: &mut Drive, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbort> {
    let e = od::find_entry(dictionary::OBJECTS, ObjectKey::new(index, sub))?;
    od::check_write(e, data, EsmState::PreOp)?;
    d.write(ObjectKey::new(index, sub), data, EsmState::PreOp)
}

fn read_u32(d: &mut Drive, index: u16, sub: u8) -> u32 {
    let mut b = [0u8; 8];
    let n = d.read(ObjectKey::new(index, sub), &mut b).expect("read");
    let mut v = [0u8; 4];
    v[..n.min(4)].copy_from_slice(&b[..n.min(4)]);
    u32::from_le_bytes(v)
}

fn started(
    spec: BoardSpec,
    banks: DipBanks,
    before: impl FnOnce(&mut Drive),
) -> (Drive, Runtime, FakePath) {
    let mut d = Drive::new(Variant::HybridServo, 1);
    before(&mut d);
    let mut rt = Runtime::new(spec, &d);
    let mut path = FakePath {
        axis: AxisState {
            bus_mv: 48_000,
            ..AxisState::default()
        },
        ..FakePath::default()
    };
    rt.power_up(&mut d, banks, &mut NoRuntime);
    rt.offsets_checked(&mut d, &mut path, Some((2048.0, 2048.0)));
    (d, rt, path)
}

fn ticks(d: &mut Drive, rt: &mut Runtime, path: &mut FakePath, from_ms: u64, n: u64) -> Pins {
    let mut pins = Pins::default();
    for k in 0..n {
        pins = rt.tick(d, path, (from_ms + k) * 1000, 0, 0, None);
    }
    pins
}

fn enable(d: &mut Drive, rt: &mut Runtime, path: &mut FakePath) {
    for cw in [0x06u16, 0x07, 0x0F] {
        d.cia402.set_controlword(cw);
        ticks(d, rt, path, 0, 5);
    }
}

#[test]
fn function_switches_rule_with_control_mode_zero() {
    // EST-584 bank: SW1-SW3 OFF → 8.4 A, SW4 ON full standstill current, SW5 ON CW,
    // SW6/SW7 OFF → 25 ms.
    let banks = DipBanks {
        id: 0x7E,
        function: 0b0001_1000,
    };
    let (mut d, rt, _) = started(SPEC, banks, |d| {
        d.params.set_internal(Param::ControlMode, 0)
    });
    let m = rt.command().motion;
    assert!((m.peak_current - 8.4).abs() < 1e-4);
    assert!(m.reverse);
    assert_eq!(m.holding_percent, 100);
    assert!((m.filter_s - 0.025).abs() < 1e-6);
    // 0x2158 shows the switches and the settings in effect.
    assert_eq!(read_u32(&mut d, 0x2158, 1), 0x7E);
    assert_eq!(read_u32(&mut d, 0x2158, 2), 0b0001_1000);
    assert_eq!(read_u32(&mut d, 0x2158, 3), 1);
    assert_eq!(read_u32(&mut d, 0x2158, 4), 8400);
    assert_eq!(read_u32(&mut d, 0x2158, 5), 100);
    assert_eq!(read_u32(&mut d, 0x2158, 6), 1);
    assert_eq!(read_u32(&mut d, 0x2158, 7), 25_000);
    // 0x2000 still reads the object; the torque scaling follows the switches.
    assert_eq!(read_u32(&mut d, 0x2000, 0), 3200);

    // 0x2025 ≠ 0: the objects rule, the switches are ignored.
    let (mut d, rt, _) = started(SPEC, banks, |d| {
        d.params.set_internal(Param::ControlMode, 5)
    });
    let m = rt.command().motion;
    assert!((m.peak_current - 3.2).abs() < 1e-4);
    assert!(!m.reverse);
    assert_eq!(read_u32(&mut d, 0x2158, 4), 3200);
    assert_eq!(read_u32(&mut d, 0x2158, 6), 0);
    assert_eq!(
        sdo_write(&mut d, 0x2158, 4, &[0, 0]),
        Err(SdoAbort::WriteReadOnly)
    );
}

#[test]
fn a_control_mode_change_reaches_the_control_path_within_10_ms() {
    let banks = DipBanks {
        id: 0x7F,
        function: 0b0000_0111, // SW1-SW3 ON: 2.0 A
    };
    let (mut d, mut rt, mut path) = started(SPEC, banks, |_| {});
    assert!((rt.command().motion.peak_current - 3.2).abs() < 1e-4);
    sdo_write(&mut d, 0x2025, 0, &[0]).unwrap();
    ticks(&mut d, &mut rt, &mut path, 0, 10);
    assert!((rt.command().motion.peak_current - 2.0).abs() < 1e-4);
    assert!((path.sent.last().unwrap().motion.peak_current - 2.0).abs() < 1e-4);
}

#[test]
fn single_bank_station_entry_and_power_up() {
    let spec = BoardSpec {
        dip: dip::Board::SingleBank(dip::Dp3cl::D705),
        ..SPEC
    };
    // Stored station 9, SW8 OFF: functions from SW1-SW7 (DP3CL table: SW1, SW2 ON
    // → 4.2 A), address 9.
    let (mut d, mut rt, mut path) = started(
        spec,
        DipBanks {
            id: 0xFF,
            function: 0b011,
        },
        |d| {
            d.params.set_internal(Param::DipStation, 9);
            d.params.set_internal(Param::ControlMode, 0);
        },
    );
    assert_eq!(d.params.dip().address, 9);
    assert_eq!(d.params.dip().id_bits, 0, "no ID bank on this board");
    assert!((rt.command().motion.peak_current - 4.2).abs() < 1e-4);
    // SW8 ON, SW1-SW7 = 23, SW8 OFF: 0x2156 = 23 (taken at the next power-up).
    for (k, bits) in [0x80 | 23u8, 0x80 | 23, 23].into_iter().enumerate() {
        rt.tick(&mut d, &mut path, k as u64 * 1000, 0, bits, None);
    }
    assert_eq!(read_u32(&mut d, 0x2156, 0), 23);
    assert_eq!(
        d.params.dip().address,
        9,
        "in effect from the next power-up"
    );
    // Power-up with SW8 ON: station entry, no function switches: objects rule.
    let (d, _, _) = started(
        spec,
        DipBanks {
            id: 0,
            function: 0x80 | 5,
        },
        |d| d.params.set_internal(Param::ControlMode, 0),
    );
    assert_eq!(d.params.dip().functions, None);
    assert_eq!(d.params.settings().peak_current_ma, 3200);
}

#[test]
fn alias_from_the_switches_or_the_objects() {
    let mut d = Drive::new(Variant::HybridServo, 1);
    let mut rt = Runtime::new(SPEC, &d);
    let p = rt.power_up(
        &mut d,
        DipBanks {
            id: 0x7A,
            function: 0,
        },
        &mut NoRuntime,
    );
    assert_eq!((p.alias, p.alias_source), (Some(5), AliasSource::Dip));
    let mut d = Drive::new(Variant::HybridServo, 1);
    let p = rt.power_up(
        &mut d,
        DipBanks {
            id: 0x7F,
            function: 0,
        },
        &mut NoRuntime,
    );
    assert_eq!((p.alias, p.alias_source), (None, AliasSource::Sii));
}

#[test]
fn master_outputs_drive_the_pins_and_0x2157() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    let pins = ticks(&mut d, &mut rt, &mut path, 0, 2);
    assert_eq!(pins.outputs & 0b100, 0, "OUT3 inactive, active-high → low");
    assert!(pins.green);
    // OUT3 = 0x60FE bit 18 with its mask bit.
    sdo_write(&mut d, 0x60FE, 1, &(1u32 << 18).to_le_bytes()).unwrap();
    let pins = ticks(&mut d, &mut rt, &mut path, 2, 1);
    assert_eq!(
        pins.outputs & 0b100,
        0,
        "no mask bit: the master does not drive it"
    );
    sdo_write(&mut d, 0x60FE, 2, &(1u32 << 18).to_le_bytes()).unwrap();
    let pins = ticks(&mut d, &mut rt, &mut path, 3, 1);
    assert_eq!(pins.outputs & 0b100, 0b100);
    assert_eq!(read_u32(&mut d, 0x2157, 0) & 0x7, u32::from(pins.outputs));
    assert_eq!(read_u32(&mut d, 0x2157, 0) >> 9 & 1, 1, "green LED");
}

#[test]
fn alarm_output_follows_a_fault_and_brake_follows_the_drive() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    let pins = ticks(&mut d, &mut rt, &mut path, 0, 2);
    // OUT1/OUT2 alarm, active-low: inactive → high.
    assert_eq!(pins.outputs & 0b11, 0b11);
    assert!(!pins.brake_released);
    enable(&mut d, &mut rt, &mut path);
    let pins = ticks(&mut d, &mut rt, &mut path, 20, 2);
    assert!(d.command().drive_enabled);
    assert!(pins.brake_released);
    assert_eq!(read_u32(&mut d, 0x2157, 0) >> 8 & 1, 1);
    // The master sets the brake (0x60FE bit 0 with its mask): engaged.
    sdo_write(&mut d, 0x60FE, 2, &1u32.to_le_bytes()).unwrap();
    sdo_write(&mut d, 0x60FE, 1, &1u32.to_le_bytes()).unwrap();
    assert!(!ticks(&mut d, &mut rt, &mut path, 30, 1).brake_released);
    sdo_write(&mut d, 0x60FE, 1, &0u32.to_le_bytes()).unwrap();
    assert!(ticks(&mut d, &mut rt, &mut path, 31, 1).brake_released);
    // Over-voltage: fault, alarm outputs active (low), brake engaged, red LED.
    path.axis.bus_mv = 70_000;
    let pins = ticks(&mut d, &mut rt, &mut path, 40, 3);
    assert!(d.faults.any_active());
    assert_eq!(pins.outputs & 0b11, 0);
    assert!(!pins.brake_released);
    assert_eq!(read_u32(&mut d, 0x2157, 0) >> 8 & 1, 0);
}

#[test]
fn brake_never_released_while_the_break_is_latched() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    enable(&mut d, &mut rt, &mut path);
    assert!(ticks(&mut d, &mut rt, &mut path, 20, 1).brake_released);
    path.latched = true;
    for k in 0..5 {
        let pins = rt.tick(&mut d, &mut path, (30 + k) * 1000, 0, 0, None);
        assert!(!pins.brake_released, "tick {k}");
    }
    assert!(d.faults.is_active(crate::faults::FaultKind::OverCurrent));
    // The latch is re-armed only after a command without power was sent.
    assert!(path.rearms > 0);
    assert!(!path.sent.last().unwrap().power_allowed);
}

#[test]
fn counters_follow_the_axis_and_the_command() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    ticks(&mut d, &mut rt, &mut path, 0, 1);
    // 50 000 command units per revolution, 1000 lines × 4 per revolution.
    path.axis.position = 12_500;
    ticks(&mut d, &mut rt, &mut path, 1, 1);
    let counts = read_u32(&mut d, 0x2041, 0) << 16 | read_u32(&mut d, 0x2042, 0);
    let cpr = d.params.get(Param::EncoderResolution) as u32 * 4;
    assert_eq!(counts, cpr / 4);
    path.axis.position = 0;
    ticks(&mut d, &mut rt, &mut path, 2, 1);
    let counts = read_u32(&mut d, 0x2041, 0) << 16 | read_u32(&mut d, 0x2042, 0);
    assert_eq!(counts, 0, "signed sum back to 0");
    // Command pulses: the enabled drive's position set-point changes (a PP move).
    d.on_state_change(EsmState::SafeOp, EsmState::Op);
    enable(&mut d, &mut rt, &mut path);
    let before = read_u32(&mut d, 0x2039, 0) << 16 | read_u32(&mut d, 0x2040, 0);
    sdo_write(&mut d, 0x6060, 0, &[1]).unwrap();
    sdo_write(&mut d, 0x607A, 0, &5000i32.to_le_bytes()).unwrap();
    ticks(&mut d, &mut rt, &mut path, 40, 2);
    d.cia402.set_controlword(0x1F);
    ticks(&mut d, &mut rt, &mut path, 42, 2000);
    let after = read_u32(&mut d, 0x2039, 0) << 16 | read_u32(&mut d, 0x2040, 0);
    assert_eq!(d.command().position, 5000);
    assert_eq!(
        after.wrapping_sub(before),
        5000,
        "the move's set-points were counted"
    );
}

#[test]
fn watchdog_fed_only_with_samples_ticks_and_control() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    assert!(!rt.feed_watchdog(1, true), "no tick ran yet");
    ticks(&mut d, &mut rt, &mut path, 0, 1);
    assert!(!rt.feed_watchdog(1, false), "control state not installed");
    assert!(rt.feed_watchdog(1, true));
    ticks(&mut d, &mut rt, &mut path, 1, 1);
    assert!(!rt.feed_watchdog(1, true), "no new samples");
    assert!(rt.feed_watchdog(2, true));
    assert!(!rt.feed_watchdog(3, true), "no tick since the last feed");
}

#[test]
fn emergencies_go_to_the_mailbox_before_the_poll() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    path.axis.bus_mv = 70_000;
    ticks(&mut d, &mut rt, &mut path, 0, 3);
    let mut sent = Vec::new();
    rt.before_poll(&mut d, &mut |e| sent.push(e.code));
    assert!(sent.contains(&0x3210), "{sent:x?}");
    let work = rt.after_poll(&mut d, &mut path, true, 0);
    assert!(!work.reset && !work.confirmed);
    let _ = NoStore;
}

#[test]
fn an_esc_that_stops_answering_is_the_loss_of_the_master() {
    use crate::cia402::pds::PdsState;
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    d.on_state_change(EsmState::SafeOp, EsmState::Op);
    enable(&mut d, &mut rt, &mut path);
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
    // PV at speed.
    sdo_write(&mut d, 0x6060, 0, &[3]).unwrap();
    sdo_write(&mut d, 0x60FF, 0, &50_000i32.to_le_bytes()).unwrap();
    ticks(&mut d, &mut rt, &mut path, 20, 200);
    assert!(d.command().velocity > 0.0);
    // The ESC fails: every poll errs. Shorter than ESC_LOSS_US: nothing yet.
    let t0 = 220_000u64;
    for k in 0..99u64 {
        rt.after_poll(&mut d, &mut path, false, t0 + k * 1000);
        rt.tick(&mut d, &mut path, t0 + k * 1000, 0, 0, None);
    }
    assert_eq!(d.cia402.state(), PdsState::OperationEnabled);
    // From ESC_LOSS_US on: the 0x6007 reaction (default 1: fault) on the drive's clock.
    for k in 99..400u64 {
        rt.after_poll(&mut d, &mut path, false, t0 + k * 1000);
        rt.tick(&mut d, &mut path, t0 + k * 1000, 0, 0, None);
    }
    assert_eq!(d.cia402.state(), PdsState::Fault);
    assert!(!d.command().drive_enabled);
    assert!(!rt.pins().brake_released);
    assert!(!rt.command().power_allowed);
}

#[test]
fn brake_released_only_after_the_bridges_are_on_for_the_delay() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    // A power stage that does not start: enabled, but the brake holds.
    path.bridges_dead = true;
    enable(&mut d, &mut rt, &mut path);
    assert!(d.command().drive_enabled);
    for k in 0..50 {
        let pins = rt.tick(&mut d, &mut path, (100 + k) * 1000, 0, 0, None);
        assert!(
            !pins.brake_released,
            "bridges off: brake engaged (tick {k})"
        );
    }
    // The bridges come on; 0x2159 = 30 ms: the brake releases 30 ms later.
    sdo_write(&mut d, 0x2159, 0, &30u16.to_le_bytes()).unwrap();
    path.bridges_dead = false;
    let mut released_at = None;
    for k in 0..100u64 {
        let pins = rt.tick(&mut d, &mut path, (200 + k) * 1000, 0, 0, None);
        // The control path drives the pin from the command: it carries the decision.
        assert_eq!(
            path.sent.last().map(|c| c.brake_released),
            Some(pins.brake_released)
        );
        if pins.brake_released && released_at.is_none() {
            released_at = Some(k);
        }
    }
    let k = released_at.expect("released");
    assert!(
        (30..=32).contains(&k),
        "released {k} ms after the bridges came on"
    );
    // The bridges drop out: engaged at once.
    path.bridges_dead = true;
    assert!(
        !rt.tick(&mut d, &mut path, 400_000, 0, 0, None)
            .brake_released
    );
}

#[test]
fn a_trip_between_two_measurements_engages_the_brake_decision_at_once() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    enable(&mut d, &mut rt, &mut path);
    for k in 0..50 {
        rt.tick(&mut d, &mut path, (100 + k) * 1000, 0, 0, None);
    }
    assert!(rt.pins().brake_released, "released once the bridges held");
    // The interrupt switched its bridges off after its last published measurements
    // (they still say "on"): the decision and 0x2157 engage at this tick, and so
    // does the next cycle's.
    path.tripped_between = true;
    rt.before_step(&mut d, &mut path);
    assert!(!rt.pins().brake_released, "0x2157 at the cycle");
    let pins = rt.tick(&mut d, &mut path, 200_000, 0, 0, None);
    assert!(!pins.brake_released);
    assert_eq!(path.sent.last().map(|c| c.brake_released), Some(false));
}

#[test]
fn a_failed_flash_record_is_an_emergency() {
    let (d, mut rt, _) = started(SPEC, DipBanks::default(), |_| {});
    let mut sent = Vec::new();
    rt.record_committed(&d, true, &mut |e| sent.push(e.code));
    assert!(sent.is_empty());
    rt.record_committed(&d, false, &mut |e| sent.push(e.code));
    assert_eq!(sent, [crate::storage::EMCY_RECORD_CORRUPT]);
}

/// Ticks with the raw input levels `raw` (bit n = IN n+1).
fn ticks_with(d: &mut Drive, rt: &mut Runtime, path: &mut FakePath, from_ms: u64, n: u64, raw: u8) {
    for k in 0..n {
        rt.tick(d, path, (from_ms + k) * 1000, raw, 0, None);
    }
}

#[test]
fn an_input_assigned_probe_latches_the_position_for_touch_probe_1() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    // Touch probe 1 on, input trigger, rising and falling edge, first event.
    sdo_write(&mut d, 0x60B8, 0, &0x0031u16.to_le_bytes()).unwrap();
    path.axis.position = 1234;
    ticks_with(&mut d, &mut rt, &mut path, 0, 5, 0);
    // IN4 without the probe function: its edges latch nothing.
    ticks_with(&mut d, &mut rt, &mut path, 5, 5, 0b1000);
    ticks_with(&mut d, &mut rt, &mut path, 10, 5, 0);
    assert_eq!(
        read_u32(&mut d, 0x60B9, 0) & 0x7,
        0x1,
        "enabled, nothing stored"
    );
    // IN4 assigned "probe" (0x2152:04 = 32): the rising edge stores the position of
    // the tick at which the filtered input changed.
    sdo_write(&mut d, 0x2152, 4, &32u16.to_le_bytes()).unwrap();
    ticks_with(&mut d, &mut rt, &mut path, 15, 5, 0);
    ticks_with(&mut d, &mut rt, &mut path, 20, 5, 0b1000);
    let at_rise = read_u32(&mut d, 0x6064, 0);
    assert_eq!(
        read_u32(&mut d, 0x60B9, 0) & 0x7,
        0x3,
        "rising value stored"
    );
    assert_eq!(read_u32(&mut d, 0x60BA, 0), at_rise);
    // The axis moves, the input drops: the falling value is the new position; the
    // rising one (first event) stays.
    path.axis.position = 5678;
    ticks_with(&mut d, &mut rt, &mut path, 25, 3, 0b1000);
    let at_fall = read_u32(&mut d, 0x6064, 0);
    assert_ne!(at_fall, at_rise);
    ticks_with(&mut d, &mut rt, &mut path, 28, 5, 0);
    assert_eq!(read_u32(&mut d, 0x60B9, 0) & 0x7, 0x7, "both values stored");
    assert_eq!(read_u32(&mut d, 0x60BB, 0), at_fall);
    assert_eq!(read_u32(&mut d, 0x60BA, 0), at_rise);
    // Input polarity (0x2154 bit 3) swaps the edges: the probe function is active
    // while the input is low; re-armed by switching the channel off and on.
    sdo_write(&mut d, 0x2154, 0, &[0x08]).unwrap();
    sdo_write(&mut d, 0x60B8, 0, &0x0000u16.to_le_bytes()).unwrap();
    ticks_with(&mut d, &mut rt, &mut path, 33, 2, 0b1000);
    sdo_write(&mut d, 0x60B8, 0, &0x0011u16.to_le_bytes()).unwrap();
    path.axis.position = 9000;
    ticks_with(&mut d, &mut rt, &mut path, 35, 3, 0b1000);
    assert_eq!(read_u32(&mut d, 0x60B9, 0) & 0x7, 0x1, "no edge yet");
    let at_low = read_u32(&mut d, 0x6064, 0);
    ticks_with(&mut d, &mut rt, &mut path, 38, 3, 0);
    assert_eq!(
        read_u32(&mut d, 0x60B9, 0) & 0x7,
        0x3,
        "falling level = rising edge"
    );
    assert_eq!(read_u32(&mut d, 0x60BA, 0), at_low);
}

/// Whether the last command sent lets the motor hold (bridges permitted, drive enabled).
fn holding(path: &FakePath) -> bool {
    path.sent
        .last()
        .is_some_and(|c| c.permits_power() && c.motion_command().drive_enabled)
}

#[test]
fn disable_engages_the_brake_then_holds_through_the_close_delay() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    sdo_write(&mut d, 0x215A, 0, &40u16.to_le_bytes()).unwrap();
    enable(&mut d, &mut rt, &mut path);
    assert!(ticks(&mut d, &mut rt, &mut path, 20, 5).brake_released);
    let hold_at = path.sent.last().unwrap().command.position;
    // Shutdown (0x605B = 0: the drive function ends at once).
    d.cia402.set_controlword(0x06);
    let mut off_at = None;
    for k in 0..100u64 {
        let pins = rt.tick(&mut d, &mut path, (30 + k) * 1000, 0, 0, None);
        assert!(
            !pins.brake_released,
            "brake engaged from the disable on ({k})"
        );
        assert_eq!(read_u32(&mut d, 0x2157, 0) >> 8 & 1, 0);
        if holding(&path) {
            assert!(off_at.is_none(), "no hold after the bridges went off ({k})");
            let c = path.sent.last().unwrap().command;
            assert_eq!((c.position, c.velocity), (hold_at, 0.0), "at standstill");
        } else {
            off_at.get_or_insert(k);
        }
    }
    assert!(!d.command().drive_enabled);
    let k = off_at.expect("the bridges go off");
    assert!(
        (40..=41).contains(&k),
        "held {k} ms after the brake engaged"
    );
}

#[test]
fn a_fault_ramp_keeps_the_brake_released_and_closes_it_at_its_end() {
    use crate::cia402::pds::PdsState;
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    sdo_write(&mut d, 0x215A, 0, &20u16.to_le_bytes()).unwrap();
    d.on_state_change(EsmState::SafeOp, EsmState::Op);
    enable(&mut d, &mut rt, &mut path);
    sdo_write(&mut d, 0x6060, 0, &[3]).unwrap();
    sdo_write(&mut d, 0x60FF, 0, &50_000i32.to_le_bytes()).unwrap();
    // The axis turns at the demand (the ramp starts from the actual speed).
    path.axis.velocity = 50_000;
    ticks(&mut d, &mut rt, &mut path, 20, 200);
    assert!(rt.pins().brake_released);
    // The master is lost: fault 0x8700, reaction 0x605E = 2 (quick-stop ramp).
    d.on_outputs_lost(ecat_slave_stack::al_status::AlStatusCode::SmWatchdog);
    let (mut ramp_ticks, mut ended_at, mut off_at) = (0, None, None);
    for k in 0..500u64 {
        let pins = rt.tick(&mut d, &mut path, (220 + k) * 1000, 0, 0, None);
        match d.cia402.state() {
            PdsState::FaultReactionActive => {
                ramp_ticks += 1;
                assert!(pins.brake_released, "not at the start of the ramp ({k})");
                assert!(holding(&path));
            }
            PdsState::Fault => {
                let end = *ended_at.get_or_insert(k);
                assert!(!pins.brake_released, "engaged at the end of the ramp ({k})");
                if holding(&path) {
                    assert!(off_at.is_none());
                } else {
                    off_at.get_or_insert(k - end);
                }
            }
            s => panic!("{s:?}"),
        }
    }
    assert!(ramp_ticks > 5, "a ramp ran ({ramp_ticks} ticks)");
    let k = off_at.expect("the bridges go off");
    assert!(
        (20..=21).contains(&k),
        "held {k} ms after the brake engaged"
    );
}

#[test]
fn a_lost_power_stage_engages_the_brake_at_once_with_no_hold() {
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    sdo_write(&mut d, 0x215A, 0, &100u16.to_le_bytes()).unwrap();
    enable(&mut d, &mut rt, &mut path);
    assert!(ticks(&mut d, &mut rt, &mut path, 20, 2).brake_released);
    // The break latches: the over-current cuts the power, brake and bridges at once.
    path.latched = true;
    let pins = rt.tick(&mut d, &mut path, 30_000, 0, 0, None);
    assert!(!pins.brake_released);
    assert!(!holding(&path), "no hold with the break latched");
    // The bridges drop out on their own while enabled, then the drive is disabled:
    // the brake is already engaged and nothing holds the power on.
    let (mut d, mut rt, mut path) = started(SPEC, DipBanks::default(), |_| {});
    sdo_write(&mut d, 0x215A, 0, &100u16.to_le_bytes()).unwrap();
    enable(&mut d, &mut rt, &mut path);
    assert!(ticks(&mut d, &mut rt, &mut path, 20, 2).brake_released);
    path.bridges_dead = true;
    assert!(!ticks(&mut d, &mut rt, &mut path, 30, 1).brake_released);
    d.cia402.set_controlword(0x06);
    ticks(&mut d, &mut rt, &mut path, 31, 1);
    assert!(!rt.command().power_allowed, "no hold without bridges");
}
