//! A directed testbench of the memory unit with the `fixed` timing model (the
//! `gddr5` model's channels have their own bench, `mem_ctrl`): two ports, one
//! line per cycle, a masked write and reads.
//!
//! The script: port 0 writes bytes 0-3 and 9 of line `LINE_W` (a mask of five
//! bytes) and then reads that line; port 1 reads line `LINE_R`; all three are
//! offered in cycle 1. The unit accepts one line per cycle, round-robin from
//! `cycle mod ports`, so port 0's write in cycle 2, port 1's read in 3 and port
//! 0's read in 4, each answered `latency` cycles after it was accepted. The
//! write is answered with zeros; the read after it sees the five bytes written
//! and the others as the image held them. The script runs at two latencies, so
//! a latency that does not add up shows.

use crate::contract::{LINE_BYTES, SparseMem};
use crate::mem::StreamTag;
use crate::rtl::{LinkCfg, Sim, SimOptions, Status, TraceStats, Tracer};
use crate::units::l1::Line;
use crate::units::memory::{
    MemLineReq, MemLineResp, Memory, MemoryModel, MemoryPorts, MemoryProbe, MemoryUnitCfg,
};

use super::harness::{Driver, Sink};
use super::{TbError, TbOptions, TbReport};

/// The written line and the line only read.
pub const LINE_W: u64 = 0x1000;
pub const LINE_R: u64 = 0x1040;
/// The bytes of `LINE_W` the write's mask selects.
pub const MASKED: [usize; 5] = [0, 1, 2, 3, 9];
/// The latencies the script runs at.
pub const LATENCIES: [u32; 2] = [10, 30];

/// A line whose bytes name their offset (the image's content before the write).
pub fn pattern() -> Line {
    Line(std::array::from_fn(|k| k as u8))
}

/// What the ports received, (cycle taken, response) each, and the unit's
/// counters, status cycles and the waveform's statistics.
pub struct MemoryRun {
    pub port0: Vec<(u64, MemLineResp)>,
    pub port1: Vec<(u64, MemLineResp)>,
    pub probe: MemoryProbe,
    pub status_cycles: [u64; 4],
    pub end: u64,
    pub trace: Option<TraceStats>,
}

/// The script at `latency` under `sim_opts` on a `core_ps` clock, with a
/// waveform if `tracer`.
pub fn script(
    sim_opts: SimOptions,
    latency: u32,
    core_ps: u64,
    tracer: Option<Tracer>,
) -> Result<MemoryRun, TbError> {
    let mut sim = Sim::new(sim_opts);
    let clk = sim.clock("core", core_ps)?;
    let link = LinkCfg { depth: 2, delay: 1 };
    let (req_o, req_i) = sim.links::<MemLineReq>(2, |p| format!("tb.req{p}"), link);
    let (resp_o, resp_i) = sim.links::<MemLineResp>(2, |p| format!("tb.resp{p}"), link);
    let mut image = SparseMem::new(1 << 20);
    image.write(LINE_W, &pattern().0);
    image.write(LINE_R, &pattern().0);
    let cfg = MemoryUnitCfg {
        model: MemoryModel::Fixed,
        latency,
        bytes_per_cycle: LINE_BYTES as u32,
        check_timing: false,
    };
    let mem = sim.add(
        "tb.memory",
        clk,
        Memory::new(
            &cfg,
            link.delay,
            image,
            MemoryPorts {
                req: req_i,
                resp: resp_o,
                ch_req: Vec::new(),
                ch_resp: Vec::new(),
            },
        ),
    );
    let drivers: Vec<_> = req_o
        .into_iter()
        .enumerate()
        .map(|(p, o)| sim.add(&format!("tb.port{p}"), clk, Driver::new(o)))
        .collect();
    let sinks: Vec<_> = resp_i
        .into_iter()
        .enumerate()
        .map(|(p, i)| sim.add(&format!("tb.sink{p}"), clk, Sink::new(i, 1.0, 0)))
        .collect();
    sim.elaborate()?;
    if let Some(t) = tracer {
        sim.attach_tracer(t)?;
    }
    let mask = MASKED.iter().fold(0u64, |m, &k| m | 1 << k);
    let write = MemLineReq {
        addr: LINE_W,
        write: true,
        tag: StreamTag::Hit,
        id: 1,
        mask,
        data: Line([0xAA; 64]),
    };
    let d0 = sim.unit_mut::<Driver<MemLineReq>>(drivers[0]);
    d0.send(1, write);
    d0.send(1, MemLineReq::read(LINE_W, StreamTag::Hit, 2));
    let d1 = sim.unit_mut::<Driver<MemLineReq>>(drivers[1]);
    d1.send(1, MemLineReq::read(LINE_R, StreamTag::Scene, 3));
    for &d in &drivers {
        sim.wake(d);
    }
    let end = sim.run_to_idle(1000 * core_ps)?;
    let got = |s| sim.unit_ref::<Sink<MemLineResp>>(s).got.clone();
    let (port0, port1) = (got(sinks[0]), got(sinks[1]));
    let probe = sim.unit_ref::<Memory>(mem).probe();
    let status_cycles = sim.unit_stats(mem).status_cycles;
    let trace = super::harness::close_trace(&mut sim)?;
    Ok(MemoryRun {
        port0,
        port1,
        probe,
        status_cycles,
        end: end / core_ps,
        trace,
    })
}

