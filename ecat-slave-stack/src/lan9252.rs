//! Microchip LAN9252 EtherCAT slave controller over SPI (embedded-hal 1.0 [`SpiDevice`]).
//!
//! The LAN9252 is an ESC core behind a host bus interface. The host never sees the
//! ESC address space directly: it talks to a small set of 32-bit *system registers*
//! over SPI and reaches the ESC through two indirect windows:
//!
//! * **ESC registers (0x0000-0x0FFF)** through the CSR window: the data goes through
//!   `ECAT_CSR_DATA` and the access is started by writing `ECAT_CSR_CMD`; the driver
//!   polls the command's busy bit. One CSR access moves 1, 2 or 4 bytes at a naturally
//!   aligned address, so longer or unaligned accesses are split.
//! * **Process RAM (0x1000-0x1FFF)** through the PRAM FIFOs: the driver writes address
//!   and length, starts the transfer, and moves 32-bit words through the read FIFO
//!   (port 0x000) or the write FIFO (port 0x020), polling the word count the FIFO
//!   reports. The first FIFO word carries the first data byte at byte lane
//!   `address & 3`; lanes before the first and after the last byte are padding.
//!
//! # SPI framing (SPI mode, not SQI)
//! Every transaction starts with an instruction byte and a 16-bit big-endian address
//! (only bits 13:0 address a register; the driver sends bits 15:14 as 0):
//!
//! | instruction | bytes on MOSI | data |
//! |---|---|---|
//! | serial read [`cmd::SERIAL_READ`] 0x03 | `03 AH AL` | read bytes follow at once |
//! | fast read [`cmd::FAST_READ`] 0x0B | `0B AH AL DD` | one dummy byte `DD` ([`FAST_READ_DUMMY`]), then data |
//! | serial write [`cmd::SERIAL_WRITE`] 0x02 | `02 AH AL D0 D1 …` | bytes follow the address |
//!
//! System registers are little-endian 32-bit words (`D0` = bits 7:0). The internal
//! address advances with every byte, except inside the FIFO ports (0x000-0x01F read,
//! 0x020-0x03F write) where every 4 bytes pop or push one FIFO word; that is what lets
//! one SPI transaction move a whole burst of FIFO words.
//!
//! # System registers used (LAN9252 datasheet, "System Control and Status Registers")
//! | addr | name | use here |
//! |---|---|---|
//! | 0x000 | ECAT_PRAM_RD_DATA (FIFO port) | process-RAM read data |
//! | 0x020 | ECAT_PRAM_WR_DATA (FIFO port) | process-RAM write data |
//! | 0x050 | ID_REV | bits 31:16 chip ID (0x9252), bits 15:0 revision; read and kept |
//! | 0x054 | IRQ_CFG | bit 0 IRQ buffer type (1 = push-pull, 0 = open drain), bit 4 polarity (1 = active high), bit 8 IRQ enable, bits 31:24 de-assertion interval (10 µs units) |
//! | 0x058 | INT_STS | bit 0 ECAT_INT (an unmasked AL event is pending) |
//! | 0x05C | INT_EN | bit 0 ECAT_INT_EN |
//! | 0x064 | BYTE_TEST | reads 0x87654321 when the host interface is up and the byte order is right |
//! | 0x074 | HW_CFG | bit 27 READY (device ready to be accessed after power-up / reset) |
//! | 0x1F8 | RESET_CTL | bit 0 DIGITAL_RST, bit 6 ECAT_RST (self-clearing) |
//! | 0x300 | ECAT_CSR_DATA | CSR data, ESC bytes right-aligned (lane 0 = the byte at the ESC address) |
//! | 0x304 | ECAT_CSR_CMD | bit 31 CSR_BUSY (write 1 to start, reads 1 while running), bit 30 R/nW (1 = read), bits 18:16 size (1, 2, 4), bits 15:0 ESC address |
//! | 0x308 | ECAT_PRAM_RD_ADDR_LEN | bits 31:16 length in bytes, bits 15:0 ESC address |
//! | 0x30C | ECAT_PRAM_RD_CMD | bit 31 busy (write 1 = start), bit 30 abort, bits 12:8 words available in the read FIFO, bit 0 data available |
//! | 0x310 | ECAT_PRAM_WR_ADDR_LEN | as 0x308, for writes |
//! | 0x314 | ECAT_PRAM_WR_CMD | as 0x30C; bits 12:8 free words in the write FIFO, bit 0 space available |
//!
//! # Bounded waiting
//! Every wait (BYTE_TEST, READY, reset, CSR busy, FIFO ready) is a bounded number of
//! polls ([`Lan9252Config`]); a chip that never answers gives
//! [`EscError::NotDetected`] (BYTE_TEST never right) or [`EscError::Timeout`], never a
//! hang and never a panic. A PRAM transfer cut short by an error is aborted
//! (`ECAT_PRAM_*_CMD` abort bit) before the next one starts; before every other
//! transfer the driver waits until the unit's busy bit is clear, and only then writes
//! ECAT_PRAM_*_ADDR_LEN (it must not change while busy: a write may still be moving
//! its FIFO into process RAM after the last word was pushed).

