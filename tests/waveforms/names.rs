//! Names shared with the Verilog: a model waveform's scopes are the netlist's
//! instance paths (`chip.tm3.tp5`), and in each unit's scope the signals are
//! its Verilog module's ports and registers, at the same widths and kinds
//! (`wire`, `reg`). Checked on the 8-TM chip against the netlist `dualstream
//! hdl` emits for it, read from the Verilog text, and, with Icarus Verilog
//! installed, against the trace of an RTL simulation of that netlist.
//!
//! What one side holds and the other does not, by design, is the table in
//! docs/chip.md "Instance paths: the waveform's scopes"; [`Scopes::of_model`],
//! [`Scopes::of_netlist`] and [`mismatches`] apply it: the host's signals are
//! the chip's ports, `fire` is the waveform's own, fields are in struct scopes
//! (not compared), each module's `clk` and `rst` are the root's clocks, a
//! structural scope (`chip`, `chip.tm3`) may hold nets the model does not
//! trace, memories are not traced, `_unused_ok` is the skeletons' lint sink,
//! and `box_pipe` has no instance (the crossbar holds the box pipeline).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::process::Command;

use crate::common::sv::Pkg;
use crate::common::{Scratch, succeeds};
use crate::{chip_trace, dualstream, have, read};

const CONFIG: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/examples/chip-8tms.toml");

/// A variable: width and kind (`wire`, `reg`).
type Var = (u32, String);

/// One module scope: the unit's module (`None`: a structural scope, no
/// unit), its variables by name.
#[derive(Clone, Debug, Default, PartialEq)]
struct Scope {
    module: Option<String>,
    vars: BTreeMap<String, Var>,
}

/// Module scopes by path (`chip.tm3.tp5`).
#[derive(Clone, Debug, Default)]
struct Scopes(BTreeMap<String, Scope>);

/// A Verilog module as `dualstream hdl` writes it: its ports and registers
/// (not arrays) and its instances (module, name).
#[derive(Default)]
struct Module {
    vars: BTreeMap<String, Var>,
    instances: Vec<(String, String)>,
}

/// Every module of the emitted files in `dir`, by name; a port or register
/// of a package type (`input  box_req_t req_data`) as wide as the type in
/// `ds_pkg.sv`.
fn parse_netlist(files: &BTreeMap<String, String>) -> BTreeMap<String, Module> {
    let pkg = Pkg::parse(&files["ds_pkg.sv"]);
    let mut out = BTreeMap::new();
    for (file, text) in files {
        if !file.ends_with(".v") {
            continue;
        }
        let mut name = None;
        let mut m = Module::default();
        for line in text.lines() {
            let l = line.trim().trim_end_matches([',', ';']);
            if let Some(r) = line.strip_prefix("module ") {
                name = Some(r.split([' ', '(', '#']).next().unwrap().to_string());
                continue;
            }
            // `input  wire [W:0] name`, `input  box_req_t name`, `reg [W:0]
            // name`, `tp_state_t state` (not `reg name [0:D]`, a memory).
            if let Some((var, ty, kind)) = pkg.decl(line) {
                m.vars.insert(var, (pkg.width(&ty), kind.to_string()));
                continue;
            }
            // An instance: `module #(...) name (` or `module name (`.
            if let Some(head) = l.strip_suffix(" (")
                && !head.starts_with("module ")
                && head != ")"
            {
                let (module, inst) = match head.split_once(" #(") {
                    Some((module, rest)) => (module, rest.rsplit_once(") ").unwrap().1),
                    None => head.split_once(' ').unwrap(),
                };
                m.instances.push((module.to_string(), inst.to_string()));
            }
        }
        out.insert(name.expect("a module per file"), m);
    }
    out
}

impl Scopes {
    /// The module scopes of a waveform and their own variables (not the
    /// fields'): for the model, each unit's module from its header comment
    /// (`chip.tm0.tp0: module tp (...)`).
    fn of_wave(w: &read::Wave) -> Scopes {
        let mut s: BTreeMap<String, Scope> = w
            .modules
            .iter()
            .map(|p| (p.clone(), Scope::default()))
            .collect();
        for (path, v) in &w.vars {
            let (scope, name) = path.rsplit_once('.').unwrap();
            if let Some(sc) = s.get_mut(scope) {
                sc.vars.insert(name.to_string(), (v.width, v.kind.clone()));
            }
        }
        for c in &w.comments {
            if let Some((path, rest)) = c.split_once(": module ")
                && let Some(sc) = s.get_mut(path)
            {
                sc.module = Some(rest.split(' ').next().unwrap().to_string());
            }
        }
        Scopes(s)
    }

