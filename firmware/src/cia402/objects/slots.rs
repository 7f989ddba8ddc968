//! The cyclic path of the CiA 402 objects: the PDO slot ids ([`RX_SLOTS`],
//! [`TX_SLOTS`], in table order) and the slot accessors of [`Cia402`].

use super::{u32_from_le_prefix, OBJECTS};
use crate::cia402::Cia402;
use ecat_slave_stack::od::ObjectKey;

/// Number of entries of [`OBJECTS`] mappable in the direction `rx` (else tx).
const fn mappable_count(rx: bool) -> usize {
    let mut n = 0;
    let mut o = 0;
    while o < OBJECTS.len() {
        let entries = OBJECTS[o].entries();
        let mut e = 0;
        while e < entries.len() {
            let pdo = entries[e].pdo_mappable();
            if (rx && pdo.rx()) || (!rx && pdo.tx()) {
                n += 1;
            }
            e += 1;
        }
        o += 1;
    }
    n
}

/// `(index, sub-index)` of the entries mappable in the direction `rx`, in table order.
const fn mappable_keys<const N: usize>(rx: bool) -> [(u16, u8); N] {
    let mut keys = [(0, 0); N];
    let mut n = 0;
    let mut o = 0;
    while o < OBJECTS.len() {
        let entries = OBJECTS[o].entries();
        let mut e = 0;
        while e < entries.len() {
            let pdo = entries[e].pdo_mappable();
            if (rx && pdo.rx()) || (!rx && pdo.tx()) {
                keys[n] = (OBJECTS[o].index, entries[e].sub());
                n += 1;
            }
            e += 1;
        }
        o += 1;
    }
    keys
}

const RX_SLOT_KEYS: [(u16, u8); mappable_count(true)] = mappable_keys(true);
const TX_SLOT_KEYS: [(u16, u8); mappable_count(false)] = mappable_keys(false);

/// RxPDO-mappable entries; the position in this table is the slot id.
pub const RX_SLOTS: &[(u16, u8)] = &RX_SLOT_KEYS;

/// TxPDO-mappable entries; the position in this table is the slot id.
pub const TX_SLOTS: &[(u16, u8)] = &TX_SLOT_KEYS;

const _: () = assert!(RX_SLOTS.len() <= 256 && TX_SLOTS.len() <= 256);

fn slot_of(table: &[(u16, u8)], index: u16, sub: u8) -> Option<u8> {
    table
        .iter()
        .position(|&e| e == (index, sub))
        .map(|i| i as u8)
}

/// Slot id of an RxPDO-mappable entry.
pub fn rx_slot(index: u16, sub: u8) -> Option<u8> {
    slot_of(RX_SLOTS, index, sub)
}

/// Slot id of a TxPDO-mappable entry.
pub fn tx_slot(index: u16, sub: u8) -> Option<u8> {
    slot_of(TX_SLOTS, index, sub)
}

impl Cia402 {
    /// Cyclic path: stores an RxPDO entry by slot id from its little-endian bytes
    /// (see [`Cia402::set_rx_raw`]).
    #[inline]
    pub fn set_rx(&mut self, slot: u8, data: &[u8]) {
        self.set_rx_raw(slot, u32_from_le_prefix(data));
    }
    /// Cyclic path: writes a TxPDO entry by slot id (little-endian, as many bytes as
    /// fit in `buf`, at most 4) and returns the number written.
    #[inline]
    pub fn get_tx(&self, slot: u8, buf: &mut [u8]) -> usize {
        let b = self.get_tx_raw(slot).to_le_bytes();
        let n = buf.len().min(4);
        buf[..n].copy_from_slice(&b[..n]);
        n
    }
}

/// The cyclic path of the stack: slots are the indices of [`RX_SLOTS`] / [`TX_SLOTS`].
/// (The drive's own `ProcessData` dispatches to these when it combines several
/// modules' objects.)
impl ecat_slave_stack::pdo::ProcessData for Cia402 {
    fn rx_slot(&self, key: ObjectKey) -> Option<u16> {
        rx_slot(key.index, key.sub).map(u16::from)
    }
    fn tx_slot(&self, key: ObjectKey) -> Option<u16> {
        tx_slot(key.index, key.sub).map(u16::from)
    }
    #[inline]
    fn set_rx(&mut self, slot: u16, raw: u64) {
        if let Ok(s) = u8::try_from(slot) {
            self.set_rx_raw(s, raw as u32);
        }
    }
    #[inline]
    fn get_tx(&self, slot: u16) -> u64 {
        u8::try_from(slot).map_or(0, |s| self.get_tx_raw(s) as u64)
    }
}
