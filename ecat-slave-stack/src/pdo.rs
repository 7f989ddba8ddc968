//! Process data mapping: the objects 0x1600-0x1603, 0x1A00-0x1A03, 0x1C00, 0x1C12,
//! 0x1C13, their SDO rules, and the copy plan of the cyclic path.
//!
//! # Objects
//! * 0x1600-0x1603 RxPDO mapping, 0x1A00-0x1A03 TxPDO mapping (RECORD): sub-index 0
//!   is the number of entries (0-16), sub-indices 1-16 are `index << 16 | sub << 8 |
//!   bit length`; index 0 (sub-index 0) is a padding gap of the given length.
//! * 0x1C00 SM communication types (read-only: 1 mailbox out, 2 mailbox in,
//!   3 outputs, 4 inputs).
//! * 0x1C12 / 0x1C13 RxPDO / TxPDO assignment of SM2 / SM3: up to 4 map indices
//!   (0x1600-0x1603 resp. 0x1A00-0x1A03).
//!
//! # Write rules (CiA 301 / ETG.1020)
//! * Writable only in Pre-Op → else 0x08000022.
//! * An entry (sub-index ≥ 1) is writable only while sub-index 0 is 0 → else
//!   0x06010003. The value must name an existing entry of the product dictionary that is
//!   mappable in the map's direction and whose bit length is the mapped length →
//!   else 0x06040041 (a length that differs from the object's: 0x06040043); padding
//!   (index 0) must have sub-index 0 and a length of 1-64 bits.
//! * Writing sub-index 0 = n validates entries 1..n; a map longer than 64 bytes, or an
//!   assigned set of maps longer than 64 bytes per direction → 0x06040042.
//! * Assignment entries must be one of the four maps of the direction → 0x06090030;
//!   the same map twice → 0x06040043.
//!
//! # Cyclic path
//! On P→S the assigned maps are compiled into a [`CopyPlan`]: each mapped entry is
//! resolved once to an application slot ([`ProcessData::rx_slot`] /
//! [`ProcessData::tx_slot`]) and a bit offset. [`unpack`] and [`pack`] then only walk
//! that array: no dictionary lookups, no mapping decoding per cycle. Values travel as
//! raw little-endian bit patterns in a `u64`, zero-extended; the application knows
//! each slot's type and sign-extends where needed.

use crate::al_status::AlStatusCode;
use crate::esm::EsmState;
use crate::od::{self, Access, DataType, EntryDesc, Object, ObjectDesc, ObjectKey, SdoAbort};

mod copy;
pub use copy::{extract, insert, pack, unpack, CopyPlan, DirPlan, PlanEntry};

/// Entries per mapping object.
pub const MAX_ENTRIES: usize = 16;
/// Maps per direction.
pub const MAPS: usize = 4;
/// Process data bytes per direction.
pub const MAX_BYTES: usize = 64;
/// First RxPDO mapping object.
pub const RX_MAP_BASE: u16 = 0x1600;
/// First TxPDO mapping object.
pub const TX_MAP_BASE: u16 = 0x1A00;
/// SM communication types.
pub const SM_COMM_TYPE: u16 = 0x1C00;
/// RxPDO assignment (SM2).
pub const RX_ASSIGN: u16 = 0x1C12;
/// TxPDO assignment (SM3).
pub const TX_ASSIGN: u16 = 0x1C13;
/// Most mapped (non-padding) entries a plan can hold per direction.
pub const MAX_PLAN_ENTRIES: usize = MAX_ENTRIES * MAPS;

/// Direction of a map.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dir {
    /// RxPDO: outputs of the master, SM2.
    Rx,
    /// TxPDO: inputs of the master, SM3.
    Tx,
}

impl Dir {
    /// AL status code of an invalid mapping in this direction at P→S.
    pub const fn mapping_error(self) -> AlStatusCode {
        match self {
            Dir::Rx => AlStatusCode::InvalidOutputMapping,
            Dir::Tx => AlStatusCode::InvalidInputMapping,
        }
    }
}

