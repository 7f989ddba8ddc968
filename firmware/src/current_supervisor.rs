//! Supervision of the current loop, at the current-loop (PWM) rate: the power-up
//! auto-tune of the current loop (0x2013) and the running "current does not follow"
//! check (fault 0x5210). Chip-independent, no allocation, no formatting: the board's
//! current-loop interrupt and the simulator's `tests_host::sim_axis::PlantAxis` call
//! the same code.
//!
//! # Power-up auto-tune (0x2013 = 1)
//! **When:** once per power cycle, as soon as the drive permits it
//! ([`CurrentSupervisor::permit_tune`], from `Drive::tune_permitted`: current-sensor
//! offsets passed, the bus voltage is inside the under/over-voltage window and no
//! fault is active) — that is, during the start-up self-test, before an EtherCAT
//! master can normally have taken the slave to Op and enabled it (the ESM alone takes
//! longer than the ≈ 0.3 s the measurement needs). This is what the E5 parameter
//! describes ("auto tuning when power up") and what stepper drives of this class do:
//! the coils get a test current with the holding brake still applied (a locked rotor
//! is the best condition for measuring R and L), and the first enable already runs
//! with tuned gains. Measuring at the first enable instead would delay the first
//! motion by the tune and move the shaft (up to ¼ electrical period while each phase
//! is energised) after the master has taken the position as the CSP start.
//! Should the master enable while the tune runs, the motion layer is held
//! (`Motion::step_held`: no current reference, the demand tracks the actual position)
//! and starts with its soft start at the actual position when the tune is done.
//!
//! **How:** [`foc::autotune`] in voltage mode at the current-loop rate with the test
//! current [`TEST_CURRENT_FRACTION`] × 0x2000. On success the loop's gains and the
//! decoupling inductance are set at once (in the interrupt, no round trip) to the
//! values the parameters will report: `Kp = 0x2015 × 0.01 V/A`, `Ki = 0x2016 × 10
//! V/(A·s)`, `L = 0x2021 µH`; the drive writes 0x2020/0x2021/0x2015/0x2016 from the
//! [`CurrentReport`]. The tune's current-sensing calibration is applied at the same
//! moment ([`Calibration`]): the channel offsets re-measured with the bridges
//! switching, both channels' gains referred to their mean (`foc::autotune`, "Channel
//! gains": 0x2022:01 is B's gain over A's, A's own is `1/√(0x2022:01)`), and the
//! dead-time compensation of the measured loss (`foc::current_loop`, "Dead-time
//! compensation"); the drive reports it in 0x2022. The loop uses exactly the values
//! 0x2022 reports (the integer ones). **Offsets:** the start-up calibration
//! (bridges off, `crate::sampling`) and the tune's combine: the loop's offset of each
//! channel is the start-up offset plus the tune's trim, 0x2022:02/03
//! ([`Calibration::offset_trim`]); `ControlCore` keeps that sum whenever it
//! re-applies the start-up offsets. A later tune measures against that sum and adds
//! its result to the trim. A calibration outside its
//! plausible band fails the tune with [`TuneError::Sensing`], the current-sensing
//! fault 0x5210 (detail 2) with its emergency; the loop then keeps the power-up
//! calibration.
//!
//! **Failure:** [`TuneError::OpenPhase`] (no current in a phase), `Unbalanced` (the
//! phases differ, poor contact) and `Implausible` are all the motor-open / poor-contact
//! fault 0x7120 (LED 4, 0x2056 bit 2, not latched). The drive reports the condition
//! gone at once, so a **fault reset clears it**; the fault withdraws the permission and
//! its return (after the reset) starts the tune again, which raises the fault again if
//! the motor is still open. A failed tune while bit 2 is off is not retried (the
//! permission does not drop) and the loop keeps its start-up gains. A tune
//! interrupted by a withdrawn permission (another fault) restarts from the beginning
//! when the permission returns.
//!
//! 0x2013 = 0: no tune; the loop keeps the gains the board configured. Instead, the
//! first time the motion layer asks for the bridges ([`CurrentSupervisor::request_power`])
//! a short phase check ([`foc::autotune::PhaseCheck`]: a voltage pulse per phase until
//! [`CHECK_CURRENT_FRACTION`] × 0x2000 flows, under 1 ms for the product's motors,
//! at most [`CHECK_TIME_S`] per phase) runs in its place, with the motion layer held as
//! for the tune. A phase without current is the same motor-open fault; the fault
//! reset arms the check again for the next enable.
//!
//! # "Current does not follow" (fault 0x5210, 0x2056 bit 3)
//! While the bridges are on and the closed current loop runs, every PWM period that
//! ends with the voltage vector **saturated** is examined (an unsaturated period costs
//! one branch). It counts when both hold:
//! * the current error is large: `|i*−i| > max(FOLLOW_MIN_ERROR_A, FOLLOW_REL_ERROR·|i*|)`
//!   (dq vectors), and
//! * the motor model says the reference is reachable: the steady-state voltage the
//!   reference needs, `v = R·i* + ωe·L·J·i* + Ke·ω` (J = rotation by 90°), is below
//!   [`FOLLOW_HEADROOM`] of the voltage limit. This keeps high speed (back-EMF near the
//!   bus voltage) and low bus voltage, where the loop legitimately cannot reach its
//!   reference, out of the check.
//!
//! [`FOLLOW_TIME_S`] of uninterrupted counting is one detection (reported once until
//! the bridges have been off). Thresholds, from the motor model
//! (the motor model of `tests-host/src/plant/motor.rs`): the longest legitimate saturation is a
//! current reversal at the lowest bus voltage — ECN57-20 (1.8 mH, 0.4 Ω) from −8.4 A
//! to +8.4 A at 12 V (11.4 V usable): `L·ΔI/(V − R·I) ≈ 3.8 ms`; TC86-45 (3 mH): ≈ 6.3 ms.
//! 20 ms is three times the worst case. 0.3 A is above the sensors' noise (±0.25 A
//! peak-to-peak at the start-up check) and half of the reference means "far"; the
//! 80 % headroom leaves room for the dead-time loss and the `L·di/dt` of transients.
//! What it catches: a dead / disconnected current sensor, or a gain far off, while
//! current is demanded (an open phase is classified first, below). A sensor *offset* or moderate gain error is regulated away by
//! the loop (the measured current follows) and is the start-up check's job.
//! With no current demanded (servo holding without load) nothing can be detected.
//!
//! # Motor open while running (fault 0x7120, 0x2056 bit 2)
//! An open coil or a lost contact leaves its phase without current however large its
//! voltage: the loop winds up and saturates, so the same saturated periods are
//! examined (no cost when unsaturated). Per phase, a saturated period is evidence
//! *for* an open phase when the phase voltage exceeds [`OPEN_VOLTAGE_FRACTION`] of
//! the voltage limit while its current stays below [`OPEN_CURRENT_A`]; a saturated
//! period in which the phase carries [`OPEN_CURRENT_A`] or more clears the evidence
//! (an open phase never does). Only periods whose reference the motor model calls
//! reachable (as above) count; [`OPEN_TIME_S`] of evidence without a current is one
//! detection, before the 20 ms of the follow check, which is then not reported for
//! the same event. A healthy phase at speed also crosses zero current while its
//! voltage is large (back-EMF and `ωL` put the voltage ahead of the current), but it
//! stays inside the ±0.2 A band for 2·asin(0.2 A / |i|) / ω_e per crossing: with a
//! reference of at least [`OPEN_MIN_REF_A`] that is 10 ms only below 0.22 rev/s,
//! where the voltage is far from large. Below that reference magnitude the check does
//! not count. (An earlier rule that only *subtracted* a period of current from the
//! sum tripped on the TC86-45 at 13 V: at the voltage limit the current lags the
//! voltage by up to 80°, so most large-voltage periods fall near a zero crossing.)

