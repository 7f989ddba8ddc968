//! Tests of the control path on a model board ([`super::ControlHw`]).
extern crate std;
use super::*;
use crate::cia402::{DriveCommand, SetpointKind};
use crate::identity::Variant;
use crate::motion::{ECN57_20, SERVO_TS};
use crate::params::Params;
use std::vec::Vec;

const STAGE: PowerStageConfig = PowerStageConfig {
    pwm_hz: 40_000,
    pwm_arr: 2125,
    analog: AnalogScale {
        amps_per_count: 0.006,
        volts_per_count: 0.016,
        offset_nominal: 2048,
        offset_tolerance: 200,
        noise_tolerance: 40,
    },
};

/// Registers of a model board: what the control path did to them.
#[derive(Default)]
struct ModelHw {
    count: u32,
    command: Option<ControlCommand>,
    index: Option<u32>,
    halted: bool,
    break_latched: bool,
    on: bool,
    enables: u32,
    duties: Option<Duties>,
    traced: Vec<ServoPoint>,
    /// The brake pin (true: released) and how often it was written.
    brake: bool,
    brake_writes: u32,
}

impl ControlHw for ModelHw {
    fn raw_count(&mut self) -> u32 {
        self.count
    }
    fn command(&mut self) -> Option<ControlCommand> {
        self.command
    }
    fn take_index_capture(&mut self) -> Option<u32> {
        self.index.take()
    }
    fn take_probe1_capture(&mut self) -> Option<(u32, bool)> {
        None
    }
    fn probe2(&mut self) -> Option<Edges<u32>> {
        None
    }
    fn halted(&self) -> bool {
        self.halted
    }
    fn break_latched(&self) -> bool {
        self.break_latched
    }
    fn enable_outputs(&mut self) -> bool {
        // The board refuses with a latched break or when halted.
        self.on = !self.break_latched && !self.halted;
        self.enables += 1;
        self.on
    }
    fn disable_outputs(&mut self) {
        self.on = false;
    }
    fn set_brake_released(&mut self, released: bool) {
        self.brake = released;
        self.brake_writes += 1;
    }
    fn set_duties(&mut self, d: Duties) {
        self.duties = Some(d);
    }
    fn trace(&mut self, p: &ServoPoint) {
        self.traced.push(*p);
    }
}

fn core(variant: Variant) -> (ControlCore, ControlCommand) {
    let mut p = Params::new(variant);
    // Open loop: no commutation alignment before the current flows.
    p.set_internal(crate::params::Param::LoopMode, 1);
    let motion = MotionConfig::from_params(&p, variant, &ECN57_20, SERVO_TS);
    let sup = SupervisorConfig::from_params(&p, 1.0 / STAGE.pwm_hz as f32, STAGE.pwm_arr);
    let c = ControlCore::new(
        STAGE,
        LoopMotor {
            r_ohm: 0.5,
            l_h: 1.6e-3,
            ke: ECN57_20.kt,
            encoder_lines: motion.counts_per_rev / 4,
        },
        motion,
        false,
        sup,
        0,
    );
    let cmd = ControlCommand {
        cycle: 1,
        command: DriveCommand {
            power_stage: true,
            drive_enabled: true,
            kind: SetpointKind::Position,
            position: 0,
            velocity: 0.0,
            acceleration: 0.0,
            torque_limit: 1000,
            current_limit: 1000,
            torque: 0,
            brake_release: true,
        },
        cycle_s: 1e-3,
        power_allowed: true,
        config: 1,
        motion,
        align_wiggle: false,
        offsets: Some((2048.0, 2048.0)),
        supervisor: sup,
        tune_allowed: false,
        trace: false,
        brake_released: false,
    };
    (c, cmd)
}

/// Zero current at 24 V.
const REST: RawSample = RawSample {
    ia: 2048,
    ib: 2048,
    vbus: 1500,
};

fn run(c: &mut ControlCore, hw: &mut ModelHw, periods: u32) -> Option<Feedback> {
    let mut last = None;
    for _ in 0..periods {
        if let Some(f) = c.period(hw, REST) {
            last = Some(f);
        }
    }
    last
}

#[test]
fn feedback_at_the_servo_rate_and_bridges_off_without_a_command() {
    let (mut c, _) = core(Variant::OpenLoop);
    let mut hw = ModelHw::default();
    let mut published = 0;
    for _ in 0..40 {
        published += u32::from(c.period(&mut hw, REST).is_some());
    }
    assert_eq!(published, 40 / u32::from(SERVO_DIVIDER));
    assert_eq!((hw.enables, hw.on), (0, false));
    assert!(!c.bridges_on());
}

