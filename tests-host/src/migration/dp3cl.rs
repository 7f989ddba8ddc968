//! Xinje DP3CL (-305 / -705 / -808) open-loop bus stepper → this drive (ECS-OL on the
//! board with the single DIP bank).

use super::{ro, row, rw, rx, tx, Change, Guide, Here, Row, Section};
use firmware::faults::FaultKind;

const COMM: &[Row] = &[
    row("0x1000", "device type", ro(0x1000, 0), ""),
    row("0x1001", "error register: bit 4 EtherCAT alarm, bit 7 any other alarm", tx(0x1001, 0),
        "Same bits: 4 for an EtherCAT fault, 7 for every drive alarm; bits 0-2 and 5 as CiA 301 defines them."),
    row("0x1600-0x1603", "RxPDO mappings", Here::Object(0x1600), "Four RxPDOs, up to 16 entries each, 64 bytes per direction."),
    row("0x1A00-0x1A03", "TxPDO mappings", Here::Object(0x1A00), "Four TxPDOs, up to 16 entries each, 64 bytes per direction."),
    row("0x1C12", "RxPDO assignment", Here::Object(0x1C12), ""),
    row("0x1C13", "TxPDO assignment", Here::Object(0x1C13), ""),
    row("0x1C32", "SM2 synchronisation", Here::Object(0x1C32), "Free run, SM2 and DC SYNC0; cycles 125 µs to 4 ms in 125 µs steps."),
    row("0x1C33", "SM3 synchronisation", Here::Object(0x1C33), ""),
];

const CIA402: &[Row] = &[
    row(
        "0x603F",
        "error code",
        tx(0x603F, 0),
        "CiA 402 codes; EtherCAT faults 0x8700 / 0xA000 / 0xA001.",
    ),
    row("0x6040", "controlword", rx(0x6040, 0), ""),
    row("0x6041", "statusword", tx(0x6041, 0), ""),
    row("0x605A", "quick stop option code", rx(0x605A, 0), ""),
    row("0x605B", "shutdown option code", rw(0x605B, 0), ""),
    row("0x605E", "fault reaction option code", rw(0x605E, 0), ""),
    row(
        "0x6060",
        "modes of operation",
        rx(0x6060, 0),
        "PT and CST need the closed loop: refused on ECS-OL (0x06090030).",
    ),
    row("0x6061", "modes of operation display", tx(0x6061, 0), ""),
    row("0x6062", "position demand value", tx(0x6062, 0), ""),
    row(
        "0x6063",
        "position actual internal value",
        tx(0x6063, 0),
        "",
    ),
    row("0x6064", "position actual value", tx(0x6064, 0), ""),
    row("0x6065", "following error window", rx(0x6065, 0), ""),
    row("0x6066", "following error time out", rx(0x6066, 0), ""),
    row("0x6067", "position window", rx(0x6067, 0), ""),
    row("0x6068", "position window time", rx(0x6068, 0), ""),
    row("0x606B", "velocity demand value", tx(0x606B, 0), ""),
    row(
        "0x606C",
        "velocity actual value",
        tx(0x606C, 0),
        "Command units/s on both.",
    ),
    row("0x606D", "velocity window", rw(0x606D, 0), ""),
    row("0x606E", "velocity window time", rw(0x606E, 0), ""),
    row("0x606F", "velocity threshold", rw(0x606F, 0), ""),
    row("0x6071", "target torque", rx(0x6071, 0), ""),
    row("0x6072", "max torque", rx(0x6072, 0), ""),
    row("0x6074", "torque demand", tx(0x6074, 0), ""),
    row("0x6075", "motor rated current", ro(0x6075, 0), ""),
    row("0x6076", "motor rated torque", ro(0x6076, 0), ""),
    row(
        "0x6077",
        "torque actual value",
        tx(0x6077, 0),
        "INTEGER16 here (the DP3CL lists UNSIGNED16); 0 without an encoder.",
    ),
    row("0x6078", "current actual value", tx(0x6078, 0), ""),
    row("0x607A", "target position", rx(0x607A, 0), ""),
    row(
        "0x607B:01",
        "position range limit, min",
        rw(0x607B, 1),
        "Positions wrap around in [min, max] when min < max.",
    ),
    row("0x607B:02", "position range limit, max", rw(0x607B, 2), ""),
    row("0x607C", "home offset", rx(0x607C, 0), ""),
    row(
        "0x607D",
        "software position limit",
        Here::Object(0x607D),
        "",
    ),
    row("0x607E", "polarity", rw(0x607E, 0), ""),
    row("0x607F", "max profile velocity", rx(0x607F, 0), ""),
    row("0x6080", "max motor speed", rw(0x6080, 0), ""),
    row("0x6081", "profile velocity", rx(0x6081, 0), ""),
    row("0x6083", "profile acceleration", rx(0x6083, 0), ""),
    row("0x6084", "profile deceleration", rx(0x6084, 0), ""),
    row("0x6085", "quick stop deceleration", rx(0x6085, 0), ""),
    row(
        "0x6086",
        "motion profile type",
        rw(0x6086, 0),
        "0 linear and 3 jerk-limited; 1 and 2 refused.",
    ),
    row("0x6087", "torque slope", rx(0x6087, 0), ""),
    row(
        "0x6093",
        "position factor",
        Here::Object(0x6093),
        "Writable; sets 0x2001 (with 0x6091 / 0x6092).",
    ),
    row(
        "0x6098",
        "homing method",
        rx(0x6098, 0),
        "Methods 1-14, 17-30, 33-35, 37 (and stall homing -1 / -2).",
    ),
    row("0x6099", "homing speeds", Here::Object(0x6099), ""),
    row("0x609A", "homing acceleration", rx(0x609A, 0), ""),
    row("0x60B8", "touch probe function", rx(0x60B8, 0), ""),
    row("0x60B9", "touch probe status", tx(0x60B9, 0), ""),
    row("0x60BA", "probe 1 rising edge", tx(0x60BA, 0), ""),
    row("0x60BB", "probe 1 falling edge", tx(0x60BB, 0), ""),
    row("0x60BC", "probe 2 rising edge", tx(0x60BC, 0), ""),
    row("0x60BD", "probe 2 falling edge", tx(0x60BD, 0), ""),
    row(
        "0x60C0",
        "interpolation sub mode",
        rw(0x60C0, 0),
        "0 (linear) only.",
    ),
    row(
        "0x60C1",
        "interpolation data record",
        Here::None,
        "Not needed: CSP takes 0x607A every cycle.",
    ),
    row(
        "0x60C2",
        "interpolation time period",
        Here::Object(0x60C2),
        "",
    ),
    row("0x60C5", "max acceleration", rw(0x60C5, 0), ""),
    row("0x60C6", "max deceleration", rw(0x60C6, 0), ""),
    row("0x60F2", "positioning option code", rw(0x60F2, 0), ""),
    row("0x60F4", "following error actual value", tx(0x60F4, 0), ""),
    row(
        "0x60FA",
        "control effort",
        tx(0x60FA, 0),
        "Command units/s: the commanded velocity in open loop.",
    ),
    row(
        "0x60FC",
        "position demand internal value",
        tx(0x60FC, 0),
        "",
    ),
    row("0x60FD", "digital inputs", tx(0x60FD, 0), ""),
    row(
        "0x60FF",
        "target velocity, 0.1 rpm",
        rx(0x60FF, 0),
        "Command units/s here: value here = value there · 0x2001 / 600.",
    ),
    row("0x6502", "supported drive modes", ro(0x6502, 0), ""),
];

