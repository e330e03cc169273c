//! `dualstream report`: what it needs is named when missing.

use std::process::Command;

use crate::common::Scratch;
use crate::fails_with;

#[test]
fn report_paper_names_missing_scenes() {
    // Away from the repository (no scenes/), with an empty search path.
    let t = Scratch::new("cli-report-missing");
    let o = Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .current_dir(&*t)
        .env_remove("DUALSTREAM_SCENES")
        .args(["report", "paper", "--scenes-dir", "/nonexistent"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    for n in ["dragon.toml", "--scenes-dir", "DUALSTREAM_SCENES"] {
        assert!(err.contains(n), "{n}: {err}");
    }
    fails_with(&["report", "nonsense"], &["unknown report"]);
}
