//! `dualstream dram`: trace generation and replay, and bad traces and presets.

use crate::common::Scratch;
use crate::{fails_with, run};

#[test]
fn dram_generates_replays_and_rejects_bad_input() {
    let t = Scratch::new("cli-dram");
    let trace = t.join("mixed.trc");
    let o = run(&[
        "dram",
        "--generate",
        "mixed",
        "--requests",
        "3000",
        "--out",
        trace.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for (preset, energy) in [("paper", "paper"), ("dramsim3-gddr5", "physical")] {
        let o = run(&[
            "dram",
            "--trace",
            trace.to_str().unwrap(),
            "--preset",
            preset,
            "--energy",
            energy,
            "--check",
        ]);
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(
            out.contains(&format!("preset {preset}, energy preset {energy}")),
            "{out}"
        );
        assert!(out.contains("requests 3000") && out.contains("timing checker: 0 violations"));
        assert!(out.contains("nJ per"), "{out}");
    }
    let bad = t.join("bad.trc");
    std::fs::write(&bad, "0x40 READ 1\n0x80 READ x\n").unwrap();
    fails_with(
        &["dram", "--trace", bad.to_str().unwrap()],
        &["trace line 2", "cycle 'x'"],
    );
    std::fs::write(&bad, "0xFFFFFFFFFF READ 1\n").unwrap();
    fails_with(
        &["dram", "--trace", bad.to_str().unwrap()],
        &["line 1", "beyond the configured capacity"],
    );
    fails_with(
        &["dram", "--generate", "zigzag"],
        &["unknown trace generator"],
    );
    fails_with(
        &["dram", "--generate", "random", "--preset", "ddr9"],
        &["unknown memory preset"],
    );
    fails_with(
        &["dram", "--generate", "random", "--energy", "solar"],
        &["unknown energy preset"],
    );
    fails_with(&["dram"], &["nothing to do"]);
    let cfg = t.join("badmem.toml");
    std::fs::write(&cfg, "[mem.timing]\ntRC = 10\n").unwrap();
    fails_with(
        &[
            "--config",
            cfg.to_str().unwrap(),
            "dram",
            "--generate",
            "random",
        ],
        &["tRC = 10 < tRAS + tRP"],
    );
    std::fs::write(&cfg, "[mem.geometry]\nchannels = 0\n").unwrap();
    fails_with(
        &[
            "--config",
            cfg.to_str().unwrap(),
            "dram",
            "--generate",
            "random",
        ],
        &["channels = 0"],
    );
}
