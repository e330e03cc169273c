//! A directed testbench of a TM's ray staging buffer: three buckets (4, 2 and 3
//! rays; a half holds 4) through a buffer draining to two TPs, each of which
//! takes its next ray at cycles of a seeded pattern (`--seed`, `--ready`).
//!
//! It checks that every ray comes out once, with its own data and its own
//! bucket's header (a half is refilled only once drained, a bucket's `last`
//! seals its half), that each TP gets its rays in fill order, and that the
//! halves swapped once per bucket.

use glam::Vec3;

use crate::contract::{RAY_BYTES, RayRec};
use crate::rtl::{LinkCfg, Sim, SimOptions, Status, TraceStats, Tracer};
use crate::units::staging_buffer::{SbFill, SbHeader, SbRay, StagingBuffer, StagingBufferPorts};
use crate::units::tm::TmCfg;

use super::harness::{Driver, Sink, counter};
use super::{TbError, TbOptions, TbReport};

/// The buckets: (segment, rays).
pub const BUCKETS: [(u32, u32); 3] = [(11, 4), (12, 2), (13, 3)];
/// Rays a half holds.
pub const HALF_RAYS: u32 = 4;

/// What the bench runs (`tb`'s report and errors).
pub fn workload() -> String {
    let rays: Vec<String> = BUCKETS.iter().map(|(_, n)| n.to_string()).collect();
    format!(
        "a directed script: {} ray buckets ({} rays) through halves of {HALF_RAYS}",
        BUCKETS.len(),
        rays.join(", ")
    )
}

/// The header of segment `seg`'s bucket.
pub fn header(seg: u32) -> SbHeader {
    SbHeader {
        seg,
        base: 0x1000 * seg as u64,
        nodes: seg,
    }
}

/// The segment of ray `id` (rays are numbered over the buckets in order).
fn seg_of(id: u32) -> Option<u32> {
    let mut first = 0;
    for (seg, n) in BUCKETS {
        if id < first + n {
            return Some(seg);
        }
        first += n;
    }
    None
}

/// What each TP received, (cycle taken, ray), and the buffer's counters
/// (rays in, rays out, swaps), status cycles and the waveform's statistics.
pub struct StagingRun {
    pub tps: Vec<Vec<(u64, SbRay)>>,
    pub counts: (u64, u64, u64),
    pub status_cycles: [u64; 4],
    pub end: u64,
    pub trace: Option<TraceStats>,
}

/// The script under `sim_opts` on a `core_ps` clock, the TPs ready with
/// probability `ready_p` (patterns from `seed`), with a waveform if `tracer`.
pub fn script(
    sim_opts: SimOptions,
    ready_p: f64,
    seed: u64,
    core_ps: u64,
    tracer: Option<Tracer>,
) -> Result<StagingRun, TbError> {
    let mut sim = Sim::new(sim_opts);
    let clk = sim.clock("core", core_ps)?;
    let link = LinkCfg { depth: 2, delay: 1 };
    // A TP's ray link holds one ray (its next), as in the TM.
    let ray_link = LinkCfg { depth: 1, delay: 1 };
    let (fill_o, fill_i) = sim.link::<SbFill>("tb.fill", link);
    let (ray_o, ray_i) = sim.links::<SbRay>(2, |p| format!("tb.ray{p}"), ray_link);
    let cfg = TmCfg {
        tps: 2,
        staging_half_bytes: HALF_RAYS * RAY_BYTES,
        ..TmCfg::default()
    };
    let sb = sim.add(
        "tb.staging_buffer",
        clk,
        StagingBuffer::new(
            &cfg,
            StagingBufferPorts {
                fill: fill_i,
                ray: ray_o,
            },
        ),
    );
    let drv = sim.add("tb.fill_driver", clk, Driver::new(fill_o));
    let sinks: Vec<_> = ray_i
        .into_iter()
        .enumerate()
        .map(|(p, i)| {
            let s = Sink::new(i, ready_p, seed.wrapping_add(p as u64));
            sim.add(&format!("tb.tp{p}"), clk, s)
        })
        .collect();
    sim.elaborate()?;
    if let Some(t) = tracer {
        sim.attach_tracer(t)?;
    }
    let mut id = 0u32;
    for (seg, n) in BUCKETS {
        for k in 0..n {
            let ray = RayRec {
                origin: Vec3::new(id as f32, 0.0, 0.0),
                dir: Vec3::Z,
                ray_id: id,
                entry: 0,
            };
            let fill = SbFill {
                ray,
                hdr: header(seg),
                last: k + 1 == n,
            };
            sim.unit_mut::<Driver<SbFill>>(drv).send(1, fill);
            id += 1;
        }
    }
    sim.wake(drv);
    let end = sim.run_to_idle(10_000 * core_ps)?;
    let st = sim.unit_stats(sb);
    let c = |n: &str| counter(&st, n);
    let tps = sinks
        .iter()
        .map(|&s| sim.unit_ref::<Sink<SbRay>>(s).got.clone())
        .collect();
    let trace = super::harness::close_trace(&mut sim)?;
    Ok(StagingRun {
        tps,
        counts: (c("rays_in"), c("rays_out"), c("swaps")),
        status_cycles: st.status_cycles,
        end: end / core_ps,
        trace,
    })
}

