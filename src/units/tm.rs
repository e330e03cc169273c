//! The thread multiprocessor (TM, paper §4 and Figure 1): 16 thread processors
//! sharing an L1, a ray staging buffer, one ray-box pipeline, two ray-triangle
//! pipelines and one divider. The TM is structural: this file holds its
//! configuration, builds its units and links into a simulator, and emits the
//! structural Verilog module that instantiates them. The arbitration between the
//! TPs lives in `tm_xbar.rs` (pipelines, outputs) and `l1.rs` (banks).
//!
//! Ports to the outside (created by the caller, see [`build`]):
//! - `fill` (in, [`SbFill`]): rays of one bucket into the staging buffer;
//! - `miss_req` (out, [`L1Req`]) / `miss_resp` (in, [`L1Resp`]): the L1 miss path,
//!   line address out, 64 B line back (later: the scene buffer);
//! - `ray_write` (out, [`RayWrite`]): a duplicate for a child segment's queue;
//! - `hit` (out, [`HitUpdate`]): a segment's best hit for the hit record updater;
//! - `gmem_req` (out, [`MemLineReq`]) / `gmem_resp` (in, [`MemLineResp`]): the TPs'
//!   global loads and stores of the shading pass (to the L2), `id` = TP index.

use serde::{Deserialize, Serialize};

use crate::contract::{HitRec, RayRec};
use crate::rtl::PipeCfg;
use crate::rtl::bits::{Bits, Field, Payload, field_path};
use crate::rtl::sv::SvType;
use crate::rtl::{ClockId, In, LinkCfg, Out, Sim, UnitId};

use super::divider::{Divider, DividerPorts};
use super::l1::{L1, L1Ports, L1Req, L1Resp};
use super::memory::{MemLineReq, MemLineResp};
use super::staging_buffer::{SbFill, StagingBuffer, StagingBufferPorts};
use super::tm_xbar::{TmXbar, TmXbarPorts};
use super::tp::{HitUpdate, RayWrite, Tp, TpPorts};
use super::tri_pipe::{TriPipe, TriPipePorts};

/// Everything a TM is built from: its own configuration and the timing of the
/// pipelines it holds and of its internal links (the model configuration's
/// `[tm]`, `[box_pipe]`, `[tri_pipe]`, `[divider]`, `[links] tm` and
/// `[clocks] core_ps`; `Config::tm_spec`).
#[derive(Clone, Debug, PartialEq)]
pub struct TmSpec {
    pub tm: TmCfg,
    pub box_pipe: PipeCfg,
    pub tri_pipe: PipeCfg,
    pub divider: PipeCfg,
    /// Request and response links between the TPs and the shared units.
    pub link: LinkCfg,
    /// The core clock period (ps), for the scratch simulator of `emit_verilog`.
    pub core_ps: u64,
}

// ---- payloads of data-contract records ----

impl Payload for RayRec {
    const BITS: u32 = 256;
    fn sv_type() -> SvType {
        SvType::Struct {
            name: "RayRec".into(),
            members: vec![
                ("origin", glam::Vec3::sv_type()),
                ("dir", glam::Vec3::sv_type()),
                ("ray_id", SvType::Logic(32)),
                ("entry", SvType::Logic(32)),
            ],
        }
    }
    fn fields(prefix: &str, at: u32, out: &mut Vec<Field>) {
        glam::Vec3::fields(&field_path(prefix, "origin"), at, out);
        glam::Vec3::fields(&field_path(prefix, "dir"), at + 96, out);
        u32::fields(&field_path(prefix, "ray_id"), at + 192, out);
        u32::fields(&field_path(prefix, "entry"), at + 224, out);
    }
    fn pack(&self, out: &mut Bits) {
        self.origin.pack(out);
        self.dir.pack(out);
        self.ray_id.pack(out);
        self.entry.pack(out);
    }
    fn same_bits(&self, o: &Self) -> bool {
        self.origin.same_bits(&o.origin)
            && self.dir.same_bits(&o.dir)
            && self.ray_id == o.ray_id
            && self.entry == o.entry
    }
}