pub use crate::params::Calibration;
use crate::params::{Param, Params};
use foc::angle::Angle;
use foc::autotune::{
    ki_from_param, kp_from_param, Autotune, AutotuneConfig, Phase, PhaseCheck, TuneError, TuneState,
};
use foc::current_loop::{AdcSample, CurrentLoop};
use foc::modulation::Duties;

/// Test current of the auto-tune, fraction of the peak current 0x2000.
pub const TEST_CURRENT_FRACTION: f32 = 0.8;
/// Current the first-enable phase check waits for, fraction of 0x2000 (at least
/// 0.5 A, at most 2 A).
pub const CHECK_CURRENT_FRACTION: f32 = 0.25;
/// Longest voltage pulse of the phase check, s (a coil of 20 mH reaches 2 A at 12 V
/// in 3.3 ms).
pub const CHECK_TIME_S: f32 = 0.005;
/// Time the current must stay far from its reference while saturated, s.
pub const FOLLOW_TIME_S: f32 = 0.02;
/// Smallest current error counted, A.
pub const FOLLOW_MIN_ERROR_A: f32 = 0.3;
/// Current error counted relative to the reference magnitude.
pub const FOLLOW_REL_ERROR: f32 = 0.5;
/// The reference counts as reachable when it needs less than this fraction of the
/// voltage limit.
pub const FOLLOW_HEADROOM: f32 = 0.8;
/// A phase carrying less than this current, A, counts as carrying none (the sensors'
/// noise is ±0.125 A).
pub const OPEN_CURRENT_A: f32 = 0.2;
/// A phase voltage above this fraction of the voltage limit counts as large.
pub const OPEN_VOLTAGE_FRACTION: f32 = 0.5;
/// Net time of evidence for an open phase, s.
pub const OPEN_TIME_S: f32 = 0.01;
/// Smallest reference magnitude, A, for which the open-phase check counts.
pub const OPEN_MIN_REF_A: f32 = 0.6;

