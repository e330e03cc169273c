//! The L2 testbench: one scripted driver per client pokes seeded random line
//! requests (reads, full-line writes, partial writes with random byte masks) to a
//! small pool of lines (more than the cache holds, few per set, so hits, merges,
//! bank conflicts and dirty evictions all happen) into `req[k]`; one sink per
//! client takes the answers with a seeded ready pattern; the memory stand-in is
//! one `LineMem` (fixed latency, seeded back-pressure per lane) per memory lane
//! (`l2.mem_lines_per_cycle`), each holding the DRAM image of its lane's lines. A
//! flush with invalidation is sent in the middle of the traffic and a plain one
//! after it.
//!
//! Scoreboard (the unit logs every access in the order it applies them):
//! - replaying the log on a reference image, every read's answer equals the
//!   reference line at its turn, and every request is answered exactly once;
//! - per client and line, accesses are applied in the order the client sent them;
//! - real time: an access accepted after a write to its line was answered to its
//!   client is applied after that write (a read after a write from any client
//!   sees it);
//! - after the final flush the DRAM image equals the reference on every line;
//! - the memory never holds two requests for one line at once (it may reorder a
//!   read before an older write);
//! - every memory request went out on its line's lane (`line index mod lanes`),
//!   and its answer came back there (each lane's stand-in answers on its lane);
//! - counters: accesses = requests, hits + misses = accesses, fills = memory
//!   reads, writebacks = memory writes, two flushes answered.

use crate::testbench::TbError;
use std::collections::BTreeMap;

use crate::contract::SparseMem;
use crate::mem::StreamTag;
use crate::rtl::{ClockId, SharedBuf, Sim, Status, UnitId};
use crate::units::l1::Line;
use crate::units::l2::{L2, L2Applied, L2Cfg, L2Flush, L2Ports};
use crate::units::memory::{MemLineReq, MemLineResp};
use crate::util::rng::Rng;

use super::harness::{Driver, Sink, attach_trace, finish_trace};
use super::hit_record_updater_tb::{LineMem, MemFaults};
use super::pipe_tb::{TbOptions, TbReport};

/// The bench's knobs beyond `TbOptions`.
#[derive(Clone)]
pub struct L2TbCfg {
    pub clients: u32,
    pub requests_per_client: u32,
    /// Distinct lines addressed.
    pub lines: u32,
    pub mem_latency: u32,
    /// A small cache so the pool does not fit.
    pub l2: L2Cfg,
    pub faults: MemFaults,
    /// Trace into this buffer (invariance tests) instead of `opts.vcd`.
    pub trace_buf: Option<SharedBuf>,
}

impl Default for L2TbCfg {
    fn default() -> Self {
        L2TbCfg {
            clients: 4,
            requests_per_client: 500,
            lines: 96,
            mem_latency: 20,
            l2: L2Cfg {
                bytes: 4096,
                banks: 4,
                ways: 2,
                mshrs: 6,
                targets: 3,
                writebacks: 2,
                port_queue: 6,
                hit_latency: 4,
                ..L2Cfg::default()
            },
            faults: MemFaults::default(),
            trace_buf: None,
        }
    }
}

/// The configuration the bench elaborates its unit with: the chip's L2 has one
/// client per TM plus the hit record updater, so `clients - 1` TMs.
pub fn unit_config(base: &crate::config::Config, b: &L2TbCfg) -> crate::config::Config {
    let mut c = base.clone();
    c.chip.tms = b.clients.max(2) - 1;
    c.chip.l2 = b.l2.clone();
    c
}

const BASE: u64 = 0x4_0000;

/// What the default bench sends (`tb`'s report and errors).
pub fn workload() -> String {
    let b = L2TbCfg::default();
    format!(
        "at most {} accesses from each of {} clients",
        b.requests_per_client, b.clients
    )
}

/// `dualstream tb l2` with the default bench knobs.
pub fn run(opts: &TbOptions) -> Result<TbReport, TbError> {
    run_with(opts, &L2TbCfg::default())
}

/// The address of line `i` of the pool.
fn line_addr(i: u64) -> u64 {
    BASE + i * 64
}

/// The memory lane of a line (`line index mod lanes`, as the L2 has it).
fn lane_of(addr: u64, lanes: usize) -> usize {
    (addr / 64 % lanes as u64) as usize
}

