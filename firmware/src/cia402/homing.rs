//! Homing (mode 6): methods 1-14, 17-30, 33, 34, 35 and 37, and the manufacturer's
//! stall homing −1 / −2.
//!
//! Every switch-based method is described by the *reference edge* `E` it homes on and
//! the direction of the final approach to it (`final_dir`). The points before `E` seen
//! in that direction form the approach side `P`, the others the far side `Q`. The
//! engine then runs the same sequence for every method:
//!
//! 1. (home-switch zone methods only, while the side is unknown) search in the method's
//!    initial direction at the switch-search speed 0x6099:01; on the method's limit
//!    switch stop and reverse;
//! 2. if on `P`: move in `final_dir` at 0x6099:01 until `Q` is reached, stop;
//! 3. on `Q`: move against `final_dir` until `P` is reached (0x6099:01 the first time,
//!    0x6099:02 after a reversal), stop;
//! 4. final approach in `final_dir` at the zero-search speed 0x6099:02 until the side
//!    changes: the position of that cycle is `E`;
//! 5. methods with index: keep moving at 0x6099:02 until the encoder index pulse; its
//!    hardware-latched position is the home position; without index the home position
//!    is `E`;
//! 6. stop, move back to the home position (0x6099:02) and make it read 0x607C
//!    (position actual value at the home position = home offset).
//!
//! Every move accelerates and stops with 0x609A. Reaching a limit switch that the method
//! does not use (or, in zone methods, after the reversal) is a homing error, as is an
//! index method without an encoder index or a method whose inputs are not assigned.
//! Methods 33/34 search the index directly (0x6099:02); 35/37 take the present position.
//!
//! **Stall homing** (−1 in the positive, −2 in the negative direction; open loop with
//! the stall detection 0x2060 on, `motion`): search at 0x6099:01 until the
//! motion layer confirms a stall against a hard stop ([`HomingInputs::stall`]: the
//! position where the stall began). That position is the home position: the demand
//! stops at once (the rotor stands at the stop; a ramp would drive the field on past
//! it), returns to it at 0x6099:02 and it reads 0x607C. The stall does not raise the
//! 0x2062 reaction during the search. A limit switch in the direction of the search
//! is a homing error. The search speed must lie above the detection's minimum
//! (1 rev/s, `foc::stall::MIN_SPEED_E`), or no stall is ever seen: a start without
//! the detection (closed loop or 0x2060 = 0) or with 0x6099:01 below that minimum
//! ([`HomingParams::stall_min_speed`]) is a homing error at once, with no motion.

use super::profile::{Motion, MoveStatus};

/// 0x60FD bit of the negative limit switch.
pub const DI_NEG_LIMIT: u32 = 1 << 0;
/// 0x60FD bit of the positive limit switch.
pub const DI_POS_LIMIT: u32 = 1 << 1;
/// 0x60FD bit of the home switch.
pub const DI_HOME: u32 = 1 << 2;

/// Which input a method homes on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sig {
    Neg,
    Pos,
    Home,
}

impl Sig {
    const fn mask(self) -> u32 {
        match self {
            Sig::Neg => DI_NEG_LIMIT,
            Sig::Pos => DI_POS_LIMIT,
            Sig::Home => DI_HOME,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// One edge: the signal equals `level` on the approach side.
    Edge { sig: Sig, level: bool },
    /// Home switch active on a zone `[lower, upper]`; `upper` chooses the edge;
    /// `init_dir` is the first search direction, reversed on that side's limit switch.
    Zone { upper: bool, init_dir: i8 },
    /// Index pulse only, searching in `final_dir`.
    Index,
    /// The present position.
    Here,
    /// A hard stop in `final_dir`, found by the stall detection.
    Stall,
}

/// What a method does (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Method {
    kind: Kind,
    final_dir: i8,
    index: bool,
}

impl Method {
    /// The description of `method`, `None` if unsupported: `Method::spec`, looked up
    /// in a one-byte-per-method table built from it at compile time (`PACKED`).
    pub const fn describe(method: i8) -> Option<Method> {
        if method < 0 {
            return Method::spec(method);
        }
        if method as usize >= PACKED.len() {
            return None;
        }
        Method::unpack(PACKED[method as usize])
    }