    /// A model waveform as the netlist would show it: `fire` dropped, the
    /// host's signals moved to the root (the chip's ports).
    fn of_model(w: &read::Wave) -> Scopes {
        let mut s = Scopes::of_wave(w).0;
        for sc in s.values_mut() {
            sc.vars.retain(|n, _| !n.ends_with("_fire"));
        }
        let host = s.remove("chip.host").expect("the host's scope");
        s.get_mut("chip").unwrap().vars.extend(host.vars);
        Scopes(s)
    }

    /// The instance tree below `chip` and each instance's ports and
    /// registers.
    fn of_netlist(modules: &BTreeMap<String, Module>) -> Scopes {
        fn walk(
            modules: &BTreeMap<String, Module>,
            path: &str,
            module: &str,
            out: &mut BTreeMap<String, Scope>,
        ) {
            if module == "ds_link" {
                // Hand-written (hdl/ref/), not parsed: see `without_links`.
                out.insert(path.to_string(), Scope::default());
                return;
            }
            let m = modules
                .get(module)
                .unwrap_or_else(|| panic!("{path}: no module {module}"));
            out.insert(
                path.to_string(),
                Scope {
                    module: Some(module.to_string()),
                    vars: m.vars.clone(),
                },
            );
            for (sub, inst) in &m.instances {
                walk(modules, &format!("{path}.{inst}"), sub, out);
            }
        }
        let mut out = BTreeMap::new();
        walk(modules, "chip", "chip", &mut out);
        Scopes(out).without_links().without_module_clocks()
    }

    /// An RTL simulation's waveform, as [`Scopes::of_netlist`] reads the
    /// netlist.
    fn of_rtl(w: &read::Wave) -> Scopes {
        let mut s = Scopes::of_wave(w);
        for sc in s.0.values_mut() {
            sc.vars.retain(|n, _| n != "_unused_ok");
        }
        s.without_links().without_module_clocks()
    }

    /// The links' `ds_link` instances (`link_<name>`, and their generate
    /// blocks) dropped: netlist-only scopes (the model traces a link as its
    /// two ends' ports).
    fn without_links(mut self) -> Scopes {
        let link = |p: &str| p.split('.').any(|c| c.starts_with("link_"));
        self.0.retain(|p, _| !link(p));
        self
    }

    /// Each module's `clk` and `rst` dropped below the root (the model has
    /// its clocks and reset there only).
    fn without_module_clocks(mut self) -> Scopes {
        for (_, sc) in self.0.iter_mut().filter(|(p, _)| p.as_str() != "chip") {
            sc.vars.retain(|n, _| n != "clk" && n != "rst");
        }
        self
    }
}

/// What differs between the model's scopes and the netlist's: scopes on one
/// side only; in a unit's scope a module or a variable (name, width, kind)
/// that differs; in a structural scope a model variable the netlist lacks.
fn mismatches(model: &Scopes, rtl: &Scopes) -> Vec<String> {
    let mut bad = Vec::new();
    let (m, r) = (&model.0, &rtl.0);
    for p in m.keys().filter(|p| !r.contains_key(*p)) {
        bad.push(format!("scope {p} only in the model"));
    }
    for p in r.keys().filter(|p| !m.contains_key(*p)) {
        bad.push(format!("scope {p} only in the netlist"));
    }
    for (p, ms) in m {
        let Some(rs) = r.get(p) else { continue };
        let unit = ms.module.is_some();
        if unit && rs.module.is_some() && ms.module != rs.module {
            bad.push(format!(
                "{p}: module {:?} in the model, {:?} in the netlist",
                ms.module, rs.module
            ));
        }
        for (n, v) in &ms.vars {
            match rs.vars.get(n) {
                None => bad.push(format!("{p}.{n} only in the model")),
                Some(x) if x != v => {
                    bad.push(format!("{p}.{n}: {v:?} in the model, {x:?} in the netlist"))
                }
                _ => {}
            }
        }
        if unit {
            for n in rs.vars.keys().filter(|n| !ms.vars.contains_key(*n)) {
                bad.push(format!("{p}.{n} only in the netlist"));
            }
        }
    }
    bad
}

