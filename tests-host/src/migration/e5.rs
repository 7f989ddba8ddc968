//! ECON E5-CAT-HS68D hybrid servo → this drive (ECS-HS). The vendor parameters are
//! shared with the EST-584 ([`PARAMS`]): both ECON drives use the same table.

use super::{ro, row, rw, rw_tx, rx, tx, Change, Guide, Here, Row, Section};
use firmware::faults::FaultKind;

/// CiA 301 and PDO objects of the ECON drives' manuals.
pub(super) const COMM: &[Row] = &[
    row("0x1000", "device type", ro(0x1000, 0), ""),
    row("0x1010:04", "write 'load' (0x64616F6C): all parameters to their defaults", rw(0x1010, 4),
        "Same value, same effect here; 'save' (0x65766173) to 0x1010:01-04 stores, 'load' to 0x1011:01-04 restores defaults (CiA 301)."),
    row("0x1600", "RxPDO 1: 6040, 607A, 60B0, 60B8 (CSP)", Here::Object(0x1600), "Same default map."),
    row("0x1601", "RxPDO 2: 6040, 607A, 6081, 6083, 6084, 6060 (PP)", Here::Object(0x1601), "Same default map."),
    row("0x1602", "RxPDO 3: 6040, 60FF, 6083, 6084, 6060 (PV)", Here::Object(0x1602), "Same default map."),
    row("0x1603", "RxPDO 4: 6040, 6098, 6099:01, 6099:02, 609A, 607C, 6060 (HM)", Here::Object(0x1603), "Same default map."),
    row("0x1A00", "TxPDO 1: 603F, 6041, 6061, 6064, 60B9, 60BA, 60FD", Here::Object(0x1A00), "Same default map."),
    row("0x1A01", "TxPDO 2 (no default entries)", Here::Object(0x1A01),
        "0x1A02 and 0x1A03 exist as well (four TxPDOs)."),
    row("0x1C12", "RxPDO assignment (0x1600-0x1603)", Here::Object(0x1C12), "Default: 0x1600 only."),
    row("0x1C13", "TxPDO assignment (0x1A00-0x1A01)", Here::Object(0x1C13), "Default: 0x1A00."),
];

/// CiA 402 objects of the ECON drives' manuals.
pub(super) const CIA402: &[Row] = &[
    row("0x603F", "error code", tx(0x603F, 0), ""),
    row("0x6040", "controlword", rx(0x6040, 0), ""),
    row(
        "0x6041",
        "statusword",
        tx(0x6041, 0),
        "Bits 8, 14, 15 as on the E5.",
    ),
    row(
        "0x605A",
        "quick stop option code",
        rx(0x605A, 0),
        "Range 0-8 (CiA 402).",
    ),
    row(
        "0x6060",
        "modes of operation: 1 PP, 3 PV, 6 HM, 8 CSP",
        rx(0x6060, 0),
        "Also 4 PT, 9 CSV, 10 CST (PT and CST in closed loop only, see 0x6502).",
    ),
    row("0x6061", "mode display", tx(0x6061, 0), ""),
    row("0x6062", "command position", tx(0x6062, 0), ""),
    row("0x6064", "actual position", tx(0x6064, 0), ""),
    row("0x606B", "command speed", tx(0x606B, 0), ""),
    row(
        "0x606C",
        "actual speed, rpm",
        tx(0x606C, 0),
        "Command units per second here, not rpm: rpm = 0x606C · 60 / 0x2001. Read-only.",
    ),
    row("0x607A", "target position (PP, CSP)", rx(0x607A, 0), ""),
    row("0x607C", "homing offset", rx(0x607C, 0), ""),
    row("0x6081", "PP travel speed", rx(0x6081, 0), ""),
    row("0x6082", "PP start/stop speed", rx(0x6082, 0), ""),
    row("0x6083", "acceleration", rx(0x6083, 0), ""),
    row("0x6084", "deceleration", rx(0x6084, 0), ""),
    row("0x6085", "quick-stop deceleration", rx(0x6085, 0), ""),
    row(
        "0x6098",
        "homing method",
        rx(0x6098, 0),
        "Methods 1-14, 17-30, 33-35, 37 and stall homing -1/-2 (open loop).",
    ),
    row(
        "0x6099:01",
        "homing speed, search for the switch",
        rx(0x6099, 1),
        "",
    ),
    row(
        "0x6099:02",
        "homing speed, search for zero",
        rx(0x6099, 2),
        "",
    ),
    row("0x609A", "homing acceleration", rx(0x609A, 0), ""),
    row("0x60B0", "position offset (CSP)", rx(0x60B0, 0), ""),
    row("0x60B8", "touch probe function", rx(0x60B8, 0), ""),
    row("0x60B9", "touch probe status", tx(0x60B9, 0), ""),
    row("0x60BA", "probe 1 rising-edge position", tx(0x60BA, 0), ""),
    row("0x60F4", "following error", tx(0x60F4, 0), ""),
    row(
        "0x60FD",
        "inputs: bit 0 negative limit, 1 positive limit, 2 home",
        tx(0x60FD, 0),
        "Same bits.",
    ),
    row(
        "0x60FF",
        "target speed (PV)",
        rx(0x60FF, 0),
        "Command units per second.",
    ),
];