impl Payload for HitRec {
    const BITS: u32 = 128;
    fn sv_type() -> SvType {
        SvType::Struct {
            name: "HitRec".into(),
            members: vec![
                ("t", SvType::Float),
                ("tri_id", SvType::Logic(32)),
                ("u", SvType::Float),
                ("v", SvType::Float),
            ],
        }
    }
    fn fields(prefix: &str, at: u32, out: &mut Vec<Field>) {
        f32::fields(&field_path(prefix, "t"), at, out);
        u32::fields(&field_path(prefix, "tri_id"), at + 32, out);
        f32::fields(&field_path(prefix, "u"), at + 64, out);
        f32::fields(&field_path(prefix, "v"), at + 96, out);
    }
    fn pack(&self, out: &mut Bits) {
        self.t.pack(out);
        self.tri_id.pack(out);
        self.u.pack(out);
        self.v.pack(out);
    }
    fn same_bits(&self, o: &Self) -> bool {
        self.t.same_bits(&o.t)
            && self.tri_id == o.tri_id
            && self.u.same_bits(&o.u)
            && self.v.same_bits(&o.v)
    }
}

// ---- configuration ----

/// Cost of one TP FSM state: the cycles it occupies the TP and the instructions of
/// the traversal kernel it stands for, by functional-unit class (simtrax classes,
/// hardware reference §1.2 and §4.1), for the energy model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StateCost {
    /// Core cycles the state occupies its TP.
    pub cycles: u32,
    /// INTADD, BITWISE, moves (1 cycle each).
    pub int: u32,
    /// INTMUL (1 cycle, one unit per 16 threads).
    pub int_mul: u32,
    /// FPADD (2 cycles).
    pub fp_add: u32,
    /// FPMUL (2 cycles).
    pub fp_mul: u32,
    /// FPMIN, FPCMP (1 cycle).
    pub fp_cmp: u32,
    /// BLT and friends (1 cycle).
    pub branch: u32,
    /// Loads from the local store or the staging buffer (L1 loads are counted by the L1).
    pub load: u32,
    /// Stores to the local store, and sends to the stream units.
    pub store: u32,
}

impl StateCost {
    const fn new(cycles: u32, i: [u32; 8]) -> Self {
        StateCost {
            cycles,
            int: i[0],
            int_mul: i[1],
            fp_add: i[2],
            fp_mul: i[3],
            fp_cmp: i[4],
            branch: i[5],
            load: i[6],
            store: i[7],
        }
    }
    pub fn instructions(&self) -> u32 {
        self.int
            + self.int_mul
            + self.fp_add
            + self.fp_mul
            + self.fp_cmp
            + self.branch
            + self.load
            + self.store
    }
}

/// The TP cost table. Calibration: a TP is single-issue and in order, so a state
/// costs one cycle per instruction of the traversal kernel it stands for, plus one
/// bubble per dependent FPADD/FPMUL (simtrax latency 2, hardware reference §1.2);
/// every other class has latency 1. Waiting for the L1, the divider and the
/// pipelines is not in the table: it is the simulated round trip. The instruction
/// lists are in `docs/tm.md`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TpCosts {
    /// Load the ray (8 words) from the staging buffer; issue the inverse.
    pub fetch: StateCost,
    /// Reset the best hit; push the entry reference onto the stack.
    pub init: StateCost,
    /// Pop an entry, cull it against the best hit, decode its reference.
    pub pop: StateCost,
    /// Send the duplicate to the child segment's queue.
    pub exit: StateCost,
    /// Node address; the L1 load itself is the round trip.
    pub node_fetch: StateCost,
    /// Box-test limit, issue both children.
    pub box_issue: StateCost,
    /// Order the hit children, push them.
    pub node_push: StateCost,
    /// Triangle address and its lines.
    pub tri_fetch: StateCost,
    /// Triangle-test limit, issue.
    pub tri_issue: StateCost,
    /// Closest-hit compare and update, next triangle.
    pub tri_result: StateCost,
    /// Hit index, send the hit update.
    pub finish: StateCost,
    /// Shading: address of a record (path state, hit records, triangle index,
    /// triangle, material) and its global load through the L2.
    pub shade_load: StateCost,
    /// Shading: the shading arithmetic of one pixel (`units::shade::shade_step`).
    pub shade: StateCost,
    /// Shading: send one new ray (8 words) to the root queue, or the item's end marker.
    pub shade_emit: StateCost,
    /// Shading: store the path state and reset the new rays' hit records.
    pub shade_store: StateCost,
}

/// Number of costed TP states (`TpCosts::all`).
pub const COSTS: usize = 15;