#[test]
fn servo_points_for_the_scope_only_while_the_command_asks() {
    let (mut c, cmd) = core(Variant::OpenLoop);
    let mut hw = ModelHw {
        command: Some(cmd),
        ..ModelHw::default()
    };
    for _ in 0..40 {
        c.period(&mut hw, REST);
    }
    assert!(hw.traced.is_empty());
    hw.command = Some(ControlCommand { trace: true, ..cmd });
    let mut published = Vec::new();
    for _ in 0..40 {
        if let Some(f) = c.period(&mut hw, REST) {
            published.push(ServoPoint::of(&f.axis));
        }
    }
    // One point per servo period: what the period published.
    assert_eq!(hw.traced.len(), 40 / usize::from(SERVO_DIVIDER));
    assert_eq!(hw.traced, published);
}

#[test]
fn permission_and_offsets_switch_on_and_their_withdrawal_off() {
    let (mut c, cmd) = core(Variant::OpenLoop);
    let mut hw = ModelHw {
        command: Some(ControlCommand {
            offsets: None,
            ..cmd
        }),
        ..ModelHw::default()
    };
    run(&mut c, &mut hw, 40);
    assert!(!hw.on, "no offsets: no power");
    hw.command = Some(cmd);
    let fb = run(&mut c, &mut hw, 400).expect("feedback");
    assert!(hw.on && c.bridges_on() && fb.bridges_on);
    assert_eq!(hw.enables, 1, "enabled once, then held");
    assert!(hw.duties.is_some());
    assert!(
        (fb.axis.bus_mv as i32 - 24_000).abs() < 100,
        "{}",
        fb.axis.bus_mv
    );
    hw.command = Some(ControlCommand {
        power_allowed: false,
        ..cmd
    });
    run(&mut c, &mut hw, u32::from(SERVO_DIVIDER));
    assert!(!hw.on && !c.bridges_on(), "off within one servo period");
}

#[test]
fn halt_and_break_keep_the_bridges_off() {
    for (halted, brk) in [(true, false), (false, true)] {
        let (mut c, cmd) = core(Variant::OpenLoop);
        let mut hw = ModelHw {
            command: Some(cmd),
            ..ModelHw::default()
        };
        run(&mut c, &mut hw, 200);
        assert!(hw.on);
        hw.halted = halted;
        hw.break_latched = brk;
        run(&mut c, &mut hw, 200);
        assert!(!hw.on && !c.bridges_on(), "halted {halted} break {brk}");
    }
}

#[test]
fn the_brake_engages_in_the_period_the_bridges_go_off() {
    type Loss = fn(&mut ModelHw, &ControlCommand);
    let losses: [(&str, Loss); 4] = [
        ("break latched", |hw, _| hw.break_latched = true),
        ("halted", |hw, _| hw.halted = true),
        ("permission withdrawn", |hw, cmd| {
            hw.command = Some(ControlCommand {
                power_allowed: false,
                ..*cmd
            })
        }),
        ("offsets lost", |hw, cmd| {
            hw.command = Some(ControlCommand {
                offsets: None,
                ..*cmd
            })
        }),
    ];
    for (what, lose) in losses {
        let (mut c, cmd) = core(Variant::OpenLoop);
        let cmd = ControlCommand {
            brake_released: true,
            ..cmd
        };
        let mut hw = ModelHw {
            command: Some(cmd),
            ..ModelHw::default()
        };
        run(&mut c, &mut hw, 200);
        assert!(hw.on && hw.brake && c.brake_released(), "{what}: released");
        lose(&mut hw, &cmd);
        // Period by period: the pin is never released with the bridges off, and
        // the measurements of a period report its bridges.
        let mut periods = 0;
        while hw.on {
            let fb = c.period(&mut hw, REST);
            periods += 1;
            assert_eq!(hw.brake, hw.on, "{what}: period {periods}");
            assert!(fb.is_none_or(|f| f.bridges_on == hw.on), "{what}");
            assert!(periods <= u32::from(SERVO_DIVIDER), "{what}: still on");
        }
        assert!(!hw.brake && !c.brake_released(), "{what}");
        assert_eq!(hw.brake_writes, 2, "{what}: released once, engaged once");
    }
    // The runtime's decision alone engages it at the next servo period.
    let (mut c, cmd) = core(Variant::OpenLoop);
    let mut hw = ModelHw {
        command: Some(ControlCommand {
            brake_released: true,
            ..cmd
        }),
        ..ModelHw::default()
    };
    run(&mut c, &mut hw, 200);
    hw.command = Some(cmd);
    run(&mut c, &mut hw, u32::from(SERVO_DIVIDER));
    assert!(hw.on && !hw.brake, "engaged, the motor still holding");
}

#[test]
fn index_capture_becomes_an_axis_position() {
    let (mut c, cmd) = core(Variant::HybridServo);
    let mut hw = ModelHw {
        command: Some(cmd),
        ..ModelHw::default()
    };
    let before = run(&mut c, &mut hw, 8).expect("feedback").index_seq;
    hw.count = 100;
    hw.index = Some(60);
    let fb = run(&mut c, &mut hw, u32::from(SERVO_DIVIDER)).expect("feedback");
    assert_eq!(fb.index_seq, before + 1);
    // 40 counts moved since the pulse: the index was 40 counts behind, in units.
    let m = c.motion.motion();
    assert_eq!(
        fb.index_units,
        units_at_count(m.config(), m.position_units(), 40)
    );
}

