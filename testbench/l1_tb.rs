//! A directed L1 testbench: a line that comes back right behind a fill that
//! cannot be answered yet.
//!
//! The L1 answers a fill on `miss_resp` only when every waiting TP's response
//! link has room. A fill for a TP that is not taking its responses waits at the
//! head of `miss_resp`; a second line arriving behind it wakes the L1 when it
//! becomes visible, but the L1 cannot reach it then (one fill per cycle, in
//! order) and sleeps again. When the TP finally takes its response, the pop wakes
//! the L1, which answers the first fill — and must look again the next cycle,
//! although nothing wakes it: the second line's wake-up has passed
//! (`Ctx::holds_more`). Without that look the second line waits for whatever
//! wakes the L1 next: here port 0 taking its answer, a cycle late; with nothing
//! else going on, for ever.
//!
//! The script (per-port request drivers, a scripted line source on `miss_resp`,
//! one sink per response port, a sink on `miss_req`):
//! - port 0 misses on line A; the line comes back and its answer fills port 0's
//!   response link (one entry deep), whose sink is not ready until `ready_from`;
//! - port 0 then misses on line C and port 1 on line D (other banks);
//! - C and D come back on consecutive cycles, long before port 0 is ready.

use crate::rtl::{ClockId, LinkCfg, Sim, SimOptions, Status, TraceStats, Tracer, UnitId};
use crate::testbench::TbError;
use crate::units::l1::{L1, L1Ports, L1Req, L1Resp, Line};
use crate::units::tm::L1Cfg;

use super::harness::{Driver, Sink};
use super::{TbOptions, TbReport};

/// Lines A, C and D: consecutive lines, so three different banks.
pub const LINE_A: u64 = 0x1000;
pub const LINE_C: u64 = 0x1040;
pub const LINE_D: u64 = 0x1080;

/// When things happen (cycles).
#[derive(Clone, Copy, Debug)]
pub struct FillBehindCfg {
    /// Line A arrives on `miss_resp`.
    pub a_back: u64,
    /// Port 0 asks for C and port 1 for D.
    pub cd_asked: u64,
    /// C arrives on `miss_resp`, D the cycle after.
    pub c_back: u64,
    /// Port 0's sink takes responses from this cycle on.
    pub ready_from: u64,
}

impl Default for FillBehindCfg {
    fn default() -> Self {
        FillBehindCfg {
            a_back: 8,
            cd_asked: 12,
            c_back: 30,
            ready_from: 50,
        }
    }
}

/// What the ports received, with the cycle each response was taken.
#[derive(Clone, Debug, PartialEq)]
pub struct FillBehindRun {
    pub port0: Vec<(u64, u64, Line)>,
    pub port1: Vec<(u64, u64, Line)>,
    /// Line requests on `miss_req`, in order.
    pub miss_reqs: Vec<u64>,
    /// The L1's fills and accesses counters.
    pub fills: u64,
    pub accesses: u64,
    /// The cycle the run went idle.
    pub end: u64,
}

/// A line whose bytes name its address, so a response names what it carries.
pub fn line_of(addr: u64) -> Line {
    let mut l = [0u8; 64];
    for (k, b) in l.iter_mut().enumerate() {
        *b = (addr >> (8 * (k % 4))) as u8 ^ k as u8;
    }
    Line(l)
}

/// Runs the script on a two-port L1 under `sim` (sleeping, shadow, shuffled).
pub fn fill_behind_blocked_fill(
    sim_opts: SimOptions,
    b: FillBehindCfg,
) -> Result<FillBehindRun, TbError> {
    fill_behind(sim_opts, b, 1000, None).map(|(run, _, _)| run)
}

/// `dualstream tb l1`: the script under `opts.sim`, with a waveform if asked,
/// checked against the timing the L1 owes it (the report's errors say what
/// came late or twice). The stimulus is directed: `--cycles`, `--load` and
/// `--ready` do not apply.
pub fn run(opts: &TbOptions) -> Result<TbReport, TbError> {
    let b = FillBehindCfg::default();
    let tracer = match &opts.vcd {
        Some(path) => Some(Tracer::to_file(path, opts.trace.clone())?),
        None => None,
    };
    let (got, status_cycles, trace) =
        fill_behind(opts.sim.clone(), b, opts.config.clocks.core_ps, tracer)?;
    let r = b.ready_from;
    let mut errors = Vec::new();
    // Port 0 takes A when its sink starts; the freed link wakes the L1 the next
    // cycle, which answers C; D, behind it, goes the cycle after.
    let want0 = vec![
        (r, LINE_A, line_of(LINE_A)),
        (r + 2, LINE_C, line_of(LINE_C)),
    ];
    let want1 = vec![(r + 3, LINE_D, line_of(LINE_D))];
    for (port, have, want) in [(0, &got.port0, &want0), (1, &got.port1, &want1)] {
        if have != want {
            let when = |v: &Vec<(u64, u64, Line)>| -> Vec<(u64, u64)> {
                v.iter().map(|(c, a, _)| (*c, *a)).collect()
            };
            errors.push(format!(
                "port {port}: got (cycle, line) {:x?}, want {:x?}",
                when(have),
                when(want)
            ));
        }
    }
    let mut asked = got.miss_reqs.clone();
    asked.sort_unstable();
    if asked != [LINE_A, LINE_C, LINE_D] {
        errors.push(format!("misses {asked:x?}: want one per line (A, C, D)"));
    }
    if (got.fills, got.accesses) != (3, 3) {
        errors.push(format!(
            "{} fills and {} accesses: want 3 and 3",
            got.fills, got.accesses
        ));
    }
    let mut rep = TbReport {
        unit: "l1",
        requests: 3,
        results: (got.port0.len() + got.port1.len()) as u64,
        cycles: got.end,
        min_latency: 0,
        max_latency: 0,
        stall_cycles: status_cycles[Status::OutputBlocked as usize],
        errors,
        vcd_changes: 0,
        vcd_bytes: 0,
        status_cycles,
        counters: vec![("fills", got.fills), ("accesses", got.accesses)],
    };
    if let Some(s) = trace {
        rep.vcd_changes = s.changes;
        rep.vcd_bytes = s.bytes;
    }
    Ok(rep)
}