/// What the script owes at `latency`, as errors (none: it passed).
pub fn check(r: &MemoryRun, latency: u32) -> Vec<String> {
    let l = latency as u64;
    let mut errors = Vec::new();
    let when = |v: &[(u64, MemLineResp)]| -> Vec<(u64, u32)> {
        v.iter().map(|(c, r)| (*c, r.id)).collect()
    };
    for (port, have, want) in [
        (0, when(&r.port0), vec![(2 + l, 1), (4 + l, 2)]),
        (1, when(&r.port1), vec![(3 + l, 3)]),
    ] {
        if have != want {
            errors.push(format!(
                "latency {latency}, port {port}: got (cycle, id) {have:?}, want {want:?}"
            ));
        }
    }
    let mut written = pattern();
    for k in MASKED {
        written.0[k] = 0xAA;
    }
    let data = |v: &[(u64, MemLineResp)], k: usize| v.get(k).map(|(_, x)| x.data.clone());
    if r.port0
        .first()
        .is_some_and(|(_, x)| !x.write || x.data != Line::default())
    {
        errors.push(format!(
            "latency {latency}: the write's answer is not a write of zeros"
        ));
    }
    if data(&r.port0, 1) != Some(written) {
        errors.push(format!(
            "latency {latency}: the read after the masked write got {:?}",
            data(&r.port0, 1)
        ));
    }
    if data(&r.port1, 0) != Some(pattern()) {
        errors.push(format!(
            "latency {latency}: port 1's read got {:?}",
            data(&r.port1, 0)
        ));
    }
    let p = &r.probe;
    let lines = (
        p.lines_written[StreamTag::Hit as usize],
        p.lines_read[StreamTag::Hit as usize],
        p.lines_read[StreamTag::Scene as usize],
    );
    if (p.requests, p.responses, p.in_flight) != (3, 3, 0) || lines != (1, 1, 1) {
        errors.push(format!(
            "latency {latency}: {} requests, {} responses, {} in flight, (hit written, hit read, scene read) {lines:?}: want 3, 3, 0 and (1, 1, 1)",
            p.requests, p.responses, p.in_flight
        ));
    }
    errors
}

/// `dualstream tb memory`: the script at each latency of [`LATENCIES`] under
/// `opts.sim`, the first with a waveform if asked. The stimulus is directed:
/// `--cycles`, `--load` and `--ready` do not apply.
pub fn run(opts: &TbOptions) -> Result<TbReport, TbError> {
    let mut rep = TbReport {
        unit: "memory",
        requests: 0,
        results: 0,
        cycles: 0,
        min_latency: LATENCIES[0] as u64,
        max_latency: LATENCIES[1] as u64,
        stall_cycles: 0,
        errors: Vec::new(),
        vcd_changes: 0,
        vcd_bytes: 0,
        status_cycles: [0; 4],
        counters: Vec::new(),
    };
    for (k, latency) in LATENCIES.into_iter().enumerate() {
        let tracer = match (&opts.vcd, k) {
            (Some(path), 0) => Some(Tracer::to_file(path, opts.trace.clone())?),
            _ => None,
        };
        // The first run alone is traced and captured.
        let sim = crate::rtl::SimOptions {
            capture: opts.sim.capture.clone().filter(|_| k == 0),
            ..opts.sim.clone()
        };
        let r = script(sim, latency, opts.config.clocks.core_ps, tracer)?;
        rep.errors.extend(check(&r, latency));
        rep.requests += r.probe.requests;
        rep.results += (r.port0.len() + r.port1.len()) as u64;
        rep.cycles += r.end;
        rep.stall_cycles += r.status_cycles[Status::OutputBlocked as usize];
        for (a, b) in rep.status_cycles.iter_mut().zip(r.status_cycles) {
            *a += b;
        }
        if let Some(s) = r.trace {
            rep.vcd_changes = s.changes;
            rep.vcd_bytes = s.bytes;
        }
    }
    Ok(rep)
}