/// Two RL coils behind the bridges (no rotor), one period of delay, and current
/// sensors whose true zero is off the start-up offsets by `zero_error` counts.
struct CoilBench {
    i: [f32; 2],
    pending: (f32, f32),
    zero_error: [f32; 2],
}

impl CoilBench {
    fn sample(&self) -> RawSample {
        let a = STAGE.analog;
        let raw =
            |k: usize| (2048.0 + self.zero_error[k] + self.i[k] / a.amps_per_count).round() as u16;
        RawSample {
            ia: raw(0),
            ib: raw(1),
            vbus: REST.vbus,
        }
    }

    /// One period: the voltages computed in the previous one act now.
    fn advance(&mut self, hw: &ModelHw) {
        let (r, l, ts) = (0.5f32, 1.6e-3f32, 1.0 / STAGE.pwm_hz as f32);
        let (va, vb) = self.pending;
        let e = libm::expf(-r / l * ts);
        for (i, v) in self.i.iter_mut().zip([va, vb]) {
            *i = v / r + (*i - v / r) * e;
        }
        self.pending = match (hw.on, hw.duties) {
            (true, Some(d)) => {
                Modulator::new(STAGE.pwm_arr).voltages(&d, STAGE.analog.volts(REST.vbus))
            }
            _ => (0.0, 0.0),
        };
    }
}

#[test]
fn the_loop_uses_the_offsets_0x2022_reports_after_the_tune() {
    use crate::current_supervisor::TuneStatus;
    let (mut c, cmd) = core(Variant::OpenLoop);
    let cmd = ControlCommand {
        tune_allowed: true,
        command: DriveCommand {
            drive_enabled: false,
            ..cmd.command
        },
        ..cmd
    };
    assert!(cmd.supervisor.auto_tune, "0x2013 = 1 by default");
    let mut hw = ModelHw {
        command: Some(cmd),
        ..ModelHw::default()
    };
    // The start-up calibration (bridges off) said 2048; with the bridges switching
    // the zero reads 5 counts higher on A, 4 lower on B (30 / −24 mA).
    let mut bench = CoilBench {
        i: [0.0; 2],
        pending: (0.0, 0.0),
        zero_error: [5.0, -4.0],
    };
    let mut fb = None;
    for _ in 0..40_000 * 2 {
        if let Some(f) = c.period(&mut hw, bench.sample()) {
            fb = Some(f);
        }
        bench.advance(&hw);
        if fb
            .as_ref()
            .is_some_and(|f| f.current.tune == TuneStatus::Done)
        {
            break;
        }
    }
    let fb = fb.expect("feedback");
    assert_eq!(fb.current.tune, TuneStatus::Done);
    let cal = fb.current.tuned.calibration;
    assert!(
        (cal.offset_ma[0] - 30).abs() <= 4 && (cal.offset_ma[1] + 24).abs() <= 4,
        "{cal:?}"
    );
    // Many servo periods later, with the start-up offsets still in every command,
    // the loop uses the start-up offsets plus exactly what 0x2022 reports.
    for _ in 0..400 {
        c.period(&mut hw, bench.sample());
        bench.advance(&hw);
    }
    let apc = STAGE.analog.amps_per_count;
    let s = c.cl.config().sense;
    let want = [
        2048.0 + f32::from(cal.offset_ma[0]) * 1e-3 / apc,
        2048.0 + f32::from(cal.offset_ma[1]) * 1e-3 / apc,
    ];
    assert!(
        (s.offset_a - want[0]).abs() < 1e-3 && (s.offset_b - want[1]).abs() < 1e-3,
        "loop {} / {}, 0x2022 says {want:?}",
        s.offset_a,
        s.offset_b
    );
    // And the channels' gains are the ones 0x2022:01 gives.
    let g = c.cl.channel_gains();
    assert_eq!(g, cal.channel_gains());
    assert!(
        (g[1] / g[0] * 1e4 - f32::from(cal.gain_b_e4)).abs() < 1.0,
        "{g:?}"
    );
}

#[test]
fn loop_motor_takes_a_plausible_inductance_from_the_parameters() {
    use crate::params::Param;
    let mut p = Params::new(Variant::HybridServo);
    p.set_internal(Param::MotorInductance, 50);
    let m = LoopMotor::from_params(&p, (0.5, 1.6e-3), 0.1, 1000);
    assert_eq!(
        (m.r_ohm, m.l_h, m.ke, m.encoder_lines),
        (0.5, 1.6e-3, 0.1, 1000)
    );
    p.set_internal(Param::MotorInductance, 2500);
    p.set_internal(Param::MotorResistance, 0);
    let m = LoopMotor::from_params(&p, (0.5, 1.6e-3), 0.1, 1000);
    assert_eq!((m.r_ohm, m.l_h), (1e-3, 2.5e-3), "R at least 1 mΩ");
}
