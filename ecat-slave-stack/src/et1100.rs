//! Beckhoff ET1100 EtherCAT slave controller, SPI PDI (embedded-hal 1.0 [`SpiDevice`]).
//!
//! The ET1100's SPI slave gives the host the ESC address space directly (registers
//! 0x0000-0x0FFF, process RAM 0x1000-0x2FFF). Every access is one SPI transaction
//! (chip select low for its whole length):
//!
//! # Address/command phase
//! * **Two bytes** for addresses below 0x2000 (13-bit address):
//!   byte 0 = A12..A5, byte 1 = A4..A0 in bits 7:3 and the 3-bit command in bits 2:0.
//! * **Three bytes** for the full 16-bit range: bytes 0 and 1 as above but with the
//!   command field set to [`cmd::ADDR_EXT`] (0b110); byte 2 = A15..A13 in bits 7:5,
//!   the real command in bits 4:2, bits 1:0 reserved (0).
//!
//! Commands ([`cmd`]): 0b000 NOP, 0b010 read, 0b011 read with wait-state byte,
//! 0b100 write, 0b110 address extension; the others are reserved.
//!
//! # AL event for free
//! While the master clocks the address bytes out on MOSI, the ET1100 clocks the AL
//! event request register out on MISO: byte 0 = 0x0220, byte 1 = 0x0221, and in
//! three-byte mode byte 2 = 0x0222. The driver keeps these bytes;
//! [`EscAccess::al_event`] returns them without an extra transfer when any access
//! happened since the previous call, and otherwise refreshes them with a two-byte
//! NOP transaction. (0x0223 is never clocked out; its bits are SM 16-31 events, which
//! the ET1100 does not have. In two-byte mode bits 23:16 read as 0 — SyncManagers
//! 8-15, also absent in this stack's use of the chip.)
//!
//! # Reads
//! The ESC needs time between the address phase and the first data byte. With
//! [`ReadMode::WaitState`] (default) the driver uses command 0b011 and sends one
//! wait-state byte 0xFF after the address; with [`ReadMode::Delay`] it uses 0b010
//! and inserts an SPI delay operation instead. During the data phase the master sends
//! 0x00 for every byte except the **last, which it sends as 0xFF (read termination)**:
//! that tells the ESC to stop prefetching, so it never touches (and never hands over)
//! a byte beyond the requested range. A 1-byte read therefore sends a single 0xFF.
//!
//! # Writes
//! Command 0b100, then the data bytes; MISO is don't-care after the address.
//!
//! A chip that does not answer is detected by [`Et1100::init`] (ESC type register
//! reads as 0x00/0xFF or not the expected type: [`EscError::NotDetected`]; DL status
//! "PDI operational" never set: [`EscError::Timeout`]); both waits are bounded.

use embedded_hal::delay::DelayNs;
use embedded_hal::spi::{Operation, SpiDevice};

use crate::esc::{EscAccess, EscError};
use crate::registers;

/// 3-bit SPI commands.
pub mod cmd {
    /// No operation (still clocks out the AL event bytes).
    pub const NOP: u8 = 0b000;
    /// Read (the master must wait before the first data byte).
    pub const READ: u8 = 0b010;
    /// Read with one wait-state byte (0xFF) after the address.
    pub const READ_WAIT: u8 = 0b011;
    /// Write.
    pub const WRITE: u8 = 0b100;
    /// Address extension: a third address/command byte follows.
    pub const ADDR_EXT: u8 = 0b110;
}

/// MOSI value of the wait-state byte.
pub const WAIT_STATE_BYTE: u8 = 0xFF;
/// MOSI value of the last data byte of a read (read termination).
pub const READ_TERMINATION: u8 = 0xFF;
/// ESC type register value of the ET1100.
pub const ET1100_TYPE: u8 = 0x11;
/// One past the last ESC address of the ET1100 (8 KiB process RAM from 0x1000).
pub const ESC_END: u32 = 0x3000;

/// How the driver gives the ESC time to fetch read data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadMode {
    /// Command 0b011 and one 0xFF wait-state byte.
    WaitState,
    /// Command 0b010 and an SPI delay of this many ns between address and data.
    Delay(u32),
}

/// Which address phase the driver uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Addressing {
    /// Two bytes below 0x2000, three bytes above.
    Auto,
    /// Always three bytes (also clocks out AL event byte 0x0222).
    Extended,
}

/// Driver settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Et1100Config {
    /// Read timing.
    pub read_mode: ReadMode,
    /// Address phase length.
    pub addressing: Addressing,
    /// Polls during start-up, each after a delay.
    pub startup_polls: u32,
    /// Delay between two start-up polls, µs.
    pub startup_poll_interval_us: u32,
    /// ESC type expected at 0x0000 (None: anything but 0x00 / 0xFF).
    pub expected_type: Option<u8>,
}

impl Default for Et1100Config {
    fn default() -> Self {
        Et1100Config {
            read_mode: ReadMode::WaitState,
            addressing: Addressing::Auto,
            startup_polls: 200,
            startup_poll_interval_us: 1000,
            expected_type: Some(ET1100_TYPE),
        }
    }
}

