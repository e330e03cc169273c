//! One name per unit in `tb` and `render`: each takes the other's name for a
//! unit (`stream_scheduler` and `scheduler`), and lists its own names with
//! the others beside them.

use std::process::Command;

use dualstream::machine::trace::resolve;
use dualstream::testbench;

/// The 8-TM chip's instances, as `render` sees them.
const PATHS: &[&str] = &[
    "chip.host",
    "chip.scheduler",
    "chip.scene_buffer",
    "chip.hit_updater",
    "chip.memory",
    "chip.mem_ctrl0",
    "chip.l2",
    "chip.tm0.tp0",
    "chip.tm0.staging_buffer",
    "chip.tm0.l1",
    "chip.tm0.xbar",
    "chip.tm0.tri_pipe0",
    "chip.tm0.divider",
];

/// Every bench whose unit is on the chip names it for `render` too, by its
/// name and each of its other names, and `tb` takes render's names for the
/// global units.
#[test]
fn tb_and_render_take_each_others_unit_names() {
    assert_eq!(
        resolve("stream_scheduler", PATHS).unwrap(),
        resolve("scheduler", PATHS).unwrap()
    );
    assert_eq!(
        resolve("hit_record_updater", PATHS).unwrap(),
        resolve("hit_updater", PATHS).unwrap()
    );
    for b in testbench::BENCHES {
        // The box pipeline is no instance of the chip's TMs.
        if b.name == "box_pipe" {
            continue;
        }
        for n in std::iter::once(&b.name).chain(b.aliases) {
            let f = resolve(n, PATHS).unwrap_or_else(|e| panic!("render --trace-units {n}: {e}"));
            assert!(!f.is_empty(), "{n}");
        }
    }
    assert_eq!(
        testbench::find("scheduler").unwrap().name,
        "stream_scheduler"
    );
    assert_eq!(
        testbench::find("hit_updater").unwrap().name,
        "hit_record_updater"
    );
    // The errors list each name with its others.
    let e = resolve("sched", PATHS).unwrap_err().to_string();
    assert!(
        e.contains("scheduler (the stream scheduler; also stream_scheduler)"),
        "{e}"
    );
    let e = testbench::find("sched").err().unwrap().to_string();
    assert!(e.contains("stream_scheduler (scheduler)"), "{e}");
}

/// `tb stream_scheduler --trace scheduler` traces the scheduler's instance
/// (`tb.stream_scheduler`), as `tb scheduler` runs its bench.
#[test]
fn tb_trace_takes_a_benchs_other_name() {
    let d = crate::common::Scratch::new("wave-names");
    let p = d.join("s.vcd");
    crate::dualstream(&[
        "tb",
        "scheduler",
        "--vcd",
        p.to_str().unwrap(),
        "--trace",
        "scheduler",
    ]);
    let w = crate::read::vcd(&p);
    assert!(w.modules.contains("tb.stream_scheduler"), "{:?}", w.modules);
    assert!(!w.modules.contains("tb.host"), "{:?}", w.modules);
    let o = Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args(["tb", "--help"])
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&o.stdout).contains("stream_scheduler (scheduler)"));
}
