//! One declaration per unit: the VCD scope of every unit has exactly the ports and
//! registers of its Verilog module, at the same widths; the committed `hdl/` is what
//! the code emits; the Verilog passes verilator, iverilog and yosys; the VCD reads
//! back with an independent parser (the `vcd` crate) and with GTKWave's `vcd2fst`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use dualstream::config::Config;
use dualstream::machine::hdl::{catalog, write_hdl};
use dualstream::rtl::TraceSpec;
use dualstream::testbench::{self, TbOptions};

mod common;
use common::sv::{Def, Pkg};
use common::{Scratch, have, succeeds};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn tmpdir(name: &str) -> Scratch {
    Scratch::new(&format!("test-{name}"))
}

#[test]
fn committed_hdl_matches_what_the_code_emits() {
    let out = tmpdir("hdl");
    let written = write_hdl(&Config::default(), &out).unwrap();
    let mut want: Vec<String> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into())
        .collect();
    want.sort();
    // hdl/ref/ is hand-written reference RTL (tests/rtl_ref.rs checks it);
    // the emitter copies only the link module the netlists instantiate
    // (ref/ds_link.sv) from it.
    let mut have: Vec<String> = std::fs::read_dir(repo().join("hdl"))
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
        .map(|e| e.file_name().to_string_lossy().into())
        .filter(|n: &String| n.ends_with(".v") || n.ends_with(".sv"))
        .chain(["ds_link.sv".to_string()])
        .collect();
    have.sort();
    assert_eq!(
        have, want,
        "hdl/ holds other modules than the code emits: run `dualstream hdl --out hdl/`"
    );
    for p in written {
        let committed =
            std::fs::read_to_string(repo().join("hdl").join(p.strip_prefix(&*out).unwrap()))
                .unwrap();
        let fresh = std::fs::read_to_string(&p).unwrap();
        assert_eq!(
            committed,
            fresh,
            "{} is stale: run `dualstream hdl --out hdl/`",
            p.display()
        );
    }
}

/// The package the code emits for the default configuration.
fn package() -> Pkg {
    Pkg::parse(&dualstream::machine::hdl::emit_package(&Config::default()).unwrap())
}

/// (name, width) of the module's ports (without clk and rst) and non-array
/// regs, a typed one as wide as its type in the package.
fn verilog_signals(pkg: &Pkg, text: &str) -> BTreeMap<String, u32> {
    let mut m = BTreeMap::new();
    for line in text.lines() {
        if let Some((name, ty, _)) = pkg.decl(line)
            && name != "clk"
            && name != "rst"
        {
            m.insert(name, pkg.width(&ty));
        }
    }
    m
}

/// Scope path -> (signal -> width), read with the `vcd` crate; also checks every
/// change is a declared id with a value no wider than declared, and time is monotonic.
fn read_vcd(path: &Path) -> (BTreeMap<String, BTreeMap<String, u32>>, u64) {
    let f = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut scopes: BTreeMap<String, BTreeMap<String, u32>> = BTreeMap::new();
    let mut stack: Vec<String> = Vec::new();
    let mut ids = std::collections::HashMap::new();
    let (mut changes, mut last_t) = (0u64, 0u64);
    for cmd in vcd::Parser::new(f) {
        match cmd.expect("valid VCD") {
            vcd::Command::ScopeDef(_, name) => stack.push(name),
            vcd::Command::Upscope => {
                stack.pop();
            }
            vcd::Command::VarDef(_, size, code, name, _) => {
                scopes
                    .entry(stack.join("."))
                    .or_default()
                    .insert(name, size);
                ids.insert(code, size);
            }
            vcd::Command::Timestamp(t) => {
                assert!(t >= last_t, "time goes backwards");
                last_t = t;
            }
            vcd::Command::ChangeScalar(code, _) => {
                assert_eq!(ids.get(&code), Some(&1));
                changes += 1;
            }
            vcd::Command::ChangeVector(code, v) => {
                let w = *ids.get(&code).expect("declared id");
                assert!(v.len() as u32 <= w, "value wider than its variable");
                changes += 1;
            }
            vcd::Command::ChangeReal(code, _) => {
                assert_eq!(ids.get(&code), Some(&64), "a real is 64 bits");
                changes += 1;
            }
            _ => {}
        }
    }
    (scopes, changes)
}

