//! Power-up measurement of phase resistance and inductance, and current-loop gains.
//!
//! Runs at the current-loop rate in voltage mode ([`crate::current_loop::CurrentLoop::voltage_step`]).
//! Each phase is measured in turn while the other phase is held at 0 V (its bridge
//! shorts the coil, which damps the rotor as it pulls into the energised phase):
//!
//! 1. **DC point 1**: a slow PI regulator (`Kp = kp_init` V/A, integral corner
//!    `wi_init` rad/s, independent of the unknown motor) brings the phase current to
//!    `I₁ = ½·I_test`; after `settle` s the applied voltage and the current are
//!    averaged for `average` s. No current (`< 20 %` of I₁) at the end of the settle
//!    time → [`TuneError::OpenPhase`].
//! 2. **DC point 2** at `I₂ = I_test`, same procedure. `R = (V₂ − V₁)/(I₂ − I₁)`: the
//!    bridge's dead-time voltage loss (same sign at both points) cancels.
//! 3. **Toggling**: around the DC voltage of point 2 the voltage is switched by
//!    `±V_t` every `h` samples ([`AutotuneConfig::toggle_half`], 8). The bridge
//!    applies a command `D` samples after the sample it was computed from (the
//!    computation + PWM delay, unknown: 0.5 or 1.0 sample on the board, see
//!    [`crate::current_loop`]), so the current is a triangle whose corners lie `D`
//!    after each command change. The **slope** of each half period is taken between
//!    two samples on the same straight edge: `p = delay + 1` samples after the
//!    change ([`AutotuneConfig::delay`] is the largest delay the measurement must
//!    tolerate, 1 → p = 2) and the last sample before the next change (`h` after
//!    it). Both lie on the edge for every `0 ≤ D ≤ p`, so
//!    `L = V_t·(h − p)·Ts·N / Σ|Δi|` does not depend on `D`. (The earlier method,
//!    the change between the samples `delay` after two changes, spans a corner
//!    whenever `D` is not the assumed one: `L̂ = L·h/(h − 2|D − 1|)`, +33 % at D = 1.5
//!    with h = 4.) The change across each corner, `p` samples, gives the delay
//!    itself: the current runs `D` samples on the old edge and `p − D` on the new one,
//!    `Δi_c = ±s·(2D − p)` with `s` the slope per sample, so
//!    `D = (p + Σ±Δi_c/(N_c·s))/2` ([`TuneResult::delay`], reported, not applied:
//!    the loop's own interrupt is longer than the tune's, its delay can differ).
//!
//!    **Error of L** (the incremental inductance around the DC current, over the
//!    swing `h·s` p-p, 1.1 A on the ECN57-20 at 48 V):
//!    * the delay: none for `0 ≤ D ≤ p` (the samples are on the edge);
//!    * the DC part `V_dc − R·i − V_dt`: it slopes the rising and falling edges
//!      alike and cancels in the alternating sum to first order; the `R·(i − I₂)` of
//!      the triangle only bends the edges, of the order `(R·h·Ts/L)²` (< 0.2 % here);
//!    * the ADC: ±1 LSB on each `Δi` of `(h − p)·s` (0.8 A here, 4.9 mA LSB), a
//!      systematic ≤ 0.6 % only if the pattern never dithers; the sensor noise dithers
//!      it and the mean over the `N` ≈ 100 half periods of 20 ms leaves ≈ 0.1 %;
//!    * the channel gain: `L` is in the units of the (calibrated) channel, like R;
//!    * L(i): the mean over the swing instead of the value at I₂, second order in the
//!      swing (−1.0 % on the plant's ECN57-20, whose L falls 30 % to rated current,
//!      with L 30 % below the data and 1.5 samples of delay).
//!
//!    On the plant (`tests-host` `robustness`, the "Robustness" rows of
//!    BENCHMARKS.md) the tuned L is within ±0.5 % of the true incremental inductance
//!    at the test current for D = 0.5, 0.75, 1.0, 1.25 and 1.5 samples and true L
//!    0.7-1.3 × the motor data (the test asserts ±2 %), and `D` comes out within
//!    0.05 sample (asserted: 0.1).
//!
//! 4. **Inductance at two currents**: the toggling runs after DC point 1 too, so L
//!    is measured at `½·I_test` ([`TuneResult::l_low`]) and at `I_test`
//!    ([`TuneResult::l_phase`]): the drop of the incremental inductance with the
//!    current. The current loop is designed to stay within 5 % overshoot from 0.7
//!    to 1.3 × the tuned L ([`crate::current_loop`], "Design").
//!
//! After phase B, with both bridges at 0 V for `settle` s (the test current decays
//! through the winding), the phase currents are averaged for `average` s: the
//! **offsets** of the current channels with the bridges switching
//! ([`TuneResult::offset`], A; the power-up calibration is made with the bridges
//! off). They are measured last because the rotor is then at rest in the detent the
//! test current pulled it into: before the first DC point a rotor creeping into its
//! detent drives a real back-EMF current through the switching bridges (tens of mA
//! in the plant for a rotor 0.7° off its detent), which an offset measurement
//! cannot tell from an offset. R and L come from differences and do not depend on
//! the offsets; the dead-time intercept below is corrected with them.
//!
//! From the DC points come two more results:
//! * **dead-time loss** ([`TuneResult::dead_time_v`]): the intercept `V₂ − R·I₂` of
//!   each phase's V-I line, the voltage the bridge loses at a positive current,
//!   mean of both phases;
//! * **channel gain ratio** ([`TuneResult::gain_b`]): the two windings are wound
//!   alike, so a difference between the phases' apparent resistances `R/g` is the
//!   current sensors' gain difference `g`; `gain_b = R_B/R_A` is the factor that
//!   scales channel B to channel A. A winding mismatch is indistinguishable from it
//!   and is calibrated away with it (it is what the bridge sees as the same
//!   current). A ratio outside [`GAIN_RATIO_BAND`] or an offset above
//!   [`AutotuneConfig::max_offset`] is a sensing fault, [`TuneError::Sensing`].
//!
//! # Channel gains
//! Each channel `X` reads `g_X` times its current. [`TuneResult::gain`] scales channel
//! A by `1/√gain_b` and B by `√gain_b`: both then read `√(g_A·g_B)` times the current,
//! the geometric mean of the two sensing paths. Against what reference? Only the
//! bus voltage is measured independently of the current channels, and every
//! electrical quantity the drive can measure at the motor terminals is a voltage
//! over a current it reads through the same channels: a gain `c` common to both
//! channels makes the motor look like one with `R/c` and `L/c`, with the same
//! voltages and the same time constant `L/R`, so no terminal measurement can tell
//! it (the bus voltage over the measured R is `c` times the true current, exactly as
//! the channels read it). The difference of the channels is observable (the two
//! windings are the reference for each other) and is calibrated; the common part
//! `√(g_A·g_B) − 1` is what is left. For channels independently within ±x % of
//! nominal the residual is the mean of two independent errors, `±x/√2` % rms-wise
//! and at most `±x` %; for the symmetric case (`g = 1 ± x`) it is `x²/2`
//! (0.05 % for ±3 %). A reference outside the terminals (a precision current
//! through a sensing path, a torque measurement) would be needed for more; the
//! board has none.
//!
//! All applied voltages are rounded to the modulator's resolution (`2·Vbus/period`,
//! see [`crate::modulation::Modulator::duties`]) so the averaged command equals what
//! the bridge produced. Gains: `Kp = L·ωc`, `Ki = R·ωc` with the means of both phases.
//! Phases differing by more than `unbalance` (relative) → [`TuneError::Unbalanced`].
//!
//! Integer scaling of the reported values (drive parameters):
//! * resistance: mΩ (`0x2020`), inductance: µH (`0x2021`);
//! * current Kp (`0x2015`): **0.01 V/A** per unit (1000 = 10 V/A);
//! * current Ki (`0x2016`): **10 V/(A·s)** per unit (200 = 2000 V/(A·s)).
//!
//! With the default ωc = [`crate::current_loop::robust_bandwidth`] (0.23/Ts, 9.2·10³
//! rad/s at 40 kHz) an ECN57-20 (0.4 Ω, 1.8 mH) gives Kp = 1656, Ki = 368.