/// What the script owes, as errors (none: it passed).
pub fn check(r: &StagingRun) -> Vec<String> {
    let mut errors = Vec::new();
    let total: u32 = BUCKETS.iter().map(|b| b.1).sum();
    let mut all = Vec::new();
    for (p, got) in r.tps.iter().enumerate() {
        let ids: Vec<u32> = got.iter().map(|(_, x)| x.ray.ray_id).collect();
        if !ids.windows(2).all(|w| w[0] < w[1]) {
            errors.push(format!("TP {p} got rays out of fill order: {ids:?}"));
        }
        for (_, x) in got {
            let i = x.ray.ray_id;
            if x.ray.origin.x != i as f32 {
                errors.push(format!("TP {p}: ray {i} carries another ray's data"));
            }
            match seg_of(i) {
                Some(seg) if x.hdr == header(seg) => {}
                _ => errors.push(format!(
                    "TP {p}: ray {i} came with segment {}'s header",
                    x.hdr.seg
                )),
            }
        }
        all.extend(ids);
    }
    all.sort_unstable();
    if all != (0..total).collect::<Vec<_>>() {
        errors.push(format!("rays out {all:?}: want each of 0..{total} once"));
    }
    let n = total as u64;
    if r.counts != (n, n, BUCKETS.len() as u64) {
        errors.push(format!(
            "(rays in, rays out, swaps) {:?}: want ({n}, {n}, {})",
            r.counts,
            BUCKETS.len()
        ));
    }
    errors
}

/// `dualstream tb staging_buffer`: the script under `opts.sim` with the TPs
/// ready with probability `--ready` (seeded by `--seed`); `--cycles` and
/// `--load` do not apply.
pub fn run(opts: &TbOptions) -> Result<TbReport, TbError> {
    let tracer = match &opts.vcd {
        Some(path) => Some(Tracer::to_file(path, opts.trace.clone())?),
        None => None,
    };
    let r = script(
        opts.sim.clone(),
        opts.ready_p,
        opts.seed,
        opts.config.clocks.core_ps,
        tracer,
    )?;
    let (rays_in, rays_out, swaps) = r.counts;
    let mut rep = TbReport {
        unit: "staging_buffer",
        requests: rays_in,
        results: r.tps.iter().map(|t| t.len() as u64).sum(),
        cycles: r.end,
        min_latency: 0,
        max_latency: 0,
        stall_cycles: r.status_cycles[Status::OutputBlocked as usize],
        errors: check(&r),
        vcd_changes: 0,
        vcd_bytes: 0,
        status_cycles: r.status_cycles,
        counters: vec![("rays_out", rays_out), ("swaps", swaps)],
    };
    if let Some(s) = r.trace {
        rep.vcd_changes = s.changes;
        rep.vcd_bytes = s.bytes;
    }
    Ok(rep)
}
