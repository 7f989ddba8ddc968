//! SPI-level model of the LAN9252 host interface (SPI mode).
//!
//! Decodes `03 AH AL data…` (serial read), `0B AH AL DD data…` (fast read, one dummy
//! byte) and `02 AH AL data…` (serial write); the address is bits 13:0 of the two
//! address bytes. System registers are 32-bit little-endian words: a read latches the
//! word when its first byte is clocked out, a write takes effect when its fourth byte
//! arrives (a partial word is dropped and recorded as a violation). In the FIFO ports
//! (0x000-0x01F read, 0x020-0x03F write) the address does not advance: every 4 bytes
//! pop or push one FIFO word.
//!
//! Behind the CSR window and the PRAM FIFOs sits the ESC memory `B`. The model checks
//! what the chip requires: CSR size 1/2/4 and natural alignment, no CSR data access
//! while the command is busy, PRAM ranges inside 0x1000-0x1FFF, no FIFO underrun or
//! overrun. *Model choices*: a CSR access executes at once and then reports busy for
//! `faults.csr_busy_polls` reads of ECAT_CSR_CMD; after a digital reset the next
//! `faults.reset_busy_reads` register reads return 0 (chip not yet accessible); the
//! read FIFO is refilled from process RAM whenever it is polled or popped, up to
//! `faults.fifo_words` words.
//!
//! *Write completion*: after the last word of a PRAM write has been pushed, the write
//! unit stays busy (ECAT_PRAM_WR_CMD bit 31) for `faults.pram_write_busy_reads`
//! further reads of ECAT_PRAM_WR_CMD (default 2: the chip still moves the FIFO into
//! process RAM; its real duration is not published, so the model counts the polls
//! instead of time, and a driver must poll for it), or for ever with
//! `faults.pram_write_stuck_busy`.
//!
//! *Refused* (recorded as violations), because no reference driver relies on them:
//! writing ECAT_PRAM_RD/WR_ADDR_LEN or starting a transfer while that unit is busy
//! (the abort bit is always accepted), and a register access of more than one 32-bit
//! word outside the FIFO ports (the model does not assume that the address
//! auto-increments there).

use std::collections::VecDeque;

use ecat_slave_stack::lan9252::{self as chip, reg};
use ecat_slave_stack::EscAccess;
use embedded_hal::spi::{ErrorType, Operation, SpiDevice};

use super::{model_transaction, ByteDevice, ModelBusError, Transaction};

/// ID_REV value of the model (chip ID 0x9252, revision 1).
pub const MODEL_ID_REV: u32 = 0x9252_0001;

/// Injected faults and timing choices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Lan9252Faults {
    /// No chip: MISO floats high, nothing is decoded.
    pub absent: bool,
    /// BYTE_TEST reads this instead of 0x87654321.
    pub byte_test: Option<u32>,
    /// HW_CFG READY never sets.
    pub never_ready: bool,
    /// Reads of ECAT_CSR_CMD that still show busy after a command.
    pub csr_busy_polls: u32,
    /// ECAT_CSR_CMD busy never clears.
    pub csr_stuck_busy: bool,
    /// The PRAM FIFOs never report data / space.
    pub fifo_never_ready: bool,
    /// Most words the read FIFO holds / the write FIFO reports free (1-16).
    pub fifo_words: usize,
    /// Register reads returning 0 after a digital reset.
    pub reset_busy_reads: u32,
    /// Reads of ECAT_PRAM_WR_CMD that still show busy after the last word of a write.
    pub pram_write_busy_reads: u32,
    /// The write unit never finishes (busy stays set after the last word).
    pub pram_write_stuck_busy: bool,
    /// The next transaction fails with a bus error (cleared when used).
    pub fail_next: bool,
}

