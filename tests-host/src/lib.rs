//! placeholder
pub mod esc_sim;
pub mod ethercrab_seam;