use crate::num;
use crate::pi::Pi;

/// Phase being measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Phase {
    /// Phase A.
    #[default]
    A,
    /// Phase B.
    B,
}

/// Why auto-tune failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TuneError {
    /// No current flows in this phase (open coil, poor contact).
    OpenPhase(Phase),
    /// The phases' R or L differ by more than the configured ratio.
    Unbalanced,
    /// A result outside the physically plausible range (R ≤ 0, L ≤ 0, no ripple).
    Implausible,
    /// The current sensing calibration is outside its plausible band: the channels'
    /// gains differ by more than [`GAIN_RATIO_BAND`] or an offset with the bridges
    /// switching exceeds [`AutotuneConfig::max_offset`].
    Sensing,
}

/// Time constants `L/R` the test current decays for before the offsets are
/// measured (e⁻¹² of 4 A is 25 µA).
pub const OFFSET_SETTLE_TAUS: f32 = 12.0;

/// Plausible band of the channel gain ratio [`TuneResult::gain_b`].
pub const GAIN_RATIO_BAND: (f32, f32) = (0.9, 1.1);

/// Steps of the procedure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TuneState {
    /// First DC point on the phase.
    Dc1(Phase),
    /// Second DC point.
    Dc2(Phase),
    /// Voltage toggling for L (after DC point 1, then after DC point 2).
    Toggle(Phase),
    /// Current-channel offsets with both bridges at 0 V.
    Offsets,
    /// Finished.
    Done(TuneResult),
    /// Failed.
    Failed(TuneError),
}