/// The application side of the cyclic data.
///
/// Slots are the application's own numbering of the values it exchanges; they are
/// resolved once per P→S and then used on every cycle.
pub trait ProcessData {
    /// Slot receiving the RxPDO entry `key`, `None` if the application cannot take it
    /// (then the mapping is refused at P→S with 0x0025).
    fn rx_slot(&self, key: ObjectKey) -> Option<u16>;
    /// Slot providing the TxPDO entry `key`, `None` → 0x0024 at P→S.
    fn tx_slot(&self, key: ObjectKey) -> Option<u16>;
    /// Stores a received raw value (zero-extended little-endian bit pattern).
    fn set_rx(&mut self, slot: u16, raw: u64);
    /// The raw value to send (only the mapped number of low bits is used).
    fn get_tx(&self, slot: u16) -> u64;
}

/// One mapping object's contents.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Map {
    n: u8,
    e: [u32; MAX_ENTRIES],
}

impl Map {
    const EMPTY: Map = Map {
        n: 0,
        e: [0; MAX_ENTRIES],
    };
    fn from_slice(v: &[u32]) -> Map {
        let mut m = Map::EMPTY;
        let n = v.len().min(MAX_ENTRIES);
        m.e[..n].copy_from_slice(&v[..n]);
        m.n = n as u8;
        m
    }
    fn entries(&self) -> &[u32] {
        &self.e[..(self.n as usize).min(MAX_ENTRIES)]
    }
    fn bits(&self) -> u32 {
        self.entries().iter().map(|e| *e & 0xFF).sum()
    }
}

/// One assignment object's contents.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Assign {
    n: u8,
    e: [u16; MAPS],
}

impl Assign {
    fn from_slice(v: &[u16]) -> Assign {
        let mut a = Assign { n: 0, e: [0; MAPS] };
        let n = v.len().min(MAPS);
        a.e[..n].copy_from_slice(&v[..n]);
        a.n = n as u8;
        a
    }
    fn entries(&self) -> &[u16] {
        &self.e[..(self.n as usize).min(MAPS)]
    }
}

/// The product's default mapping and assignment (`docs/object-dictionary.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoDefaults {
    /// Contents of 0x1600-0x1603 (at most 16 entries each).
    pub rx: [&'static [u32]; MAPS],
    /// Contents of 0x1A00-0x1A03.
    pub tx: [&'static [u32]; MAPS],
    /// 0x1C12.
    pub rx_assign: &'static [u16],
    /// 0x1C13.
    pub tx_assign: &'static [u16],
}

impl PdoDefaults {
    /// Nothing mapped.
    pub const EMPTY: PdoDefaults = PdoDefaults {
        rx: [&[]; MAPS],
        tx: [&[]; MAPS],
        rx_assign: &[],
        tx_assign: &[],
    };
}

/// The mapping and assignment objects' values.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PdoConfig {
    rx: [Map; MAPS],
    tx: [Map; MAPS],
    rx_assign: Assign,
    tx_assign: Assign,
    defaults: PdoDefaults,
}

fn check_entry(value: u32, dir: Dir, objects: &'static [Object]) -> Result<(), SdoAbort> {
    let key = ObjectKey::from_mapping_word(value);
    let bits = (value & 0xFF) as u16;
    if key.index == 0 {
        return if key.sub == 0 && (1..=64).contains(&bits) {
            Ok(())
        } else {
            Err(SdoAbort::NotMappable)
        };
    }
    let e = od::find_entry(objects, key).map_err(|_| SdoAbort::NotMappable)?;
    let ok = match dir {
        Dir::Rx => e.pdo_mappable().rx(),
        Dir::Tx => e.pdo_mappable().tx(),
    };
    if !ok || e.bits() == 0 || e.bits() > 64 {
        return Err(SdoAbort::NotMappable);
    }
    if e.bits() != bits {
        return Err(SdoAbort::ParameterIncompatibility);
    }
    Ok(())
}

fn write_u8(buf: &mut [u8], v: u8) -> Result<usize, SdoAbort> {
    let b = buf.get_mut(0).ok_or(SdoAbort::ExceedsMailbox)?;
    *b = v;
    Ok(1)
}

