//! What several test binaries share.

use std::path::{Path, PathBuf};

#[allow(dead_code)] // read by the tests of the generated SystemVerilog
pub mod sv;

/// A directory of one test's own under the system's temporary directory,
/// removed with everything in it when the test passes. A failing test leaves it
/// in place, so its files can be looked at.
pub struct Scratch(PathBuf);

impl Scratch {
    /// A fresh, empty directory named after `name` and this process.
    pub fn new(name: &str) -> Scratch {
        let d = std::env::temp_dir().join(format!("dualstream-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        Scratch(d)
    }
}

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

/// Whether an external tool (verilator, gtkwave, xvfb-run, ...) is installed.
/// In CI `.ci/run` installs them and they must be there; on a developer
/// machine without one its check is reported and skipped.
#[allow(dead_code)] // not every test binary runs external tools
pub fn have(tool: &str) -> bool {
    let ok = std::process::Command::new("which")
        .arg(tool)
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var("CI").map_or(true, |v| v != "true"),
            "{tool} is required in CI (.ci/run installs it)"
        );
        eprintln!("note: {tool} not installed; skipping its check (CI runs it)");
    }
    ok
}

/// Runs `cmd`, insisting that it succeeds; a failure names `what` and shows
/// the tool's output. Returns the output (stdout for the caller to read).
#[allow(dead_code)] // not every test binary runs tools
pub fn succeeds(cmd: &mut std::process::Command, what: &str) -> std::process::Output {
    let o = cmd.output().unwrap();
    assert!(
        o.status.success(),
        "{what} failed: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Runs a yosys script that ends in `stat` and returns the design's cell
/// count (the last `Number of cells:` it prints: the top's).
#[allow(dead_code)] // not every test binary synthesizes
pub fn yosys_cells(script: &str) -> u64 {
    let o = succeeds(
        std::process::Command::new("yosys").args(["-p", script]),
        "yosys synth",
    );
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .rev()
        .find_map(|l| l.trim().strip_prefix("Number of cells:"))
        .and_then(|n| n.trim().parse().ok())
        .expect("yosys stat prints the cells")
}