/// Auto-tune configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutotuneConfig {
    /// Sample period, s.
    pub ts: f32,
    /// Test current I₂, A (I₁ = I₂/2).
    pub test_current: f32,
    /// PWM timer period in counts (voltage resolution `2·Vbus/period`).
    pub pwm_period: u16,
    /// Largest voltage used, fraction of the bus voltage.
    pub max_modulation: f32,
    /// DC regulator proportional gain, V/A.
    pub kp_init: f32,
    /// DC regulator integral corner, rad/s.
    pub wi_init: f32,
    /// Settling time at each DC point, s.
    pub settle: f32,
    /// Averaging time at each DC point, s.
    pub average: f32,
    /// Toggle amplitude, fraction of the bus voltage.
    pub toggle_modulation: f32,
    /// Toggle half period, samples (at least `delay + 3`).
    pub toggle_half: u32,
    /// Toggling time, s.
    pub toggle_time: f32,
    /// Largest delay between a command and the bridge applying it that the L
    /// measurement tolerates, whole samples (0..=8): each half period's slope is taken
    /// from `delay + 1` samples after the command changed (module docs, step 3).
    pub delay: u32,
    /// Target current-loop bandwidth ωc, rad/s.
    pub bandwidth: f32,
    /// Largest relative difference between the phases' R and L.
    pub unbalance: f32,
    /// Largest plausible current-channel offset with the bridges switching, A.
    pub max_offset: f32,
}

impl AutotuneConfig {
    /// Defaults for a 40 kHz loop and test current `i_test` (A).
    pub fn new(ts: f32, pwm_period: u16, i_test: f32) -> Self {
        AutotuneConfig {
            ts,
            test_current: i_test,
            pwm_period,
            max_modulation: 0.5,
            kp_init: 2.0,
            wi_init: 400.0,
            settle: 0.04,
            average: 0.02,
            toggle_modulation: 0.2,
            toggle_half: 8,
            toggle_time: 0.02,
            delay: 1,
            bandwidth: crate::current_loop::robust_bandwidth(ts),
            unbalance: 0.2,
            max_offset: 0.25,
        }
    }
}

/// Measured values and computed gains.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TuneResult {
    /// Resistance per phase (A, B), Ω.
    pub r_phase: [f32; 2],
    /// Inductance per phase (A, B), H.
    pub l_phase: [f32; 2],
    /// Mean resistance, Ω.
    pub r: f32,
    /// Mean inductance, H.
    pub l: f32,
    /// Current-loop proportional gain, V/A.
    pub kp: f32,
    /// Current-loop integral gain, V/(A·s).
    pub ki: f32,
    /// Inductance per phase at half the test current, H.
    pub l_low: [f32; 2],
    /// Current-channel offsets (A, B) with the bridges switching at 0 V, A.
    pub offset: [f32; 2],
    /// Dead-time voltage loss of the bridges, V (mean of both phases).
    pub dead_time_v: f32,
    /// Gain factor that scales current channel B to channel A (`gain[1]/gain[0]`).
    pub gain_b: f32,
    /// Gain factor of each current channel (A, B) that makes both read their common
    /// mean (module docs, "Channel gains").
    pub gain: [f32; 2],
    /// Delay from a command to the bridge applying it, samples (mean of both
    /// phases, measured at the test current).
    pub delay: f32,
}

