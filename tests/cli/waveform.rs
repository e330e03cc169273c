//! Waveforms of the chip (`render --mode cycle --vcd`): the chosen units and window,
//! read back with the `vcd` crate; and the size guard of every waveform (render and tb).

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::common::{Scratch, have};
use crate::{fails_with, run};

/// Unit scopes (dotted paths of the module scopes holding variables, below
/// the root that holds the clocks; a port's fields are a `begin` scope inside
/// its unit's) and timestamps of a VCD, read with the `vcd` crate.
fn vcd_scopes_and_times(path: &std::path::Path) -> (std::collections::BTreeSet<String>, Vec<u64>) {
    let f = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let (mut scopes, mut stack, mut times) =
        (std::collections::BTreeSet::new(), Vec::new(), Vec::new());
    for cmd in vcd::Parser::new(f) {
        match cmd.expect("valid VCD") {
            vcd::Command::ScopeDef(t, name) => stack.push((t, name)),
            vcd::Command::Upscope => {
                stack.pop();
            }
            vcd::Command::VarDef(..)
                if stack.len() > 1 && stack.iter().all(|s| s.0 == vcd::ScopeType::Module) =>
            {
                let path: Vec<&str> = stack.iter().map(|s| s.1.as_str()).collect();
                scopes.insert(path.join("."));
            }
            vcd::Command::Timestamp(t) => times.push(t),
            _ => {}
        }
    }
    (scopes, times)
}

/// `render --mode cycle` of the tiny scene on a chip of 2 TMs x 4 TPs with
/// GDDR5, its waveform written to `NAME.vcd` in `t`: the arguments (the last
/// two are `--vcd FILE`) and the waveform's path.
fn traced_render(t: &Scratch, name: &str) -> (Vec<String>, PathBuf) {
    let (cfg, vcd, png) = (
        t.join(format!("{name}.toml")),
        t.join(format!("{name}.vcd")),
        t.join(format!("{name}.png")),
    );
    std::fs::write(
        &cfg,
        "[tm]\ntps = 4\n[chip]\ntms = 2\n[chip.memory]\nmodel = \"gddr5\"\n",
    )
    .unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let mut args = vec!["--config".to_string(), s(&cfg)];
    args.extend(
        [
            "render",
            "--mode",
            "cycle",
            "--scene",
            "tiny",
            "--res",
            "8x8",
            "--bounces",
            "1",
            "--out",
        ]
        .map(String::from),
    );
    args.extend([s(&png), "--vcd".to_string(), s(&vcd)]);
    (args, vcd)
}

