//! Faults injected into the simulated drives' plants at a given time
//! (`virtual-drive --fault KIND@TIME`), and the log of what an integrator then sees:
//! the injection itself and every change of the LED patterns (RUN, ERR, the red fault
//! LED's blink code) with its time.
//!
//! An injection changes the *plant* (the motor, the power stage, the supply), never
//! the drive: the drive's own detections (`firmware::faults`, the current-loop
//! supervisor, the power stage's break latch) must find the fault, exactly as on a
//! board. The kinds are those the drive can detect ([`InjectedFault::ALL`]); what the
//! drive reports for each is in [`InjectedFault::effect`] (checked by
//! `tests-host/tests/virtual_fault_inject.rs`).
//!
//! Encoder loss has no fault of its own: the encoder interface of the board (a timer
//! counting A/B edges) cannot tell a lost signal from a shaft at rest, so the drive
//! notices it as the following error of the closed loop once the axis should move —
//! as the reference product does ("over-error", 7 flashes). Not offered:
//! over-temperature (neither the plant nor the drive models a temperature).

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::leds::{run_pattern, ErrCondition, Pattern};
use firmware::faults::{FaultKind, Faults};

use crate::segment::Segment;
use crate::sim_drive::SimDrive;

/// A physical fault the plant develops.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InjectedFault {
    /// Motor phase A open: no current in it whatever the bridge applies.
    OpenPhaseA,
    /// Motor phase B open.
    OpenPhaseB,
    /// Short circuit across the terminals of phase A.
    PhaseShort,
    /// The DC bus rises to [`OVERVOLTAGE_V`].
    BusOvervoltage,
    /// The DC bus falls to [`UNDERVOLTAGE_V`].
    BusUndervoltage,
    /// The encoder signals are lost: the counter stops where it is.
    EncoderLoss,
}

/// Bus voltage of [`InjectedFault::BusOvervoltage`], V (the drive's limit: 55 V).
pub const OVERVOLTAGE_V: f64 = 60.0;
/// Bus voltage of [`InjectedFault::BusUndervoltage`], V (the drive's limit: 12 V).
pub const UNDERVOLTAGE_V: f64 = 9.0;

impl InjectedFault {
    /// Every kind, in the order of `--help`.
    pub const ALL: [InjectedFault; 6] = [
        InjectedFault::OpenPhaseA,
        InjectedFault::OpenPhaseB,
        InjectedFault::PhaseShort,
        InjectedFault::BusOvervoltage,
        InjectedFault::BusUndervoltage,
        InjectedFault::EncoderLoss,
    ];

    /// Its name on the command line.
    pub const fn name(self) -> &'static str {
        match self {
            InjectedFault::OpenPhaseA => "open-phase-a",
            InjectedFault::OpenPhaseB => "open-phase-b",
            InjectedFault::PhaseShort => "phase-short",
            InjectedFault::BusOvervoltage => "bus-overvoltage",
            InjectedFault::BusUndervoltage => "bus-undervoltage",
            InjectedFault::EncoderLoss => "encoder-loss",
        }
    }

    /// The kind called `name`.
    pub fn from_name(name: &str) -> Option<InjectedFault> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The fault the drive reports for it (closed loop for the encoder loss).
    pub const fn reported(self) -> FaultKind {
        match self {
            InjectedFault::OpenPhaseA | InjectedFault::OpenPhaseB => FaultKind::MotorOpen,
            InjectedFault::PhaseShort => FaultKind::OverCurrent,
            InjectedFault::BusOvervoltage => FaultKind::OverVoltage,
            InjectedFault::BusUndervoltage => FaultKind::UnderVoltage,
            InjectedFault::EncoderLoss => FaultKind::FollowingError,
        }
    }

    /// What the plant does, and when the drive can see it.
    pub const fn plant(self) -> &'static str {
        match self {
            InjectedFault::OpenPhaseA | InjectedFault::OpenPhaseB => {
                "phase current 0; at start (TIME 0s) the power-up tune, or the phase check \
                 of the first enable, finds it; while running, the current loop finds it \
                 once the drive demands 0.6 A or more in that phase (a load or a fast \
                 acceleration; the virtual axis has no load)"
            }
            InjectedFault::PhaseShort => "phase A shorted; found while the power stage is on",
            InjectedFault::BusOvervoltage => "bus 60 V",
            InjectedFault::BusUndervoltage => "bus 9 V (the injected bus stays low)",
            InjectedFault::EncoderLoss => {
                "encoder counter stops; closed loop (0x2024 = 2): the rotor stalls on the \
                 frozen commutation angle, and once the axis is commanded to move (any \
                 mode) the following error passes 0x2030; open loop: the motor keeps \
                 running and 0x6064 stops, so 0x60F4 grows against the window 0x6065 in \
                 PP, CSP and HM"
            }
        }
    }

    /// What the plant does and what the drive reports (for `--help` and the log):
    /// [`InjectedFault::plant`], then the fault table's row of
    /// [`InjectedFault::reported`] ([`report_text`]).
    pub fn effect(self) -> String {
        format!(
            "{}; the drive reports {}",
            self.plant(),
            report_text(self.reported())
        )
    }
}

