//! The stream scheduler testbench: the scheduler on a real scene's DRAM image
//! (segment table, child lists, bucket pool) with stand-ins for everything else:
//! the host emits one wavefront of rays into the root queue, a line memory
//! (`LineMem`, fixed latency, seeded back-pressure) serves the ray stream and the
//! segment info (the scheduler's `ray_lines_per_cycle` lanes reach it through a
//! `LaneMux`), sinks take the segment streams (one per scene lane) and slot
//! mappings, and one fake
//! TM per port takes bucket rays with a seeded ready pattern and answers each ray
//! with duplicates into a pseudo-random subset of the segment's children (a pure
//! function of the seed, segment and ray; a fixed third of the segments never gets
//! any, so their subtrees are skipped) followed by the ray's end marker.
//!
//! Scoreboard:
//! - every enqueued (segment, ray) — root rays and duplicates — is forwarded to a
//!   TM exactly once, and nothing else is; a bucket's rays share one segment;
//! - order: a segment is admitted (mapped) only after its parent was admitted and
//!   every ray of the parent had sent its end marker (the parent retired);
//!   siblings are admitted in increasing id (depth-first pre-order); exactly the
//!   segments that received rays are admitted, each once, and each retires;
//! - every admitted segment's lines are streamed exactly once;
//! - every bucket is freed: written = read = forwarded buckets, no live bucket.

use crate::testbench::TbError;
use std::collections::VecDeque;

use crate::contract::{RayRec, SegEntry};
use crate::machine::host::Host;
use crate::render::{Prepared, RenderCfg, prepare};
use crate::rtl::decl::{Samples, StateList};
use crate::rtl::{
    Ctx, Declared, In, Logic, Next, Out, Payload, PortDecl, PortDir, SharedBuf, Sim, Status,
    UnitDecl, UnitId,
};
use crate::units::memory::{MemLineReq, MemLineResp};
use crate::units::scene_buffer::SlotMap;
use crate::units::staging_buffer::SbFill;
use crate::units::stream_scheduler::{StreamScheduler, StreamSchedulerPorts, WaveStart};
use crate::units::tp::RayWrite;
use crate::util::rng::Rng;

use super::harness::{Sink, attach_trace, finish_trace};
use super::hit_record_updater_tb::LineMem;
use super::pipe_tb::{TbOptions, TbReport};

mod scoreboard;
use scoreboard::{Traffic, check_admissions, check_buckets, check_rays, check_streams, forwarded};

/// A TM stand-in on the fill and ray-write ports.
pub struct FakeTm {
    pub fill: In<SbFill>,
    pub out: Out<RayWrite>,
    children: std::sync::Arc<Vec<Vec<u32>>>,
    dup_p: f64,
    ready_p: f64,
    seed: u64,
    dead_seed: u64,
    q: VecDeque<RayWrite>,
    /// Fault: the n-th end marker (0-based, this TM) is not sent.
    pub skip_marker: Option<u64>,
    markers: u64,
    /// (cycle, fill) taken; (cycle, write) sent.
    pub got: Vec<(u64, SbFill)>,
    pub sent: Vec<(u64, RayWrite)>,
}

impl FakeTm {
    fn ready(&self, c: u64) -> bool {
        self.ready_p >= 1.0 || {
            let mut r = Rng::new(self.seed ^ c.wrapping_mul(0x9E37_79B9_7F4A_7C15));
            r.chance(self.ready_p)
        }
    }
}

impl Declared for FakeTm {
    fn decl(&self) -> UnitDecl {
        UnitDecl {
            module: "tb_fake_tm",
            source: file!(),
            doc: "testbench component",
            params: vec![],
            ports: self.ports(),
            state: StateList::default().items,
        }
    }
    fn ports(&self) -> Vec<PortDecl> {
        vec![
            PortDecl {
                name: "fill",
                dir: PortDir::In,
                width: <SbFill as Payload>::BITS,
                ty: <SbFill as Payload>::sv_type(),
                fields: <SbFill as Payload>::field_list(),
                link: self.fill.id,
            },
            PortDecl {
                name: "ray_write",
                dir: PortDir::Out,
                width: <RayWrite as Payload>::BITS,
                ty: <RayWrite as Payload>::sv_type(),
                fields: <RayWrite as Payload>::field_list(),
                link: self.out.id,
            },
        ]
    }
    fn sample_state(&self, _cycle: u64, _out: &mut Samples) {}
    fn commit_state(&mut self) {}
    fn reset_state(&mut self) {
        self.q.clear();
    }
    fn state_pending(&self) -> bool {
        false
    }
}

