//! Reports that put our figures next to the paper's.
pub mod paper;
pub mod svg;