    /// The methods as written in the standard (compile time only: [`PACKED`]).
    const fn spec(method: i8) -> Option<Method> {
        use Kind::*;
        use Sig::{Home, Neg, Pos};
        /// An edge of `sig`, which equals `level` on the approach side.
        const fn edge(sig: Sig, level: bool) -> Kind {
            Edge { sig, level }
        }
        /// The `upper` or lower edge of the home switch zone, searched first in
        /// `init_dir`.
        const fn zone(upper: bool, init_dir: i8) -> Kind {
            Zone { upper, init_dir }
        }
        // Methods 1-14 end on the index pulse, 17-30 are the same without it.
        let (kind, final_dir, index) = match method {
            1 => (edge(Neg, true), 1, true),
            2 => (edge(Pos, true), -1, true),
            3 => (edge(Home, true), -1, true),
            4 => (edge(Home, false), 1, true),
            5 => (edge(Home, true), 1, true),
            6 => (edge(Home, false), -1, true),
            7 => (zone(false, 1), -1, true),
            8 => (zone(false, 1), 1, true),
            9 => (zone(true, 1), -1, true),
            10 => (zone(true, 1), 1, true),
            11 => (zone(true, -1), 1, true),
            12 => (zone(true, -1), -1, true),
            13 => (zone(false, -1), 1, true),
            14 => (zone(false, -1), -1, true),
            17 => (edge(Neg, true), 1, false),
            18 => (edge(Pos, true), -1, false),
            19 => (edge(Home, true), -1, false),
            20 => (edge(Home, false), 1, false),
            21 => (edge(Home, true), 1, false),
            22 => (edge(Home, false), -1, false),
            23 => (zone(false, 1), -1, false),
            24 => (zone(false, 1), 1, false),
            25 => (zone(true, 1), -1, false),
            26 => (zone(true, 1), 1, false),
            27 => (zone(true, -1), 1, false),
            28 => (zone(true, -1), -1, false),
            29 => (zone(false, -1), 1, false),
            30 => (zone(false, -1), -1, false),
            33 => (Index, -1, true),
            34 => (Index, 1, true),
            35 | 37 => (Here, 1, false),
            -1 => (Stall, 1, false),
            -2 => (Stall, -1, false),
            _ => return None,
        };
        Some(Method {
            kind,
            final_dir,
            index,
        })
    }

    /// One byte for [`PACKED`]: 0 = unsupported; else bit 7 set, bits 0-1 the kind
    /// (edge, zone, index, here), bit 2 `final_dir` > 0, bit 3 `index`; an edge's signal
    /// in bits 4-5 (negative, positive, home) and its level in bit 6; a zone's `upper` in
    /// bit 4 and `init_dir` > 0 in bit 5.
    const fn pack(m: Option<Method>) -> u8 {
        let Some(m) = m else {
            return 0;
        };
        let kind = match m.kind {
            Kind::Edge { sig, level } => {
                let s = match sig {
                    Sig::Neg => 0,
                    Sig::Pos => 1,
                    Sig::Home => 2,
                };
                (s << 4) | ((level as u8) << 6)
            }
            Kind::Zone { upper, init_dir } => {
                1 | ((upper as u8) << 4) | (((init_dir > 0) as u8) << 5)
            }
            Kind::Index => 2,
            Kind::Here | Kind::Stall => 3,
        };
        0x80 | kind | (((m.final_dir > 0) as u8) << 2) | ((m.index as u8) << 3)
    }