/// The computing states' names, in [`TpCosts::all`] order (the TP's counters).
pub const COST_NAMES: [&str; COSTS] = [
    "fetch",
    "init",
    "pop",
    "exit",
    "node_fetch",
    "box_issue",
    "node_push",
    "tri_fetch",
    "tri_issue",
    "tri_result",
    "finish",
    "shade_load",
    "shade",
    "shade_emit",
    "shade_store",
];

impl Default for TpCosts {
    fn default() -> Self {
        // [int, int_mul, fp_add, fp_mul, fp_cmp, branch, load, store]
        TpCosts {
            fetch: StateCost::new(8, [0, 0, 0, 0, 0, 0, 8, 0]),
            init: StateCost::new(8, [5, 0, 0, 0, 0, 0, 0, 3]),
            pop: StateCost::new(14, [4, 0, 0, 1, 2, 3, 3, 0]),
            exit: StateCost::new(3, [2, 0, 0, 0, 0, 0, 0, 1]),
            node_fetch: StateCost::new(3, [3, 0, 0, 0, 0, 0, 0, 0]),
            box_issue: StateCost::new(4, [0, 0, 0, 1, 1, 0, 0, 1]),
            node_push: StateCost::new(12, [2, 0, 0, 0, 1, 3, 0, 6]),
            tri_fetch: StateCost::new(5, [3, 1, 0, 0, 0, 1, 0, 0]),
            tri_issue: StateCost::new(2, [0, 0, 0, 0, 1, 0, 0, 1]),
            tri_result: StateCost::new(12, [6, 0, 0, 0, 2, 4, 0, 0]),
            finish: StateCost::new(4, [2, 0, 0, 0, 0, 1, 0, 1]),
            // Shading (docs/tm.md, "Cost table calibration"): estimates from the
            // operation counts of `shade_step`, not calibrated against simtrax like
            // the rest.
            shade_load: StateCost::new(3, [2, 1, 0, 0, 0, 0, 0, 0]),
            shade: StateCost::new(124, [15, 2, 36, 40, 13, 8, 0, 0]),
            shade_emit: StateCost::new(8, [0, 0, 0, 0, 0, 0, 0, 8]),
            shade_store: StateCost::new(16, [0, 0, 0, 0, 0, 0, 0, 16]),
        }
    }
}

impl TpCosts {
    pub fn all(&self) -> [(&'static str, &StateCost); COSTS] {
        let c = [
            &self.fetch,
            &self.init,
            &self.pop,
            &self.exit,
            &self.node_fetch,
            &self.box_issue,
            &self.node_push,
            &self.tri_fetch,
            &self.tri_issue,
            &self.tri_result,
            &self.finish,
            &self.shade_load,
            &self.shade,
            &self.shade_emit,
            &self.shade_store,
        ];
        std::array::from_fn(|k| (COST_NAMES[k], c[k]))
    }

    /// The index of the state named `name` in [`TpCosts::all`] (and in
    /// `TpStats::uses`).
    pub fn index_of(name: &str) -> Option<usize> {
        COST_NAMES.iter().position(|&n| n == name)
    }
}

/// The per-TM L1 data cache.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct L1Cfg {
    /// 16 KB [DS17 Table 1].
    pub bytes: u32,
    /// 8 banks [DS17 Table 1]; a bank serves one request per cycle.
    pub banks: u32,
    /// 64 B lines (simtrax default, hardware reference §1.2; one data-contract line).
    pub line_bytes: u32,
    /// Cycles from acceptance to the line being visible to the TP, including the
    /// response link: 1, simtrax's L1 hit (hardware reference §1.2). Direct mapped
    /// like simtrax's L1.
    pub hit_latency: u32,
    /// Outstanding line misses (MSHRs); a miss to a line already missing merges.
    pub mshrs: u32,
}

impl Default for L1Cfg {
    fn default() -> Self {
        L1Cfg {
            bytes: 16 << 10,
            banks: 8,
            line_bytes: 64,
            hit_latency: 1,
            mshrs: 8,
        }
    }
}

/// The thread multiprocessor.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TmCfg {
    /// Thread processors per TM: 16 [DS17 Table 1].
    pub tps: u32,
    /// Ray-triangle pipelines per TM: 2 [DS17 §5.1].
    pub tri_pipes: u32,
    /// Local scratchpad per TP: 512 B [DS17 §5.1]; holds the traversal stack.
    pub scratchpad_bytes: u32,
    /// One stack entry: reference, segment word, entry distance (3 words).
    pub stack_entry_bytes: u32,
    /// One half of the ray staging buffer: 2 KB, one ray bucket [DS17 Table 1, §4.1].
    pub staging_half_bytes: u32,
    pub l1: L1Cfg,
    pub costs: TpCosts,
}

