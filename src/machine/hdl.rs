//! `hdl/chip.v`: the chip top as structural Verilog, emitted from a chip elaborated
//! by [`Chip::new`] (the same code and links the simulation runs), so the netlist
//! cannot drift from the model. Every instance is named as the model's unit
//! (`scheduler`, `l2`, `tm3`, `mem_ctrl2`; inside `hdl/tm.v`, `tp5`, `l1`, ...), so
//! an RTL simulation's trace has the model waveform's scopes (`chip.tm3.tp5`), and
//! the clocks are the waveform's (`clk_core`, `clk_dram`). Each top-level instance
//! is a global unit (its module, parameters from its declaration) or a member of a
//! numbered family (`tm<k>`, `mem_ctrl<c>`), one instance each (not a `generate`
//! loop, whose instances would be `g_tm[3].u_tm`); a family whose members hold
//! units (a TM) instantiates its structural module (`hdl/tm.v`), whose ports are
//! named after the inner units' ports as there. The host is not hardware: its
//! links become the chip's ports. One valid/ready/data triple per link; a
//! family's links are vectors indexed by the member.

use std::collections::BTreeMap;
use std::fmt::Write;

use crate::config::Config;
use crate::rtl::decl::PortDir;
use crate::rtl::link::LinkId;
use crate::rtl::{In, Out, SimOptions, Unit, UnitDecl, UnitId};
use crate::units;

use super::{Chip, ChipError};
use crate::util::FileError;

/// A chip elaborated for emission: the default-sized scene map (interfaces do not
/// depend on the scene).
fn elaborate(cfg: &Config) -> Result<Chip, ChipError> {
    let map = crate::contract::MemoryMap::new(
        &crate::contract::MemoryMapCfg {
            bucket_pool_bytes: 1 << 20,
            ..cfg.memory.clone()
        },
        &[cfg.accel.segment_bytes],
        0,
        1,
        1,
        1,
    )?;
    let shade = crate::units::shade::ShadeConsts {
        light_pos: glam::Vec3::ZERO,
        light_intensity: glam::Vec3::ZERO,
        sky: glam::Vec3::ZERO,
        bounces: 1,
        root_entry: 0,
    };
    Chip::new(cfg, &map, 1, &shade, SimOptions::default())
}

/// How many links the chip elaborated for `cfg` has (each is a `ds_link`
/// instance in `chip.v` or `tm.v`, or a clock crossing).
pub fn link_count(cfg: &Config) -> Result<usize, ChipError> {
    Ok(elaborate(cfg)?.sim.link_count())
}

/// The declarations of the chip's own units (not the TMs' insides, not the host),
/// one per module, as the chip instantiates them (e.g. the memory unit with a
/// port per requester).
pub fn global_decls(cfg: &Config) -> Result<Vec<UnitDecl>, ChipError> {
    let chip = elaborate(cfg)?;
    let mut v: Vec<UnitDecl> = Vec::new();
    for i in 0..chip.sim.unit_count() {
        let u = UnitId(i as u32);
        let path = chip.sim.unit_path(u).to_string();
        let top = top_of(&path);
        if path != format!("chip.{top}") || top == "host" {
            continue;
        }
        // Fresh from elaboration: the registers stand at their reset values.
        let d = chip.sim.unit(u).decl_at_reset();
        if !v.iter().any(|x| x.module == d.module) {
            v.push(d);
        }
    }
    Ok(v)
}

/// `chip.tm3.l1` -> `tm3`.
fn top_of(path: &str) -> &str {
    path.strip_prefix("chip.")
        .unwrap_or(path)
        .split('.')
        .next()
        .unwrap_or(path)
}

/// `tm3` -> (`tm`, Some(3)); `scheduler` -> (`scheduler`, None).
fn family(top: &str) -> (&str, Option<usize>) {
    let base = top.trim_end_matches(|c: char| c.is_ascii_digit());
    if base.len() < top.len() && !base.is_empty() {
        (base, top[base.len()..].parse().ok())
    } else {
        (top, None)
    }
}

