//! `dualstream tb`: the unit and TM testbenches, their waveforms, trace windows and
//! filters, and bad input.

use crate::common::Scratch;
use crate::{fails_with, run};

#[test]
fn tb_runs_and_writes_a_vcd() {
    let t = Scratch::new("cli-tb");
    let vcd = t.join("box.vcd");
    let o = run(&[
        "tb",
        "box_pipe",
        "--cycles",
        "500",
        "--seed",
        "1",
        "--vcd",
        vcd.to_str().unwrap(),
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.contains("PASS") && out.contains("gtkwave"), "{out}");
    let text = std::fs::read_to_string(&vcd).unwrap();
    assert!(text.contains("$scope module box_pipe $end"));
}

#[test]
fn same_seed_same_waveform() {
    let t = Scratch::new("cli-seed");
    let (a, b, c) = (t.join("a.vcd"), t.join("b.vcd"), t.join("c.vcd"));
    for (p, seed) in [(&a, "4"), (&b, "4"), (&c, "5")] {
        assert!(
            run(&[
                "tb",
                "tri_pipe",
                "--cycles",
                "300",
                "--seed",
                seed,
                "--vcd",
                p.to_str().unwrap()
            ])
            .status
            .success()
        );
    }
    let read = |p: &std::path::Path| std::fs::read(p).unwrap();
    assert_eq!(read(&a), read(&b));
    assert_ne!(read(&a), read(&c));
}

#[test]
fn unknown_unit() {
    fails_with(
        &["tb", "warp_drive"],
        &["unknown unit 'warp_drive'", "box_pipe"],
    );
}

#[test]
fn unwritable_outputs() {
    fails_with(
        &["tb", "box_pipe", "--vcd", "/nonexistent-dir/out.vcd"],
        &["cannot write the VCD", "--vcd"],
    );
    fails_with(&["hdl", "--out", "/proc/forbidden"], &["--out"]);
}

#[test]
fn trace_window_and_filter() {
    let t = Scratch::new("cli-trace");
    let vcd = t.join("w.vcd");
    let v = vcd.to_str().unwrap();
    fails_with(
        &[
            "tb",
            "box_pipe",
            "--vcd",
            v,
            "--trace-from",
            "50",
            "--trace-to",
            "10",
        ],
        &["before it starts"],
    );
    fails_with(
        &["tb", "box_pipe", "--vcd", v, "--trace", "nosuchunit"],
        &["no unit matches", "tb.box_pipe"],
    );
    fails_with(&["tb", "box_pipe", "--cycles", "0"], &["--cycles 0"]);
    fails_with(&["tb", "box_pipe", "--ready", "0"], &["probabilities"]);
    // A window and a filter limit what is written.
    let o = run(&[
        "tb",
        "box_pipe",
        "--cycles",
        "400",
        "--vcd",
        v,
        "--trace",
        "box_pipe",
        "--trace-from",
        "100",
        "--trace-to",
        "120",
    ]);
    assert!(o.status.success());
    let text = std::fs::read_to_string(&vcd).unwrap();
    assert!(!text.contains("module driver"));
    let times: Vec<u64> = text
        .lines()
        .filter_map(|l| l.strip_prefix('#'))
        .map(|t| t.parse().unwrap())
        .collect();
    assert!(
        times.iter().all(|&t| (100_000..=120_000).contains(&t)),
        "{times:?}"
    );
}

#[test]
fn tb_tm_runs_a_treelet_and_writes_a_vcd() {
    let t = Scratch::new("cli-tm");
    let vcd = t.join("tm.vcd");
    let o = run(&[
        "tb",
        "tm",
        "--scene",
        "builtin:cornell",
        "--treelet",
        "1",
        "--res",
        "16x16",
        "--vcd",
        vcd.to_str().unwrap(),
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(out.contains("PASS") && out.contains("TM cycles"), "{out}");
    let text = std::fs::read_to_string(&vcd).unwrap();
    assert!(text.contains("$scope module tp15 $end"));
    fails_with(
        &["tb", "tm", "--scene", "builtin:tiny", "--treelet", "3"],
        &["treelet 3 does not exist", "1 segments"],
    );
}

/// Trace options without `--vcd` would be ignored: refused, naming the fix.
#[test]
fn tb_trace_options_without_a_waveform_are_refused() {
    fails_with(&["tb", "box_pipe", "--trace", "box_pipe"], &["--vcd FILE"]);
    fails_with(
        &["tb", "box_pipe", "--trace-signals", "fsm"],
        &["--vcd FILE"],
    );
}

/// Every stimulus option is honoured or refused: `--cycles` bounds the
/// random benches (the hit record updater sends fewer updates in 100 cycles
/// than in 10,000), and a directed or scripted bench refuses the options it
/// does not read, naming the benches that take them; the report says what
/// ran, and `--shadow` that its check ran.
#[test]
fn stimulus_options_are_honoured_or_refused() {
    let requests = |cycles: &str| {
        let o = run(&["tb", "hru", "--cycles", cycles]);
        let out = String::from_utf8_lossy(&o.stdout).to_string();
        assert!(o.status.success(), "{out}");
        assert!(out.contains(&format!("random, {cycles} cycles")), "{out}");
        let line = out.lines().find(|l| l.contains("requests")).unwrap();
        line.split_whitespace()
            .nth(1)
            .unwrap()
            .parse::<u64>()
            .unwrap()
    };
    let (short, long) = (requests("100"), requests("10000"));
    assert!(short > 0 && short * 4 < long, "{short} vs {long}");
    fails_with(
        &["tb", "l1", "--cycles", "100"],
        &[
            "tb l1 runs a directed script",
            "--cycles does not apply",
            "box_pipe",
        ],
    );
    fails_with(
        &["tb", "stream_scheduler", "--load", "0.3"],
        &["--load does not apply", "it reads --ready"],
    );
    fails_with(&["tb", "tm", "--ready", "0.5"], &["--ready does not apply"]);
    let o = run(&["tb", "divider", "--cycles", "200", "--shadow"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && out.contains("shadow: every sleeping unit"),
        "{out}"
    );
    let o = run(&["tb", "scene_buffer"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("stimulus: a fixed script"), "{out}");
    assert!(!out.contains("latency min 0 max 0"), "{out}");
}

/// `tb` takes `render`'s trace flags: `--trace-units` and `--trace-window
/// A..B` write the same waveform as `--trace` with `--trace-from A
/// --trace-to B-1`.
#[test]
fn tb_takes_renders_trace_flags() {
    let t = Scratch::new("cli-tb-flags");
    let wave = |name: &str, extra: &[&str]| {
        let p = t.join(name);
        let mut a = vec![
            "tb",
            "box_pipe",
            "--cycles",
            "200",
            "--vcd",
            p.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        let o = run(&a);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(&p).unwrap()
    };
    let a = wave(
        "a.vcd",
        &["--trace-units", "box_pipe", "--trace-window", "10..20"],
    );
    let b = wave(
        "b.vcd",
        &[
            "--trace",
            "box_pipe",
            "--trace-from",
            "10",
            "--trace-to",
            "19",
        ],
    );
    assert!(a.len() > 100);
    assert_eq!(a, b);
    let c = wave("c.vcd", &["--trace-window", "10..30"]);
    assert_ne!(a, c, "the window matters");
}
