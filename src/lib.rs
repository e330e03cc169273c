//! dualstream: an RTL-style, cycle-level model of the Dual Streaming ray-tracing
//! hardware (Shkurko et al., HPG 2017).
pub mod accel;
pub mod bench;
pub mod config;
pub mod contract;
pub mod energy;
pub mod geom;
pub mod machine;
pub mod mem;
pub mod render;
pub mod report;
pub mod rtl;
pub mod sampling;
pub mod scene;
#[path = "../testbench/mod.rs"]
pub mod testbench;
pub mod units;
pub mod util;