/// What the drive reports for `kind`, from its row of the fault table
/// (`firmware::faults::TABLE`): name, code, red flashes, reaction, latching, 0x2056
/// bit and whether the default mask enables it.
pub fn report_text(kind: FaultKind) -> String {
    let i = kind.info();
    let flashes = match i.flashes {
        0 => "the ERR LED".to_string(),
        1 => "1 red flash".to_string(),
        n => format!("{n} red flashes"),
    };
    let reaction = if i.cuts_power {
        "power off at once"
    } else {
        "0x605E fault reaction then Fault"
    };
    let latched = if i.latched {
        "latched (0x2057)"
    } else {
        "not latched"
    };
    let mask = match kind.mask_bit() {
        None => "cannot be masked".to_string(),
        Some(b) => format!(
            "0x2056 bit {b} ({} by default)",
            if Faults::default().enabled(kind) {
                "on"
            } else {
                "off"
            }
        ),
    };
    format!(
        "{} {:#06x}, {flashes}, {reaction}, {latched}, {mask}",
        i.name, i.code
    )
}

/// One `--fault KIND@TIME`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Injection {
    /// The fault.
    pub fault: InjectedFault,
    /// When, ns of simulated time since start.
    pub at_ns: u64,
}

/// A time like `5s`, `250ms`, `1.5s`, `800us`: nanoseconds.
pub fn parse_time(s: &str) -> Result<u64, String> {
    let (num, scale) = if let Some(n) = s.strip_suffix("ms") {
        (n, 1e6)
    } else if let Some(n) = s.strip_suffix("us") {
        (n, 1e3)
    } else if let Some(n) = s.strip_suffix('s') {
        (n, 1e9)
    } else {
        return Err(format!(
            "time '{s}' needs a unit: s, ms or us (e.g. 5s, 250ms)"
        ));
    };
    match num.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 && v * scale < u64::MAX as f64 => {
            Ok((v * scale).round() as u64)
        }
        _ => Err(format!("'{s}' is not a time (e.g. 5s, 250ms)")),
    }
}

/// The kinds for an error message or the usage text.
pub fn kind_names() -> String {
    InjectedFault::ALL
        .iter()
        .map(|k| k.name())
        .collect::<Vec<_>>()
        .join(", ")
}

/// `KIND@TIME`, e.g. `bus-overvoltage@1s`.
pub fn parse_injection(s: &str) -> Result<Injection, String> {
    let Some((kind, time)) = s.split_once('@') else {
        return Err(format!(
            "--fault '{s}': expected KIND@TIME, e.g. bus-overvoltage@5s"
        ));
    };
    let fault = InjectedFault::from_name(&kind.to_ascii_lowercase()).ok_or_else(|| {
        format!(
            "--fault '{s}': unknown fault kind '{kind}' (one of: {})",
            kind_names()
        )
    })?;
    let at_ns = parse_time(time).map_err(|e| format!("--fault '{s}': {e}"))?;
    Ok(Injection { fault, at_ns })
}