/// The address/command bytes for `addr` and `command`: two bytes when `addr` fits in
/// 13 bits and `extended` is false, else three.
pub const fn address_phase(addr: u16, command: u8, extended: bool) -> ([u8; 3], usize) {
    let b0 = (addr >> 5) as u8;
    let low = ((addr & 0x1F) as u8) << 3;
    if !extended && addr < 0x2000 {
        ([b0, low | (command & 7), 0], 2)
    } else {
        let b2 = (((addr >> 13) as u8) << 5) | ((command & 7) << 2);
        ([b0, low | cmd::ADDR_EXT, b2], 3)
    }
}

/// ET1100 driver: implements [`EscAccess`] over an SPI device.
pub struct Et1100<SPI> {
    spi: SPI,
    cfg: Et1100Config,
    al_event: u32,
    al_event_fresh: bool,
}

impl<SPI: SpiDevice> Et1100<SPI> {
    /// Wraps an SPI device.
    pub fn new(spi: SPI, cfg: Et1100Config) -> Self {
        Et1100 {
            spi,
            cfg,
            al_event: 0,
            al_event_fresh: false,
        }
    }

    /// Gives the SPI device back.
    pub fn release(self) -> SPI {
        self.spi
    }

    /// The SPI device (tests inspect the model through this).
    pub fn spi_mut(&mut self) -> &mut SPI {
        &mut self.spi
    }

    /// The AL event bytes clocked out by the last transaction (no SPI traffic).
    pub fn last_al_event(&self) -> u32 {
        self.al_event
    }

    /// Start-up: waits until the ESC type register answers (see [`Et1100Config`]) and
    /// DL status bit 0 (PDI operational, EEPROM loaded) is set.
    pub fn init(&mut self, delay: &mut impl DelayNs) -> Result<(), EscError> {
        let polls = self.cfg.startup_polls.max(1);
        let mut found = false;
        for i in 0..polls {
            if i > 0 {
                delay.delay_us(self.cfg.startup_poll_interval_us);
            }
            let t = self.get(registers::ESC_TYPE)?;
            let ok = match self.cfg.expected_type {
                Some(e) => t == e,
                None => t != 0x00 && t != 0xFF,
            };
            if ok {
                found = true;
                break;
            }
        }
        if !found {
            return Err(EscError::NotDetected);
        }
        for i in 0..polls {
            if i > 0 {
                delay.delay_us(self.cfg.startup_poll_interval_us);
            }
            if self.get(registers::DL_STATUS)? & 1 != 0 {
                return Ok(());
            }
        }
        Err(EscError::Timeout)
    }

    fn check(&self, addr: u16, len: usize) -> Result<bool, EscError> {
        if (addr as usize).saturating_add(len) > ESC_END as usize {
            return Err(EscError::OutOfRange);
        }
        Ok(self.cfg.addressing == Addressing::Extended)
    }

    fn keep_al_event(&mut self, miso: &[u8; 3], n: usize) {
        let mut v = miso[0] as u32 | (miso[1] as u32) << 8;
        if n == 3 {
            v |= (miso[2] as u32) << 16;
        }
        self.al_event = v;
        self.al_event_fresh = true;
    }
}

impl<SPI: SpiDevice> EscAccess for Et1100<SPI> {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        let ext = self.check(addr, buf.len())?;
        if buf.is_empty() {
            return Ok(());
        }
        let command = match self.cfg.read_mode {
            ReadMode::WaitState => cmd::READ_WAIT,
            ReadMode::Delay(_) => cmd::READ,
        };
        let (hdr, n) = address_phase(addr, command, ext);
        let mut miso = [0u8; 3];
        buf.fill(0x00);
        if let Some(last) = buf.last_mut() {
            *last = READ_TERMINATION;
        }
        let r = match self.cfg.read_mode {
            ReadMode::WaitState => self.spi.transaction(&mut [
                Operation::Transfer(&mut miso[..n], &hdr[..n]),
                Operation::Write(&[WAIT_STATE_BYTE]),
                Operation::TransferInPlace(buf),
            ]),
            ReadMode::Delay(ns) => self.spi.transaction(&mut [
                Operation::Transfer(&mut miso[..n], &hdr[..n]),
                Operation::DelayNs(ns),
                Operation::TransferInPlace(buf),
            ]),
        };
        r.map_err(|_| EscError::Bus)?;
        self.keep_al_event(&miso, n);
        Ok(())
    }

    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        let ext = self.check(addr, data.len())?;
        if data.is_empty() {
            return Ok(());
        }
        let (hdr, n) = address_phase(addr, cmd::WRITE, ext);
        let mut miso = [0u8; 3];
        self.spi
            .transaction(&mut [
                Operation::Transfer(&mut miso[..n], &hdr[..n]),
                Operation::Write(data),
            ])
            .map_err(|_| EscError::Bus)?;
        self.keep_al_event(&miso, n);
        Ok(())
    }

    /// The AL event bytes of the last transaction if one happened since the previous
    /// call; otherwise a NOP transaction (address phase only) fetches them.
    fn al_event(&mut self) -> Result<u32, EscError> {
        if !self.al_event_fresh {
            let ext = self.cfg.addressing == Addressing::Extended;
            let (hdr, n) = address_phase(0, cmd::NOP, ext);
            let mut miso = [0u8; 3];
            self.spi
                .transaction(&mut [Operation::Transfer(&mut miso[..n], &hdr[..n])])
                .map_err(|_| EscError::Bus)?;
            self.keep_al_event(&miso, n);
        }
        self.al_event_fresh = false;
        Ok(self.al_event)
    }
}