/// The elaborated bench: the simulator and the units the scoreboard reads.
struct Bench {
    sim: Sim,
    clk: ClockId,
    lanes: usize,
    drivers: Vec<UnitId>,
    sinks: Vec<UnitId>,
    flusher: UnitId,
    flush_sink: UnitId,
    dut: UnitId,
    memus: Vec<UnitId>,
}

pub fn run_with(opts: &TbOptions, b: &L2TbCfg) -> Result<TbReport, TbError> {
    check_knobs(opts, b)?;
    let cfg = &unit_config(&opts.config, b);
    cfg.chip.l2.validate(cfg.chip.links.delay)?;
    let mut rng = Rng::new(opts.seed);
    let lanes = cfg.chip.l2.mem_lines_per_cycle as usize;
    let (images, initial) = initial_images(b, lanes, &mut rng);
    let mut bench = build(opts, b, cfg, images)?;
    attach_trace(&mut bench.sim, opts, b.trace_buf.as_ref())?;
    let (sent, end) = drive(&mut bench, opts, b, cfg, &mut rng)?;
    let mut errors = Vec::new();
    let log = bench
        .sim
        .unit_ref::<L2>(bench.dut)
        .log
        .clone()
        .unwrap_or_default();
    let (reference, expect) = check_log(&log, initial, sent, &mut errors);
    let answered = check_answers(&bench, &expect, sent, &mut errors);
    check_real_time(&log, &answered, &mut errors);
    check_dram(&bench, b, &reference, &mut errors);
    let mem_lines_peak = check_memory_side(&bench, &mut errors);
    check_counts(&bench, sent, &mut errors);
    let rep = report(
        &bench,
        b,
        sent,
        answered.len() as u64,
        end,
        mem_lines_peak,
        errors,
    );
    finish_trace(&mut bench.sim, rep)
}

fn check_knobs(opts: &TbOptions, b: &L2TbCfg) -> Result<(), TbError> {
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
    if b.clients < 2 || b.lines == 0 || b.mem_latency < 2 {
        return Err(TbError::Invalid(
            "the bench needs at least 2 clients, lines and a memory latency >= 2".into(),
        ));
    }
    Ok(())
}

/// The initial image: seeded bytes on every line of the pool, as one DRAM
/// image per memory lane (holding the lane's lines) and as a whole.
fn initial_images(b: &L2TbCfg, lanes: usize, rng: &mut Rng) -> (Vec<SparseMem>, SparseMem) {
    let cap = BASE + (b.lines as u64 + 1) * 64;
    let mut images: Vec<SparseMem> = (0..lanes).map(|_| SparseMem::new(cap)).collect();
    let mut initial = SparseMem::new(cap);
    for i in 0..b.lines as u64 {
        let mut l = [0u8; 64];
        l.iter_mut().for_each(|x| *x = rng.below(256) as u8);
        images[lane_of(line_addr(i), lanes)].write(line_addr(i), &l);
        initial.write(line_addr(i), &l);
    }
    (images, initial)
}