/// The DP3CL's parameters (CoE index there = 0x2000 + the parameter address).
const PARAMS: &[Row] = &[
    row(
        "P0-01 (0x2001)",
        "subdivision, pulses per revolution (default 10000)",
        rw(0x2001, 0),
        "Same index; default 50000 here: write 0x2001 = 10000 to keep the master's scaling.",
    ),
    row(
        "P0-02 (0x2002)",
        "command filter time, ms",
        rw(0x2010, 2),
        "0x2010:02 in µs with 0x2009 = 1; 0x2002 here is the stand-by time.",
    ),
    row(
        "P0-05 (0x2005)",
        "open-loop running current, % of peak",
        rx(0x2000, 0),
        "Set the running current in 0x2000 (mA); 0x2005 here is the output function.",
    ),
    row(
        "P0-08 (0x2008)",
        "holding current, % of peak",
        rw(0x2026, 0),
        "0x2008 here is the output level.",
    ),
    row(
        "P0-11 (0x200B)",
        "panel display mode",
        Here::None,
        "No panel.",
    ),
    row(
        "P0-12 (0x200C)",
        "time to the holding current, ms",
        rw(0x2002, 0),
        "",
    ),
    row(
        "P1-00 (0x2100)",
        "current loop auto-tune",
        rw(0x2013, 0),
        "",
    ),
    row(
        "P1-01 (0x2101)",
        "current Kp",
        rw(0x2015, 0),
        "Different scale: re-tune or keep the auto-tune.",
    ),
    row(
        "P1-02 (0x2102)",
        "current Ki",
        rw(0x2016, 0),
        "Different scale.",
    ),
    row(
        "P1-13 (0x210D)",
        "in-position delay",
        rx(0x6068, 0),
        "Use the position window time.",
    ),
    row(
        "P2-02 (0x2202)",
        "alarm output terminal",
        rw(0x2005, 1),
        "Output functions 0x2005:01-03.",
    ),
    row("P2-03 (0x2203)", "brake output terminal", rw(0x2005, 2), ""),
    row(
        "P2-05 (0x2205)",
        "alarm clear input",
        rw(0x2152, 1),
        "Input functions 0x2152:01-05.",
    ),
    row("P2-06 (0x2206)", "positive limit input", rw(0x2152, 2), ""),
    row("P2-07 (0x2207)", "negative limit input", rw(0x2152, 1), ""),
    row("P2-08 (0x2208)", "home input", rw(0x2152, 3), ""),
    row(
        "P3-01 (0x2301)",
        "fault detection selection",
        rw(0x2056, 0),
        "0x2301 here is a monitoring value.",
    ),
    row(
        "P3-02 (0x2302)",
        "under-voltage threshold, 0 = off (default)",
        rw(0x2055, 0),
        "Default 12 V here: write 0 to match.",
    ),
    row(
        "P4-00 (0x2400)",
        "peak current, 100 mA",
        rx(0x2000, 0),
        "0x2000 in mA; 0x2400 here is the fault history.",
    ),
    row(
        "P4-01 (0x2401)",
        "encoder resolution",
        Here::None,
        "ECS-OL has no encoder.",
    ),
    row(
        "P8-00 … P8-15",
        "scope channels",
        Here::Object(0x2501),
        "Scope 0x2500-0x2510.",
    ),
    row(
        "P8-16 … P8-23",
        "scope mode, interval, length, trigger",
        Here::Object(0x2500),
        "",
    ),
    row(
        "U0-26 / U0-27",
        "phase A / B current",
        Here::Object(0x2303),
        "0x2303 / 0x2304.",
    ),
    row(
        "U0-29 / U0-30",
        "phase A / B current set-point",
        Here::Object(0x2301),
        "0x2301 / 0x2302.",
    ),
    row("U0-25", "electrical angle", Here::Object(0x2300), ""),
    row("U0-32", "bus voltage", Here::Object(0x2305), ""),
    row(
        "U0-10 … U0-21",
        "command pulse counters",
        Here::Object(0x2039),
        "0x2039 / 0x2040.",
    ),
    row(
        "U1-00 … U1-14",
        "alarm code, values at the alarm, last alarms",
        Here::Object(0x2400),
        "0x2400-0x2406 and 0x1003, 0x10F3.",
    ),
    row("U2-00", "power-on count", Here::Object(0x2306), ""),
    row(
        "U2-07 / U2-08",
        "software / hardware version",
        Here::Object(0x100A),
        "0x100A / 0x1009.",
    ),
    row("U2-09 … U2-11", "operating time", Here::Object(0x2307), ""),
    row(
        "U2-12 / U2-13",
        "serial number",
        Here::Object(0x1018),
        "0x1018:04.",
    ),
    row(
        "U3-00 … U3-11",
        "PDI and SYNC0 timing",
        Here::Object(0x2200),
        "",
    ),
    row(
        "F0-00",
        "clear the alarm",
        rx(0x6040, 0),
        "Controlword bit 7 (fault reset).",
    ),
    row(
        "F0-01",
        "restore factory settings",
        rw(0x1011, 1),
        "'load' to 0x1011:01.",
    ),
    row(
        "F0-02",
        "save the parameters",
        rw(0x1010, 1),
        "'save' to 0x1010:01.",
    ),
];