impl Default for Lan9252Faults {
    fn default() -> Self {
        Lan9252Faults {
            absent: false,
            byte_test: None,
            never_ready: false,
            csr_busy_polls: 1,
            csr_stuck_busy: false,
            fifo_never_ready: false,
            fifo_words: chip::FIFO_WORDS,
            reset_busy_reads: 2,
            pram_write_busy_reads: 2,
            pram_write_stuck_busy: false,
            fail_next: false,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    Instr,
    AddrHi,
    AddrLo,
    Dummy,
    Data,
    Ignore,
}

#[derive(Debug, Clone, Default)]
struct Pram {
    active: bool,
    addr: u16,
    len: usize,
    lead: usize,
    total_words: usize,
    moved: usize,
    fifo: VecDeque<u32>,
    /// Write unit: status reads left that still show busy after the last word.
    settling: u32,
}

impl Pram {
    fn start(&mut self, addr_len: u32) -> Result<(), String> {
        let addr = addr_len as u16;
        let len = (addr_len >> 16) as usize;
        *self = Pram::default();
        if addr < chip::PRAM_START || addr as usize + len > chip::ESC_END as usize || len == 0 {
            return Err(format!(
                "PRAM transfer outside process RAM: addr {addr:#06x} len {len}"
            ));
        }
        self.active = true;
        self.addr = addr;
        self.len = len;
        self.lead = (addr & 3) as usize;
        self.total_words = (self.lead + len).div_ceil(4);
        Ok(())
    }
    /// Data bytes of stream word `w`: (lane, ESC address) of each valid lane.
    fn lanes(&self, w: usize) -> impl Iterator<Item = (usize, u16)> + '_ {
        (0..4).filter_map(move |lane| {
            let s = w * 4 + lane;
            (s >= self.lead && s - self.lead < self.len)
                .then(|| (lane, self.addr + (s - self.lead) as u16))
        })
    }
}

/// The LAN9252 model.
pub struct Lan9252Model<B> {
    /// The ESC memory behind the CSR window and the FIFOs.
    pub esc: B,
    /// Every transaction.
    pub log: Vec<Transaction>,
    /// Protocol violations seen.
    pub violations: Vec<String>,
    /// Injected faults.
    pub faults: Lan9252Faults,
    /// Digital resets seen.
    pub digital_resets: u32,
    /// EtherCAT-core resets seen.
    pub ecat_resets: u32,
    /// IRQ_CFG.
    pub irq_cfg: u32,
    /// INT_EN.
    pub int_en: u32,
    csr_data: u32,
    csr_cmd: u32,
    csr_busy_left: u32,
    rd_addr_len: u32,
    wr_addr_len: u32,
    rd: Pram,
    wr: Pram,
    reset_reads_left: u32,
    // Transaction decoding.
    phase: Phase,
    instr: u8,
    addr: u16,
    index: usize,
    latched_word: Option<u16>,
    latch: [u8; 4],
    acc: [u8; 4],
    acc_n: usize,
}

impl<B: EscAccess> Lan9252Model<B> {
    /// A LAN9252 in front of `esc`, no faults.
    pub fn new(esc: B) -> Self {
        Lan9252Model {
            esc,
            log: Vec::new(),
            violations: Vec::new(),
            faults: Lan9252Faults::default(),
            digital_resets: 0,
            ecat_resets: 0,
            irq_cfg: 0,
            int_en: 0,
            csr_data: 0,
            csr_cmd: 0,
            csr_busy_left: 0,
            rd_addr_len: 0,
            wr_addr_len: 0,
            rd: Pram::default(),
            wr: Pram::default(),
            reset_reads_left: 0,
            phase: Phase::Instr,
            instr: 0,
            addr: 0,
            index: 0,
            latched_word: None,
            latch: [0; 4],
            acc: [0; 4],
            acc_n: 0,
        }
    }

    /// MOSI bytes of every transaction recorded since `from`.
    pub fn mosi_since(&self, from: usize) -> Vec<Vec<u8>> {
        self.log[from.min(self.log.len())..]
            .iter()
            .map(|t| t.mosi.clone())
            .collect()
    }

    fn violation(&mut self, s: String) {
        self.violations.push(s);
    }

    fn esc_read(&mut self, addr: u16, buf: &mut [u8]) {
        if let Err(e) = self.esc.read(addr, buf) {
            self.violation(format!("ESC read {addr:#06x}+{} failed: {e:?}", buf.len()));
        }
    }

    fn esc_write(&mut self, addr: u16, data: &[u8]) {
        if let Err(e) = self.esc.write(addr, data) {
            self.violation(format!(
                "ESC write {addr:#06x}+{} failed: {e:?}",
                data.len()
            ));
        }
    }