/// A driver and a sink per client, the flush driver and its sink, the unit
/// (logging every access) and one memory stand-in per lane on `images`.
fn build(
    opts: &TbOptions,
    b: &L2TbCfg,
    cfg: &crate::config::Config,
    images: Vec<SparseMem>,
) -> Result<Bench, TbError> {
    let link = cfg.chip.links;
    let lanes = images.len();
    let mut sim = Sim::new(opts.sim.clone());
    let clk = sim.clock("core", cfg.clocks.core_ps)?;
    let n = b.clients as usize;
    let (mut req_i, mut resp_o) = (Vec::new(), Vec::new());
    let (mut drivers, mut sinks): (Vec<UnitId>, Vec<UnitId>) = (Vec::new(), Vec::new());
    let mut req_outs = Vec::new();
    let mut resp_ins = Vec::new();
    for k in 0..n {
        let (o, i) = sim.link::<MemLineReq>(&format!("c{k}.req"), link);
        req_i.push(i);
        req_outs.push(o);
        let (o, i) = sim.link::<MemLineResp>(&format!("c{k}.resp"), link);
        resp_o.push(o);
        resp_ins.push(i);
    }
    let (mut mqo, mut mqi, mut mro, mut mri) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for j in 0..lanes {
        let (o, i) = sim.link::<MemLineReq>(&format!("l2.mem_req{j}"), link);
        mqo.push(o);
        mqi.push(i);
        let (o, i) = sim.link::<MemLineResp>(&format!("l2.mem_resp{j}"), link);
        mro.push(o);
        mri.push(i);
    }
    let (fo, fi) = sim.link::<L2Flush>("l2.flush", link);
    let (fdo, fdi) = sim.link::<L2Flush>("l2.flush_done", link);
    for (k, (o, i)) in req_outs.into_iter().zip(resp_ins).enumerate() {
        drivers.push(sim.add(&format!("tb.c{k}"), clk, Driver::new(o)));
        sinks.push(sim.add(
            &format!("tb.c{k}_sink"),
            clk,
            Sink::new(i, opts.ready_p, opts.seed ^ (0xC0 + k as u64)),
        ));
    }
    let flusher = sim.add("tb.flush", clk, Driver::new(fo));
    let flush_sink = sim.add("tb.flush_done", clk, Sink::new(fdi, 1.0, 0));
    let ports = L2Ports {
        req: req_i,
        resp: resp_o,
        mem_req: mqo,
        mem_resp: mri,
        flush: fi,
        flush_done: fdo,
    };
    let mut unit = L2::new(&cfg.chip.l2, link.delay, ports);
    unit.enable_log();
    let dut = sim.add("tb.l2", clk, unit);
    // One stand-in per lane (the faults go to lane 0's).
    let mut memus = Vec::new();
    for (j, ((q, r), image)) in mqi.into_iter().zip(mro).zip(images).enumerate() {
        let mut mem = LineMem::new(
            q,
            r,
            image,
            b.mem_latency,
            link.delay,
            opts.ready_p,
            opts.seed ^ 0x5EED ^ (j as u64) << 8,
            0,
        );
        if j == 0 {
            mem.faults = b.faults.clone();
        }
        memus.push(sim.add(&format!("tb.mem{j}"), clk, mem));
    }
    sim.elaborate()?;
    Ok(Bench {
        sim,
        clk,
        lanes,
        drivers,
        sinks,
        flusher,
        flush_sink,
        dut,
        memus,
    })
}

/// Stimulus: per client, requests at seeded cycles (a hot quarter of the
/// pool), a flush with invalidation in the middle of the traffic, and after
/// it the final flush, as the chip does after a run. Returns the requests
/// sent and the last cycle.
fn drive(
    bench: &mut Bench,
    opts: &TbOptions,
    b: &L2TbCfg,
    cfg: &crate::config::Config,
    rng: &mut Rng,
) -> Result<(u64, u64), TbError> {
    let sim = &mut bench.sim;
    let hot = (b.lines / 4).max(1) as u64;
    let mut sent = 0u64;
    let mut last = 0u64;
    let tags = [StreamTag::Shading, StreamTag::Other];
    for &d in &bench.drivers {
        let mut c = 0u64;
        for id in 0..b.requests_per_client {
            while !rng.chance(opts.load) {
                c += 1;
            }
            // `--cycles` is the stimulus window; the workload caps it.
            if c >= opts.cycles {
                break;
            }
            let line = if rng.chance(0.5) {
                rng.below(hot)
            } else {
                rng.below(b.lines as u64)
            };
            let mut data = Line::default();
            data.0.iter_mut().for_each(|x| *x = rng.below(256) as u8);
            let kind = rng.below(10);
            let (write, mask) = match kind {
                0..=3 => (false, 0),
                4..=5 => (true, u64::MAX),
                _ => (true, rng.next_u64() | 1),
            };
            let r = MemLineReq {
                addr: line_addr(line),
                write,
                tag: tags[rng.below(2) as usize],
                id,
                mask,
                data,
            };
            sim.unit_mut::<Driver<MemLineReq>>(d).send(c, r);
            sent += 1;
            c += 1;
        }
        last = last.max(c);
        sim.wake(d);
    }
    sim.unit_mut::<Driver<L2Flush>>(bench.flusher)
        .send(last / 2, L2Flush { invalidate: true });
    sim.wake(bench.flusher);
    let p = cfg.clocks.core_ps;
    let limit = (sent * 200 + 100_000) * p;
    sim.run_to_idle(limit)?;
    let now = sim.cycle(bench.clk);
    sim.unit_mut::<Driver<L2Flush>>(bench.flusher)
        .send(now, L2Flush { invalidate: false });
    sim.wake(bench.flusher);
    let end = sim.run_to_idle(sim.now() + limit)? / p;
    Ok((sent, end))
}

