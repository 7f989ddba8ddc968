//! The board's commutation path (`firmware::commutation::CommutatedMotion`: power-up
//! alignment, then the motion layer) on the electrical plant with an encoder whose
//! electrical offset is unknown: the offset found, a closed-loop move after it, and
//! the failures (rotor locked, wrong encoder line count) with the wiggle (0x2083 = 1).
use firmware::cia402::{DriveCommand, SetpointKind};
use firmware::commutation::{CommutatedMotion, Commutation, Step};
use firmware::identity::Variant;
use firmware::motion::{Feedback, Frame, MotionConfig, SERVO_TS};
use firmware::params::Params;
use foc::encoder::{Encoder, EncoderConfig};
use tests_host::plant::motor::{PlantConfig, ECN57_20};
use tests_host::plant::rig::{Rig, PLL_OMEGA, SERVO_DIV, TS};

const UNITS_PER_REV: f64 = 50_000.0;

fn motion_config() -> MotionConfig {
    let p = Params::new(Variant::HybridServo);
    MotionConfig::from_params(
        &p,
        Variant::HybridServo,
        &firmware::motion::ECN57_20,
        SERVO_TS,
    )
}

fn command(enabled: bool, position: i32, velocity: f32) -> DriveCommand {
    DriveCommand {
        power_stage: enabled,
        drive_enabled: enabled,
        kind: SetpointKind::Position,
        position,
        velocity,
        torque_limit: 1000,
        current_limit: 1000,
        ..DriveCommand::default()
    }
}

/// The board's servo period on the rig (as `hw::control::servo_step` + `on_sample`).
struct Axis {
    rig: Rig,
    m: CommutatedMotion,
    offsets: u32,
    failures: u32,
}

impl Axis {
    fn new(cfg: PlantConfig, wiggle: bool) -> Self {
        Axis {
            rig: Rig::new_unaligned(cfg),
            m: CommutatedMotion::new(motion_config(), wiggle),
            offsets: 0,
            failures: 0,
        }
    }

    fn servo_period(&mut self) -> Step {
        let fb = Feedback {
            position: self.rig.enc.position(),
            velocity: self.rig.enc.velocity(),
            electrical_angle: self.rig.enc.electrical_angle(),
            voltage_limited: self.rig.cl.saturated,
            ..Feedback::default()
        };
        let s = self.m.step(&fb, self.rig.enc.raw_electrical_angle());
        if let Some(off) = s.offset {
            self.rig.enc.set_electrical_offset(off);
            self.offsets += 1;
        }
        if s.failed {
            self.failures += 1;
        }
        let r = s.reference;
        if r.reset {
            self.rig.cl.reset();
        }
        self.rig.cl.id_ref = r.id;
        self.rig.cl.iq_ref = r.iq;
        for _ in 0..SERVO_DIV {
            match (r.power, r.frame) {
                (false, _) => self.rig.tick_with(|cl, _, adc| {
                    let _ = cl.voltage_step(adc, 0.0, 0.0);
                    foc::modulation::Duties::zero(2125)
                }),
                (true, Frame::Encoder) => self.rig.tick(),
                (true, Frame::Command { angle, omega_e }) => self.rig.tick_at(angle, omega_e),
            }
        }
        s
    }

    /// One 1 ms drive cycle.
    fn cycle(&mut self, c: &DriveCommand) {
        self.m.set_command(c, 0.001);
        for _ in 0..10 {
            self.servo_period();
        }
    }

    fn true_units(&self, theta0: f64) -> f64 {
        (self.rig.plant.theta - theta0) / (2.0 * std::f64::consts::PI) * UNITS_PER_REV
    }
}

fn align(ax: &mut Axis) -> u32 {
    let mut cycles = 0;
    ax.cycle(&command(true, 0, 0.0));
    while ax.m.state() == Commutation::Aligning && cycles < 2000 {
        ax.cycle(&command(true, 0, 0.0));
        cycles += 1;
    }
    cycles
}

