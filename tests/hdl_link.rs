//! `hdl/ref/ds_link.sv` against the model's link (`src/rtl/link.rs`), cycle for
//! cycle: a producer and a consumer unit drive a model link with random offers
//! (a refused payload held until taken) and random stalls, record both sides
//! as vectors (docs/rtl.md, "Vectors"), and `hdl/ref/ds_link_tb.sv` replays
//! them into the RTL under Icarus (and Verilator for one shape). Planted: a
//! link that returns its credit a cycle early and one with a cycle more delay
//! must fail the same check.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use dualstream::rtl::{Ctx, LinkCfg, Logic, Next, Sim, SimOptions};
use dualstream::util::rng::Rng;

mod common;
use common::{Scratch, have};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// One cycle as the vectors hold it: the producer's (valid, data, ready) and
/// the consumer's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Row {
    push: (bool, u32, bool),
    pop: (bool, u32, bool),
}

dualstream::unit! {
    /// Offers a fresh random payload on random cycles and holds a refused one
    /// until it is taken (valid/ready's rule); records what it drove and the
    /// ready it saw.
    pub struct Source : "source" {
        new(seed: u64, rate: u32; ports: SourcePorts) {}
        params { }
        inputs { }
        outputs { out: u32 }
        state { }
        extra { rng: Rng = Rng::new(seed), rate: u32 = rate, held: Option<u32> = None,
                rows: Vec<(bool, u32, bool)> = Vec::new() }
    }
}
impl Logic for Source {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let ready = ctx.can_push(&self.out);
        if self.held.is_none() && self.rng.below(100) < self.rate as u64 {
            self.held = Some(self.rng.next_u32());
        }
        match self.held {
            Some(v) => {
                if ctx.offer(&self.out, v) {
                    self.held = None;
                }
                self.rows.push((true, v, ready));
            }
            None => self.rows.push((false, 0, ready)),
        }
        Next::Cycle
    }
}

dualstream::unit! {
    /// Ready on random cycles; pops when ready and the head is visible;
    /// records the head it saw and its ready.
    pub struct Drain : "drain" {
        new(seed: u64, rate: u32; ports: DrainPorts) {}
        params { }
        inputs { inp: u32 }
        outputs { }
        state { }
        extra { rng: Rng = Rng::new(seed), rate: u32 = rate,
                rows: Vec<(bool, u32, bool)> = Vec::new() }
    }
}
impl Logic for Drain {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        // Phases of 150 cycles: draining at `rate`, then slowly (the FIFO fills).
        let rate = if ctx.cycle() / 150 % 2 == 0 {
            self.rate
        } else {
            10
        };
        let ready = self.rng.below(100) < rate as u64;
        let head = ctx.peek(&self.inp).copied();
        if ready && head.is_some() {
            ctx.pop(&self.inp);
        }
        self.rows.push((head.is_some(), head.unwrap_or(0), ready));
        Next::Cycle
    }
}

/// `cycles` cycles of a model link of `cfg` under random traffic.
fn model_rows(cfg: LinkCfg, seed: u64, cycles: u64) -> Vec<Row> {
    let mut sim = Sim::new(SimOptions::default());
    let c = sim.clock("core", 1000).unwrap();
    let (o, i) = sim.link::<u32>("link", cfg);
    // Bursts and stalls on both sides: rates from the seed.
    let (pr, cr) = (40 + (seed % 5) as u32 * 15, 30 + (seed % 7) as u32 * 10);
    let s = sim.add("src", c, Source::new(seed, pr, SourcePorts { out: o }));
    let d = sim.add(
        "drain",
        c,
        Drain::new(seed ^ 0xD1, cr, DrainPorts { inp: i }),
    );
    sim.run(cycles * 1000 - 1).unwrap();
    let src = &sim.unit_ref::<Source>(s).rows;
    let dst = &sim.unit_ref::<Drain>(d).rows;
    assert_eq!(src.len() as u64, cycles);
    assert_eq!(dst.len() as u64, cycles);
    src.iter()
        .zip(dst)
        .map(|(&push, &pop)| Row { push, pop })
        .collect()
}