    fn fill_read_fifo(&mut self) {
        if self.faults.fifo_never_ready {
            return;
        }
        let cap = self.faults.fifo_words.clamp(1, chip::FIFO_WORDS);
        while self.rd.active && self.rd.fifo.len() < cap && self.rd.moved < self.rd.total_words {
            let w = self.rd.moved;
            let lanes: Vec<(usize, u16)> = self.rd.lanes(w).collect();
            let mut word = [0u8; 4];
            if let (Some(&(l0, a0)), Some(&(l1, _))) = (lanes.first(), lanes.last()) {
                let mut tmp = vec![0u8; l1 - l0 + 1];
                self.esc_read(a0, &mut tmp);
                word[l0..=l1].copy_from_slice(&tmp);
            }
            self.rd.fifo.push_back(u32::from_le_bytes(word));
            self.rd.moved += 1;
        }
    }

    /// The write unit is busy: a transfer running or its data still being moved.
    fn wr_busy(&self) -> bool {
        self.wr.active || self.wr.settling > 0
    }

    fn pram_status(&mut self, write: bool) -> u32 {
        let busy = if write {
            let b = self.wr_busy();
            if !self.wr.active && self.wr.settling > 0 && !self.faults.pram_write_stuck_busy {
                self.wr.settling -= 1;
            }
            b
        } else {
            self.rd.active
        };
        let mut v = if busy { chip::PRAM_BUSY } else { 0 };
        let count = if self.faults.fifo_never_ready {
            0
        } else if write {
            if self.wr.active {
                self.faults
                    .fifo_words
                    .clamp(1, chip::FIFO_WORDS)
                    .min(self.wr.total_words - self.wr.moved)
            } else {
                0
            }
        } else {
            self.fill_read_fifo();
            self.rd.fifo.len()
        };
        if count > 0 {
            v |= chip::PRAM_AVAIL | ((count as u32) << chip::PRAM_COUNT_SHIFT);
        }
        v
    }

    fn read_reg(&mut self, a: u16) -> u32 {
        if self.reset_reads_left > 0 {
            self.reset_reads_left -= 1;
            return 0;
        }
        match a {
            0x000..=0x01F => {
                self.fill_read_fifo();
                match self.rd.fifo.pop_front() {
                    Some(v) => {
                        if self.rd.moved == self.rd.total_words && self.rd.fifo.is_empty() {
                            self.rd.active = false;
                        }
                        v
                    }
                    None => {
                        self.violation("read FIFO underrun".into());
                        0
                    }
                }
            }
            reg::ID_REV => MODEL_ID_REV,
            reg::IRQ_CFG => self.irq_cfg,
            reg::INT_STS => {
                let mut m = [0u8; 4];
                let mut r = [0u8; 4];
                self.esc_read(ecat_slave_stack::registers::AL_EVENT_MASK.addr(), &mut m);
                self.esc_read(ecat_slave_stack::registers::AL_EVENT_REQUEST.addr(), &mut r);
                (u32::from_le_bytes(m) & u32::from_le_bytes(r) != 0) as u32
            }
            reg::INT_EN => self.int_en,
            reg::BYTE_TEST => self.faults.byte_test.unwrap_or(chip::BYTE_TEST_VALUE),
            reg::HW_CFG => {
                if self.faults.never_ready {
                    0
                } else {
                    chip::HW_CFG_READY
                }
            }
            reg::RESET_CTL => 0,
            reg::ECAT_CSR_DATA => {
                if self.csr_busy_left > 0 || self.faults.csr_stuck_busy {
                    self.violation("ECAT_CSR_DATA read while CSR busy".into());
                }
                self.csr_data
            }
            reg::ECAT_CSR_CMD => {
                let busy = self.faults.csr_stuck_busy || self.csr_busy_left > 0;
                self.csr_busy_left = self.csr_busy_left.saturating_sub(1);
                (self.csr_cmd & !chip::CSR_BUSY) | if busy { chip::CSR_BUSY } else { 0 }
            }
            reg::PRAM_RD_ADDR_LEN => self.rd_addr_len,
            reg::PRAM_RD_CMD => self.pram_status(false),
            reg::PRAM_WR_ADDR_LEN => self.wr_addr_len,
            reg::PRAM_WR_CMD => self.pram_status(true),
            _ => {
                self.violation(format!("read of unmodelled register {a:#05x}"));
                0
            }
        }
    }

