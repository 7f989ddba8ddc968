//! The copy plan of the cyclic path: the assigned maps compiled into (slot, bit
//! offset, bits) entries, and the bit copies between the process image and the
//! application ([`unpack`], [`pack`]).

use super::{ProcessData, MAX_PLAN_ENTRIES};

/// One mapped entry of a plan.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PlanEntry {
    /// Application slot.
    pub slot: u16,
    /// Bit offset in the process image.
    pub bit_offset: u16,
    /// Length in bits (1-64).
    pub bits: u8,
}

/// The compiled plan of one direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DirPlan {
    pub(super) entries: [PlanEntry; MAX_PLAN_ENTRIES],
    pub(super) n: u8,
    pub(super) bytes: u16,
}

impl DirPlan {
    /// No entries, 0 bytes.
    pub const EMPTY: DirPlan = DirPlan {
        entries: [PlanEntry {
            slot: 0,
            bit_offset: 0,
            bits: 0,
        }; MAX_PLAN_ENTRIES],
        n: 0,
        bytes: 0,
    };
    /// The mapped entries (padding excluded).
    pub fn entries(&self) -> &[PlanEntry] {
        &self.entries[..(self.n as usize).min(MAX_PLAN_ENTRIES)]
    }
    /// Size of the process image in bytes.
    pub const fn bytes(&self) -> u16 {
        self.bytes
    }
}

/// The compiled plans of both directions.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CopyPlan {
    /// RxPDO (SM2 → application).
    pub rx: DirPlan,
    /// TxPDO (application → SM3).
    pub tx: DirPlan,
}

impl CopyPlan {
    /// Nothing mapped.
    pub const EMPTY: CopyPlan = CopyPlan {
        rx: DirPlan::EMPTY,
        tx: DirPlan::EMPTY,
    };
}

#[inline]
pub(super) fn mask(bits: u8) -> u64 {
    if bits >= 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    }
}

/// Extracts `bits` bits at `bit_offset` (little-endian bit order) from `data`; bytes
/// beyond `data` read as 0.
#[inline(always)]
pub fn extract(data: &[u8], bit_offset: u16, bits: u8) -> u64 {
    let byte = (bit_offset / 8) as usize;
    let shift = (bit_offset % 8) as u32;
    if shift == 0 {
        // Byte-aligned 8/16/32-bit entries: direct loads, the common case.
        match bits {
            8 => {
                if let Some(v) = data.get(byte) {
                    return *v as u64;
                }
            }
            16 => {
                if let Some(&[a, b]) = data.get(byte..byte + 2) {
                    return u16::from_le_bytes([a, b]) as u64;
                }
            }
            32 => {
                if let Some(&[a, b, c, d]) = data.get(byte..byte + 4) {
                    return u32::from_le_bytes([a, b, c, d]) as u64;
                }
            }
            _ => {}
        }
    }
    extract_bits(data, bit_offset, bits)
}

/// [`extract`] for any offset and length: out of line, so that the byte-aligned
/// fast path stays small enough to inline into the copy loops.
// Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path attributes
// the image grew 1184 B; this and `insert_bits` inline into the cyclic copy, +204 B.
#[inline(never)]
fn extract_bits(data: &[u8], bit_offset: u16, bits: u8) -> u64 {
    let byte = (bit_offset / 8) as usize;
    let shift = (bit_offset % 8) as u32;
    let mut b = [0u8; 16];
    let end = (byte + 9).min(data.len());
    if byte < end {
        b[..end - byte].copy_from_slice(&data[byte..end]);
    }
    let lo = u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]);
    let v = if shift == 0 {
        lo
    } else {
        (lo >> shift) | ((b[8] as u64) << (64 - shift))
    };
    v & mask(bits)
}

/// Inserts the low `bits` bits of `value` at `bit_offset` into `data`; bits beyond
/// `data` are dropped, the other bits of `data` are kept.
#[inline(always)]
pub fn insert(data: &mut [u8], bit_offset: u16, bits: u8, value: u64) {
    let byte = (bit_offset / 8) as usize;
    let shift = (bit_offset % 8) as u32;
    if shift == 0 {
        match bits {
            8 => {
                if let Some(d) = data.get_mut(byte) {
                    *d = value as u8;
                    return;
                }
            }
            16 => {
                if let Some(d) = data.get_mut(byte..byte + 2) {
                    d.copy_from_slice(&(value as u16).to_le_bytes());
                    return;
                }
            }
            32 => {
                if let Some(d) = data.get_mut(byte..byte + 4) {
                    d.copy_from_slice(&(value as u32).to_le_bytes());
                    return;
                }
            }
            _ => {}
        }
    }
    insert_bits(data, bit_offset, bits, value);
}

/// [`insert`] for any offset and length (out of line, as [`extract_bits`]).
// Measured (cargo xtask size, LAN9252 image): dropped with the other hot-path attributes
// the image grew 1184 B; see `extract_bits`.
#[inline(never)]
fn insert_bits(data: &mut [u8], bit_offset: u16, bits: u8, value: u64) {
    let byte = (bit_offset / 8) as usize;
    let shift = (bit_offset % 8) as u32;
    let m = mask(bits);
    let v = value & m;
    for k in 0..=(bits as u32 + shift).div_ceil(8) as usize {
        let Some(d) = data.get_mut(byte + k) else {
            break;
        };
        let pos = (k as i32) * 8 - shift as i32;
        let (mk, vk) = if pos >= 0 {
            let p = pos as u32;
            (
                m.checked_shr(p).unwrap_or(0) as u8,
                v.checked_shr(p).unwrap_or(0) as u8,
            )
        } else {
            (
                ((m << (-pos) as u32) & 0xFF) as u8,
                ((v << (-pos) as u32) & 0xFF) as u8,
            )
        };
        *d = (*d & !mk) | vk;
    }
}

/// Copies the outputs of `sm2` into the application through the plan.
#[inline]
pub fn unpack<P: ProcessData + ?Sized>(plan: &DirPlan, sm2: &[u8], app: &mut P) {
    for e in plan.entries() {
        app.set_rx(e.slot, extract(sm2, e.bit_offset, e.bits));
    }
}

/// Copies the application's inputs into `sm3` through the plan (padding bits keep
/// their contents: zero the buffer once).
#[inline]
pub fn pack<P: ProcessData + ?Sized>(plan: &DirPlan, app: &P, sm3: &mut [u8]) {
    for e in plan.entries() {
        insert(sm3, e.bit_offset, e.bits, app.get_tx(e.slot));
    }
}