/// The vectors of one ds_link instance (docs/rtl.md, "Vectors").
fn vectors(cfg: LinkCfg, rows: &[Row]) -> String {
    let mut v = String::new();
    let _ = writeln!(v, "// dualstream vectors 1");
    let _ = writeln!(v, "// module ds_link");
    let _ = writeln!(v, "// instance link");
    let _ = writeln!(v, "// clock core 1000");
    let _ = writeln!(v, "// cycles 0 {}", rows.len());
    let _ = writeln!(v, "// from_reset 1");
    let _ = writeln!(
        v,
        "// params WIDTH 32 DEPTH {} DELAY {}",
        cfg.depth, cfg.delay
    );
    let _ = writeln!(v, "// port push in 32 -");
    let _ = writeln!(v, "// port pop out 32 -");
    for (k, r) in rows.iter().enumerate() {
        let _ = writeln!(
            v,
            "{k:x} {:x} {:08x} {:x} {:x} {:08x} {:x}",
            r.push.0 as u8, r.push.1, r.push.2 as u8, r.pop.0 as u8, r.pop.1, r.pop.2 as u8
        );
    }
    v
}

/// The RTL under test: `hdl/ref/ds_link.sv`, or a copy with `plant` applied
/// (a text replacement that must match).
fn rtl(dir: &Path, plant: Option<(&str, &str)>) -> PathBuf {
    let src = repo().join("hdl/ref/ds_link.sv");
    let Some((from, to)) = plant else {
        return src;
    };
    let text = std::fs::read_to_string(&src).unwrap();
    assert!(text.contains(from), "the planted fault no longer applies");
    let p = dir.join("ds_link_planted.sv");
    std::fs::write(&p, text.replace(from, to)).unwrap();
    p
}

/// Replays `vec` into `rtl` under Icarus with the link's parameters; returns
/// (passed, output).
fn icarus(dir: &Path, rtl: &Path, cfg: LinkCfg, vec: &Path) -> (bool, String) {
    let exe = dir.join("tb.vvp");
    let o = Command::new("iverilog")
        .args(["-g2012", "-o"])
        .arg(&exe)
        .args([
            "-P",
            "ds_link_tb.WIDTH=32",
            "-P",
            &format!("ds_link_tb.DEPTH={}", cfg.depth),
            "-P",
            &format!("ds_link_tb.DELAY={}", cfg.delay),
        ])
        .arg(rtl)
        .arg(repo().join("hdl/ref/ds_link_tb.sv"))
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "iverilog: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let o = Command::new("vvp")
        .arg("-n")
        .arg(&exe)
        .arg(format!("+vectors={}", vec.display()))
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    (o.status.success() && out.contains("PASS"), out)
}

/// The shapes checked: depth 1 to 5, delay 1 to 3, full throughput and not
/// (depth < delay + 1). Delay 0 is refused by the model (a combinational path).
const SHAPES: [(u32, u32); 6] = [(2, 1), (1, 1), (3, 2), (4, 3), (2, 3), (5, 1)];
const CYCLES: u64 = 3000;

#[test]
fn ds_link_matches_the_model_link_cycle_for_cycle() {
    assert!(
        LinkCfg { depth: 2, delay: 0 }.validate("x").is_err(),
        "the model allows delay 0: check it too"
    );
    if !have("iverilog") {
        return;
    }
    let dir = Scratch::new("ds-link");
    for (k, &(depth, delay)) in SHAPES.iter().enumerate() {
        let cfg = LinkCfg { depth, delay };
        let rows = model_rows(cfg, k as u64 + 1, CYCLES);
        // The traffic exercises the link: transfers, a full FIFO, stalls.
        let pushes = rows.iter().filter(|r| r.push.0 && r.push.2).count();
        let full = rows.iter().filter(|r| r.push.0 && !r.push.2).count();
        let stalled = rows.iter().filter(|r| r.pop.0 && !r.pop.2).count();
        assert!(
            pushes > 300 && full > 50 && stalled > 50,
            "{cfg:?}: {pushes} {full} {stalled}"
        );
        let vec = dir.join(format!("link_{depth}_{delay}.vec"));
        std::fs::write(&vec, vectors(cfg, &rows)).unwrap();
        let (ok, out) = icarus(&dir, &rtl(&dir, None), cfg, &vec);
        assert!(ok, "{cfg:?}: {out}");
        assert!(out.contains(&format!("PASS {CYCLES}")), "{out}");
    }
}

