//! The reference RTL (`hdl/ref/`) against the model: vectors captured from a
//! frame (`render --capture`), a testbench generated from the unit's
//! declaration (`hdl --testbench`), run under Icarus and Verilator. The
//! skeleton and a planted fault must fail the same check.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;
use common::{Scratch, have};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn ds(args: &[&str]) -> Output {
    let o = Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "dualstream {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// Vectors of `instance` (module `module`) over cycles 0..`cycles` of the
/// builtin Cornell box (no mesh files needed: CI has none) at 64x64 on the
/// default chip, and the testbenches of both modes: (vectors, cycle-mode tb,
/// order-mode tb).
fn capture(t: &Scratch, instance: &str, module: &str, cycles: u64) -> (PathBuf, PathBuf, PathBuf) {
    let s = |p: &Path| p.to_str().unwrap().to_string();
    ds(&[
        "render",
        "--scene",
        "cornell",
        "--mode",
        "cycle",
        "--res",
        "64x64",
        "--out",
        &s(&t.join("f.png")),
        "--capture",
        instance,
        "--capture-window",
        &format!("0..{cycles}"),
        "--capture-dir",
        &s(&t.join("vec")),
    ]);
    let v = t.join(format!("vec/chip.{instance}.vec"));
    for (mode, dir) in [("cycle", "tbc"), ("order", "tbo")] {
        let o = ds(&[
            "hdl",
            "--testbench",
            module,
            "--vectors",
            &s(&v),
            "--out",
            &s(&t.join(dir)),
            "--mode",
            mode,
        ]);
        assert!(String::from_utf8_lossy(&o.stdout).contains(&format!("{cycles} cycles")));
    }
    let tb = |d: &str| t.join(d).join(format!("tb_{module}.sv"));
    (v, tb("tbc"), tb("tbo"))
}

/// The staging buffer of TM 0 over the first 5,000 cycles.
fn capture_sb(t: &Scratch) -> (PathBuf, PathBuf, PathBuf) {
    capture(t, "tm0.staging_buffer", "staging_buffer", SB_CYCLES)
}
const SB_CYCLES: u64 = 5000;

/// The hit record updater over the first `cycles` cycles: its first
/// updates arrive near cycle 6,400, and near 18,000 the first merge whose
/// order matters (a closer hit over a farther one of the same ray).
fn capture_hru(t: &Scratch, cycles: u64) -> (PathBuf, PathBuf, PathBuf) {
    capture(t, "hit_updater", "hit_record_updater", cycles)
}

fn pkg() -> PathBuf {
    repo().join("hdl/ds_pkg.sv")
}
fn reference(module: &str) -> PathBuf {
    repo().join(format!("hdl/ref/{module}.sv"))
}
fn skeleton(module: &str) -> PathBuf {
    repo().join(format!("hdl/{module}.v"))
}

/// Compiles and runs `tb` with `dut` under Icarus (with `-D` defines).
fn icarus(t: &Scratch, dut: &Path, tb: &Path, defines: &[&str]) -> Output {
    let out = t.join("sim.vvp");
    let mut c = Command::new("iverilog");
    c.arg("-g2012").arg("-o").arg(&out);
    for d in defines {
        c.arg(format!("-D{d}"));
    }
    common::succeeds(c.arg(pkg()).arg(dut).arg(tb), "iverilog");
    Command::new("vvp").arg("-n").arg(&out).output().unwrap()
}

/// Builds and runs `tb` with `dut` under `verilator --binary -Wall`.
fn verilator(t: &Scratch, module: &str, tb: &Path, defines: &[&str], name: &str) -> Output {
    let dir = t.join(format!("obj_{name}"));
    let top = format!("tb_{module}");
    let dut = reference(module);
    let mut c = Command::new("verilator");
    c.args(["--binary", "-j", "1", "-Wall", "--top-module", &top])
        .arg("--Mdir")
        .arg(&dir)
        .args(["-o", "tb"]);
    for d in defines {
        c.arg(format!("+define+{d}"));
    }
    common::succeeds(c.arg(pkg()).arg(&dut).arg(tb), "verilator --binary");
    Command::new(dir.join("tb")).output().unwrap()
}

/// `o` passed every one of `rows` cycles, with more than `min` transfers.
fn passes(o: &Output, module: &str, rows: u64, min: u64, what: &str) -> String {
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        o.status.success() && out.contains(&format!("tb_{module}: PASS")),
        "{what} should pass: {out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // Every cycle checked, and rays moved in them.
    let line = out
        .lines()
        .find(|l| l.contains(&format!("{rows} vectors checked, ")))
        .unwrap_or_else(|| panic!("{out}"));
    let transfers: u64 = line
        .split("checked, ")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!(transfers > min && line.ends_with(" 0 mismatches"), "{line}");
    out
}

fn fails(o: &Output, module: &str, what: &str, needles: &[&str]) -> String {
    let out = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{what} should fail: {out}");
    assert!(out.contains(&format!("tb_{module}: FAIL")), "{what}: {out}");
    for n in needles {
        assert!(out.contains(n), "{what}: no '{n}' in {out}");
    }
    out
}

#[test]
fn staging_buffer_rtl_passes_under_icarus_where_the_skeleton_and_a_late_swap_fail() {
    if !have("iverilog") {
        return;
    }
    let t = Scratch::new("rtl-ref-icarus");
    let (v, tbc, tbo) = capture_sb(&t);
    let sb = "staging_buffer";
    let pass = |o: &Output, what: &str| passes(o, sb, SB_CYCLES, 10, what);
    pass(
        &icarus(&t, &reference(sb), &tbc, &[]),
        "the reference, cycle mode",
    );
    pass(
        &icarus(&t, &reference(sb), &tbo, &[]),
        "the reference, order mode",
    );
    // +wave=FILE: the unit's waveform, for side-by-side debugging.
    let wave = t.join("rtl.vcd");
    let o = Command::new("vvp")
        .arg("-n")
        .arg(t.join("sim.vvp"))
        .arg(format!("+wave={}", wave.display()))
        .output()
        .unwrap();
    passes(&o, sb, SB_CYCLES, 10, "the reference with a waveform");
    let vcd = std::fs::read_to_string(&wave).unwrap();
    assert!(
        vcd.contains("$scope module dut $end") && vcd.contains(" fill_valid $end"),
        "{}",
        &vcd[..vcd.len().min(2000)]
    );
    // The skeleton (outputs tied low): never ready, never a ray.
    fails(
        &icarus(&t, &skeleton(sb), &tbc, &[]),
        sb,
        "the skeleton, cycle mode",
        &[
            "cycle 0 port fill: expected ready=1 got 0",
            "stopped after 10 mismatches",
        ],
    );
    fails(
        &icarus(&t, &skeleton(sb), &tbo, &[]),
        sb,
        "the skeleton, order mode",
        &["port ray_0: ", "transfers not delivered within"],
    );
    // Swapping a cycle late: the first bucket's rays leave a cycle late, and
    // the report says which field of which ray differs.
    fails(
        &icarus(
            &t,
            &reference(sb),
            &tbc,
            &["STAGING_BUFFER_WRONG_LATE_SWAP"],
        ),
        sb,
        "the late swap, cycle mode",
        &[": expected valid=1 got 0", "expected .ray.dir.x="],
    );
    // Vectors of another unit are refused, naming it.
    let o = Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args(["hdl", "--testbench", "hit_record_updater", "--vectors"])
        .arg(&v)
        .arg("--out")
        .arg(t.join("x"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("module 'staging_buffer'"),
        "{e}"
    );
    assert!(!t.join("x/tb_hit_record_updater.sv").exists());
}

#[test]
fn staging_buffer_rtl_passes_under_verilator_where_a_late_swap_fails() {
    if !have("verilator") {
        return;
    }
    let t = Scratch::new("rtl-ref-verilator");
    let (_, tbc, _) = capture_sb(&t);
    let sb = "staging_buffer";
    passes(
        &verilator(&t, sb, &tbc, &[], "ref"),
        sb,
        SB_CYCLES,
        10,
        "the reference under Verilator",
    );
    fails(
        &verilator(&t, sb, &tbc, &["STAGING_BUFFER_WRONG_LATE_SWAP"], "late"),
        sb,
        "the late swap under Verilator",
        &[": expected valid=1 got 0"],
    );
}

/// `module`'s reference lints clean under `verilator -Wall`, and `yosys
/// synth` with `chparam` (a small size: the same logic, small memories;
/// the full sizes are in docs/rtl.md) gives more than `min_cells` cells.
fn lints_and_synthesizes(module: &str, chparam: &str, min_cells: u64) {
    let (p, r) = (pkg(), reference(module));
    if have("verilator") {
        common::succeeds(
            Command::new("verilator")
                .args(["--lint-only", "-Wall", "--top-module", module])
                .arg(&p)
                .arg(&r),
            "verilator --lint-only",
        );
    }
    if have("yosys") {
        let script = format!(
            "read_verilog -sv {} {}; chparam {chparam} {module}; synth -top {module}; stat",
            p.display(),
            r.display()
        );
        let cells = common::yosys_cells(&script);
        assert!(
            cells > min_cells,
            "a real netlist, not a skeleton's: {cells} cells"
        );
    }
}

#[test]
fn staging_buffer_rtl_lints_and_synthesizes() {
    // Two rays a half.
    lints_and_synthesizes("staging_buffer", "-set HALF_RAYS 2", 500);
}

const HRU: &str = "hit_record_updater";

#[test]
fn hit_record_updater_rtl_passes_under_icarus_where_the_skeleton_and_a_late_request_fail() {
    if !have("iverilog") {
        return;
    }
    let t = Scratch::new("rtl-ref-hru-icarus");
    // 10,000 cycles: Icarus takes about 3 ms a cycle once updates flow.
    let (_, tbc, _) = capture_hru(&t, 10_000);
    passes(
        &icarus(&t, &reference(HRU), &tbc, &[]),
        HRU,
        10_000,
        1000,
        "the reference, cycle mode",
    );
    fails(
        &icarus(&t, &skeleton(HRU), &tbc, &[]),
        HRU,
        "the skeleton",
        &[
            "cycle 0 port hit_0: expected ready=1 got 0",
            "stopped after 128 mismatches",
        ],
    );
    // One cycle more latency on the memory request: the first read is late.
    fails(
        &icarus(&t, &reference(HRU), &tbc, &["HRU_WRONG_LATENCY"]),
        HRU,
        "one cycle more latency",
        &["port mem_req: expected valid=1 got 0"],
    );
}

#[test]
fn hit_record_updater_rtl_passes_under_verilator_where_a_merge_keeping_the_farther_hit_fails() {
    if !have("verilator") {
        return;
    }
    let t = Scratch::new("rtl-ref-hru-verilator");
    let cycles = 20_000;
    let (_, tbc, tbo) = capture_hru(&t, cycles);
    passes(
        &verilator(&t, HRU, &tbc, &[], "ref"),
        HRU,
        cycles,
        5000,
        "the reference, cycle mode",
    );
    passes(
        &verilator(&t, HRU, &tbo, &[], "ref_order"),
        HRU,
        cycles,
        5000,
        "the reference, order mode",
    );
    // A merge that keeps the farther hit writes the wrong record: the
    // report names the request's data field.
    fails(
        &verilator(&t, HRU, &tbc, &["HRU_WRONG_MERGE"], "merge"),
        HRU,
        "a merge keeping the farther hit",
        &["port mem_req: expected .data="],
    );
}

#[test]
fn hit_record_updater_rtl_lints_and_synthesizes() {
    // Four ports, four queue entries, two in flight.
    lints_and_synthesizes(HRU, "-set TMS 4 -set QUEUE 4 -set IN_FLIGHT 2", 5000);
}
