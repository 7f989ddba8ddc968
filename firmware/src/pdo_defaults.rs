//! The product's default PDO mapping and assignment (`docs/object-dictionary.md`, 0x1600 / 0x1A00): the
//! values of 0x1600-0x1603, 0x1A00-0x1A03, 0x1C12 and 0x1C13 at power-up and after
//! 'load'. The slave runtime starts from [`PDO_DEFAULTS`]; the ESI's `RxPdo`/`TxPdo`
//! are generated from the same constant, so the file and the drive cannot disagree.
//!
//! | map | entries | bytes |
//! |---|---|---|
//! | 0x1600 RxPDO1 (CSP) | 6040, 607A, 60B0, 60B8 | 12 |
//! | 0x1601 RxPDO2 (PP) | 6040, 607A, 6081, 6083, 6084, 6060 | 19 |
//! | 0x1602 RxPDO3 (PV) | 6040, 60FF, 6083, 6084, 6060 | 15 |
//! | 0x1603 RxPDO4 (HM) | 6040, 6098, 6099:01, 6099:02, 609A, 607C, 6060 | 20 |
//! | 0x1A00 TxPDO1 | 603F, 6041, 6061, 6064, 60B9, 60BA, 60FD | 19 |
//! | 0x1A01-0x1A03 | empty | 0 |
//!
//! (The requirements table gives 22 bytes for RxPDO4; its entries add up to 20.)
//!
//! Assigned by default: 0x1C12 = {0x1600}, 0x1C13 = {0x1A00}.

use ecat_slave_stack::od::ObjectKey;
use ecat_slave_stack::pdo::PdoDefaults;

/// 0x1600 RxPDO1: controlword, target position, position offset, touch probe function.
pub const RX_PDO1: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x607A, 0).mapping_word(32),
    ObjectKey::new(0x60B0, 0).mapping_word(32),
    ObjectKey::new(0x60B8, 0).mapping_word(16),
];

/// 0x1601 RxPDO2: controlword, target position, profile velocity, acceleration,
/// deceleration, modes of operation.
pub const RX_PDO2: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x607A, 0).mapping_word(32),
    ObjectKey::new(0x6081, 0).mapping_word(32),
    ObjectKey::new(0x6083, 0).mapping_word(32),
    ObjectKey::new(0x6084, 0).mapping_word(32),
    ObjectKey::new(0x6060, 0).mapping_word(8),
];

/// 0x1602 RxPDO3: controlword, target velocity, acceleration, deceleration, modes of
/// operation.
pub const RX_PDO3: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x60FF, 0).mapping_word(32),
    ObjectKey::new(0x6083, 0).mapping_word(32),
    ObjectKey::new(0x6084, 0).mapping_word(32),
    ObjectKey::new(0x6060, 0).mapping_word(8),
];

/// 0x1603 RxPDO4: controlword, homing method, homing speeds (switch, zero), homing
/// acceleration, home offset, modes of operation.
pub const RX_PDO4: &[u32] = &[
    ObjectKey::new(0x6040, 0).mapping_word(16),
    ObjectKey::new(0x6098, 0).mapping_word(8),
    ObjectKey::new(0x6099, 1).mapping_word(32),
    ObjectKey::new(0x6099, 2).mapping_word(32),
    ObjectKey::new(0x609A, 0).mapping_word(32),
    ObjectKey::new(0x607C, 0).mapping_word(32),
    ObjectKey::new(0x6060, 0).mapping_word(8),
];

/// 0x1A00 TxPDO1: error code, statusword, modes of operation display, position actual
/// value, touch probe status, touch probe 1 positive edge, digital inputs.
pub const TX_PDO1: &[u32] = &[
    ObjectKey::new(0x603F, 0).mapping_word(16),
    ObjectKey::new(0x6041, 0).mapping_word(16),
    ObjectKey::new(0x6061, 0).mapping_word(8),
    ObjectKey::new(0x6064, 0).mapping_word(32),
    ObjectKey::new(0x60B9, 0).mapping_word(16),
    ObjectKey::new(0x60BA, 0).mapping_word(32),
    ObjectKey::new(0x60FD, 0).mapping_word(32),
];

/// The default mapping and assignment (0x1600 / 0x1A00, 0x1C12 / 0x1C13).
pub const PDO_DEFAULTS: PdoDefaults = PdoDefaults {
    rx: [RX_PDO1, RX_PDO2, RX_PDO3, RX_PDO4],
    tx: [TX_PDO1, &[], &[], &[]],
    rx_assign: &[0x1600],
    tx_assign: &[0x1A00],
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dictionary::OBJECTS;
    use ecat_slave_stack::od;

    fn bytes(map: &[u32]) -> u32 {
        map.iter().map(|v| v & 0xFF).sum::<u32>() / 8
    }

    #[test]
    fn sizes_of_the_requirements_table() {
        let rx: [u32; 4] = core::array::from_fn(|i| bytes(PDO_DEFAULTS.rx[i]));
        assert_eq!(rx, [12, 19, 15, 20]);
        assert_eq!(bytes(PDO_DEFAULTS.tx[0]), 19);
        assert!(PDO_DEFAULTS.tx[1..].iter().all(|m| m.is_empty()));
        assert_eq!(PDO_DEFAULTS.rx_assign, &[0x1600]);
        assert_eq!(PDO_DEFAULTS.tx_assign, &[0x1A00]);
    }

    #[test]
    fn every_entry_is_mappable_with_its_length() {
        for (maps, rx) in [(&PDO_DEFAULTS.rx, true), (&PDO_DEFAULTS.tx, false)] {
            for v in maps.iter().flat_map(|m| m.iter()) {
                let (key, bits) = (ObjectKey::from_mapping_word(*v), (v & 0xFF) as u16);
                let e = od::find_entry(OBJECTS, key)
                    .unwrap_or_else(|_| panic!("{key} not in the dictionary"));
                assert_eq!(e.bits(), bits, "{key} length");
                assert!(
                    if rx {
                        e.pdo_mappable().rx()
                    } else {
                        e.pdo_mappable().tx()
                    },
                    "{key} not mappable in this direction"
                );
            }
        }
    }
}