use embedded_hal::delay::DelayNs;
use embedded_hal::spi::{Operation, SpiDevice};

use crate::esc::{EscAccess, EscError};

/// SPI instruction bytes.
pub mod cmd {
    /// Serial read: instruction, 2 address bytes, data.
    pub const SERIAL_READ: u8 = 0x03;
    /// Fast read: instruction, 2 address bytes, 1 dummy byte, data.
    pub const FAST_READ: u8 = 0x0B;
    /// Serial write: instruction, 2 address bytes, data.
    pub const SERIAL_WRITE: u8 = 0x02;
}

/// Value of the dummy byte sent after the address of a fast read. The chip ignores
/// its value in SPI mode; 0x01 is what the common open-source drivers send.
pub const FAST_READ_DUMMY: u8 = 0x01;
/// ESC type register (0x0000) value of the LAN9252's EtherCAT core, as the ESC
/// simulator reproduces it (no data sheet among the project's sources states it).
pub const LAN9252_TYPE: u8 = 0xC0;

/// System register addresses (host side, not ESC addresses).
pub mod reg {
    /// Process-RAM read FIFO port (0x000-0x01F alias the same port).
    pub const PRAM_RD_FIFO: u16 = 0x000;
    /// Process-RAM write FIFO port (0x020-0x03F alias the same port).
    pub const PRAM_WR_FIFO: u16 = 0x020;
    /// Chip ID (bits 31:16) and revision (15:0).
    pub const ID_REV: u16 = 0x050;
    /// IRQ pin configuration.
    pub const IRQ_CFG: u16 = 0x054;
    /// Interrupt status.
    pub const INT_STS: u16 = 0x058;
    /// Interrupt enable.
    pub const INT_EN: u16 = 0x05C;
    /// Byte-order test register.
    pub const BYTE_TEST: u16 = 0x064;
    /// Hardware configuration (READY bit).
    pub const HW_CFG: u16 = 0x074;
    /// Reset control.
    pub const RESET_CTL: u16 = 0x1F8;
    /// ESC CSR data window.
    pub const ECAT_CSR_DATA: u16 = 0x300;
    /// ESC CSR command.
    pub const ECAT_CSR_CMD: u16 = 0x304;
    /// Process-RAM read address and length.
    pub const PRAM_RD_ADDR_LEN: u16 = 0x308;
    /// Process-RAM read command / status.
    pub const PRAM_RD_CMD: u16 = 0x30C;
    /// Process-RAM write address and length.
    pub const PRAM_WR_ADDR_LEN: u16 = 0x310;
    /// Process-RAM write command / status.
    pub const PRAM_WR_CMD: u16 = 0x314;
}

