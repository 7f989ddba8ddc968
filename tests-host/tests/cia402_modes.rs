//! CiA 402 drive profile on the host: a first-order simulated axis (the actual position
//! follows the demand with a time constant, like a stiff servo), every homing method
//! from many start positions, the PDS against an independent reference model, long
//! randomized runs with garbage controlwords / SDO / PDO values, and the touch probe on
//! a moving axis.
use ecat_slave_stack::od::{self, DataType, ObjectKey, SdoAbort};
use firmware::cia402::objects::{RX_SLOTS, TX_SLOTS};
use firmware::cia402::pds::PdsState;
use firmware::cia402::{mode, sw, Cia402, DriveCommand, DriveFeedback, EdgeLatch, SetpointKind};
use firmware::dictionary::Sdo;

/// The CiA 402 table as the product packs it.
static OBJECTS: &[ecat_slave_stack::od::Object] =
    ecat_slave_stack::packed_dictionary!(&[firmware::cia402::objects::OBJECTS]);

const DT: f32 = 0.001;

#[derive(Clone, Copy, PartialEq, Debug)]
enum HomeSw {
    None,
    Above(i32),
    Below(i32),
    Zone(i32, i32),
}

/// First-order axis: x' = (demand − x)/τ, integrated per cycle in f64, reported in
/// whole counts. Switches act on the true position; index pulses are latched exactly.
struct Axis {
    x: f64,
    v: f64,
    tau: f64,
    nl: i32,
    pl: i32,
    home: HomeSw,
    pitch: i64,
    phase: i64,
    index: Option<i32>,
    probe: EdgeLatch,
    probe_edge: Option<i32>,
    fault: u16,
}

impl Axis {
    fn new(x: i32, tau: f64) -> Axis {
        Axis {
            x: x as f64,
            v: 0.0,
            tau,
            nl: i32::MIN,
            pl: i32::MAX,
            home: HomeSw::None,
            pitch: 1000,
            phase: 100,
            index: None,
            probe: EdgeLatch::default(),
            probe_edge: None,
            fault: 0,
        }
    }
    fn pos(&self) -> i32 {
        self.x.round() as i32
    }
    fn inputs(&self) -> u32 {
        let x = self.pos();
        let mut di = 0;
        if x <= self.nl {
            di |= 1;
        }
        if x >= self.pl {
            di |= 2;
        }
        if match self.home {
            HomeSw::None => false,
            HomeSw::Above(e) => x >= e,
            HomeSw::Below(e) => x <= e,
            HomeSw::Zone(lo, hi) => x >= lo && x <= hi,
        } {
            di |= 4;
        }
        di
    }
    fn feedback(&mut self) -> DriveFeedback {
        DriveFeedback {
            position: self.pos(),
            velocity: self.v.round() as i32,
            digital_inputs: self.inputs(),
            index: self.index.take(),
            probe1: std::mem::take(&mut self.probe),
            fault: self.fault,
            ..Default::default()
        }
    }
    fn apply(&mut self, c: &DriveCommand) {
        let a = self.x;
        if c.drive_enabled {
            if c.kind == SetpointKind::Velocity {
                self.x += c.velocity as f64 * DT as f64;
            } else {
                let k = 1.0 - (-(DT as f64) / self.tau).exp();
                self.x += (c.position as f64 - self.x) * k;
            }
        }
        self.v = (self.x - a) / DT as f64;
        let (lo, hi) = if self.x > a { (a, self.x) } else { (self.x, a) };
        if self.x != a {
            // Index pulses crossed (the first one in the direction of travel).
            let first = if self.x > a {
                let k = ((lo - self.phase as f64) / self.pitch as f64).floor() as i64 + 1;
                k * self.pitch + self.phase
            } else {
                let k = ((hi - self.phase as f64) / self.pitch as f64).ceil() as i64 - 1;
                k * self.pitch + self.phase
            };
            if (first as f64) > lo && (first as f64) <= hi {
                self.index = Some(first as i32);
            }
            // Probe input edge at a fixed position (rising moving +, falling moving −).
            if let Some(e) = self.probe_edge {
                if (e as f64) > lo && (e as f64) <= hi {
                    if self.x > a {
                        self.probe.rising = Some(e);
                    } else {
                        self.probe.falling = Some(e);
                    }
                }
            }
        }
    }
}