const DIP: &[Row] = &[
    row(
        "SW1-SW3 (SW8 OFF)",
        "running current, per model",
        Here::Text("single bank SW1-SW3: the same tables (305, 705, 808)"),
        "The switches' current is in 0x2158.",
    ),
    row(
        "SW4 (SW8 OFF)",
        "half / full holding current",
        Here::Text("single bank SW4: the same"),
        "",
    ),
    row(
        "SW5-SW6 (SW8 OFF)",
        "filter time 1.5 / 3 / 12 ms / off",
        Here::Text("single bank SW5-SW6: the same"),
        "",
    ),
    row(
        "SW7 (SW8 OFF)",
        "direction",
        Here::Text("single bank SW7: the same"),
        "",
    ),
    row(
        "SW8 ON, SW1-SW7",
        "station number, binary (SW1 least significant), kept when SW8 returns OFF",
        Here::Object(0x2156),
        "The same procedure; the stored number is 0x2156.",
    ),
];

const ALARMS: &[Row] = &[
    row("E-800", "invalid ESM request", Here::Al(0x0011), ""),
    row("E-801", "undefined ESM request", Here::Al(0x0012), ""),
    row(
        "E-802",
        "Bootstrap request",
        Here::Al(0x0013),
        "Here Bootstrap exists (firmware update over FoE).",
    ),
    row("E-803", "no SYNC (PLL incomplete)", Here::Al(0x002D), ""),
    row(
        "E-804",
        "PDO watchdog",
        Here::Al(0x001B),
        "0x6007 chooses the drive's reaction; 0x603F 0x8700 with a fault.",
    ),
    row("E-806", "PLL error", Here::Al(0x0032), ""),
    row("E-807", "sync signal error", Here::Al(0x002C), ""),
    row("E-810", "sync cycle out of range", Here::Al(0x0035), ""),
    row("E-811", "mailbox SM setting", Here::Al(0x0016), ""),
    row("E-814", "watchdog setting", Here::Al(0x001F), ""),
    row("E-815", "DC setting", Here::Al(0x0030), ""),
    row("E-816", "SM event mode setting", Here::Al(0x0028), ""),
    row(
        "E-817",
        "SM2 / SM3 setting",
        Here::Al(0x001D),
        "0x001E for SM3.",
    ),
    row("E-850", "TxPDO mapping", Here::Al(0x0024), ""),
    row("E-851", "RxPDO mapping", Here::Al(0x0025), ""),
    row(
        "E-881",
        "enabled with 0x6060 = 0",
        Here::Text("accepted, no alarm"),
        "See below.",
    ),
    row(
        "E-882",
        "ESM change requested while enabled",
        Here::Fault(FaultKind::Ecat),
        "0x6007 decides: fault 0xA000 / 0xA001 by default.",
    ),
    row(
        "over-current",
        "drive alarm",
        Here::Fault(FaultKind::OverCurrent),
        "",
    ),
    row(
        "over-voltage",
        "drive alarm",
        Here::Fault(FaultKind::OverVoltage),
        "Threshold 0x2054.",
    ),
    row(
        "under-voltage",
        "drive alarm",
        Here::Fault(FaultKind::UnderVoltage),
        "Threshold 0x2055.",
    ),
    row(
        "RUN / ERR LEDs",
        "EtherCAT state and errors",
        Here::Text("RUN and ERR LEDs (ETG.1300)"),
        "",
    ),
];

