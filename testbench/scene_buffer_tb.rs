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
use crate::rtl::{LinkId, SharedBuf, Sim, Status, Tracer, UnitId};
use crate::units::l1::{L1Req, L1Resp, Line};
use crate::units::memory::MemLineResp;
use crate::units::scene_buffer::SceneBufferCfg;
use crate::units::scene_buffer::{SceneBuffer, SlotMap, fill_id};
use crate::util::rng::Rng;

use super::harness::{Driver, Sink};
use super::pipe_tb::{TbOptions, TbReport};

/// The bench's knobs beyond `TbOptions`.
#[derive(Clone)]
pub struct SbTbCfg {
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

impl Default for SbTbCfg {
    fn default() -> Self {
        SbTbCfg {
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
pub fn unit_config(base: &crate::config::Config, b: &SbTbCfg) -> crate::config::Config {
    let mut c = base.clone();
    c.chip.tms = b.tms;
    c.chip.scene_buffer = b.sb.clone();
    // The bench's memory stand-in streams on one fill lane.
    c.chip.scheduler.scene_lines_per_cycle = 1;
    c
}

pub fn run(opts: &TbOptions) -> Result<TbReport, String> {
    run_with(opts, &SbTbCfg::default())
}

pub fn run_with(opts: &TbOptions, b: &SbTbCfg) -> Result<TbReport, String> {
    let prob = |p: f64| p > 0.0 && p <= 1.0;
    if !prob(opts.ready_p) {
        return Err("--ready is a probability in (0, 1]".into());
    }
    let slots = b.sb.slots();
    let slot_lines = b.sb.slot_bytes / LINE_BYTES as u32;
    if b.tms == 0 || slots < 2 || slot_lines < 8 || b.sb.banks == 0 || b.sb.latency < 2 {
        return Err("the bench needs TMs, >= 2 slots of >= 8 lines, banks and latency >= 2".into());
    }
    let cfg = &unit_config(&opts.config, b);
    let link = cfg.chip.links;
    let p = cfg.clocks.core_ps;
    let mut rng = Rng::new(opts.seed);
    // Segments: phase 1 fills every slot, phase 2 replaces the even slots.
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
    let mut sim = Sim::new(opts.sim.clone());
    let clk = sim.clock("core", p).map_err(|e| e.to_string())?;
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
            mi,
            vec![fi],
            reqs,
            resps,
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
    sim.elaborate().map_err(|e| e.to_string())?;
    sim.log_link(fo.id, true);
    for &l in &req_links {
        sim.log_link(l, true);
    }
    if let Some(buf) = &b.trace_buf {
        let t = Tracer::new(Box::new(buf.clone()), opts.trace.clone())?;
        sim.attach_tracer(t).map_err(|e| e.to_string())?;
    } else if let Some(path) = &opts.vcd {
        let t = Tracer::to_file(path, opts.trace.clone())?;
        sim.attach_tracer(t).map_err(|e| e.to_string())?;
    }
    // The scoreboard's record: per TM the requested line addresses and the
    // segment line serving each (index into `fills`, once known).
    let mut fills: Vec<Fill> = Vec::new();
    let mut asked: Vec<Vec<(u64, usize, u32)>> = vec![Vec::new(); b.tms as usize];
    let mut maps = 0u64;
    let mut stale_n = 0u64;
    let mut end = 0u64;
    // slot -> (segment, generation) after each phase.
    let mut holder: Vec<(usize, u8)> = (0..slots as usize).map(|s| (s, 1)).collect();
    for phase in 0..2u32 {
        let t0 = end + 2;
        let mut ev: Vec<Fill> = Vec::new();
        let mut remapped: Vec<u16> = Vec::new();
        if phase == 0 {
            for s in 0..slots as u16 {
                let at = t0 + s as u64 * 3;
                let sg = &segs[s as usize];
                sim.unit_mut::<Driver<SlotMap>>(map_drv).send(
                    at,
                    SlotMap {
                        slot: s,
                        generation: 1,
                        base: sg.base,
                        lines: sg.lines,
                    },
                );
                maps += 1;
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
        } else {
            for s in (0..slots as u16).step_by(2) {
                let e = slots as usize + s as usize / 2;
                let (old, og) = holder[s as usize];
                let sg = &segs[e];
                sim.unit_mut::<Driver<SlotMap>>(map_drv).send(
                    t0,
                    SlotMap {
                        slot: s,
                        generation: og + 1,
                        base: sg.base,
                        lines: sg.lines,
                    },
                );
                maps += 1;
                holder[s as usize] = (e, og + 1);
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
                    stale_n += 1;
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
        }
        ev.sort_by_key(|f| f.at);
        for f in &ev {
            let sg = &segs[f.seg];
            let a = sg.base + f.line as u64 * LINE_BYTES;
            sim.unit_mut::<Driver<MemLineResp>>(fill_drv).send(
                f.at,
                MemLineResp {
                    addr: a,
                    write: false,
                    tag: StreamTag::Scene,
                    id: fill_id(f.generation, f.slot, f.line),
                    data: line_of(&image, a),
                },
            );
        }
        fills.extend(ev.iter().copied());
        // Requests: current segments' lines, some before they stream in (and in
        // phase 2 the remapped slots' first lines right after their stale lines).
        for (k, &d) in drivers.iter().enumerate() {
            let mut at = t0;
            for n in 0..b.requests_per_tm {
                at += rng.below(4);
                let s = if phase == 1 && n < 2 {
                    remapped[(k + n as usize) % remapped.len()] as usize
                } else {
                    rng.below(slots as u64) as usize
                };
                let (e, g) = holder[s];
                let l = if phase == 1 && n < 2 {
                    (k as u32 + n) % 4
                } else {
                    rng.below(segs[e].lines as u64) as u32
                };
                let req_at = if phase == 1 && n < 2 { t0 + 20 } else { at };
                let a = segs[e].base + l as u64 * LINE_BYTES;
                sim.unit_mut::<Driver<L1Req>>(d).send(
                    req_at.max(at),
                    L1Req {
                        addr: a + rng.below(LINE_BYTES),
                    },
                );
                // The fill that serves it: this phase's current-generation line, or
                // phase 1's for slots kept.
                let serve = fills
                    .iter()
                    .enumerate()
                    .rev()
                    .find(|(_, f)| !f.stale && f.seg == e && f.line == l && f.generation == g)
                    .map(|(i, _)| i)
                    .expect("every requested line is streamed");
                asked[k].push((a, serve, phase));
            }
        }
        for &d in &drivers {
            sim.wake(d);
        }
        sim.wake(map_drv);
        sim.wake(fill_drv);
        end = sim
            .run_to_idle((end + 1_000_000) * p)
            .map_err(|e| e.to_string())?
            / p;
    }
    // Scoreboard.
    let mut expect_img = image;
    if b.corrupt_expect {
        let a = asked[0][0].0 + 5;
        let mut x = [0u8; 1];
        expect_img.read(a, &mut x);
        expect_img.write(a, &[x[0] ^ 0x40]);
    }
    let pushes = |id: LinkId| -> Vec<(u64, u64)> {
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
    };
    let fill_t = pushes(fo.id);
    let lat = b.sb.latency as u64;
    let mut errors = Vec::new();
    let mut requests = 0u64;
    let mut results = 0u64;
    let mut early = 0u64;
    let (mut min_l, mut max_l) = (u64::MAX, 0u64);
    for k in 0..b.tms as usize {
        let got = &sim.unit_ref::<Sink<L1Resp>>(sinks[k]).got;
        let req_t = pushes(req_links[k]);
        requests += asked[k].len() as u64;
        results += got.len() as u64;
        if got.len() != asked[k].len() {
            errors.push(format!(
                "TM {k}: {} requests, {} responses",
                asked[k].len(),
                got.len()
            ));
        }
        for (i, ((c, r), &(a, serve, phase))) in got.iter().zip(&asked[k]).enumerate() {
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
    let st = sim.unit_stats(dut);
    let ctr = |n: &str| {
        st.counters
            .iter()
            .find(|(k, _)| *k == n)
            .map_or(0, |(_, v)| *v)
    };
    let fresh = fills.len() as u64 - stale_n;
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
    let mut rep = TbReport {
        unit: "scene_buffer",
        requests,
        results,
        cycles: end,
        min_latency: if min_l == u64::MAX { 0 } else { min_l },
        max_latency: max_l,
        stall_cycles: ctr("stall_cycles"),
        errors,
        vcd_changes: 0,
        vcd_bytes: 0,
        status_cycles: st.status_cycles,
        counters: vec![
            ("maps", maps),
            ("fills", ctr("fills")),
            ("stale_fills", ctr("stale_fills")),
            ("early_requests", early),
            ("stalls", ctr("stalls")),
            ("stall_cycles", ctr("stall_cycles")),
            ("bank_conflicts", ctr("bank_conflicts")),
            (
                "sink_blocked_cycles",
                st.status_cycles[Status::OutputBlocked as usize],
            ),
        ],
    };
    if let Some(r) = sim.finish_trace() {
        let s = r.map_err(|e| format!("writing the VCD failed: {e}"))?;
        rep.vcd_changes = s.changes;
        rep.vcd_bytes = s.bytes;
    }
    Ok(rep)
}
