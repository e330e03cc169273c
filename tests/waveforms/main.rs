//! Waveforms as an RTL engineer opens them (issue 46): FST and VCD carry the
//! same values, every FSM register shows its states by name, registers are
//! `reg` and port signals `wire`. Each file is read back by an independent
//! reader: the `vcd` crate for VCD, GTKWave's `fst2vcd` for FST.

use std::process::Command;

#[path = "../common/mod.rs"]
mod common;

mod formats;
mod gtkwave;
mod initial;
mod names;
mod read;
mod ready;

pub use common::have;
mod signals;
mod unit_names;
mod windows;

/// Runs the command line and insists that it succeeds.
pub fn dualstream(args: &[&str]) {
    common::succeeds(
        Command::new(env!("CARGO_BIN_EXE_dualstream")).args(args),
        &format!("dualstream {args:?}"),
    );
}

/// Traces a window of an 8x8 cycle frame on the 8-TM chip into `trace` (its
/// image beside it): `units` as `--trace-units`, `window` as
/// `--trace-window`, then any `extra` flags.
pub fn chip_trace(trace: &std::path::Path, units: &str, window: &str, extra: &[&str]) {
    let cfg = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/examples/chip-8tms.toml");
    let png = trace.with_extension("png");
    let mut args = vec![
        "render",
        "--config",
        cfg,
        "--mode",
        "cycle",
        "--res",
        "8x8",
        "--out",
        png.to_str().unwrap(),
        "--vcd",
        trace.to_str().unwrap(),
        "--trace-units",
        units,
        "--trace-window",
        window,
    ];
    args.extend_from_slice(extra);
    dualstream(&args);
}
