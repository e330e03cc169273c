//! The command line as a user meets it: the main commands work, and bad input gets
//! a clear error naming the problem and the fix, a non-zero exit, and no panic.
//! One test binary, a module per subcommand.

use std::process::{Command, Output};

#[path = "../common/mod.rs"]
mod common;

mod bench;
mod capture;
mod config;
mod dram;
mod progress;
mod render;
mod report;
mod scene;
mod tb;
mod waveform;

pub fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args(args)
        .output()
        .unwrap()
}

/// Runs the command and checks that it fails without a panic, with an error
/// naming every needle.
pub fn fails_with(args: &[&str], needles: &[&str]) {
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{args:?} should fail");
    assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    for n in needles {
        assert!(
            err.contains(n),
            "{args:?}: error should mention '{n}': {err}"
        );
    }
}