fn step(d: &mut Cia402, ax: &mut Axis) -> DriveCommand {
    let fb = ax.feedback();
    let c = d.cycle(&fb, DT);
    ax.apply(&c);
    c
}

fn cw(d: &mut Cia402, ax: &mut Axis, w: u16) -> u16 {
    d.set_controlword(w);
    step(d, ax);
    d.statusword()
}

fn enable(d: &mut Cia402, ax: &mut Axis, m: i8) {
    d.write(0x6060, 0, &[m as u8]).unwrap();
    for w in [0x00, 0x06, 0x07, 0x0F] {
        cw(d, ax, w);
    }
    assert_eq!(d.state(), PdsState::OperationEnabled);
    assert_eq!(d.mode_display(), m);
}

fn sdo_u32(d: &mut Cia402, index: u16, sub: u8, v: u32) {
    let e = od::find_entry(OBJECTS, ObjectKey::new(index, sub)).unwrap();
    d.write(index, sub, &v.to_le_bytes()[..e.byte_len()])
        .unwrap();
}

/// A reference model of the PDS written from the standard's tables, independent of
/// the drive's transition table (quick-stop option fixed to 6: stays in QSA).
fn model(state: PdsState, cw: u16, prev_cw: u16, fault: bool) -> PdsState {
    use PdsState::*;
    if fault && !matches!(state, Fault | FaultReactionActive) {
        return FaultReactionActive;
    }
    if state == Fault {
        return if cw & 0x80 != 0 && prev_cw & 0x80 == 0 && !fault {
            SwitchOnDisabled
        } else {
            Fault
        };
    }
    if state == FaultReactionActive || state == NotReadyToSwitchOn {
        return state;
    }
    let shutdown = cw & 0x87 == 0x06;
    let switch_on = cw & 0x8F == 0x07;
    let enable_op = cw & 0x8F == 0x0F;
    let disable_voltage = cw & 0x82 == 0x00;
    let quick_stop = cw & 0x86 == 0x02;
    match state {
        SwitchOnDisabled if shutdown => ReadyToSwitchOn,
        ReadyToSwitchOn if switch_on || enable_op => SwitchedOn,
        ReadyToSwitchOn if disable_voltage || quick_stop => SwitchOnDisabled,
        SwitchedOn if enable_op => OperationEnabled,
        SwitchedOn if shutdown => ReadyToSwitchOn,
        SwitchedOn if disable_voltage || quick_stop => SwitchOnDisabled,
        OperationEnabled if switch_on => SwitchedOn,
        OperationEnabled if shutdown => ReadyToSwitchOn,
        OperationEnabled if disable_voltage => SwitchOnDisabled,
        OperationEnabled if quick_stop => QuickStopActive,
        QuickStopActive if disable_voltage => SwitchOnDisabled,
        QuickStopActive if enable_op => OperationEnabled,
        s => s,
    }
}

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
}