/// `x·scale` rounded to a parameter value in `min..=max` (`min` for a non-finite or
/// non-positive product). One out-of-line copy for the four scalings (cold code: once
/// per auto-tune).
// Measured (cargo xtask size, LAN9252 image): without it and `quantize`'s, both are inlined
// into the current-loop interrupt (+876 B there), +636 B flash.
#[inline(never)]
fn to_param(x: f32, scale: f32, min: u16, max: u16) -> u16 {
    let x = x * scale;
    let p = if x.is_finite() && x > 0.0 {
        (x + 0.5).min(max as f32) as u16
    } else {
        0
    };
    p.max(min)
}

impl TuneResult {
    /// Resistance in mΩ (0x2020 scaling, 1..=20000).
    pub fn resistance_mohm(&self) -> u16 {
        to_param(self.r, 1e3, 1, 20000)
    }
    /// Inductance in µH (0x2021 scaling, 1..=6000).
    pub fn inductance_uh(&self) -> u16 {
        to_param(self.l, 1e6, 1, 6000)
    }
    /// Kp in 0.01 V/A (0x2015 scaling, clamped to 200..=32767).
    pub fn kp_param(&self) -> u16 {
        to_param(self.kp, 100.0, 200, 32767)
    }
    /// Ki in 10 V/(A·s) (0x2016 scaling, 0..=32767).
    pub fn ki_param(&self) -> u16 {
        to_param(self.ki, 0.1, 0, 32767)
    }
}

/// Kp (V/A) from a 0x2015 value.
pub fn kp_from_param(p: u16) -> f32 {
    p as f32 * 0.01
}

/// Ki (V/(A·s)) from a 0x2016 value.
pub fn ki_from_param(p: u16) -> f32 {
    p as f32 * 10.0
}

/// `v` rounded to a multiple of the voltage step `q` (0 without a step). One
/// out-of-line copy for the three uses in [`Autotune::step`].
// Measured (cargo xtask size, LAN9252 image): see `to_param`.
#[inline(never)]
fn quantize(v: f32, q: f32) -> f32 {
    if q > 0.0 {
        libm::roundf(v / q) * q
    } else {
        0.0
    }
}

/// The short phase check at the first enable when the power-up tune is off
/// (0x2013 = 0): is there a coil behind each phase?
///
/// Each phase in turn gets the voltage passed to [`PhaseCheck::step`] while the other is held at 0 V, until its
/// current reaches `i_check` (A); then the reverse voltage until the current is below
/// a tenth of it (or `max_steps` passed), and the next phase. A phase whose current has
/// not reached `i_check` after `max_steps` samples is [`TuneError::OpenPhase`].
///
/// With ½·Vmax the current of an ECN57-20 (1.8 mH) at 48 V rises by
/// 12.7 A/ms, so 1 A takes 3-4 samples of 25 µs and the whole check well under 1 ms;
/// the one sample of computation delay overshoots `i_check` by one sample's rise
/// (0.3 A). The pulses are too short to move the rotor, unlike the tune's DC points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhaseCheck {
    i_check: f32,
    max_steps: u32,
    phase: Phase,
    decaying: bool,
    t: u32,
    /// `Some` once finished: `Ok` when both phases carried current.
    pub result: Option<Result<(), TuneError>>,
}

impl PhaseCheck {
    /// New check (phase A first).
    pub fn new(i_check: f32, max_steps: u32) -> Self {
        PhaseCheck {
            i_check: num::pos(i_check),
            max_steps: max_steps.max(2),
            phase: Phase::A,
            decaying: false,
            t: 0,
            result: None,
        }
    }

    /// One sample: measured phase currents (A) and the pulse voltage (V). Returns the
    /// phase voltages (V).
    pub fn step(&mut self, ia: f32, ib: f32, v_check: f32) -> (f32, f32) {
        if self.result.is_some() {
            return (0.0, 0.0);
        }
        let i = if self.phase == Phase::A { ia } else { ib };
        let v = num::pos(v_check);
        let on_phase = |v: f32| match self.phase {
            Phase::A => (v, 0.0),
            Phase::B => (0.0, v),
        };
        self.t += 1;
        if self.decaying {
            if i < 0.1 * self.i_check || self.t >= self.max_steps {
                self.t = 0;
                self.decaying = false;
                match self.phase {
                    Phase::A => self.phase = Phase::B,
                    Phase::B => self.result = Some(Ok(())),
                }
                return (0.0, 0.0);
            }
            // The reverse voltage brings the current back as fast as it rose.
            return on_phase(-v);
        }
        if i >= self.i_check {
            self.t = 0;
            self.decaying = true;
            return on_phase(-v);
        }
        if self.t >= self.max_steps {
            self.result = Some(Err(TuneError::OpenPhase(self.phase)));
            return (0.0, 0.0);
        }
        on_phase(v)
    }
}

