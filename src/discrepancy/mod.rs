//! (under construction)

pub mod consistency;
pub mod locate;
pub mod residual_map;
