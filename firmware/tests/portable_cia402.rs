#![cfg_attr(target_os = "none", no_std, no_main)]
//! CiA 402 power drive system and operating modes, checked cycle by cycle against a
//! simulated axis that follows the position demand with one cycle of delay (ideal
//! servo). Runs on the host and under QEMU.
use firmware::cia402::pds::{PdsState, TRANSITIONS};
use firmware::cia402::{
    mode, sw, AbortConnection, Cia402, DriveCommand, DriveFeedback, EdgeLatch, SetpointArrival,
    ERR_FOLLOWING,
};
use firmware::dictionary::Sdo;

const DT: f32 = 0.001;

#[derive(Clone, Copy, PartialEq)]
enum HomeSw {
    None,
    /// Active for x >= e (positive home switch).
    Above(i32),
    /// Active for x <= e (negative home switch).
    Below(i32),
    /// Active on [lo, hi].
    Zone(i32, i32),
}

/// An ideal axis with limit switches, a home switch and an index pulse.
struct Axis {
    pos: i32,
    vel: i32,
    nl: i32,
    pl: i32,
    home: HomeSw,
    pitch: i32,
    phase: i32,
    index: Option<i32>,
    stuck: bool,
    fault: u16,
    extra_inputs: u32,
    probe1: EdgeLatch,
    /// The motor side is not ready to follow (commutation alignment pending).
    enable_pending: bool,
}

impl Axis {
    fn new(pos: i32) -> Axis {
        Axis {
            pos,
            vel: 0,
            nl: i32::MIN,
            pl: i32::MAX,
            home: HomeSw::None,
            pitch: 1000,
            phase: 100,
            index: None,
            stuck: false,
            fault: 0,
            extra_inputs: 0,
            probe1: EdgeLatch::default(),
            enable_pending: false,
        }
    }
    fn inputs(&self) -> u32 {
        let x = self.pos;
        let mut di = self.extra_inputs;
        if x <= self.nl {
            di |= 1;
        }
        if x >= self.pl {
            di |= 2;
        }
        let h = match self.home {
            HomeSw::None => false,
            HomeSw::Above(e) => x >= e,
            HomeSw::Below(e) => x <= e,
            HomeSw::Zone(lo, hi) => x >= lo && x <= hi,
        };
        if h {
            di |= 4;
        }
        di
    }
    fn feedback(&mut self) -> DriveFeedback {
        DriveFeedback {
            position: self.pos,
            velocity: self.vel,
            digital_inputs: self.inputs(),
            index: self.index.take(),
            probe1: core::mem::take(&mut self.probe1),
            fault: self.fault,
            enable_pending: self.enable_pending,
            ..Default::default()
        }
    }
    fn apply(&mut self, c: &DriveCommand) {
        if !c.drive_enabled || self.stuck {
            self.vel = 0;
            return;
        }
        let a = self.pos;
        let b = c.position;
        // Index pulses at phase + k·pitch crossed by the move a → b.
        if a != b {
            let (lo, hi) = if b > a { (a + 1, b) } else { (b, a - 1) };
            let k0 = (lo - self.phase).div_euclid(self.pitch);
            let mut p = k0 * self.pitch + self.phase;
            if p < lo {
                p += self.pitch;
            }
            if p <= hi {
                // First crossed in the direction of travel.
                self.index = Some(if b > a {
                    p
                } else {
                    let k1 = (hi - self.phase).div_euclid(self.pitch);
                    k1 * self.pitch + self.phase
                });
            }
        }
        self.vel = c.velocity as i32;
        self.pos = b;
    }
}

/// RxPDO slot of 0x60B8 (touch probe function).
fn probe_fn_slot() -> u8 {
    firmware::cia402::objects::rx_slot(0x60B8, 0).unwrap_or(u8::MAX)
}

fn step(d: &mut Cia402, ax: &mut Axis) -> DriveCommand {
    let fb = ax.feedback();
    let c = d.cycle(&fb, DT);
    ax.apply(&c);
    c
}

fn steps(d: &mut Cia402, ax: &mut Axis, n: usize) {
    for _ in 0..n {
        step(d, ax);
    }
}

fn cw(d: &mut Cia402, ax: &mut Axis, word: u16) -> u16 {
    d.set_controlword(word);
    step(d, ax);
    d.statusword()
}

/// Writes the controlword, runs one cycle, returns its command.
fn step_cw(d: &mut Cia402, ax: &mut Axis, word: u16) -> DriveCommand {
    d.set_controlword(word);
    step(d, ax)
}

fn enable(d: &mut Cia402, ax: &mut Axis, m: i8) {
    d.set_mode(m);
    cw(d, ax, 0x0000);
    assert_eq!(d.state(), PdsState::SwitchOnDisabled);
    cw(d, ax, 0x0006);
    assert_eq!(d.state(), PdsState::ReadyToSwitchOn);
    cw(d, ax, 0x0007);
    assert_eq!(d.state(), PdsState::SwitchedOn);
    let s = cw(d, ax, 0x000F);
    assert_eq!(d.state(), PdsState::OperationEnabled);
    assert_eq!(s & 0x6F, 0x27);
    assert_eq!(d.mode_display(), m);
}

fn state_of(sw: u16) -> PdsState {
    PdsState::from_statusword(sw).unwrap()
}

/// Brings a fresh drive into `s` with controlwords (and a fault where needed).
fn reach(s: PdsState) -> (Cia402, Axis) {
    let mut d = Cia402::new();
    let mut ax = Axis::new(0);
    if s == PdsState::NotReadyToSwitchOn {
        return (d, ax);
    }
    d.set_mode(mode::PV);
    d.params.quick_stop_option = 6;
    let path: &[u16] = match s {
        PdsState::SwitchOnDisabled => &[0x00],
        PdsState::ReadyToSwitchOn => &[0x00, 0x06],
        PdsState::SwitchedOn => &[0x00, 0x06, 0x07],
        PdsState::OperationEnabled => &[0x00, 0x06, 0x07, 0x0F],
        PdsState::QuickStopActive => &[0x00, 0x06, 0x07, 0x0F, 0x0B],
        _ => &[0x00, 0x06, 0x07, 0x0F],
    };
    for &w in path {
        cw(&mut d, &mut ax, w);
    }
    if s == PdsState::Fault || s == PdsState::FaultReactionActive {
        // A fault while moving: the reaction (quick-stop ramp) takes a few cycles.
        d.params.target_velocity = 50_000;
        steps(&mut d, &mut ax, 200);
        ax.fault = 0x4310;
        step(&mut d, &mut ax);
        ax.fault = 0;
        if s == PdsState::Fault {
            steps(&mut d, &mut ax, 1000);
        }
    }
    assert_eq!(d.state(), s);
    (d, ax)
}

