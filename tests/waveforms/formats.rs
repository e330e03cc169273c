//! FST and VCD: one trace, two formats, the same values.

use crate::common::Scratch;
use crate::{chip_trace, dualstream, have, read};

/// A box-pipe testbench and a small chip window, traced once as VCD and once
/// as FST: every variable and every change agree.
#[test]
fn fst_and_vcd_hold_the_same_values() {
    if !have("fst2vcd") {
        return;
    }
    let d = Scratch::new("wave-formats");
    for ext in ["vcd", "fst"] {
        let p = d.join(format!("tb.{ext}"));
        dualstream(&[
            "tb",
            "box_pipe",
            "--cycles",
            "300",
            "--seed",
            "5",
            "--vcd",
            p.to_str().unwrap(),
        ]);
    }
    let v = read::vcd(&d.join("tb.vcd"));
    let (f, _) = read::fst(&d.join("tb.fst"));
    assert!(v.vars.len() > 10 && v.changes.values().map(Vec::len).sum::<usize>() > 500);
    assert_eq!(v.vars, f.vars, "the same variables, widths and kinds");
    assert_eq!(v.end, f.end, "the same end time");
    for (p, ch) in &v.changes {
        // FST records each variable's value at its first time; VCD only
        // its changes: compare the changes.
        let dedup = |c: &Vec<(u64, String)>| {
            let mut out: Vec<(u64, String)> = Vec::new();
            for x in c {
                if out.last().is_none_or(|l| l.1 != x.1) {
                    out.push(x.clone());
                }
            }
            out
        };
        assert_eq!(dedup(ch), dedup(&f.changes[p]), "changes of {p}");
    }
}

/// Every register the model declares as an FSM state carries an enum table
/// in FST (GTKWave and Surfer show names with no filter file) and is `reg`,
/// while each port's valid, ready and data are `wire` (a register whose name
/// starts with a port's, like the TP's `ray_index` beside port `ray`, is no
/// port signal).
#[test]
fn fsm_states_are_named_and_registers_are_regs() {
    if !have("fst2vcd") {
        return;
    }
    let d = Scratch::new("wave-enums");
    for ext in ["vcd", "fst"] {
        let p = d.join(format!("c.{ext}"));
        chip_trace(&p, "chip.tm0.tp0,mem_ctrl0", "1000..1400", &[]);
    }
    let v = read::vcd(&d.join("c.vcd"));
    let (f, ext) = read::fst(&d.join("c.fst"));
    assert_eq!(v.vars, f.vars);
    let tp = "chip.tm0.tp0";
    assert_eq!(v.vars[&format!("{tp}.ray_index")].kind, "reg");
    assert_eq!(v.vars[&format!("{tp}.state")].kind, "reg");
    assert_eq!(v.vars[&format!("{tp}.ray_valid")].kind, "wire");
    // fst2vcd -e writes an enum table as `$attrbegin misc 07 <name> <count>
    // <names...> <values...> $end`, and a reference to one before each
    // variable that uses it.
    let tables: Vec<&str> = ext
        .lines()
        .filter(|l| l.starts_with("$attrbegin misc 07 ") && !l.contains("\"\""))
        .collect();
    let tp_table = tables
        .iter()
        .find(|l| l.contains(" Idle Fetch DivWait "))
        .expect("the TP's state table");
    assert!(
        tp_table.contains(" ShDone ") && tp_table.contains(" 00000 "),
        "{tp_table}"
    );
    // Each `state` variable follows a table reference.
    let lines: Vec<&str> = ext.lines().collect();
    let mut states = 0;
    for (k, l) in lines.iter().enumerate() {
        if l.starts_with("$var ") && l.contains(" state ") {
            states += 1;
            assert!(
                lines[k - 1].starts_with("$attrbegin misc 07 "),
                "no enum table before {l}"
            );
        }
    }
    assert!(states >= 1);
}

/// The tracer samples a unit only when it ran, a link of its moved, a head
/// became visible to it or its state moves on its own; sampling every unit at
/// every edge (`--trace-every-edge`) must write the very same file. On a chip
/// window across both clock domains (TPs, the L1, crossbar and pipelines of a
/// TM, the scheduler, the L2 and a GDDR5 channel) and on unit benches.
#[test]
fn sampling_on_activity_writes_what_sampling_every_edge_writes() {
    let d = Scratch::new("wave-activity");
    let read = |p: &std::path::Path| std::fs::read(p).unwrap();
    for every in [false, true] {
        let p = d.join(format!("c{every}.vcd"));
        let extra: &[&str] = if every { &["--trace-every-edge"] } else { &[] };
        chip_trace(&p, "chip.tm0,scheduler,l2,mem_ctrl0", "11000..14000", extra);
        for (unit, extra) in [
            ("mem_ctrl", "--cycles=400"),
            ("hit_record_updater", "--cycles=400"),
            ("box_pipe", "--cycles=400"),
        ] {
            let p = d.join(format!("{unit}{every}.vcd"));
            let mut a = vec![
                "tb",
                unit,
                extra,
                "--seed",
                "2",
                "--vcd",
                p.to_str().unwrap(),
            ];
            if every {
                a.push("--trace-every-edge");
            }
            dualstream(&a);
        }
    }
    let chip = read(&d.join("cfalse.vcd"));
    assert!(
        chip.len() > 1_000_000,
        "a busy window: {} bytes",
        chip.len()
    );
    assert!(
        chip == read(&d.join("ctrue.vcd")),
        "chip window: the two samplings differ"
    );
    for unit in ["mem_ctrl", "hit_record_updater", "box_pipe"] {
        let a = read(&d.join(format!("{unit}false.vcd")));
        assert!(
            a == read(&d.join(format!("{unit}true.vcd"))),
            "tb {unit}: the two samplings differ"
        );
    }
    // Links of delay 3: a head becomes visible two cycles after anything
    // moved (the rule that wakes a unit's sampling when it does).
    let cfg = d.join("delay3.toml");
    std::fs::write(
        &cfg,
        "[links.tm]\ndepth = 4\ndelay = 3\n[tm.l1]\nhit_latency = 4\n",
    )
    .unwrap();
    for unit in ["box_pipe", "divider"] {
        let files: Vec<Vec<u8>> = [false, true]
            .into_iter()
            .map(|every| {
                let p = d.join(format!("{unit}-d3-{every}.vcd"));
                let mut a = vec![
                    "--config",
                    cfg.to_str().unwrap(),
                    "tb",
                    unit,
                    "--cycles=400",
                    "--seed",
                    "2",
                ];
                a.extend(["--vcd", p.to_str().unwrap()]);
                if every {
                    a.push("--trace-every-edge");
                }
                dualstream(&a);
                read(&p)
            })
            .collect();
        assert!(
            files[0] == files[1],
            "tb {unit} on delay-3 links: the two samplings differ"
        );
    }
}

