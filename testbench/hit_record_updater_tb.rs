//! The hit record updater testbench: one scripted driver per TM pokes seeded
//! random hit updates (many to the same indices, ties on t with different triangle
//! ids, no NaN) into `hit[k]`; a memory stand-in with a fixed latency and a seeded
//! ready pattern (back-pressure on the request link) serves the 16 B hit records
//! from a `SparseMem` and applies writes when it answers them.
//!
//! Scoreboard:
//! - every record of the region equals the atomic-min over its initial value and
//!   all updates of its index, by (t, id), bit for bit; neighbours in the same line
//!   are untouched by the masked writes;
//! - merges: `updates` = updates sent and `merged + reads = updates` (each queue
//!   entry is read exactly once);
//! - no lost or duplicated write: every write names a record whose read was
//!   answered and not yet written, its mask is exactly that 16 B record, and the
//!   stand-in answered as many writes as the unit issued;
//! - the read-compare-write hazard: no second read of a record while its read is
//!   unanswered, and no write ever replaces a record by a farther one (a lost
//!   closer hit);
//! - queue-full back-pressure reaches the TM side: the unit's `resource_busy`
//!   cycles and the drivers' blocked cycles are reported (the tests require both).

use crate::testbench::TbError;
use std::collections::{BTreeMap, VecDeque};

use crate::contract::{HIT_BYTES, HitRec, LINE_BYTES, SparseMem};
use crate::mem::StreamTag;
use crate::rtl::decl::{Samples, StateList};
use crate::rtl::{
    Ctx, Declared, In, Logic, Next, Out, Payload, PortDecl, PortDir, SharedBuf, Sim, Status,
    UnitDecl, UnitId, UnitStats,
};
use crate::units::hit_record_updater::HitUpdaterCfg;
use crate::units::hit_record_updater::{HitRecordUpdater, HitRecordUpdaterPorts};
use crate::units::memory::{MemLineReq, MemLineResp};
use crate::units::tp::HitUpdate;
use crate::util::rng::Rng;

use super::harness::{Driver, attach_trace, counter, finish_trace};
use super::pipe_tb::{TbOptions, TbReport};

/// Faults injected into the stand-in, to show the scoreboard catches them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MemFaults {
    /// Answer the n-th write (0-based) without applying it.
    pub drop_write: Option<u64>,
}

/// A memory stand-in on one line port: accepts a request when its seeded ready
/// pattern allows (one per cycle), answers it `latency` cycles after acceptance
/// (response link included), in order, applying writes (masked) when it answers.
pub struct LineMem {
    pub req: In<MemLineReq>,
    pub resp: Out<MemLineResp>,
    pub image: SparseMem,
    latency: u64,
    out_delay: u64,
    ready_p: f64,
    seed: u64,
    cap: usize,
    q: VecDeque<(u64, MemLineReq)>,
    pub faults: MemFaults,
    /// Every request as (cycle accepted, request) and every answer's cycle.
    pub accepted: Vec<(u64, MemLineReq)>,
    pub answered: Vec<(u64, MemLineResp)>,
    /// Hit-record protocol violations seen while answering (hazards, bad masks).
    pub violations: Vec<String>,
    /// Per hit index: 0 idle, 1 read outstanding, 2 read answered (write allowed).
    rcw: BTreeMap<u32, u8>,
    hits_base: u64,
    pub writes: u64,
}