impl Default for TmCfg {
    fn default() -> Self {
        TmCfg {
            tps: 16,
            tri_pipes: 2,
            scratchpad_bytes: 512,
            stack_entry_bytes: 12,
            staging_half_bytes: 2048,
            l1: L1Cfg::default(),
            costs: TpCosts::default(),
        }
    }
}

impl TmCfg {
    /// Stack entries the scratchpad holds.
    pub fn stack_entries(&self) -> u32 {
        self.scratchpad_bytes / self.stack_entry_bytes.max(1)
    }
    /// Rays one staging-buffer half holds.
    pub fn half_rays(&self) -> u32 {
        self.staging_half_bytes / crate::contract::RAY_BYTES
    }

    pub fn validate(&self, links: &LinkCfg) -> Result<(), super::UnitError> {
        if self.tps == 0 || self.tps > 32 {
            return Err(super::UnitError::Invalid(format!(
                "tm.tps = {} is impossible: a TM needs 1 to 32 thread processors (L1 waiter masks are 32 bits)",
                self.tps
            )));
        }
        if self.tri_pipes == 0 || self.tri_pipes > 8 {
            return Err(super::UnitError::Invalid(format!(
                "tm.tri_pipes = {}: give 1 to 8 ray-triangle pipelines",
                self.tri_pipes
            )));
        }
        if self.stack_entry_bytes < 12 {
            return Err(super::UnitError::Invalid(format!(
                "tm.stack_entry_bytes = {} cannot hold a reference, a segment word and a distance (12 B)",
                self.stack_entry_bytes
            )));
        }
        if self.stack_entries() < 2 {
            return Err(super::UnitError::Invalid(format!(
                "tm.scratchpad_bytes = {} holds {} stack entries; a traversal needs at least 2 (a node pushes two children)",
                self.scratchpad_bytes,
                self.stack_entries()
            )));
        }
        if self.half_rays() == 0 || self.half_rays() > 1024 {
            return Err(super::UnitError::Invalid(format!(
                "tm.staging_half_bytes = {} must hold 1 to 1024 rays of 32 B",
                self.staging_half_bytes
            )));
        }
        let l1 = &self.l1;
        if l1.line_bytes != crate::contract::LINE_BYTES as u32 {
            return Err(super::UnitError::Invalid(format!(
                "tm.l1.line_bytes = {}: only 64 B lines are modelled (the data contract's line)",
                l1.line_bytes
            )));
        }
        if l1.banks == 0 || !l1.banks.is_power_of_two() {
            return Err(super::UnitError::Invalid(format!(
                "tm.l1.banks = {} must be a power of two",
                l1.banks
            )));
        }
        let lines = l1.bytes / l1.line_bytes;
        if l1.bytes == 0 || !lines.is_power_of_two() || lines < l1.banks {
            return Err(super::UnitError::Invalid(format!(
                "tm.l1.bytes = {} must be a power-of-two number of lines, at least one per bank",
                l1.bytes
            )));
        }
        if l1.hit_latency < links.delay {
            return Err(super::UnitError::Invalid(format!(
                "tm.l1.hit_latency = {} is shorter than the response link delay ({}, links.tm.delay), which is part of it",
                l1.hit_latency, links.delay
            )));
        }
        if l1.mshrs == 0 {
            return Err(super::UnitError::Invalid(
                "tm.l1.mshrs = 0: a cache needs at least one miss register".into(),
            ));
        }
        for (name, c) in self.costs.all() {
            if c.cycles == 0 {
                return Err(super::UnitError::Invalid(format!(
                    "tm.costs.{name}.cycles = 0: every TP state takes at least one cycle"
                )));
            }
            if c.instructions() > c.cycles {
                return Err(super::UnitError::Invalid(format!(
                    "tm.costs.{name}: {} instructions cannot issue in {} cycles on a single-issue TP",
                    c.instructions(),
                    c.cycles
                )));
            }
        }
        Ok(())
    }
}

// ---- structure ----