#[test]
fn vcd_scopes_equal_verilog_modules_and_read_back() {
    let dir = tmpdir("vcd");
    // The benches whose unit is the scope `tb.<name>` with a random stimulus.
    for name in [
        "box_pipe",
        "tri_pipe",
        "divider",
        "mem_ctrl",
        "hit_record_updater",
        "l2",
    ] {
        // The global units' benches elaborate them with their own TM count.
        let decls = catalog(&testbench::bench_config(name, &Config::default()));
        let vcd = dir.join(format!("{name}.vcd"));
        let opts = TbOptions {
            cycles: 300,
            vcd: Some(vcd.clone()),
            trace: TraceSpec::all(),
            ..TbOptions::default()
        };
        let rep = testbench::run_by_name(name, &opts).unwrap();
        assert!(rep.passed(), "{rep}");
        let (scopes, changes) = read_vcd(&vcd);
        assert_eq!(
            changes, rep.vcd_changes,
            "our count of changes equals what a reader finds"
        );
        assert!(changes > 100);
        let traced = &scopes[&format!("tb.{name}")];
        let decl = decls.iter().find(|d| d.module == name).unwrap();
        let module = dualstream::rtl::verilog::emit_module(decl);
        let verilog = verilog_signals(&package(), &module);
        // `x_fire` (valid and ready) is the waveform's own, derived from
        // two signals the module has.
        let traced: BTreeMap<String, u32> = traced
            .iter()
            .filter(|(n, _)| !n.ends_with("_fire"))
            .map(|(n, w)| (n.clone(), *w))
            .collect();
        assert_eq!(
            traced, verilog,
            "{name}: VCD scope and Verilog module disagree"
        );
        // Payload ports are packed vectors as wide as the Rust payload.
        for p in &decl.ports {
            assert_eq!(verilog[&format!("{}_data", p.name)], p.width);
        }
        if have("vcd2fst") {
            let fst = dir.join(format!("{name}.fst"));
            succeeds(
                Command::new("vcd2fst").arg(&vcd).arg(&fst),
                &format!("vcd2fst on {}", vcd.display()),
            );
            assert!(std::fs::metadata(&fst).unwrap().len() > 0);
        }
    }
}

#[test]
fn renaming_a_port_renames_it_everywhere() {
    // The declaration is the only place names come from: the VCD signal list and the
    // Verilog text are both functions of it.
    let mut d = catalog(&Config::default()).remove(0);
    d.ports[0].name = "request";
    let sigs: Vec<String> = d.signals().into_iter().map(|s| s.name).collect();
    assert!(sigs.contains(&"request_data".to_string()));
    let v = dualstream::rtl::verilog::emit_module(&d);
    assert!(v.contains("request_data") && !v.contains(" req_data"));
    assert_eq!(
        verilog_signals(&package(), &v)
            .keys()
            .cloned()
            .collect::<Vec<_>>(),
        {
            let mut s = sigs.clone();
            s.sort();
            s
        }
    );
}

#[test]
fn state_inventory_counts_every_bit() {
    let cfg = Config::default();
    for d in catalog(&cfg) {
        if !d.state.iter().any(|s| s.name == "pipe_stage_data") {
            continue; // the pipeline checks below; TM units are checked in tests/tm.rs
        }
        let regs: u64 = d
            .state
            .iter()
            .map(|s| s.width as u64 * s.depth.unwrap_or(1) as u64)
            .sum();
        assert_eq!(d.state_bits(), regs);
        // A pipeline holds one request per internal stage.
        let Some(latency) = d.params.iter().find(|p| p.name == "LATENCY") else {
            continue; // not a fixed-latency pipeline (the memory controller)
        };
        let stages = latency.value - cfg.links.tm.delay as u64;
        let data = d
            .state
            .iter()
            .find(|s| s.name == "pipe_stage_data")
            .unwrap();
        assert_eq!(data.depth, Some(stages as u32));
        assert_eq!(data.width, d.ports[0].width);
    }
}