impl LineMem {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        req: In<MemLineReq>,
        resp: Out<MemLineResp>,
        image: SparseMem,
        latency: u32,
        out_delay: u32,
        ready_p: f64,
        seed: u64,
        hits_base: u64,
    ) -> Self {
        LineMem {
            req,
            resp,
            image,
            latency: latency as u64,
            out_delay: out_delay as u64,
            ready_p,
            seed,
            cap: latency as usize + 2,
            q: VecDeque::new(),
            faults: MemFaults::default(),
            accepted: Vec::new(),
            answered: Vec::new(),
            violations: Vec::new(),
            rcw: BTreeMap::new(),
            hits_base,
            writes: 0,
        }
    }

    fn ready(&self, cycle: u64) -> bool {
        self.ready_p >= 1.0 || {
            let mut r = Rng::new(self.seed ^ cycle.wrapping_mul(0x9E37_79B9_7F4A_7C15));
            r.chance(self.ready_p)
        }
    }

    fn check_accept(&mut self, c: u64, r: &MemLineReq) {
        if r.tag != StreamTag::Hit {
            return;
        }
        let want = self.hits_base + r.id as u64 * HIT_BYTES as u64;
        if r.addr != want / LINE_BYTES * LINE_BYTES {
            self.violations.push(format!(
                "cycle {c}: request for hit {} at line {:#x}, the record is at {want:#x}",
                r.id, r.addr
            ));
        }
        let st = self.rcw.get(&r.id).copied().unwrap_or(0);
        if !r.write {
            if st == 1 {
                self.violations.push(format!(
                    "cycle {c}: hazard: second read of hit {} while its read is in flight",
                    r.id
                ));
            }
            self.rcw.insert(r.id, 1);
        } else {
            if st != 2 {
                self.violations.push(format!(
                    "cycle {c}: write of hit {} without an answered read (duplicated or unread)",
                    r.id
                ));
            }
            let off = want % LINE_BYTES;
            if r.mask != 0xFFFFu64 << off {
                self.violations.push(format!(
                    "cycle {c}: write of hit {} has mask {:#x}, the record is bytes {off}..{}",
                    r.id,
                    r.mask,
                    off + 16
                ));
            }
            self.rcw.insert(r.id, 0);
        }
    }

    fn complete(&mut self, c: u64, r: &MemLineReq) -> MemLineResp {
        let mut data = crate::units::l1::Line::default();
        if r.write {
            let n = self.writes;
            self.writes += 1;
            if r.tag == StreamTag::Hit {
                let a = self.hits_base + r.id as u64 * HIT_BYTES as u64;
                let off = (a % LINE_BYTES) as usize;
                let old = HitRec::read(&self.image, a);
                let new = HitRec {
                    t: r.data.f32_at(off),
                    tri_id: r.data.u32_at(off + 4),
                    u: r.data.f32_at(off + 8),
                    v: r.data.f32_at(off + 12),
                };
                if !new.closer_than(&old) {
                    self.violations.push(format!(
                        "cycle {c}: write of hit {} replaces (t {}, id {}) by the farther (t {}, id {})",
                        r.id, old.t, old.tri_id, new.t, new.tri_id
                    ));
                }
            }
            if self.faults.drop_write != Some(n) {
                for i in 0..64 {
                    if r.mask >> i & 1 == 1 {
                        self.image.write(r.addr + i as u64, &r.data.0[i..i + 1]);
                    }
                }
            }
        } else {
            self.image.read(r.addr, &mut data.0);
            if r.tag == StreamTag::Hit {
                self.rcw.insert(r.id, 2);
            }
        }
        MemLineResp {
            addr: r.addr,
            write: r.write,
            tag: r.tag,
            id: r.id,
            data,
        }
    }
}