#[test]
fn pds_matches_reference_model_on_random_controlwords() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let interesting = [
        0x00u16, 0x02, 0x06, 0x07, 0x0F, 0x0B, 0x80, 0x86, 0x8F, 0x1F, 0x04, 0x01, 0x0D,
    ];
    let mut d = Cia402::new();
    d.params.quick_stop_option = 6;
    d.params.fault_reaction_option = 0;
    let mut ax = Axis::new(0, 0.002);
    step(&mut d, &mut ax); // transition 1
    let mut prev = 0u16;
    let mut seen = std::collections::HashSet::new();
    for _ in 0..50_000 {
        let w = if rng.below(4) == 0 {
            rng.next() as u16
        } else {
            interesting[rng.below(interesting.len() as u64) as usize]
        };
        let fault = rng.below(50) == 0;
        ax.fault = if fault { 0x5210 } else { 0 };
        let before = d.state();
        let expect = model(before, w, prev, fault);
        d.set_controlword(w);
        let c = step(&mut d, &mut ax);
        let mut got = d.state();
        // The model stops at Fault reaction active; with option 0 the drive reaches
        // Fault in the same cycle (transition 14).
        if expect == PdsState::FaultReactionActive && got == PdsState::Fault {
            got = PdsState::FaultReactionActive;
        }
        // With a 0x605A = 6 quick stop, a stopped axis is held in QSA.
        assert_eq!(got, expect, "from {before:?} cw {w:#06x} fault {fault}");
        let s = d.statusword();
        assert_eq!(PdsState::from_statusword(s), Some(d.state()));
        assert_eq!(c.power_stage, d.state().voltage_enabled());
        if c.drive_enabled {
            assert!(matches!(
                d.state(),
                PdsState::OperationEnabled
                    | PdsState::QuickStopActive
                    | PdsState::FaultReactionActive
            ));
        }
        seen.insert((before as u8, d.state() as u8));
        prev = w;
    }
    // Every edge of the state diagram was exercised.
    assert!(seen.len() >= 20, "{} distinct (from, to) pairs", seen.len());
}

#[test]
fn homing_every_method_from_many_starts_on_a_first_order_axis() {
    let methods: Vec<i8> = (1..=14).chain(17..=30).chain([33, 34, 35, 37]).collect();
    for &method in &methods {
        for &start in &[
            -15_000, -3_000, 0, 1_500, 2_500, 4_000, 5_800, 6_500, 9_000, 15_000,
        ] {
            let mut d = Cia402::new();
            let mut ax = Axis::new(start, 0.003);
            ax.nl = -20_000;
            ax.pl = 20_000;
            ax.home = match method {
                3 | 4 | 19 | 20 => HomeSw::Above(2000),
                5 | 6 | 21 | 22 => HomeSw::Below(2000),
                7..=14 | 23..=30 => HomeSw::Zone(2000, 6000),
                _ => HomeSw::None,
            };
            // The home position each method defines on this axis.
            let idx_up = |x: i32| ((x - 100).div_euclid(1000) + 1) * 1000 + 100; // first index > x
            let idx_dn = |x: i32| ((x - 100 - 1).div_euclid(1000)) * 1000 + 100; // first index < x
            let expect = match method {
                1 => idx_up(-19_999),
                2 => idx_dn(19_999),
                3 | 6 | 7 | 14 => idx_dn(2000),
                4 | 5 | 8 | 13 => idx_up(1999),
                9 | 12 => idx_dn(6000 + 1),
                10 | 11 => idx_up(6000),
                17 => -19_999,
                18 => 19_999,
                19 | 23 | 30 => 1_999,
                20 | 22 | 24 | 29 => 2_000,
                21 => 2_001,
                25 | 28 => 6_000,
                26 | 27 => 6_001,
                33 => idx_dn(start),
                34 => idx_up(start),
                _ => start,
            };
            d.params.homing_method = method;
            sdo_u32(&mut d, 0x6099, 1, 10_000);
            sdo_u32(&mut d, 0x6099, 2, 1_000);
            sdo_u32(&mut d, 0x609A, 0, 100_000);
            sdo_u32(&mut d, 0x607C, 0, (-42i32) as u32);
            d.params.position_window = 1;
            enable(&mut d, &mut ax, mode::HM);
            let mut n = 0;
            loop {
                let s = cw(&mut d, &mut ax, 0x1F);
                assert_eq!(
                    s & sw::HOMING_ERROR,
                    0,
                    "method {method} start {start}: error at {}",
                    ax.pos()
                );
                if s & 0x3400 == 0x1400 {
                    break;
                }
                n += 1;
                assert!(
                    n < 80_000,
                    "method {method} start {start}: timeout at {}",
                    ax.pos()
                );
            }
            for _ in 0..50 {
                cw(&mut d, &mut ax, 0x1F);
            }
            assert!(
                (ax.pos() - expect).abs() <= 1,
                "method {method} start {start}: ended at {} instead of {expect}",
                ax.pos()
            );
            assert!(
                (d.position_actual() + 42).abs() <= 1,
                "method {method} start {start}: 6064 = {}",
                d.position_actual()
            );
            assert_eq!(d.statusword() & 0x3400, 0x1400);
        }
    }
}

