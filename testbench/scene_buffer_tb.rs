//! The scene buffer testbench: a scripted scheduler stand-in maps segments into
//! slots (`slot_map`) and a memory stand-in streams their lines in (`fill`) after
//! seeded random delays; one driver per TM (L1 miss port) asks for lines,
//! including lines not streamed in yet and lines of segments not mapped yet; a
//! seeded back-pressuring sink per TM takes the answers.
//!
//! Two phases: phase 1 maps every slot (generation 1) and streams each segment;
//! phase 2 reuses half of the slots for new segments (generation 2) while late
//! lines of the retired segments (generation 1) still arrive and must be dropped.
//!
//! Scoreboard:
//! - every response carries exactly the DRAM image's 64 bytes for the requested
//!   line, in request order per TM, one response per request;
//! - causality: a response is visible no earlier than `latency` cycles after the
//!   request and after the fill of its line was taken;
//! - requests for lines not yet streamed wait and complete: `stalls` is at most
//!   the number of requests made before their line arrived (reported, and the
//!   tests require some);
//! - `reads` = requests, `fills` = current-generation lines streamed,
//!   `stale_fills` = late lines of retired segments (never served: requests for
//!   the new segment's lines made between a stale line and the real one wait);
//! - bank conflicts are counted (reported; the tests require some).

use crate::contract::{LINE_BYTES, SparseMem};
use crate::mem::StreamTag;
use crate::rtl::link::LinkEvent;
use crate::rtl::{LinkId, SharedBuf, Sim, Status, UnitId, UnitStats};
use crate::testbench::TbError;
use crate::units::l1::{L1Req, L1Resp, Line};
use crate::units::memory::MemLineResp;
use crate::units::scene_buffer::SceneBufferCfg;
use crate::units::scene_buffer::{SceneBuffer, SceneBufferPorts, SlotMap, fill_id};
use crate::util::rng::Rng;

use super::harness::{Driver, Sink, attach_trace, counter, finish_trace};
use super::pipe_tb::{TbOptions, TbReport};

/// The bench's knobs beyond `TbOptions`.
#[derive(Clone)]
pub struct SceneBufferTbCfg {
    pub tms: u32,
    /// Requests per TM and phase.
    pub requests_per_tm: u32,
    pub sb: SceneBufferCfg,
    /// Largest delay of a streamed line after its mapping (cycles).
    pub max_fill_delay: u64,
    /// Fault: late lines of retired segments carry the new generation.
    pub stale_as_current: bool,
    /// Wrong expectation: one byte of the expected image is flipped.
    pub corrupt_expect: bool,
    pub trace_buf: Option<SharedBuf>,
}

impl Default for SceneBufferTbCfg {
    fn default() -> Self {
        SceneBufferTbCfg {
            tms: 6,
            requests_per_tm: 150,
            sb: SceneBufferCfg {
                bytes: 8 * 4096,
                slot_bytes: 4096,
                banks: 4,
                latency: 4,
            },
            max_fill_delay: 300,
            stale_as_current: false,
            corrupt_expect: false,
            trace_buf: None,
        }
    }
}

/// A fill event: (cycle, slot, generation, segment, line, stale).
#[derive(Clone, Copy)]
struct Fill {
    at: u64,
    slot: u16,
    generation: u8,
    seg: usize,
    line: u32,
    stale: bool,
}

struct Seg {
    base: u64,
    lines: u32,
}

fn line_of(mem: &SparseMem, a: u64) -> Line {
    let mut l = Line::default();
    mem.read(a, &mut l.0);
    l
}

/// The configuration the bench elaborates its unit with: `base` with the bench's
/// TM count and scene-buffer geometry (the Verilog module of the traced scope).
pub fn unit_config(base: &crate::config::Config, b: &SceneBufferTbCfg) -> crate::config::Config {
    let mut c = base.clone();
    c.chip.tms = b.tms;
    c.chip.scene_buffer = b.sb.clone();
    // The bench's memory stand-in streams on one fill lane.
    c.chip.scheduler.scene_lines_per_cycle = 1;
    c
}

/// What the default bench runs (`tb`'s report and errors).
pub fn workload() -> String {
    let b = SceneBufferTbCfg::default();
    format!(
        "a fixed script: {} line requests from each of {} TMs over two phases of segment maps",
        b.requests_per_tm, b.tms
    )
}

pub fn run(opts: &TbOptions) -> Result<TbReport, TbError> {
    run_with(opts, &SceneBufferTbCfg::default())
}

