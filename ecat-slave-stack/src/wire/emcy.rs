//! The emergency message (CoE service 1): mailbox length 10, CoE header (service 1,
//! number 0), u16 error code, u8 error register (the value of 0x1001), 5 bytes of
//! manufacturer data. The queue that sends them is [`crate::coe::emcy`].

use super::coe::{Header, Service, HEADER_LEN as COE_HEADER_LEN};

/// Length of the CoE payload of an emergency (CoE header + 8 bytes).
pub const PAYLOAD_LEN: usize = COE_HEADER_LEN + 8;

/// One emergency message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Emergency {
    /// Error code (CiA 301/402, ETG).
    pub error_code: u16,
    /// Error register (object 0x1001).
    pub error_register: u8,
    /// Manufacturer-specific data.
    pub data: [u8; 5],
}

impl Emergency {
    /// Parses the CoE payload of an emergency (CoE header included).
    pub fn parse(coe_payload: &[u8]) -> Option<Self> {
        let h = Header::parse(coe_payload)?;
        if h.service != Service::Emergency {
            return None;
        }
        let b = coe_payload.get(COE_HEADER_LEN..PAYLOAD_LEN)?;
        let mut data = [0u8; 5];
        data.copy_from_slice(&b[3..8]);
        Some(Emergency {
            error_code: u16::from_le_bytes([b[0], b[1]]),
            error_register: b[2],
            data,
        })
    }
    /// Writes the CoE payload (10 bytes); returns its length, 0 if `out` is too short.
    pub fn emit(&self, out: &mut [u8]) -> usize {
        let Some(b) = out.get_mut(..PAYLOAD_LEN) else {
            return 0;
        };
        Header::of(Service::Emergency).emit(b);
        b[2..4].copy_from_slice(&self.error_code.to_le_bytes());
        b[4] = self.error_register;
        b[5..10].copy_from_slice(&self.data);
        PAYLOAD_LEN
    }
}