    fn csr_command(&mut self, v: u32) {
        self.csr_cmd = v;
        if v & chip::CSR_BUSY == 0 {
            return;
        }
        let size = ((v >> chip::CSR_SIZE_SHIFT) & 7) as usize;
        let addr = v as u16;
        if !matches!(size, 1 | 2 | 4) {
            self.violation(format!("CSR size {size}"));
            return;
        }
        if !(addr as usize).is_multiple_of(size) {
            self.violation(format!(
                "CSR access of {size} bytes at unaligned {addr:#06x}"
            ));
        }
        if v & chip::CSR_READ != 0 {
            let mut b = [0u8; 4];
            self.esc_read(addr, &mut b[..size]);
            self.csr_data = u32::from_le_bytes(b);
        } else {
            let b = self.csr_data.to_le_bytes();
            self.esc_write(addr, &b[..size]);
        }
        self.csr_busy_left = self.faults.csr_busy_polls;
    }

    /// A word into the PRAM write FIFO (0x020-0x03F).
    fn write_fifo(&mut self, v: u32) {
        if !self.wr.active || self.wr.moved >= self.wr.total_words {
            self.violation("write FIFO overrun (no PRAM write active)".into());
            return;
        }
        let w = self.wr.moved;
        let lanes: Vec<(usize, u16)> = self.wr.lanes(w).collect();
        if let (Some(&(l0, a0)), Some(&(l1, _))) = (lanes.first(), lanes.last()) {
            let b = v.to_le_bytes();
            self.esc_write(a0, &b[l0..=l1]);
        }
        self.wr.moved += 1;
        if self.wr.moved == self.wr.total_words {
            self.wr.active = false;
            self.wr.settling = if self.faults.pram_write_stuck_busy {
                1
            } else {
                self.faults.pram_write_busy_reads
            };
        }
    }

    /// RESET_CTL written: a digital reset clears the PDI side, an EtherCAT reset is
    /// counted.
    fn reset(&mut self, v: u32) {
        if v & chip::RESET_DIGITAL != 0 {
            self.digital_resets += 1;
            self.irq_cfg = 0;
            self.int_en = 0;
            self.rd = Pram::default();
            self.wr = Pram::default();
            self.csr_busy_left = 0;
            self.reset_reads_left = self.faults.reset_busy_reads;
        }
        if v & chip::RESET_ETHERCAT != 0 {
            self.ecat_resets += 1;
        }
    }

    fn write_reg(&mut self, a: u16, v: u32) {
        match a {
            0x020..=0x03F => self.write_fifo(v),
            reg::IRQ_CFG => self.irq_cfg = v,
            reg::INT_EN => self.int_en = v,
            reg::RESET_CTL => self.reset(v),
            reg::ECAT_CSR_DATA => {
                if self.csr_busy_left > 0 || self.faults.csr_stuck_busy {
                    self.violation("ECAT_CSR_DATA written while CSR busy".into());
                }
                self.csr_data = v;
            }
            reg::ECAT_CSR_CMD => self.csr_command(v),
            reg::PRAM_RD_ADDR_LEN => {
                if self.rd.active {
                    self.violation("ECAT_PRAM_RD_ADDR_LEN written while the read is busy".into());
                }
                self.rd_addr_len = v
            }
            reg::PRAM_WR_ADDR_LEN => {
                if self.wr_busy() {
                    self.violation("ECAT_PRAM_WR_ADDR_LEN written while the write is busy".into());
                }
                self.wr_addr_len = v
            }
            reg::PRAM_RD_CMD => {
                if v & chip::PRAM_ABORT != 0 {
                    self.rd = Pram::default();
                } else if v & chip::PRAM_BUSY != 0 {
                    if self.rd.active {
                        self.violation("PRAM read started while the read is busy".into());
                    }
                    if let Err(e) = self.rd.start(self.rd_addr_len) {
                        self.violation(e);
                    }
                }
            }
            reg::PRAM_WR_CMD => {
                if v & chip::PRAM_ABORT != 0 {
                    self.wr = Pram::default();
                } else if v & chip::PRAM_BUSY != 0 {
                    if self.wr_busy() {
                        self.violation("PRAM write started while the write is busy".into());
                    }
                    if let Err(e) = self.wr.start(self.wr_addr_len) {
                        self.violation(e);
                    }
                }
            }
            _ => self.violation(format!("write of unmodelled register {a:#05x} = {v:#010x}")),
        }
    }