#[test]
fn pp_sequence_on_first_order_axis_with_window_time() {
    let mut d = Cia402::new();
    let mut ax = Axis::new(0, 0.005);
    sdo_u32(&mut d, 0x6081, 0, 80_000);
    sdo_u32(&mut d, 0x6083, 0, 800_000);
    sdo_u32(&mut d, 0x6084, 0, 400_000);
    sdo_u32(&mut d, 0x6067, 0, 20);
    sdo_u32(&mut d, 0x6068, 0, 5);
    sdo_u32(&mut d, 0x6065, 0, 2_000);
    enable(&mut d, &mut ax, mode::PP);
    let mut rng = Rng(77);
    for _ in 0..20 {
        let target = rng.below(200_000) as i32 - 100_000;
        sdo_u32(&mut d, 0x607A, 0, target as u32);
        let s = cw(&mut d, &mut ax, 0x3F);
        assert_ne!(s & sw::SETPOINT_ACKNOWLEDGE, 0);
        assert_eq!(s & sw::TARGET_REACHED, 0);
        let s = cw(&mut d, &mut ax, 0x2F);
        assert_eq!(s & sw::SETPOINT_ACKNOWLEDGE, 0);
        let mut n = 0;
        let mut in_window_since: Option<usize> = None;
        loop {
            let s = cw(&mut d, &mut ax, 0x2F);
            assert_eq!(s & sw::FOLLOWING_ERROR, 0, "following error");
            assert!(d.following_error().abs() <= 2_000);
            if (ax.pos() - target).abs() <= 20 && d.position_demand() == target {
                in_window_since.get_or_insert(n);
            } else {
                in_window_since = None;
            }
            if s & sw::TARGET_REACHED != 0 {
                // Reached only after 0x6068 = 5 ms inside the window.
                let since = in_window_since.expect("reached while outside the window");
                assert!(
                    n - since >= 4,
                    "window time respected ({} cycles)",
                    n - since
                );
                break;
            }
            n += 1;
            assert!(n < 20_000);
        }
    }
}

#[test]
fn touch_probe_on_a_moving_axis() {
    let mut d = Cia402::new();
    let mut ax = Axis::new(0, 0.002);
    ax.probe_edge = Some(5_000);
    enable(&mut d, &mut ax, mode::PV);
    // Probe 1: input, continuous, both edges; probe 2: index, first event, rising.
    d.write(0x60B8, 0, &0x1533u16.to_le_bytes()).unwrap();
    d.params.target_velocity = 20_000;
    for _ in 0..600 {
        cw(&mut d, &mut ax, 0x0F);
    }
    let mut buf = [0u8; 4];
    d.read(0x60BA, 0, &mut buf).unwrap();
    assert_eq!(i32::from_le_bytes(buf), 5_000);
    d.read(0x60BC, 0, &mut buf).unwrap();
    assert_eq!(
        i32::from_le_bytes(buf),
        100,
        "first index pulse after the start"
    );
    d.read(0x60B9, 0, &mut buf[..2]).unwrap();
    let st = u16::from_le_bytes([buf[0], buf[1]]);
    assert_eq!(st & 0x0707, 0x0303);
    // Back through the edge: the falling value.
    d.params.target_velocity = -20_000;
    for _ in 0..800 {
        cw(&mut d, &mut ax, 0x0F);
    }
    d.read(0x60BB, 0, &mut buf).unwrap();
    assert_eq!(i32::from_le_bytes(buf), 5_000);
    d.read(0x60BC, 0, &mut buf).unwrap();
    assert_eq!(
        i32::from_le_bytes(buf),
        100,
        "probe 2 single event: unchanged"
    );
}