#[test]
fn verilog_passes_verilator_iverilog_and_yosys() {
    let files: Vec<PathBuf> = std::fs::read_dir(repo().join("hdl"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "v"))
        // The 128-TM chip top takes minutes in these tools: its 2-TM twin is
        // linted in `chip_top_wires_every_unit_and_lints`.
        .filter(|p| !p.ends_with("chip.v"))
        .collect();
    assert!(files.len() >= 3);
    for f in &files {
        lint_with_library(&repo().join("hdl"), f, "");
        if have("yosys") {
            // A structural module (tm.v) reads its parts from the other files.
            let all: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
            let top = f.file_stem().unwrap().to_string_lossy();
            let script = format!(
                "read_verilog -sv {} {} {}; hierarchy -check -top {top}; check -assert",
                repo().join("hdl/ds_pkg.sv").display(),
                repo().join("hdl/ref/ds_link.sv").display(),
                all.join(" ")
            );
            succeeds(Command::new("yosys").args(["-q", "-p", &script]), "yosys");
        }
        let text = std::fs::read_to_string(f).unwrap();
        assert!(!text.contains("lint_off"), "no lint pragmas");
    }
}

/// The chip top: every global unit, every TM (and with GDDR5 every channel
/// controller), named as the model's units and wired as the chip is simulated; the memory module
/// has a port per requester the chip gives it; a 2-TM top passes verilator,
/// iverilog and yosys (the committed 128-TM one is the same code, bigger).
#[test]
fn chip_top_wires_every_unit_and_lints() {
    let committed = std::fs::read_to_string(repo().join("hdl/chip.v")).unwrap();
    let cfg = Config::default();
    assert!(committed.contains(&format!("localparam integer TMS = {};", cfg.chip.tms)));
    assert!(committed.contains(&format!("localparam integer TPS = {};", cfg.tm.tps)));
    // One instance per TM, named as the model's unit (no generate loop).
    assert!(!committed.contains("genvar"));
    for k in [0, cfg.chip.tms - 1] {
        assert!(committed.contains(&format!("\n    tm tm{k} (\n")), "tm{k}");
    }
    for inst in [
        "stream_scheduler #(",
        ") scheduler (",
        ") scene_buffer (",
        ") hit_updater (",
        ") memory (",
    ] {
        assert!(committed.contains(inst), "chip.v lacks {inst}");
    }
    assert!(!committed.contains(" host ("), "the host is not hardware");
    // The memory unit as instantiated (memory.v is emitted from the same chip):
    // the scheduler, scene and L2 ports (the L2 serves the hit record updater and
    // the TMs' global-memory ports; without the L2, the hit port and one
    // global-memory port per TM), then the scheduler's further ray and scene lanes,
    // then the L2's further memory lanes.
    let memory = std::fs::read_to_string(repo().join("hdl/memory.v")).unwrap();
    let lanes =
        cfg.chip.scheduler.ray_lines_per_cycle - 1 + cfg.chip.scheduler.scene_lines_per_cycle - 1;
    let ports = lanes
        + if cfg.chip.l2.enabled {
            assert!(committed.contains(") l2 ("), "chip.v lacks the L2");
            let l2 = std::fs::read_to_string(repo().join("hdl/l2.v")).unwrap();
            let l2_lanes = cfg.chip.l2.mem_lines_per_cycle;
            assert!(l2.contains(&format!("parameter integer MEM_LANES = {l2_lanes}")));
            assert_eq!(
                l2.matches("input  wire mem_req_").count() as u32,
                l2_lanes,
                "one memory request port per L2 lane"
            );
            3 + l2_lanes - 1
        } else {
            3 + cfg.chip.tms
        };
    assert!(memory.contains(&format!("parameter integer PORTS = {ports}")));
    assert!(committed.contains(&format!("memory #(.PORTS({ports}),")));
    assert_eq!(memory.matches("input  wire req_").count() as u32, ports);
    assert!(committed.contains(&format!(".req_{}_valid(", ports - 1)));
    // Every scheduler fill port drives its TM's link, which drives the TM's
    // slice.
    for k in [0, cfg.chip.tms - 1] {
        assert!(committed.contains(&format!(".fill_{k}_valid(tm{k}_fill_push_valid)")));
        assert!(committed.contains(&format!(".push_valid(tm{k}_fill_push_valid)")));
        assert!(committed.contains(&format!(".pop_valid(tm_fill_valid[{k}])")));
    }
    // Every link is a ds_link (with its depth and delay) but the clock
    // crossings; each TM's internal links are in tm.v.
    let tm_v = std::fs::read_to_string(repo().join("hdl/tm.v")).unwrap();
    let tm_links = tm_v.matches("    ds_link #(").count();
    let chip_links = committed.matches("    ds_link #(").count();
    let crossings = if cfg.chip.memory.model == dualstream::units::memory::MemoryModel::Gddr5 {
        2 * cfg.mem.geometry.channels as usize
    } else {
        0
    };
    assert_eq!(
        chip_links + crossings + cfg.chip.tms as usize * tm_links,
        dualstream::machine::hdl::link_count(&cfg).unwrap(),
        "one ds_link per link of the model"
    );
    assert!(committed.contains("ds_link #(.WIDTH("));

    for (name, toml) in [
        (
            "fixed",
            "[chip]\ntms = 2\n[chip.memory]\nmodel = \"fixed\"\n",
        ),
        // GDDR5 is the default memory.
        ("gddr5", "[chip]\ntms = 2\n"),
    ] {
        let cfg = Config::from_toml(toml).unwrap();
        let dir = tmpdir(&format!("chip2-{name}"));
        write_hdl(&cfg, &dir).unwrap();
        let top = dir.join("chip.v");
        let text = std::fs::read_to_string(&top).unwrap();
        assert!(text.contains("localparam integer TMS = 2;"));
        if name == "gddr5" {
            assert!(text.contains("input  wire clk_dram"));
            for c in [0, cfg.mem.geometry.channels - 1] {
                assert!(
                    text.contains(&format!("mem_ctrl #(.CHANNEL({c}),")),
                    "one instance per channel"
                );
                assert!(text.contains(&format!(") mem_ctrl{c} (")));
            }
            assert!(text.contains(".clk(clk_dram)"));
        } else {
            assert!(!text.contains("mem_ctrl"));
        }
        lint_with_library(&dir, &top, &format!(" ({name})"));
        // yosys reads every module (seconds): once, on the top with every loop.
        if name == "gddr5" && have("yosys") {
            // Every instance's ports exist and match; the top has one driver per
            // net. The modules are read as black boxes (ports only): their bodies
            // are checked file by file above, and elaborating them all (the L2's
            // deep arrays) takes minutes.
            let lib: Vec<String> = std::fs::read_dir(&dir)
                .unwrap()
                .map(|e| e.unwrap().path().display().to_string())
                .filter(|p| p.ends_with(".v") && !p.ends_with("chip.v"))
                .collect();
            let script = format!(
                "read_verilog -sv -lib {} {}; read_verilog -sv {} {}; hierarchy -check -top chip; check -assert chip",
                dir.join("ds_pkg.sv").display(),
                lib.join(" "),
                dir.join("ref/ds_link.sv").display(),
                top.display()
            );
            succeeds(
                Command::new("yosys").args(["-q", "-p", &script]),
                &format!("yosys ({name})"),
            );
        }
        assert!(!text.contains("lint_off"), "no lint pragmas");
    }
}

