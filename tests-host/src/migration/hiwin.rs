//! Hiwin E1 servo (CoE command manual, first chapters) → this drive (ECS-HS). The
//! manual's chapters at hand cover the EtherCAT side: indicators, station alias, ESM
//! and PDS, synchronisation, PDO limits.

use super::{row, rw, Change, Guide, Here, Row, Section};
use firmware::faults::FaultKind;

const ETHERCAT: &[Row] = &[
    row(
        "RUN LED",
        "EtherCAT state",
        Here::Text("RUN LED (ETG.1300)"),
        "Same patterns.",
    ),
    row(
        "ERR LED",
        "EtherCAT errors",
        Here::Al(0x001B),
        "Watchdog: double flash; see the ERR row of the other guides for the rest.",
    ),
    row(
        "L/A IN, L/A OUT",
        "link / activity",
        Here::Text("the ESC's link LEDs"),
        "",
    ),
    row(
        "rotary switch, 0-255",
        "station alias",
        Here::Text("DIP ID bank or the single bank, 0-127"),
        "Used when 0x2151 = 0.",
    ),
    row(
        "alias in the EEPROM, 0-65535",
        "station alias",
        rw(0x2150, 0),
        "0x2151 = 1 selects it; or the SII alias word when the switches read 0.",
    ),
    row(
        "SyncManagers: 4, FMMUs: 3",
        "ESC resources",
        Here::Object(0x1C00),
        "Same: SM0/1 mailbox, SM2/3 process data.",
    ),
    row(
        "DC SYNC0",
        "synchronisation",
        Here::Object(0x1C32),
        "Also SM2-synchronous.",
    ),
    row("FreeRun", "synchronisation", Here::Object(0x1C32), ""),
    row(
        "cycle 250, 500, 1000, 2000, 4000 µs",
        "cycle times",
        Here::Object(0x1C32),
        "125 µs to 4 ms in steps of 125 µs.",
    ),
    row(
        "RxPDO: 8 objects, 32 bytes",
        "mapping limits",
        Here::Object(0x1600),
        "4 mapping objects, 16 entries each, 64 bytes per direction.",
    ),
    row(
        "TxPDO: 8 objects, 32 bytes",
        "mapping limits",
        Here::Object(0x1A00),
        "4 mapping objects, 16 entries each, 64 bytes per direction.",
    ),
    row(
        "SDO abort codes",
        "CiA 301 abort codes",
        Here::Text("the same CiA 301 codes"),
        "",
    ),
    row(
        "emergency message",
        "CiA 301 emergency",
        Here::Object(0x1003),
        "Emergencies carry the 0x603F code and 0x1001; history in 0x1003 and 0x10F3.",
    ),
];

const PDS: &[Row] = &[
    row("Op → other state while Operation enabled", "PDS goes to Fault", Here::Fault(FaultKind::Ecat),
        "0x6007 = 1 (default): the same; 0x6007 = 0, 2, 3 choose no reaction, disable voltage, quick stop."),
    row("PreOp / SafeOp / Op → Init", "PDS to Switch on disabled", Here::Text("Switch on disabled"),
        "Unless the axis is enabled, stopping or in Fault: then the 0x6007 reaction runs first."),
    row("modes PP, PV, PT, HM, CSP, CSV, CST", "supported modes", Here::Object(0x6502), "All seven on ECS-HS in closed loop (0x2024 = 2)."),
    row("touch probe", "two probes", Here::Object(0x60B8), ""),
    row("torque limit", "limit of the torque", Here::Object(0x6072), ""),
];

const STARTUP: &[Change] = &[
    Change {
        was: "0x1C32:02 cycle time",
        now: "keep",
        why: "Every cycle of the E1 is one of this drive's.",
    },
    Change {
        was: "PDOs with up to 8 entries",
        now: "keep",
        why: "Up to 16 entries per mapping object here.",
    },
    Change {
        was: "0x6060 = 4 (profile torque)",
        now: "keep (ECS-HS, 0x2024 = 2)",
        why: "PT runs in closed loop with 0x6087 / 0x6088.",
    },
];

/// The guide.
pub(super) const GUIDE: Guide = Guide {
    file: "hiwin-e1.md",
    drive: "Hiwin E1",
    summary: "The Hiwin E1 is an AC servo drive with a CoE interface; its counterpart here is the \
              hybrid servo variant ECS-HS. The chapters of the E1's CoE manual this guide was \
              written from cover the EtherCAT side (indicators, alias, ESM and PDS, \
              synchronisation, PDO limits); the servo parameters are not among them.",
    sections: &[
        Section {
            title: "EtherCAT side",
            rows: ETHERCAT,
        },
        Section {
            title: "Drive profile",
            rows: PDS,
        },
    ],
    startup: STARTUP,
    notes: &[
        "The E1 is a servo for AC motors; this drive runs two-phase hybrid steppers. Tuning \
         values, motor data and units of a start-up list written for the E1 do not carry \
         over: set 0x2000 (peak current), 0x2001 (pulses per revolution) and the servo \
         tune (0x2160-0x2165) for the motor.",
    ],
};