fn write_le(buf: &mut [u8], v: &[u8]) -> Result<usize, SdoAbort> {
    let dst = buf.get_mut(..v.len()).ok_or(SdoAbort::ExceedsMailbox)?;
    dst.copy_from_slice(v);
    Ok(v.len())
}

/// `data` as exactly `N` bytes, else the length-too-high/too-low abort.
pub(crate) fn exact<const N: usize>(data: &[u8]) -> Result<[u8; N], SdoAbort> {
    if data.len() > N {
        return Err(SdoAbort::LengthTooHigh);
    }
    if data.len() < N {
        return Err(SdoAbort::LengthTooLow);
    }
    let mut b = [0u8; N];
    b.copy_from_slice(data);
    Ok(b)
}

impl PdoConfig {
    /// The defaults' contents.
    pub fn new(defaults: PdoDefaults) -> Self {
        let mut c = PdoConfig {
            rx: [Map::EMPTY; MAPS],
            tx: [Map::EMPTY; MAPS],
            rx_assign: Assign::from_slice(&[]),
            tx_assign: Assign::from_slice(&[]),
            defaults,
        };
        c.restore_defaults();
        c
    }

    /// Back to the product's defaults (0x1011 restore, power-up).
    pub fn restore_defaults(&mut self) {
        for i in 0..MAPS {
            self.rx[i] = Map::from_slice(self.defaults.rx[i]);
            self.tx[i] = Map::from_slice(self.defaults.tx[i]);
        }
        self.rx_assign = Assign::from_slice(self.defaults.rx_assign);
        self.tx_assign = Assign::from_slice(self.defaults.tx_assign);
    }

    fn maps(&self, dir: Dir) -> &[Map; MAPS] {
        match dir {
            Dir::Rx => &self.rx,
            Dir::Tx => &self.tx,
        }
    }
    fn assign(&self, dir: Dir) -> &Assign {
        match dir {
            Dir::Rx => &self.rx_assign,
            Dir::Tx => &self.tx_assign,
        }
    }

    /// The entries of map `index` (0x1600-0x1603, 0x1A00-0x1A03).
    pub fn map_entries(&self, index: u16) -> Option<&[u32]> {
        let (dir, i) = map_slot(index)?;
        Some(self.maps(dir)[i].entries())
    }

    /// The assigned maps of a direction.
    pub fn assigned(&self, dir: Dir) -> &[u16] {
        self.assign(dir).entries()
    }

    /// Total mapped bits of the assigned maps of `dir`.
    pub fn assigned_bits(&self, dir: Dir) -> u32 {
        self.assigned_bits_with(dir, None)
    }

    /// Process data bytes of `dir` (bits rounded up).
    pub fn assigned_bytes(&self, dir: Dir) -> u16 {
        self.assigned_bits(dir).div_ceil(8).min(u16::MAX as u32) as u16
    }

    fn assigned_bits_with(&self, dir: Dir, replace: Option<(usize, &Map)>) -> u32 {
        self.assign(dir)
            .entries()
            .iter()
            .filter_map(|idx| map_slot(*idx).filter(|(d, _)| *d == dir).map(|(_, i)| i))
            .map(|i| match replace {
                Some((r, m)) if r == i => m.bits(),
                _ => self.maps(dir)[i].bits(),
            })
            .sum()
    }

    /// Reads one entry of 0x1600-0x1603, 0x1A00-0x1A03, 0x1C00, 0x1C12, 0x1C13.
    pub fn read(&self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let ObjectKey { index, sub } = key;
        // (sub-index 0, entry length in bytes, entry `sub`): one answer path for all.
        let i = sub.wrapping_sub(1) as usize;
        let (n, len, v) = if let Some((dir, m)) = map_slot(index) {
            let m = &self.maps(dir)[m];
            (m.n, 4, m.e.get(i).copied())
        } else {
            match index {
                SM_COMM_TYPE => (4, 1, (1..=4).contains(&sub).then_some(sub as u32)),
                RX_ASSIGN | TX_ASSIGN => {
                    let a = if index == RX_ASSIGN {
                        &self.rx_assign
                    } else {
                        &self.tx_assign
                    };
                    (a.n, 2, a.e.get(i).map(|v| *v as u32))
                }
                _ => return Err(SdoAbort::ObjectDoesNotExist),
            }
        };
        if sub == 0 {
            return write_u8(buf, n);
        }
        let v = v.ok_or(SdoAbort::SubindexDoesNotExist)?;
        write_le(buf, &v.to_le_bytes()[..len])
    }