#[test]
fn the_link_check_catches_an_early_credit_and_a_longer_delay() {
    if !have("iverilog") {
        return;
    }
    let dir = Scratch::new("ds-link-planted");
    let cfg = LinkCfg { depth: 2, delay: 1 };
    let rows = model_rows(cfg, 7, CYCLES);
    let vec = dir.join("link.vec");
    std::fs::write(&vec, vectors(cfg, &rows)).unwrap();
    assert!(icarus(&dir, &rtl(&dir, None), cfg, &vec).0);
    // A pop frees its entry for the producer in the same cycle.
    let early = rtl(
        &dir,
        Some((
            "assign push_ready = held != FULL;",
            "assign push_ready = held != FULL || pop;",
        )),
    );
    let (ok, out) = icarus(&dir, &early, cfg, &vec);
    assert!(
        !ok && out.contains("push_ready"),
        "early credit not caught: {out}"
    );
    // A payload visible a cycle later: the RTL built with DELAY + 1.
    let (ok, out) = icarus(
        &dir,
        &rtl(&dir, None),
        LinkCfg {
            delay: cfg.delay + 1,
            ..cfg
        },
        &vec,
    );
    assert!(
        !ok && out.contains("pop_valid"),
        "longer delay not caught: {out}"
    );
}

/// The same replay under Verilator (`--binary`), for the default link.
#[test]
fn ds_link_matches_the_model_under_verilator() {
    if !have("verilator") {
        return;
    }
    let dir = Scratch::new("ds-link-verilator");
    let cfg = LinkCfg::default();
    let rows = model_rows(cfg, 11, CYCLES);
    let vec = dir.join("link.vec");
    std::fs::write(&vec, vectors(cfg, &rows)).unwrap();
    let o = Command::new("verilator")
        .args(["--binary", "-Wall", "-j", "1", "--top-module", "ds_link_tb"])
        .arg("--Mdir")
        .arg(dir.join("obj"))
        .args(["-GWIDTH=32", "-GDEPTH=2", "-GDELAY=1"])
        .arg(repo().join("hdl/ref/ds_link.sv"))
        .arg(repo().join("hdl/ref/ds_link_tb.sv"))
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "verilator: {}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let o = Command::new(dir.join("obj/Vds_link_tb"))
        .arg(format!("+vectors={}", vec.display()))
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && out.contains(&format!("PASS {CYCLES}")),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `hdl/ref/` is hand-written: lint-clean as the generated files, and left
/// alone by `dualstream hdl` (the drift test reads only `hdl/*.v`, `hdl/*.sv`).
#[test]
fn reference_link_lints_and_synthesizes() {
    let link = repo().join("hdl/ref/ds_link.sv");
    let text = std::fs::read_to_string(&link).unwrap();
    assert!(!text.contains("lint_off"));
    assert!(text.starts_with("// Hand-written reference RTL"));
    if have("verilator") {
        common::succeeds(
            Command::new("verilator")
                .args(["--lint-only", "-Wall"])
                .arg(&link),
            "verilator",
        );
    }
    if have("yosys") {
        let cells = common::yosys_cells(&format!(
            "read_verilog -sv {}; chparam -set WIDTH 64 ds_link; synth -top ds_link; stat",
            link.display()
        ));
        // 128 storage flops, 64 output multiplexers and the control.
        assert!((200..400).contains(&cells), "{cells} cells");
    }
}