/// The units of one built TM.
#[derive(Clone, Debug)]
pub struct TmUnits {
    pub tps: Vec<UnitId>,
    pub staging_buffer: UnitId,
    pub l1: UnitId,
    /// The crossbar, which holds the ray-box pipeline.
    pub xbar: UnitId,
    pub tri_pipes: Vec<UnitId>,
    pub divider: UnitId,
}

impl TmUnits {
    /// Every unit of the TM.
    pub fn all(&self) -> impl Iterator<Item = UnitId> + '_ {
        self.tps
            .iter()
            .copied()
            .chain([self.staging_buffer, self.l1, self.xbar])
            .chain(self.tri_pipes.iter().copied())
            .chain([self.divider])
    }
}

/// The TM's outside ports, as seen from the TM.
pub struct TmPorts {
    pub fill: In<SbFill>,
    pub miss_req: Out<L1Req>,
    pub miss_resp: In<L1Resp>,
    pub ray_write: Out<RayWrite>,
    pub hit: Out<HitUpdate>,
    pub gmem_req: Out<MemLineReq>,
    pub gmem_resp: In<MemLineResp>,
}

/// Round trips a TP sees with idle units (cycles from its push to the response
/// being visible): TP -> xbar -> unit -> xbar -> TP, each link `d`, the unit's
/// latency including its output link.
pub fn round_trip(pipe: &PipeCfg, links: &LinkCfg) -> u64 {
    pipe.latency as u64 + 3 * links.delay as u64
}

/// Builds a TM under `path` (e.g. `chip.tm3`) in `sim`.
pub fn build(sim: &mut Sim, clock: ClockId, cfg: &TmSpec, path: &str, ports: TmPorts) -> TmUnits {
    let l = cfg.link;
    let n = cfg.tm.tps as usize;
    let p = |s: &str| format!("{path}.{s}");
    macro_rules! links {
        ($t:ty, $name:expr, $count:expr) => {
            sim.links::<$t>($count, |k| format!("{path}.{}{k}", $name), l)
        };
    }
    // One-entry ray links: a TP holds at most its next ray, so rays go to free TPs.
    let (sb_o, sb_i) = sim.links(n, |k| p(&format!("ray{k}")), LinkCfg { depth: 1, ..l });
    let (div_q_o, div_q_i) = links!(super::divider::DivReq, "tp_div_req", n);
    let (div_r_o, div_r_i) = links!(super::divider::DivResp, "tp_div_resp", n);
    let (box_q_o, box_q_i) = links!(super::box_pipe::BoxReq, "tp_box_req", n);
    let (box_r_o, box_r_i) = links!(super::box_pipe::BoxResp, "tp_box_resp", n);
    let (tri_q_o, tri_q_i) = links!(super::tri_pipe::TriReq, "tp_tri_req", n);
    let (tri_r_o, tri_r_i) = links!(super::tri_pipe::TriResp, "tp_tri_resp", n);
    let (mem_q_o, mem_q_i) = links!(L1Req, "tp_mem_req", n);
    let (mem_r_o, mem_r_i) = links!(L1Resp, "tp_mem_resp", n);
    let (rw_o, rw_i) = links!(RayWrite, "tp_ray_write", n);
    let (hit_o, hit_i) = links!(HitUpdate, "tp_hit", n);
    let (gq_o, gq_i) = links!(MemLineReq, "tp_gmem_req", n);
    let (gr_o, gr_i) = links!(MemLineResp, "tp_gmem_resp", n);
    let np = cfg.tm.tri_pipes as usize;
    let (pq_o, pq_i) = links!(super::tri_pipe::TriReq, "tri_req", np);
    let (pr_o, pr_i) = links!(super::tri_pipe::TriResp, "tri_resp", np);
    let (dq_o, dq_i) = sim.link(&p("div_req"), l);
    let (dr_o, dr_i) = sim.link(&p("div_resp"), l);

    let mut tps = Vec::with_capacity(n);
    let (mut gq_o, mut gr_i) = (gq_o.into_iter(), gr_i.into_iter());
    for k in 0..n {
        let tp = Tp::new(
            cfg,
            k as u16,
            TpPorts {
                ray: sb_i[k],
                div_req: div_q_o[k],
                div_resp: div_r_i[k],
                box_req: box_q_o[k],
                box_resp: box_r_i[k],
                tri_req: tri_q_o[k],
                tri_resp: tri_r_i[k],
                mem_req: mem_q_o[k],
                mem_resp: mem_r_i[k],
                ray_write: rw_o[k],
                hit: hit_o[k],
                gmem_req: gq_o.next().expect("one per TP"),
                gmem_resp: gr_i.next().expect("one per TP"),
            },
        );
        tps.push(sim.add(&p(&format!("tp{k}")), clock, tp));
    }
    let staging_buffer = sim.add(
        &p("staging_buffer"),
        clock,
        StagingBuffer::new(
            &cfg.tm,
            StagingBufferPorts {
                fill: ports.fill,
                ray: sb_o,
            },
        ),
    );
    let l1 = sim.add(
        &p("l1"),
        clock,
        L1::new(
            &cfg.tm.l1,
            l.delay,
            L1Ports {
                req: mem_q_i,
                resp: mem_r_o,
                miss_req: ports.miss_req,
                miss_resp: ports.miss_resp,
            },
        ),
    );
    let xbar = sim.add(
        &p("xbar"),
        clock,
        TmXbar::new(
            cfg,
            TmXbarPorts {
                div_resp: dr_i,
                div_req: dq_o,
                ray_write: ports.ray_write,
                hit: ports.hit,
                gmem_req: ports.gmem_req,
                gmem_resp: ports.gmem_resp,
                tp_div_req: div_q_i,
                tp_box_req: box_q_i,
                tp_tri_req: tri_q_i,
                tp_ray_write: rw_i,
                tp_hit: hit_i,
                tp_gmem_req: gq_i,
                tri_resp: pr_i,
                tp_div_resp: div_r_o,
                tp_box_resp: box_r_o,
                tp_tri_resp: tri_r_o,
                tp_gmem_resp: gr_o,
                tri_req: pq_o,
            },
        ),
    );
    let mut tri_pipes = Vec::new();
    for (k, (req, resp)) in pq_i.into_iter().zip(pr_o).enumerate() {
        tri_pipes.push(sim.add(
            &p(&format!("tri_pipe{k}")),
            clock,
            TriPipe::new(&cfg.tri_pipe, l.delay, TriPipePorts { req, resp }),
        ));
    }
    let divider = sim.add(
        &p("divider"),
        clock,
        Divider::new(
            &cfg.divider,
            l.delay,
            DividerPorts {
                req: dq_i,
                resp: dr_o,
            },
        ),
    );
    TmUnits {
        tps,
        staging_buffer,
        l1,
        xbar,
        tri_pipes,
        divider,
    }
}