/// Verilator (`-Wall`) and Icarus lint `file` after `lib`'s package, finding
/// the modules it instantiates in `lib` (each skipped when the tool is
/// missing; `have` requires it under CI).
fn lint_with_library(lib: &std::path::Path, file: &std::path::Path, what: &str) {
    let pkg = lib.join("ds_pkg.sv");
    // The link module the netlists instantiate: found by Verilator in ref/,
    // given to Icarus (whose -y looks for `.v` files).
    let link = lib.join("ref/ds_link.sv");
    if have("verilator") {
        succeeds(
            Command::new("verilator")
                .args(["--lint-only", "-Wall", "-y"])
                .arg(lib)
                .arg("-y")
                .arg(lib.join("ref"))
                .arg(&pkg)
                .arg(file),
            &format!("verilator{what}"),
        );
    }
    if have("iverilog") {
        succeeds(
            Command::new("iverilog")
                .args(["-g2012", "-o", "/dev/null", "-y"])
                .arg(lib)
                .arg(&pkg)
                .arg(&link)
                .arg(file),
            &format!("iverilog{what}"),
        );
    }
}

/// Signal -> value (binary digits, no leading zeros) at the first time step of a
/// VCD, for the signals under `scope`.
fn first_values(path: &Path, scope: &str) -> BTreeMap<String, String> {
    let f = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let mut stack: Vec<String> = Vec::new();
    let mut names = std::collections::HashMap::new();
    let mut out = BTreeMap::new();
    let mut steps = 0;
    let bin = |v: &mut dyn Iterator<Item = vcd::Value>| -> String {
        let s: String = v
            .map(|b| if b == vcd::Value::V1 { '1' } else { '0' })
            .collect();
        let t = s.trim_start_matches('0');
        if t.is_empty() { "0".into() } else { t.into() }
    };
    for cmd in vcd::Parser::new(f) {
        match cmd.expect("valid VCD") {
            vcd::Command::ScopeDef(_, name) => stack.push(name),
            vcd::Command::Upscope => {
                stack.pop();
            }
            vcd::Command::VarDef(_, _, code, name, _) if stack.join(".") == scope => {
                names.insert(code, name);
            }
            vcd::Command::Timestamp(_) => {
                steps += 1;
                if steps > 1 {
                    break;
                }
            }
            vcd::Command::ChangeScalar(code, v) => {
                if let Some(n) = names.get(&code) {
                    out.insert(n.clone(), bin(&mut std::iter::once(v)));
                }
            }
            vcd::Command::ChangeVector(code, v) => {
                if let Some(n) = names.get(&code) {
                    out.insert(n.clone(), bin(&mut v.iter()));
                }
            }
            _ => {}
        }
    }
    out
}

