//! Benchmark rows of the CoE mailbox: from `MailboxServer::on_request` (a whole 128-byte
//! SM0 buffer arrived) to the reply written by `next_output` (ready for SM1).
//!
//! The dictionary is a sorted table of 32 VAR objects whose values live in an array
//! indexed by the table position, so the rows count the mailbox/SDO code (header checks,
//! binary search, access/length/range checks, reply building, copy), not an
//! application's value lookup.

use core::hint::black_box;

use ecat_slave_stack::esm::EsmState;
use ecat_slave_stack::mailbox::MailboxServer;
use ecat_slave_stack::od::{
    self, Access, DataType, Dictionary, EntryDesc, Object, ObjectDesc, ObjectKey, PdoMappable,
    SdoAbort,
};

macro_rules! objects {
    ($( $idx:literal $t:ident ),* $(,)?) => {
        &[$(ObjectDesc::var($idx, "", &[EntryDesc::new(0, "", DataType::$t, Access::RW).pdo(PdoMappable::RxTx)], "")),*]
    };
}

static OBJECTS: &[Object] = ecat_slave_stack::packed_dictionary!(&[SOURCE]);
const SOURCE: &[ObjectDesc] = objects![
    0x1000 Unsigned32, 0x1001 Unsigned8, 0x2000 Integer32, 0x2001 Unsigned16,
    0x2002 Unsigned16, 0x2003 Integer32, 0x2004 Unsigned32, 0x2005 Integer16,
    0x603F Unsigned16, 0x6040 Unsigned16, 0x6041 Unsigned16, 0x6060 Integer8,
    0x6061 Integer8, 0x6064 Integer32, 0x6065 Unsigned32, 0x606C Integer32,
    0x6071 Integer16, 0x6077 Integer16, 0x607A Integer32, 0x607C Integer32,
    0x6081 Unsigned32, 0x6083 Unsigned32, 0x6084 Unsigned32, 0x6098 Integer8,
    0x6099 Unsigned32, 0x609A Unsigned32, 0x60B0 Integer32, 0x60B1 Integer32,
    0x60B2 Integer16, 0x60FD Unsigned32, 0x60FF Integer32, 0x6502 Unsigned32,
];

struct BenchDict {
    v: [u32; 32],
}

impl Dictionary for BenchDict {
    fn objects(&self) -> &'static [Object] {
        OBJECTS
    }
    fn read(&mut self, key: ObjectKey, buf: &mut [u8]) -> Result<usize, SdoAbort> {
        let ObjectKey { index, .. } = key;
        let p = OBJECTS
            .binary_search_by_key(&index, |o| o.index)
            .map_err(|_| SdoAbort::ObjectDoesNotExist)?;
        let e = od::find_entry(OBJECTS, key)?;
        let n = e.byte_len();
        let dst = buf.get_mut(..n).ok_or(SdoAbort::GeneralError)?;
        dst.copy_from_slice(&self.v[p].to_le_bytes()[..n]);
        Ok(n)
    }
    fn write(&mut self, key: ObjectKey, data: &[u8], _state: EsmState) -> Result<(), SdoAbort> {
        let ObjectKey { index, .. } = key;
        let p = OBJECTS
            .binary_search_by_key(&index, |o| o.index)
            .map_err(|_| SdoAbort::ObjectDoesNotExist)?;
        let mut b = [0u8; 4];
        let n = data.len().min(4);
        b[..n].copy_from_slice(&data[..n]);
        self.v[p] = u32::from_le_bytes(b);
        Ok(())
    }
}

/// A 128-byte SM0 buffer holding one SDO request.
fn sm0(counter: u8, coe: &[u8; 10]) -> [u8; 128] {
    let mut f = [0u8; 128];
    f[0] = 10;
    f[5] = 0x03 | (counter << 4);
    f[6..16].copy_from_slice(coe);
    f
}

pub fn run() {
    let mut srv = MailboxServer::new(128);
    let mut dict = BenchDict { v: [0x0237; 32] };
    let mut out = [0u8; 128];
    // Upload of the statusword 0x6041 (u16).
    let up = sm0(1, &[0x00, 0x20, 0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]);
    let n = crate::bench("SDO expedited upload (SM0 → reply)", || {
        srv.on_request(black_box(&up), &mut dict, black_box(EsmState::Op), 0);
        srv.next_output(&mut out, 0)
    });
    assert_eq!((n, out[8]), (16, 0x4B));
    // Download of the target position 0x607A (i32).
    let down = sm0(
        2,
        &[0x00, 0x20, 0x23, 0x7A, 0x60, 0x00, 0x40, 0x0D, 0x03, 0x00],
    );
    let n = crate::bench("SDO expedited download (SM0 → reply)", || {
        srv.on_request(black_box(&down), &mut dict, black_box(EsmState::Op), 0);
        srv.next_output(&mut out, 0)
    });
    assert_eq!((n, out[8]), (16, 0x60));
    black_box(&dict.v);
}