/// The vendor parameters of the ECON drives (same indices here).
pub(super) const PARAMS: &[Row] = &[
    row("0x2000", "peak current, mA", rx(0x2000, 0),
        "At most 8000 mA on ECS-HS, 8400 mA on ECS-OL; RxPDO-mappable (a mapped value out of range is not taken over)."),
    row("0x2001", "pulses per revolution (200-51200, default 50000)", rw(0x2001, 0),
        "Same range and default; effective after restart. 0x6091-0x6093 are views of it."),
    row("0x2002", "stand-by time before the holding current, ms", rw(0x2002, 0), ""),
    row("0x2005:01", "output 1 function (alarm / ready / in position)", rw(0x2005, 1), "Range 0-31 here: more functions (brake, enabled)."),
    row("0x2005:02", "output 2 function", rw(0x2005, 2), "Output 3 is 0x2005:03."),
    row("0x2008", "output level (bit n: output n+1)", rw(0x2008, 0), ""),
    row("0x2009", "command filter enable", rw(0x2009, 0), ""),
    row("0x2010:02", "command filter time, µs", rw(0x2010, 2), ""),
    row("0x2013", "current loop auto-tune at power-up", rw(0x2013, 0), ""),
    row("0x2015", "current loop Kp", rw(0x2015, 0), ""),
    row("0x2016", "current loop Ki", rw(0x2016, 0), ""),
    row("0x2017", "current loop Kc (read-only)", ro(0x2017, 0), ""),
    row("0x2020", "motor resistance, mΩ", rw(0x2020, 0), ""),
    row("0x2021", "motor inductance, µH", rw(0x2021, 0), ""),
    row("0x2024", "1 open loop, 2 closed loop", rw(0x2024, 0), "ECS-OL (no encoder) accepts 1 only."),
    row("0x2025", "control mode (0 DIP switches, 5 closed loop …)", rw(0x2025, 0), "Range 0-5 here."),
    row("0x2026", "holding current, % (open loop)", rw(0x2026, 0), ""),
    row("0x2029", "encoder resolution, lines per revolution", rw(0x2029, 0), ""),
    row("0x2030", "following error limit, pulses (closed loop)", rw(0x2030, 0), "Listed by the EST-584 and E5 tables alike."),
    row("0x2039", "received pulse count, high word", tx(0x2039, 0), ""),
    row("0x2040", "received pulse count, low word; write 1 to clear", rw_tx(0x2040, 0), ""),
    row("0x2041", "encoder count, high word", tx(0x2041, 0), ""),
    row("0x2042", "encoder count, low word; write 1 to clear", rw_tx(0x2042, 0), ""),
    row("0x2051", "direction reversal", rw(0x2051, 0), ""),
    row("0x2053", "in-position output level", rw(0x2053, 0), ""),
    row("0x2056", "fault detection selection (default 0xC3)", rw(0x2056, 0), "Same bits and default."),
    row("0x2057", "fault clear allowed", rw(0x2057, 0), ""),
    row("0x2058", "current soft-start at enable, 50 µs", rw(0x2058, 0), ""),
    row("0x2083", "wiggle at power-up", rw(0x2083, 0), ""),
    row("0x2093", "write 1: clear the fault record", rw(0x2093, 0), ""),
    row("0x2137", "position loop Kp", rw(0x2137, 0), ""),
    row("0x2138", "position loop Ki", rw(0x2138, 0), ""),
    row("0x2139", "velocity feed-forward", rw(0x2139, 0), ""),
    row("0x2140", "speed loop Kp", rw(0x2140, 0), ""),
    row("0x2150", "station alias", rw(0x2150, 0), ""),
    row("0x2151", "alias source: 0 DIP switches, 1 0x2150", rw(0x2151, 0), "Effective after restart."),
    row("0x2152:01", "input 1 function (bit mask)", rw(0x2152, 1), "0x2152:02-05: inputs 2-5."),
    row("0x2153:01", "input 1 filter, 50 µs", rw(0x2153, 1), "0x2153:02-05: inputs 2-5."),
    row("0x2154", "input polarity (bit n: input n+1)", rw(0x2154, 0), ""),
    row("0x2155", "input levels (bit n: input n+1)", tx(0x2155, 0), ""),
];