impl Logic for FakeTm {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let mut worked = false;
        if let Some(w) = self.q.front()
            && ctx.offer(&self.out, w.clone())
        {
            let w = self.q.pop_front().expect("front");
            self.sent.push((c, w));
            worked = true;
        }
        let mut waiting = false;
        if ctx.peek(&self.fill).is_some() {
            if self.q.len() < 8 && self.ready(c) {
                let f = ctx.pop(&self.fill).expect("peeked");
                let seg = f.hdr.seg;
                for &ch in &self.children[seg as usize] {
                    // A fixed third of the segments never gets rays (their
                    // subtrees are skipped).
                    let dead = crate::util::fnv1a(
                        &[self.dead_seed.to_le_bytes(), (ch as u64).to_le_bytes()].concat(),
                    )
                    .is_multiple_of(3);
                    if dead {
                        continue;
                    }
                    let h = crate::util::fnv1a(
                        &[
                            self.seed.to_le_bytes().as_slice(),
                            &ch.to_le_bytes(),
                            &f.ray.encode(),
                        ]
                        .concat(),
                    );
                    if (h % 1000) as f64 / 1000.0 < self.dup_p {
                        self.q.push_back(RayWrite {
                            seg: ch,
                            ray: f.ray,
                            done: false,
                        });
                    }
                }
                if self.skip_marker != Some(self.markers) {
                    self.q.push_back(RayWrite {
                        seg,
                        ray: f.ray,
                        done: true,
                    });
                }
                self.markers += 1;
                self.got.push((c, f));
                worked = true;
            } else {
                waiting = true;
            }
        }
        ctx.set_status(if worked {
            Status::Busy
        } else if !self.q.is_empty() {
            Status::OutputBlocked
        } else if waiting {
            Status::ResourceBusy
        } else {
            Status::WaitInput
        });
        if worked || waiting || !self.q.is_empty() {
            Next::Cycle
        } else {
            Next::Idle
        }
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("rays", self.got.len() as u64),
            ("writes", self.sent.len() as u64),
        ]
    }
}

crate::unit! {
    /// Testbench component: the scheduler's ray lanes (`mem_req[j]`/`mem_resp[j]`)
    /// onto the one-port line memory, one request per cycle (lanes round-robin
    /// from `cycle mod lanes`); each answer goes back on its request's lane (the
    /// memory answers in order).
    pub struct LaneMux : "tb_lane_mux" {
        new(; ports: LaneMuxPorts) {}
        params { lanes_n: u32 = lane_req.len() as u32 => "LANES" }
        inputs { resp: MemLineResp }
        outputs { req: MemLineReq }
        in_arrays { lane_req: MemLineReq }
        out_arrays { lane_resp: MemLineResp }
        state { }
        extra { order: VecDeque<usize> = VecDeque::new() }
    }
}

impl Logic for LaneMux {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let n = self.lane_req.len();
        let mut worked = false;
        if let (Some(_), Some(&j)) = (ctx.peek(&self.resp), self.order.front())
            && ctx.can_push(&self.lane_resp[j])
        {
            let r = ctx.pop(&self.resp).expect("peeked");
            ctx.push(&self.lane_resp[j], r);
            self.order.pop_front();
            worked = true;
        }
        let (mut waiting, mut sent) = (false, false);
        for k in 0..n {
            let j = (c as usize + k) % n;
            if ctx.peek(&self.lane_req[j]).is_none() {
                continue;
            }
            if !sent && ctx.can_push(&self.req) {
                sent = true;
                let r = ctx.pop(&self.lane_req[j]).expect("peeked");
                ctx.push(&self.req, r);
                self.order.push_back(j);
                worked = true;
            } else {
                waiting = true;
            }
        }
        ctx.set_status(if worked || !self.order.is_empty() {
            Status::Busy
        } else if waiting {
            Status::ResourceBusy
        } else {
            Status::WaitInput
        });
        if worked || waiting || !self.order.is_empty() {
            Next::Cycle
        } else {
            Next::Idle
        }
    }
}

