//! Access to the EtherCAT slave controller's address space from the PDI side.
//!
//! Every ESC driver (LAN9252, ET1100, the host simulator) implements [`EscAccess`];
//! everything above it (state machine, mailbox, process data) only ever talks to
//! this trait. Addresses are ESC addresses (registers 0x0000-0x0FFF, process RAM
//! from 0x1000); multi-byte values are little-endian as on the wire.

use crate::registers::Register;

/// Errors an ESC access can report. Drivers map their bus errors onto these.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EscError {
    /// The SPI (or other PDI) bus reported an error.
    Bus,
    /// The chip did not identify itself (e.g. LAN9252 BYTE_TEST != 0x87654321).
    NotDetected,
    /// The chip stayed busy longer than the bounded retry allows.
    Timeout,
    /// The address range is outside what the chip implements.
    OutOfRange,
}

/// An integer register value: little-endian on the wire, as wide as its type.
pub trait RegisterValue: Copy {
    /// Width, bytes.
    const LEN: usize;
    /// Decodes `LEN` little-endian bytes.
    fn from_le(b: &[u8]) -> Self;
    /// Encodes into `LEN` little-endian bytes.
    fn to_le(self, out: &mut [u8]);
}

macro_rules! register_value {
    ($($t:ty),*) => {$(
        impl RegisterValue for $t {
            const LEN: usize = core::mem::size_of::<$t>();
            fn from_le(b: &[u8]) -> Self {
                let mut a = [0u8; core::mem::size_of::<$t>()];
                a.copy_from_slice(b);
                <$t>::from_le_bytes(a)
            }
            fn to_le(self, out: &mut [u8]) {
                out.copy_from_slice(&self.to_le_bytes());
            }
        }
    )*};
}
register_value!(u8, u16, u32, u64);

/// Read/write access to the ESC address space as seen from the PDI.
pub trait EscAccess {
    /// Reads `buf.len()` bytes starting at ESC address `addr`.
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError>;
    /// Writes `data` starting at ESC address `addr`.
    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError>;
    /// Reads the AL event request register (0x0220, 32 bit). Drivers that get it for
    /// free during an SPI address phase (ET1100) return the last value clocked out.
    fn al_event(&mut self) -> Result<u32, EscError> {
        self.get(crate::registers::AL_EVENT_REQUEST)
    }

    /// Reads a register at its width.
    fn get<T: RegisterValue>(&mut self, r: Register<T>) -> Result<T, EscError> {
        let mut b = [0u8; 8];
        let b = &mut b[..T::LEN];
        self.read(r.addr(), b)?;
        Ok(T::from_le(b))
    }
    /// Writes a register at its width.
    fn set<T: RegisterValue>(&mut self, r: Register<T>, v: T) -> Result<(), EscError> {
        let mut b = [0u8; 8];
        let b = &mut b[..T::LEN];
        v.to_le(b);
        self.write(r.addr(), b)
    }

    /// Reads one byte.
    fn read_u8(&mut self, addr: u16) -> Result<u8, EscError> {
        let mut b = [0u8; 1];
        self.read(addr, &mut b)?;
        Ok(b[0])
    }
    /// Reads a little-endian u16.
    fn read_u16(&mut self, addr: u16) -> Result<u16, EscError> {
        let mut b = [0u8; 2];
        self.read(addr, &mut b)?;
        Ok(u16::from_le_bytes(b))
    }
    /// Reads a little-endian u32.
    fn read_u32(&mut self, addr: u16) -> Result<u32, EscError> {
        let mut b = [0u8; 4];
        self.read(addr, &mut b)?;
        Ok(u32::from_le_bytes(b))
    }
    /// Writes one byte.
    fn write_u8(&mut self, addr: u16, v: u8) -> Result<(), EscError> {
        self.write(addr, &[v])
    }
    /// Writes a little-endian u16.
    fn write_u16(&mut self, addr: u16, v: u16) -> Result<(), EscError> {
        self.write(addr, &v.to_le_bytes())
    }
    /// Writes a little-endian u32.
    fn write_u32(&mut self, addr: u16, v: u32) -> Result<(), EscError> {
        self.write(addr, &v.to_le_bytes())
    }
}

impl<T: EscAccess + ?Sized> EscAccess for &mut T {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        (**self).read(addr, buf)
    }
    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        (**self).write(addr, data)
    }
    fn al_event(&mut self) -> Result<u32, EscError> {
        (**self).al_event()
    }
}