    /// The inverse of [`Method::pack`].
    const fn unpack(b: u8) -> Option<Method> {
        if b == 0 {
            return None;
        }
        let kind = match b & 3 {
            0 => Kind::Edge {
                sig: match (b >> 4) & 3 {
                    0 => Sig::Neg,
                    1 => Sig::Pos,
                    _ => Sig::Home,
                },
                level: b & 0x40 != 0,
            },
            1 => Kind::Zone {
                upper: b & 0x10 != 0,
                init_dir: ((b >> 5) & 1) as i8 * 2 - 1,
            },
            2 => Kind::Index,
            _ => Kind::Here,
        };
        Some(Method {
            kind,
            final_dir: ((b >> 2) & 1) as i8 * 2 - 1,
            index: b & 0x08 != 0,
        })
    }

    /// True if the method needs the encoder index pulse.
    pub const fn needs_index(&self) -> bool {
        self.index
    }

    /// 0x60FD bits the method needs assigned to inputs.
    pub const fn needs_inputs(&self) -> u32 {
        match self.kind {
            Kind::Edge { sig, .. } => sig.mask(),
            Kind::Zone { init_dir, .. } => {
                DI_HOME
                    | if init_dir > 0 {
                        DI_POS_LIMIT
                    } else {
                        DI_NEG_LIMIT
                    }
            }
            Kind::Index | Kind::Here | Kind::Stall => 0,
        }
    }
}

/// True if `method` is supported (0x6098 values accepted).
pub const fn supported(method: i8) -> bool {
    Method::describe(method).is_some()
}

/// [`Method::spec`] of the methods 0-37, one byte each ([`Method::pack`]).
const PACKED: [u8; 38] = {
    let mut t = [0u8; 38];
    let mut i = 0;
    while i < t.len() {
        t[i] = Method::pack(Method::spec(i as i8));
        i += 1;
    }
    t
};

/// Where the axis is relative to a home-switch zone.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Region {
    Unknown,
    Below,
    Inside,
    Above,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum After {
    Replan,
    SeekP { fast: bool },
    Fine,
    Return,
    Error,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    Idle,
    Locate {
        dir: i8,
    },
    /// Move in `dir` until the side is `P` (`to_p`) or `Q`.
    Seek {
        dir: i8,
        fast: bool,
        to_p: bool,
    },
    Fine,
    IndexSearch,
    /// Stall homing: move in `final_dir` at the search speed until a stall.
    StallSearch,
    Stopping {
        then: After,
    },
    Return,
    Done,
    Error,
}

/// Homing status as shown in statusword bits 10, 12, 13.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HomingStatus {
    /// Not started or interrupted.
    Idle,
    /// Running.
    InProgress,
    /// Home position set.
    Attained,
    /// Failed.
    Error,
}

/// The parameters of one homing run (already limited by 0x60C5/0x60C6).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomingParams {
    /// 0x6098.
    pub method: i8,
    /// 0x6099:01 (command units/s).
    pub fast: f32,
    /// 0x6099:02 (command units/s).
    pub slow: f32,
    /// 0x609A (command units/s²).
    pub acc: f32,
    /// 0x607C.
    pub offset: i32,
    /// The encoder has an index pulse.
    pub has_index: bool,
    /// 0x60FD bits that are assigned to physical inputs.
    pub assigned: u32,
    /// Stall homing's lowest search speed (command units/s), `None`: no stall
    /// detection (closed loop, or 0x2060 = 0).
    pub stall_min_speed: Option<f32>,
}

/// What one homing cycle sees.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct HomingInputs {
    /// 0x60FD.
    pub digital_inputs: u32,
    /// Position actual value (user units).
    pub actual: i32,
    /// Index pulse latched this cycle (user units).
    pub index: Option<i32>,
    /// A stall confirmed this cycle: where it began (user units).
    pub stall: Option<i32>,
}

/// The homing engine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homing {
    step: Step,
    method: Option<Method>,
    params: Option<HomingParams>,
    region: Region,
    prev_active: bool,
    edge: Option<i32>,
    home: i32,
    status: HomingStatus,
}

impl Default for Homing {
    fn default() -> Self {
        Self::new()
    }
}