/// Register -> reset value (binary digits, no leading zeros) from a module's
/// reset block (`name <= '0;`, `name <= W'hHEX;` or an enum literal of the
/// package, `state <= TP_STATE_IDLE;`).
fn verilog_resets(pkg: &Pkg, module: &str) -> BTreeMap<String, String> {
    let literal = |v: &str| {
        pkg.types.values().find_map(|d| match d {
            Def::Enum(_, lits) => lits.iter().find(|(n, _)| n == v).map(|(_, k)| *k),
            Def::Struct(_) => None,
        })
    };
    let mut out = BTreeMap::new();
    for l in module.lines() {
        let l = l.trim();
        let Some((name, v)) = l.strip_suffix(';').and_then(|l| l.split_once(" <= ")) else {
            continue;
        };
        if name.contains('[') {
            continue;
        }
        let bits = match v.split_once("'h") {
            Some((_, hex)) => {
                let s: String = hex
                    .chars()
                    .map(|c| format!("{:04b}", c.to_digit(16).expect("hex digit")))
                    .collect();
                let t = s.trim_start_matches('0');
                if t.is_empty() {
                    "0".to_string()
                } else {
                    t.to_string()
                }
            }
            None => match literal(v) {
                Some(k) => format!("{k:b}"),
                None => {
                    assert_eq!(v, "'0", "{l}");
                    "0".to_string()
                }
            },
        };
        out.insert(name.to_string(), bits);
    }
    out
}