    /// Writes one entry (rules in the module docs). `objects` is the full product
    /// dictionary, used to check mappability.
    pub fn write(
        &mut self,
        key: ObjectKey,
        data: &[u8],
        state: EsmState,
        objects: &'static [Object],
    ) -> Result<(), SdoAbort> {
        let ObjectKey { index, sub } = key;
        if let Some((dir, i)) = map_slot(index) {
            return self.write_map(dir, i, sub, data, state, objects);
        }
        match index {
            SM_COMM_TYPE => {
                if sub > 4 {
                    Err(SdoAbort::SubindexDoesNotExist)
                } else {
                    Err(SdoAbort::WriteReadOnly)
                }
            }
            RX_ASSIGN => self.write_assign(Dir::Rx, sub, data, state),
            TX_ASSIGN => self.write_assign(Dir::Tx, sub, data, state),
            _ => Err(SdoAbort::ObjectDoesNotExist),
        }
    }

    /// Writes sub-index `sub` of the mapping object `i` of direction `dir`.
    fn write_map(
        &mut self,
        dir: Dir,
        i: usize,
        sub: u8,
        data: &[u8],
        state: EsmState,
        objects: &'static [Object],
    ) -> Result<(), SdoAbort> {
        if sub > MAX_ENTRIES as u8 {
            return Err(SdoAbort::SubindexDoesNotExist);
        }
        if state != EsmState::PreOp {
            return Err(SdoAbort::StateConflict);
        }
        if sub == 0 {
            let [n] = exact::<1>(data)?;
            if n as usize > MAX_ENTRIES {
                return Err(SdoAbort::ValueTooHigh);
            }
            let mut m = self.maps(dir)[i];
            m.n = n;
            for e in m.entries() {
                check_entry(*e, dir, objects)?;
            }
            if m.bits() > (MAX_BYTES * 8) as u32 {
                return Err(SdoAbort::PdoLengthExceeded);
            }
            if self.assigned_bits_with(dir, Some((i, &m))) > (MAX_BYTES * 8) as u32 {
                return Err(SdoAbort::PdoLengthExceeded);
            }
            match dir {
                Dir::Rx => self.rx[i] = m,
                Dir::Tx => self.tx[i] = m,
            }
            return Ok(());
        }
        let v = u32::from_le_bytes(exact::<4>(data)?);
        if self.maps(dir)[i].n != 0 {
            return Err(SdoAbort::SubindexZeroFirst);
        }
        check_entry(v, dir, objects)?;
        let slot = &mut match dir {
            Dir::Rx => &mut self.rx,
            Dir::Tx => &mut self.tx,
        }[i];
        slot.e[sub as usize - 1] = v;
        Ok(())
    }

    /// Writes sub-index `sub` of the assignment object of direction `dir`.
    fn write_assign(
        &mut self,
        dir: Dir,
        sub: u8,
        data: &[u8],
        state: EsmState,
    ) -> Result<(), SdoAbort> {
        if sub > MAPS as u8 {
            return Err(SdoAbort::SubindexDoesNotExist);
        }
        if state != EsmState::PreOp {
            return Err(SdoAbort::StateConflict);
        }
        if sub == 0 {
            let [n] = exact::<1>(data)?;
            if n as usize > MAPS {
                return Err(SdoAbort::ValueTooHigh);
            }
            let mut a = *self.assign(dir);
            a.n = n;
            let list = a.entries();
            for (k, idx) in list.iter().enumerate() {
                if !matches!(map_slot(*idx), Some((d, _)) if d == dir) {
                    return Err(SdoAbort::ValueRangeExceeded);
                }
                if list[..k].contains(idx) {
                    return Err(SdoAbort::ParameterIncompatibility);
                }
            }
            let old = *self.assign(dir);
            self.set_assign(dir, a);
            if self.assigned_bits(dir) > (MAX_BYTES * 8) as u32 {
                self.set_assign(dir, old);
                return Err(SdoAbort::PdoLengthExceeded);
            }
            return Ok(());
        }
        let v = u16::from_le_bytes(exact::<2>(data)?);
        if self.assign(dir).n != 0 {
            return Err(SdoAbort::SubindexZeroFirst);
        }
        if !matches!(map_slot(v), Some((d, _)) if d == dir) {
            return Err(SdoAbort::ValueRangeExceeded);
        }
        let mut a = *self.assign(dir);
        a.e[sub as usize - 1] = v;
        self.set_assign(dir, a);
        Ok(())
    }