impl Homing {
    /// Idle engine.
    pub const fn new() -> Self {
        Homing {
            step: Step::Idle,
            method: None,
            params: None,
            region: Region::Unknown,
            prev_active: false,
            edge: None,
            home: 0,
            status: HomingStatus::Idle,
        }
    }

    /// Current status.
    pub fn status(&self) -> HomingStatus {
        self.status
    }

    /// True while the engine commands motion.
    pub fn running(&self) -> bool {
        !matches!(self.step, Step::Idle | Step::Done | Step::Error)
    }

    /// True while a stall homing method searches its hard stop (a stall is then the
    /// reference, not a fault).
    pub fn seeking_stall(&self) -> bool {
        self.step == Step::StallSearch
    }

    /// Reference edge found in the last run (user units at detection), for diagnostics.
    pub fn edge(&self) -> Option<i32> {
        self.edge
    }

    /// Forgets any run (mode change, disable): status Idle.
    pub fn reset(&mut self) {
        *self = Homing::new();
    }

    /// Starts a run (rising edge of controlword bit 4). Returns `Some(delta)` when the
    /// home position is set immediately (methods 35/37): the caller shifts the
    /// coordinates by `delta`.
    pub fn start(&mut self, p: HomingParams, inp: &HomingInputs) -> Option<i32> {
        *self = Homing::new();
        self.params = Some(p);
        let Some(m) = Method::describe(p.method) else {
            self.fail_now();
            return None;
        };
        self.method = Some(m);
        // Stall homing needs the detection and a search speed it can judge.
        let stall_unfit =
            matches!(m.kind, Kind::Stall) && !p.stall_min_speed.is_some_and(|v| p.fast >= v);
        if (m.needs_index() && !p.has_index) || m.needs_inputs() & !p.assigned != 0 || stall_unfit {
            self.fail_now();
            return None;
        }
        let needs_motion = !matches!(m.kind, Kind::Here);
        if needs_motion
            && (p.slow <= 0.0 || p.acc <= 0.0 || (p.fast <= 0.0 && !matches!(m.kind, Kind::Index)))
        {
            self.fail_now();
            return None;
        }
        self.status = HomingStatus::InProgress;
        match m.kind {
            Kind::Here => {
                self.home = inp.actual;
                self.step = Step::Done;
                self.status = HomingStatus::Attained;
                return Some(p.offset.wrapping_sub(inp.actual));
            }
            Kind::Index => self.step = Step::IndexSearch,
            Kind::Stall => self.step = Step::StallSearch,
            Kind::Zone { .. } => {
                let active = inp.digital_inputs & DI_HOME != 0;
                self.prev_active = active;
                self.region = if active {
                    Region::Inside
                } else {
                    Region::Unknown
                };
                self.plan();
            }
            Kind::Edge { sig, .. } => {
                self.prev_active = inp.digital_inputs & sig.mask() != 0;
                self.plan();
            }
        }
        None
    }

    fn fail_now(&mut self) {
        self.step = Step::Error;
        self.status = HomingStatus::Error;
    }

    /// Ends a run that was interrupted (controlword bit 4 cleared, halt) once the axis
    /// has stopped: the status becomes Idle ("interrupted / not started").
    pub fn abort(&mut self) {
        if self.running() {
            self.step = Step::Idle;
            self.status = HomingStatus::Idle;
        }
    }

    /// Side of the axis relative to the reference edge: Some(true) = approach side.
    fn side(&self, active: bool) -> Option<bool> {
        let m = self.method?;
        match m.kind {
            Kind::Edge { level, .. } => Some(active == level),
            Kind::Zone { upper, .. } => {
                // Is the axis below the reference edge?
                let below = match (self.region, upper) {
                    (Region::Unknown, _) => return None,
                    (Region::Below, _) => true,
                    (Region::Inside, up) => up,
                    (Region::Above, _) => false,
                };
                Some(below == (m.final_dir > 0))
            }
            _ => None,
        }
    }

