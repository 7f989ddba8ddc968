//! ECON EST-584 open-loop stepper → this drive (ECS-OL). Same protocol and vendor
//! parameters as the E5 ([`super::e5`]); the DIP bank selects motor settings.

use super::e5::{CIA402, COMM, LEDS, PARAMS};
use super::{row, rw, Change, Guide, Here, Row, Section};

const DIP: &[Row] = &[
    row(
        "SW1-SW3",
        "peak current: all ON 2.0 A; then 3.5, 4.5, 5.2, 5.8, 6.7, 7.7, 8.4 A",
        Here::Text("function bank SW1-SW3: the same table"),
        "Used when 0x2025 = 0; the table in effect is readable in 0x2158 (see the list below).",
    ),
    row(
        "SW4",
        "standstill current: OFF from software (0x2026), ON equal to the running current",
        Here::Text("function bank SW4: the same"),
        "",
    ),
    row(
        "SW5",
        "direction: OFF CCW, ON CW",
        Here::Text("function bank SW5: the same"),
        "0x2051 when 0x2025 ≠ 0.",
    ),
    row(
        "SW6-SW7",
        "smoothing filter: all ON 0 ms; then 2, 12, 25 ms",
        Here::Text("function bank SW6-SW7: the same table"),
        "0x2009 / 0x2010:02 when 0x2025 ≠ 0.",
    ),
    row(
        "(switch positions)",
        "—",
        Here::Object(0x2158),
        "What the switches set, as read at power-up.",
    ),
    row(
        "0x2025 = 0",
        "settings from the switches",
        rw(0x2025, 0),
        "Same meaning.",
    ),
];

const STARTUP: &[Change] = &[
    Change {
        was: "0x2000 peak current",
        now: "keep (at most 8400 mA on ECS-OL)",
        why: "Same index and unit; ignored while 0x2025 = 0 takes the switches' current.",
    },
    Change {
        was: "0x2024 = 1 (open loop)",
        now: "keep",
        why: "ECS-OL has no encoder: 0x2024 accepts 1 only.",
    },
    Change {
        was: "0x1C12 / 0x1C13 and the default maps",
        now: "keep",
        why: "Same default maps.",
    },
];

/// The guide.
pub(super) const GUIDE: Guide = Guide {
    file: "est-584.md",
    drive: "ECON EST-584",
    summary: "The EST-584 is an open-loop EtherCAT stepper drive with the E5's protocol and \
              vendor parameters; its counterpart here is the open-loop variant ECS-OL on the board \
              with the function DIP bank.",
    sections: &[
        Section { title: "Communication and PDO objects", rows: COMM },
        Section { title: "CiA 402 objects", rows: CIA402 },
        Section { title: "Vendor parameters", rows: PARAMS },
        Section { title: "DIP switches (function bank)", rows: DIP },
        Section { title: "LEDs and alarms", rows: LEDS },
    ],
    startup: STARTUP,
    notes: &[
        "Open loop has no position feedback: 0x6064 follows the commanded position, and PT / CST (0x6060 = 4 / 10) are refused with 0x06090030 (the EST-584 \
         has no torque modes either).",
    ],
};