    fn set_assign(&mut self, dir: Dir, a: Assign) {
        match dir {
            Dir::Rx => self.rx_assign = a,
            Dir::Tx => self.tx_assign = a,
        }
    }

    /// Compiles the assigned maps of `dir` into a plan (P→S). Any entry that is not
    /// valid in the dictionary, has no application slot, or a total above 64 bytes →
    /// the direction's mapping error (0x0025 Rx / 0x0024 Tx).
    pub fn compile_dir<P: ProcessData + ?Sized>(
        &self,
        dir: Dir,
        app: &P,
        objects: &'static [Object],
    ) -> Result<DirPlan, AlStatusCode> {
        let err = dir.mapping_error();
        let mut plan = DirPlan::EMPTY;
        let mut offset: u32 = 0;
        for idx in self.assign(dir).entries() {
            let (d, i) = map_slot(*idx).ok_or(err)?;
            if d != dir {
                return Err(err);
            }
            for e in self.maps(dir)[i].entries() {
                check_entry(*e, dir, objects).map_err(|_| err)?;
                let key = ObjectKey::from_mapping_word(*e);
                let bits = (*e & 0xFF) as u8;
                if key.index != 0 {
                    let slot = match dir {
                        Dir::Rx => app.rx_slot(key),
                        Dir::Tx => app.tx_slot(key),
                    }
                    .ok_or(err)?;
                    let n = plan.n as usize;
                    let pe = plan.entries.get_mut(n).ok_or(err)?;
                    *pe = PlanEntry {
                        slot,
                        bit_offset: offset as u16,
                        bits,
                    };
                    plan.n += 1;
                }
                offset += bits as u32;
                if offset > (MAX_BYTES * 8) as u32 {
                    return Err(err);
                }
            }
        }
        plan.bytes = offset.div_ceil(8) as u16;
        Ok(plan)
    }

    /// Compiles both directions (outputs first: 0x0025 before 0x0024).
    pub fn compile<P: ProcessData + ?Sized>(
        &self,
        app: &P,
        objects: &'static [Object],
    ) -> Result<CopyPlan, AlStatusCode> {
        let rx = self.compile_dir(Dir::Rx, app, objects)?;
        let tx = self.compile_dir(Dir::Tx, app, objects)?;
        Ok(CopyPlan { rx, tx })
    }
}

/// (direction, 0-3) of a mapping object index. Out of line: the SDO and P→S paths
/// call it in many places (never the cyclic copy).
// Measured (cargo xtask size, LAN9252 image): see `od::Entry::bits`.
#[inline(never)]
pub const fn map_slot(index: u16) -> Option<(Dir, usize)> {
    if index >= RX_MAP_BASE && index < RX_MAP_BASE + MAPS as u16 {
        Some((Dir::Rx, (index - RX_MAP_BASE) as usize))
    } else if index >= TX_MAP_BASE && index < TX_MAP_BASE + MAPS as u16 {
        Some((Dir::Tx, (index - TX_MAP_BASE) as usize))
    } else {
        None
    }
}

/// True for the indices this module serves.
pub const fn is_pdo_index(index: u16) -> bool {
    map_slot(index).is_some() || matches!(index, SM_COMM_TYPE | RX_ASSIGN | TX_ASSIGN)
}