    fn plan(&mut self) {
        let Some(m) = self.method else {
            self.fail_now();
            return;
        };
        match self.side(self.prev_active) {
            None => {
                if let Kind::Zone { init_dir, .. } = m.kind {
                    self.step = Step::Locate { dir: init_dir };
                }
            }
            Some(true) => {
                self.step = Step::Seek {
                    dir: m.final_dir,
                    fast: true,
                    to_p: false,
                }
            }
            Some(false) => {
                self.step = Step::Seek {
                    dir: -m.final_dir,
                    fast: true,
                    to_p: true,
                }
            }
        }
    }

    /// Reads the switches of this cycle: the home signal's side before and now (zone
    /// tracking from the switch edges and the direction of travel `v`), and whether a
    /// limit switch the method does not home on was hit in the direction of travel.
    fn sense(&mut self, m: &Method, di: u32, v: f32) -> Sensed {
        let sig_mask = match m.kind {
            Kind::Edge { sig, .. } => sig.mask(),
            Kind::Zone { .. } => DI_HOME,
            _ => 0,
        };
        let active = di & sig_mask != 0;
        let moving_dir: i8 = if v > 0.0 {
            1
        } else if v < 0.0 {
            -1
        } else {
            0
        };
        let side_before = self.side(self.prev_active);
        // Zone tracking from the switch edges and the direction of travel.
        if let Kind::Zone { .. } = m.kind {
            if active && !self.prev_active {
                self.region = Region::Inside;
            } else if !active && self.prev_active {
                self.region = if moving_dir >= 0 {
                    Region::Above
                } else {
                    Region::Below
                };
            }
        }
        self.prev_active = active;
        let side = self.side(active);
        // Limit switch in the direction of travel that the method does not home on.
        let lim_mask = if moving_dir > 0 {
            DI_POS_LIMIT
        } else if moving_dir < 0 {
            DI_NEG_LIMIT
        } else {
            0
        };
        let limit_hit = di & lim_mask & !sig_mask != 0;
        Sensed {
            side_before,
            side,
            limit_hit,
        }
    }

    /// The approach of the home position at the slow speed (`slow`, command units/s):
    /// the switch edge, then the index pulse if the method homes on it. Returns the
    /// velocity to move towards (0 = stop).
    fn approach_home(&mut self, m: &Method, inp: &HomingInputs, sensed: Sensed, slow: f32) -> f32 {
        let Sensed {
            side_before,
            side,
            limit_hit,
        } = sensed;
        match self.step {
            Step::Fine => {
                if side_before == Some(true) && side == Some(false) {
                    self.edge = Some(inp.actual);
                    if m.index {
                        self.step = Step::IndexSearch;
                        return m.final_dir as f32 * slow;
                    } else {
                        self.home = inp.actual;
                        self.step = Step::Stopping {
                            then: After::Return,
                        };
                    }
                } else if side == Some(false) {
                    // Pushed over the edge before the approach started: approach again.
                    self.step = Step::Seek {
                        dir: -m.final_dir,
                        fast: false,
                        to_p: true,
                    };
                } else if limit_hit {
                    self.step = Step::Stopping { then: After::Error };
                } else {
                    return m.final_dir as f32 * slow;
                }
            }
            Step::IndexSearch => {
                let idx = inp.index.filter(|&i| match self.edge {
                    Some(e) => i.wrapping_sub(e) as i64 * m.final_dir as i64 >= 0,
                    None => true,
                });
                if let Some(i) = idx {
                    self.home = i;
                    self.step = Step::Stopping {
                        then: After::Return,
                    };
                } else if limit_hit {
                    self.step = Step::Stopping { then: After::Error };
                } else {
                    return m.final_dir as f32 * slow;
                }
            }
            _ => {}
        }
        0.0
    }