/// Configuration (from the parameters: [`SupervisorConfig::from_params`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SupervisorConfig {
    /// Current-loop period, s.
    pub ts: f32,
    /// PWM timer period, counts (voltage resolution of the tune).
    pub pwm_period: u16,
    /// 0x2013 = 1.
    pub auto_tune: bool,
    /// Auto-tune test current, A.
    pub test_current: f32,
    /// Periods of [`FOLLOW_TIME_S`].
    pub follow_periods: u32,
    /// Periods of [`OPEN_TIME_S`].
    pub open_periods: u32,
    /// First-enable phase check current, A.
    pub check_current: f32,
    /// Fast protection: a phase current above this trips the bridges, A.
    pub trip_current_a: f32,
    /// Fast protection: a bus voltage above this trips the bridges, V.
    pub trip_bus_v: f32,
}

impl SupervisorConfig {
    /// From 0x2013 and 0x2000 for a loop of period `ts` and PWM period `pwm_period`.
    pub fn from_params(p: &Params, ts: f32, pwm_period: u16) -> Self {
        let ts = if ts.is_finite() && ts > 0.0 {
            ts
        } else {
            25e-6
        };
        let peak = p.settings().peak_current_ma.clamp(100, 20_000) as f32 * 1e-3;
        SupervisorConfig {
            ts,
            pwm_period: pwm_period.max(2),
            auto_tune: p.get(Param::AutoTune) == 1,
            test_current: TEST_CURRENT_FRACTION * peak,
            check_current: (CHECK_CURRENT_FRACTION * peak).clamp(0.5, 2.0),
            follow_periods: ((FOLLOW_TIME_S / ts) as u32).max(1),
            open_periods: ((OPEN_TIME_S / ts) as u32).max(1),
            trip_current_a: FAULT_LIMITS.over_current_ma as f32 * 1e-3,
            trip_bus_v: FAULT_LIMITS.over_voltage_mv as f32 * 1e-3,
        }
    }
}

/// The protections' thresholds (the same the drive's 1 ms checks use).
const FAULT_LIMITS: crate::faults::FaultConfig = crate::faults::FaultConfig::DEFAULT;

/// What the fast protection tripped on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Trip {
    /// Nothing yet.
    #[default]
    None,
    /// A phase current above [`SupervisorConfig::trip_current_a`].
    OverCurrent,
    /// The bus voltage above [`SupervisorConfig::trip_bus_v`].
    OverVoltage,
}

/// State of the power-up tune.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TuneStatus {
    /// Not wanted (0x2013 = 0).
    #[default]
    Off,
    /// Wanted, waiting for the permission.
    Pending,
    /// Measuring.
    Running,
    /// Finished; the loop uses the tuned gains.
    Done,
    /// Failed (motor open / poor contact).
    Failed(TuneError),
}

/// Tune results in the parameters' integer units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TunedValues {
    /// 0x2020, mΩ.
    pub r_mohm: u16,
    /// 0x2021, µH.
    pub l_uh: u16,
    /// 0x2015, 0.01 V/A.
    pub kp: u16,
    /// 0x2016, 10 V/(A·s).
    pub ki: u16,
    /// The current-sensing calibration (0x2022).
    pub calibration: Calibration,
}

