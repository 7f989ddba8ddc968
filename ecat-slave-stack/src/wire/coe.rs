//! The CoE header (ETG.1000.6): the u16 after the mailbox header, bits 8:0 number (PDO
//! number, 0 for SDO), bits 11:9 reserved, bits 15:12 service.

/// Size of the CoE header.
pub const HEADER_LEN: usize = 2;

/// CoE services (bits 15:12 of the CoE header).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Service {
    /// Emergency message.
    Emergency,
    /// SDO request (also carries aborts, in both directions).
    SdoRequest,
    /// SDO response.
    SdoResponse,
    /// TxPDO.
    TxPdo,
    /// RxPDO.
    RxPdo,
    /// TxPDO remote request.
    TxPdoRemoteRequest,
    /// RxPDO remote request.
    RxPdoRemoteRequest,
    /// SDO information.
    SdoInformation,
    /// Any other code (0, 9…15).
    Unknown(u8),
}

impl Service {
    /// Decodes the 4-bit service.
    pub const fn from_bits(v: u8) -> Self {
        match v & 0x0F {
            1 => Self::Emergency,
            2 => Self::SdoRequest,
            3 => Self::SdoResponse,
            4 => Self::TxPdo,
            5 => Self::RxPdo,
            6 => Self::TxPdoRemoteRequest,
            7 => Self::RxPdoRemoteRequest,
            8 => Self::SdoInformation,
            x => Self::Unknown(x),
        }
    }
    /// The 4-bit code.
    pub const fn bits(self) -> u8 {
        match self {
            Self::Emergency => 1,
            Self::SdoRequest => 2,
            Self::SdoResponse => 3,
            Self::TxPdo => 4,
            Self::RxPdo => 5,
            Self::TxPdoRemoteRequest => 6,
            Self::RxPdoRemoteRequest => 7,
            Self::SdoInformation => 8,
            Self::Unknown(x) => x & 0x0F,
        }
    }
}

/// A parsed CoE header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Bits 8:0 (PDO number; 0 for SDO services).
    pub number: u16,
    /// The service.
    pub service: Service,
}

impl Header {
    /// Parses the first two bytes of a CoE mailbox payload.
    pub fn parse(payload: &[u8]) -> Option<Self> {
        let b = payload.get(..HEADER_LEN)?;
        let v = u16::from_le_bytes([b[0], b[1]]);
        Some(Header {
            number: v & 0x01FF,
            service: Service::from_bits(b[1] >> 4),
        })
    }
    /// The raw u16.
    pub const fn to_u16(self) -> u16 {
        (self.number & 0x01FF) | ((self.service.bits() as u16) << 12)
    }
    /// Writes the header into the first two bytes of `out` (returns false if too short).
    pub fn emit(self, out: &mut [u8]) -> bool {
        match out.get_mut(..HEADER_LEN) {
            Some(b) => {
                b.copy_from_slice(&self.to_u16().to_le_bytes());
                true
            }
            None => false,
        }
    }
    /// The header of a service with number 0.
    pub const fn of(service: Service) -> Self {
        Header { number: 0, service }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_bytes() {
        assert_eq!(
            Header::parse(&[0x00, 0x20]),
            Some(Header {
                number: 0,
                service: Service::SdoRequest
            })
        );
        assert_eq!(
            Header::parse(&[0x05, 0x51]),
            Some(Header {
                number: 0x105,
                service: Service::RxPdo
            })
        );
        assert_eq!(Header::parse(&[0x00]), None);
        assert_eq!(
            Header::of(Service::SdoInformation).to_u16().to_le_bytes(),
            [0x00, 0x80]
        );
        assert_eq!(
            Header::of(Service::Emergency).to_u16().to_le_bytes(),
            [0x00, 0x10]
        );
        assert_eq!(
            Header::parse(&[0, 0xF0]).map(|h| h.service),
            Some(Service::Unknown(15))
        );
        let mut b = [0u8; 1];
        assert!(!Header::of(Service::SdoResponse).emit(&mut b));
        for s in 0..16 {
            assert_eq!(Service::from_bits(s).bits(), s);
        }
    }
}