#[test]
fn dictionary_types_lengths_and_access() {
    let mut d = Cia402::new();
    for o in OBJECTS {
        for e in o.entries() {
            let mut buf = [0u8; 8];
            let n = d.read(o.index, e.sub, &mut buf).unwrap();
            assert_eq!(n, e.byte_len(), "{:#06x}:{}", o.index, e.sub);
            assert!(!e.data_type.is_variable_length());
            let (bits, _, _) = od::type_range(e.data_type);
            assert_eq!(bits, e.bits());
            if !e.access.writable() {
                assert_eq!(
                    d.write(o.index, e.sub, &buf[..n]),
                    Err(SdoAbort::WriteReadOnly)
                );
            } else if e.sub != 0 || o.entries().len() == 1 {
                // Writing back the value read is accepted (except when a rule forbids it).
                let r = d.write(o.index, e.sub, &buf[..n]);
                assert!(r.is_ok(), "{:#06x}:{} {:?}", o.index, e.sub, r);
            }
            assert!(
                !e.pdo_mappable().rx() || e.access.writable(),
                "Rx-mappable must be writable"
            );
        }
    }
    // Every mappable entry in the tables is at most 32 bits.
    for &(i, s) in RX_SLOTS.iter().chain(TX_SLOTS) {
        assert!(
            od::find_entry(OBJECTS, ObjectKey::new(i, s))
                .unwrap()
                .bits()
                <= 32
        );
    }
    // Signed entries sign-extend.
    d.write(0x607C, 0, &(-5i32).to_le_bytes()).unwrap();
    assert_eq!(d.value(0x607C, 0), Some(-5));
    let e = od::find_entry(OBJECTS, ObjectKey::new(0x6060, 0)).unwrap();
    assert_eq!(e.data_type, DataType::Integer8);
}

#[test]
fn random_garbage_never_panics_and_states_stay_consistent() {
    let mut rng = Rng(0xDEAD_BEEF);
    let mut d = Cia402::new();
    let mut ax = Axis::new(0, 0.002);
    ax.nl = -1_000_000;
    ax.pl = 1_000_000;
    ax.home = HomeSw::Zone(-500, 500);
    for i in 0..200_000u32 {
        match rng.below(20) {
            0 => {
                let slot = rng.below(RX_SLOTS.len() as u64 + 3) as u8;
                d.set_rx_raw(slot, rng.next() as u32);
            }
            1 => {
                let o = &OBJECTS[rng.below(OBJECTS.len() as u64) as usize];
                let e = &o.entries()[rng.below(o.entries().len() as u64) as usize];
                let v = rng.next().to_le_bytes();
                let len = rng.below(6) as usize;
                let _ = d.write(o.index, e.sub, &v[..len]);
            }
            2 => {
                // Sensible values now and then so that motion really happens.
                d.params.profile_velocity = rng.below(100_000) as u32;
                d.params.target_velocity = rng.below(100_000) as i32 - 50_000;
                d.params.target_position = rng.below(2_000_000) as i32 - 1_000_000;
                d.params.quick_stop_option = rng.below(9) as i16;
                d.set_mode([0i8, 1, 3, 6, 8, 9][rng.below(6) as usize]);
            }
            3 if rng.below(100) == 0 => {
                d.params.abort_connection_option = rng.below(4) as i16;
                d.on_connection_lost(0x8700);
            }
            4 if rng.below(100) == 0 => d.on_esm_init(),
            _ => {}
        }
        let w = [
            0x06u16, 0x07, 0x0F, 0x1F, 0x3F, 0x5F, 0x10F, 0x80, 0x00, 0x0B,
        ][rng.below(10) as usize];
        d.set_controlword(if rng.below(8) == 0 {
            rng.next() as u16
        } else {
            w
        });
        ax.fault = if rng.below(3000) == 0 { 0x2310 } else { 0 };
        let fb = ax.feedback();
        let dt = if i % 1000 == 0 {
            [0.0, -1.0, f32::NAN, 10.0][rng.below(4) as usize]
        } else {
            DT
        };
        let c = d.cycle(&fb, dt);
        ax.apply(&c);
        let s = d.statusword();
        assert_eq!(PdsState::from_statusword(s), Some(d.state()), "sw {s:#06x}");
        assert_eq!(c.power_stage, d.state().voltage_enabled());
        assert!(c.velocity.is_finite());
        if !c.drive_enabled {
            assert_eq!(
                c.position, fb.position,
                "disabled: demand tracks the actual position"
            );
        }
    }
}