/// The auto-tune state machine.
#[derive(Clone, Copy, Debug)]
pub struct Autotune {
    cfg: AutotuneConfig,
    /// Present state.
    pub state: TuneState,
    t: u32,
    settle_steps: u32,
    avg_steps: u32,
    toggle_steps: u32,
    /// The DC regulator (`kp_init`, `kp_init·wi_init`; its limit is passed per step).
    pi: Pi,
    sum_v: f32,
    sum_i: f32,
    n: u32,
    v1: f32,
    i1: f32,
    v_dc: f32,
    /// Current at the end of the last half period (the sample before a change).
    i_mark: f32,
    /// Current `delay + 1` samples after the last change.
    i_start: f32,
    sum_di: f32,
    n_di: u32,
    /// Signed current changes across the corners, and their number (the delay).
    sum_c: f32,
    n_c: u32,
    vt: f32,
    /// The toggling after DC point 2 (not after DC point 1).
    second_toggle: bool,
    /// Settling steps of the offset measurement.
    offset_settle: u32,
    res: TuneResult,
}

impl Autotune {
    /// New procedure (starts with phase A, DC point 1).
    pub fn new(cfg: AutotuneConfig) -> Self {
        let ts = if cfg.ts > 0.0 && cfg.ts.is_finite() {
            cfg.ts
        } else {
            25e-6
        };
        let mut cfg = cfg;
        cfg.ts = ts;
        cfg.delay = cfg.delay.min(8);
        cfg.toggle_half = cfg.toggle_half.clamp(cfg.delay + 3, 1000);
        cfg.pwm_period = cfg.pwm_period.max(2);
        let steps = |t: f32| ((t.max(0.0) / ts) as u32).max(1);
        Autotune {
            cfg,
            state: TuneState::Dc1(Phase::A),
            t: 0,
            settle_steps: steps(cfg.settle),
            avg_steps: steps(cfg.average),
            toggle_steps: steps(cfg.toggle_time).max(4 * cfg.toggle_half),
            pi: Pi::new(cfg.kp_init, cfg.kp_init * cfg.wi_init, ts, 0.0),
            sum_v: 0.0,
            sum_i: 0.0,
            n: 0,
            v1: 0.0,
            i1: 0.0,
            v_dc: 0.0,
            i_mark: 0.0,
            i_start: 0.0,
            sum_di: 0.0,
            n_di: 0,
            sum_c: 0.0,
            n_c: 0,
            vt: 0.0,
            second_toggle: false,
            offset_settle: 0,
            res: TuneResult {
                gain_b: 1.0,
                gain: [1.0; 2],
                ..TuneResult::default()
            },
        }
    }

    /// True when finished (done or failed).
    pub fn finished(&self) -> bool {
        matches!(self.state, TuneState::Done(_) | TuneState::Failed(_))
    }

    /// One step: measured phase currents (A) and bus voltage (V). Returns the phase
    /// voltages `(v_A, v_B)` to apply (V).
    pub fn step(&mut self, ia: f32, ib: f32, vbus: f32) -> (f32, f32) {
        if self.state == TuneState::Offsets {
            self.measure_offsets(ia, ib);
            return (0.0, 0.0);
        }
        let (phase, i) = match self.state {
            TuneState::Dc1(p) | TuneState::Dc2(p) | TuneState::Toggle(p) => {
                (p, if p == Phase::A { ia } else { ib })
            }
            _ => return (0.0, 0.0),
        };
        self.t = self.t.saturating_add(1);
        let v = match self.state {
            TuneState::Dc1(_) | TuneState::Dc2(_) => self.dc_step(phase, i, vbus),
            TuneState::Toggle(_) => self.toggle_step(phase, i),
            _ => 0.0,
        };
        match phase {
            Phase::A => (v, 0.0),
            Phase::B => (0.0, v),
        }
    }

