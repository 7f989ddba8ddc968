//! placeholder
pub mod esc_sim;
pub mod plant;
pub mod ethercrab_seam;
pub mod spi_models;
pub mod segment;
