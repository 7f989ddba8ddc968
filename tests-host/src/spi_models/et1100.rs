//! SPI-level model of the ET1100's SPI PDI.
//!
//! Address phase: byte 0 = A12..A5, byte 1 = A4..A0 + command; command 0b110 extends
//! the phase by byte 2 = A15..A13 + command + 2 reserved bits. While the address bytes
//! come in, MISO carries the AL event request register (0x0220, 0x0221, 0x0222),
//! sampled from the ESC memory when chip select goes low.
//!
//! Reads: command 0b011 expects one wait-state byte 0xFF before the data; command
//! 0b010 expects an SPI delay operation between the address phase and the first data
//! byte (the ESC's fetch time; *model choice*: any delay counts). During the data
//! phase MOSI must be 0x00, except the last byte which must be 0xFF (read
//! termination); a byte after the termination or a read that ends without one is a
//! violation. Data bytes are fetched from the ESC memory one by one as they are
//! clocked out, so nothing beyond the terminated range is ever touched.
//!
//! Writes: command 0b100; the data bytes are written to the ESC memory in one access
//! when chip select goes high. NOP (0b000): address phase only. Reserved commands are
//! violations.

use ecat_slave_stack::et1100::cmd;
use ecat_slave_stack::registers::AL_EVENT_REQUEST;
use ecat_slave_stack::EscAccess;
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};

use super::{model_transaction, ByteDevice, ModelBusError, Transaction};

/// Injected faults.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Et1100Faults {
    /// No chip: MISO floats high, nothing is decoded.
    pub absent: bool,
    /// The next transaction fails with a bus error (cleared when used).
    pub fail_next: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    A0,
    A1,
    A2,
    Wait,
    Data,
    Ignore,
}

/// The ET1100 model.
pub struct Et1100Model<B> {
    /// The ESC memory.
    pub esc: B,
    /// Every transaction.
    pub log: Vec<Transaction>,
    /// Protocol violations seen.
    pub violations: Vec<String>,
    /// Injected faults.
    pub faults: Et1100Faults,
    /// Require a delay operation before the data of a 0b010 read.
    pub require_read_delay: bool,
    phase: Phase,
    al: [u8; 4],
    hdr: [u8; 2],
    addr: u16,
    command: u8,
    index: usize,
    delay_seen: bool,
    terminated: bool,
    write_buf: Vec<u8>,
}

impl<B: EscAccess> Et1100Model<B> {
    /// An ET1100 in front of `esc`, no faults.
    pub fn new(esc: B) -> Self {
        Et1100Model {
            esc,
            log: Vec::new(),
            violations: Vec::new(),
            faults: Et1100Faults::default(),
            require_read_delay: true,
            phase: Phase::A0,
            al: [0; 4],
            hdr: [0; 2],
            addr: 0,
            command: 0,
            index: 0,
            delay_seen: false,
            terminated: false,
            write_buf: Vec::new(),
        }
    }

    /// MOSI bytes of every transaction recorded since `from`.
    pub fn mosi_since(&self, from: usize) -> Vec<Vec<u8>> {
        self.log[from.min(self.log.len())..]
            .iter()
            .map(|t| t.mosi.clone())
            .collect()
    }

    fn command_decoded(&mut self) {
        self.phase = match self.command {
            cmd::NOP => Phase::Ignore,
            cmd::READ_WAIT => Phase::Wait,
            cmd::READ | cmd::WRITE => Phase::Data,
            c => {
                self.violations.push(format!("reserved command {c:#05b}"));
                Phase::Ignore
            }
        };
    }