/// Numbered instances `<base>0..<base>n-1` form a family (their links are vectors indexed by the member);
/// a lone number that does not start at 0 is part of a name (`l2`).
fn families<'a>(tops: impl IntoIterator<Item = &'a str>) -> BTreeMap<String, Vec<usize>> {
    let mut f: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for top in tops {
        if let (base, Some(k)) = family(top) {
            f.entry(base.to_string()).or_default().push(k);
        }
    }
    f.retain(|_, ks| {
        ks.sort_unstable();
        ks.iter().enumerate().all(|(i, &k)| i == k)
    });
    f
}

fn range(w: u32) -> String {
    if w == 1 {
        String::new()
    } else {
        format!("[{}:0] ", w - 1)
    }
}

/// One end of a chip-level link: the top instance and its port there.
#[derive(Clone, Debug)]
struct End {
    top: String,
    port: &'static str,
    width: u32,
    ty: crate::rtl::sv::SvType,
}

/// A top-level instance: a leaf unit or a structural group of units.
struct Inst {
    module: String,
    params: Vec<(&'static str, u64)>,
    clock: String,
    /// (port, dir, width) in declaration order.
    ports: Vec<(&'static str, PortDir, u32)>,
}

/// The chip top's instances and the links between them (links inside a
/// structural instance, a TM, are left out), from the elaborated chip.
struct Top {
    insts: BTreeMap<String, Inst>,
    /// (link, producer end, consumer end).
    nets: Vec<(u32, End, End)>,
    /// Numbered instances whose links are vectors (see [`families`]).
    families: BTreeMap<String, Vec<usize>>,
    link_names: Vec<String>,
    /// Each link's depth and delay, from the simulator.
    link_cfgs: Vec<crate::rtl::LinkCfg>,
}

/// What the chip's module declares and connects: its ports (the host's links
/// and the clocks), its wires, and the net each instance port connects to.
struct Wiring {
    ports: Vec<String>,
    wires: Vec<String>,
    /// (instance, port) -> (valid, ready, data) expressions.
    conn: BTreeMap<(String, &'static str), [String; 3]>,
    /// One `ds_link` instance per link (not the crossings'), as text.
    links: Vec<String>,
}

/// The clock net of a clock domain, named as the waveform's (`clk_core`,
/// `clk_dram`).
fn clk(name: &str) -> String {
    format!("clk_{name}")
}

/// The `localparam` holding a family's member count (`tm` -> `TMS`).
fn count_name(base: &str) -> String {
    format!("{}S", base.to_uppercase())
}

impl Top {
    fn of(chip: &Chip) -> Result<Top, ChipError> {
        let sim = &chip.sim;
        let link_names: Vec<String> = sim.link_stats().into_iter().map(|(n, _)| n).collect();
        let clock_names: Vec<String> = sim.clocks().iter().map(|c| c.name.clone()).collect();
        // Top instances and link ends.
        let mut insts: BTreeMap<String, Inst> = BTreeMap::new();
        let mut ends: BTreeMap<u32, [Option<End>; 2]> = BTreeMap::new();
        for i in 0..sim.unit_count() {
            let u = UnitId(i as u32);
            let path = sim.unit_path(u).to_string();
            let d = sim.unit(u).decl_at_reset();
            let top = top_of(&path).to_string();
            let leaf = path == format!("chip.{top}");
            let inst = insts.entry(top.clone()).or_insert_with(|| Inst {
                module: if leaf {
                    d.module.to_string()
                } else {
                    family(&top).0.to_string()
                },
                params: Vec::new(),
                clock: clk(&clock_names[sim.unit_clock(u).0 as usize]),
                ports: Vec::new(),
            });
            if leaf {
                inst.params = d.params.iter().map(|p| (p.name, p.value)).collect();
            }
            for p in &d.ports {
                let e = ends.entry(p.link.0).or_default();
                e[(p.dir == PortDir::In) as usize] = Some(End {
                    top: top.clone(),
                    port: p.name,
                    width: p.width,
                    ty: p.ty.clone(),
                });
            }
        }
        // Ports of each top instance: its ends on links leaving it.
        let mut nets = Vec::new();
        for (id, e) in &ends {
            let [Some(p), Some(c)] = e else {
                return Err(ChipError::Hdl(format!(
                    "link '{}' has an open end",
                    link_names[*id as usize]
                )));
            };
            if p.top == c.top {
                continue; // inside a structural instance (a TM)
            }
            for (end, dir) in [(p, PortDir::Out), (c, PortDir::In)] {
                let inst = insts.get_mut(&end.top).expect("instance");
                if !inst.ports.iter().any(|x| x.0 == end.port) {
                    inst.ports.push((end.port, dir, end.width));
                }
            }
            nets.push((*id, p.clone(), c.clone()));
        }
        // Families: members with the same module and ports share vector nets.
        let families = families(insts.keys().map(String::as_str));
        for (base, ks) in &families {
            let first = &insts[&format!("{base}0")];
            for &k in ks.iter() {
                let m = &insts[&format!("{base}{k}")];
                if m.module != first.module || m.ports != first.ports || m.clock != first.clock {
                    return Err(ChipError::Hdl(format!(
                        "{base}{k} differs from {base}0 in module or ports"
                    )));
                }
            }
        }
        let link_cfgs = (0..sim.link_count() as u32)
            .map(|l| sim.link_cfg(LinkId(l)))
            .collect();
        Ok(Top {
            insts,
            nets,
            families,
            link_names,
            link_cfgs,
        })
    }

    /// Whether the top instance `top` is a family member (built in a loop).
    fn in_family(&self, top: &str) -> bool {
        family(top).1.is_some() && self.families.contains_key(family(top).0)
    }

    /// The net a link end connects to: (valid, ready, data) expressions.
    fn signal(&self, end: &End, link: u32) -> [String; 3] {
        if let (base, Some(k)) = family(&end.top)
            && self.families.contains_key(base)
        {
            let n = format!("{base}_{}", end.port);
            let w = end.width;
            return [
                format!("{n}_valid[{k}]"),
                format!("{n}_ready[{k}]"),
                if w == 1 {
                    format!("{n}_data[{k}]")
                } else {
                    format!("{n}_data[{}:{}]", (k as u32 + 1) * w - 1, k as u32 * w)
                },
            ];
        }
        let n = self.link_names[link as usize]
            .trim_start_matches("chip.")
            .replace('.', "_");
        ["valid", "ready", "data"].map(|s| format!("{n}_{s}"))
    }

    /// Chip ports (the host's links), wires, and each instance's connections.
    fn wiring(&self) -> Result<Wiring, ChipError> {
        let insts = &self.insts;
        let mut ports = vec!["input  wire rst".to_string()];
        let mut clocks: Vec<String> = insts
            .iter()
            .filter(|(t, _)| t.as_str() != "host")
            .map(|(_, i)| i.clock.clone())
            .collect();
        clocks.sort();
        clocks.dedup();
        for c in clocks.iter().rev() {
            ports.insert(0, format!("input  wire {c}"));
        }
        let mut wires = Vec::new();
        let mut conn: BTreeMap<(String, &'static str), [String; 3]> = BTreeMap::new();
        for base in self.families.keys() {
            let inst = &insts[&format!("{base}0")];
            let n = count_name(base);
            for &(port, _, w) in &inst.ports {
                let s = format!("{base}_{port}");
                wires.push(format!("    wire [{n}-1:0] {s}_valid;"));
                wires.push(format!("    wire [{n}-1:0] {s}_ready;"));
                wires.push(format!("    wire [{n}*{w}-1:0] {s}_data;"));
            }
        }
        let mut links = Vec::new();
        for (id, p, c) in &self.nets {
            let pf = self.in_family(&p.top);
            let cf = self.in_family(&c.top);
            if pf && cf {
                return Err(ChipError::Hdl(format!(
                    "link '{}' joins two families; not supported by the emitter",
                    self.link_names[*id as usize]
                )));
            }
            let local = self.link_names[*id as usize].trim_start_matches("chip.");
            let n = local.replace('.', "_");
            let host = p.top == "host" || c.top == "host";
            if host {
                // The host's side is the chip's port, named after the host's port.
                let (h, other, dir, ddir) = if p.top == "host" {
                    (p, c, ("input ", "output"), PortDir::In)
                } else {
                    (c, p, ("output", "input "), PortDir::Out)
                };
                if self.in_family(&other.top) {
                    return Err(ChipError::Hdl(format!(
                        "link '{}' joins the host to a family member; not supported by the emitter",
                        self.link_names[*id as usize]
                    )));
                }
                ports.push(format!("{} wire {}_valid", dir.0, h.port));
                ports.push(format!("{} wire {}_ready", dir.1, h.port));
                ports.push(crate::rtl::verilog::port_decl(
                    ddir,
                    &h.ty,
                    &format!("{}_data", h.port),
                ));
            }
            let (pclk, cclk) = (&insts[&p.top].clock, &insts[&c.top].clock);
            if pclk != cclk && !host {
                // A clock-domain crossing: wired straight (see docs/rtl.md,
                // "Netlists and ds_link").
                if !pf && !cf {
                    wires.push(format!("    wire {n}_valid;"));
                    wires.push(format!("    wire {n}_ready;"));
                    wires.push(format!("    wire {}{n}_data;", range(p.width)));
                }
                let s = if pf {
                    self.signal(p, *id)
                } else if cf {
                    self.signal(c, *id)
                } else {
                    ["valid", "ready", "data"].map(|x| format!("{n}_{x}"))
                };
                conn.insert((p.top.clone(), p.port), s.clone());
                conn.insert((c.top.clone(), c.port), s);
                continue;
            }
            // The producer's net, the link (ds_link, on the producer's clock,
            // or the chip's unit's for the host's links), the consumer's net:
            // a family member's is its slice of the family's vectors, the
            // host's is the chip's port.
            let mut side = |end: &End, s: &str| -> [String; 3] {
                if end.top == "host" {
                    return ["valid", "ready", "data"].map(|x| format!("{}_{x}", end.port));
                }
                if self.in_family(&end.top) {
                    return self.signal(end, *id);
                }
                wires.push(format!("    wire {n}_{s}_valid;"));
                wires.push(format!("    wire {n}_{s}_ready;"));
                wires.push(format!("    wire {}{n}_{s}_data;", range(end.width)));
                ["valid", "ready", "data"].map(|x| format!("{n}_{s}_{x}"))
            };
            let push = side(p, "push");
            let pop = side(c, "pop");
            let clock = if p.top == "host" { cclk } else { pclk };
            links.push(crate::rtl::verilog::link_instance(
                local,
                p.width,
                self.link_cfgs[*id as usize],
                clock,
                &push,
                &pop,
            ));
            if p.top != "host" {
                conn.insert((p.top.clone(), p.port), push);
            }
            if c.top != "host" {
                conn.insert((c.top.clone(), c.port), pop);
            }
        }
        Ok(Wiring {
            ports,
            wires,
            conn,
            links,
        })
    }

    /// An instance's parameter list, its declared values.
    fn params_of(inst: &Inst) -> String {
        if inst.params.is_empty() {
            return String::new();
        }
        let ps: Vec<String> = inst
            .params
            .iter()
            .map(|(name, val)| format!(".{name}({val})"))
            .collect();
        format!(" #({})", ps.join(", "))
    }

    /// One instantiation per instance, named as the model's unit (`scheduler`,
    /// `tm3`, `mem_ctrl2`): the other instances, then each family's members
    /// in order.
    fn write_instances(&self, v: &mut String, conn: &Wiring) {
        let write = |v: &mut String, top: &str| {
            let inst = &self.insts[top];
            let mut cs = vec![format!(".clk({})", inst.clock), ".rst(rst)".to_string()];
            for &(port, _, _) in &inst.ports {
                let s = &conn.conn[&(top.to_string(), port)];
                for (k, suf) in ["valid", "ready", "data"].iter().enumerate() {
                    cs.push(format!(".{port}_{suf}({})", s[k]));
                }
            }
            let _ = writeln!(
                v,
                "    {}{} {top} (\n        {}\n    );",
                inst.module,
                Self::params_of(inst),
                cs.join(",\n        ")
            );
        };
        for top in self.insts.keys() {
            if top != "host" && !self.in_family(top) {
                write(v, top);
            }
        }
        for (base, ks) in &self.families {
            for k in ks {
                write(v, &format!("{base}{k}"));
            }
        }
    }
}

/// The Verilog text of the chip top for `cfg`.
pub fn emit_chip(cfg: &Config) -> Result<String, ChipError> {
    let chip = elaborate(cfg)?;
    let top = Top::of(&chip)?;
    let w = top.wiring()?;
    let mut v = String::new();
    let _ = writeln!(
        v,
        "// Generated by dualstream from {}; do not edit.",
        file!()
    );
    let _ = writeln!(
        v,
        "// Regenerate with `dualstream hdl --out hdl/` (sizes from the config: --config)."
    );
    let _ = writeln!(
        v,
        "// The chip top: {} TMs of {} TPs, the global units and their links, as simulated.",
        cfg.chip.tms, cfg.tm.tps
    );
    let _ = writeln!(
        v,
        "// Ports: the host's links (it is not hardware); one clock per clock domain."
    );
    let _ = writeln!(
        v,
        "module chip\n{}(\n    {}\n);",
        crate::rtl::verilog::IMPORT,
        w.ports.join(",\n    ")
    );
    for (base, ks) in &top.families {
        let _ = writeln!(
            v,
            "    localparam integer {} = {};",
            count_name(base),
            ks.len()
        );
    }
    let _ = writeln!(
        v,
        "    localparam integer TPS = {}; // TPs per TM (tm.v is generated for this many)",
        cfg.tm.tps
    );
    for l in &w.wires {
        let _ = writeln!(v, "{l}");
    }
    top.write_instances(&mut v, &w);
    for l in &w.links {
        v.push_str(l);
    }
    let _ = writeln!(v, "    wire _unused_ok = &{{1'b0, TPS[0], 1'b0}};");
    let _ = writeln!(v, "endmodule");
    Ok(v)
}

/// The declaration of every hardware unit, built with `cfg` (for `dualstream hdl`
/// and the declaration tests). Link ids are placeholders: only the interface
/// matters. Panics on an invalid `cfg` (tests); `dualstream hdl` uses
/// [`catalog_checked`].
pub fn catalog(cfg: &Config) -> Vec<UnitDecl> {
    catalog_checked(cfg).expect("a valid configuration")
}

/// The units the catalog declares as constructed on their own (the chip's
/// global units come from the elaborated chip): the pipelines, a channel
/// controller and the TM's units. Link ids are placeholders.
fn standalone_units(cfg: &Config) -> Vec<Box<dyn Unit>> {
    use units::{box_pipe, divider, mem_ctrl, tri_pipe};
    let d = cfg.links.tm.delay;
    let (i, o) = (LinkId(0), LinkId(1));
    let mut v: Vec<Box<dyn Unit>> = vec![
        Box::new(box_pipe::BoxPipe::new(
            &cfg.box_pipe,
            d,
            box_pipe::BoxPipePorts {
                req: In::new(i),
                resp: Out::new(o),
            },
        )),
        Box::new(tri_pipe::TriPipe::new(
            &cfg.tri_pipe,
            d,
            tri_pipe::TriPipePorts {
                req: In::new(i),
                resp: Out::new(o),
            },
        )),
        Box::new(divider::Divider::new(
            &cfg.divider,
            d,
            divider::DividerPorts {
                req: In::new(i),
                resp: Out::new(o),
            },
        )),
        Box::new(mem_ctrl::MemCtrl::new(
            &cfg.mem,
            cfg.clocks.dram_ps,
            0,
            mem_ctrl::MemCtrlPorts {
                req: In::new(i),
                resp: Out::new(o),
            },
        )),
    ];
    v.extend(units::tm_units(&cfg.tm_spec()));
    v
}

/// [`catalog`], with an error naming what is wrong in `cfg`.
pub fn catalog_checked(cfg: &Config) -> Result<Vec<UnitDecl>, ChipError> {
    let mut v: Vec<UnitDecl> = standalone_units(cfg)
        .iter()
        .map(|u| u.decl_at_reset())
        .collect();
    // The chip's global units as the chip instantiates them (one source: the
    // elaborated chip, so `hdl/chip.v` and these modules agree).
    for g in global_decls(cfg)? {
        if !v.iter().any(|x| x.module == g.module) {
            v.push(g);
        }
    }
    Ok(v)
}

/// The configuration sections whose integers size or time the hardware; in
/// `tm.costs` only each state's `cycles` (the rest are instruction counts
/// for the energy model); [`SIM_ONLY`] left out.
const PARAM_SECTIONS: [&str; 8] = [
    "clocks", "links", "box_pipe", "tri_pipe", "divider", "tm", "chip", "mem",
];

/// `cfg`'s sizes and latencies as (name, SV type, value) localparams, named
/// by their path in the configuration (`[tm.l1] bytes` -> `TM_L1_BYTES`);
/// texts and fractions are left to the comment lines of `notes`.
/// Settings of the simulation or the energy model, not of the hardware.
const SIM_ONLY: [&str; 3] = [
    "mem.energy",
    "chip.watchdog_cycles",
    "chip.memory.check_timing",
];

fn config_params(cfg: &Config, notes: &mut Vec<String>) -> Vec<(String, String, String)> {
    fn walk(
        path: &str,
        v: &serde_json::Value,
        out: &mut Vec<(String, String, String)>,
        notes: &mut Vec<String>,
    ) {
        use serde_json::Value;
        let name = path.replace('.', "_").to_ascii_uppercase();
        let energy_count = path.starts_with("tm.costs.")
            && path.matches('.').count() == 3
            && !path.ends_with(".cycles");
        if energy_count || SIM_ONLY.contains(&path) {
            return;
        }
        match v {
            Value::Object(m) => {
                for (k, x) in m {
                    walk(&format!("{path}.{k}"), x, out, notes);
                }
            }
            // Icarus 11 takes no `int unsigned`/`bit` localparams.
            Value::Bool(b) => out.push((name, "[0:0]".into(), format!("1'b{}", *b as u8))),
            Value::Number(n) => match n.as_u64() {
                Some(x) if x < 1 << 31 => out.push((name, "integer".into(), x.to_string())),
                Some(x) => out.push((name, "[63:0]".into(), format!("64'd{x}"))),
                None => notes.push(format!("{name} = {n}")),
            },
            Value::String(t) => notes.push(format!("{name} = \"{t}\"")),
            Value::Array(a) => {
                for (k, x) in a.iter().enumerate() {
                    walk(&format!("{path}.{k}"), x, out, notes);
                }
            }
            Value::Null => {}
        }
    }
    let json = serde_json::to_value(cfg).expect("a configuration serialises");
    let mut out = Vec::new();
    for sec in PARAM_SECTIONS {
        if let Some(v) = json.get(sec) {
            walk(sec, v, &mut out, notes);
        }
    }
    out
}

/// The text of `hdl/ds_pkg.sv` for `cfg`: a struct for every payload type on
/// a port of the catalog's modules, an enum for every FSM state register,
/// and the configured sizes and latencies.
pub fn emit_package(cfg: &Config) -> Result<String, ChipError> {
    let mut pkg = crate::rtl::sv::Package::default();
    for d in catalog_checked(cfg)? {
        for p in &d.ports {
            pkg.declare(&p.ty).map_err(ChipError::Hdl)?;
        }
        for s in &d.state {
            if let Some(t @ crate::rtl::sv::SvType::Enum { .. }) = &s.ty {
                pkg.declare(t).map_err(ChipError::Hdl)?;
            }
        }
    }
    let mut notes = Vec::new();
    let params = config_params(cfg, &mut notes);
    let mut header = vec![
        format!("Generated by dualstream from {}; do not edit.", file!()),
        "Regenerate with `dualstream hdl --out hdl/` (sizes from the config: --config).".into(),
        "The payload types, FSM encodings and configured sizes every module imports.".into(),
        "A struct's members are listed MSB first: the reverse of the model's field".into(),
        "order (`pack` puts the first field in the lowest bits). Read it before the".into(),
        "modules: `verilator ... hdl/ds_pkg.sv hdl/<unit>.v`.".into(),
    ];
    if !notes.is_empty() {
        header.push("Configured, not numbers:".into());
        header.extend(notes.into_iter().map(|n| format!("  {n}")));
    }
    Ok(pkg.emit(&header, &params))
}

/// Writes `ds_pkg.sv`, one `<module>.v` per unit, `tm.v`, `chip.v` and the
/// link module they instantiate (`ref/ds_link.sv`) into `dir` (created if
/// missing); returns the paths.
pub fn write_hdl(
    cfg: &Config,
    dir: &std::path::Path,
) -> Result<Vec<std::path::PathBuf>, ChipError> {
    std::fs::create_dir_all(dir).map_err(|e| {
        let msg = format!(
            "cannot create the HDL directory '{}': {e}; choose a writable --out",
            dir.display()
        );
        ChipError::File(FileError::new(dir, e, msg))
    })?;
    let unwritable = |p: &std::path::Path, e: std::io::Error| {
        let msg = format!(
            "cannot write '{}': {e}; choose a writable --out",
            p.display()
        );
        ChipError::File(FileError::new(p, e, msg))
    };
    let mut out = Vec::new();
    // The package first: every module imports it.
    let p = dir.join("ds_pkg.sv");
    std::fs::write(&p, emit_package(cfg)?).map_err(|e| unwritable(&p, e))?;
    out.push(p);
    for d in catalog_checked(cfg)? {
        let p = dir.join(format!("{}.v", d.module));
        std::fs::write(&p, crate::rtl::verilog::emit_module(&d)).map_err(|e| unwritable(&p, e))?;
        out.push(p);
    }
    // The link module the netlists instantiate: hand-written (hdl/ref/),
    // copied so that an emitted directory is complete.
    let r = dir.join("ref");
    std::fs::create_dir_all(&r).map_err(|e| unwritable(&r, e))?;
    let p = r.join("ds_link.sv");
    std::fs::write(&p, crate::rtl::verilog::LINK_RTL).map_err(|e| unwritable(&p, e))?;
    out.push(p);
    // The TM is structural: instances of the units above, wired as simulated.
    let p = dir.join("tm.v");
    std::fs::write(&p, units::tm::emit_verilog(&cfg.tm_spec())).map_err(|e| unwritable(&p, e))?;
    out.push(p);
    // The chip top: every unit instantiated and wired as simulated.
    let p = dir.join("chip.v");
    std::fs::write(&p, emit_chip(cfg)?).map_err(|e| unwritable(&p, e))?;
    out.push(p);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbered_instances_from_zero_are_families() {
        let f = families(["tm0", "tm1", "tm2", "l2", "scheduler", "mem_ctrl0", "host"]);
        assert_eq!(f.keys().collect::<Vec<_>>(), ["mem_ctrl", "tm"]);
        assert_eq!(f["tm"], [0, 1, 2]);
        assert_eq!(family("tm12"), ("tm", Some(12)));
        assert_eq!(family("scene_buffer"), ("scene_buffer", None));
        assert_eq!(top_of("chip.tm3.l1"), "tm3");
    }

    /// Every memory sized by a parameter expression is that big, on the
    /// default chip and on one whose sizes all differ; a wrong bound is
    /// caught and named.
    #[test]
    fn memories_are_sized_by_their_parameters() {
        let mut other = Config::default();
        other.tm.scratchpad_bytes /= 2;
        other.tm.staging_half_bytes *= 2;
        other.tm.l1.bytes /= 4;
        other.tm.l1.mshrs += 3;
        for cfg in [Config::default(), other] {
            let decls = catalog_checked(&cfg).unwrap();
            let sized: usize = decls
                .iter()
                .map(|d| d.state.iter().filter(|s| s.depth_expr.is_some()).count())
                .sum();
            assert!(sized >= 6, "{sized}");
            for d in &decls {
                assert_eq!(d.depth_mismatches(), Vec::<String>::new());
            }
            let tp = decls.iter().find(|d| d.module == "tp").unwrap();
            let v = crate::rtl::verilog::emit_module(tp);
            assert!(v.contains(" stack [0:STACK_ENTRIES - 1];"), "{v}");
            assert!(!v.contains("for (int i"), "memories are not reset: {v}");
            // A bound that is not the depth.
            let mut bad = tp.clone();
            let k = bad.state.iter().position(|s| s.name == "stack").unwrap();
            bad.state[k].depth_expr = Some("2 * STACK_ENTRIES");
            let m = bad.depth_mismatches();
            assert!(
                m.len() == 1 && m[0].contains("tp.stack") && m[0].contains("'2 * STACK_ENTRIES'"),
                "{m:?}"
            );
            bad.state[k].depth_expr = Some("STACK_ENTRIE");
            assert!(bad.depth_mismatches()[0].contains("'STACK_ENTRIE' is no parameter of tp"));
        }
    }

    #[test]
    fn the_top_instantiates_every_unit_of_a_small_chip() {
        let mut cfg = Config::default();
        cfg.chip.tms = 3;
        cfg.tm.tps = 2;
        let v = emit_chip(&cfg).unwrap();
        assert!(v.contains("localparam integer TMS = 3;"));
        assert!(v.contains("localparam integer TPS = 2;"));
        // One instance per TM, named as the model's unit; no generate loop.
        for k in 0..3 {
            assert_eq!(v.matches(&format!("    tm tm{k} (")).count(), 1, "tm{k}");
        }
        assert!(!v.contains("genvar") && !v.contains(" u_"), "{v}");
        for u in ["scheduler", "scene_buffer", "hit_updater", "memory"] {
            assert_eq!(v.matches(&format!(" {u} (")).count(), 1, "{u}");
        }
        assert!(v.contains("    input  wire clk_core,") && v.contains(".clk(clk_core)"));
        // Each TM's seven links, on both ends.
        for p in [
            "fill",
            "miss_req",
            "miss_resp",
            "ray_write",
            "hit",
            "gmem_req",
            "gmem_resp",
        ] {
            for k in 0..3 {
                assert!(
                    v.contains(&format!(".{p}_valid(tm_{p}_valid[{k}])")),
                    "{p} {k}"
                );
            }
        }
        assert!(v.contains(".fill_2_valid(tm2_fill_push_valid)"));
        assert!(v.contains(".pop_valid(tm_fill_valid[2])"));
        // TM 2's other ends are wired to some global unit's port.
        for p in [
            "miss_req",
            "miss_resp",
            "ray_write",
            "hit",
            "gmem_req",
            "gmem_resp",
        ] {
            assert_eq!(
                v.matches(&format!("_valid(tm_{p}_valid[2])")).count(),
                2,
                "{p}: TM 2's port and the other end"
            );
        }
        let mut bad = cfg.clone();
        bad.chip.tms = 0;
        let e = emit_chip(&bad).unwrap_err();
        assert!(matches!(e, ChipError::Config(_)), "{e:?}");
        assert!(e.to_string().contains("chip.tms"));
    }

    /// Every unit, as constructed for the catalog and as elaborated into the
    /// chip (which resets it), holds the reset its declaration gives (the
    /// Verilog's): with the L2 and GDDR5 channels, and without.
    #[test]
    fn every_unit_holds_its_declared_reset() {
        let mut plain = Config::default();
        plain.chip.l2.enabled = false;
        plain.chip.memory.model = crate::units::memory::MemoryModel::Fixed;
        let mut modules = std::collections::BTreeSet::new();
        for cfg in [Config::default(), plain] {
            let own = standalone_units(&cfg);
            let chip = elaborate(&cfg).unwrap();
            let in_chip = (0..chip.sim.unit_count()).map(|i| chip.sim.unit(UnitId(i as u32)));
            for u in own.iter().map(|u| &**u).chain(in_chip) {
                let bad = crate::rtl::unit::reset_mismatches(u, 0);
                assert!(bad.is_empty(), "{bad:?}");
                modules.insert(u.decl().module);
            }
        }
        for m in [
            "box_pipe",
            "tri_pipe",
            "divider",
            "mem_ctrl",
            "tp",
            "l1",
            "staging_buffer",
            "tm_xbar",
            "stream_scheduler",
            "scene_buffer",
            "hit_record_updater",
            "l2",
            "memory",
        ] {
            assert!(modules.contains(m), "{m} not checked");
        }
    }
}