/// The bench's knobs beyond `TbOptions`.
#[derive(Clone)]
pub struct SchedTbCfg {
    pub scene: String,
    pub tms: u32,
    pub rays: u32,
    /// Probability that a ray is duplicated into each child of its segment.
    pub dup_p: f64,
    pub mem_latency: u32,
    /// Overrides `accel.segment_bytes` (small segments: a deeper segment tree).
    pub segment_bytes: Option<u32>,
    /// Overrides the scene buffer's slot count (few slots: admission waits).
    pub slots: Option<u32>,
    /// Fault: TM 0 does not send its n-th end marker.
    pub skip_marker: Option<u64>,
    /// Wrong expectation: one root ray is left out of the expected set.
    pub drop_expected: bool,
    pub trace_buf: Option<SharedBuf>,
}

impl Default for SchedTbCfg {
    fn default() -> Self {
        SchedTbCfg {
            scene: "cornell".into(),
            tms: 4,
            rays: 300,
            dup_p: 0.3,
            mem_latency: 20,
            segment_bytes: Some(8192),
            slots: Some(6),
            skip_marker: None,
            drop_expected: false,
            trace_buf: None,
        }
    }
}

/// The configuration the bench elaborates its unit with: `base` with the bench's
/// TM count, segment size and slot count (the Verilog module of the traced scope).
pub fn unit_config(base: &crate::config::Config, b: &SchedTbCfg) -> crate::config::Config {
    let mut cfg = base.clone();
    cfg.chip.tms = b.tms;
    // The ray lanes (`ray_lines_per_cycle`) share the one-port line memory
    // through a `LaneMux`; the scene lanes (`scene_lines_per_cycle`) each go to
    // a sink.
    if let Some(sb) = b.segment_bytes {
        cfg.accel.segment_bytes = sb;
        cfg.chip.scene_buffer.slot_bytes = sb;
    }
    if let Some(n) = b.slots {
        cfg.chip.scene_buffer.bytes = n * cfg.chip.scene_buffer.slot_bytes;
    }
    cfg
}

pub fn run(opts: &TbOptions) -> Result<TbReport, TbError> {
    run_with(opts, &SchedTbCfg::default())
}

type Key = (u32, Vec<u8>);

/// The segment tree as the scoreboard and the fake TMs see it: each segment's
/// table entry (base, bytes), children and parent.
struct SegTree {
    entries: Vec<SegEntry>,
    children: std::sync::Arc<Vec<Vec<u32>>>,
    parent: Vec<Option<u32>>,
}

/// The elaborated bench: the simulator and the units the scoreboard reads.
struct Bench {
    sim: Sim,
    host: UnitId,
    dut: UnitId,
    memu: UnitId,
    map_sink: UnitId,
    scene_sinks: Vec<UnitId>,
    tms: Vec<UnitId>,
    /// The core clock's period (ps).
    p: u64,
}

pub fn run_with(opts: &TbOptions, b: &SchedTbCfg) -> Result<TbReport, TbError> {
    check_knobs(opts, b)?;
    let cfg = &unit_config(&opts.config, b);
    cfg.validate()?;
    let scene = crate::scene::load(&b.scene)?;
    let rcfg = RenderCfg {
        accel: cfg.accel.clone(),
        memory: cfg.memory.clone(),
        ..RenderCfg::default()
    };
    let prep = prepare(&scene, &rcfg)?;
    let tree = seg_tree(&prep);
    let mut bench = build(opts, b, cfg, prep, &tree)?;
    attach_trace(&mut bench.sim, opts, b.trace_buf.as_ref())?;
    let (rays, end) = drive(&mut bench, opts, b)?;
    let mut errors = Vec::new();
    let traffic = forwarded(&bench, b, &tree, &rays, &mut errors);
    check_rays(&traffic, &mut errors);
    let admitted = check_admissions(&bench, &tree, &traffic, &mut errors);
    let scene_lines = check_streams(&bench, &tree, &admitted, &mut errors);
    check_buckets(&bench, &traffic, &admitted, &mut errors);
    let nseg = tree.entries.len();
    let admitted = admitted.len() as u64;
    let rep = report(&bench, &traffic, nseg, scene_lines, admitted, end, errors);
    finish_trace(&mut bench.sim, rep)
}