/// `--trace-signals` and `--trace-max-width` trim what the file holds (as
/// Verilator's --trace-depth and --trace-max-width do) and nothing else: the
/// signals kept carry the same changes as in the whole trace.
#[test]
fn trace_signals_and_max_width_trim_the_file() {
    let d = Scratch::new("wave-trim");
    let (all, trim) = (d.join("all.vcd"), d.join("trim.vcd"));
    let t = |p: &std::path::Path, extra: &[&str]| {
        let mut a = vec![
            "tb",
            "mem_ctrl",
            "--cycles",
            "300",
            "--seed",
            "4",
            "--vcd",
            p.to_str().unwrap(),
        ];
        a.extend_from_slice(extra);
        dualstream(&a);
    };
    t(&all, &[]);
    t(
        &trim,
        &["--trace-signals", "ports,fsm", "--trace-max-width", "8"],
    );
    let (a, b) = (read::vcd(&all), read::vcd(&trim));
    assert!(
        b.vars.len() < a.vars.len() / 2,
        "{} of {} signals",
        b.vars.len(),
        a.vars.len()
    );
    for (p, v) in &b.vars {
        assert!(v.width <= 8, "{p} is {} bits", v.width);
        assert!(!p.ends_with("_data"), "{p}: data left out");
        assert_eq!(a.vars.get(p), Some(v), "{p} as in the whole trace");
        assert_eq!(a.changes.get(p), b.changes.get(p), "{p}: the same changes");
    }
    assert!(
        b.vars.keys().any(|p| p.ends_with("tb.mem_ctrl.cmd")),
        "the DRAM command FSM is kept"
    );
    assert!(b.vars.keys().any(|p| p.ends_with("tb.mem_ctrl.req_fire")));
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args([
            "tb",
            "box_pipe",
            "--vcd",
            d.join("x.vcd").to_str().unwrap(),
            "--trace-signals",
            "ports,wires",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("'wires'") && err.contains("fsm, regs"),
        "{err}"
    );
    assert!(!d.join("x.vcd").exists(), "no file for a refused trace");
}

/// Mistakes a user makes get an error and leave no file: a trace of FSMs
/// alone works (no port signals at all), a window after the run's end is
/// refused, and a render refused for an unknown unit leaves neither its
/// image nor its trace behind.
#[test]
fn trimmed_late_and_refused_traces_leave_no_wrong_file() {
    let d = Scratch::new("wave-mistakes");
    let fsm = d.join("fsm.vcd");
    dualstream(&[
        "tb",
        "mem_ctrl",
        "--cycles",
        "200",
        "--vcd",
        fsm.to_str().unwrap(),
        "--trace-signals",
        "fsm",
    ]);
    let w = read::vcd(&fsm);
    assert!(w.vars.keys().any(|p| p.ends_with("tb.mem_ctrl.cmd")));
    assert!(
        w.vars
            .keys()
            .all(|p| !p.contains("_valid") && !p.contains("_fire")),
        "{:?}",
        w.vars.keys()
    );
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_dualstream"))
            .args(args)
            .output()
            .unwrap()
    };
    let late = d.join("late.fst");
    let o = run(&[
        "tb",
        "box_pipe",
        "--cycles",
        "100",
        "--vcd",
        late.to_str().unwrap(),
        "--trace-from",
        "100000",
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("before the trace window starts"),
        "{err}"
    );
    assert!(!late.exists(), "no empty FST");
    let (png, vcd) = (d.join("r.png"), d.join("r.vcd"));
    let o = run(&[
        "render",
        "--mode",
        "cycle",
        "--res",
        "8x8",
        "--out",
        png.to_str().unwrap(),
        "--vcd",
        vcd.to_str().unwrap(),
        "--trace-units",
        "tm999",
    ]);
    assert!(!o.status.success());
    assert!(
        !png.exists() && !vcd.exists(),
        "a refused render leaves no empty outputs"
    );
}