    /// A step of DC point 1 or 2 on `phase` (current `i`, bus voltage `vbus`): the
    /// regulator, then the averages. Returns the phase voltage.
    fn dc_step(&mut self, phase: Phase, i: f32, vbus: f32) -> f32 {
        let q = 2.0 * num::pos(vbus) / self.cfg.pwm_period as f32;
        let quant = |v: f32| quantize(v, q);
        let vmax = num::pos(self.cfg.max_modulation * vbus);
        let first = matches!(self.state, TuneState::Dc1(_));
        let target = if first {
            0.5 * self.cfg.test_current
        } else {
            self.cfg.test_current
        };
        let e = target - i;
        let u = self.pi.output_unlimited(e);
        // Limited: at or beyond ±vmax (or not a number).
        let limited = u.abs().partial_cmp(&vmax) != Some(core::cmp::Ordering::Less);
        self.pi.integrate(e, u, limited, -vmax, vmax);
        let v = quant(num::clamp(u, -vmax, vmax));
        if self.t == self.settle_steps
            && first
            && i.abs().partial_cmp(&(0.2 * target.abs())) != Some(core::cmp::Ordering::Greater)
        {
            self.state = TuneState::Failed(TuneError::OpenPhase(phase));
            return 0.0;
        }
        if self.t > self.settle_steps {
            // The voltage applied now reaches the coil one sample later;
            // at steady state that does not matter for the averages.
            self.sum_v += v;
            self.sum_i += i;
            self.n += 1;
        }
        if self.t >= self.settle_steps.saturating_add(self.avg_steps) {
            let n = self.n.max(1) as f32;
            let (va, im) = (self.sum_v / n, self.sum_i / n);
            self.sum_v = 0.0;
            self.sum_i = 0.0;
            self.n = 0;
            self.t = 0;
            self.vt = quant(num::pos(self.cfg.toggle_modulation * vbus));
            self.sum_di = 0.0;
            self.n_di = 0;
            self.sum_c = 0.0;
            self.n_c = 0;
            if first {
                self.v1 = va;
                self.i1 = im;
                self.v_dc = quant(va);
                self.second_toggle = false;
                self.state = TuneState::Toggle(phase);
            } else {
                let di = im - self.i1;
                let r = if di.abs() > 1e-6 {
                    (va - self.v1) / di
                } else {
                    0.0
                };
                self.res.r_phase[phase as usize] = r;
                self.res.dead_time_v += 0.5 * (va - r * im);
                self.v_dc = quant(va);
                self.second_toggle = true;
                self.state = TuneState::Toggle(phase);
            }
        }
        v
    }

    /// A step of the toggling on `phase` (current `i`). Returns the phase voltage.
    fn toggle_step(&mut self, phase: Phase, i: f32) -> f32 {
        // Sample k = t−1 (0-based). Half periods: the first is h/2 long so the
        // triangle is centred on I₂, then half period m (m ≥ 0) is commanded
        // from k = h0 + m·h, negative for even m. (h ≥ delay + 3 since `new`;
        // the `max` tells the compiler it is not 0.)
        let h = self.cfg.toggle_half.max(1);
        let p = self.cfg.delay + 1;
        let k = self.t - 1;
        let h0 = h / 2;
        let sign = if k < h0 || ((k - h0) / h) % 2 == 1 {
            1.0
        } else {
            -1.0
        };
        if k >= h0 {
            let (m, j) = ((k - h0) / h, (k - h0) % h);
            // Sign of the half period that ends at a change (m − 1 when j = 0).
            let ended = if m % 2 == 1 { -1.0 } else { 1.0 };
            if j == 0 {
                if m > 0 {
                    // The edge of half period m − 1: from p after its change to now.
                    self.sum_di += ended * (i - self.i_start);
                    self.n_di += 1;
                }
                self.i_mark = i;
            } else if j == p && m > 0 {
                // Across the corner after the change at h0 + m·h: the old edge
                // (sign of half period m − 1) for D samples, the new one for p − D.
                self.sum_c += ended * (i - self.i_mark);
                self.n_c += 1;
            }
            if j == p {
                self.i_start = i;
            }
        }
        if self.t >= self.toggle_steps && k > h0 && (k - h0).is_multiple_of(2 * h) {
            self.finish_phase(phase);
            0.0
        } else {
            self.v_dc + sign * self.vt
        }
    }