/// The elaborated bench: the simulator, the units the bench drives and reads,
/// and the links whose pushes and pops the scoreboard times.
struct Bench {
    sim: Sim,
    map_drv: UnitId,
    fill_drv: UnitId,
    drivers: Vec<UnitId>,
    dut: UnitId,
    sinks: Vec<UnitId>,
    fill_link: LinkId,
    req_links: Vec<LinkId>,
}

/// What the bench sent, for the scoreboard.
#[derive(Default)]
struct Sent {
    fills: Vec<Fill>,
    /// Per TM the requested line addresses, the segment line serving each
    /// (index into `fills`) and the phase.
    asked: Vec<Vec<(u64, usize, u32)>>,
    maps: u64,
    stale_n: u64,
    /// slot -> (segment, generation) after each phase.
    holder: Vec<(usize, u8)>,
}

/// One phase of the script: its number (0, 1), its first cycle and the slots
/// it remapped.
struct Phase {
    n: u32,
    t0: u64,
    remapped: Vec<u16>,
}

/// What the scoreboard measured beside its errors.
struct Score {
    errors: Vec<String>,
    requests: u64,
    results: u64,
    /// Requests made before their line was taken.
    early: u64,
    min_l: u64,
    max_l: u64,
}

pub fn run_with(opts: &TbOptions, b: &SceneBufferTbCfg) -> Result<TbReport, TbError> {
    check_knobs(opts, b)?;
    let cfg = &unit_config(&opts.config, b);
    let p = cfg.clocks.core_ps;
    let mut rng = Rng::new(opts.seed);
    let (segs, image) = segments(b, &mut rng);
    let mut bench = build(opts, b, cfg)?;
    attach_trace(&mut bench.sim, opts, b.trace_buf.as_ref())?;
    let mut sent = Sent {
        asked: vec![Vec::new(); b.tms as usize],
        holder: (0..b.sb.slots() as usize).map(|s| (s, 1)).collect(),
        ..Sent::default()
    };
    let mut end = 0u64;
    for phase in 0..2u32 {
        let t0 = end + 2;
        let (ev, remapped) = if phase == 0 {
            (
                map_all(&mut bench, b, &segs, t0, &mut sent, &mut rng),
                Vec::new(),
            )
        } else {
            remap_even(&mut bench, b, &segs, t0, &mut sent, &mut rng)
        };
        send_fills(&mut bench, &segs, &image, ev, &mut sent);
        let ph = Phase {
            n: phase,
            t0,
            remapped,
        };
        send_requests(&mut bench, b, &segs, &ph, &mut sent, &mut rng);
        for &d in &bench.drivers {
            bench.sim.wake(d);
        }
        bench.sim.wake(bench.map_drv);
        bench.sim.wake(bench.fill_drv);
        end = bench.sim.run_to_idle((end + 1_000_000) * p)? / p;
    }
    let st = bench.sim.unit_stats(bench.dut);
    let score = check(&bench, b, image, &sent, &st, p);
    let rep = report(&st, &sent, score, end);
    finish_trace(&mut bench.sim, rep)
}

fn check_knobs(opts: &TbOptions, b: &SceneBufferTbCfg) -> Result<(), TbError> {
    let prob = |p: f64| p > 0.0 && p <= 1.0;
    if !prob(opts.ready_p) {
        return Err(TbError::Invalid(
            "--ready is a probability in (0, 1]".into(),
        ));
    }
    let slots = b.sb.slots();
    let slot_lines = b.sb.slot_bytes / LINE_BYTES as u32;
    if b.tms == 0 || slots < 2 || slot_lines < 8 || b.sb.banks == 0 || b.sb.latency < 2 {
        return Err(TbError::Invalid(
            "the bench needs TMs, >= 2 slots of >= 8 lines, banks and latency >= 2".into(),
        ));
    }
    Ok(())
}

/// Segments (phase 1 fills every slot, phase 2 replaces the even slots) of
/// seeded lengths, and the DRAM image of their lines.
fn segments(b: &SceneBufferTbCfg, rng: &mut Rng) -> (Vec<Seg>, SparseMem) {
    let slots = b.sb.slots();
    let slot_lines = b.sb.slot_bytes / LINE_BYTES as u32;
    let base0 = 0x10_0000u64;
    let mut segs: Vec<Seg> = Vec::new();
    let n_segs = slots + slots.div_ceil(2);
    for e in 0..n_segs {
        segs.push(Seg {
            base: base0 + e as u64 * b.sb.slot_bytes as u64,
            lines: 8 + rng.below((slot_lines - 7) as u64) as u32,
        });
    }
    let mut image = SparseMem::new(base0 + (n_segs as u64 + 1) * b.sb.slot_bytes as u64);
    for s in &segs {
        for l in 0..s.lines as u64 {
            let bytes: Vec<u8> = (0..LINE_BYTES).map(|_| rng.next_u32() as u8).collect();
            image.write(s.base + l * LINE_BYTES, &bytes);
        }
    }
    (segs, image)
}