fn check_knobs(opts: &TbOptions, b: &SchedTbCfg) -> Result<(), TbError> {
    let prob = |p: f64| p > 0.0 && p <= 1.0;
    if !prob(opts.ready_p) {
        return Err(TbError::Invalid(
            "--ready is a probability in (0, 1]".into(),
        ));
    }
    if b.tms == 0 || b.rays == 0 || b.mem_latency < 2 {
        return Err(TbError::Invalid(
            "the bench needs TMs, rays and a memory latency >= 2".into(),
        ));
    }
    Ok(())
}

/// The segment tree of the prepared scene, its entries read from the image.
fn seg_tree(prep: &Prepared) -> SegTree {
    let nseg = prep.seg.segments.len();
    let entries: Vec<SegEntry> = (0..nseg as u32)
        .map(|s| SegEntry::read(&prep.mem, prep.map.seg_entry_addr(s)))
        .collect();
    let children: Vec<Vec<u32>> = prep
        .seg
        .segments
        .iter()
        .map(|s| s.children.clone())
        .collect();
    let parent: Vec<Option<u32>> = prep.seg.segments.iter().map(|s| s.parent).collect();
    SegTree {
        entries,
        children: std::sync::Arc::new(children),
        parent,
    }
}

/// The host, the unit, the lane mux onto the line memory (holding the scene's
/// DRAM image), the slot-map and scene-stream sinks, and one fake TM per port.
fn build(
    opts: &TbOptions,
    b: &SchedTbCfg,
    cfg: &crate::config::Config,
    prep: Prepared,
    tree: &SegTree,
) -> Result<Bench, TbError> {
    let nseg = tree.entries.len();
    let link = cfg.chip.links;
    let p = cfg.clocks.core_ps;
    let mut sim = Sim::new(opts.sim.clone());
    let clk = sim.clock("core", p)?;
    let (eo, ei) = sim.link::<RayWrite>("sched.emit", link);
    let (so, si) = sim.link::<WaveStart>("sched.start", link);
    let ray_lanes = cfg.chip.scheduler.ray_lines_per_cycle as usize;
    let (lq_o, lq_i): (Vec<_>, Vec<_>) = (0..ray_lanes)
        .map(|j| sim.link::<MemLineReq>(&format!("sched.mem_req{j}"), link))
        .unzip();
    let (lr_o, lr_i): (Vec<_>, Vec<_>) = (0..ray_lanes)
        .map(|j| sim.link::<MemLineResp>(&format!("sched.mem_resp{j}"), link))
        .unzip();
    let (qo, qi) = sim.link::<MemLineReq>("mux.mem_req", link);
    let (ro, ri) = sim.link::<MemLineResp>("mux.mem_resp", link);
    let (mo, mi) = sim.link::<SlotMap>("sched.slot_map", link);
    let lanes = cfg.chip.scheduler.scene_lines_per_cycle as usize;
    let (sco, sci): (Vec<_>, Vec<_>) = (0..lanes)
        .map(|j| sim.link::<MemLineReq>(&format!("sched.scene_req{j}"), link))
        .unzip();
    let mut rw_in = Vec::new();
    let mut fill_out = Vec::new();
    let mut tm_ports = Vec::new();
    for k in 0..b.tms {
        let (wo, wi) = sim.link::<RayWrite>(&format!("tm{k}.ray_write"), link);
        let (fo, fi) = sim.link::<SbFill>(&format!("tm{k}.fill"), link);
        rw_in.push(wi);
        fill_out.push(fo);
        tm_ports.push((fi, wo));
    }
    let host = sim.add("tb.host", clk, Host::new(eo, so));
    let dut = sim.add(
        "tb.stream_scheduler",
        clk,
        StreamScheduler::new(
            &cfg.chip.scheduler,
            &cfg.chip.scene_buffer,
            &prep.map,
            nseg,
            StreamSchedulerPorts {
                emit: ei,
                start: si,
                mem_resp: lr_i,
                slot_map: mo,
                scene_req: sco,
                mem_req: lq_o,
                ray_write: rw_in,
                fill: fill_out,
            },
        ),
    );
    sim.add(
        "tb.lane_mux",
        clk,
        LaneMux::new(LaneMuxPorts {
            resp: ri,
            req: qo,
            lane_req: lq_i,
            lane_resp: lr_o,
        }),
    );
    let memu = sim.add(
        "tb.mem",
        clk,
        LineMem::new(
            qi,
            ro,
            prep.mem,
            b.mem_latency,
            link.delay,
            opts.ready_p,
            opts.seed ^ 0xA11,
            u64::MAX,
        ),
    );
    let map_sink = sim.add("tb.slot_map", clk, Sink::new(mi, 1.0, 0));
    let scene_sinks: Vec<UnitId> = sci
        .into_iter()
        .enumerate()
        .map(|(j, i)| sim.add(&format!("tb.scene{j}"), clk, Sink::new(i, 1.0, 0)))
        .collect();
    let mut tms: Vec<UnitId> = Vec::new();
    for (k, (fi, wo)) in tm_ports.into_iter().enumerate() {
        tms.push(sim.add(
            &format!("tb.tm{k}"),
            clk,
            FakeTm {
                fill: fi,
                out: wo,
                children: tree.children.clone(),
                dup_p: b.dup_p,
                ready_p: opts.ready_p,
                seed: opts.seed.wrapping_mul(77) + k as u64,
                dead_seed: opts.seed,
                q: VecDeque::new(),
                skip_marker: if k == 0 { b.skip_marker } else { None },
                markers: 0,
                got: Vec::new(),
                sent: Vec::new(),
            },
        ));
    }
    sim.elaborate()?;
    Ok(Bench {
        sim,
        host,
        dut,
        memu,
        map_sink,
        scene_sinks,
        tms,
        p,
    })
}