/// The injections still to come, applied to every drive of a segment when their time
/// is reached.
#[derive(Debug, Clone, Default)]
pub struct Schedule {
    pending: Vec<Injection>,
}

impl Schedule {
    /// The injections, in any order.
    pub fn new(mut injections: Vec<Injection>) -> Self {
        injections.sort_by_key(|i| std::cmp::Reverse(i.at_ns));
        Schedule {
            pending: injections,
        }
    }

    /// True when every injection has been applied.
    pub fn is_done(&self) -> bool {
        self.pending.is_empty()
    }

    /// Applies the injections whose time has come (segment time) to every drive's
    /// plant; one log line each.
    pub fn apply_due(&mut self, seg: &mut Segment<SimDrive>, log: &mut dyn FnMut(String)) {
        let now = seg.now_ns();
        while self.pending.last().is_some_and(|i| i.at_ns <= now) {
            let Some(inj) = self.pending.pop() else {
                break;
            };
            for (n, d) in seg.drives_mut().iter_mut().enumerate() {
                let applied = d.app.axis.inject(inj.fault);
                log(format!(
                    "{} drive {}: fault injected: {}{}",
                    stamp(now),
                    n + 1,
                    inj.fault.name(),
                    if applied {
                        format!(" ({})", inj.fault.effect())
                    } else {
                        " — not supported by this axis model".to_string()
                    }
                ));
            }
        }
    }
}

/// `[  12.345 s]`.
fn stamp(now_ns: u64) -> String {
    format!("[{:9.3} s]", now_ns as f64 * 1e-9)
}

/// What the LEDs of one drive show: RUN and ERR (ETG.1300, from the ESM state and AL
/// status) and the red fault LED's blink code (number of flashes, `None` dark).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LedState {
    /// RUN pattern.
    pub run: Pattern,
    /// ERR pattern.
    pub err: Pattern,
    /// Red fault LED: flashes per burst.
    pub red: Option<u8>,
}

/// The LED state of drive `i` of `seg` now.
pub fn led_state(seg: &Segment<SimDrive>, i: usize) -> LedState {
    let d = seg.drive(i);
    let (status, code) = seg.al_status(i);
    let state = EsmState::from_bits(status as u8).unwrap_or(EsmState::Init);
    LedState {
        run: run_pattern(state),
        err: ErrCondition::from_al_status(status, code).pattern(),
        red: d.app.drive.faults.led_code(),
    }
}

/// Logs each change of a drive's [`LedState`] with the time: the LED timeline.
#[derive(Debug, Clone, Default)]
pub struct LedLog {
    last: Vec<Option<LedState>>,
}

impl LedLog {
    /// Compares every drive's LEDs with the last seen and logs the changes.
    pub fn observe(&mut self, seg: &Segment<SimDrive>, log: &mut dyn FnMut(String)) {
        self.last.resize(seg.len(), None);
        for i in 0..seg.len() {
            let now = led_state(seg, i);
            if self.last[i] != Some(now) {
                self.last[i] = Some(now);
                let red = match now.red {
                    Some(n) => format!("{n} flash(es) every 3 s"),
                    None => "dark".to_string(),
                };
                log(format!(
                    "{} drive {}: LEDs RUN {:?}, ERR {:?}, red fault LED {red}",
                    stamp(seg.now_ns()),
                    i + 1,
                    now.run,
                    now.err
                ));
            }
        }
    }
}

/// Logs each change of a drive's output pins and brake (what the board's tick drives,
/// [`firmware::runtime::Pins`]) with the time: OUT1-OUT3 levels and whether the brake
/// is released.
#[derive(Debug, Clone, Default)]
pub struct PinLog {
    last: Vec<Option<(u8, bool, bool)>>,
}