#[test]
fn render_cycle_writes_a_waveform_of_the_chosen_units_and_window() {
    let t = Scratch::new("cli-chipv");
    let (owned, vcd) = traced_render(&t, "chipv");
    let base: Vec<&str> = owned.iter().map(String::as_str).collect();
    let args: Vec<&str> = base
        .iter()
        .copied()
        .chain([
            "--trace-units",
            "scheduler,tm0,mem_ctrl",
            "--trace-window",
            "200..1200",
        ])
        .collect();
    let o = run(&args);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        out.contains("waveform:") && out.contains("gtkwave"),
        "{out}"
    );
    assert!(
        out.contains("drain"),
        "the summary gives drain cycles: {out}"
    );
    // Tracing changes nothing: the same cycles per run without the waveform.
    let plain = run(&base[..base.len() - 2]);
    let runs = |s: &str| -> Vec<String> {
        s.lines()
            .filter(|l| l.contains("run ") || l.contains("total cycles"))
            .map(String::from)
            .collect()
    };
    let plain_out = String::from_utf8_lossy(&plain.stdout);
    assert!(plain.status.success() && !plain_out.contains("waveform"));
    assert!(runs(&out).len() >= 3);
    assert_eq!(
        runs(&out),
        runs(&plain_out),
        "cycles with and without --vcd"
    );
    let (scopes, times) = vcd_scopes_and_times(&vcd);
    assert!(scopes.contains("chip.scheduler"), "{scopes:?}");
    assert!(scopes.contains("chip.tm0.l1") && scopes.contains("chip.tm0.tp3"));
    assert!(scopes.contains("chip.tm0.xbar") && scopes.contains("chip.tm0.staging_buffer"));
    assert_eq!(
        scopes
            .iter()
            .filter(|s| s.starts_with("chip.mem_ctrl"))
            .count(),
        16,
        "every channel: {scopes:?}"
    );
    for s in &scopes {
        assert!(
            s == "chip.scheduler" || s.starts_with("chip.tm0.") || s.starts_with("chip.mem_ctrl"),
            "only the requested units are traced, not {s}"
        );
    }
    // Core cycles 200..1200 of 1000 ps (run 0's tracing), the end excluded;
    // changes in it.
    assert!(times.len() > 100, "{}", times.len());
    assert!(
        times.iter().all(|&t| (200_000..1_200_000).contains(&t)),
        "{:?}",
        (times.first(), times.last())
    );
    if have("vcd2fst") {
        let fst = t.join("chipv.fst");
        let o = Command::new("vcd2fst")
            .arg(&vcd)
            .arg(&fst)
            .output()
            .unwrap();
        assert!(
            o.status.success() && std::fs::metadata(&fst).unwrap().len() > 0,
            "vcd2fst: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

/// The chip's waveform also takes the testbenches' flags; bad unit names and
/// windows, and trace options without `--vcd` or cycle mode, are refused.
#[test]
fn render_cycle_takes_the_old_trace_flags_and_names_bad_units() {
    let t = Scratch::new("cli-chipv-old");
    let (owned, vcd) = traced_render(&t, "chipv");
    let base: Vec<&str> = owned.iter().map(String::as_str).collect();
    let v = vcd.to_str().unwrap();
    // The old flags: --trace (instance patterns) and --trace-from/--trace-to.
    let args: Vec<&str> = base
        .iter()
        .copied()
        .chain([
            "--trace",
            "chip.tm1.l1",
            "--trace-from",
            "100",
            "--trace-to",
            "200",
        ])
        .collect();
    assert!(run(&args).status.success());
    let (scopes, times) = vcd_scopes_and_times(&vcd);
    assert_eq!(scopes.into_iter().collect::<Vec<_>>(), ["chip.tm1.l1"]);
    assert!(times.iter().all(|&t| (100_000..201_000).contains(&t)));
    // Bad names and windows are named.
    let with = |extra: &[&'static str]| -> Vec<&str> {
        base.iter().copied().chain(extra.iter().copied()).collect()
    };
    fails_with(
        &with(&["--trace-units", "scheduler,tm7"]),
        &["'tm7' matches no unit", "tm0..tm1", "mem_ctrl0..mem_ctrl15"],
    );
    fails_with(
        &with(&["--trace-units", "sched"]),
        &[
            "unknown unit 'sched'",
            "scheduler",
            "scene_buffer",
            "hit_updater",
        ],
    );
    fails_with(
        &with(&["--trace-window", "30..10"]),
        &["--trace-window", "A..B"],
    );
    fails_with(
        &["render", "--vcd", v, "--scene", "tiny", "--res", "8x8"],
        &["--mode cycle"],
    );
    fails_with(
        &["render", "--mode", "cycle", "--trace-units", "tm0"],
        &["--vcd"],
    );
}

/// The waveform's size guard: a trace far over the limit is refused before the
/// run with its estimate, one that grows past it is stopped (by its projection
/// or its bytes), and no file is left either way.
#[test]
fn oversized_waveforms_are_refused_or_stopped_and_leave_no_file() {
    let t = Scratch::new("cli-trace-guard");
    // The whole chip over a whole 64x64 frame: refused up front.
    let f = t.join("frame.vcd");
    let start = std::time::Instant::now();
    fails_with(
        &[
            "render",
            "--mode",
            "cycle",
            "--res",
            "64x64",
            "--vcd",
            f.to_str().unwrap(),
            "--out",
            t.join("f.png").to_str().unwrap(),
        ],
        &[
            "estimated before it started",
            "--trace-window",
            "--trace-max-bytes",
        ],
    );
    assert!(!f.exists(), "a refused trace left its file");
    assert!(
        start.elapsed().as_secs() < 120,
        "refusing took {:?}",
        start.elapsed()
    );
    // A busy testbench's window (to cycle 20000), estimated under the limit,
    // whose first cycles project past it.
    let p = t.join("projected.vcd");
    fails_with(
        &[
            "tb",
            "box_pipe",
            "--cycles",
            "20000",
            "--trace-to",
            "20000",
            "--vcd",
            p.to_str().unwrap(),
            "--trace-max-bytes",
            "1M",
        ],
        &["projected from its first", "--trace-max-bytes"],
    );
    assert!(!p.exists(), "a stopped trace left its file");
    // A unit testbench with no window end: stopped at the limit.
    let b = t.join("box.vcd");
    fails_with(
        &[
            "tb",
            "box_pipe",
            "--cycles",
            "20000",
            "--vcd",
            b.to_str().unwrap(),
            "--trace-max-bytes",
            "100K",
        ],
        &["reached", "--trace-from/--trace-to"],
    );
    assert!(!b.exists(), "a stopped trace left its file");
    // Under the limit, the same testbench writes its waveform.
    let o = run(&[
        "tb",
        "box_pipe",
        "--cycles",
        "2000",
        "--vcd",
        b.to_str().unwrap(),
        "--trace-max-bytes",
        "10M",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(std::fs::metadata(&b).unwrap().len() > 10_000);
    fails_with(
        &[
            "tb",
            "box_pipe",
            "--vcd",
            b.to_str().unwrap(),
            "--trace-max-bytes",
            "12X",
        ],
        &["--trace-max-bytes 12X", "500M"],
    );
}