    /// One byte of the data phase: written bytes are collected, read bytes come from the
    /// ESC (the read protocol's rules checked).
    fn data_byte(&mut self, mosi: u8) -> u8 {
        let i = self.index;
        self.index += 1;
        let a = self.addr.wrapping_add(i as u16);
        if self.command == cmd::WRITE {
            self.write_buf.push(mosi);
            return 0x00;
        }
        if i == 0 && self.command == cmd::READ && self.require_read_delay && !self.delay_seen {
            self.violations
                .push("0b010 read without wait time before the data".into());
        }
        if self.terminated {
            self.violations
                .push(format!("byte clocked after read termination at {a:#06x}"));
            return 0x00;
        }
        match mosi {
            0xFF => self.terminated = true,
            0x00 => {}
            b => self.violations.push(format!(
                "MOSI {b:#04x} during read data (must be 0x00 or 0xFF)"
            )),
        }
        let mut b = [0u8; 1];
        if let Err(e) = self.esc.read(a, &mut b) {
            self.violations
                .push(format!("ESC read {a:#06x} failed: {e:?}"));
        }
        b[0]
    }
}

impl<B: EscAccess> ByteDevice for Et1100Model<B> {
    fn take_injected_failure(&mut self) -> bool {
        std::mem::take(&mut self.faults.fail_next)
    }
    fn log(&mut self) -> &mut Vec<Transaction> {
        &mut self.log
    }
    fn begin(&mut self) {
        self.phase = Phase::A0;
        self.index = 0;
        self.delay_seen = false;
        self.terminated = false;
        self.write_buf.clear();
        let mut al = [0u8; 4];
        if self.esc.read(AL_EVENT_REQUEST.addr(), &mut al).is_err() {
            self.violations
                .push("ESC read of the AL event register failed".into());
        }
        self.al = al;
    }

    fn delay(&mut self, _ns: u32) {
        self.delay_seen = true;
    }

    fn exchange(&mut self, mosi: u8) -> u8 {
        if self.faults.absent {
            return 0xFF;
        }
        match self.phase {
            Phase::A0 => {
                self.hdr[0] = mosi;
                self.phase = Phase::A1;
                self.al[0]
            }
            Phase::A1 => {
                self.hdr[1] = mosi;
                self.addr = ((self.hdr[0] as u16) << 5) | (mosi >> 3) as u16;
                self.command = mosi & 7;
                if self.command == cmd::ADDR_EXT {
                    self.phase = Phase::A2;
                } else {
                    self.delay_seen = false;
                    self.command_decoded();
                }
                self.al[1]
            }
            Phase::A2 => {
                self.addr |= ((mosi >> 5) as u16) << 13;
                self.command = (mosi >> 2) & 7;
                if mosi & 3 != 0 {
                    self.violations
                        .push(format!("reserved bits set in address byte 2: {mosi:#04x}"));
                }
                if self.command == cmd::ADDR_EXT {
                    self.violations
                        .push("address extension inside the extended address".into());
                }
                self.delay_seen = false;
                self.command_decoded();
                self.al[2]
            }
            Phase::Wait => {
                if mosi != 0xFF {
                    self.violations
                        .push(format!("wait-state byte {mosi:#04x} instead of 0xFF"));
                }
                self.phase = Phase::Data;
                0x00
            }
            Phase::Data => self.data_byte(mosi),
            Phase::Ignore => 0x00,
        }
    }

    fn end(&mut self) {
        if self.faults.absent {
            return;
        }
        if matches!(self.phase, Phase::A0 | Phase::A1 | Phase::A2) && self.index == 0 {
            if self.phase != Phase::A0 {
                self.violations
                    .push("transaction ended inside the address phase".into());
            }
            return;
        }
        let reading = matches!(self.command, cmd::READ | cmd::READ_WAIT);
        if reading && self.index > 0 && !self.terminated {
            self.violations
                .push("read ended without read termination (0xFF)".into());
        }
        if self.command == cmd::WRITE && !self.write_buf.is_empty() {
            let data = std::mem::take(&mut self.write_buf);
            if let Err(e) = self.esc.write(self.addr, &data) {
                self.violations.push(format!(
                    "ESC write {:#06x}+{} failed: {e:?}",
                    self.addr,
                    data.len()
                ));
            }
        }
    }
}

impl<B> ErrorType for Et1100Model<B> {
    type Error = ModelBusError;
}

impl<B: EscAccess> SpiDevice for Et1100Model<B> {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), ModelBusError> {
        model_transaction(self, operations)
    }
}