/// The Verilog skeletons reset every register to the value the model starts from,
/// and the waveform's first values are those: one reset, three views (e.g. a
/// pipeline's initiation-interval counter starts at its interval, a TP's best hit
/// at infinity).
#[test]
fn verilog_resets_are_the_models_first_values() {
    let dir = tmpdir("resets");
    let mut nonzero = 0;
    for name in ["box_pipe", "tri_pipe", "divider"] {
        let decls = catalog(&testbench::bench_config(name, &Config::default()));
        let decl = decls.iter().find(|d| d.module == name).unwrap();
        let resets = verilog_resets(&package(), &dualstream::rtl::verilog::emit_module(decl));
        assert!(!resets.is_empty(), "{name}: no reset block");
        let vcd = dir.join(format!("{name}.vcd"));
        let opts = TbOptions {
            cycles: 50,
            vcd: Some(vcd.clone()),
            trace: TraceSpec::all(),
            ..TbOptions::default()
        };
        assert!(testbench::run_by_name(name, &opts).unwrap().passed());
        let first = first_values(&vcd, &format!("tb.{name}"));
        for (reg, want) in &resets {
            assert_eq!(
                first.get(reg),
                Some(want),
                "{name}.{reg}: the Verilog resets it to {want} (binary), the waveform starts at {:?}",
                first.get(reg)
            );
            nonzero += (want != "0") as u32;
        }
    }
    assert!(
        nonzero >= 3,
        "each pipeline's interval counter starts non-zero"
    );
    // A TP's best hit resets to "no hit": t = +inf, triangle id all ones.
    let tp = catalog(&Config::default())
        .into_iter()
        .find(|d| d.module == "tp")
        .unwrap();
    let best = tp.state.iter().find(|s| s.name == "best").unwrap();
    assert!(
        best.reset_literal().ends_with("ffffffff7f800000"),
        "{}",
        best.reset_literal()
    );
}

/// What differs between the package's structs and the model's packing, for
/// every port of every module: the port's type as the module writes it must
/// be as wide as the port's vector, and a struct's leaves (read from the
/// package text, members MSB first) must be the payload's fields
/// (`Payload::field_list`) at the same offsets and widths; a payload without
/// fields is a plain vector or an enum.
fn layout_mismatches(pkg: &Pkg, decls: &[dualstream::rtl::UnitDecl]) -> (Vec<String>, usize) {
    let mut bad = Vec::new();
    let mut structs = std::collections::BTreeSet::new();
    for d in decls {
        let text = dualstream::rtl::verilog::emit_module(d);
        let types: BTreeMap<String, String> = text
            .lines()
            .filter_map(|l| pkg.decl(l))
            .map(|(n, t, _)| (n, t))
            .collect();
        for p in &d.ports {
            let ty = &types[&format!("{}_data", p.name)];
            let at = format!("{}.{}_data ({ty})", d.module, p.name);
            if pkg.width(ty) != p.width {
                bad.push(format!(
                    "{at}: {} bits, the port {}",
                    pkg.width(ty),
                    p.width
                ));
            }
            let is_struct = matches!(pkg.types.get(ty), Some(Def::Struct(_)));
            if p.fields.is_empty() {
                if is_struct {
                    bad.push(format!("{at}: a struct for a payload without fields"));
                }
                continue;
            }
            if !is_struct {
                bad.push(format!("{at}: not a struct, the payload has fields"));
                continue;
            }
            structs.insert(ty.clone());
            let mut leaves = Vec::new();
            pkg.leaves(ty, "", 0, &mut leaves);
            let model: Vec<(String, u32, u32)> = p
                .fields
                .iter()
                .map(|f| (f.name.clone(), f.offset, f.width))
                .collect();
            for (m, s) in model.iter().zip(&leaves) {
                if m != s {
                    bad.push(format!("{at}: model {m:?}, package {s:?}"));
                }
            }
            if model.len() != leaves.len() {
                bad.push(format!(
                    "{at}: {} fields in the model, {} in the package",
                    model.len(),
                    leaves.len()
                ));
            }
        }
    }
    (bad, structs.len())
}

