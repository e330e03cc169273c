//! Unit testbenches, in the spirit of cocotb and ChiselSim: a driver pokes requests
//! into a unit's input link, the clock is stepped, a sink takes the outputs with a
//! seeded back-pressure pattern, and a scoreboard checks every output against the
//! pure reference function, the exact latency and the initiation interval.
//!
//! Drivers and sinks are units like any other, so the unit under test is exercised
//! through real registered links with their protocol monitors.

pub mod harness;
pub mod pipe_tb;

pub mod box_pipe_tb;
pub mod divider_tb;
pub mod hit_record_updater_tb;
pub mod l1_tb;
pub mod l2_tb;
pub mod mem_ctrl_tb;
pub mod scene_buffer_tb;
pub mod stream_scheduler_tb;
pub mod tm_tb;
pub mod tri_pipe_tb;

pub use harness::{Driver, LoadGen, Sink};
pub use pipe_tb::{PipeKind, PipeTb, TbOptions, TbReport};

/// Names accepted by `dualstream tb` (each a module name; `dram` also runs mem_ctrl).
pub const BENCHES: &[&str] = &[
    "box_pipe",
    "tri_pipe",
    "divider",
    "mem_ctrl",
    "hit_record_updater",
    "l2",
];

/// Runs a testbench by unit name (the CLI's `tb` command).
pub fn run_by_name(name: &str, opts: &TbOptions) -> Result<TbReport, String> {
    match name {
        "box_pipe" => pipe_tb::run_random::<box_pipe_tb::BoxKind>(opts),
        "tri_pipe" => pipe_tb::run_random::<tri_pipe_tb::TriKind>(opts),
        "divider" => pipe_tb::run_random::<divider_tb::DivKind>(opts),
        "mem_ctrl" | "dram" => mem_ctrl_tb::run_random(opts),
        "hit_record_updater" | "hru" => hit_record_updater_tb::run(opts),
        "scene_buffer" => scene_buffer_tb::run(opts),
        "l2" => l2_tb::run(opts),
        "stream_scheduler" => stream_scheduler_tb::run(opts),
        _ => Err(format!(
            "unknown unit '{name}'; testbenches exist for: {}, tm (dram = mem_ctrl)",
            BENCHES.join(", ")
        )),
    }
}

/// The configuration `dualstream tb <name>` elaborates its unit with, from the
/// base configuration: the global units' benches set their own TM count and sizes.
pub fn bench_config(name: &str, base: &crate::config::Config) -> crate::config::Config {
    match name {
        "hit_record_updater" | "hru" => {
            hit_record_updater_tb::unit_config(base, &hit_record_updater_tb::HruTbCfg::default())
        }
        "l2" => l2_tb::unit_config(base, &l2_tb::L2TbCfg::default()),
        "scene_buffer" => scene_buffer_tb::unit_config(base, &scene_buffer_tb::SbTbCfg::default()),
        "stream_scheduler" => {
            stream_scheduler_tb::unit_config(base, &stream_scheduler_tb::SchedTbCfg::default())
        }
        _ => base.clone(),
    }
}