/// What the control path tells the drive (copy it across to the cyclic side; the
/// drive reacts to changed sequence numbers in `Drive::current_report`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CurrentReport {
    /// State of the power-up tune.
    pub tune: TuneStatus,
    /// The results (valid once a tune finished with `Done`).
    pub tuned: TunedValues,
    /// Incremented (wrapping) each time a tune finishes, done or failed.
    pub tune_seq: u8,
    /// Incremented (wrapping) at each "current does not follow" detection.
    pub follow_seq: u8,
    /// Reference current magnitude at the last detection, mA.
    pub follow_ref_ma: u16,
    /// Incremented (wrapping) at each "motor open while running" detection.
    pub open_seq: u8,
    /// The phase of the last such detection.
    pub open_phase: Phase,
    /// Incremented (wrapping) at each trip of the fast protection.
    pub trip_seq: u8,
    /// What the last trip was.
    pub trip: Trip,
    /// Phase A current of the period the last trip happened in, mA.
    pub trip_ia_ma: i16,
    /// Phase B current of that period, mA.
    pub trip_ib_ma: i16,
    /// Bus voltage of that period, 0.1 V.
    pub trip_bus_dv: u16,
}

impl CurrentReport {
    /// Nothing measured or detected yet (for statics built at compile time).
    pub const NONE: CurrentReport = CurrentReport {
        tune: TuneStatus::Off,
        tuned: TunedValues {
            r_mohm: 0,
            l_uh: 0,
            kp: 0,
            ki: 0,
            calibration: Calibration {
                gain_b_e4: 0,
                offset_ma: [0, 0],
                dead_time_mv: 0,
                l_low_uh: 0,
            },
        },
        tune_seq: 0,
        follow_seq: 0,
        follow_ref_ma: 0,
        open_seq: 0,
        open_phase: Phase::A,
        trip_seq: 0,
        trip: Trip::None,
        trip_ia_ma: 0,
        trip_ib_ma: 0,
        trip_bus_dv: 0,
    };
}

/// The supervisor (one per axis, owned by the current-loop interrupt).
#[derive(Debug, Clone)]
pub struct CurrentSupervisor {
    cfg: SupervisorConfig,
    tune: Option<Autotune>,
    check: Option<PhaseCheck>,
    check_armed: bool,
    status: TuneStatus,
    tuned: TunedValues,
    tune_seq: u8,
    permitted: bool,
    follow_n: u32,
    follow_armed: bool,
    follow_seq: u8,
    follow_ref_ma: u16,
    open_n: [u32; 2],
    open_seq: u8,
    open_phase: Phase,
    tripped: bool,
    trip: Trip,
    trip_seq: u8,
    trip_sample: (i16, i16, u16),
}

impl CurrentSupervisor {
    /// New supervisor: the tune is pending when 0x2013 = 1.
    pub fn new(cfg: SupervisorConfig) -> Self {
        CurrentSupervisor {
            cfg,
            tune: None,
            check: None,
            check_armed: true,
            status: if cfg.auto_tune {
                TuneStatus::Pending
            } else {
                TuneStatus::Off
            },
            tuned: TunedValues::default(),
            tune_seq: 0,
            permitted: false,
            follow_n: 0,
            follow_armed: true,
            follow_seq: 0,
            follow_ref_ma: 0,
            open_n: [0; 2],
            open_seq: 0,
            open_phase: Phase::A,
            tripped: false,
            trip: Trip::None,
            trip_seq: 0,
            trip_sample: (0, 0, 0),
        }
    }

    /// New parameters. Switching 0x2013 on makes a tune pending unless one already
    /// succeeded since power-up; switching it off aborts a running tune.
    pub fn configure(&mut self, cfg: SupervisorConfig) {
        let was = self.cfg.auto_tune;
        self.cfg = cfg;
        if cfg.auto_tune && !was && self.status == TuneStatus::Off {
            self.status = TuneStatus::Pending;
        } else if !cfg.auto_tune && matches!(self.status, TuneStatus::Pending | TuneStatus::Running)
        {
            self.tune = None;
            self.status = TuneStatus::Off;
        }
    }

    /// The configuration in use.
    pub fn config(&self) -> &SupervisorConfig {
        &self.cfg
    }