/// The scheduler and stream stand-ins, one request driver and one sink per
/// TM, and the unit; the fill and request links are logged.
fn build(
    opts: &TbOptions,
    b: &SceneBufferTbCfg,
    cfg: &crate::config::Config,
) -> Result<Bench, TbError> {
    let link = cfg.chip.links;
    let mut sim = Sim::new(opts.sim.clone());
    let clk = sim.clock("core", cfg.clocks.core_ps)?;
    let (mo, mi) = sim.link::<SlotMap>("sb.slot_map", link);
    let (fo, fi) = sim.link::<MemLineResp>("sb.fill", link);
    let mut reqs = Vec::new();
    let mut resps = Vec::new();
    let mut req_outs = Vec::new();
    let mut resp_ins = Vec::new();
    let mut req_links: Vec<LinkId> = Vec::new();
    for k in 0..b.tms {
        let (o, i) = sim.link::<L1Req>(&format!("tm{k}.sb_req"), link);
        let (ro, ri) = sim.link::<L1Resp>(&format!("tm{k}.sb_resp"), link);
        req_links.push(o.id);
        req_outs.push(o);
        reqs.push(i);
        resps.push(ro);
        resp_ins.push(ri);
    }
    let fill_link = fo.id;
    let map_drv = sim.add("tb.scheduler", clk, Driver::new(mo));
    let fill_drv = sim.add("tb.stream", clk, Driver::new(fo));
    let mut drivers: Vec<UnitId> = Vec::new();
    for (k, o) in req_outs.into_iter().enumerate() {
        drivers.push(sim.add(&format!("tb.tm{k}"), clk, Driver::new(o)));
    }
    let dut = sim.add(
        "tb.scene_buffer",
        clk,
        SceneBuffer::new(
            &cfg.chip.scene_buffer,
            link.delay,
            SceneBufferPorts {
                slot_map: mi,
                fill: vec![fi],
                req: reqs,
                resp: resps,
            },
        ),
    );
    let mut sinks: Vec<UnitId> = Vec::new();
    for (k, i) in resp_ins.into_iter().enumerate() {
        sinks.push(sim.add(
            &format!("tb.tm{k}_sink"),
            clk,
            Sink::new(i, opts.ready_p, opts.seed.wrapping_mul(31) + k as u64),
        ));
    }
    sim.elaborate()?;
    sim.log_link(fill_link, true);
    for &l in &req_links {
        sim.log_link(l, true);
    }
    Ok(Bench {
        sim,
        map_drv,
        fill_drv,
        drivers,
        dut,
        sinks,
        fill_link,
        req_links,
    })
}

/// Phase 1: every slot mapped (generation 1), its segment's lines streamed
/// after seeded delays. Returns the fills.
fn map_all(
    bench: &mut Bench,
    b: &SceneBufferTbCfg,
    segs: &[Seg],
    t0: u64,
    sent: &mut Sent,
    rng: &mut Rng,
) -> Vec<Fill> {
    let mut ev: Vec<Fill> = Vec::new();
    for s in 0..b.sb.slots() as u16 {
        let at = t0 + s as u64 * 3;
        let sg = &segs[s as usize];
        bench.sim.unit_mut::<Driver<SlotMap>>(bench.map_drv).send(
            at,
            SlotMap {
                slot: s,
                generation: 1,
                base: sg.base,
                lines: sg.lines,
            },
        );
        sent.maps += 1;
        for l in 0..sg.lines {
            ev.push(Fill {
                at: at + 1 + rng.below(b.max_fill_delay),
                slot: s,
                generation: 1,
                seg: s as usize,
                line: l,
                stale: false,
            });
        }
    }
    ev
}