#[test]
fn alignment_finds_the_offset_and_the_closed_loop_then_moves_to_the_count() {
    for (wiggle, theta0) in [(false, 0.3), (true, 1.1), (true, -2.0)] {
        let mut cfg = PlantConfig::new(ECN57_20);
        cfg.theta0 = theta0;
        let mut ax = Axis::new(cfg, wiggle);
        let start = ax.rig.plant.theta;
        let ms = align(&mut ax);
        assert_eq!(ax.m.state(), Commutation::Aligned, "wiggle {wiggle}");
        assert_eq!((ax.offsets, ax.failures), (1, 0));
        assert!(
            (240..=260).contains(&ms) || wiggle && (640..=660).contains(&ms),
            "{ms} ms"
        );
        let err = ax.rig.offset_error_counts(ax.rig.enc.electrical_offset());
        assert!(
            err.abs() <= 3.0,
            "wiggle {wiggle}: offset error {err:.2} counts"
        );
        // Closed loop: hold, then a quarter turn in 250 ms from wherever the alignment
        // left the rotor, then hold.
        let p0 = ax.m.motion().position_units();
        let mut max_fe = 0.0f32;
        for k in 0..=250 {
            let p = p0 + (12_500 * k / 250);
            ax.cycle(&command(true, p, 50_000.0));
            max_fe = max_fe.max(ax.m.motion().following_error().abs());
        }
        for _ in 0..300 {
            ax.cycle(&command(true, p0 + 12_500, 0.0));
            max_fe = max_fe.max(ax.m.motion().following_error().abs());
        }
        assert!(ax.m.motion().closed_loop() && ax.m.motion().enabled());
        let moved = ax.true_units(start);
        let target = f64::from(p0 + 12_500);
        assert!(
            (moved - target).abs() <= 2.0 * 12.5,
            "wiggle {wiggle}: at {moved:.0} units, target {target}"
        );
        assert!(
            max_fe < 10.0,
            "wiggle {wiggle}: following error up to {max_fe:.1} counts"
        );
    }
}

#[test]
fn locked_rotor_fails_the_wiggle_and_nothing_is_driven_after() {
    let mut cfg = PlantConfig::new(ECN57_20);
    cfg.locked = true;
    let mut ax = Axis::new(cfg, true);
    align(&mut ax);
    assert_eq!(ax.m.state(), Commutation::Failed);
    assert_eq!((ax.offsets, ax.failures), (0, 1));
    for _ in 0..20 {
        ax.cycle(&command(true, 0, 0.0));
    }
    assert_eq!(ax.failures, 1);
    assert!(!ax.m.motion().enabled());
    assert!(ax.rig.plant.ia.abs() < 0.05 && ax.rig.plant.ib.abs() < 0.05);
}

#[test]
fn wrong_line_count_fails_the_wiggle_and_a_retry_with_the_right_encoder_succeeds() {
    let cfg = PlantConfig::new(ECN57_20);
    let mut ax = Axis::new(cfg, true);
    // The encoder configured with four times the real lines (0x2029 wrong): it sees a
    // quarter of the sweep.
    let real_lines = ax.rig.plant.cfg.cpr / 4;
    ax.rig.enc = Encoder::new(
        EncoderConfig {
            lines: real_lines * 4,
            ts: TS,
            pll_omega: PLL_OMEGA,
        },
        ax.rig.plant.encoder_raw(),
    );
    align(&mut ax);
    assert_eq!(ax.m.state(), Commutation::Failed);
    assert_eq!(ax.failures, 1);
    // Disabled by the fault; the right encoder; enabled again: aligned.
    ax.cycle(&command(false, 0, 0.0));
    ax.rig.enc = Encoder::new(
        EncoderConfig {
            lines: real_lines,
            ts: TS,
            pll_omega: PLL_OMEGA,
        },
        ax.rig.plant.encoder_raw(),
    );
    align(&mut ax);
    assert_eq!(ax.m.state(), Commutation::Aligned);
    let err = ax.rig.offset_error_counts(ax.rig.enc.electrical_offset());
    assert!(err.abs() <= 3.0, "offset error {err:.2} counts");
}