    /// Permission for the tune (the drive's `tune_permitted`, passed on at the servo
    /// rate). Withdrawn during a tune: the tune stops (restarts later). Given again
    /// after a failed tune: the tune is retried.
    pub fn permit_tune(&mut self, yes: bool) {
        if !yes && self.status == TuneStatus::Running {
            self.tune = None;
            self.status = TuneStatus::Pending;
        }
        if !yes && self.check.take().is_some() {
            self.check_armed = true;
        }
        if yes && !self.permitted && matches!(self.status, TuneStatus::Failed(_)) {
            if self.cfg.auto_tune {
                self.status = TuneStatus::Pending;
            } else {
                // A failed phase check: checked again at the next enable.
                self.status = TuneStatus::Off;
                self.check_armed = true;
            }
        }
        self.permitted = yes;
    }

    /// The motion layer's power request of this servo period (before it is held). The
    /// first request with 0x2013 = 0 starts the phase check (module docs).
    pub fn request_power(&mut self, wanted: bool) {
        if wanted
            && self.check_armed
            && self.permitted
            && !self.tripped
            && !self.cfg.auto_tune
            && self.status == TuneStatus::Off
        {
            self.check_armed = false;
            let steps = ((CHECK_TIME_S / self.cfg.ts) as u32).max(2);
            self.check = Some(PhaseCheck::new(self.cfg.check_current, steps));
        }
    }

    /// The offset trim of the tune's calibration (0x2022:02/03) in counts of
    /// `amps_per_count`: what the loop adds to the start-up offsets (0 before a tune).
    pub fn offset_trim(&self, amps_per_count: f32) -> [f32; 2] {
        self.tuned.calibration.offset_trim(amps_per_count)
    }

    /// The phase resistance the last finished tune measured, Ω (`None` before one).
    pub fn tuned_resistance(&self) -> Option<f32> {
        match self.status {
            TuneStatus::Done if self.tuned.r_mohm > 0 => Some(f32::from(self.tuned.r_mohm) * 1e-3),
            _ => None,
        }
    }

    /// True while the tune owns the bridges: switch them on and call
    /// [`Self::tune_step`] instead of the current loop, and hold the motion layer
    /// (`Motion::step_held`).
    #[inline]
    pub fn tuning(&self) -> bool {
        self.permitted
            && !self.tripped
            && (self.check.is_some()
                || matches!(self.status, TuneStatus::Pending | TuneStatus::Running))
    }

    /// One PWM period of the tune (voltage mode). Returns the duties to apply.
    pub fn tune_step(&mut self, cl: &mut CurrentLoop, adc: &AdcSample) -> Duties {
        if !self.tuning() {
            return cl.voltage_step(adc, 0.0, 0.0);
        }
        if self.check.is_some() {
            return self.check_step(cl, adc);
        }
        let cfg = self.cfg;
        let t = self.tune.get_or_insert_with(|| {
            Autotune::new(AutotuneConfig::new(
                cfg.ts,
                cfg.pwm_period,
                cfg.test_current,
            ))
        });
        self.status = TuneStatus::Running;
        let sense = cl.config().sense;
        let i = sense.currents(adc);
        let (va, vb) = t.step(i.alpha, i.beta, sense.vbus(adc));
        let d = cl.voltage_step(adc, va, vb);
        match t.state {
            TuneState::Done(r) => {
                // The tune measured the offsets against the ones the loop uses: the
                // start-up offsets plus the trim of an earlier tune (0 before one).
                let before = self.tuned.calibration;
                let mut calibration = Calibration::from_tune(&r);
                for (o, b) in calibration.offset_ma.iter_mut().zip(before.offset_ma) {
                    *o = o.saturating_add(b);
                }
                self.tuned = TunedValues {
                    r_mohm: r.resistance_mohm(),
                    l_uh: r.inductance_uh(),
                    kp: r.kp_param(),
                    ki: r.ki_param(),
                    calibration,
                };
                let ke = cl.config().ke;
                cl.set_gains(kp_from_param(self.tuned.kp), ki_from_param(self.tuned.ki));
                cl.set_motor(f32::from(self.tuned.l_uh) * 1e-6, ke);
                apply_calibration(cl, &before, &calibration, sense.vbus(adc));
                cl.reset();
                self.finish(TuneStatus::Done);
            }
            TuneState::Failed(e) => self.finish(TuneStatus::Failed(e)),
            _ => {}
        }
        d
    }