qemu_runner::tests! {
    fn power_on_is_not_ready_then_switch_on_disabled() {
        let mut d = Cia402::new();
        assert_eq!(d.state(), PdsState::NotReadyToSwitchOn);
        assert_eq!(d.statusword() & 0x4F, 0x00);
        let mut ax = Axis::new(0);
        let s = cw(&mut d, &mut ax, 0x0000);
        assert_eq!(s & 0x4F, 0x40);
        assert!(s & sw::REMOTE != 0);
        assert!(s & sw::VOLTAGE_ENABLED == 0);
    }

    fn every_controlword_transition_of_the_table() {
        // (from, controlword, expected state, transition number)
        let cases: &[(PdsState, u16, PdsState, u8)] = &[
            (PdsState::SwitchOnDisabled, 0x06, PdsState::ReadyToSwitchOn, 2),
            (PdsState::ReadyToSwitchOn, 0x07, PdsState::SwitchedOn, 3),
            (PdsState::ReadyToSwitchOn, 0x0F, PdsState::SwitchedOn, 3),
            (PdsState::SwitchedOn, 0x0F, PdsState::OperationEnabled, 4),
            (PdsState::OperationEnabled, 0x07, PdsState::SwitchedOn, 5),
            (PdsState::SwitchedOn, 0x06, PdsState::ReadyToSwitchOn, 6),
            (PdsState::ReadyToSwitchOn, 0x00, PdsState::SwitchOnDisabled, 7),
            (PdsState::ReadyToSwitchOn, 0x02, PdsState::SwitchOnDisabled, 7),
            (PdsState::OperationEnabled, 0x06, PdsState::ReadyToSwitchOn, 8),
            (PdsState::OperationEnabled, 0x00, PdsState::SwitchOnDisabled, 9),
            (PdsState::SwitchedOn, 0x00, PdsState::SwitchOnDisabled, 10),
            (PdsState::SwitchedOn, 0x02, PdsState::SwitchOnDisabled, 10),
            (PdsState::OperationEnabled, 0x02, PdsState::QuickStopActive, 11),
            (PdsState::QuickStopActive, 0x00, PdsState::SwitchOnDisabled, 12),
            (PdsState::Fault, 0x80, PdsState::SwitchOnDisabled, 15),
            (PdsState::QuickStopActive, 0x0F, PdsState::OperationEnabled, 16),
            // Commands that do nothing in a state.
            (PdsState::SwitchOnDisabled, 0x0F, PdsState::SwitchOnDisabled, 0),
            (PdsState::SwitchOnDisabled, 0x07, PdsState::SwitchOnDisabled, 0),
            (PdsState::ReadyToSwitchOn, 0x06, PdsState::ReadyToSwitchOn, 0),
            (PdsState::Fault, 0x0F, PdsState::Fault, 0),
            (PdsState::OperationEnabled, 0x8F, PdsState::OperationEnabled, 0),
        ];
        for &(from, word, to, n) in cases {
            if n != 0 {
                assert!(TRANSITIONS.iter().any(|t| t.number == n && t.to == to));
            }
            let (mut d, mut ax) = reach(from);
            let s = cw(&mut d, &mut ax, word);
            assert_eq!(d.state(), to, "from {:?} cw {:#x}", from, word);
            assert_eq!(state_of(s), to);
            assert_eq!(s & sw::VOLTAGE_ENABLED != 0, to.voltage_enabled());
        }
    }

    fn fault_reaction_then_fault_then_reset_on_rising_edge_only() {
        let (mut d, mut ax) = reach(PdsState::OperationEnabled);
        d.params.target_velocity = 100_000;
        steps(&mut d, &mut ax, 300);
        assert!(ax.vel > 0);
        ax.fault = 0x2310;
        let c = step(&mut d, &mut ax);
        assert_eq!(d.state(), PdsState::FaultReactionActive); // 13
        assert_eq!(d.error_code(), 0x2310);
        assert!(c.drive_enabled); // reaction 2 ramps with the motor controlled
        let mut n = 0;
        while d.state() == PdsState::FaultReactionActive {
            step(&mut d, &mut ax);
            n += 1;
            assert!(n < 1000);
        }
        // 100 000 / 2 000 000 per s² = 50 ms of ramp.
        assert!((45..=56).contains(&n), "{n}");
        assert_eq!(d.state(), PdsState::Fault); // 14
        let c = step(&mut d, &mut ax);
        assert!(!c.power_stage && !c.drive_enabled);
        // Reset while the condition persists: refused.
        cw(&mut d, &mut ax, 0x80);
        assert_eq!(d.state(), PdsState::Fault);
        ax.fault = 0;
        // Bit 7 still high: no new edge, stays in Fault.
        cw(&mut d, &mut ax, 0x80);
        assert_eq!(d.state(), PdsState::Fault);
        cw(&mut d, &mut ax, 0x00);
        cw(&mut d, &mut ax, 0x80);
        assert_eq!(d.state(), PdsState::SwitchOnDisabled); // 15
        assert_eq!(d.error_code(), 0);
    }

    fn fault_reaction_option_0_and_tripped_power_stage_stop_at_once() {
        for (opt, tripped) in [(0i16, false), (2, true)] {
            let (mut d, mut ax) = reach(PdsState::OperationEnabled);
            d.params.fault_reaction_option = opt;
            d.params.target_velocity = 100_000;
            steps(&mut d, &mut ax, 300);
            ax.fault = 0x3210;
            let fb = DriveFeedback { fault: 0x3210, power_stage_tripped: tripped, position: ax.pos, ..Default::default() };
            let c = d.cycle(&fb, DT);
            assert_eq!(d.state(), PdsState::Fault);
            assert!(!c.drive_enabled);
        }
    }

    fn quick_stop_every_option_code() {
        for opt in 0i16..=8 {
            let (mut d, mut ax) = reach(PdsState::OperationEnabled);
            d.params.quick_stop_option = opt;
            d.params.target_velocity = 100_000;
            d.params.profile_deceleration = 400_000;
            d.params.quick_stop_deceleration = 1_000_000;
            d.params.max_deceleration = 5_000_000;
            steps(&mut d, &mut ax, 300);
            let s = cw(&mut d, &mut ax, 0x000B);
            if opt == 0 {
                // Drive function disabled at once: transitions 11 and 12 in one cycle.
                assert_eq!(d.state(), PdsState::SwitchOnDisabled);
                assert_eq!(ax.vel, 0);
                continue;
            }
            assert_eq!(d.state(), PdsState::QuickStopActive, "opt {opt}");
            assert_eq!(s & 0x6F, 0x07);
            assert!(s & sw::ABNORMAL_STOP != 0);
            let mut n: i32 = 1;
            while ax.vel != 0 && n < 2000 {
                step(&mut d, &mut ax);
                n += 1;
            }
            let expect = match opt {
                1 | 5 => 250,
                2 | 6 => 100,
                _ => 20,
            };
            assert!((n - expect).abs() <= 3, "opt {opt}: {n} cycles");
            steps(&mut d, &mut ax, 3);
            if opt <= 4 {
                assert_eq!(d.state(), PdsState::SwitchOnDisabled, "opt {opt}"); // 12
            } else {
                assert_eq!(d.state(), PdsState::QuickStopActive, "opt {opt}");
                assert!(d.statusword() & sw::TARGET_REACHED != 0, "sw {:#x} pos {} demand {}", d.statusword(), ax.pos, d.position_demand());
                let pos = ax.pos;
                steps(&mut d, &mut ax, 50);
                assert_eq!(ax.pos, pos, "held at standstill");
                cw(&mut d, &mut ax, 0x000F);
                assert_eq!(d.state(), PdsState::OperationEnabled); // 16
            }
        }
    }

    fn quick_stop_from_each_mode() {
        for m in [mode::PP, mode::PV, mode::HM, mode::CSP, mode::CSV] {
            let mut d = Cia402::new();
            let mut ax = Axis::new(0);
            ax.home = HomeSw::Above(1_000_000);
            d.params.homing_method = 19;
            enable(&mut d, &mut ax, m);
            d.params.target_position = 1_000_000;
            d.params.target_velocity = 50_000;
            d.params.profile_velocity = 50_000;
            d.params.homing_speed_switch = 50_000;
            let mut csp_target = 0;
            for _ in 0..300 {
                if m == mode::CSP {
                    csp_target += 50;
                    d.params.target_position = csp_target;
                }
                cw(&mut d, &mut ax, 0x001F);
            }
            assert!(ax.vel >= 40_000, "mode {m}: {}", ax.vel);
            cw(&mut d, &mut ax, 0x000B);
            assert_eq!(d.state(), PdsState::QuickStopActive);
            let mut n = 0;
            while d.state() == PdsState::QuickStopActive {
                cw(&mut d, &mut ax, 0x000B);
                n += 1;
                assert!(n < 200, "mode {m}");
            }
            // 0x605A = 2: 50 000 / 2 000 000 = 25 ms.
            assert!((24..=28).contains(&n), "mode {m}: {n}");
            assert_eq!(d.state(), PdsState::SwitchOnDisabled);
        }
    }

    fn disable_operation_and_shutdown_option_codes() {
        // 0x605C = 1: ramp with 0x6084 while still operation enabled, then 5.
        let (mut d, mut ax) = reach(PdsState::OperationEnabled);
        d.params.target_velocity = 100_000;
        d.params.profile_deceleration = 1_000_000;
        steps(&mut d, &mut ax, 300);
        let mut n = 0;
        while d.state() == PdsState::OperationEnabled {
            cw(&mut d, &mut ax, 0x0007);
            n += 1;
            assert!(n < 500);
        }
        assert!((99..=103).contains(&n), "{n}");
        assert_eq!(d.state(), PdsState::SwitchedOn);
        // 0x605C = 0: immediately.
        let (mut d, mut ax) = reach(PdsState::OperationEnabled);
        d.params.disable_op_option = 0;
        d.params.target_velocity = 100_000;
        steps(&mut d, &mut ax, 300);
        cw(&mut d, &mut ax, 0x0007);
        assert_eq!(d.state(), PdsState::SwitchedOn);
        // 0x605B = 1: ramp then 8.
        let (mut d, mut ax) = reach(PdsState::OperationEnabled);
        d.params.shutdown_option = 1;
        d.params.target_velocity = 100_000;
        d.params.profile_deceleration = 1_000_000;
        steps(&mut d, &mut ax, 300);
        cw(&mut d, &mut ax, 0x0006);
        assert_eq!(d.state(), PdsState::OperationEnabled);
        steps(&mut d, &mut ax, 120);
        assert_eq!(d.state(), PdsState::ReadyToSwitchOn);
        assert_eq!(ax.vel, 0);
    }

    fn esm_coupling() {
        let (mut d, mut ax) = reach(PdsState::OperationEnabled);
        assert_eq!(d.on_connection_lost(0x8700), AbortConnection::Fault);
        steps(&mut d, &mut ax, 5);
        assert_eq!(d.state(), PdsState::Fault);
        assert_eq!(d.error_code(), 0x8700);
        // Init keeps the fault (0x603F tells what happened); a fault reset clears it.
        d.on_esm_init();
        assert_eq!(d.state(), PdsState::Fault);
        assert_eq!(d.error_code(), 0x8700);
        cw(&mut d, &mut ax, 0x0080);
        assert_eq!(d.state(), PdsState::SwitchOnDisabled);
        step(&mut d, &mut ax);
        assert_eq!(d.statusword() & 0x4F, 0x40);
        let (mut d, mut ax) = reach(PdsState::SwitchedOn);
        d.on_connection_lost(0x8700);
        step(&mut d, &mut ax);
        assert_eq!(d.state(), PdsState::SwitchOnDisabled);
        // Init from Switched on: Switch on disabled, controlword cleared.
        let (mut d, mut ax) = reach(PdsState::SwitchedOn);
        d.on_esm_init();
        assert_eq!(d.state(), PdsState::SwitchOnDisabled);
        assert_eq!(d.controlword(), 0);
        step(&mut d, &mut ax);
        assert_eq!(d.state(), PdsState::SwitchOnDisabled);
    }

    fn abort_connection_options_in_pv() {
        // Moving in PV at 100 000 inc/s; each 0x6007 option, then 2 s of steps with
        // no further command from the master.
        for option in 0..=3i16 {
            let (mut d, mut ax) = reach(PdsState::OperationEnabled);
            d.params.abort_connection_option = option;
            d.params.quick_stop_option = 2;
            d.params.target_velocity = 100_000;
            d.params.quick_stop_deceleration = 1_000_000;
            d.params.profile_acceleration = 10_000_000;
            steps(&mut d, &mut ax, 100);
            assert_eq!(ax.vel, 100_000);
            let got = d.on_connection_lost(0x8700);
            assert_eq!(got as i16, option);
            let mut stop_ms = None;
            for k in 0..2000 {
                let c = step(&mut d, &mut ax);
                if stop_ms.is_none() && !c.drive_enabled {
                    stop_ms = Some(k + 1);
                }
            }
            match got {
                AbortConnection::NoAction => {
                    // The drive goes on with its last set-points.
                    assert_eq!(d.state(), PdsState::OperationEnabled);
                    assert_eq!(ax.vel, 100_000);
                    assert_eq!(stop_ms, None);
                }
                AbortConnection::Fault => {
                    // 0x605E = 2 (default): quick-stop ramp 0.1 s, then Fault.
                    assert_eq!(d.state(), PdsState::Fault);
                    assert_eq!(d.error_code(), 0x8700);
                    let t = stop_ms.expect("stopped");
                    assert!((100..=102).contains(&t), "ramp took {t} ms");
                }
                AbortConnection::DisableVoltage => {
                    assert_eq!(d.state(), PdsState::SwitchOnDisabled);
                    assert_eq!(stop_ms, Some(1), "power off at once");
                }
                AbortConnection::QuickStop => {
                    // 0x605A = 2: quick-stop ramp, then Switch on disabled.
                    assert_eq!(d.state(), PdsState::SwitchOnDisabled);
                    assert_eq!(d.controlword(), 0x0002);
                    let t = stop_ms.expect("stopped");
                    assert!((100..=102).contains(&t), "ramp took {t} ms");
                }
            }
            if got != AbortConnection::NoAction {
                assert_eq!(ax.vel, 0);
                // Nothing moves afterwards: no enable without a new command sequence.
                let at = ax.pos;
                let c = step(&mut d, &mut ax);
                assert!(!c.drive_enabled && !c.brake_release && !c.power_stage);
                assert_eq!(ax.pos, at);
            }
        }
    }

    fn quick_stop_reaction_that_stays_holds_in_quick_stop_active() {
        let (mut d, mut ax) = reach(PdsState::OperationEnabled);
        d.params.abort_connection_option = 3;
        d.params.quick_stop_option = 6;
        d.params.target_velocity = 50_000;
        steps(&mut d, &mut ax, 200);
        d.on_connection_lost(0x8700);
        steps(&mut d, &mut ax, 500);
        assert_eq!(d.state(), PdsState::QuickStopActive);
        let at = ax.pos;
        for _ in 0..2000 {
            let c = step(&mut d, &mut ax);
            assert!(c.drive_enabled && c.power_stage, "holding with power");
        }
        assert_eq!(ax.pos, at);
        assert_eq!(ax.vel, 0);
    }

    fn init_does_not_cut_a_running_fault_reaction_short() {
        let (mut d, mut ax) = reach(PdsState::OperationEnabled);
        d.params.target_velocity = 100_000;
        d.params.profile_acceleration = 10_000_000;
        d.params.quick_stop_deceleration = 1_000_000;
        steps(&mut d, &mut ax, 100);
        d.on_connection_lost(0x8700);
        d.on_esm_init();
        let c = step(&mut d, &mut ax);
        assert_eq!(d.state(), PdsState::FaultReactionActive);
        assert!(c.drive_enabled && ax.vel > 0 && ax.vel < 100_000, "ramping");
        steps(&mut d, &mut ax, 200);
        assert_eq!(d.state(), PdsState::Fault);
        assert_eq!(ax.vel, 0);
    }

    fn csp_runs_on_for_one_period_without_set_points_then_holds() {
        // Direct CSP at 1 ms: 100 inc per set-point. The master stops after 50.
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::CSP);
        let mut target = 0;
        for _ in 0..50 {
            target += 100;
            d.params.target_position = target;
            let fb = ax.feedback();
            let c = d.step(&fb, DT, SetpointArrival::Fresh);
            ax.apply(&c);
            assert_eq!(c.position, target);
            assert!((c.velocity - 100_000.0).abs() < 1.0, "{}", c.velocity);
        }
        // Steps of the drive's own clock, half a period each: the demand runs on at
        // 100 inc/ms for one period, then holds.
        let mut seen = [0i32; 6];
        for v in seen.iter_mut() {
            let fb = ax.feedback();
            let c = d.step(&fb, DT / 2.0, SetpointArrival::Stale);
            ax.apply(&c);
            *v = c.position;
        }
        assert_eq!(seen, [target + 50, target + 100, target + 100, target + 100, target + 100, target + 100]);
        let fb = ax.feedback();
        let c = d.step(&fb, DT, SetpointArrival::Stale);
        assert_eq!(c.velocity, 0.0, "held");
        // The master comes back 5 ms after its last set-point: the next one is
        // followed at once, with the mean velocity over the gap as feed-forward.
        d.params.target_position = target + 200;
        let fb = ax.feedback();
        let c = d.step(&fb, DT, SetpointArrival::Fresh);
        assert_eq!(c.position, target + 200);
        assert!((c.velocity - 40_000.0).abs() < 1.0, "{}", c.velocity);
    }

    fn csp_interpolates_a_slow_cycle_between_supervision_steps() {
        // 4 ms set-points (0x60C2 = 4 ms), steps every 1 ms: linear, one period behind;
        // after the last set-point, one period of run-on, then hold.
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        d.params.interpolation_period = 4;
        enable(&mut d, &mut ax, mode::CSP);
        let mut demands = [0i32; 18];
        let mut n = 0;
        for k in 1..=3 {
            d.params.target_position = k * 400;
            for j in 0..4 {
                let arrival = if j == 0 { SetpointArrival::Fresh } else { SetpointArrival::Stale };
                let fb = ax.feedback();
                let c = d.step(&fb, DT, arrival);
                ax.apply(&c);
                demands[n] = c.position;
                n += 1;
            }
        }
        for _ in 0..6 {
            let fb = ax.feedback();
            let c = d.step(&fb, DT, SetpointArrival::Stale);
            ax.apply(&c);
            demands[n] = c.position;
            n += 1;
        }
        assert_eq!(n, demands.len());
        assert_eq!(
            demands,
            [0, 100, 200, 300, 400, 500, 600, 700, 800, 900, 1000, 1100, 1200, 1300, 1400, 1500, 1600, 1600]
        );
    }

    fn mode_display_follows_after_the_switch() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        d.set_mode(mode::PV);
        assert_eq!(d.mode_display(), 0);
        step(&mut d, &mut ax);
        assert_eq!(d.mode_display(), mode::PV);
        d.set_mode(2); // velocity mode (vl) is not supported: ignored
        step(&mut d, &mut ax);
        assert_eq!(d.mode_display(), mode::PV);
        assert_eq!(d.value(0x6502, 0), Some(0x3AD));
        d.set_torque_control(false);
        assert_eq!(d.value(0x6502, 0), Some(0x1A5));
    }

    fn pp_single_setpoint_handshake_cycle_by_cycle() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PP);
        d.params.profile_velocity = 100_000;
        d.params.profile_acceleration = 1_000_000;
        d.params.profile_deceleration = 1_000_000;
        let s = cw(&mut d, &mut ax, 0x000F);
        assert!(s & sw::TARGET_REACHED != 0 && s & sw::SETPOINT_ACKNOWLEDGE == 0 && s & sw::SETPOINT_FREE != 0);
        d.params.target_position = 10_000;
        let s = cw(&mut d, &mut ax, 0x003F); // new set-point, change immediately
        assert!(s & sw::SETPOINT_ACKNOWLEDGE != 0, "acknowledged in the same cycle");
        assert!(s & sw::TARGET_REACHED == 0);
        assert!(s & sw::SETPOINT_FREE == 0);
        let s = cw(&mut d, &mut ax, 0x003F);
        assert!(s & sw::SETPOINT_ACKNOWLEDGE != 0, "held while bit 4 is high");
        let s = cw(&mut d, &mut ax, 0x002F);
        assert!(s & sw::SETPOINT_ACKNOWLEDGE == 0, "cleared when bit 4 drops");
        assert!(s & sw::SETPOINT_FREE != 0);
        let mut n = 0;
        while d.statusword() & sw::TARGET_REACHED == 0 {
            cw(&mut d, &mut ax, 0x002F);
            n += 1;
            assert!(n < 1000);
            // Speed never exceeds the profile velocity.
            assert!(ax.vel <= 100_000);
        }
        // Within the window (the axis lags one cycle), then exactly on the target.
        assert!((ax.pos - 10_000).abs() <= 100);
        step(&mut d, &mut ax);
        assert_eq!(ax.pos, 10_000);
        step(&mut d, &mut ax);
        assert_eq!(d.position_actual(), 10_000);
        // 10 000 at 100 000/s with 1e6/s² ramps: 0.1 s + 0.1 s = ~200 cycles.
        assert!((195..=215).contains(&n), "{n}");
    }

    fn pp_buffered_setpoint_and_change_on_setpoint() {
        for through in [false, true] {
            let mut d = Cia402::new();
            let mut ax = Axis::new(0);
            enable(&mut d, &mut ax, mode::PP);
            d.params.profile_velocity = 100_000;
            d.params.profile_acceleration = 1_000_000;
            d.params.profile_deceleration = 1_000_000;
            let b9 = if through { 0x200 } else { 0 };
            d.params.target_position = 20_000;
            cw(&mut d, &mut ax, 0x001F | b9);
            cw(&mut d, &mut ax, 0x000F | b9);
            steps(&mut d, &mut ax, 10);
            d.params.target_position = 40_000;
            let s = cw(&mut d, &mut ax, 0x001F | b9);
            assert!(s & sw::SETPOINT_ACKNOWLEDGE != 0);
            let s = cw(&mut d, &mut ax, 0x000F | b9);
            assert!(s & sw::SETPOINT_ACKNOWLEDGE != 0, "buffer full: acknowledge stays");
            assert!(s & sw::SETPOINT_FREE == 0);
            // A third set-point is not accepted while the buffer is full.
            d.params.target_position = -5;
            cw(&mut d, &mut ax, 0x001F | b9);
            cw(&mut d, &mut ax, 0x000F | b9);
            let mut min_v_mid = i32::MAX;
            let mut n = 0;
            while !(d.statusword() & sw::TARGET_REACHED != 0 && ax.pos == 40_000) {
                cw(&mut d, &mut ax, 0x000F | b9);
                if (19_000..21_000).contains(&ax.pos) {
                    min_v_mid = min_v_mid.min(ax.vel);
                }
                n += 1;
                assert!(n < 5000);
            }
            assert!(d.statusword() & sw::SETPOINT_ACKNOWLEDGE == 0, "buffer empty again");
            if through {
                assert!(min_v_mid >= 90_000, "passed through at speed: {min_v_mid}");
            } else {
                assert!(min_v_mid < 5_000, "stopped at the first target: {min_v_mid}");
            }
            steps(&mut d, &mut ax, 20);
            assert_eq!(ax.pos, 40_000);
        }
    }

    fn pp_change_immediately_and_relative() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(500);
        enable(&mut d, &mut ax, mode::PP);
        d.params.profile_velocity = 100_000;
        d.params.target_position = 100_000;
        cw(&mut d, &mut ax, 0x003F);
        cw(&mut d, &mut ax, 0x002F);
        steps(&mut d, &mut ax, 100);
        assert!(ax.vel > 0);
        // Change immediately to a target behind: reverses.
        d.params.target_position = -3000;
        cw(&mut d, &mut ax, 0x003F);
        cw(&mut d, &mut ax, 0x002F);
        let mut n = 0;
        while d.statusword() & sw::TARGET_REACHED == 0 {
            step(&mut d, &mut ax);
            n += 1;
            assert!(n < 5000);
        }
        assert_eq!(ax.pos, -3000);
        // Relative to the previous target.
        d.params.target_position = 1234;
        cw(&mut d, &mut ax, 0x007F);
        cw(&mut d, &mut ax, 0x006F);
        steps(&mut d, &mut ax, 400);
        assert_eq!(ax.pos, -3000 + 1234);
        assert!(d.statusword() & sw::TARGET_REACHED != 0);
    }

    fn pp_zero_motion_parameter_sets_bit_14_and_refuses() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PP);
        d.params.profile_acceleration = 0;
        d.params.target_position = 1000;
        let s = cw(&mut d, &mut ax, 0x003F);
        assert!(s & sw::PARAM_ZERO != 0);
        assert!(s & sw::SETPOINT_ACKNOWLEDGE == 0);
        steps(&mut d, &mut ax, 50);
        assert_eq!(ax.pos, 0);
        d.params.profile_acceleration = 100_000;
        let s = cw(&mut d, &mut ax, 0x002F);
        assert!(s & sw::PARAM_ZERO == 0);
    }

    fn pp_halt_stops_with_605d_and_reports_target_reached() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PP);
        d.params.profile_velocity = 100_000;
        d.params.profile_acceleration = 1_000_000;
        d.params.quick_stop_deceleration = 5_000_000;
        d.params.halt_option = 2;
        d.params.target_position = 1_000_000;
        cw(&mut d, &mut ax, 0x003F);
        cw(&mut d, &mut ax, 0x002F);
        steps(&mut d, &mut ax, 200);
        let mut n = 0;
        loop {
            let s = cw(&mut d, &mut ax, 0x012F);
            assert_eq!(d.state(), PdsState::OperationEnabled);
            assert!(s & sw::ABNORMAL_STOP != 0);
            if s & sw::TARGET_REACHED != 0 {
                break;
            }
            n += 1;
            assert!(n < 100);
        }
        // 100 000 / 5 000 000 = 20 ms.
        assert!((19..=21).contains(&n), "{n}");
        assert_eq!(ax.vel, 0);
    }

    fn following_error_sets_bit_13_and_faults() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PP);
        d.params.following_error_window = 1000;
        d.params.following_error_timeout = 10;
        d.params.target_position = 100_000;
        cw(&mut d, &mut ax, 0x003F);
        ax.stuck = true;
        let mut n = 0;
        while d.state() == PdsState::OperationEnabled {
            cw(&mut d, &mut ax, 0x002F);
            n += 1;
            assert!(n < 2000);
        }
        assert_eq!(d.error_code(), ERR_FOLLOWING);
        assert!(d.following_error() > 1000);
        assert!(matches!(d.state(), PdsState::FaultReactionActive | PdsState::Fault));
    }

    fn pv_velocity_reached_and_speed_zero() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PV);
        d.params.profile_acceleration = 100_000;
        d.params.profile_deceleration = 200_000;
        d.params.velocity_window = 100;
        d.params.velocity_threshold = 10;
        let s = cw(&mut d, &mut ax, 0x000F);
        assert!(s & sw::SPEED_ZERO != 0, "speed zero");
        d.params.target_velocity = 20_000;
        let mut n = 0;
        while cw(&mut d, &mut ax, 0x000F) & sw::TARGET_REACHED == 0 {
            n += 1;
            assert!(n < 1000);
            if n > 2 {
                assert!(d.statusword() & sw::SPEED_ZERO == 0);
            }
        }
        // 20 000 / 100 000 = 200 ms.
        assert!((198..=203).contains(&n), "{n}");
        d.params.target_velocity = -20_000;
        n = 0;
        while cw(&mut d, &mut ax, 0x000F) & sw::TARGET_REACHED == 0 {
            n += 1;
            assert!(n < 1000);
        }
        // 100 ms down, 200 ms up.
        assert!((298..=304).contains(&n), "{n}");
        // Halt: stop, target reached when stopped.
        n = 0;
        while cw(&mut d, &mut ax, 0x010F) & sw::TARGET_REACHED == 0 {
            n += 1;
            assert!(n < 1000);
        }
        assert_eq!(ax.vel, 0);
        // Zero deceleration shows bit 14.
        d.params.profile_deceleration = 0;
        assert!(cw(&mut d, &mut ax, 0x000F) & sw::PARAM_ZERO != 0);
    }

    fn csp_follows_targets_with_offset_and_interpolation() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(100);
        // The set-points jump (100 → 0 → 107): no acceleration limit 0x60C5 / 0x60C6.
        d.params.max_acceleration = u32::MAX;
        d.params.max_deceleration = u32::MAX;
        enable(&mut d, &mut ax, mode::CSP);
        d.params.position_offset = 10;
        let mut t = 90;
        for i in 0..100 {
            t += 7;
            d.params.target_position = t;
            let s = cw(&mut d, &mut ax, 0x000F);
            assert!(s & sw::DRIVE_FOLLOWS != 0, "drive follows command");
            assert_eq!(ax.pos, t + 10, "cycle {i}");
            assert_eq!(d.position_demand(), t + 10);
        }
        assert!((ax.vel - 7000).abs() <= 1, "{}", ax.vel);
        // Halt: not following.
        let s = cw(&mut d, &mut ax, 0x010F);
        assert!(s & sw::DRIVE_FOLLOWS == 0);
        cw(&mut d, &mut ax, 0x000F);
        // Sync cycle 1 ms, control cycle 250 µs: linear interpolation inside the period
        // (from standstill to 0.4 inc/µs at once: no acceleration limit).
        let mut d = Cia402::new();
        d.params.max_acceleration = u32::MAX;
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::CSP);
        let mut seen = [0i32; 12];
        for k in 0..3 {
            d.params.target_position = (k + 1) * 400;
            for j in 0..4 {
                let fb = ax.feedback();
                let c = d.cycle(&fb, 0.00025);
                ax.apply(&c);
                seen[(k * 4 + j) as usize] = c.position;
            }
        }
        assert_eq!(seen, [100, 200, 300, 400, 500, 600, 700, 800, 900, 1000, 1100, 1200]);
        // A jittering measured cycle time (0.98-1.02 ms) with 0x60C2 = 1 ms: every
        // target is taken in its own cycle, never held for one more.
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::CSP);
        for k in 1..200 {
            d.params.target_position = k * 10;
            let fb = ax.feedback();
            let jitter = [0.00098, 0.00102, 0.001, 0.000999][k as usize % 4];
            let c = d.cycle(&fb, jitter);
            ax.apply(&c);
            assert_eq!(c.position, k * 10);
            assert!((c.velocity - 10_000.0).abs() < 1.0, "{}", c.velocity);
        }
    }

    fn csv_runs_at_target_velocity_plus_offset() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::CSV);
        d.params.target_velocity = 10_000;
        d.params.velocity_offset = 500;
        for _ in 0..100 {
            let s = cw(&mut d, &mut ax, 0x000F);
            assert!(s & sw::DRIVE_FOLLOWS != 0);
        }
        assert_eq!(ax.vel, 10_500);
        assert!((ax.pos - 1050).abs() <= 11, "{}", ax.pos);
    }

    fn hardware_limit_stops_and_sets_bits_8_and_11() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        ax.pl = 5000;
        enable(&mut d, &mut ax, mode::PV);
        d.params.target_velocity = 50_000;
        d.params.quick_stop_deceleration = 1_000_000;
        let mut n = 0;
        while ax.pos < 5000 {
            cw(&mut d, &mut ax, 0x000F);
            n += 1;
            assert!(n < 1000);
        }
        steps(&mut d, &mut ax, 60);
        assert_eq!(ax.vel, 0);
        let s = d.statusword();
        assert!(s & sw::ABNORMAL_STOP != 0 && s & sw::INTERNAL_LIMIT != 0);
        // 50 000² / (2 · 1e6) = 1250 counts of braking.
        assert!(ax.pos < 5000 + 1300);
        // Away from the limit is allowed.
        d.params.target_velocity = -10_000;
        steps(&mut d, &mut ax, 300);
        assert!(ax.vel < 0);
    }

    fn software_limits_clamp_pp_and_csp() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        d.params.sw_limit_min = -1000;
        d.params.sw_limit_max = 2000;
        // The CSP target jumps to the limit at once: no acceleration limit.
        d.params.max_acceleration = u32::MAX;
        d.params.max_deceleration = u32::MAX;
        enable(&mut d, &mut ax, mode::PP);
        d.params.target_position = 50_000;
        cw(&mut d, &mut ax, 0x003F);
        cw(&mut d, &mut ax, 0x002F);
        steps(&mut d, &mut ax, 500);
        assert_eq!(ax.pos, 2000);
        assert!(d.statusword() & sw::INTERNAL_LIMIT != 0);
        d.set_mode(mode::CSP);
        d.params.target_position = -5000;
        let s = cw(&mut d, &mut ax, 0x000F);
        assert_eq!(ax.pos, -1000);
        assert!(s & sw::INTERNAL_LIMIT != 0);
    }

    fn position_range_wraps_positions_and_targets() {
        // Without 0x607B (the type limits): positions are not wrapped.
        let mut d = Cia402::new();
        let mut ax = Axis::new(72_500);
        assert_eq!(d.value(0x607B, 1), Some(i64::from(i32::MIN)));
        assert_eq!(d.value(0x607B, 2), Some(i64::from(i32::MAX)));
        step(&mut d, &mut ax);
        assert_eq!(d.value(0x6064, 0), Some(72_500));
        // A rotary axis of 36 000 units: 0x6064 and 0x6062 are shown in [0, 35 999].
        d.write(0x607B, 1, &0i32.to_le_bytes()).unwrap();
        d.write(0x607B, 2, &35_999i32.to_le_bytes()).unwrap();
        step(&mut d, &mut ax);
        assert_eq!(d.value(0x6064, 0), Some(500));
        let slot = firmware::cia402::objects::tx_slot(0x6064, 0).unwrap();
        assert_eq!(d.get_tx_raw(slot), 500);
        let mut ax = Axis::new(-100);
        step(&mut d, &mut ax);
        assert_eq!(d.position_actual(), 35_900);
        // CSP: the master's targets wrap at the end of the range; the axis goes on
        // the shortest way (forward through 35 999 → 0), not back round the range.
        // (The master copies 0x6064 into 0x607A before the enable.) The set-points
        // jump: no acceleration limit 0x60C5 / 0x60C6.
        d.params.max_acceleration = u32::MAX;
        d.params.max_deceleration = u32::MAX;
        d.params.target_position = 35_900;
        enable(&mut d, &mut ax, mode::CSP);
        for t in [35_950, 0, 50, 100] {
            d.params.target_position = t;
            cw(&mut d, &mut ax, 0x000F);
            assert_eq!(d.position_demand(), t, "demand {} axis {}", d.position_demand(), ax.pos);
        }
        cw(&mut d, &mut ax, 0x000F);
        assert_eq!(ax.pos, 100, "continuous: -100 + 200");
        assert_eq!(d.position_actual(), 100);
        // The software limits 0x607D are not applied on a wrapping axis.
        d.params.sw_limit_min = 0;
        d.params.sw_limit_max = 1000;
        d.params.target_position = 2000;
        let s = cw(&mut d, &mut ax, 0x000F);
        assert_eq!(ax.pos, 2000);
        assert!(s & sw::INTERNAL_LIMIT == 0);
        // (At rest before the mode switch.)
        steps(&mut d, &mut ax, 3);
        d.params.sw_limit_min = i32::MIN;
        d.params.sw_limit_max = i32::MAX;
        // PP absolute targets: 0x60F2 bits 6-7 choose the way.
        d.set_mode(mode::PP);
        d.params.profile_velocity = 1_000_000;
        d.params.profile_acceleration = 10_000_000;
        d.params.profile_deceleration = 10_000_000;
        let pp = |d: &mut Cia402, ax: &mut Axis, option: u16, target: i32| {
            d.write(0x60F2, 0, &option.to_le_bytes()).unwrap();
            d.params.target_position = target;
            cw(d, ax, 0x003F);
            cw(d, ax, 0x002F);
            steps(d, ax, 200);
            assert!(d.statusword() & sw::TARGET_REACHED != 0, "sw {:#x} pos {} demand {}", d.statusword(), ax.pos, d.position_demand());
            assert_eq!(d.position_actual(), target);
            ax.pos
        };
        assert_eq!(pp(&mut d, &mut ax, 0xC0, 35_000), -1000, "shortest: back 3000");
        assert_eq!(pp(&mut d, &mut ax, 0x80, 34_000), 34_000, "positive only: 35 000 forward");
        assert_eq!(pp(&mut d, &mut ax, 0x40, 35_000), -1000, "negative only: 35 000 back");
        assert_eq!(pp(&mut d, &mut ax, 0x00, 1000), -35_000, "inside the range: 34 000 back");
        // 0x60F2: bits 0-1 (0-2) and 6-7; other bits and 3 in bits 0-1 refused.
        for ok in [0x00u16, 0x02, 0x41, 0xC2] {
            assert!(d.write(0x60F2, 0, &ok.to_le_bytes()).is_ok(), "{ok:#x}");
        }
        for bad in [0x03u16, 0x04, 0x20, 0xC3, 0x100] {
            assert!(d.write(0x60F2, 0, &bad.to_le_bytes()).is_err(), "{bad:#x}");
        }
    }

    fn polarity_inverts_positions_and_velocities() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        d.params.polarity = 0xC0;
        enable(&mut d, &mut ax, mode::PP);
        d.params.target_position = 3000;
        cw(&mut d, &mut ax, 0x003F);
        cw(&mut d, &mut ax, 0x002F);
        steps(&mut d, &mut ax, 500);
        assert_eq!(ax.pos, -3000);
        assert_eq!(d.position_actual(), 3000);
        assert_eq!(d.position_demand_internal(), -3000);
    }

    fn touch_probe_single_continuous_and_index() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::CSP);
        d.params.target_position = 0;
        // Probe 1: input, single, both edges. Probe 2: index, continuous, rising.
        d.set_rx(probe_fn_slot(), &0x1711u16.to_le_bytes());
        d.set_rx(probe_fn_slot(), &0x1731u16.to_le_bytes());
        step(&mut d, &mut ax);
        assert_eq!(d.touch_probe().status(), 0x0101);
        ax.probe1 = EdgeLatch { rising: Some(111), falling: None };
        step(&mut d, &mut ax);
        assert_eq!(d.touch_probe().status() & 0xFF, 0x03);
        assert_eq!(d.touch_probe().value(0), 111);
        ax.probe1 = EdgeLatch { rising: Some(222), falling: Some(333) };
        step(&mut d, &mut ax);
        assert_eq!(d.touch_probe().value(0), 111, "single: first event only");
        assert_eq!(d.touch_probe().value(1), 333);
        assert_eq!(d.touch_probe().status() & 0xFF, 0x07);
        // Index pulses on probe 2, continuous: every one is latched, toggle bit 6.
        ax.index = Some(1100);
        step(&mut d, &mut ax);
        assert_eq!(d.touch_probe().value(2), 1100);
        assert_eq!(d.touch_probe().status() >> 8, 0x03);
        ax.index = Some(2100);
        step(&mut d, &mut ax);
        assert_eq!(d.touch_probe().value(2), 2100);
        assert_eq!(d.touch_probe().status() >> 8, 0x43);
        // Re-arm probe 1 by switching it off and on.
        d.set_rx(probe_fn_slot(), &0x1700u16.to_le_bytes());
        step(&mut d, &mut ax);
        assert_eq!(d.touch_probe().status() & 0xFF, 0);
        d.set_rx(probe_fn_slot(), &0x1731u16.to_le_bytes());
        ax.probe1 = EdgeLatch { rising: Some(444), falling: None };
        step(&mut d, &mut ax);
        assert_eq!(d.touch_probe().value(0), 444);
    }

    fn quick_stop_input_acts_like_controlword_bit_2() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PV);
        d.params.target_velocity = 10_000;
        steps(&mut d, &mut ax, 50);
        let fb = DriveFeedback { position: ax.pos, quick_stop_input: true, ..Default::default() };
        d.set_controlword(0x0F);
        let c = d.cycle(&fb, DT);
        ax.apply(&c);
        assert_eq!(d.state(), PdsState::QuickStopActive);
    }

    fn start_stop_speed_jumps_from_standstill() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PP);
        d.params.start_stop_speed = 5_000;
        d.params.profile_velocity = 20_000;
        d.params.profile_acceleration = 100_000;
        d.params.profile_deceleration = 100_000;
        d.params.target_position = 3_000;
        cw(&mut d, &mut ax, 0x3F);
        assert_eq!(d.velocity_demand(), 5_000);
        let mut n = 0;
        while cw(&mut d, &mut ax, 0x2F) & sw::TARGET_REACHED == 0 {
            n += 1;
            assert!(n < 2000);
        }
        step(&mut d, &mut ax);
        assert_eq!(ax.pos, 3_000);
    }

    fn mode_switch_while_moving_is_bumpless() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PV);
        d.params.target_velocity = 30_000;
        steps(&mut d, &mut ax, 200);
        assert_eq!(ax.vel, 30_000);
        // PV -> PP: the new move starts from the running speed.
        d.set_mode(mode::PP);
        d.params.target_position = ax.pos + 20_000;
        d.params.profile_velocity = 30_000;
        let target = d.params.target_position;
        let s = cw(&mut d, &mut ax, 0x3F);
        assert_eq!(d.mode_display(), mode::PP);
        assert!(s & sw::SETPOINT_ACKNOWLEDGE != 0);
        assert!((ax.vel - 30_000).abs() <= 1_000, "{}", ax.vel);
        let mut n = 0;
        while cw(&mut d, &mut ax, 0x2F) & sw::TARGET_REACHED == 0 {
            n += 1;
            assert!(n < 5000);
        }
        step(&mut d, &mut ax);
        assert_eq!(ax.pos, target);
    }

    fn pv_and_csv_respect_software_limits() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        d.params.sw_limit_min = -10_000;
        d.params.sw_limit_max = 10_000;
        enable(&mut d, &mut ax, mode::PV);
        d.params.target_velocity = 20_000;
        steps(&mut d, &mut ax, 2000);
        assert!(ax.pos <= 10_000 && ax.pos > 9_000, "{}", ax.pos);
        assert_eq!(ax.vel, 0);
        assert!(d.statusword() & sw::INTERNAL_LIMIT != 0);
        d.set_mode(mode::CSV);
        d.params.target_velocity = -50_000;
        steps(&mut d, &mut ax, 1000);
        assert_eq!(ax.pos, -10_000);
        assert!(d.statusword() & sw::INTERNAL_LIMIT != 0);
    }

    fn warning_torque_limit_and_outputs() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::CSP);
        d.params.max_torque = 500;
        let fb = DriveFeedback { torque: -600, warning: true, ..Default::default() };
        let c = d.cycle(&fb, DT);
        assert_eq!(c.torque_limit, 500);
        let s = d.statusword();
        assert!(s & sw::WARNING != 0 && s & sw::INTERNAL_LIMIT != 0);
        let fb = DriveFeedback { torque: 100, ..Default::default() };
        d.cycle(&fb, DT);
        assert!(d.statusword() & (sw::WARNING | sw::INTERNAL_LIMIT) == 0);
        d.params.digital_outputs = 0b1011;
        d.params.digital_outputs_mask = 0b0011;
        assert_eq!(d.digital_outputs(), 0b0011);
    }

    fn pp_jerk_limited_profile_ends_on_target() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(7);
        enable(&mut d, &mut ax, mode::PP);
        d.write(0x6086, 0, &3i16.to_le_bytes()).unwrap();
        assert!(d.write(0x6086, 0, &1i16.to_le_bytes()).is_err());
        d.params.profile_velocity = 100_000;
        d.params.profile_acceleration = 5_000_000; // 20 ms to full speed: 20-cycle window
        d.params.profile_deceleration = 5_000_000;
        d.params.target_position = 50_007;
        cw(&mut d, &mut ax, 0x3F);
        let mut v_prev = 0;
        let mut max_dv = 0;
        let mut n = 0;
        while cw(&mut d, &mut ax, 0x2F) & sw::TARGET_REACHED == 0 {
            max_dv = max_dv.max((ax.vel - v_prev).abs());
            v_prev = ax.vel;
            n += 1;
            if n == 3 {
                // Jerk-limited start: ≈ 1 100 counts/s after 3 cycles (trapezoid: 15 000).
                assert!(ax.vel < 3_000, "{}", ax.vel);
            }
            assert!(n < 2000);
        }
        assert!(max_dv <= 5_000 + 1_000, "acceleration within 0x6083: {max_dv}");
        step(&mut d, &mut ax);
        assert_eq!(ax.pos, 50_007);
        // Halt in the middle of a jerk-limited move: smooth stop, target reached.
        d.params.target_position = 0;
        cw(&mut d, &mut ax, 0x3F);
        steps(&mut d, &mut ax, 100);
        n = 0;
        while cw(&mut d, &mut ax, 0x12F) & sw::TARGET_REACHED == 0 {
            n += 1;
            assert!(n < 500);
        }
        assert_eq!(ax.vel, 0);
        // Back to the trapezoid.
        d.write(0x6086, 0, &0i16.to_le_bytes()).unwrap();
        d.params.target_position = 1_000;
        cw(&mut d, &mut ax, 0x3F);
        n = 0;
        while cw(&mut d, &mut ax, 0x2F) & sw::TARGET_REACHED == 0 {
            n += 1;
            assert!(n < 2000);
        }
        step(&mut d, &mut ax);
        assert_eq!(ax.pos, 1_000);
    }

    fn acceleration_feed_forward_follows_the_ramp() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PV);
        d.params.profile_acceleration = 100_000;
        d.params.target_velocity = 50_000;
        for _ in 0..10 {
            let c = step(&mut d, &mut ax);
            assert!((c.acceleration - 100_000.0).abs() < 1.0, "{}", c.acceleration);
        }
        d.params.polarity = 0x40;
        let c = step(&mut d, &mut ax);
        assert!((c.acceleration + 100_000.0).abs() < 1.0, "{}", c.acceleration);
        d.set_controlword(0x0007);
        let c = step(&mut d, &mut ax);
        // Disable operation with 0x605C = 1: the 0x6084 ramp (velocity inverted by 0x607E).
        assert!((c.acceleration - 500_000.0).abs() < 1.0, "{}", c.acceleration);
        steps(&mut d, &mut ax, 600);
        let c = step(&mut d, &mut ax);
        assert!(!c.drive_enabled && c.acceleration == 0.0);
    }

    fn homing_every_method_ends_on_its_reference() {
        // World: limits at ±20 000, home switch edge at 2 000 (or zone 2 000..6 000),
        // index pulses at 100 + k·1000.
        let cases: &[(i8, i32, i32)] = &[
            // (method, start, expected home position)
            (1, 0, -19_900), (2, 0, 19_100), (3, 0, 1_100), (3, 9000, 1_100), (4, 0, 2_100), (4, 9000, 2_100),
            (5, 0, 2_100), (5, 9000, 2_100), (6, 0, 1_100), (6, 9000, 1_100),
            (7, 0, 1_100), (7, 4000, 1_100), (7, 9000, 1_100),
            (8, 0, 2_100), (8, 4000, 2_100), (8, 9000, 2_100),
            (9, 0, 5_100), (9, 4000, 5_100), (9, 9000, 5_100),
            (10, 0, 6_100), (10, 4000, 6_100), (10, 9000, 6_100),
            (11, 0, 6_100), (11, 9000, 6_100), (12, 0, 5_100), (12, 9000, 5_100),
            (13, 0, 2_100), (13, 9000, 2_100), (14, 0, 1_100), (14, 9000, 1_100),
            (17, 0, -19_999), (18, 0, 19_999),
            (19, 0, 1_999), (19, 9000, 1_999), (20, 0, 2_000), (20, 9000, 2_000),
            (21, 0, 2_001), (21, 9000, 2_001), (22, 0, 2_000), (22, 9000, 2_000),
            (23, 0, 1_999), (23, 9000, 1_999), (24, 0, 2_000), (24, 4000, 2_000),
            (25, 0, 6_000), (25, 4000, 6_000), (26, 0, 6_001), (26, 9000, 6_001),
            (27, 0, 6_001), (27, 9000, 6_001), (28, 0, 6_000), (28, 4000, 6_000),
            (29, 0, 2_000), (29, 9000, 2_000), (30, 0, 1_999), (30, 4000, 1_999),
            (33, 0, -900), (34, 0, 100), (35, 1234, 1234), (37, -77, -77),
        ];
        for &(method, start, expect) in cases {
            let mut d = Cia402::new();
            let mut ax = Axis::new(start);
            ax.nl = -20_000;
            ax.pl = 20_000;
            ax.home = match method {
                3 | 4 | 19 | 20 => HomeSw::Above(2000),
                5 | 6 | 21 | 22 => HomeSw::Below(2000),
                7..=14 | 23..=30 => HomeSw::Zone(2000, 6000),
                _ => HomeSw::None,
            };
            d.params.homing_method = method;
            d.params.homing_speed_switch = 10_000;
            d.params.homing_speed_zero = 1_000;
            d.params.homing_acceleration = 100_000;
            d.params.home_offset = 555;
            enable(&mut d, &mut ax, mode::HM);
            let s = cw(&mut d, &mut ax, 0x000F);
            assert_eq!(s & 0x3400, 0x0400, "not started");
            let mut n = 0;
            loop {
                let s = cw(&mut d, &mut ax, 0x001F);
                assert!(s & sw::HOMING_ERROR == 0, "method {method} start {start}: homing error");
                if s & 0x3400 == 0x1400 {
                    break;
                }
                n += 1;
                assert!(n < 60_000, "method {method} start {start}: timeout at {}", ax.pos);
            }
            assert!((ax.pos - expect).abs() <= 1, "method {method} start {start}: {} vs {expect}", ax.pos);
            assert!((d.position_actual() - 555).abs() <= 1, "method {method}");
        }
    }

    fn homing_errors() {
        // Index method without an encoder index.
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        d.set_has_index(false);
        d.params.homing_method = 1;
        enable(&mut d, &mut ax, mode::HM);
        let s = cw(&mut d, &mut ax, 0x001F);
        assert_eq!(s & 0x3400, 0x2400, "homing error, stopped");
        // Home switch not assigned.
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        d.set_assigned_inputs(0b011);
        d.params.homing_method = 19;
        enable(&mut d, &mut ax, mode::HM);
        let s = cw(&mut d, &mut ax, 0x001F);
        assert!(s & sw::HOMING_ERROR != 0);
        // Home switch never found: runs into the limit switch.
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        ax.pl = 3000;
        d.params.homing_method = 20;
        d.params.homing_speed_switch = 10_000;
        enable(&mut d, &mut ax, mode::HM);
        let mut n = 0;
        while cw(&mut d, &mut ax, 0x001F) & sw::HOMING_ERROR == 0 {
            n += 1;
            assert!(n < 5000);
        }
        steps(&mut d, &mut ax, 5);
        assert_eq!(d.statusword() & 0x3400, 0x2400);
        // Interrupt by clearing bit 4: "not started / interrupted".
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        ax.nl = -20_000;
        d.params.homing_method = 17;
        enable(&mut d, &mut ax, mode::HM);
        cw(&mut d, &mut ax, 0x001F);
        steps(&mut d, &mut ax, 100);
        assert_eq!(d.statusword() & 0x3400, 0x0000, "in progress");
        for _ in 0..200 {
            cw(&mut d, &mut ax, 0x000F);
        }
        assert_eq!(d.statusword() & 0x3400, 0x0400);
    }
    fn transition_4_waits_for_the_power_stage_then_starts_at_the_actual_position() {
        let mut d = Cia402::new();
        let mut ax = Axis::new(1_000);
        ax.enable_pending = true;
        d.set_mode(mode::CSP);
        d.params.target_position = 1_000;
        for w in [0x0000, 0x0006, 0x0007] {
            cw(&mut d, &mut ax, w);
        }
        assert_eq!(d.state(), PdsState::SwitchedOn);
        // Before "enable operation" nothing is asked of the motor side.
        assert!(!d.enable_waiting());
        // Enable operation while the alignment is pending: Switched on (with voltage),
        // the motor side enabled at the actual position, which moves (the alignment
        // pulls the rotor onto its vector) and is followed by the demand. The master
        // (CSP) copies 0x6064 into 0x607A until it sees Operation enabled.
        d.set_controlword(0x000F);
        for k in 0..270 {
            ax.pos = 1_000 + k.min(250) * 2;
            d.params.target_position = d.position_actual();
            let c = step(&mut d, &mut ax);
            assert_eq!(d.state(), PdsState::SwitchedOn, "cycle {k}");
            assert_eq!(d.statusword() & 0x7F, 0x33, "cycle {k}");
            assert!(d.enable_waiting());
            assert!(c.power_stage && c.drive_enabled && c.brake_release);
            assert_eq!(c.position, 1_000 + k.min(250) * 2);
            assert_eq!((c.velocity, c.acceleration), (0.0, 0.0));
            assert_eq!(d.position_demand(), d.position_actual());
            assert_eq!(d.following_error(), 0);
            assert_eq!(d.error_code(), 0);
        }
        // Aligned (the rotor at rest on 1500): the next cycle enters Operation enabled
        // with 0x6062 = 0x6064 = 0x607A — no jump.
        ax.enable_pending = false;
        d.params.target_position = d.position_actual();
        let c = step(&mut d, &mut ax);
        assert_eq!(d.state(), PdsState::OperationEnabled);
        assert!(!d.enable_waiting());
        assert_eq!(d.statusword() & 0x6F, 0x27);
        assert_eq!(d.position_actual(), 1_500);
        assert_eq!(d.position_demand(), 1_500);
        assert_eq!((c.position, c.drive_enabled), (1_500, true));
        for k in 1..=500 {
            d.params.target_position = 1_500 + k * 20;
            step(&mut d, &mut ax);
            assert!(d.following_error().abs() <= 20, "{}", d.following_error());
        }
        assert_eq!(d.state(), PdsState::OperationEnabled);
        assert_eq!(ax.pos, 11_500);
        // A later pending report (a re-alignment) does not drop Operation enabled.
        ax.enable_pending = true;
        steps(&mut d, &mut ax, 5);
        assert_eq!(d.state(), PdsState::OperationEnabled);
        assert!(!d.enable_waiting());
    }

    fn the_wait_ends_with_other_commands_a_fault_or_the_esm() {
        for end in 0..5 {
            let mut d = Cia402::new();
            let mut ax = Axis::new(-300);
            ax.enable_pending = true;
            d.set_mode(mode::CSP);
            for w in [0x0000, 0x0006, 0x000F] {
                cw(&mut d, &mut ax, w);
            }
            // 0x0F from Ready to switch on: transition 3, then the wait.
            assert_eq!(d.state(), PdsState::SwitchedOn);
            assert!(d.enable_waiting());
            steps(&mut d, &mut ax, 20);
            let c = match end {
                0 => {
                    let c = step_cw(&mut d, &mut ax, 0x0007);
                    assert_eq!(d.state(), PdsState::SwitchedOn);
                    c
                }
                1 => {
                    let c = step_cw(&mut d, &mut ax, 0x0006);
                    assert_eq!(d.state(), PdsState::ReadyToSwitchOn);
                    c
                }
                2 => {
                    let c = step_cw(&mut d, &mut ax, 0x0002);
                    assert_eq!(d.state(), PdsState::SwitchOnDisabled);
                    c
                }
                3 => {
                    // The failed alignment: following error raised by the motor side.
                    ax.fault = ERR_FOLLOWING;
                    for _ in 0..50 {
                        step(&mut d, &mut ax);
                        assert_ne!(d.state(), PdsState::OperationEnabled);
                    }
                    assert_eq!(d.state(), PdsState::Fault);
                    assert_eq!(d.error_code(), ERR_FOLLOWING);
                    // Still pending and still commanded: never Operation enabled.
                    let c = step(&mut d, &mut ax);
                    assert_eq!(d.state(), PdsState::Fault);
                    c
                }
                _ => {
                    d.on_connection_lost(0x8700);
                    assert_eq!(d.state(), PdsState::SwitchOnDisabled);
                    assert_eq!(d.error_code(), 0);
                    step_cw(&mut d, &mut ax, 0x000F)
                }
            };
            assert!(!d.enable_waiting(), "end {end}");
            assert!(!c.drive_enabled && !c.brake_release, "end {end}");
        }
    }

    fn no_wait_without_pending_and_transition_16_does_not_wait() {
        // Nothing pending (open loop, aligned): transition 4 at once, as always.
        let mut d = Cia402::new();
        let mut ax = Axis::new(0);
        enable(&mut d, &mut ax, mode::PP);
        assert!(!d.enable_waiting());
        // Quick stop that stays (0x605A = 6), then enable operation again
        // (transition 16) with the motor side reporting pending: no wait, the drive
        // function never left.
        let (mut d, mut ax) = reach(PdsState::QuickStopActive);
        ax.enable_pending = true;
        steps(&mut d, &mut ax, 50);
        assert_eq!(d.state(), PdsState::QuickStopActive);
        cw(&mut d, &mut ax, 0x000F);
        assert_eq!(d.state(), PdsState::OperationEnabled);
        assert!(!d.enable_waiting());
        // Switch on disabled with 0x0F and pending: no transition, no enable.
        let (mut d, mut ax) = reach(PdsState::SwitchOnDisabled);
        ax.enable_pending = true;
        let c = step_cw(&mut d, &mut ax, 0x000F);
        assert_eq!(d.state(), PdsState::SwitchOnDisabled);
        assert!(!c.drive_enabled && !d.enable_waiting());
    }
}
