#![no_std]
pub mod cia402;
pub mod comm;
pub mod dictionary;
pub mod dip;
pub mod drive;
pub mod fault_led;
pub mod faults;
pub mod flash_region;
pub mod identity;
pub mod io;
pub mod monitor;
pub mod motion;
pub mod params;
pub mod pdo_defaults;
pub mod sampling;
pub mod staged_flash;
pub mod storage;