/// The netlist `dualstream hdl` emits for the 8-TM chip: file name -> text.
fn emitted(d: &Path) -> BTreeMap<String, String> {
    let dir = d.join("hdl");
    dualstream(&["--config", CONFIG, "hdl", "--out", dir.to_str().unwrap()]);
    std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file()) // ref/: the hand-written link module
        .map(|p| {
            let n = p.file_name().unwrap().to_string_lossy().to_string();
            (n, std::fs::read_to_string(&p).unwrap())
        })
        .collect()
}

/// Every unit of the 8-TM chip, one cycle.
fn model_trace(d: &Path) -> read::Wave {
    let p = d.join("model.vcd");
    chip_trace(&p, "chip.*", "1000..1001", &[]);
    read::vcd(&p)
}

/// The model's scopes are the netlist's instances, each unit's signals its
/// module's ports and registers; a register named after a port (the TP's
/// `ray_index` beside port `ray`) is a `reg`. Planted faults (an instance
/// renamed in `tm.v`, a port renamed in `tp.v`, `ray_index` dumped as a
/// wire) are each reported.
#[test]
fn trace_scopes_are_the_netlists_instances() {
    let d = Scratch::new("wave-names");
    let files = emitted(&d);
    let netlist = parse_netlist(&files);
    let model = Scopes::of_model(&model_trace(&d));
    let rtl = Scopes::of_netlist(&netlist);
    assert_eq!(mismatches(&model, &rtl), Vec::<String>::new());
    // The netlist-only scopes left out are the links' ds_link instances.
    let links = netlist["tm"]
        .instances
        .iter()
        .chain(&netlist["chip"].instances)
        .filter(|(m, i)| m == "ds_link" && i.starts_with("link_"))
        .count();
    assert!(links > 100, "{links} ds_link instances");

    // What it covered: every unit of 8 TMs and the global units.
    let units = model.0.values().filter(|s| s.module.is_some()).count();
    let tm = 16 + 6; // TPs, staging buffer, L1, crossbar, two triangle pipes, divider
    let globals = 5 + 16; // scheduler, scene buffer, hit updater, L2, memory, channels
    assert_eq!(units, 8 * tm + globals);
    for p in [
        "chip.tm7.tp15",
        "chip.tm3.xbar",
        "chip.mem_ctrl15",
        "chip.l2",
    ] {
        assert!(model.0[p].module.is_some(), "{p}");
    }
    // The root: the clocks and reset, and the host's links as the chip's
    // ports, exactly.
    assert_eq!(model.0["chip"].vars, rtl.0["chip"].vars);
    assert!(model.0["chip"].vars.contains_key("clk_core"));
    assert!(model.0["chip"].vars.contains_key("emit_valid"));
    assert!(
        netlist
            .values()
            .all(|m| m.instances.iter().all(|(sub, _)| sub != "box_pipe")),
        "box_pipe has no instance (the crossbar holds the box pipeline)"
    );

    // Registers whose name starts with a port's and `_` (once taken for that
    // port's wire, `ray_index` beside `ray`): `reg` in every scope of their
    // module in the model's trace, as in the netlist.
    let mut named_after_ports = BTreeSet::new();
    for (name, m) in &netlist {
        let ports: Vec<&str> = m
            .vars
            .keys()
            .filter_map(|n| n.strip_suffix("_valid"))
            .collect();
        for (reg, _) in m.vars.iter().filter(|(_, v)| v.1 == "reg") {
            if ports.iter().any(|p| reg.starts_with(&format!("{p}_"))) {
                named_after_ports.insert(format!("{name}.{reg}"));
                for sc in model.0.values().filter(|s| s.module.as_ref() == Some(name)) {
                    assert_eq!(sc.vars[reg].1, "reg", "{name}.{reg}");
                }
            }
        }
    }
    assert!(
        named_after_ports.contains("tp.ray_index"),
        "{named_after_ports:?}"
    );
    assert_eq!(model.0["chip.tm0.tp0"].vars["ray_index"].1, "reg");

    // Planted faults, each reported.
    let mut renamed = files.clone();
    let tm_v = renamed.get_mut("tm.v").unwrap();
    assert!(tm_v.contains(") tp5 ("));
    *tm_v = tm_v.replace(") tp5 (", ") u_tp5 (");
    let bad = mismatches(&model, &Scopes::of_netlist(&parse_netlist(&renamed)));
    for k in 0..8 {
        assert!(bad.contains(&format!("scope chip.tm{k}.tp5 only in the model")));
        assert!(bad.contains(&format!("scope chip.tm{k}.u_tp5 only in the netlist")));
    }
    assert_eq!(bad.len(), 16, "{bad:?}");

    let mut renamed = files.clone();
    let tp_v = renamed.get_mut("tp.v").unwrap();
    *tp_v = tp_v.replace("output wire ray_ready", "output wire rays_ready");
    let bad = mismatches(&model, &Scopes::of_netlist(&parse_netlist(&renamed)));
    assert!(bad.contains(&"chip.tm0.tp0.ray_ready only in the model".to_string()));
    assert!(bad.contains(&"chip.tm7.tp15.rays_ready only in the netlist".to_string()));
    assert_eq!(bad.len(), 2 * 8 * 16, "{bad:?}");

    let mut wire = model.clone();
    wire.0
        .get_mut("chip.tm0.tp0")
        .unwrap()
        .vars
        .get_mut("ray_index")
        .unwrap()
        .1 = "wire".into();
    let bad = mismatches(&wire, &rtl);
    assert_eq!(
        bad,
        ["chip.tm0.tp0.ray_index: (32, \"wire\") in the model, (32, \"reg\") in the netlist"]
    );
}