    /// One PWM period of the first-enable phase check.
    fn check_step(&mut self, cl: &mut CurrentLoop, adc: &AdcSample) -> Duties {
        let sense = cl.config().sense;
        let i = sense.currents(adc);
        let v = 0.5 * cl.config().modulator.vmax(sense.vbus(adc));
        let Some(c) = &mut self.check else {
            return cl.voltage_step(adc, 0.0, 0.0);
        };
        let (va, vb) = c.step(i.alpha, i.beta, v);
        let d = cl.voltage_step(adc, va, vb);
        match c.result {
            Some(Ok(())) => self.check = None,
            Some(Err(e)) => {
                self.check = None;
                self.finish(TuneStatus::Failed(e));
            }
            None => {}
        }
        d
    }

    fn finish(&mut self, s: TuneStatus) {
        self.tune = None;
        self.status = s;
        self.tune_seq = self.tune_seq.wrapping_add(1);
    }

    /// One PWM period of the closed current loop with the bridges on: the loop's
    /// step plus the "current does not follow" check (one branch when unsaturated).
    #[inline(always)]
    pub fn run_step(
        &mut self,
        cl: &mut CurrentLoop,
        adc: &AdcSample,
        theta_e: Angle,
        omega_e: f32,
    ) -> Duties {
        let d = cl.step(adc, theta_e, omega_e);
        if cl.saturated {
            self.check_follow(cl, omega_e);
        } else {
            self.follow_n = 0;
        }
        d
    }

    /// One PWM period with the bridges off (re-arms the check).
    #[inline]
    pub fn idle(&mut self) {
        self.follow_n = 0;
        self.open_n = [0; 2];
        self.follow_armed = true;
    }

    /// The open-phase evidence of one saturated period (module docs). True when it
    /// found an open phase now.
    fn check_open(&mut self, cl: &CurrentLoop, r2: f32) -> bool {
        if r2 < OPEN_MIN_REF_A * OPEN_MIN_REF_A {
            return false;
        }
        let v_large = OPEN_VOLTAGE_FRACTION * cl.config().modulator.vmax(cl.vbus);
        let phases = [
            (cl.v_ab.alpha, cl.i_ab.alpha, Phase::A),
            (cl.v_ab.beta, cl.i_ab.beta, Phase::B),
        ];
        for (n, (v, i, phase)) in self.open_n.iter_mut().zip(phases) {
            if i.abs() >= OPEN_CURRENT_A {
                *n = 0;
                continue;
            }
            if v.abs() <= v_large {
                continue;
            }
            *n += 1;
            if *n >= self.cfg.open_periods {
                *n = 0;
                self.open_phase = phase;
                self.open_seq = self.open_seq.wrapping_add(1);
                return true;
            }
        }
        false
    }

    fn check_follow(&mut self, cl: &CurrentLoop, omega_e: f32) {
        let (id, iq) = (cl.id_ref, cl.iq_ref);
        let ed = id - cl.i_dq.d;
        let eq = iq - cl.i_dq.q;
        let e2 = ed * ed + eq * eq;
        let r2 = id * id + iq * iq;
        let floor = FOLLOW_MIN_ERROR_A * FOLLOW_MIN_ERROR_A;
        let rel = FOLLOW_REL_ERROR * FOLLOW_REL_ERROR * r2;
        let big = e2 > if rel > floor { rel } else { floor };
        let c = cl.config();
        // R from the gains (Kp = L·ωc, Ki = R·ωc).
        let r = if c.kp > 0.0 {
            c.ki * c.inductance / c.kp
        } else {
            0.0
        };
        let wl = omega_e * c.inductance;
        let vd = r * id - wl * iq;
        let vq = r * iq + wl * id + c.ke * (1.0 / foc::angle::POLE_PAIRS as f32) * omega_e;
        let vmax = c.modulator.vmax(cl.vbus) * FOLLOW_HEADROOM;
        let reachable = vd * vd + vq * vq < vmax * vmax;
        if reachable && self.follow_armed && self.check_open(cl, r2) {
            // The same event is not a "current does not follow" fault as well.
            self.follow_n = 0;
            self.follow_armed = false;
            return;
        }
        if !(big && reachable && self.follow_armed) {
            self.follow_n = 0;
            return;
        }
        self.follow_n += 1;
        if self.follow_n >= self.cfg.follow_periods {
            self.follow_n = 0;
            self.follow_armed = false;
            self.follow_seq = self.follow_seq.wrapping_add(1);
            self.follow_ref_ma = (foc::num::sqrtf(r2) * 1000.0).clamp(0.0, 65535.0) as u16;
        }
    }