macro_rules! map_entries {
    ($($sub:literal),*) => {
        &[
            EntryDesc::new(0, "Number of entries", DataType::Unsigned8, Access::RW_PREOP).range(0, MAX_ENTRIES as i64).saved(),
            $(EntryDesc::new($sub, concat!("Mapping entry ", $sub), DataType::Unsigned32, Access::RW_PREOP).saved(),)*
        ]
    };
}

const MAP_ENTRIES: &[EntryDesc] =
    map_entries!(1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16);

const fn map_object(index: u16, name: &'static str) -> ObjectDesc {
    ObjectDesc::record(
        index,
        name,
        MAP_ENTRIES,
        "PDO mapping: sub-index 0 = number of entries, then index<<16 | sub<<8 | bit length; Pre-Op only, sub-index 0 to 0 first",
    )
}

/// Entries of an assignment object (0x1C12 / 0x1C13): the count, then one UINT16 per
/// assignable map, limited to the maps `base..base + MAPS`.
const fn assign_entries(base: u16) -> [EntryDesc; MAPS + 1] {
    const NAMES: [&str; MAPS] = [
        "Assigned PDO 1",
        "Assigned PDO 2",
        "Assigned PDO 3",
        "Assigned PDO 4",
    ];
    let count = EntryDesc::new(
        0,
        "Number of assigned PDOs",
        DataType::Unsigned8,
        Access::RW_PREOP,
    )
    .range(0, MAPS as i64)
    .saved();
    let mut out = [count; MAPS + 1];
    let mut i = 0;
    while i < MAPS {
        out[i + 1] = EntryDesc::new(
            (i + 1) as u8,
            NAMES[i],
            DataType::Unsigned16,
            Access::RW_PREOP,
        )
        .range(base as i64, base as i64 + MAPS as i64 - 1)
        .saved();
        i += 1;
    }
    out
}

const RX_ASSIGN_ENTRIES: &[EntryDesc] = &assign_entries(RX_MAP_BASE);
const TX_ASSIGN_ENTRIES: &[EntryDesc] = &assign_entries(TX_MAP_BASE);
const SM_TYPE_ENTRIES: &[EntryDesc] = &[
    EntryDesc::new(
        0,
        "Number of sync managers",
        DataType::Unsigned8,
        Access::RO,
    )
    .default(4),
    EntryDesc::new(1, "SM0 communication type", DataType::Unsigned8, Access::RO).default(1),
    EntryDesc::new(2, "SM1 communication type", DataType::Unsigned8, Access::RO).default(2),
    EntryDesc::new(3, "SM2 communication type", DataType::Unsigned8, Access::RO).default(3),
    EntryDesc::new(4, "SM3 communication type", DataType::Unsigned8, Access::RO).default(4),
];

/// Descriptions of the objects this module and [`crate::sync`] serve (0x1600-0x1C33),
/// sorted by index.
pub const OBJECTS: &[ObjectDesc] = &[
    map_object(0x1600, "RxPDO mapping 1"),
    map_object(0x1601, "RxPDO mapping 2"),
    map_object(0x1602, "RxPDO mapping 3"),
    map_object(0x1603, "RxPDO mapping 4"),
    map_object(0x1A00, "TxPDO mapping 1"),
    map_object(0x1A01, "TxPDO mapping 2"),
    map_object(0x1A02, "TxPDO mapping 3"),
    map_object(0x1A03, "TxPDO mapping 4"),
    ObjectDesc::array(
        SM_COMM_TYPE,
        "Sync manager communication type",
        SM_TYPE_ENTRIES,
        "1 mailbox out, 2 mailbox in, 3 process data outputs, 4 process data inputs",
    ),
    ObjectDesc::array(
        RX_ASSIGN,
        "RxPDO assign",
        RX_ASSIGN_ENTRIES,
        "RxPDO mapping objects carried by SM2 (outputs)",
    ),
    ObjectDesc::array(
        TX_ASSIGN,
        "TxPDO assign",
        TX_ASSIGN_ENTRIES,
        "TxPDO mapping objects carried by SM3 (inputs)",
    ),
    crate::sync::SM2_SYNC_OBJECT,
    crate::sync::SM3_SYNC_OBJECT,
];

#[cfg(test)]
mod tests;
