//! `dualstream bench`: the speed/error study and the benchmarks' own flags.

use crate::common::Scratch;
use crate::{fails_with, run};

#[test]
fn bench_speed_error_prints_every_mode_with_json_and_plot() {
    let t = Scratch::new("cli-se");
    let cfg = t.join("se.toml");
    std::fs::write(&cfg, "[chip]\ntms = 2\n[tm]\ntps = 4\n").unwrap();
    let (json, svg, wlog) = (
        t.join("se.json"),
        t.join("se.svg"),
        t.join("se-windows.json"),
    );
    let o = run(&[
        "--config",
        cfg.to_str().unwrap(),
        "bench",
        "speed-error",
        "--scene",
        "tiny",
        "--res",
        "8x8",
        "--small-tms",
        "1",
        "--tile",
        "2",
        "--sample-every",
        "4",
        "--json",
        json.to_str().unwrap(),
        "--plot",
        svg.to_str().unwrap(),
        "--window-log",
        wlog.to_str().unwrap(),
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for mode in [
        "cycle ",
        "cycle-fixed",
        "functional+estimate",
        "small-chip",
        "quarter-pixels",
        "sampled ",
        "sampled-scaled",
        "windows",
    ] {
        assert!(out.contains(mode), "{mode} missing: {out}");
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // The header says what ran.
    assert_eq!(v["header"]["tool"], "dualstream");
    assert_eq!(v["header"]["run"]["resolution"][0], 8);
    let rows = v["runs"].as_array().unwrap();
    assert_eq!(rows.len(), 8);
    assert_eq!(rows[0]["err_cycles"], 0.0);
    assert!(rows[1]["speedup"].as_f64().unwrap() > 0.0);
    let plot = std::fs::read_to_string(&svg).unwrap();
    assert_eq!(plot.matches("<circle").count(), 8);
    // The window log: the estimate by part and every window with its passes.
    let log: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&wlog).unwrap()).unwrap();
    let parts = log["parts"].as_array().unwrap();
    for part in ["root", "shade", "emit"] {
        assert!(
            parts.iter().any(|p| p["part"] == part),
            "{part} in {parts:?}"
        );
    }
    let estimated: f64 = parts.iter().map(|p| p["cycles"].as_f64().unwrap()).sum();
    let windows = rows.iter().find(|r| r["mode"] == "windows").unwrap();
    let cycles = windows["cycles"].as_f64().unwrap();
    assert!(
        (estimated - cycles).abs() <= 1e-6 * cycles,
        "{estimated} vs {cycles}"
    );
    let samples = log["record"]["samples"].as_array().unwrap();
    assert!(
        samples
            .iter()
            .any(|s| s["kind"] == "Root" && !s["run"]["passes"].as_array().unwrap().is_empty())
    );
    fails_with(
        &[
            "--config",
            cfg.to_str().unwrap(),
            "bench",
            "speed-error",
            "--scene",
            "tiny",
            "--res",
            "8x8",
            "--small-tms",
            "2",
        ],
        &["--small-tms 2", "chip.tms"],
    );
    for (flags, want) in [
        (["--window-measure", "2000"], "windows overlap"),
        (["--shade-windows", "0"], "--shade-windows 0"),
    ] {
        let mut a = vec!["bench", "speed-error", "--scene", "tiny", "--res", "8x8"];
        a.extend(["--modes", "windows"]);
        a.extend(flags);
        fails_with(&a, &[want]);
    }
    fails_with(
        &["bench", "nonsense"],
        &["unknown benchmark", "speed-error"],
    );
}

/// Each benchmark is a subcommand with only its own flags: the time-sampling
/// plan's (`--window-*`, `--shade-*`) belong to `bench speed-error` alone, so
/// neither `render --help` nor the other benchmarks list them.
#[test]
fn bench_subcommands_carry_only_their_own_flags() {
    let help = |args: &[&str]| -> String {
        let o = run(args);
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let se = help(&["bench", "speed-error", "--help"]);
    for f in [
        "--window-every",
        "--window-waves",
        "--window-wave-ray-share",
        "--shade-head",
        "--window-log",
        "--reference-passes",
        "--small-tms",
        "Windows mode (time sampling)",
    ] {
        assert!(se.contains(f), "bench speed-error --help lacks {f}: {se}");
    }
    for args in [
        &["--help"][..],
        &["render", "--help"],
        &["bench", "--help"],
        &["bench", "kernel", "--help"],
        &["bench", "dram", "--help"],
        &["bench", "threads", "--help"],
    ] {
        let h = help(args);
        assert!(
            !h.contains("--window-") && !h.contains("--shade-"),
            "{args:?} lists time-sampling flags: {h}"
        );
    }
    let list = help(&["bench", "--help"]);
    for name in ["kernel", "dram", "speed-error", "threads"] {
        assert!(list.contains(name), "{name}: {list}");
    }
    assert!(
        !list.lines().any(|l| l.trim_start().starts_with("busy")),
        "the competing process stays hidden: {list}"
    );
    // A flag given to a benchmark it does not belong to is refused, named.
    fails_with(
        &["bench", "kernel", "--window-every", "3"],
        &["--window-every"],
    );
    fails_with(&["bench", "threads", "--res", "8x8"], &["--res"]);
    fails_with(
        &["bench", "kernel", "--scale", "0"],
        &["--scale must be positive"],
    );
    fails_with(
        &["bench", "dram", "--scale=-1"],
        &["--scale must be positive"],
    );
    // Each name runs its own benchmark.
    let k = help(&["bench", "kernel", "--scale", "0.001"]);
    assert!(k.contains("128 TMs") && k.contains("cycles/s"), "{k}");
    let d = help(&["bench", "dram", "--scale", "0.001"]);
    assert!(
        d.contains("energy per 64 B line") && d.contains("requests/s"),
        "{d}"
    );
}