/// The structural Verilog of the TM: one instance per unit, named as the unit's
/// instance in the model (`tp5`, `l1`, `xbar`: a waveform's `chip.tm3.tp5` is the
/// netlist's `chip.tm3.tp5`), each internal link an instance of `ds_link`
/// (`link_<name>`, the model's width, depth and delay) between the producer's
/// and the consumer's valid/ready/data nets (`<name>_push_*`, `<name>_pop_*`),
/// and the outside links as module ports (their `ds_link` is in `chip.v`). Built from a TM elaborated in a scratch
/// simulator, so it is exactly the simulated netlist.
pub fn emit_verilog(cfg: &TmSpec) -> String {
    use crate::rtl::decl::PortDir;
    use crate::rtl::verilog::{IMPORT, link_instance, port_decl};
    use std::collections::BTreeMap;
    use std::fmt::Write;
    let mut sim = Sim::default();
    let clk = sim.clock("core", cfg.core_ps).expect("valid clock");
    let l = cfg.link;
    let (_, fill) = sim.link::<SbFill>("fill", l);
    let (miss_req, _) = sim.link::<L1Req>("miss_req", l);
    let (_, miss_resp) = sim.link::<L1Resp>("miss_resp", l);
    let (ray_write, _) = sim.link::<RayWrite>("ray_write", l);
    let (hit, _) = sim.link::<HitUpdate>("hit", l);
    let (gmem_req, _) = sim.link::<MemLineReq>("gmem_req", l);
    let (_, gmem_resp) = sim.link::<MemLineResp>("gmem_resp", l);
    build(
        &mut sim,
        clk,
        cfg,
        "tm",
        TmPorts {
            fill,
            miss_req,
            miss_resp,
            ray_write,
            hit,
            gmem_req,
            gmem_resp,
        },
    );
    let names: Vec<String> = sim.link_stats().into_iter().map(|(n, _)| n).collect();
    let decls = sim.decls();
    // link -> (producer (inst, port), consumer (inst, port))
    type End = Option<(String, &'static str, crate::rtl::sv::SvType)>;
    let mut ends: BTreeMap<u32, [End; 2]> = BTreeMap::new();
    for (path, d) in &decls {
        let inst = path.trim_start_matches("tm.").to_string();
        for p in &d.ports {
            let e = ends.entry(p.link.0).or_default();
            let k = if p.dir == PortDir::Out { 0 } else { 1 };
            e[k] = Some((inst.clone(), p.name, p.ty.clone()));
        }
    }
    let mut v = String::new();
    let _ = writeln!(
        v,
        "// Generated by dualstream from {}; do not edit.",
        file!()
    );
    let _ = writeln!(v, "// Regenerate with `dualstream hdl --out hdl/`.");
    let _ = writeln!(
        v,
        "// Thread multiprocessor: structural, {} TPs, staging buffer, L1, crossbar, pipelines.",
        cfg.tm.tps
    );
    let mut ports = vec!["input  wire clk".to_string(), "input  wire rst".to_string()];
    let mut wires = Vec::new();
    let mut links = Vec::new();
    // (inst, port) -> signal prefix
    let mut conn: BTreeMap<(String, &'static str), String> = BTreeMap::new();
    for (id, e) in &ends {
        let rng = |w: u32| {
            if w == 1 {
                String::new()
            } else {
                format!("[{}:0] ", w - 1)
            }
        };
        match e {
            [Some(p), Some(c)] => {
                // The producer's net, the link (ds_link), the consumer's net.
                let local = names[*id as usize].trim_start_matches("tm.");
                let w = local.replace('.', "_");
                let side = |s: &str| ["valid", "ready", "data"].map(|x| format!("{w}_{s}_{x}"));
                for s in ["push", "pop"] {
                    wires.push(format!("    wire {w}_{s}_valid;"));
                    wires.push(format!("    wire {w}_{s}_ready;"));
                    wires.push(format!("    wire {}{w}_{s}_data;", rng(p.2.width())));
                }
                links.push(link_instance(
                    local,
                    p.2.width(),
                    sim.link_cfg(crate::rtl::LinkId(*id)),
                    "clk",
                    &side("push"),
                    &side("pop"),
                ));
                conn.insert((p.0.clone(), p.1), format!("{w}_push"));
                conn.insert((c.0.clone(), c.1), format!("{w}_pop"));
            }
            [Some(p), None] => {
                ports.push(format!("output wire {}_valid", p.1));
                ports.push(format!("input  wire {}_ready", p.1));
                ports.push(port_decl(PortDir::Out, &p.2, &format!("{}_data", p.1)));
                conn.insert((p.0.clone(), p.1), p.1.to_string());
            }
            [None, Some(c)] => {
                ports.push(format!("input  wire {}_valid", c.1));
                ports.push(format!("output wire {}_ready", c.1));
                ports.push(port_decl(PortDir::In, &c.2, &format!("{}_data", c.1)));
                conn.insert((c.0.clone(), c.1), c.1.to_string());
            }
            [None, None] => {}
        }
    }
    let _ = writeln!(v, "module tm\n{IMPORT}(\n    {}\n);", ports.join(",\n    "));
    for w in wires {
        let _ = writeln!(v, "{w}");
    }
    for (path, d) in &decls {
        let inst = path.trim_start_matches("tm.").to_string();
        let _ = write!(v, "    {}", d.module);
        if !d.params.is_empty() {
            let ps: Vec<String> = d
                .params
                .iter()
                .map(|p| format!(".{}({})", p.name, p.value))
                .collect();
            let _ = write!(v, " #({})", ps.join(", "));
        }
        let mut cs = vec![".clk(clk)".to_string(), ".rst(rst)".to_string()];
        for p in &d.ports {
            let s = &conn[&(inst.clone(), p.name)];
            for suf in ["valid", "ready", "data"] {
                cs.push(format!(".{}_{suf}({s}_{suf})", p.name));
            }
        }
        debug_assert!(
            !inst.contains('.'),
            "a TM's units sit directly in it: {inst}"
        );
        let _ = writeln!(v, " {inst} (\n        {}\n    );", cs.join(",\n        "));
    }
    // Each internal link: the model's FIFO with its depth and delay.
    for l in links {
        v.push_str(&l);
    }
    let _ = writeln!(v, "endmodule");
    v
}
