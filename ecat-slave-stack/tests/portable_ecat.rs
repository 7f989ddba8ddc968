//! Tests of `ecat-slave-stack` that run on the host and under QEMU (Cortex-M4F).
#![cfg_attr(target_os = "none", no_std, no_main)]

use ecat_slave_stack::AlStatusCode;

qemu_runner::tests! {
    fn al_status_codes_round_trip() {
        for c in AlStatusCode::ALL {
            assert_eq!(AlStatusCode::from_code(c.code()), Some(*c));
            assert!(!c.text().is_empty());
        }
        assert_eq!(AlStatusCode::from_code(0x0004), None);
        assert_eq!(AlStatusCode::BootstrapNotSupported.code(), 0x0013);
        assert_eq!(AlStatusCode::DcInvalidCycleTime.code(), 0x0035);
    }
}
