//! Waveforms as an RTL engineer opens them (issue 46): FST and VCD carry the
//! same values, every FSM register shows its states by name, registers are
//! `reg` and port signals `wire`. Each file is read back by an independent
//! reader: the `vcd` crate for VCD, GTKWave's `fst2vcd` for FST.

use std::process::Command;

#[path = "../common/mod.rs"]
mod common;

mod formats;
mod gtkwave;
mod read;
mod signals;

/// Runs the command line and insists that it succeeds.
pub fn dualstream(args: &[&str]) {
    let o = Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "dualstream {args:?} failed:\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// In CI the external tools are installed by `.ci/run` and must be there; on a
/// developer machine without them the check is reported and skipped.
pub fn have(tool: &str) -> bool {
    let ok = Command::new("which")
        .arg(tool)
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var_os("CI").is_none(),
            "{tool} is required in CI (.ci/run installs it)"
        );
        eprintln!("note: {tool} not installed; skipping its check (CI runs it)");
    }
    ok
}