    /// The fast protections, every PWM period after the loop's step (bridges on or
    /// off: the step measured `cl.i_ab` and `cl.vbus`): a phase current above
    /// [`SupervisorConfig::trip_current_a`] or a bus voltage above
    /// [`SupervisorConfig::trip_bus_v`] trips. Returns true while tripped: the caller
    /// switches the bridges off in this very period. The trip holds until
    /// [`Self::rearm`], which the caller does once the drive has withdrawn the power
    /// permission (the drive raised the fault from [`CurrentReport::trip_seq`] by
    /// then), so the bridges never come back on by themselves. This is the software
    /// twin of the timer break input, at the current-loop rate: it keeps working
    /// whatever thread mode is doing (a flash commit, a long SDO).
    #[inline(always)]
    pub fn protect(&mut self, cl: &CurrentLoop) -> bool {
        let (ia, ib) = (cl.i_ab.alpha, cl.i_ab.beta);
        let lim = self.cfg.trip_current_a;
        let over_current = ia > lim || ia < -lim || ib > lim || ib < -lim;
        if !self.tripped && (over_current || cl.vbus > self.cfg.trip_bus_v) {
            self.trip_now(cl, over_current);
        }
        self.tripped
    }

    fn trip_now(&mut self, cl: &CurrentLoop, over_current: bool) {
        let milliamps = |a: f32| (a * 1000.0).clamp(-32000.0, 32000.0) as i16;
        self.tripped = true;
        self.trip = if over_current {
            Trip::OverCurrent
        } else {
            Trip::OverVoltage
        };
        self.trip_seq = self.trip_seq.wrapping_add(1);
        self.trip_sample = (
            milliamps(cl.i_ab.alpha),
            milliamps(cl.i_ab.beta),
            (cl.vbus * 10.0).clamp(0.0, 65535.0) as u16,
        );
        self.tune = None;
        if self.status == TuneStatus::Running {
            self.status = TuneStatus::Pending;
        }
    }

    /// True while a trip holds the bridges off.
    pub fn tripped(&self) -> bool {
        self.tripped
    }

    /// Ends a trip (call when the drive's power permission is withdrawn).
    pub fn rearm(&mut self) {
        self.tripped = false;
    }

    /// The state for the drive.
    pub fn report(&self) -> CurrentReport {
        CurrentReport {
            tune: self.status,
            tuned: self.tuned,
            tune_seq: self.tune_seq,
            follow_seq: self.follow_seq,
            follow_ref_ma: self.follow_ref_ma,
            open_seq: self.open_seq,
            open_phase: self.open_phase,
            trip_seq: self.trip_seq,
            trip: self.trip,
            trip_ia_ma: self.trip_sample.0,
            trip_ib_ma: self.trip_sample.1,
            trip_bus_dv: self.trip_sample.2,
        }
    }
}

/// Applies a finished tune's current-sensing calibration `new` (what 0x2022 reports)
/// to the loop, which used `before` (the previous tune's, or none): the offsets
/// (the start-up ones plus [`Calibration::offset_trim`]), both channels' gains, and
/// the dead-time compensation as a fraction of the bus voltage `vbus` (V) at the tune.
fn apply_calibration(cl: &mut CurrentLoop, before: &Calibration, new: &Calibration, vbus: f32) {
    let s = cl.config().sense;
    let (old, trim) = (
        before.offset_trim(s.amps_per_count),
        new.offset_trim(s.amps_per_count),
    );
    cl.set_offsets(s.offset_a - old[0] + trim[0], s.offset_b - old[1] + trim[1]);
    let [a, b] = new.channel_gains();
    cl.set_channel_gains(a, b);
    if vbus > 1.0 {
        let v_dt = f32::from(new.dead_time_mv) * 1e-3;
        cl.set_dead_time(v_dt / vbus, foc::current_loop::DEAD_TIME_BAND);
    }
}

#[cfg(test)]
mod tests;