    /// Offsets: at 0 V for `settle` s or [`OFFSET_SETTLE_TAUS`] of phase B's measured
    /// `L/R` (whichever is longer: the test current must have decayed to a few µA),
    /// then the currents averaged for `average` s.
    fn measure_offsets(&mut self, ia: f32, ib: f32) {
        self.t = self.t.saturating_add(1);
        if self.t == 1 {
            let (r, l) = (self.res.r_phase[1], self.res.l_phase[1]);
            let tau = if r > 0.0 && l > 0.0 { l / r } else { 0.0 };
            let decay = (OFFSET_SETTLE_TAUS * tau / self.cfg.ts).min(u32::MAX as f32) as u32;
            self.offset_settle = self.settle_steps.max(decay);
        }
        if self.t <= self.offset_settle {
            return;
        }
        self.sum_v += ia;
        self.sum_i += ib;
        self.n += 1;
        if self.t >= self.offset_settle.saturating_add(self.avg_steps) {
            let n = self.n.max(1) as f32;
            self.res.offset = [self.sum_v / n, self.sum_i / n];
            self.sum_v = 0.0;
            self.sum_i = 0.0;
            self.n = 0;
            self.t = 0;
            self.evaluate();
        }
    }

    fn finish_phase(&mut self, phase: Phase) {
        let p = self.cfg.delay + 1;
        let edge = (self.cfg.toggle_half - p) as f32;
        let span = self.vt * edge * self.cfg.ts * self.n_di as f32;
        let l = if self.sum_di > 1e-6 {
            span / self.sum_di
        } else {
            0.0
        };
        if self.second_toggle && self.n_c > 0 && self.n_di > 0 && self.sum_di > 1e-6 {
            // Slope per sample, then D from the corners (module docs, step 3).
            let s = self.sum_di / (self.n_di as f32 * edge);
            let d = 0.5 * (p as f32 + self.sum_c / (self.n_c as f32 * s));
            self.res.delay += 0.5 * d;
        }
        self.t = 0;
        if !self.second_toggle {
            // After DC point 1: on to DC point 2 (the regulator keeps its state).
            self.res.l_low[phase as usize] = l;
            self.state = TuneState::Dc2(phase);
            return;
        }
        self.res.l_phase[phase as usize] = l;
        self.pi.reset();
        match phase {
            Phase::A => self.state = TuneState::Dc1(Phase::B),
            Phase::B => self.state = TuneState::Offsets,
        }
    }

    fn evaluate(&mut self) {
        let r = self.res.r_phase;
        let l = self.res.l_phase;
        let ok = |x: f32| x.is_finite() && x > 0.0;
        if !(ok(r[0]) && ok(r[1]) && ok(l[0]) && ok(l[1])) {
            self.state = TuneState::Failed(TuneError::Implausible);
            return;
        }
        let u = self.cfg.unbalance;
        let (rm, lm) = (0.5 * (r[0] + r[1]), 0.5 * (l[0] + l[1]));
        if (r[0] - r[1]).abs() > u * rm || (l[0] - l[1]).abs() > u * lm {
            self.state = TuneState::Failed(TuneError::Unbalanced);
            return;
        }
        let gain_b = r[1] / r[0];
        let m = self.cfg.max_offset;
        let offset_ok = |o: f32| o.is_finite() && o.abs() <= m;
        let off = self.res.offset;
        let plausible = (GAIN_RATIO_BAND.0..=GAIN_RATIO_BAND.1).contains(&gain_b)
            && offset_ok(off[0])
            && offset_ok(off[1]);
        if !plausible {
            self.state = TuneState::Failed(TuneError::Sensing);
            return;
        }
        self.res.gain_b = gain_b;
        // Both channels to their geometric mean (module docs, "Channel gains").
        let g = num::sqrtf(gain_b);
        self.res.gain = [1.0 / g, g];
        // The intercepts were taken on currents that include the offsets.
        self.res.dead_time_v += 0.5 * (r[0] * off[0] + r[1] * off[1]);
        // R and L in the units of the calibrated channels: √(R_A·R_B), √(L_A·L_B)
        // (a channel reading `c` times the current shows R/c and L/c).
        self.res.r = num::sqrtf(r[0] * r[1]);
        self.res.l = num::sqrtf(l[0] * l[1]);
        self.res.kp = lm * self.cfg.bandwidth;
        self.res.ki = rm * self.cfg.bandwidth;
        self.state = TuneState::Done(self.res);
    }

    /// Partial results so far (per-phase values filled as they are measured).
    pub fn partial(&self) -> &TuneResult {
        &self.res
    }
}