/// BYTE_TEST reads this when the SPI link works.
pub const BYTE_TEST_VALUE: u32 = 0x8765_4321;
/// HW_CFG: device ready.
pub const HW_CFG_READY: u32 = 1 << 27;
/// RESET_CTL: digital reset of the whole chip (self-clearing).
pub const RESET_DIGITAL: u32 = 1 << 0;
/// RESET_CTL: reset of the EtherCAT core only (self-clearing).
pub const RESET_ETHERCAT: u32 = 1 << 6;
/// ECAT_CSR_CMD: busy / start.
pub const CSR_BUSY: u32 = 1 << 31;
/// ECAT_CSR_CMD: 1 = read, 0 = write.
pub const CSR_READ: u32 = 1 << 30;
/// ECAT_CSR_CMD: position of the size field (bits 18:16).
pub const CSR_SIZE_SHIFT: u32 = 16;
/// ECAT_PRAM_*_CMD: busy / start.
pub const PRAM_BUSY: u32 = 1 << 31;
/// ECAT_PRAM_*_CMD: abort the running transfer.
pub const PRAM_ABORT: u32 = 1 << 30;
/// ECAT_PRAM_*_CMD: data (read) / space (write) available.
pub const PRAM_AVAIL: u32 = 1 << 0;
/// ECAT_PRAM_*_CMD: position of the 5-bit word count (bits 12:8).
pub const PRAM_COUNT_SHIFT: u32 = 8;
/// ECAT_PRAM_*_CMD: mask of the word count after shifting.
pub const PRAM_COUNT_MASK: u32 = 0x1F;
/// Depth of each PRAM FIFO in 32-bit words.
pub const FIFO_WORDS: usize = 16;
/// IRQ_CFG: push-pull output (0 = open drain).
pub const IRQ_CFG_PUSH_PULL: u32 = 1 << 0;
/// IRQ_CFG: active-high polarity (0 = active low).
pub const IRQ_CFG_ACTIVE_HIGH: u32 = 1 << 4;
/// IRQ_CFG: IRQ output enable.
pub const IRQ_CFG_ENABLE: u32 = 1 << 8;
/// IRQ_CFG: position of the de-assertion interval (bits 31:24, 10 µs units).
pub const IRQ_CFG_DEAS_SHIFT: u32 = 24;
/// INT_EN / INT_STS: EtherCAT (AL event) interrupt.
pub const INT_ECAT: u32 = 1 << 0;

/// First ESC address handled by the PRAM FIFOs.
pub const PRAM_START: u16 = 0x1000;
/// One past the last ESC address of the LAN9252 (4 KiB process RAM).
pub const ESC_END: u32 = 0x2000;

/// Which read instruction the driver uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadCommand {
    /// 0x03, data right after the address (slower SPI clocks).
    Serial,
    /// 0x0B with one dummy byte (full SPI clock rate).
    Fast,
}

/// Reset issued by [`Lan9252::init`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResetKind {
    /// No reset: use the chip as power-up left it.
    None,
    /// RESET_CTL DIGITAL_RST: whole chip, reloads the EEPROM configuration.
    Digital,
    /// RESET_CTL ECAT_RST: EtherCAT core only.
    EtherCat,
}

/// Driver settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Lan9252Config {
    /// Read instruction.
    pub read_command: ReadCommand,
    /// Polls of a busy/ready bit during normal accesses before [`EscError::Timeout`].
    pub max_polls: u32,
    /// Polls during start-up (BYTE_TEST, READY, reset), each after a delay.
    pub startup_polls: u32,
    /// Delay between two start-up polls, µs.
    pub startup_poll_interval_us: u32,
    /// Reset issued by [`Lan9252::init`].
    pub reset: ResetKind,
}

impl Default for Lan9252Config {
    fn default() -> Self {
        Lan9252Config {
            read_command: ReadCommand::Fast,
            max_polls: 1000,
            startup_polls: 200,
            startup_poll_interval_us: 1000,
            reset: ResetKind::Digital,
        }
    }
}

/// IRQ pin configuration (IRQ_CFG + INT_EN).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IrqConfig {
    /// Drive the IRQ pin at all.
    pub enable: bool,
    /// Active high (else active low).
    pub active_high: bool,
    /// Push-pull (else open drain).
    pub push_pull: bool,
    /// Minimum de-assertion time between two interrupts, in 10 µs units.
    pub deassert_interval: u8,
}

impl IrqConfig {
    /// The IRQ_CFG register value.
    pub const fn irq_cfg(&self) -> u32 {
        (if self.enable { IRQ_CFG_ENABLE } else { 0 })
            | (if self.active_high {
                IRQ_CFG_ACTIVE_HIGH
            } else {
                0
            })
            | (if self.push_pull { IRQ_CFG_PUSH_PULL } else { 0 })
            | ((self.deassert_interval as u32) << IRQ_CFG_DEAS_SHIFT)
    }
}

/// LAN9252 driver: implements [`EscAccess`] over an SPI device.
pub struct Lan9252<SPI> {
    spi: SPI,
    cfg: Lan9252Config,
    id_rev: u32,
    rd_dirty: bool,
    wr_dirty: bool,
}