#[test]
fn csp_following_error_supervision_on_lagging_axis() {
    let mut d = Cia402::new();
    let mut ax = Axis::new(0, 0.050); // a slow axis
    sdo_u32(&mut d, 0x6065, 0, 500);
    sdo_u32(&mut d, 0x6066, 0, 20);
    enable(&mut d, &mut ax, mode::CSP);
    let mut t = 0i32;
    let mut n = 0;
    while d.state() == PdsState::OperationEnabled {
        t += 100; // 100 000 counts/s: lag 5 000 counts
        d.write(0x607A, 0, &t.to_le_bytes()).unwrap();
        cw(&mut d, &mut ax, 0x0F);
        n += 1;
        assert!(n < 1000);
    }
    assert_eq!(d.error_code(), 0x8611);
    // Reset after the axis has stopped.
    for _ in 0..200 {
        cw(&mut d, &mut ax, 0x00);
    }
    cw(&mut d, &mut ax, 0x80);
    assert_eq!(d.state(), PdsState::SwitchOnDisabled);
    assert_eq!(d.error_code(), 0);
}

#[test]
fn random_feedback_and_raw_parameters_never_panic() {
    let mut rng = Rng(0x1234_5678_9ABC_DEF1);
    let mut d = Cia402::new();
    for i in 0..100_000u32 {
        if i % 97 == 0 {
            // Parameters written directly (the struct is public): any bit pattern.
            let p = &mut d.params;
            p.quick_stop_option = rng.next() as i16;
            p.halt_option = rng.next() as i16;
            p.fault_reaction_option = rng.next() as i16;
            p.shutdown_option = rng.next() as i16;
            p.disable_op_option = rng.next() as i16;
            p.max_profile_velocity = rng.next() as u32;
            p.max_motor_speed = rng.next() as u32;
            p.profile_velocity = rng.next() as u32;
            p.profile_acceleration = rng.next() as u32;
            p.profile_deceleration = rng.next() as u32;
            p.quick_stop_deceleration = rng.next() as u32;
            p.max_acceleration = rng.next() as u32;
            p.max_deceleration = rng.next() as u32;
            p.start_stop_speed = rng.next() as u32;
            p.motion_profile_type = [0i16, 3, 7, -1][rng.below(4) as usize];
            p.homing_method = rng.next() as i8;
            p.homing_speed_switch = rng.next() as u32;
            p.homing_speed_zero = rng.next() as u32;
            p.homing_acceleration = rng.next() as u32;
            p.interpolation_period = rng.next() as u8;
            p.interpolation_index = rng.next() as i8;
            p.sw_limit_min = rng.next() as i32;
            p.sw_limit_max = rng.next() as i32;
            p.polarity = rng.next() as u8;
            p.target_position = rng.next() as i32;
            p.target_velocity = rng.next() as i32;
            p.position_offset = rng.next() as i32;
            p.velocity_offset = rng.next() as i32;
            p.following_error_window = rng.next() as u32;
            p.positioning_option = rng.next() as u16;
            d.set_mode([0i8, 1, 3, 6, 8, 9][rng.below(6) as usize]);
            d.set_rx_raw(19, rng.next() as u32);
        }
        d.set_controlword(
            [0x0Fu16, 0x1F, 0x3F, 0x7F, 0x21F, 0x10F, 0x06, 0x80][rng.below(8) as usize],
        );
        let some = |r: &mut Rng| {
            if r.below(4) == 0 {
                Some(r.next() as i32)
            } else {
                None
            }
        };
        let fb = DriveFeedback {
            position: rng.next() as i32,
            velocity: rng.next() as i32,
            control_effort: rng.next() as i32,
            torque: rng.next() as i16,
            torque_demand: rng.next() as i16,
            current: rng.next() as i16,
            digital_inputs: rng.next() as u32,
            index: some(&mut rng),
            probe1: EdgeLatch {
                rising: some(&mut rng),
                falling: some(&mut rng),
            },
            probe2: EdgeLatch {
                rising: some(&mut rng),
                falling: some(&mut rng),
            },
            fault: if rng.below(500) == 0 {
                rng.next() as u16
            } else {
                0
            },
            power_stage_tripped: rng.below(2) == 0,
            warning: rng.below(2) == 0,
            current_limited: rng.below(2) == 0,
            quick_stop_input: rng.below(50) == 0,
            enable_pending: rng.below(4) == 0,
            stall: some(&mut rng),
        };
        let c = d.cycle(
            &fb,
            [0.001f32, 0.000125, 0.004, 1.0e-9][rng.below(4) as usize],
        );
        assert!(c.velocity.is_finite(), "{}", c.velocity);
        assert_eq!(PdsState::from_statusword(d.statusword()), Some(d.state()));
        let mut buf = [0u8; 4];
        for &(i, s) in TX_SLOTS {
            d.read(i, s, &mut buf).unwrap();
        }
    }
}