    /// [`Step::Locate`] in `dir` (at the speed `fast`): stop once the home signal's
    /// side is known; a limit switch reverses a zone method that started this way,
    /// else it is an error. Returns the velocity to move towards (0 = stop).
    fn locate(&mut self, m: &Method, dir: i8, sensed: Sensed, fast: f32) -> f32 {
        if sensed.side.is_some() {
            self.step = Step::Stopping {
                then: After::Replan,
            };
        } else if sensed.limit_hit {
            let reversing = matches!(m.kind, Kind::Zone { init_dir, .. } if init_dir == dir);
            if reversing {
                self.region = if dir > 0 {
                    Region::Above
                } else {
                    Region::Below
                };
                self.step = Step::Stopping {
                    then: After::Replan,
                };
            } else {
                self.step = Step::Stopping { then: After::Error };
            }
        } else {
            return dir as f32 * fast;
        }
        0.0
    }

    /// The step that follows a stop (the axis is at rest).
    fn after_stop(&mut self, m: &Method, then: After) {
        match then {
            After::Replan => self.plan(),
            After::SeekP { fast: f } => {
                self.step = Step::Seek {
                    dir: -m.final_dir,
                    fast: f,
                    to_p: true,
                }
            }
            After::Fine => self.step = Step::Fine,
            After::Return => self.step = Step::Return,
            After::Error => self.fail_now(),
        }
    }

    /// One cycle. Drives `motion` (user units) and returns `Some(delta)` when the home
    /// position has been set: the caller shifts actual and demand positions by `delta`.
    pub fn cycle(&mut self, motion: &mut Motion, inp: &HomingInputs, dt: f32) -> Option<i32> {
        let (Some(p), Some(m)) = (self.params, self.method) else {
            if self.running() {
                self.fail_now();
            }
            return None;
        };
        let sensed = self.sense(&m, inp.digital_inputs, motion.velocity());
        let Sensed {
            side, limit_hit, ..
        } = sensed;
        let fast = p.fast;
        let slow = p.slow;
        let acc = p.acc;
        // Velocity this cycle moves towards with the homing acceleration (0 = stop).
        let mut target = 0.0;
        match self.step {
            Step::Idle | Step::Done | Step::Error => {}
            Step::Locate { dir } => target = self.locate(&m, dir, sensed, fast),
            Step::Seek { dir, fast: f, to_p } => {
                if side == Some(to_p) {
                    let then = if to_p {
                        After::Fine
                    } else {
                        After::SeekP { fast: false }
                    };
                    self.step = Step::Stopping { then };
                } else if limit_hit {
                    self.step = Step::Stopping { then: After::Error };
                } else {
                    target = dir as f32 * if f { fast } else { slow };
                }
            }
            Step::Fine | Step::IndexSearch => {
                target = self.approach_home(&m, inp, sensed, slow);
            }
            Step::StallSearch => {
                if let Some(at) = inp.stall {
                    self.edge = Some(at);
                    self.home = at;
                    motion.stop(0.0, dt);
                    self.step = Step::Return;
                    return None;
                } else if limit_hit {
                    self.step = Step::Stopping { then: After::Error };
                } else {
                    target = m.final_dir as f32 * fast;
                }
            }
            Step::Stopping { then } => {
                if motion.stop(acc, dt) {
                    self.after_stop(&m, then);
                }
                return None;
            }
            Step::Return => {
                if motion.to_position(self.home, slow, acc, acc, 0.0, 0.0, dt)
                    == MoveStatus::Reached
                {
                    self.step = Step::Done;
                    self.status = HomingStatus::Attained;
                    return Some(p.offset.wrapping_sub(self.home));
                }
                return None;
            }
        }
        // A stop is the ramp to 0: with the target 0 the speed only falls, so the
        // acceleration argument is not used (same as `Motion::stop(acc, dt)`).
        motion.ramp_velocity(target, acc, acc, dt);
        None
    }
}

/// The switches as [`Homing::cycle`] sees them in one cycle.
#[derive(Clone, Copy)]
struct Sensed {
    /// Side of the home signal before this cycle (`None`: not known).
    side_before: Option<bool>,
    /// Side of the home signal now.
    side: Option<bool>,
    /// A limit switch in the direction of travel that is not the home signal.
    limit_hit: bool,
}

#[cfg(test)]
mod tests;