    /// (word address, lane) of data byte `i` of the current transaction; `None` for a
    /// byte beyond the first register word outside the FIFO ports (refused: no
    /// address auto-increment is assumed there).
    fn locate(&self, i: usize) -> Option<(u16, usize, bool)> {
        let fifo = self.addr < 0x040;
        if fifo {
            Some((self.addr & !3, i % 4, true))
        } else {
            let a = self.addr.wrapping_add(i as u16) & 0x3FFF;
            (a & !3 == self.addr & !3).then_some((a & !3, (a & 3) as usize, false))
        }
    }
}

impl<B: EscAccess> ByteDevice for Lan9252Model<B> {
    fn take_injected_failure(&mut self) -> bool {
        std::mem::take(&mut self.faults.fail_next)
    }
    fn log(&mut self) -> &mut Vec<Transaction> {
        &mut self.log
    }
    fn begin(&mut self) {
        self.phase = Phase::Instr;
        self.index = 0;
        self.latched_word = None;
        self.acc_n = 0;
    }

    fn exchange(&mut self, mosi: u8) -> u8 {
        if self.faults.absent {
            return 0xFF;
        }
        match self.phase {
            Phase::Instr => {
                self.instr = mosi;
                self.phase = match mosi {
                    chip::cmd::SERIAL_READ | chip::cmd::FAST_READ | chip::cmd::SERIAL_WRITE => {
                        Phase::AddrHi
                    }
                    _ => {
                        self.violation(format!("unsupported instruction {mosi:#04x}"));
                        Phase::Ignore
                    }
                };
                0
            }
            Phase::AddrHi => {
                self.addr = ((mosi as u16) << 8) & 0x3F00;
                self.phase = Phase::AddrLo;
                0
            }
            Phase::AddrLo => {
                self.addr |= mosi as u16;
                self.phase = if self.instr == chip::cmd::FAST_READ {
                    Phase::Dummy
                } else {
                    Phase::Data
                };
                0
            }
            Phase::Dummy => {
                self.phase = Phase::Data;
                0
            }
            Phase::Data => {
                let i = self.index;
                self.index += 1;
                let Some((word, lane, fifo)) = self.locate(i) else {
                    self.violation(format!(
                        "access of more than one register word at {:#05x} (outside the FIFO ports)",
                        self.addr
                    ));
                    self.phase = Phase::Ignore;
                    return 0;
                };
                if self.instr == chip::cmd::SERIAL_WRITE {
                    if lane != self.acc_n {
                        self.violation(format!("write to {word:#05x} does not start at byte 0"));
                        self.acc_n = lane;
                    }
                    self.acc[lane] = mosi;
                    self.acc_n = lane + 1;
                    if lane == 3 {
                        self.acc_n = 0;
                        self.write_reg(word, u32::from_le_bytes(self.acc));
                    }
                    0
                } else {
                    let new_word = if fifo {
                        lane == 0 || self.latched_word.is_none()
                    } else {
                        self.latched_word != Some(word)
                    };
                    if new_word {
                        self.latch = self.read_reg(word).to_le_bytes();
                        self.latched_word = Some(word);
                    }
                    self.latch[lane]
                }
            }
            Phase::Ignore => 0,
        }
    }

    fn end(&mut self) {
        if self.phase == Phase::Data && self.instr == chip::cmd::SERIAL_WRITE && self.acc_n != 0 {
            self.violation(format!(
                "partial register write ({} bytes) dropped",
                self.acc_n
            ));
        }
        if matches!(self.phase, Phase::AddrHi | Phase::AddrLo | Phase::Dummy) {
            self.violation("transaction ended inside the instruction header".into());
        }
    }
}

impl<B> ErrorType for Lan9252Model<B> {
    type Error = ModelBusError;
}

impl<B: EscAccess> SpiDevice for Lan9252Model<B> {
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), ModelBusError> {
        model_transaction(self, operations)
    }
}