/// The host emits one wavefront of seeded rays into the root queue; runs to
/// idle. Returns the rays and the last cycle.
fn drive(
    bench: &mut Bench,
    opts: &TbOptions,
    b: &SchedTbCfg,
) -> Result<(Vec<RayRec>, u64), TbError> {
    let (sim, p) = (&mut bench.sim, bench.p);
    let mut rng = Rng::new(opts.seed);
    let rays: Vec<RayRec> = (0..b.rays)
        .map(|i| RayRec {
            origin: glam::Vec3::new(rng.unit_f32(), rng.unit_f32(), rng.unit_f32()),
            dir: glam::Vec3::new(rng.unit_f32(), rng.unit_f32(), 1.0),
            ray_id: i,
            entry: rng.next_u32(),
        })
        .collect();
    sim.unit_mut::<Host>(bench.host).load(rays.clone(), 0, 0);
    sim.wake(bench.host);
    let end = sim.run_to_idle((b.rays as u64 * 2000 + 1_000_000) * p)? / p;
    Ok((rays, end))
}

fn report(
    bench: &Bench,
    t: &Traffic,
    nseg: usize,
    scene_lines: u64,
    admitted: u64,
    end: u64,
    errors: Vec<String>,
) -> TbReport {
    let s = bench.sim.unit_ref::<StreamScheduler>(bench.dut).stats();
    let st = bench.sim.unit_stats(bench.dut);
    TbReport {
        unit: "stream_scheduler",
        requests: t.want.values().map(|&n| n as u64).sum(),
        results: t.fwd_rays,
        cycles: end,
        min_latency: 0,
        max_latency: 0,
        stall_cycles: st.status_cycles[Status::OutputBlocked as usize]
            + st.status_cycles[Status::ResourceBusy as usize],
        errors,
        vcd_changes: 0,
        vcd_bytes: 0,
        status_cycles: st.status_cycles,
        counters: vec![
            ("segments_admitted", admitted),
            ("segments", nseg as u64),
            ("retired", s.retired),
            ("skipped_children", s.skipped_children),
            ("buckets_forwarded", s.buckets_forwarded),
            ("rays_forwarded", s.rays_forwarded),
            ("scene_lines", scene_lines),
            ("same_segment_picks", s.same_segment_picks),
        ],
    }
}
