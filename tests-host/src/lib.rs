//! Host-side simulators and tools: the ESC simulator and virtual segment, SPI-level
//! chip models, the motor plant, the simulated drive (firmware library + ESC + axis),
//! the raw-socket transport of `virtual-drive`, the ethercrab seam for in-process
//! integration tests, the host side of the drive's scope, and a CoE / FoE client on the
//! drives' mailboxes over ethercrab (also used by the commissioning tool).
#![deny(clippy::undocumented_unsafe_blocks)]
pub mod coe_client;
pub mod counting;
pub mod esc_sim;

pub mod ethercrab_seam;
pub mod fault_inject;
pub mod file_flash;
pub mod markdown;
pub mod migration;
pub mod netns;
pub mod pi_mutex;
pub mod plant;
pub mod plot;
pub mod raw_master;
pub mod raw_socket;
pub mod realtime;
pub mod scope_host;
pub mod segment;
pub mod sim_axis;
pub mod sim_drive;
pub mod sim_inputs;
pub mod sim_update;
pub mod spi_models;
pub mod vd_master;