#[test]
fn homing_on_a_narrow_switch_zone_and_starts_on_the_edges() {
    // Zone 2 000..2 300 is narrower than the stopping distance at the switch-search
    // speed (20 000²/(2·100 000) = 2 000 counts): the engine must still end on the edge.
    for method in (7i8..=14).chain(23..=30) {
        for &start in &[0, 1_999, 2_000, 2_150, 2_300, 2_301, 5_000] {
            let mut d = Cia402::new();
            let mut ax = Axis::new(start, 0.001);
            ax.nl = -20_000;
            ax.pl = 20_000;
            ax.home = HomeSw::Zone(2000, 2300);
            let idx_up = |x: i32| ((x - 100).div_euclid(1000) + 1) * 1000 + 100;
            let idx_dn = |x: i32| ((x - 100 - 1).div_euclid(1000)) * 1000 + 100;
            let expect = match method {
                7 | 14 => idx_dn(2000),
                8 | 13 => idx_up(1999),
                9 | 12 => idx_dn(2301),
                10 | 11 => idx_up(2300),
                23 | 30 => 1_999,
                24 | 29 => 2_000,
                25 | 28 => 2_300,
                _ => 2_301,
            };
            d.params.homing_method = method;
            d.params.homing_speed_switch = 20_000;
            d.params.homing_speed_zero = 500;
            d.params.homing_acceleration = 100_000;
            d.params.position_window = 1;
            enable(&mut d, &mut ax, mode::HM);
            let mut n = 0;
            while cw(&mut d, &mut ax, 0x1F) & 0x3400 != 0x1400 {
                assert_eq!(
                    d.statusword() & sw::HOMING_ERROR,
                    0,
                    "method {method} start {start}"
                );
                n += 1;
                assert!(
                    n < 100_000,
                    "method {method} start {start}: timeout at {}",
                    ax.pos()
                );
            }
            for _ in 0..20 {
                cw(&mut d, &mut ax, 0x1F);
            }
            assert!(
                (ax.pos() - expect).abs() <= 1,
                "method {method} start {start}: ended at {} instead of {expect}",
                ax.pos()
            );
        }
    }
}