/// Phase 2: the even slots remapped to new segments (the next generation);
/// late lines of the retired segments arrive first, then the new segments'.
/// Returns the fills and the remapped slots.
fn remap_even(
    bench: &mut Bench,
    b: &SceneBufferTbCfg,
    segs: &[Seg],
    t0: u64,
    sent: &mut Sent,
    rng: &mut Rng,
) -> (Vec<Fill>, Vec<u16>) {
    let slots = b.sb.slots();
    let mut ev: Vec<Fill> = Vec::new();
    let mut remapped: Vec<u16> = Vec::new();
    for s in (0..slots as u16).step_by(2) {
        let e = slots as usize + s as usize / 2;
        let (old, og) = sent.holder[s as usize];
        let sg = &segs[e];
        bench.sim.unit_mut::<Driver<SlotMap>>(bench.map_drv).send(
            t0,
            SlotMap {
                slot: s,
                generation: og + 1,
                base: sg.base,
                lines: sg.lines,
            },
        );
        sent.maps += 1;
        sent.holder[s as usize] = (e, og + 1);
        remapped.push(s);
        // Late lines of the retired segment, then the new segment's.
        for l in 0..4u32 {
            ev.push(Fill {
                at: t0 + 1 + l as u64,
                slot: s,
                generation: if b.stale_as_current { og + 1 } else { og },
                seg: old,
                line: l,
                stale: true,
            });
            sent.stale_n += 1;
        }
        for l in 0..sg.lines {
            ev.push(Fill {
                at: t0 + 60 + rng.below(b.max_fill_delay),
                slot: s,
                generation: og + 1,
                seg: e,
                line: l,
                stale: false,
            });
        }
    }
    (ev, remapped)
}

/// The stream stand-in sends the phase's fills in time order.
fn send_fills(
    bench: &mut Bench,
    segs: &[Seg],
    image: &SparseMem,
    mut ev: Vec<Fill>,
    sent: &mut Sent,
) {
    ev.sort_by_key(|f| f.at);
    for f in &ev {
        let sg = &segs[f.seg];
        let a = sg.base + f.line as u64 * LINE_BYTES;
        bench
            .sim
            .unit_mut::<Driver<MemLineResp>>(bench.fill_drv)
            .send(
                f.at,
                MemLineResp {
                    addr: a,
                    write: false,
                    tag: StreamTag::Scene,
                    id: fill_id(f.generation, f.slot, f.line),
                    data: line_of(image, a),
                },
            );
    }
    sent.fills.extend(ev.iter().copied());
}

/// Requests: current segments' lines, some before they stream in (and in
/// phase 2 the remapped slots' first lines right after their stale lines).
fn send_requests(
    bench: &mut Bench,
    b: &SceneBufferTbCfg,
    segs: &[Seg],
    ph: &Phase,
    sent: &mut Sent,
    rng: &mut Rng,
) {
    let (phase, t0, remapped) = (ph.n, ph.t0, &ph.remapped);
    let slots = b.sb.slots();
    for (k, &d) in bench.drivers.iter().enumerate() {
        let mut at = t0;
        for n in 0..b.requests_per_tm {
            at += rng.below(4);
            let s = if phase == 1 && n < 2 {
                remapped[(k + n as usize) % remapped.len()] as usize
            } else {
                rng.below(slots as u64) as usize
            };
            let (e, g) = sent.holder[s];
            let l = if phase == 1 && n < 2 {
                (k as u32 + n) % 4
            } else {
                rng.below(segs[e].lines as u64) as u32
            };
            let req_at = if phase == 1 && n < 2 { t0 + 20 } else { at };
            let a = segs[e].base + l as u64 * LINE_BYTES;
            bench.sim.unit_mut::<Driver<L1Req>>(d).send(
                req_at.max(at),
                L1Req {
                    addr: a + rng.below(LINE_BYTES),
                },
            );
            // The fill that serves it: this phase's current-generation line, or
            // phase 1's for slots kept.
            let serve = sent
                .fills
                .iter()
                .enumerate()
                .rev()
                .find(|(_, f)| !f.stale && f.seg == e && f.line == l && f.generation == g)
                .map(|(i, _)| i)
                .expect("every requested line is streamed");
            sent.asked[k].push((a, serve, phase));
        }
    }
}

/// The cycles each entry of link `id` became visible and was taken.
fn pushes(sim: &Sim, id: LinkId, p: u64) -> Vec<(u64, u64)> {
    let log = sim.link_log(id);
    let v: Vec<u64> = log
        .iter()
        .filter_map(|e| match e {
            LinkEvent::Push { visible, .. } => Some(*visible / p),
            _ => None,
        })
        .collect();
    let pops: Vec<u64> = log
        .iter()
        .filter_map(|e| match e {
            LinkEvent::Pop { at } => Some(*at / p),
            _ => None,
        })
        .collect();
    v.into_iter().zip(pops).collect()
}

