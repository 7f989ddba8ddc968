#![cfg_attr(target_os = "none", no_std, no_main)]
qemu_runner::tests! { fn t() { assert!(true); } }