/// The script on a `core_ps` clock; with a tracer, its waveform. Returns the
/// run, the L1's status cycles and the waveform's statistics.
fn fill_behind(
    sim_opts: SimOptions,
    b: FillBehindCfg,
    core_ps: u64,
    tracer: Option<Tracer>,
) -> Result<(FillBehindRun, [u64; 4], Option<TraceStats>), TbError> {
    let mut sim = Sim::new(sim_opts);
    let clk: ClockId = sim.clock("core", core_ps)?;
    let link = LinkCfg { depth: 2, delay: 1 };
    // One entry deep: a single unread answer fills port 0's response link.
    let resp_link = LinkCfg { depth: 1, delay: 1 };
    let (req_o, req_i) = sim.links::<L1Req>(2, |p| format!("tb.req{p}"), link);
    let (resp_o, resp_i) = sim.links::<L1Resp>(2, |p| format!("tb.resp{p}"), resp_link);
    let (mq_o, mq_i) = sim.link::<L1Req>("tb.miss_req", link);
    let (mr_o, mr_i) = sim.link::<L1Resp>("tb.miss_resp", link);
    let cfg = L1Cfg::default();
    let l1 = sim.add(
        "tb.l1",
        clk,
        L1::new(
            &cfg,
            link.delay,
            L1Ports {
                req: req_i,
                resp: resp_o,
                miss_req: mq_o,
                miss_resp: mr_i,
            },
        ),
    );
    let drivers: Vec<UnitId> = req_o
        .into_iter()
        .enumerate()
        .map(|(p, o)| sim.add(&format!("tb.port{p}"), clk, Driver::new(o)))
        .collect();
    let sinks: Vec<UnitId> = resp_i
        .into_iter()
        .enumerate()
        .map(|(p, i)| {
            let from = if p == 0 { b.ready_from } else { 0 };
            sim.add(
                &format!("tb.sink{p}"),
                clk,
                Sink::new(i, 1.0, 0).ready_from(from),
            )
        })
        .collect();
    let lines = sim.add("tb.lines", clk, Driver::new(mr_o));
    let miss_sink = sim.add("tb.miss_sink", clk, Sink::new(mq_i, 1.0, 0));
    sim.elaborate()?;
    if let Some(t) = tracer {
        sim.attach_tracer(t)?;
    }
    let req = |a: u64| L1Req { addr: a };
    let resp = |a: u64| L1Resp {
        addr: a,
        line: line_of(a),
    };
    sim.unit_mut::<Driver<L1Req>>(drivers[0])
        .send(1, req(LINE_A));
    sim.unit_mut::<Driver<L1Req>>(drivers[0])
        .send(b.cd_asked, req(LINE_C));
    sim.unit_mut::<Driver<L1Req>>(drivers[1])
        .send(b.cd_asked, req(LINE_D));
    let l = sim.unit_mut::<Driver<L1Resp>>(lines);
    l.send(b.a_back, resp(LINE_A));
    l.send(b.c_back, resp(LINE_C));
    l.send(b.c_back + 1, resp(LINE_D));
    for &u in drivers.iter().chain([&lines]) {
        sim.wake(u);
    }
    let end = sim.run_to_idle(1000 * core_ps)?;
    let got = |s: UnitId| -> Vec<(u64, u64, Line)> {
        sim.unit_ref::<Sink<L1Resp>>(s)
            .got
            .iter()
            .map(|(c, r)| (*c, r.addr, r.line.clone()))
            .collect()
    };
    let st = sim.unit_stats(l1);
    let counter = |n: &str| {
        st.counters
            .iter()
            .find(|(k, _)| *k == n)
            .map_or(0, |&(_, v)| v)
    };
    let status_cycles = st.status_cycles;
    let run = FillBehindRun {
        port0: got(sinks[0]),
        port1: got(sinks[1]),
        miss_reqs: sim
            .unit_ref::<Sink<L1Req>>(miss_sink)
            .got
            .iter()
            .map(|(_, r)| r.addr)
            .collect(),
        fills: counter("fills"),
        accesses: counter("accesses"),
        end: end / core_ps,
    };
    let trace = super::harness::close_trace(&mut sim)?;
    Ok((run, status_cycles, trace))
}
