//! A trace window in the user's terms: `tb`'s `--trace-from/--trace-to`
//! count the bench's own clock (the DRAM clock for `tb mem_ctrl`), and the
//! size guard and the window checks state the window in the cycles given.

use std::process::Command;

use crate::common::Scratch;
use crate::dualstream;

fn fails(args: &[&str]) -> String {
    let o = Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args(args)
        .output()
        .unwrap();
    assert!(!o.status.success(), "{args:?} succeeded");
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Timestamps of a VCD.
fn times(p: &std::path::Path) -> Vec<u64> {
    std::fs::read_to_string(p)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix('#')?.parse().ok())
        .collect()
}

/// `tb mem_ctrl --trace-from 100 --trace-to 120` traces DRAM cycles 100 to
/// 120 (500 ps each), as `--cycles` counts them; a core-clock bench's window
/// counts core cycles. An impossible window is refused naming the clock.
#[test]
fn tb_windows_count_the_benchs_own_clock() {
    let d = Scratch::new("wave-tb-window");
    for (unit, period) in [("mem_ctrl", 500), ("box_pipe", 1000)] {
        let p = d.join(format!("{unit}.vcd"));
        dualstream(&[
            "tb",
            unit,
            "--cycles",
            "400",
            "--vcd",
            p.to_str().unwrap(),
            "--trace-from",
            "100",
            "--trace-to",
            "120",
        ]);
        let t = times(&p);
        assert_eq!(t.first(), Some(&(100 * period)), "{unit}: {t:?}");
        assert_eq!(t.last(), Some(&(120 * period)), "{unit}: {t:?}");
    }
    let p = d.join("x.vcd");
    let v = p.to_str().unwrap();
    let e = fails(&[
        "tb",
        "mem_ctrl",
        "--vcd",
        v,
        "--trace-from",
        "30",
        "--trace-to",
        "20",
    ]);
    assert!(
        e.contains("ends before it starts") && e.contains("dram clock"),
        "{e}"
    );
    let e = fails(&[
        "tb",
        "mem_ctrl",
        "--cycles",
        "100",
        "--vcd",
        v,
        "--trace-from",
        "100000",
    ]);
    assert!(
        e.contains("before the trace window starts at cycle 100000 of clk_dram"),
        "{e}"
    );
    let e = fails(&[
        "tb",
        "mem_ctrl",
        "--vcd",
        v,
        "--trace-from",
        &u64::MAX.to_string(),
    ]);
    assert!(
        e.contains("no run reaches that cycle of the dram clock"),
        "{e}"
    );
    assert!(!p.exists(), "no file for a refused window");
    let help = Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args(["tb", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    let line = help.lines().find(|l| l.contains("mem_ctrl (")).unwrap();
    assert!(line.contains("dram clock"), "{line}");
}

/// The guard's refusal states the window as given, in core cycles, with its
/// length: not counted from 0, nor in the DRAM clock's cycles of a trace that
/// holds a channel controller.
#[test]
fn the_size_guard_states_the_window() {
    let d = Scratch::new("wave-guard-window");
    let cfg = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/examples/chip-8tms.toml");
    let vcd = d.join("g.vcd");
    let png = d.join("g.png");
    let e = fails(&[
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
        vcd.to_str().unwrap(),
        "--trace-units",
        "tm0,mem_ctrl0",
        "--trace-window",
        "20000..40000",
        "--trace-max-bytes",
        "100K",
    ]);
    assert!(
        e.contains("over cycles 20000 to 39999 of clk_core (20000 cycles)"),
        "{e}"
    );
    assert!(
        !vcd.exists() && !png.exists(),
        "no file for a refused trace"
    );
}