const STARTUP: &[Change] = &[
    Change { was: "0x60FF in 0.1 rpm", now: "0x60FF in command units/s: value · 0x2001 / 600", why: "Velocities are in command units/s here." },
    Change { was: "P0-01 subdivision 10000 (the default)", now: "0x2001 = 10000, or 0x6091 / 0x6092 as before", why: "The default here is 50000 pulses per revolution; 0x2001 takes effect after a restart (save first)." },
    Change { was: "writes to 0x2002, 0x2005, 0x2008, 0x2100-0x2102, 0x2301, 0x2302, 0x2400", now: "the objects in the parameter table above", why: "The same indices mean other things here." },
    Change { was: "P3-02 = 0 (under-voltage off)", now: "0x2055 = 0", why: "On by default here (12 V)." },
    Change { was: "0x607B, 0x60C0, 0x6091-0x6093, 0x6065, 0x6066, 0x605A, 0x60FA", now: "keep", why: "Same objects; 0x6066, 0x6068, 0x605A and 0x60FA are mappable as on the DP3CL." },
];

/// The guide.
pub(super) const GUIDE: Guide = Guide {
    file: "dp3cl.md",
    drive: "Xinje DP3CL",
    summary: "The DP3CL (-305, -705, -808) is an open-loop EtherCAT stepper drive with a single \
              8-way DIP bank; its counterpart here is the open-loop variant ECS-OL on the board \
              with the single bank.",
    sections: &[
        Section {
            title: "Communication and PDO objects",
            rows: COMM,
        },
        Section {
            title: "CiA 402 objects",
            rows: CIA402,
        },
        Section {
            title: "Parameters (P, U, F groups)",
            rows: PARAMS,
        },
        Section {
            title: "DIP switches",
            rows: DIP,
        },
        Section {
            title: "Alarms and LEDs",
            rows: ALARMS,
        },
    ],
    startup: STARTUP,
    notes: &[
        "Enabling with 0x6060 = 0: the DP3CL raises E-881; this drive accepts it and holds the \
         position in position control until a mode is chosen (statusword bits 10, 12, 13 \
         clear). CiA 402 leaves the behaviour to the manufacturer; masters that enable \
         before they write 0x6060, or pass through 0 while switching modes, keep working, \
         and the axis is never left without a set-point.",
        "The DP3CL's parameters live at 0x2000 plus the parameter address; this drive's \
         vendor parameters follow the ECON numbering. Only 0x2001 (pulses per revolution) \
         means the same on both.",
    ],
};