impl<SPI: SpiDevice> Lan9252<SPI> {
    /// Wraps an SPI device; call [`Lan9252::init`] before any ESC access.
    pub fn new(spi: SPI, cfg: Lan9252Config) -> Self {
        Lan9252 {
            spi,
            cfg,
            id_rev: 0,
            rd_dirty: true,
            wr_dirty: true,
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

    /// ID_REV as read by [`Lan9252::init`] (0 before).
    pub fn id_rev(&self) -> u32 {
        self.id_rev
    }

    /// Start-up: waits for BYTE_TEST = 0x87654321 ([`EscError::NotDetected`] if it
    /// never reads right) and HW_CFG READY, issues the configured reset and waits for
    /// the chip to come back, then reads ID_REV.
    pub fn init(&mut self, delay: &mut impl DelayNs) -> Result<(), EscError> {
        self.wait_byte_test(delay)?;
        self.wait_ready(delay)?;
        let bit = match self.cfg.reset {
            ResetKind::None => 0,
            ResetKind::Digital => RESET_DIGITAL,
            ResetKind::EtherCat => RESET_ETHERCAT,
        };
        if bit != 0 {
            self.write_reg(reg::RESET_CTL, bit)?;
            // During a digital reset the host interface is down: BYTE_TEST first.
            self.wait_byte_test(delay)?;
            self.wait_ready(delay)?;
            let mut n = 0;
            while self.read_reg(reg::RESET_CTL)? & bit != 0 {
                n += 1;
                if n >= self.cfg.startup_polls {
                    return Err(EscError::Timeout);
                }
                delay.delay_us(self.cfg.startup_poll_interval_us);
            }
        }
        self.id_rev = self.read_reg(reg::ID_REV)?;
        self.rd_dirty = true;
        self.wr_dirty = true;
        Ok(())
    }

    fn wait_byte_test(&mut self, delay: &mut impl DelayNs) -> Result<(), EscError> {
        for i in 0..self.cfg.startup_polls.max(1) {
            if i > 0 {
                delay.delay_us(self.cfg.startup_poll_interval_us);
            }
            if self.read_reg(reg::BYTE_TEST)? == BYTE_TEST_VALUE {
                return Ok(());
            }
        }
        Err(EscError::NotDetected)
    }

    fn wait_ready(&mut self, delay: &mut impl DelayNs) -> Result<(), EscError> {
        for i in 0..self.cfg.startup_polls.max(1) {
            if i > 0 {
                delay.delay_us(self.cfg.startup_poll_interval_us);
            }
            if self.read_reg(reg::HW_CFG)? & HW_CFG_READY != 0 {
                return Ok(());
            }
        }
        Err(EscError::Timeout)
    }

    /// Configures the IRQ pin (IRQ_CFG) and enables or disables the EtherCAT
    /// interrupt source (INT_EN bit 0). Which AL events raise it is the ESC's AL
    /// event mask (0x0204), set by the slave runtime.
    pub fn configure_irq(&mut self, irq: IrqConfig) -> Result<(), EscError> {
        self.write_reg(reg::IRQ_CFG, irq.irq_cfg())?;
        self.write_reg(reg::INT_EN, if irq.enable { INT_ECAT } else { 0 })
    }

    /// INT_STS (bit 0: an unmasked AL event is pending).
    pub fn irq_status(&mut self) -> Result<u32, EscError> {
        self.read_reg(reg::INT_STS)
    }

    /// Reads a 32-bit system register with the configured read instruction.
    pub fn read_reg(&mut self, addr: u16) -> Result<u32, EscError> {
        let mut b = [0u8; 4];
        self.read_burst(addr, &mut b)?;
        Ok(u32::from_le_bytes(b))
    }

    /// Writes a 32-bit system register (serial write, 7 bytes). Out of line: one copy
    /// for the register accesses of set-up and mailbox paths (the process-RAM paths use
    /// `write_reg_inline`).
    // Measured (cargo xtask size, LAN9252 image): inlined into `csr` and `pram` it costs
    // +58 B flash.
    #[inline(never)]
    pub fn write_reg(&mut self, addr: u16, v: u32) -> Result<(), EscError> {
        self.write_reg_inline(addr, v)
    }

    /// [`Self::write_reg`] inlined into the cyclic process-RAM transfers.
    #[inline(always)]
    fn write_reg_inline(&mut self, addr: u16, v: u32) -> Result<(), EscError> {
        let a = addr_bytes(addr);
        let d = v.to_le_bytes();
        let frame = [cmd::SERIAL_WRITE, a[0], a[1], d[0], d[1], d[2], d[3]];
        self.spi
            .transaction(&mut [Operation::Write(&frame)])
            .map_err(|_| EscError::Bus)
    }

    /// One read transaction of `buf.len()` bytes starting at system address `addr`.
    fn read_burst(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        let a = addr_bytes(addr);
        // Fast read: instruction, address, dummy byte; serial read: the first three.
        let (instruction, header_len) = match self.cfg.read_command {
            ReadCommand::Fast => (cmd::FAST_READ, 4),
            ReadCommand::Serial => (cmd::SERIAL_READ, 3),
        };
        let header = [instruction, a[0], a[1], FAST_READ_DUMMY];
        self.spi
            .transaction(&mut [
                Operation::Write(&header[..header_len]),
                Operation::Read(buf),
            ])
            .map_err(|_| EscError::Bus)
    }

    /// One write transaction of `data` starting at system address `addr`.
    fn write_burst(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        let a = addr_bytes(addr);
        let header = [cmd::SERIAL_WRITE, a[0], a[1]];
        self.spi
            .transaction(&mut [Operation::Write(&header), Operation::Write(data)])
            .map_err(|_| EscError::Bus)
    }

    /// Polls command register `cmd_reg` (ECAT_CSR_CMD or ECAT_PRAM_*_CMD) until its
    /// busy bit reads 0. Shared by the CSR commands and the PRAM aborts.
    fn wait_idle(&mut self, cmd_reg: u16) -> Result<(), EscError> {
        const { assert!(CSR_BUSY == PRAM_BUSY) };
        for _ in 0..self.cfg.max_polls.max(1) {
            if self.read_reg(cmd_reg)? & CSR_BUSY == 0 {
                return Ok(());
            }
        }
        Err(EscError::Timeout)
    }

    /// CSR-window access of `data` at ESC register `addr`, split into naturally
    /// aligned 1-, 2- and 4-byte commands. One routine for reads and writes:
    /// a write puts each chunk into ECAT_CSR_DATA before its command, a read takes it
    /// from there once the command is done.
    fn csr(&mut self, mut addr: u16, mut data: Data<'_>) -> Result<(), EscError> {
        let len = data.len();
        let mut done = 0;
        while done < len {
            let size = csr_chunk(addr, len - done);
            let mut command = CSR_BUSY | ((size as u32) << CSR_SIZE_SHIFT) | addr as u32;
            match &data {
                Data::Write(d) => {
                    // `done + size <= len` (csr_chunk): `get` only spares the
                    // compiler a slice-index panic path it cannot rule out.
                    let mut v = [0u8; 4];
                    if let Some(src) = d.get(done..done + size) {
                        v[..size].copy_from_slice(src);
                    }
                    self.write_reg(reg::ECAT_CSR_DATA, u32::from_le_bytes(v))?;
                }
                Data::Read(_) => command |= CSR_READ,
            }
            self.write_reg(reg::ECAT_CSR_CMD, command)?;
            self.wait_idle(reg::ECAT_CSR_CMD)?;
            if let Data::Read(b) = &mut data {
                let v = self.read_reg(reg::ECAT_CSR_DATA)?.to_le_bytes();
                if let Some(dst) = b.get_mut(done..done + size) {
                    dst.copy_from_slice(&v[..size]);
                }
            }
            done += size;
            addr = addr.wrapping_add(size as u16);
        }
        Ok(())
    }

    /// Aborts a PRAM transfer left unfinished and waits until the unit is idle.
    fn pram_abort(&mut self, cmd_reg: u16) -> Result<(), EscError> {
        self.write_reg(cmd_reg, PRAM_ABORT)?;
        self.wait_idle(cmd_reg)
    }

    /// Polls a PRAM command register until the FIFO reports words (read: data, write:
    /// space); returns the count.
    fn pram_wait_fifo(&mut self, cmd_reg: u16) -> Result<usize, EscError> {
        for _ in 0..self.cfg.max_polls.max(1) {
            let v = self.read_reg(cmd_reg)?;
            let count = ((v >> PRAM_COUNT_SHIFT) & PRAM_COUNT_MASK) as usize;
            if v & PRAM_AVAIL != 0 && count > 0 {
                return Ok(count.min(FIFO_WORDS));
            }
        }
        Err(EscError::Timeout)
    }

    /// Process-RAM access of `data` at ESC address `addr` through the read or the
    /// write FIFO. One routine for both directions: the same start sequence
    /// (abort of a transfer left unfinished, address and length, start) on the
    /// direction's registers, then bursts of as many words as the FIFO reports.
    fn pram(&mut self, addr: u16, mut data: Data<'_>) -> Result<(), EscError> {
        let write = matches!(data, Data::Write(_));
        let cmd_reg = if write {
            reg::PRAM_WR_CMD
        } else {
            reg::PRAM_RD_CMD
        };
        // PRAM_*_ADDR_LEN sits right below its command register.
        let addr_len_reg = cmd_reg - 4;
        let dirty = if write { self.wr_dirty } else { self.rd_dirty };
        // ADDR_LEN must not change while the unit is busy: a transfer cut short is
        // aborted first; otherwise the previous one may still be running (a write's
        // data still moving from the FIFO into the RAM), so wait until busy clears.
        if dirty {
            self.pram_abort(cmd_reg)?;
        } else {
            self.wait_idle(cmd_reg)?;
        }
        self.set_dirty(write, true);
        let len = data.len();
        self.write_reg_inline(addr_len_reg, ((len as u32) << 16) | addr as u32)?;
        self.write_reg_inline(cmd_reg, PRAM_BUSY)?;
        let lead = (addr & 3) as usize;
        let total_words = (lead + len).div_ceil(4);
        let mut word = 0;
        let mut chunk = [0u8; FIFO_WORDS * 4];
        while word < total_words {
            let n = self.pram_wait_fifo(cmd_reg)?.min(total_words - word);
            let bytes = &mut chunk[..n * 4];
            match &mut data {
                Data::Read(buf) => {
                    self.read_burst(reg::PRAM_RD_FIFO, bytes)?;
                    for (k, b) in bytes.iter().enumerate() {
                        let stream = word * 4 + k;
                        if stream >= lead && stream - lead < buf.len() {
                            buf[stream - lead] = *b;
                        }
                    }
                }
                Data::Write(src) => {
                    for (k, b) in bytes.iter_mut().enumerate() {
                        let stream = word * 4 + k;
                        *b = if stream >= lead && stream - lead < src.len() {
                            src[stream - lead]
                        } else {
                            0
                        };
                    }
                    self.write_burst(reg::PRAM_WR_FIFO, bytes)?;
                }
            }
            word += n;
        }
        self.set_dirty(write, false);
        Ok(())
    }

    fn set_dirty(&mut self, write: bool, dirty: bool) {
        if write {
            self.wr_dirty = dirty;
        } else {
            self.rd_dirty = dirty;
        }
    }
}

/// The data of one ESC access: the buffer a read fills or the bytes a write sends.
enum Data<'a> {
    Read(&'a mut [u8]),
    Write(&'a [u8]),
}

impl Data<'_> {
    fn len(&self) -> usize {
        match self {
            Data::Read(b) => b.len(),
            Data::Write(d) => d.len(),
        }
    }
}

/// Address bytes of an instruction: big-endian, bits 15:14 zero.
const fn addr_bytes(addr: u16) -> [u8; 2] {
    [((addr >> 8) & 0x3F) as u8, addr as u8]
}

/// Largest CSR access size (4, 2 or 1) that is naturally aligned at `addr` and not
/// longer than `remaining`.
const fn csr_chunk(addr: u16, remaining: usize) -> usize {
    if addr.is_multiple_of(4) && remaining >= 4 {
        4
    } else if addr.is_multiple_of(2) && remaining >= 2 {
        2
    } else {
        1
    }
}

/// Checks that `[addr, addr + len)` lies in the LAN9252's ESC address space and
/// returns the length of the register part (below 0x1000).
fn split(addr: u16, len: usize) -> Result<usize, EscError> {
    if (addr as usize).saturating_add(len) > ESC_END as usize {
        return Err(EscError::OutOfRange);
    }
    Ok(if addr < PRAM_START {
        len.min((PRAM_START - addr) as usize)
    } else {
        0
    })
}

impl<SPI: SpiDevice> EscAccess for Lan9252<SPI> {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        let regs = split(addr, buf.len())?;
        let (r, p) = buf.split_at_mut(regs);
        if !r.is_empty() {
            self.csr(addr, Data::Read(r))?;
        }
        if !p.is_empty() {
            self.pram(addr + regs as u16, Data::Read(p))?;
        }
        Ok(())
    }

    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        let regs = split(addr, data.len())?;
        let (r, p) = data.split_at(regs);
        if !r.is_empty() {
            self.csr(addr, Data::Write(r))?;
        }
        if !p.is_empty() {
            self.pram(addr + regs as u16, Data::Write(p))?;
        }
        Ok(())
    }
}