impl PinLog {
    /// Compares every drive's pins (and its model's bridges) with the last seen and logs
    /// the changes.
    pub fn observe(&mut self, seg: &Segment<SimDrive>, log: &mut dyn FnMut(String)) {
        self.last.resize(seg.len(), None);
        for i in 0..seg.len() {
            let pins = seg.drive(i).app.pins();
            let bridges = seg.drive(i).app.bridges_on();
            let now = (pins.outputs, pins.brake_released, bridges);
            if self.last[i] != Some(now) {
                self.last[i] = Some(now);
                log(format!(
                    "{} drive {}: pins OUT1 {} OUT2 {} OUT3 {}, brake {}, bridges {}",
                    stamp(seg.now_ns()),
                    i + 1,
                    level(pins.outputs, 0),
                    level(pins.outputs, 1),
                    level(pins.outputs, 2),
                    if pins.brake_released {
                        "released"
                    } else {
                        "engaged"
                    },
                    if bridges { "on" } else { "off" }
                ));
            }
        }
    }
}

fn level(bits: u8, n: u8) -> &'static str {
    if bits & (1 << n) != 0 {
        "high"
    } else {
        "low"
    }
}

/// Parses a DIP bank as it stands: eight characters `1` (ON) or `0` (OFF), switch 1
/// first (`11111110`: switch 8 OFF); returns bit n = switch n+1 ON.
pub fn parse_dip(s: &str) -> Result<u8, String> {
    if s.len() != 8 || !s.bytes().all(|b| b == b'0' || b == b'1') {
        return Err(format!(
            "DIP bank '{s}': eight characters 1 (ON) or 0 (OFF), switch 1 first"
        ));
    }
    Ok(s.bytes()
        .enumerate()
        .fold(0u8, |acc, (i, b)| acc | (u8::from(b == b'1') << i)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dip_banks() {
        assert_eq!(parse_dip("11111111"), Ok(0xFF));
        assert_eq!(parse_dip("01111111"), Ok(0xFE), "switch 1 OFF");
        assert_eq!(parse_dip("00000001"), Ok(0x80), "switch 8 ON");
        for bad in ["1111111", "111111111", "1111111x", "", "0xFF"] {
            assert!(parse_dip(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn times() {
        assert_eq!(parse_time("5s"), Ok(5_000_000_000));
        assert_eq!(parse_time("250ms"), Ok(250_000_000));
        assert_eq!(parse_time("1.5s"), Ok(1_500_000_000));
        assert_eq!(parse_time("800us"), Ok(800_000));
        assert_eq!(parse_time("0s"), Ok(0));
        assert!(parse_time("5").unwrap_err().contains("unit"));
        assert!(parse_time("xs").is_err());
        assert!(parse_time("-1s").is_err());
        assert!(parse_time("infs").is_err());
        assert!(parse_time("1e30s").is_err());
    }

    #[test]
    fn injections() {
        assert_eq!(
            parse_injection("bus-overvoltage@1s"),
            Ok(Injection {
                fault: InjectedFault::BusOvervoltage,
                at_ns: 1_000_000_000
            })
        );
        assert_eq!(
            parse_injection("Open-Phase-B@250ms").map(|i| i.fault),
            Ok(InjectedFault::OpenPhaseB)
        );
        for k in InjectedFault::ALL {
            let i = parse_injection(&format!("{}@2s", k.name())).expect("kind");
            assert_eq!((i.fault, i.at_ns), (k, 2_000_000_000));
        }
        let e = parse_injection("nonsense@x").unwrap_err();
        assert!(e.contains("unknown fault kind 'nonsense'"), "{e}");
        assert!(e.contains("bus-overvoltage"), "lists the kinds: {e}");
        let e = parse_injection("phase-short@x").unwrap_err();
        assert!(e.contains("needs a unit"), "{e}");
        let e = parse_injection("phase-short").unwrap_err();
        assert!(e.contains("KIND@TIME"), "{e}");
    }

    #[test]
    fn schedule_orders_by_time() {
        let s = Schedule::new(vec![
            Injection {
                fault: InjectedFault::PhaseShort,
                at_ns: 5,
            },
            Injection {
                fault: InjectedFault::BusUndervoltage,
                at_ns: 1,
            },
        ]);
        assert_eq!(s.pending.last().map(|i| i.at_ns), Some(1));
        assert!(!s.is_done());
        assert!(Schedule::default().is_done());
    }
}
