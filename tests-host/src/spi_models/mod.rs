//! SPI-level models of the two ESCs: [`Lan9252Model`] and [`Et1100Model`].
//!
//! Each model implements embedded-hal 1.0 [`SpiDevice`](embedded_hal::spi::SpiDevice)
//! and decodes the byte stream of every transaction exactly as the chip's SPI slave
//! does (instruction/command, address phase, dummy and wait-state bytes, data phase),
//! while the ESC memory behind it is any [`EscAccess`] — a plain [`RamEsc`] in driver
//! tests, or the frame-level simulator's PDI side, so "SPI model + driver + ESC
//! simulator" compose into one stack.
//!
//! Every transaction is recorded ([`Transaction`]: MOSI and MISO bytes, delays) so the
//! tests can check a driver byte by byte, and every protocol rule the model can check
//! (read termination, wait-state byte, CSR size/alignment, FIFO under/overrun, partial
//! register writes, unknown instructions) is recorded in `violations` instead of
//! panicking. Faults (wrong BYTE_TEST, stuck busy bits, a FIFO that never becomes
//! ready, an absent chip, a failing bus) are injected through the models' `faults`.
//!
//! `Operation::Read` is modelled as MOSI = 0x00 (what most HALs send); drivers that
//! need defined MOSI bytes while reading (the ET1100's read termination) must use
//! `Transfer`/`TransferInPlace`.

mod et1100;
mod lan9252;

pub use et1100::{Et1100Faults, Et1100Model};
pub use lan9252::{Lan9252Faults, Lan9252Model, MODEL_ID_REV};

use ecat_slave_stack::{EscAccess, EscError};
use embedded_hal::spi::{ErrorKind, Operation};

/// One SPI transaction as seen on the wires (chip select low to high).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Transaction {
    /// Bytes sent by the master.
    pub mosi: Vec<u8>,
    /// Bytes sent by the chip.
    pub miso: Vec<u8>,
    /// `(byte position, ns)` of every delay operation.
    pub delays: Vec<(usize, u32)>,
}

/// The error a model returns when a bus fault is injected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelBusError;

impl embedded_hal::spi::Error for ModelBusError {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

/// A chip's byte-level SPI slave: called for every byte with chip select low.
pub(crate) trait ByteDevice {
    /// Chip select went low.
    fn begin(&mut self);
    /// One byte: MOSI in, MISO out.
    fn exchange(&mut self, mosi: u8) -> u8;
    /// A delay operation between two bytes.
    fn delay(&mut self, _ns: u32) {}
    /// Chip select went high.
    fn end(&mut self);
    /// Whether the next transaction is to fail (an injected fault); clears the request.
    fn take_injected_failure(&mut self) -> bool;
    /// The log of the transactions run so far.
    fn log(&mut self) -> &mut Vec<Transaction>;
}

/// One `SpiDevice` transaction of a chip model: refused when a failure was injected,
/// else run through [`run_transaction`] and appended to the model's log.
pub(crate) fn model_transaction<D: ByteDevice>(
    dev: &mut D,
    ops: &mut [Operation<'_, u8>],
) -> Result<(), ModelBusError> {
    if dev.take_injected_failure() {
        return Err(ModelBusError);
    }
    let mut log = std::mem::take(dev.log());
    run_transaction(dev, &mut log, ops);
    *dev.log() = log;
    Ok(())
}

/// Runs the operations of one transaction through `dev` and records it.
pub(crate) fn run_transaction<D: ByteDevice>(
    dev: &mut D,
    log: &mut Vec<Transaction>,
    ops: &mut [Operation<'_, u8>],
) {
    let mut t = Transaction::default();
    dev.begin();
    let xfer = |dev: &mut D, t: &mut Transaction, mosi: u8| {
        let miso = dev.exchange(mosi);
        t.mosi.push(mosi);
        t.miso.push(miso);
        miso
    };
    for op in ops.iter_mut() {
        match op {
            Operation::Write(w) => {
                for b in w.iter() {
                    xfer(dev, &mut t, *b);
                }
            }
            Operation::Read(r) => {
                for b in r.iter_mut() {
                    *b = xfer(dev, &mut t, 0x00);
                }
            }
            Operation::Transfer(r, w) => {
                for i in 0..r.len().max(w.len()) {
                    let miso = xfer(dev, &mut t, w.get(i).copied().unwrap_or(0x00));
                    if let Some(x) = r.get_mut(i) {
                        *x = miso;
                    }
                }
            }
            Operation::TransferInPlace(buf) => {
                for b in buf.iter_mut() {
                    *b = xfer(dev, &mut t, *b);
                }
            }
            Operation::DelayNs(ns) => {
                t.delays.push((t.mosi.len(), *ns));
                dev.delay(*ns);
            }
        }
    }
    dev.end();
    log.push(t);
}

/// A flat 64 KiB ESC address space with no side effects, for driver tests.
#[derive(Debug, Clone)]
pub struct RamEsc {
    /// The memory.
    pub mem: Vec<u8>,
    /// Number of read calls.
    pub reads: usize,
    /// Every write call: address and data.
    pub writes: Vec<(u16, Vec<u8>)>,
}

impl RamEsc {
    /// Zeroed memory.
    pub fn new() -> Self {
        RamEsc {
            mem: vec![0; 0x10000],
            reads: 0,
            writes: Vec::new(),
        }
    }
    /// Memory filled with a pattern that differs at every address (`addr * 7 + 3`).
    pub fn patterned() -> Self {
        let mut r = Self::new();
        for (i, b) in r.mem.iter_mut().enumerate() {
            *b = (i as u32).wrapping_mul(7).wrapping_add(3) as u8;
        }
        r
    }
}

impl Default for RamEsc {
    fn default() -> Self {
        Self::new()
    }
}

impl EscAccess for RamEsc {
    fn read(&mut self, addr: u16, buf: &mut [u8]) -> Result<(), EscError> {
        let a = addr as usize;
        let src = self.mem.get(a..a + buf.len()).ok_or(EscError::OutOfRange)?;
        buf.copy_from_slice(src);
        self.reads += 1;
        Ok(())
    }
    fn write(&mut self, addr: u16, data: &[u8]) -> Result<(), EscError> {
        let a = addr as usize;
        self.mem
            .get_mut(a..a + data.len())
            .ok_or(EscError::OutOfRange)?
            .copy_from_slice(data);
        self.writes.push((addr, data.to_vec()));
        Ok(())
    }
}
