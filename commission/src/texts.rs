//! Words for what the drives report: ESM and AL status codes (the slave stack's
//! table), CiA 402 states (the firmware's), faults, LED codes and diagnosis texts (the
//! firmware's fault and diagnosis tables), SDO aborts (ethercrab's table of the
//! CiA 301 / ETG.1000.6 codes). Nothing here keeps a second copy of a text.

use ecat_slave_stack::al_status::AlStatusCode;
use ecat_slave_stack::diag::{DiagMessage, Param};
use ecat_slave_stack::esm::EsmState;
use firmware::cia402::pds::PdsState;
use firmware::faults::{Emergency, FaultKind};

/// The ESM state of AL status bits 3:0, with " + error" when bit 4 is set.
pub fn esm(al_status: u16) -> String {
    let state = match EsmState::from_bits((al_status & 0x0F) as u8) {
        Some(EsmState::Init) => "Init",
        Some(EsmState::PreOp) => "Pre-Op",
        Some(EsmState::Bootstrap) => "Bootstrap",
        Some(EsmState::SafeOp) => "Safe-Op",
        Some(EsmState::Op) => "Op",
        None => "unknown",
    };
    if al_status & 0x10 != 0 {
        format!("{state} + error")
    } else {
        state.to_string()
    }
}

/// The AL status code in words.
pub fn al_code(code: u16) -> String {
    match AlStatusCode::from_code(code) {
        Some(c) => c.text().to_string(),
        None => format!("AL status code {code:#06x}"),
    }
}

/// The CiA 402 state of a statusword.
pub fn cia402(statusword: u16) -> String {
    match PdsState::from_statusword(statusword) {
        Some(s) => format!("{s:?}"),
        None => "unknown".into(),
    }
}

/// The fault kind of a 0x603F error code.
pub fn fault_kind(code: u16) -> Option<FaultKind> {
    FaultKind::ALL.into_iter().find(|k| k.code() == code)
}

/// The red LED's code of a fault kind.
pub fn led(kind: FaultKind) -> String {
    match kind.flashes() {
        Some(n) => format!("red LED: {n} flashes"),
        None => "EtherCAT ERR LED".into(),
    }
}

/// The active fault of a 0x603F error code: its text (parameters left out) and LED
/// code; empty without a fault.
pub fn active_fault(code: u16) -> (String, String) {
    if code == 0 {
        return (String::new(), String::new());
    }
    match fault_kind(code) {
        Some(k) => {
            let text = firmware::diagnosis::text(firmware::diagnosis::fault_text_id(k))
                .map_or("", |t| t.text);
            let short = text.split(" (").next().unwrap_or(text);
            (format!("{code:#06x} {short}"), led(k))
        }
        None => (
            format!("{code:#06x} EtherCAT communication fault"),
            led(FaultKind::Ecat),
        ),
    }
}

/// A diagnosis message's text with its parameters filled in.
pub fn message(m: &DiagMessage) -> String {
    let Some(t) = firmware::diagnosis::text(m.text_id) else {
        return format!("diagnosis code {:#010x}, text {:#06x}", m.code, m.text_id);
    };
    let mut out = String::new();
    let mut params = m.params[..usize::from(m.n_params)].iter();
    let mut rest = t.text;
    while let Some(at) = rest.find('%') {
        out.push_str(&rest[..at]);
        let spec = rest[at + 1..].chars().next().unwrap_or('d');
        let v = params.next().map_or(0i64, |p| match *p {
            Param::U8(v) => i64::from(v),
            Param::U16(v) => i64::from(v),
            Param::U32(v) => i64::from(v),
            Param::I16(v) => i64::from(v),
            Param::I32(v) => i64::from(v),
        });
        if spec == 'X' {
            out.push_str(&format!("{v:X}"));
        } else {
            out.push_str(&v.to_string());
        }
        rest = &rest[(at + 2).min(rest.len())..];
    }
    out.push_str(rest);
    out
}

/// An emergency's text: the diagnosis message the drive makes of it.
pub fn emergency(e: &[u8; 8]) -> String {
    let code = u16::from_le_bytes([e[0], e[1]]);
    let mut data = [0u8; 5];
    data.copy_from_slice(&e[3..8]);
    let emcy = Emergency {
        code,
        register: e[2],
        data,
    };
    let fault = code != 0 && fault_kind(code).is_some()
        || code & 0xFF00 == 0xA000
        || code & 0xFF00 == 0x8200;
    message(&firmware::diagnosis::message_for_emergency(&emcy, fault, 0))
}

/// An SDO abort in words.
pub fn abort(code: u32) -> String {
    let c: ethercrab::error::CoeAbortCode = code.into();
    c.to_string()
}

/// An ethercrab error in words (aborts with their text).
pub fn error(e: &ethercrab::error::Error) -> String {
    match e {
        ethercrab::error::Error::Mailbox(ethercrab::error::MailboxError::Aborted {
            code, ..
        }) => {
            let raw: u32 = (*code).into();
            abort(raw)
        }
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_come_from_the_tables() {
        assert_eq!(esm(0x08), "Op");
        assert_eq!(esm(0x14), "Safe-Op + error");
        assert_eq!(cia402(0x0237), "OperationEnabled");
        let (text, led_code) = active_fault(FaultKind::OverVoltage.code());
        assert!(text.contains("Bus over-voltage"), "{text}");
        assert_eq!(led_code, "red LED: 2 flashes");
        assert!(abort(0x0609_0031).contains("0x06090031"));
        assert_ne!(abort(0x0609_0031), abort(0x0609_0032));
        // An under-voltage emergency: bus 180 (0.1 V), detail 7.
        let e = [
            0x00,
            0x32,
            0x04,
            FaultKind::UnderVoltage as u8,
            180,
            0,
            7,
            0,
        ];
        let t = emergency(&e);
        assert!(t.contains("180") && t.contains('7'), "{t}");
    }
}
