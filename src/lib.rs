//! dualstream: an RTL-style, cycle-level model of the Dual Streaming ray-tracing
//! hardware (Shkurko et al., HPG 2017).
pub mod geom;
pub mod util;
