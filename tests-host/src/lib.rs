//! placeholder
pub mod esc_sim;