/// An RTL simulation of the emitted 8-TM netlist (Icarus Verilog, dumping
/// every variable under `chip`) has the model waveform's scopes, and in
/// each unit's scope the same signals at the same widths and kinds.
#[test]
fn an_rtl_trace_lines_up_with_the_model_trace() {
    if !have("iverilog") || !have("vvp") {
        return;
    }
    let d = Scratch::new("wave-names-rtl");
    emitted(&d);
    let dump = d.join("dump.v");
    let rtl_vcd = d.join("rtl.vcd");
    std::fs::write(
        &dump,
        format!(
            "module dump;\n    initial begin\n        $dumpfile(\"{}\");\n        $dumpvars(0, chip);\n        #1 $finish;\n    end\nendmodule\n",
            rtl_vcd.display()
        ),
    )
    .unwrap();
    let sim = d.join("sim");
    succeeds(
        Command::new("iverilog")
            .args(["-g2012", "-o"])
            .arg(&sim)
            .arg("-y")
            .arg(d.join("hdl"))
            .arg(d.join("hdl/ds_pkg.sv"))
            .arg(d.join("hdl/ref/ds_link.sv"))
            .arg(d.join("hdl/chip.v"))
            .arg(&dump),
        "iverilog",
    );
    succeeds(Command::new("vvp").arg("-n").arg(&sim), "vvp");
    let model = Scopes::of_model(&model_trace(&d));
    let rtl = Scopes::of_rtl(&read::vcd(&rtl_vcd));
    // A memory's write port (`<mem>_we`, `_wa`, `_wd`, tied off in the
    // skeletons) is the netlist's only: the model traces no memories.
    // Only the three together are a write port.
    let all = mismatches(&model, &rtl);
    let port = |m: &String| {
        let tail = " only in the netlist";
        m.strip_suffix(tail)
            .and_then(|n| n.get(..n.len().checked_sub(3)?))
            .is_some_and(|mem| {
                ["_we", "_wa", "_wd"]
                    .iter()
                    .all(|w| all.contains(&format!("{mem}{w}{tail}")))
            })
    };
    let only: Vec<&String> = all.iter().filter(|m| !port(m)).collect();
    assert_eq!(only, Vec::<&String>::new());
    assert_eq!(rtl.0["chip.tm5.tp9"].vars["ray_index"], (32, "reg".into()));
}