/// The E5's red-LED codes (the same on the EST-584).
pub(super) const LEDS: &[Row] = &[
    row("green LED on", "powered", Here::Text("green LED on while powered"), ""),
    row("red LED 1 flash per 3 s", "over-current or phase short circuit", Here::Fault(FaultKind::OverCurrent),
        "Latched until power is cycled unless 0x2057 = 1."),
    row("red LED 2 flashes", "over-voltage", Here::Fault(FaultKind::OverVoltage), "Threshold 0x2054 (55 V default)."),
    row("red LED 3 flashes", "under-voltage", Here::Fault(FaultKind::UnderVoltage), "Threshold 0x2055."),
    row("red LED 7 flashes", "following error alarm", Here::Fault(FaultKind::FollowingError), ""),
    row("red LED 9 flashes", "phase or current sensing fault", Here::Fault(FaultKind::PhaseSensing), ""),
    row("—", "(no code there)", Here::Fault(FaultKind::MotorOpen), "Power-up check, off by default (0x2056 bit 2)."),
    row("—", "(no code there)", Here::Fault(FaultKind::MotorBlocked), "Open-loop stall detection, 0x2060-0x2062."),
    row("RUN / ERR LEDs", "EtherCAT state and errors", Here::Text("RUN and ERR LEDs (ETG.1300)"),
        "ERR: blinking invalid configuration, single flash local error, double flash watchdog timeout."),
];

const DIP: &[Row] = &[
    row(
        "S1-S7",
        "station ID, binary, a switch OFF adds 1, 2, 4 … 64; all ON = 0 (no ID)",
        Here::Text("ID bank: the same code"),
        "Read at power-up; used when 0x2151 = 0.",
    ),
    row("S8", "reserved", Here::None, "Ignored here too."),
];

const STARTUP: &[Change] = &[
    Change {
        was: "0x1010:04 = 'load'",
        now: "keep",
        why: "Same answer.",
    },
    Change {
        was: "0x2000 peak current, 0x2001 pulses per revolution",
        now: "keep",
        why: "Same index, unit and range (0x2000 at most 8000 mA on ECS-HS).",
    },
    Change {
        was: "0x1C12 / 0x1C13 and 0x1600-0x1603 / 0x1A00-0x1A01",
        now: "keep",
        why: "Same default maps; up to 16 entries and 64 bytes per direction.",
    },
    Change {
        was: "speeds read from 0x606C in rpm",
        now: "convert: rpm = 0x606C · 60 / 0x2001",
        why: "0x606C is in command units per second.",
    },
];

/// The guide.
pub(super) const GUIDE: Guide = Guide {
    file: "e5-cat-hs68d.md",
    drive: "ECON E5-CAT-HS68D",
    summary: "The E5-CAT-HS68D is a hybrid (closed-loop) stepper drive with a 1000-line encoder; its \
              counterpart here is the hybrid servo variant ECS-HS. The vendor parameters keep their \
              indices, units and defaults, so most start-up lists run unchanged.",
    sections: &[
        Section { title: "Communication and PDO objects", rows: COMM },
        Section { title: "CiA 402 objects", rows: CIA402 },
        Section { title: "Vendor parameters", rows: PARAMS },
        Section { title: "DIP switches", rows: DIP },
        Section { title: "LEDs and alarms", rows: LEDS },
    ],
    startup: STARTUP,
    notes: &[
        "Both drives answer an unknown object with SDO abort 0x06020000; this drive also \
         answers out-of-range values with 0x06090030-0x06090032 and keeps the previous value.",
    ],
};