/// Replays the unit's log of applied accesses on `initial` (per client and
/// line in the client's order); returns the reference image after it and
/// each read's expected line by (client, request).
fn check_log(
    log: &[L2Applied],
    initial: SparseMem,
    sent: u64,
    errors: &mut Vec<String>,
) -> (SparseMem, BTreeMap<(u16, u32), Line>) {
    let mut reference = initial;
    let mut expect: BTreeMap<(u16, u32), Line> = BTreeMap::new();
    let mut order: BTreeMap<(u16, u64), u32> = BTreeMap::new();
    for a in log {
        let r = &a.req;
        if let Some(&prev) = order.get(&(a.port, r.addr))
            && prev >= r.id
        {
            errors.push(format!(
                "client {} line {:#x}: request {} applied after request {} (out of the client's order)",
                a.port, r.addr, r.id, prev
            ));
        }
        order.insert((a.port, r.addr), r.id);
        if r.write {
            let mut l = [0u8; 64];
            reference.read(r.addr, &mut l);
            for (i, x) in l.iter_mut().enumerate() {
                if r.mask >> i & 1 == 1 {
                    *x = r.data.0[i];
                }
            }
            reference.write(r.addr, &l);
        } else {
            let mut l = Line::default();
            reference.read(r.addr, &mut l.0);
            expect.insert((a.port, r.id), l);
        }
    }
    if log.len() as u64 != sent {
        errors.push(format!(
            "{sent} requests sent, {} applied by the cache",
            log.len()
        ));
    }
    (reference, expect)
}

/// Answers: one per request, reads with the reference bytes at their turn.
/// Returns the cycle each (client, request) was answered.
fn check_answers(
    bench: &Bench,
    expect: &BTreeMap<(u16, u32), Line>,
    sent: u64,
    errors: &mut Vec<String>,
) -> BTreeMap<(u16, u32), u64> {
    let mut answered_at: BTreeMap<(u16, u32), u64> = BTreeMap::new();
    for (k, &s) in bench.sinks.iter().enumerate() {
        for (c, r) in &bench.sim.unit_ref::<Sink<MemLineResp>>(s).got {
            if answered_at.insert((k as u16, r.id), *c).is_some() {
                errors.push(format!("client {k}: request {} answered twice", r.id));
            }
            if !r.write {
                match expect.get(&(k as u16, r.id)) {
                    Some(l) if *l == r.data => {}
                    Some(_) => errors.push(format!(
                        "client {k}: read {} of line {:#x} returned bytes that differ from the reference at its turn",
                        r.id, r.addr
                    )),
                    None => errors.push(format!(
                        "client {k}: read {} answered but never applied",
                        r.id
                    )),
                }
            }
        }
    }
    if answered_at.len() as u64 != sent {
        errors.push(format!(
            "{sent} requests sent, {} answered",
            answered_at.len()
        ));
    }
    answered_at
}

/// Real time: an access accepted after a write to its line was answered is
/// applied after that write.
fn check_real_time(
    log: &[L2Applied],
    answered_at: &BTreeMap<(u16, u32), u64>,
    errors: &mut Vec<String>,
) {
    // Per line, the log position of the writes and when answered.
    let mut writes: BTreeMap<u64, Vec<(usize, u64)>> = BTreeMap::new();
    for (pos, a) in log.iter().enumerate() {
        if a.req.write
            && let Some(&t) = answered_at.get(&(a.port, a.req.id))
        {
            writes.entry(a.req.addr).or_default().push((pos, t));
        }
    }
    for (pos, a) in log.iter().enumerate() {
        for &(wpos, t) in writes.get(&a.req.addr).map_or(&[][..], |v| &v[..]) {
            if t < a.accepted && wpos > pos {
                errors.push(format!(
                    "line {:#x}: an access accepted in cycle {} was applied before a write answered in cycle {t}",
                    a.req.addr, a.accepted
                ));
            }
        }
    }
}

/// The memory stand-ins, lane by lane.
fn mems(bench: &Bench) -> Vec<&LineMem> {
    bench
        .memus
        .iter()
        .map(|&u| bench.sim.unit_ref::<LineMem>(u))
        .collect()
}

/// DRAM after the final flush equals the reference (each line from its
/// lane's stand-in).
fn check_dram(bench: &Bench, b: &L2TbCfg, reference: &SparseMem, errors: &mut Vec<String>) {
    let mems = mems(bench);
    for i in 0..b.lines as u64 {
        let (mut got, mut want) = ([0u8; 64], [0u8; 64]);
        mems[lane_of(line_addr(i), bench.lanes)]
            .image
            .read(line_addr(i), &mut got);
        reference.read(line_addr(i), &mut want);
        if got != want {
            errors.push(format!(
                "line {:#x}: DRAM after the flush differs from the reference",
                line_addr(i)
            ));
        }
    }
}

