//! The product's ETG.1020 diagnosis messages (0x10F3, [`ecat_slave_stack::diag`]):
//! one description per message — text ID, type and text — from which the history
//! entries are made and the ESI's `<DiagMessages>` can be written.
//!
//! Every emergency the drive sends is also a diagnosis message
//! ([`message_for_emergency`]): diagnosis code 0xE800 with the emergency's error code
//! in bits 16-31, the text of the fault kind (manufacturer byte 0), and two
//! parameters: the bus voltage (0.1 V, bytes 1-2) and the detail (bytes 3-4, see
//! `faults`). Notable events without an emergency of their own (parameters
//! restored, a corrupt record) have their own code and text. Time stamps are local:
//! milliseconds since power-up, in ns.

use crate::fault_table::{Emergency, FaultKind, KINDS, TABLE};
use ecat_slave_stack::diag::{emergency_code, DiagMessage, DiagText, Param, Severity};

/// Messages the history holds (0x10F3:01).
pub const HISTORY_LEN: usize = 16;

/// The diagnosis history of the product.
pub type History = ecat_slave_stack::diag::DiagHistory<HISTORY_LEN>;

/// One message text of the ESI.
pub type Text = DiagText;

/// Text ID of fault kind `k` (0x0101 + its number).
pub const fn fault_text_id(k: FaultKind) -> u16 {
    0x0101 + k as u16
}
/// Text ID of "the drive stopped on its own, the master's commands stopped" (0x6007
/// = 2 or 3, no fault).
pub const TEXT_COMMUNICATION_STOP: u16 = 0x0110;
/// Text ID of the CiA 301 "error reset" (every fault cleared).
pub const TEXT_ERROR_RESET: u16 = 0x0120;
/// Text ID of "stored parameters not loaded" (corrupt or lost record).
pub const TEXT_PARAMETERS_LOST: u16 = 0x0130;
/// Text ID of "parameters restored to defaults" (0x1011).
pub const TEXT_PARAMETERS_RESTORED: u16 = 0x0131;

/// Text ID of "firmware update accepted" (starts after Bootstrap → Init).
pub const TEXT_UPDATE_ACCEPTED: u16 = 0x0140;
/// Text ID of "firmware update refused" (the running image is untouched).
pub const TEXT_UPDATE_REFUSED: u16 = 0x0141;
/// Text ID of "new firmware confirmed".
pub const TEXT_UPDATE_CONFIRMED: u16 = 0x0142;
/// Text ID of "unconfirmed firmware reverted".
pub const TEXT_UPDATE_REVERTED: u16 = 0x0143;

/// The texts that are not a fault kind's.
const OTHER_TEXTS: [Text; 8] = [
    Text {
        id: TEXT_COMMUNICATION_STOP,
        severity: Severity::Warning,
        text: "Master's commands stopped, drive stopped by 0x6007 (bus %d x 0.1 V, %X)",
    },
    Text {
        id: TEXT_ERROR_RESET,
        severity: Severity::Info,
        text: "Faults reset",
    },
    Text {
        id: TEXT_PARAMETERS_LOST,
        severity: Severity::Warning,
        text: "Stored parameters not loaded, defaults apply (code %X)",
    },
    Text {
        id: TEXT_PARAMETERS_RESTORED,
        severity: Severity::Info,
        text: "Parameters restored to defaults",
    },
    Text {
        id: TEXT_UPDATE_ACCEPTED,
        severity: Severity::Info,
        text: "Firmware update accepted, version %X; starts after Bootstrap to Init",
    },
    Text {
        id: TEXT_UPDATE_REFUSED,
        severity: Severity::Warning,
        text: "Firmware update refused (FoE error %X); the running firmware is unchanged",
    },
    Text {
        id: TEXT_UPDATE_CONFIRMED,
        severity: Severity::Info,
        text: "New firmware version %X confirmed",
    },
    Text {
        id: TEXT_UPDATE_REVERTED,
        severity: Severity::Warning,
        text: "New firmware was not confirmed; the previous firmware was restored",
    },
];

/// The fault kinds' texts (from `fault_table::TABLE`) and then the others.
const ALL_TEXTS: [Text; KINDS + OTHER_TEXTS.len()] = {
    let mut all = [OTHER_TEXTS[0]; KINDS + OTHER_TEXTS.len()];
    let mut i = 0;
    while i < KINDS {
        all[i] = Text {
            id: fault_text_id(FaultKind::ALL[i]),
            severity: Severity::Error,
            text: TABLE[i].text,
        };
        i += 1;
    }
    while i < all.len() {
        all[i] = OTHER_TEXTS[i - KINDS];
        i += 1;
    }
    all
};

