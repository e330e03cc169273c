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

/// The staging buffer of TM 0 over the first 5,000 cycles of the builtin
/// Cornell box (no mesh files needed: CI has none) at 64x64 on the default
/// chip, and
/// the testbenches of both modes: (vectors, cycle-mode tb, order-mode tb).
fn capture(t: &Scratch) -> (PathBuf, PathBuf, PathBuf) {
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let scene = PathBuf::from("cornell");
    ds(&[
        "render",
        "--scene",
        &s(&scene),
        "--mode",
        "cycle",
        "--res",
        "64x64",
        "--out",
        &s(&t.join("f.png")),
        "--capture",
        "tm0.staging_buffer",
        "--capture-window",
        "0..5000",
        "--capture-dir",
        &s(&t.join("vec")),
    ]);
    let v = t.join("vec/chip.tm0.staging_buffer.vec");
    for (mode, dir) in [("cycle", "tbc"), ("order", "tbo")] {
        let o = ds(&[
            "hdl",
            "--testbench",
            "staging_buffer",
            "--vectors",
            &s(&v),
            "--out",
            &s(&t.join(dir)),
            "--mode",
            mode,
        ]);
        assert!(String::from_utf8_lossy(&o.stdout).contains("5000 cycles"));
    }
    let tb = |d: &str| t.join(d).join("tb_staging_buffer.sv");
    (v, tb("tbc"), tb("tbo"))
}

fn pkg() -> PathBuf {
    repo().join("hdl/ds_pkg.sv")
}
fn reference() -> PathBuf {
    repo().join("hdl/ref/staging_buffer.sv")
}
fn skeleton() -> PathBuf {
    repo().join("hdl/staging_buffer.v")
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
fn verilator(t: &Scratch, dut: &Path, tb: &Path, defines: &[&str], name: &str) -> Output {
    let dir = t.join(format!("obj_{name}"));
    let mut c = Command::new("verilator");
    c.args([
        "--binary",
        "-j",
        "1",
        "-Wall",
        "--top-module",
        "tb_staging_buffer",
    ])
    .arg("--Mdir")
    .arg(&dir)
    .args(["-o", "tb"]);
    for d in defines {
        c.arg(format!("+define+{d}"));
    }
    common::succeeds(c.arg(pkg()).arg(dut).arg(tb), "verilator --binary");
    Command::new(dir.join("tb")).output().unwrap()
}

fn passes(o: &Output, what: &str) -> String {
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        o.status.success() && out.contains("tb_staging_buffer: PASS"),
        "{what} should pass: {out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // Every cycle checked, and rays moved in them.
    let line = out
        .lines()
        .find(|l| l.contains("5000 vectors checked, "))
        .unwrap_or_else(|| panic!("{out}"));
    let transfers: u64 = line
        .split("checked, ")
        .nth(1)
        .and_then(|r| r.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{line}"));
    assert!(transfers > 10 && line.ends_with(" 0 mismatches"), "{line}");
    out
}

fn fails(o: &Output, what: &str, needles: &[&str]) -> String {
    let out = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{what} should fail: {out}");
    assert!(out.contains("tb_staging_buffer: FAIL"), "{what}: {out}");
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
    let (v, tbc, tbo) = capture(&t);
    passes(
        &icarus(&t, &reference(), &tbc, &[]),
        "the reference, cycle mode",
    );
    passes(
        &icarus(&t, &reference(), &tbo, &[]),
        "the reference, order mode",
    );
    // The skeleton (outputs tied low): never ready, never a ray.
    fails(
        &icarus(&t, &skeleton(), &tbc, &[]),
        "the skeleton, cycle mode",
        &[
            "cycle 0 port fill: expected ready=1 got 0",
            "stopped after 10 mismatches",
        ],
    );
    fails(
        &icarus(&t, &skeleton(), &tbo, &[]),
        "the skeleton, order mode",
        &["port ray_0: ", "transfers not delivered within"],
    );
    // Swapping a cycle late: the first bucket's rays leave a cycle late, and
    // the report says which field of which ray differs.
    fails(
        &icarus(&t, &reference(), &tbc, &["STAGING_BUFFER_WRONG_LATE_SWAP"]),
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
    let (_, tbc, _) = capture(&t);
    passes(
        &verilator(&t, &reference(), &tbc, &[], "ref"),
        "the reference under Verilator",
    );
    fails(
        &verilator(
            &t,
            &reference(),
            &tbc,
            &["STAGING_BUFFER_WRONG_LATE_SWAP"],
            "late",
        ),
        "the late swap under Verilator",
        &[": expected valid=1 got 0"],
    );
}

#[test]
fn staging_buffer_rtl_lints_and_synthesizes() {
    let (p, r) = (pkg(), reference());
    if have("verilator") {
        common::succeeds(
            Command::new("verilator")
                .args(["--lint-only", "-Wall", "--top-module", "staging_buffer"])
                .arg(&p)
                .arg(&r),
            "verilator --lint-only",
        );
    }
    if have("yosys") {
        // Two rays a half: the same logic, a small memory (the full size is
        // in docs/rtl.md).
        let script = format!(
            "read_verilog -sv {} {}; chparam -set HALF_RAYS 2 staging_buffer; synth -top staging_buffer; stat",
            p.display(),
            r.display()
        );
        let cells = common::yosys_cells(&script);
        assert!(
            cells > 500,
            "a real netlist, not a skeleton's: {cells} cells"
        );
    }
}