/// Each struct of `ds_pkg.sv` lays its payload out as `pack` does: the
/// struct is as wide as the port's vector and each field sits at the
/// model's offset; every FSM register is its enum, with the model's states
/// in order, and resets to the model's state by name. Planted faults (the
/// members in declaration order, as a naive emitter writes them; a member
/// dropped) are caught.
#[test]
fn package_structs_lay_out_every_payload_as_the_model_packs_it() {
    let cfg = Config::default();
    let decls = catalog(&cfg);
    let text = dualstream::machine::hdl::emit_package(&cfg).unwrap();
    let pkg = Pkg::parse(&text);
    let (bad, structs) = layout_mismatches(&pkg, &decls);
    assert_eq!(bad, Vec::<String>::new());
    assert!(structs >= 18, "{structs} port structs checked");
    // The configured sizes, as the config gives them.
    assert_eq!(pkg.params["TM_TPS"], cfg.tm.tps.to_string());
    assert_eq!(pkg.params["CHIP_TMS"], cfg.chip.tms.to_string());
    assert_eq!(
        pkg.params["BOX_PIPE_LATENCY"],
        cfg.box_pipe.latency.to_string()
    );
    assert_eq!(pkg.params["CHIP_L2_BYTES"], cfg.chip.l2.bytes.to_string());

    // FSM registers: the enum type, its literals the model's states in
    // encoding order, the reset the model's state.
    let mut fsms = 0;
    for d in &decls {
        let module = dualstream::rtl::verilog::emit_module(d);
        for s in d.state.iter().filter(|s| s.traced()) {
            let Some(names) = s.enum_names else { continue };
            let (_, ty, kind) = module
                .lines()
                .filter_map(|l| pkg.decl(l))
                .find(|(n, _, _)| *n == s.name)
                .unwrap();
            assert_eq!(kind, "reg");
            let Some(Def::Enum(w, lits)) = pkg.types.get(&ty) else {
                panic!("{}.{}: {ty} is not an enum", d.module, s.name);
            };
            assert_eq!(*w, s.width, "{}.{}", d.module, s.name);
            assert_eq!(lits.len(), names.len());
            for (k, ((lit, v), state)) in lits.iter().zip(names.iter()).enumerate() {
                assert_eq!(*v, k as u64);
                let squashed: String = lit.chars().filter(|c| *c != '_').collect();
                assert!(
                    squashed.ends_with(&state.to_ascii_uppercase()),
                    "{lit} names {state}"
                );
            }
            let reset = s.reset.words().first().copied().unwrap_or(0) as usize;
            assert!(
                module.contains(&format!("{} <= {};", s.name, lits[reset].0)),
                "{}.{} resets to {}",
                d.module,
                s.name,
                lits[reset].0
            );
            fsms += 1;
        }
    }
    assert!(
        fsms >= 2,
        "the TP's state and the channel controller's command"
    );

    // Planted: every struct's members in declaration order (LSB first).
    let mut naive = String::new();
    let mut members: Vec<&str> = Vec::new();
    let mut inside = false;
    for l in text.lines() {
        if l.contains("typedef struct packed") {
            inside = true;
        } else if inside && l.trim_start().starts_with('}') {
            inside = false;
            for m in members.drain(..).rev() {
                naive.push_str(m);
                naive.push('\n');
            }
        } else if inside {
            members.push(l);
            continue;
        }
        naive.push_str(l);
        naive.push('\n');
    }
    let (bad, _) = layout_mismatches(&Pkg::parse(&naive), &decls);
    assert!(
        bad.iter()
            .any(|b| b.starts_with("box_pipe.req_data (box_req_t): model (\"origin.x\", 0, 32)")),
        "{bad:?}"
    );
    assert!(bad.len() > 20, "{bad:?}");

    // Planted: a member dropped (the hit flag of a box response).
    let dropped = text.replacen("        logic hit; // [0]\n", "", 1);
    assert_ne!(dropped, text);
    let (bad, _) = layout_mismatches(&Pkg::parse(&dropped), &decls);
    assert!(
        bad.contains(&"box_pipe.resp_data (box_resp_t): 48 bits, the port 49".to_string()),
        "{bad:?}"
    );
}