/// Every text, by ID.
pub const TEXTS: &[Text] = &ALL_TEXTS;

/// The text of `id`.
pub fn text(id: u16) -> Option<&'static Text> {
    TEXTS.iter().find(|t| t.id == id)
}

fn severity_of(id: u16) -> Severity {
    text(id).map_or(Severity::Error, |t| t.severity)
}

/// The diagnosis message of an emergency sent at `now_ms` (see the module docs).
/// `fault` says whether it reports a fault (else the 0x6007 stop or the error reset).
pub fn message_for_emergency(e: &Emergency, fault: bool, now_ms: u32) -> DiagMessage {
    let t = u64::from(now_ms) * 1_000_000;
    if e.code == 0 {
        return DiagMessage::new(emergency_code(0), Severity::Info, TEXT_ERROR_RESET, t);
    }
    let id = match FaultKind::ALL.get(usize::from(e.data[0])) {
        Some(&k) if fault => fault_text_id(k),
        _ => TEXT_COMMUNICATION_STOP,
    };
    DiagMessage::new(emergency_code(e.code), severity_of(id), id, t)
        .with(Param::U16(u16::from_le_bytes([e.data[1], e.data[2]])))
        .with(Param::U16(u16::from_le_bytes([e.data[3], e.data[4]])))
}

/// The message of a stored-parameter event (`restored`: 0x1011 defaults, else a
/// corrupt or lost record with the emergency code `code`).
pub fn parameter_message(restored: bool, code: u16, now_ms: u32) -> DiagMessage {
    let t = u64::from(now_ms) * 1_000_000;
    if restored {
        DiagMessage::new(0xE001, Severity::Info, TEXT_PARAMETERS_RESTORED, t)
    } else {
        DiagMessage::new(0xE002, Severity::Warning, TEXT_PARAMETERS_LOST, t).with(Param::U16(code))
    }
}

/// The message of a firmware-update event at `now_ms` (diagnosis codes 0xE010 to
/// 0xE013; the version is major << 16 | minor << 8 | patch).
pub fn update_message(e: crate::update::Event, now_ms: u32) -> DiagMessage {
    use crate::update::Event;
    let t = u64::from(now_ms) * 1_000_000;
    let (code, id) = match e {
        Event::Accepted { .. } => (0xE010, TEXT_UPDATE_ACCEPTED),
        Event::Refused(_) => (0xE011, TEXT_UPDATE_REFUSED),
        Event::Confirmed { .. } => (0xE012, TEXT_UPDATE_CONFIRMED),
        Event::Reverted => (0xE013, TEXT_UPDATE_REVERTED),
    };
    let m = DiagMessage::new(code, severity_of(id), id, t);
    match e {
        Event::Accepted { version } | Event::Confirmed { version } => m.with(Param::U32(version)),
        Event::Refused(c) => m.with(Param::U16(c as u16)),
        Event::Reverted => m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_ids_are_unique_and_every_fault_has_one() {
        for (i, a) in TEXTS.iter().enumerate() {
            assert!(TEXTS[i + 1..].iter().all(|b| b.id != a.id), "{:#x}", a.id);
        }
        for k in FaultKind::ALL {
            let t = text(fault_text_id(k)).expect("text");
            assert_eq!(t.severity, Severity::Error);
        }
    }

    #[test]
    fn an_emergency_becomes_its_message() {
        let e = Emergency {
            code: 0x3210,
            register: 0x05,
            data: [FaultKind::OverVoltage as u8, 0x26, 0x02, 0, 0],
        };
        let m = message_for_emergency(&e, true, 1500);
        assert_eq!(m.code, 0x3210_E800);
        assert_eq!(m.text_id, 0x0102);
        assert_eq!(m.time_ns, 1_500_000_000);
        assert_eq!(m.params[0], Param::U16(550));
        assert_eq!(m.n_params, 2);
        // Garbage kind byte: the generic text, no panic.
        let odd = Emergency {
            data: [200, 0, 0, 0, 0],
            ..e
        };
        assert_eq!(
            message_for_emergency(&odd, true, 0).text_id,
            TEXT_COMMUNICATION_STOP
        );
        let reset = Emergency {
            code: 0,
            register: 0,
            data: [0; 5],
        };
        assert_eq!(
            message_for_emergency(&reset, false, 0).severity,
            Severity::Info
        );
    }
}
