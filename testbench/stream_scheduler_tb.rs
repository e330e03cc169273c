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

use std::collections::{BTreeMap, VecDeque};

use crate::contract::{LINE_BYTES, RayRec, SegEntry};
use crate::machine::host::Host;
use crate::render::{RenderCfg, prepare};
use crate::rtl::decl::{Samples, StateList};
use crate::rtl::{
    Ctx, Declared, In, Logic, Next, Out, Payload, PortDecl, PortDir, SharedBuf, Sim, Status,
    Tracer, UnitDecl, UnitId,
};
use crate::units::memory::{MemLineReq, MemLineResp};
use crate::units::scene_buffer::SlotMap;
use crate::units::staging_buffer::SbFill;
use crate::units::stream_scheduler::{StreamScheduler, WaveStart};
use crate::units::tp::RayWrite;
use crate::util::rng::Rng;

use super::harness::Sink;
use super::hit_record_updater_tb::LineMem;
use super::pipe_tb::{TbOptions, TbReport};

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
                link: self.fill.id,
            },
            PortDecl {
                name: "ray_write",
                dir: PortDir::Out,
                width: <RayWrite as Payload>::BITS,
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
        params { lanes_n: u32 => "LANES" }
        inputs { resp: MemLineResp }
        outputs { req: MemLineReq }
        in_arrays { lane_req: MemLineReq }
        out_arrays { lane_resp: MemLineResp }
        state { }
        extra { order: VecDeque<usize> }
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

pub fn run(opts: &TbOptions) -> Result<TbReport, String> {
    run_with(opts, &SchedTbCfg::default())
}

type Key = (u32, Vec<u8>);

pub fn run_with(opts: &TbOptions, b: &SchedTbCfg) -> Result<TbReport, String> {
    let prob = |p: f64| p > 0.0 && p <= 1.0;
    if !prob(opts.ready_p) {
        return Err("--ready is a probability in (0, 1]".into());
    }
    if b.tms == 0 || b.rays == 0 || b.mem_latency < 2 {
        return Err("the bench needs TMs, rays and a memory latency >= 2".into());
    }
    let cfg = &unit_config(&opts.config, b);
    cfg.validate()?;
    let scene = crate::scene::load(&b.scene)?;
    let rcfg = RenderCfg {
        accel: cfg.accel.clone(),
        memory: cfg.memory.clone(),
        ..RenderCfg::default()
    };
    let prep = prepare(&scene, &rcfg)?;
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
    let children = std::sync::Arc::new(children);
    let link = cfg.chip.links;
    let p = cfg.clocks.core_ps;
    let mut sim = Sim::new(opts.sim.clone());
    let clk = sim.clock("core", p).map_err(|e| e.to_string())?;
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
            ei,
            si,
            lr_i,
            mo,
            sco,
            lq_o,
            rw_in,
            fill_out,
        ),
    );
    sim.add(
        "tb.lane_mux",
        clk,
        LaneMux {
            lanes_n: ray_lanes as u32,
            resp: ri,
            req: qo,
            lane_req: lq_i.into(),
            lane_resp: lr_o.into(),
            order: VecDeque::new(),
        },
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
                children: children.clone(),
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
    sim.elaborate().map_err(|e| e.to_string())?;
    if let Some(buf) = &b.trace_buf {
        let t = Tracer::new(Box::new(buf.clone()), opts.trace.clone())?;
        sim.attach_tracer(t).map_err(|e| e.to_string())?;
    } else if let Some(path) = &opts.vcd {
        let t = Tracer::to_file(path, opts.trace.clone())?;
        sim.attach_tracer(t).map_err(|e| e.to_string())?;
    }
    let mut rng = Rng::new(opts.seed);
    let rays: Vec<RayRec> = (0..b.rays)
        .map(|i| RayRec {
            origin: glam::Vec3::new(rng.unit_f32(), rng.unit_f32(), rng.unit_f32()),
            dir: glam::Vec3::new(rng.unit_f32(), rng.unit_f32(), 1.0),
            ray_id: i,
            entry: rng.next_u32(),
        })
        .collect();
    sim.unit_mut::<Host>(host).load(rays.clone(), 0, 0);
    sim.wake(host);
    let end = sim
        .run_to_idle((b.rays as u64 * 2000 + 1_000_000) * p)
        .map_err(|e| e.to_string())?
        / p;
    // Scoreboard.
    let mut errors = Vec::new();
    let mut want: BTreeMap<Key, u32> = BTreeMap::new();
    for (i, r) in rays.iter().enumerate() {
        if b.drop_expected && i == 0 {
            continue;
        }
        *want.entry((0, r.encode().to_vec())).or_default() += 1;
    }
    let mut got: BTreeMap<Key, u32> = BTreeMap::new();
    // Per segment: first ray forwarded, last marker sent.
    let mut last_marker: BTreeMap<u32, u64> = BTreeMap::new();
    let mut first_fwd: BTreeMap<u32, u64> = BTreeMap::new();
    let mut lasts = 0u64;
    let mut fwd_rays = 0u64;
    for (k, &t) in tms.iter().enumerate() {
        let tm = sim.unit_ref::<FakeTm>(t);
        let mut bucket_seg: Option<u32> = None;
        for (c, f) in &tm.got {
            fwd_rays += 1;
            let s = f.hdr.seg;
            *got.entry((s, f.ray.encode().to_vec())).or_default() += 1;
            first_fwd.entry(s).or_insert(*c);
            if let Some(bs) = bucket_seg
                && bs != s
            {
                errors.push(format!(
                    "TM {k}: a bucket of segment {bs} holds a ray of segment {s}"
                ));
            }
            bucket_seg = if f.last { None } else { Some(s) };
            if f.last {
                lasts += 1;
            }
            if f.hdr.base != entries[s as usize].base {
                errors.push(format!(
                    "TM {k}: bucket header of segment {s} has base {:#x}, the table {:#x}",
                    f.hdr.base, entries[s as usize].base
                ));
            }
        }
        for (c, w) in &tm.sent {
            if w.done {
                let e = last_marker.entry(w.seg).or_insert(0);
                *e = (*e).max(*c);
            } else {
                *want.entry((w.seg, w.ray.encode().to_vec())).or_default() += 1;
            }
        }
    }
    let mut lost = 0u64;
    let mut extra = 0u64;
    for (k, n) in &want {
        let g = got.get(k).copied().unwrap_or(0);
        if g != *n {
            if g < *n {
                lost += 1;
            } else {
                extra += 1;
            }
            if lost + extra <= 10 {
                errors.push(format!(
                    "segment {} ray {}: enqueued {n} times, forwarded {g}",
                    k.0,
                    u32::from_le_bytes(k.1[24..28].try_into().expect("4 bytes"))
                ));
            }
        }
    }
    for (k, g) in &got {
        if !want.contains_key(k) {
            extra += 1;
            if lost + extra <= 10 {
                errors.push(format!(
                    "segment {}: forwarded a ray never enqueued ({g}x)",
                    k.0
                ));
            }
        }
    }
    if lost + extra > 0 {
        errors.push(format!(
            "{lost} enqueued rays lost, {extra} extra forwarded"
        ));
    }
    // Order: admissions from the slot mappings.
    let maps = &sim.unit_ref::<Sink<SlotMap>>(map_sink).got;
    let by_base: BTreeMap<u64, u32> = entries
        .iter()
        .enumerate()
        .map(|(s, e)| (e.base, s as u32))
        .collect();
    let mut admitted: BTreeMap<u32, u64> = BTreeMap::new();
    let mut order = Vec::new();
    for (c, m) in maps {
        let Some(&s) = by_base.get(&m.base) else {
            errors.push(format!("slot map of an unknown base {:#x}", m.base));
            continue;
        };
        if admitted.insert(s, *c).is_some() {
            errors.push(format!("segment {s} admitted twice"));
        }
        order.push(s);
        if let Some(par) = parent[s as usize] {
            match (admitted.get(&par), last_marker.get(&par)) {
                (None, _) => errors.push(format!(
                    "segment {s} admitted at {c} before its parent {par}"
                )),
                (Some(_), Some(&lm)) if lm >= *c => errors.push(format!(
                    "segment {s} admitted at {c}, its parent {par}'s last end marker was sent at {lm}"
                )),
                _ => {}
            }
        }
    }
    // Siblings in increasing id.
    let mut last_child: BTreeMap<u32, u32> = BTreeMap::new();
    for &s in &order {
        if let Some(par) = parent[s as usize] {
            if let Some(&prev) = last_child.get(&par)
                && prev > s
            {
                errors.push(format!(
                    "segment {s} admitted after its higher sibling {prev}: not depth-first order"
                ));
            }
            last_child.insert(par, s);
        }
    }
    let with_rays: Vec<u32> = {
        let mut v: Vec<u32> = want.keys().map(|k| k.0).collect();
        v.dedup();
        v
    };
    let adm: Vec<u32> = admitted.keys().copied().collect();
    if adm != with_rays {
        errors.push(format!(
            "admitted {} segments, {} received rays",
            adm.len(),
            with_rays.len()
        ));
    }
    for (s, &c) in &first_fwd {
        if admitted.get(s).is_none_or(|&a| a > c) {
            errors.push(format!(
                "segment {s}: a ray forwarded at {c} before its admission"
            ));
        }
    }
    // Segment streams: every line of every admitted segment once.
    let scene: Vec<_> = scene_sinks
        .iter()
        .flat_map(|&u| sim.unit_ref::<Sink<MemLineReq>>(u).got.iter())
        .collect();
    let mut lines: BTreeMap<u64, u32> = BTreeMap::new();
    for (_, r) in &scene {
        *lines.entry(r.addr).or_default() += 1;
    }
    let mut want_lines = 0u64;
    for &s in admitted.keys() {
        let e = &entries[s as usize];
        let mut a = e.base / LINE_BYTES * LINE_BYTES;
        while a < e.base + e.bytes as u64 {
            want_lines += 1;
            if lines.get(&a).copied().unwrap_or(0) != 1 {
                errors.push(format!(
                    "segment {s}: line {a:#x} streamed {} times",
                    lines.get(&a).copied().unwrap_or(0)
                ));
            }
            a += LINE_BYTES;
        }
    }
    if scene.len() as u64 != want_lines {
        errors.push(format!(
            "{} scene lines streamed, the admitted segments have {want_lines}",
            scene.len()
        ));
    }
    let sch = sim.unit_ref::<StreamScheduler>(dut);
    let s = sch.stats();
    if sch.live_buckets() != 0 {
        errors.push(format!("{} buckets never freed", sch.live_buckets()));
    }
    if s.buckets_written != s.buckets_read || s.buckets_read != s.buckets_forwarded {
        errors.push(format!(
            "buckets written {} read {} forwarded {}",
            s.buckets_written, s.buckets_read, s.buckets_forwarded
        ));
    }
    if lasts != s.buckets_forwarded {
        errors.push(format!(
            "{lasts} bucket ends seen by the TMs, {} forwarded",
            s.buckets_forwarded
        ));
    }
    if s.retired != admitted.len() as u64 {
        errors.push(format!(
            "{} segments retired of {} admitted",
            s.retired,
            admitted.len()
        ));
    }
    if sch.dest_blocked() {
        errors.push("the destination table blocked".into());
    }
    let m = sim.unit_ref::<LineMem>(memu);
    if m.accepted.len() != m.answered.len() {
        errors.push("a memory request was not answered".into());
    }
    let st = sim.unit_stats(dut);
    let mut rep = TbReport {
        unit: "stream_scheduler",
        requests: want.values().map(|&n| n as u64).sum(),
        results: fwd_rays,
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
            ("segments_admitted", admitted.len() as u64),
            ("segments", nseg as u64),
            ("retired", s.retired),
            ("skipped_children", s.skipped_children),
            ("buckets_forwarded", s.buckets_forwarded),
            ("rays_forwarded", s.rays_forwarded),
            ("scene_lines", scene.len() as u64),
            ("same_segment_picks", s.same_segment_picks),
        ],
    };
    if let Some(r) = sim.finish_trace() {
        let s = r.map_err(|e| format!("writing the VCD failed: {e}"))?;
        rep.vcd_changes = s.changes;
        rep.vcd_bytes = s.bytes;
    }
    Ok(rep)
}
