//! Small helpers shared by the whole crate.
pub mod rng;
