//! A window's first values: every traced signal is written at the window's
//! first time (as an RTL simulator's `$dumpvars`), so nothing is unknown
//! once it starts, and what it shows from then on is what a trace of the
//! whole run shows.

use crate::common::Scratch;
use crate::read::Wave;
use crate::{chip_trace, dualstream, have, read};

/// Every variable has a value at `from` that is no `x` and no NaN.
fn check_defined_from(w: &Wave, from: u64, what: &str) {
    assert!(w.vars.len() > 30, "{what}: {} variables", w.vars.len());
    for p in w.vars.keys() {
        let c = w.changes.get(p).map_or(&[][..], Vec::as_slice);
        let first = c.first();
        assert!(
            first.is_some_and(|(t, _)| *t == from),
            "{what}: {p} has no value at the window's start {from}: first {first:?}"
        );
        for (t, v) in c {
            assert!(
                !v.contains('x') && !v.contains("NaN") && !v.contains("nan"),
                "{what}: {p} is {v} at {t}"
            );
        }
    }
}

/// From the start of the window on, every signal has the value a trace of
/// the whole run shows (the held data of a port with no payload is the last
/// payload it showed, before the window too).
fn check_same_from(whole: &Wave, window: &Wave, from: u64, what: &str) {
    assert_eq!(whole.vars, window.vars, "{what}: the same variables");
    let mut compared = 0;
    for (p, c) in &window.changes {
        let times = whole.changes[p]
            .iter()
            .map(|(t, _)| *t)
            .chain(c.iter().map(|(t, _)| *t))
            .filter(|t| *t >= from && *t <= window.end);
        for t in times.chain([from]) {
            assert_eq!(whole.at(p, t), window.at(p, t), "{what}: {p} at {t} ps");
            compared += 1;
        }
    }
    assert!(compared > 1000, "{what}: {compared} values compared");
}

/// A chip window across both clock domains and a DRAM-clock unit bench, as
/// VCD and FST: every signal has a value at the window's first time, and it
/// is the value the whole run's trace has then (a port's data before its
/// first payload in the window too). With a DRAM clock whose edges miss the
/// window's start, its units are written there too.
#[test]
fn every_signal_has_its_value_from_the_window_start() {
    let d = Scratch::new("wave-initial");
    let fst = have("fst2vcd");
    for ext in ["vcd", "fst"].into_iter().filter(|e| *e == "vcd" || fst) {
        let load = |p: &std::path::Path| {
            if ext == "vcd" {
                read::vcd(p)
            } else {
                read::fst(p).0
            }
        };
        let (whole, win) = (d.join(format!("whole.{ext}")), d.join(format!("win.{ext}")));
        let units = "chip.tm0.tp0,chip.tm0.l1,scheduler,l2,mem_ctrl0";
        chip_trace(&whole, units, "0..12600", &[]);
        chip_trace(&win, units, "12000..12600", &[]);
        let (a, b) = (load(&whole), load(&win));
        check_defined_from(&a, 0, &format!("chip from 0 ({ext})"));
        check_defined_from(&b, 12_000_000, &format!("chip window ({ext})"));
        check_same_from(&a, &b, 12_000_000, &format!("chip ({ext})"));

        let tb = |p: &std::path::Path, extra: &[&str]| {
            let mut a = vec!["tb", "mem_ctrl", "--cycles", "400", "--seed", "3"];
            a.extend_from_slice(&["--vcd", p.to_str().unwrap()]);
            a.extend_from_slice(extra);
            dualstream(&a);
        };
        let (whole, win) = (d.join(format!("tw.{ext}")), d.join(format!("tn.{ext}")));
        tb(&whole, &[]);
        tb(&win, &["--trace-from", "300"]);
        let (a, b) = (load(&whole), load(&win));
        // `--trace-from` counts the bench's own (DRAM, 500 ps) clock.
        check_defined_from(&b, 300 * 500, &format!("tb mem_ctrl ({ext})"));
        check_same_from(&a, &b, 300 * 500, &format!("tb mem_ctrl ({ext})"));
    }
    // DRAM edges every 700 ps: core cycle 12000 (12,000,000 ps) is none.
    let cfg = d.join("dram700.toml");
    let base = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/docs/examples/chip-8tms.toml"
    ))
    .unwrap();
    std::fs::write(
        &cfg,
        format!("{base}\n[clocks]\ncore_ps = 1000\ndram_ps = 700\n"),
    )
    .unwrap();
    let win = d.join("d700.vcd");
    let png = d.join("d700.png");
    dualstream(&[
        "--config",
        cfg.to_str().unwrap(),
        "render",
        "--mode",
        "cycle",
        "--res",
        "8x8",
        "--out",
        png.to_str().unwrap(),
        "--vcd",
        win.to_str().unwrap(),
        "--trace-units",
        "chip.tm0.tp0,mem_ctrl0",
        "--trace-window",
        "12000..12100",
    ]);
    check_defined_from(&read::vcd(&win), 12_000_000, "DRAM at 700 ps");
}
