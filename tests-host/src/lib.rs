//! placeholder
pub mod esc_sim;
pub mod ethercrab_seam;
pub mod spi_models;
