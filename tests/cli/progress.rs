//! Progress on stderr: plain lines when stderr is not a terminal (as here), the
//! last one when the work is done; nothing with `--quiet`.

use std::process::Command;

use crate::common::Scratch;

/// `dualstream args` with the plain lines' interval `interval_ms` (`None`:
/// the default, 5 s): its stderr.
fn stderr_of(args: &[&str], interval_ms: Option<&str>) -> String {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dualstream"));
    c.args(args);
    match interval_ms {
        Some(ms) => c.env("DUALSTREAM_PROGRESS_INTERVAL_MS", ms),
        None => c.env_remove("DUALSTREAM_PROGRESS_INTERVAL_MS"),
    };
    let o = c.output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{args:?}: {err}");
    err
}

#[test]
fn quiet_leaves_stderr_empty() {
    let t = Scratch::new("cli-progress-quiet");
    let png = t.join("q.png");
    for mode in ["functional", "cycle", "windows"] {
        let args = [
            "render", "--scene", "tiny", "--res", "16x16", "--mode", mode, "--out",
        ];
        let mut quiet = vec!["--quiet"];
        quiet.extend(args);
        quiet.push(png.to_str().unwrap());
        assert_eq!(
            stderr_of(&quiet, Some("0")),
            "",
            "--quiet render --mode {mode}"
        );
        // Without it, the same run says how far it is.
        let mut loud = args.to_vec();
        loud.push(png.to_str().unwrap());
        assert!(
            !stderr_of(&loud, Some("0")).is_empty(),
            "render --mode {mode}"
        );
    }
}

#[test]
fn without_a_terminal_progress_is_plain_lines_ending_with_done() {
    let t = Scratch::new("cli-progress-lines");
    let png = t.join("p.png");
    let args = [
        "render",
        "--scene",
        "tiny",
        "--res",
        "16x16",
        "--out",
        png.to_str().unwrap(),
    ];
    // A line at every update: several, each a plain line (no escape codes),
    // the last one saying the frame is done.
    let every = stderr_of(&args, Some("0"));
    let lines: Vec<&str> = every.lines().collect();
    assert!(lines.len() >= 2, "{every}");
    assert!(!every.contains('\u{1b}'), "{every}");
    assert!(lines.iter().all(|l| l.starts_with("render: ")), "{every}");
    let last = lines.last().unwrap();
    assert!(
        last.contains("100%") && last.contains("wavefronts done"),
        "{last}"
    );
    // The default interval is seconds: a sub-second frame gets the last line only.
    let default = stderr_of(&args, None);
    assert_eq!(default.lines().count(), 1, "{default}");
    assert!(default.contains("wavefronts done"), "{default}");
}