/// The memory side: every request on its line's lane, never two requests for
/// one line at once (a line has one lane, whose stand-in answers in acceptance
/// order). Returns the most lines accepted in one cycle over the lanes.
fn check_memory_side(bench: &Bench, errors: &mut Vec<String>) -> u64 {
    let lanes = bench.lanes;
    let mut per_cycle: BTreeMap<u64, u64> = BTreeMap::new();
    for (j, m) in mems(bench).iter().enumerate() {
        let mut busy_until: BTreeMap<u64, u64> = BTreeMap::new();
        for ((ca, r), (cr, _)) in m.accepted.iter().zip(m.answered.iter()) {
            *per_cycle.entry(*ca).or_default() += 1;
            if lane_of(r.addr, lanes) != j {
                errors.push(format!(
                    "line {:#x}: a memory request on lane {j}, its lane is {}",
                    r.addr,
                    lane_of(r.addr, lanes)
                ));
            }
            if let Some(&t) = busy_until.get(&r.addr)
                && *ca <= t
            {
                errors.push(format!(
                    "line {:#x}: a memory request accepted in cycle {ca} while another was in flight until {t}",
                    r.addr
                ));
            }
            busy_until.insert(r.addr, *cr);
        }
        if m.accepted.len() != m.answered.len() {
            errors.push(format!(
                "memory lane {j} accepted {} requests and answered {}",
                m.accepted.len(),
                m.answered.len()
            ));
        }
    }
    per_cycle.values().copied().max().unwrap_or(0)
}

/// Counters: accesses = requests, hits + misses = accesses, fills = memory
/// reads, writebacks = memory writes, two flushes answered.
fn check_counts(bench: &Bench, sent: u64, errors: &mut Vec<String>) {
    let mems = mems(bench);
    let s = bench.sim.unit_ref::<L2>(bench.dut).stats;
    let maccepted: u64 = mems.iter().map(|m| m.accepted.len() as u64).sum();
    let mreads = mems
        .iter()
        .flat_map(|m| m.accepted.iter())
        .filter(|(_, r)| !r.write)
        .count() as u64;
    let mwrites = maccepted - mreads;
    if s.accesses != sent || s.hits + s.misses != s.accesses {
        errors.push(format!(
            "accesses {} (sent {sent}), hits {} + misses {} must equal them",
            s.accesses, s.hits, s.misses
        ));
    }
    if s.fills != mreads || s.writebacks != mwrites {
        errors.push(format!(
            "fills {} / writebacks {}, the memory saw {mreads} reads / {mwrites} writes",
            s.fills, s.writebacks
        ));
    }
    let flushed = bench
        .sim
        .unit_ref::<Sink<L2Flush>>(bench.flush_sink)
        .got
        .len();
    if flushed != 2 {
        errors.push(format!("2 flushes sent, {flushed} answered"));
    }
}

fn report(
    bench: &Bench,
    b: &L2TbCfg,
    sent: u64,
    answered: u64,
    end: u64,
    mem_lines_peak: u64,
    errors: Vec<String>,
) -> TbReport {
    let sim = &bench.sim;
    let st = sim.unit_stats(bench.dut);
    let u = sim.unit_ref::<L2>(bench.dut);
    let lane0_writes = mems(bench)[0]
        .accepted
        .iter()
        .filter(|(_, r)| r.write)
        .count() as u64;
    let blocked: u64 = bench
        .drivers
        .iter()
        .map(|&d| sim.unit_stats(d).status_cycles[Status::OutputBlocked as usize])
        .sum();
    TbReport {
        unit: "l2",
        requests: sent,
        results: answered,
        cycles: end,
        min_latency: 0,
        max_latency: 0,
        stall_cycles: st.status_cycles[Status::ResourceBusy as usize],
        errors,
        vcd_changes: 0,
        vcd_bytes: 0,
        status_cycles: st.status_cycles,
        // The unit's own counters, then the bench's.
        counters: crate::rtl::Logic::counters(u)
            .into_iter()
            .chain([
                ("client_blocked_cycles", blocked),
                ("mem_lines_peak", mem_lines_peak),
                ("lane0_writes", lane0_writes),
                ("lines_checked", b.lines as u64),
            ])
            .collect(),
    }
}