impl Declared for LineMem {
    fn decl(&self) -> UnitDecl {
        UnitDecl {
            module: "tb_line_mem",
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
                name: "req",
                dir: PortDir::In,
                width: <MemLineReq as Payload>::BITS,
                ty: <MemLineReq as Payload>::sv_type(),
                fields: <MemLineReq as Payload>::field_list(),
                link: self.req.id,
            },
            PortDecl {
                name: "resp",
                dir: PortDir::Out,
                width: <MemLineResp as Payload>::BITS,
                ty: <MemLineResp as Payload>::sv_type(),
                fields: <MemLineResp as Payload>::field_list(),
                link: self.resp.id,
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

impl Logic for LineMem {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let mut blocked = false;
        if let Some((due, _)) = self.q.front()
            && *due <= c
        {
            if ctx.can_push(&self.resp) {
                let (_, r) = self.q.pop_front().expect("due");
                let a = self.complete(c, &r);
                self.answered.push((c, a.clone()));
                ctx.push(&self.resp, a);
            } else {
                blocked = true;
            }
        }
        let mut waiting = false;
        if ctx.peek(&self.req).is_some() {
            if self.q.len() < self.cap && self.ready(c) {
                let r = ctx.pop(&self.req).expect("peeked");
                self.check_accept(c, &r);
                self.accepted.push((c, r.clone()));
                self.q.push_back((c + self.latency - self.out_delay, r));
            } else {
                waiting = true;
            }
        }
        ctx.set_status(if blocked {
            Status::OutputBlocked
        } else if waiting {
            Status::ResourceBusy
        } else if self.q.is_empty() {
            Status::WaitInput
        } else {
            Status::Busy
        });
        // Evaluated every cycle while anything is pending (always safe to sleep
        // contract); a full response link wakes it when it drains.
        if blocked && !waiting {
            Next::Idle
        } else if !self.q.is_empty() || waiting {
            Next::Cycle
        } else {
            Next::Idle
        }
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("accepted", self.accepted.len() as u64),
            ("answered", self.answered.len() as u64),
        ]
    }
}

/// The bench's knobs beyond `TbOptions`.
#[derive(Clone)]
pub struct HruTbCfg {
    pub tms: u32,
    /// Updates sent per TM.
    pub updates_per_tm: u32,
    /// Hit indices addressed (a hot eighth of them gets most updates).
    pub indices: u32,
    pub mem_latency: u32,
    /// The unit's queue and in-flight limits (small, so the queue fills).
    pub hru: HitUpdaterCfg,
    pub faults: MemFaults,
    /// Expect the atomic-min with ties broken by the larger id (a wrong model,
    /// to show the scoreboard fails).
    pub wrong_tiebreak: bool,
    /// Trace into this buffer (invariance tests) instead of `opts.vcd`.
    pub trace_buf: Option<SharedBuf>,
}

impl Default for HruTbCfg {
    fn default() -> Self {
        HruTbCfg {
            tms: 4,
            updates_per_tm: 400,
            indices: 48,
            mem_latency: 30,
            hru: HitUpdaterCfg {
                queue: 12,
                in_flight: 8,
            },
            faults: MemFaults::default(),
            wrong_tiebreak: false,
            trace_buf: None,
        }
    }
}

/// The configuration the bench elaborates its unit with: `base` with the bench's
/// TM count and hit-updater sizes (the Verilog module of the traced scope).
pub fn unit_config(base: &crate::config::Config, b: &HruTbCfg) -> crate::config::Config {
    let mut c = base.clone();
    c.chip.tms = b.tms;
    c.chip.hit_updater = b.hru.clone();
    c
}

/// A record whose u, v are a function of (t, id): equal keys are equal records.
fn rec(t: f32, id: u32) -> HitRec {
    let h = crate::util::fnv1a(&[t.to_bits().to_le_bytes(), id.to_le_bytes()].concat());
    HitRec {
        t,
        tri_id: id,
        u: (h & 0xFFFF) as f32 / 65536.0,
        v: (h >> 16 & 0xFFFF) as f32 / 65536.0,
    }
}

fn bits(h: &HitRec) -> [u32; 4] {
    [h.t.to_bits(), h.tri_id, h.u.to_bits(), h.v.to_bits()]
}

/// What the default bench sends (`tb`'s report and errors).
pub fn workload() -> String {
    let b = HruTbCfg::default();
    format!(
        "at most {} updates per TM from {} TMs on {} records",
        b.updates_per_tm, b.tms, b.indices
    )
}

/// `dualstream tb hit_record_updater` with the default bench knobs.
pub fn run(opts: &TbOptions) -> Result<TbReport, TbError> {
    run_with(opts, &HruTbCfg::default())
}

/// Where the bench puts the hit records.
const HITS_BASE: u64 = 0x1_0000;

/// The elaborated bench: the simulator and the units the scoreboard reads.
struct Bench {
    sim: Sim,
    drivers: Vec<UnitId>,
    dut: UnitId,
    memu: UnitId,
}

pub fn run_with(opts: &TbOptions, b: &HruTbCfg) -> Result<TbReport, TbError> {
    check_knobs(opts, b)?;
    let cfg = &unit_config(&opts.config, b);
    let mut rng = Rng::new(opts.seed);
    let (image, mut expect) = initial_records(b, &mut rng);
    let mut bench = build(opts, b, cfg, image)?;
    attach_trace(&mut bench.sim, opts, b.trace_buf.as_ref())?;
    let sent = drive(&mut bench, opts, b, &mut rng, &mut expect);
    let p = cfg.clocks.core_ps;
    let end = bench.sim.run_to_idle((sent * 100 + 100_000) * p)? / p;
    let st = bench.sim.unit_stats(bench.dut);
    let errors = check(&bench, b, &st, &expect, sent);
    let rep = report(&bench, b, &st, sent, end, errors);
    finish_trace(&mut bench.sim, rep)
}

fn check_knobs(opts: &TbOptions, b: &HruTbCfg) -> Result<(), TbError> {
    if opts.cycles == 0 {
        return Err(TbError::Invalid(
            "--cycles 0 runs nothing; give at least 1 cycle".into(),
        ));
    }
    let prob = |p: f64| p > 0.0 && p <= 1.0;
    if !prob(opts.ready_p) || !prob(opts.load) {
        return Err(TbError::Invalid(
            "--ready and --load are probabilities in (0, 1]".into(),
        ));
    }
    if b.tms == 0 || b.indices == 0 || b.mem_latency < 2 {
        return Err(TbError::Invalid(
            "the bench needs TMs, indices and a memory latency >= 2".into(),
        ));
    }
    Ok(())
}

/// The initial image: no hit, or an earlier hit (so some updates lose); and
/// the records as they are so far (the scoreboard's expectation).
fn initial_records(b: &HruTbCfg, rng: &mut Rng) -> (SparseMem, Vec<HitRec>) {
    let mut image = SparseMem::new(HITS_BASE + (b.indices as u64 + 8) * HIT_BYTES as u64);
    let mut expect: Vec<HitRec> = Vec::new();
    for i in 0..b.indices {
        let h = if rng.chance(0.25) {
            rec(rng.below(16) as f32 * 0.25 + 0.25, rng.below(8) as u32)
        } else {
            HitRec::NONE
        };
        h.write(&mut image, HITS_BASE + i as u64 * HIT_BYTES as u64);
        expect.push(h);
    }
    (image, expect)
}

/// One driver per TM on `hit[k]`, the unit, and the memory stand-in on `image`.
fn build(
    opts: &TbOptions,
    b: &HruTbCfg,
    cfg: &crate::config::Config,
    image: SparseMem,
) -> Result<Bench, TbError> {
    let link = cfg.chip.links;
    let mut sim = Sim::new(opts.sim.clone());
    let clk = sim.clock("core", cfg.clocks.core_ps)?;
    let mut drivers: Vec<UnitId> = Vec::new();
    let mut hit_in = Vec::new();
    let mut outs = Vec::new();
    for k in 0..b.tms {
        let (o, i) = sim.link::<HitUpdate>(&format!("tm{k}.hit"), link);
        hit_in.push(i);
        outs.push(o);
    }
    let (qo, qi) = sim.link::<MemLineReq>("hru.mem_req", link);
    let (ro, ri) = sim.link::<MemLineResp>("hru.mem_resp", link);
    for (k, o) in outs.into_iter().enumerate() {
        drivers.push(sim.add(&format!("tb.tm{k}"), clk, Driver::new(o)));
    }
    let dut = sim.add(
        "tb.hit_record_updater",
        clk,
        HitRecordUpdater::new(
            &cfg.chip.hit_updater,
            HITS_BASE,
            HitRecordUpdaterPorts {
                hit: hit_in,
                mem_req: qo,
                mem_resp: ri,
            },
        ),
    );
    let mut mem = LineMem::new(
        qi,
        ro,
        image,
        b.mem_latency,
        link.delay,
        opts.ready_p,
        opts.seed ^ 0x5EED,
        HITS_BASE,
    );
    mem.faults = b.faults.clone();
    let memu = sim.add("tb.mem", clk, mem);
    sim.elaborate()?;
    Ok(Bench {
        sim,
        drivers,
        dut,
        memu,
    })
}

/// Stimulus: per TM, updates at seeded cycles with probability `load`; each
/// is folded into `expect` (the atomic-min). Returns the updates sent.
fn drive(
    bench: &mut Bench,
    opts: &TbOptions,
    b: &HruTbCfg,
    rng: &mut Rng,
    expect: &mut [HitRec],
) -> u64 {
    let hot = (b.indices / 8).max(1);
    let mut sent = 0u64;
    for &d in &bench.drivers {
        let mut c = 0u64;
        for _ in 0..b.updates_per_tm {
            while !rng.chance(opts.load) {
                c += 1;
            }
            // `--cycles` is the stimulus window; the workload caps it.
            if c >= opts.cycles {
                break;
            }
            let index = if rng.chance(0.6) {
                rng.below(hot as u64) as u32
            } else {
                rng.below(b.indices as u64) as u32
            };
            // Few distinct t: many ties, broken by the id.
            let h = rec(rng.below(64) as f32 * 0.25 + 0.25, rng.below(4) as u32);
            let e = &mut expect[index as usize];
            let wins = if b.wrong_tiebreak {
                h.t < e.t || (h.t == e.t && h.tri_id > e.tri_id && e.tri_id != u32::MAX)
            } else {
                h.closer_than(e)
            };
            if wins {
                *e = h;
            }
            bench
                .sim
                .unit_mut::<Driver<HitUpdate>>(d)
                .send(c, HitUpdate { index, hit: h });
            sent += 1;
            c += 1;
        }
        bench.sim.wake(d);
    }
    sent
}

/// The scoreboard (see the module doc): the records, the bytes around them,
/// the unit's counts against the memory's.
fn check(bench: &Bench, b: &HruTbCfg, st: &UnitStats, expect: &[HitRec], sent: u64) -> Vec<String> {
    let mut errors = Vec::new();
    let m = bench.sim.unit_ref::<LineMem>(bench.memu);
    errors.extend(m.violations.iter().take(20).cloned());
    for (i, e) in expect.iter().enumerate() {
        let got = HitRec::read(&m.image, HITS_BASE + i as u64 * HIT_BYTES as u64);
        if bits(&got) != bits(e) {
            errors.push(format!(
                "hit {i}: record (t {}, id {}, u {}, v {}), expected (t {}, id {}, u {}, v {})",
                got.t, got.tri_id, got.u, got.v, e.t, e.tri_id, e.u, e.v
            ));
        }
    }
    // Nothing outside the records' bytes written (the region's tail line).
    let tail = HITS_BASE + b.indices as u64 * HIT_BYTES as u64;
    let mut t0 = [0u8; 64];
    m.image.read(tail, &mut t0);
    if t0.iter().any(|&x| x != 0) {
        errors.push("bytes after the last record were written".into());
    }
    let ctr = |n: &str| counter(st, n);
    let (updates, merged, reads, writes) =
        (ctr("updates"), ctr("merged"), ctr("reads"), ctr("writes"));
    if updates != sent {
        errors.push(format!("{sent} updates sent, the unit counted {updates}"));
    }
    if merged + reads != updates {
        errors.push(format!(
            "merged {merged} + reads {reads} != updates {updates}: a queue entry was lost or read twice"
        ));
    }
    let mreads = m.accepted.iter().filter(|(_, r)| !r.write).count() as u64;
    if mreads != reads || m.writes != writes {
        errors.push(format!(
            "the memory answered {mreads} reads and {} writes, the unit issued {reads} and {writes}",
            m.writes
        ));
    }
    if m.accepted.len() != m.answered.len() {
        errors.push(format!(
            "{} requests accepted, {} answered",
            m.accepted.len(),
            m.answered.len()
        ));
    }
    errors
}

fn report(
    bench: &Bench,
    b: &HruTbCfg,
    st: &UnitStats,
    sent: u64,
    end: u64,
    errors: Vec<String>,
) -> TbReport {
    let ctr = |n: &str| counter(st, n);
    let blocked: u64 = bench
        .drivers
        .iter()
        .map(|&d| bench.sim.unit_stats(d).status_cycles[Status::OutputBlocked as usize])
        .sum();
    TbReport {
        unit: "hit_record_updater",
        requests: sent,
        results: ctr("writes"),
        cycles: end,
        min_latency: 0,
        max_latency: 0,
        stall_cycles: st.status_cycles[Status::ResourceBusy as usize],
        errors,
        vcd_changes: 0,
        vcd_bytes: 0,
        status_cycles: st.status_cycles,
        counters: vec![
            ("updates", ctr("updates")),
            ("merged", ctr("merged")),
            ("reads", ctr("reads")),
            ("writes", ctr("writes")),
            ("hazard_waits", ctr("hazard_waits")),
            (
                "queue_full_cycles",
                st.status_cycles[Status::ResourceBusy as usize],
            ),
            ("tm_blocked_cycles", blocked),
            ("records_checked", b.indices as u64),
        ],
    }
}