/// The scoreboard (see the module doc): every response's bytes, order and
/// timing per TM, then the unit's counters.
fn check(
    bench: &Bench,
    b: &SceneBufferTbCfg,
    image: SparseMem,
    sent: &Sent,
    st: &UnitStats,
    p: u64,
) -> Score {
    let sim = &bench.sim;
    let asked = &sent.asked;
    let mut expect_img = image;
    if b.corrupt_expect {
        let a = asked[0][0].0 + 5;
        let mut x = [0u8; 1];
        expect_img.read(a, &mut x);
        expect_img.write(a, &[x[0] ^ 0x40]);
    }
    let fill_t = pushes(sim, bench.fill_link, p);
    let lat = b.sb.latency as u64;
    let mut errors = Vec::new();
    let mut requests = 0u64;
    let mut results = 0u64;
    let mut early = 0u64;
    let (mut min_l, mut max_l) = (u64::MAX, 0u64);
    for (k, asked_k) in asked.iter().enumerate() {
        let got = &sim.unit_ref::<Sink<L1Resp>>(bench.sinks[k]).got;
        let req_t = pushes(sim, bench.req_links[k], p);
        requests += asked_k.len() as u64;
        results += got.len() as u64;
        if got.len() != asked_k.len() {
            errors.push(format!(
                "TM {k}: {} requests, {} responses",
                asked_k.len(),
                got.len()
            ));
        }
        for (i, ((c, r), &(a, serve, phase))) in got.iter().zip(asked_k).enumerate() {
            if r.addr != a {
                errors.push(format!(
                    "TM {k} response {i}: line {:#x}, requested {a:#x}",
                    r.addr
                ));
                continue;
            }
            if r.line != line_of(&expect_img, a) {
                errors.push(format!(
                    "TM {k} response {i} (phase {}): line {a:#x} has bytes that are not the DRAM image's",
                    phase + 1
                ));
            }
            let (rv, _) = req_t[i];
            let (_, fpop) = fill_t[serve];
            if rv < fpop {
                early += 1;
            }
            if *c < rv + lat || *c < fpop + lat {
                errors.push(format!(
                    "TM {k} response {i}: seen at cycle {c}, request visible {rv}, its line taken {fpop}, latency {lat}"
                ));
            }
            min_l = min_l.min(c - rv);
            max_l = max_l.max(c - rv);
        }
    }
    check_counters(b, sent, st, requests, early, &mut errors);
    Score {
        errors,
        requests,
        results,
        early,
        min_l,
        max_l,
    }
}

/// `reads` = requests, `fills` = current-generation lines streamed,
/// `stale_fills` = late lines of retired segments, `stalls` at most the early
/// requests.
fn check_counters(
    b: &SceneBufferTbCfg,
    sent: &Sent,
    st: &UnitStats,
    requests: u64,
    early: u64,
    errors: &mut Vec<String>,
) {
    let ctr = |n: &str| counter(st, n);
    let stale_n = sent.stale_n;
    let fresh = sent.fills.len() as u64 - stale_n;
    let checks = [
        ("reads", requests),
        ("fills", fresh),
        ("stale_fills", stale_n),
    ];
    for (name, want) in checks {
        if !b.stale_as_current && ctr(name) != want {
            errors.push(format!("{name} = {}, expected {want}", ctr(name)));
        }
    }
    if b.stale_as_current && ctr("stale_fills") != stale_n {
        errors.push(format!(
            "stale_fills = {}, expected {stale_n}",
            ctr("stale_fills")
        ));
    }
    if ctr("stalls") > early {
        errors.push(format!(
            "{} stalls but only {early} requests came before their line",
            ctr("stalls")
        ));
    }
}

fn report(st: &UnitStats, sent: &Sent, score: Score, end: u64) -> TbReport {
    let ctr = |n: &str| counter(st, n);
    TbReport {
        unit: "scene_buffer",
        requests: score.requests,
        results: score.results,
        cycles: end,
        min_latency: if score.min_l == u64::MAX {
            0
        } else {
            score.min_l
        },
        max_latency: score.max_l,
        stall_cycles: ctr("stall_cycles"),
        errors: score.errors,
        vcd_changes: 0,
        vcd_bytes: 0,
        status_cycles: st.status_cycles,
        counters: vec![
            ("maps", sent.maps),
            ("fills", ctr("fills")),
            ("stale_fills", ctr("stale_fills")),
            ("early_requests", score.early),
            ("stalls", ctr("stalls")),
            ("stall_cycles", ctr("stall_cycles")),
            ("bank_conflicts", ctr("bank_conflicts")),
            (
                "sink_blocked_cycles",
                st.status_cycles[Status::OutputBlocked as usize],
            ),
        ],
    }
}
