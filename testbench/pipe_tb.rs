//! The testbench for fixed-latency pipelined units (box pipe, triangle pipe,
//! divider): driver -> unit -> sink through two registered links, with a scoreboard.
//!
//! Checks, for every request:
//! - the output equals the pure reference function bit for bit, in order;
//! - acceptances are at least `interval` cycles apart, and exactly `interval` apart
//!   while requests are waiting and the output is not blocked (full throughput);
//! - the result is visible to the sink exactly `latency` cycles after acceptance
//!   plus the cycles the pipeline was frozen by back-pressure in between, and
//!   exactly `latency` when the sink is always ready;
//! - no link protocol violation, nothing lost or duplicated.

use crate::testbench::TbError;
use std::path::PathBuf;

use crate::config::Config;
use crate::rtl::PipeCfg;
use crate::rtl::bits::packed;
use crate::rtl::link::LinkEvent;
use crate::rtl::{
    In, LinkId, Out, Payload, Sim, SimOptions, Time, TraceSpec, Tracer, Unit, UnitId,
};
use crate::util::rng::Rng;

use super::harness::{Driver, Sink};

/// One kind of pipelined unit under test.
pub trait PipeKind {
    type Req: Payload;
    type Resp: Payload;
    type Dut: Unit;
    const NAME: &'static str;
    fn cfg(c: &Config) -> PipeCfg;
    fn build(cfg: &PipeCfg, out_delay: u32, req: In<Self::Req>, resp: Out<Self::Resp>)
    -> Self::Dut;
    fn reference(r: &Self::Req) -> Self::Resp;
    /// Hand-picked hard cases.
    fn directed() -> Vec<Self::Req>;
    /// Seeded random stimulus (including hard cases at some rate).
    fn random(rng: &mut Rng, tag: u16) -> Self::Req;
}

/// Testbench options (the CLI's `tb` flags).
#[derive(Clone, Debug)]
pub struct TbOptions {
    pub cycles: u64,
    pub seed: u64,
    /// Probability that the sink is ready in a cycle.
    pub ready_p: f64,
    /// Probability that the driver has a new request in a cycle.
    pub load: f64,
    pub vcd: Option<PathBuf>,
    pub trace: TraceSpec,
    pub sim: SimOptions,
    pub config: Config,
}

impl Default for TbOptions {
    fn default() -> Self {
        TbOptions {
            cycles: 10_000,
            seed: 1,
            ready_p: 0.8,
            load: 0.5,
            vcd: None,
            trace: TraceSpec::all(),
            sim: SimOptions::default(),
            config: Config::default(),
        }
    }
}

/// What a testbench run found.
#[derive(Clone, Debug, PartialEq)]
pub struct TbReport {
    pub unit: &'static str,
    pub requests: u64,
    pub results: u64,
    pub cycles: u64,
    pub min_latency: u64,
    pub max_latency: u64,
    pub stall_cycles: u64,
    pub errors: Vec<String>,
    pub vcd_changes: u64,
    pub vcd_bytes: u64,
    pub status_cycles: [u64; 4],
    /// Bench-specific measurements (merges, stalls, bank conflicts, ...).
    pub counters: Vec<(&'static str, u64)>,
}

impl TbReport {
    pub fn passed(&self) -> bool {
        self.errors.is_empty()
    }
}

impl std::fmt::Display for TbReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "testbench {}: {}",
            self.unit,
            if self.passed() { "PASS" } else { "FAIL" }
        )?;
        writeln!(
            f,
            "  requests {}  results {}  cycles {}",
            self.requests, self.results, self.cycles
        )?;
        // Only benches that time each request measure a latency.
        if self.max_latency > 0 {
            writeln!(
                f,
                "  latency min {} max {} (cycles, acceptance to visible result)",
                self.min_latency, self.max_latency
            )?;
        }
        writeln!(
            f,
            "  unit status cycles: busy {} wait_input {} output_blocked {} resource_busy {}",
            self.status_cycles[0],
            self.status_cycles[1],
            self.status_cycles[2],
            self.status_cycles[3]
        )?;
        if self.vcd_bytes > 0 {
            writeln!(
                f,
                "  waveform: {} changes, {} bytes",
                self.vcd_changes, self.vcd_bytes
            )?;
        }
        if !self.counters.is_empty() {
            let c: Vec<String> = self
                .counters
                .iter()
                .map(|(k, v)| format!("{k} {v}"))
                .collect();
            writeln!(f, "  {}", c.join("  "))?;
        }
        for e in self.errors.iter().take(20) {
            writeln!(f, "  ERROR {e}")?;
        }
        if self.errors.len() > 20 {
            writeln!(f, "  ... {} more errors", self.errors.len() - 20)?;
        }
        Ok(())
    }
}

/// A built bench: simulator with driver, unit under test and sink.
pub struct PipeTb<K: PipeKind> {
    pub sim: Sim,
    pub driver: UnitId,
    pub dut: UnitId,
    pub sink: UnitId,
    pub req_link: LinkId,
    pub resp_link: LinkId,
    pub cfg: PipeCfg,
    out_delay: u32,
    out_depth: u32,
    period: Time,
    _k: std::marker::PhantomData<K>,
}

impl<K: PipeKind> PipeTb<K> {
    pub fn new(
        config: &Config,
        sim_opts: SimOptions,
        ready_p: f64,
        seed: u64,
    ) -> Result<Self, TbError> {
        config.validate()?;
        let cfg = K::cfg(config);
        let link = config.links.tm;
        let mut sim = Sim::new(sim_opts);
        let clk = sim.clock("core", config.clocks.core_ps)?;
        let (req_out, req_in) = sim.link::<K::Req>("req", link);
        let (resp_out, resp_in) = sim.link::<K::Resp>("resp", link);
        let driver = sim.add("tb.driver", clk, Driver::new(req_out));
        let dut = sim.add(
            &format!("tb.{}", K::NAME),
            clk,
            K::build(&cfg, link.delay, req_in, resp_out),
        );
        let sink = sim.add("tb.sink", clk, Sink::new(resp_in, ready_p, seed ^ 0x5eed));
        sim.log_link(req_in.id, true);
        sim.log_link(resp_in.id, true);
        sim.elaborate()?;
        Ok(PipeTb {
            sim,
            driver,
            dut,
            sink,
            req_link: req_in.id,
            resp_link: resp_in.id,
            cfg,
            out_delay: link.delay,
            out_depth: link.depth,
            period: config.clocks.core_ps,
            _k: std::marker::PhantomData,
        })
    }

    /// Pokes a request to be driven at `cycle` or later.
    pub fn send(&mut self, cycle: u64, r: K::Req) {
        self.sim
            .unit_mut::<Driver<K::Req>>(self.driver)
            .send(cycle, r);
        self.sim.wake(self.driver);
    }

    pub fn received(&self) -> &[(u64, K::Resp)] {
        &self.sim.unit_ref::<Sink<K::Resp>>(self.sink).got
    }

    /// Steps until everything sent has come out (or `limit` cycles).
    pub fn run_to_idle(&mut self, limit_cycles: u64) -> Result<u64, TbError> {
        let t = self.sim.run_to_idle(limit_cycles * self.period)?;
        Ok(t / self.period)
    }

    /// Scoreboard over everything sent so far. `exact_latency`: the sink was always
    /// ready, so every latency must be exactly the configured one.
    pub fn check(&self, sent: &[K::Req], exact_latency: bool) -> TbReport {
        let mut errors = Vec::new();
        let got = self.received();
        if got.len() != sent.len() {
            errors.push(format!(
                "{} requests sent but {} results received",
                sent.len(),
                got.len()
            ));
        }
        for (i, (req, (_, resp))) in sent.iter().zip(got).enumerate() {
            let want = K::reference(req);
            if packed(&want) != packed(resp) {
                errors.push(format!(
                    "result {i}: got {resp:?}, reference says {want:?} for {req:?}"
                ));
            }
        }
        let p = self.period;
        let accepts: Vec<u64> = self
            .sim
            .link_log(self.req_link)
            .iter()
            .filter_map(|e| match e {
                LinkEvent::Pop { at } => Some(at / p),
                _ => None,
            })
            .collect();
        let resp_log = self.sim.link_log(self.resp_link);
        let pushes: Vec<(u64, u64)> = resp_log
            .iter()
            .filter_map(|e| match e {
                LinkEvent::Push { at, visible } => Some((at / p, visible / p)),
                _ => None,
            })
            .collect();
        let resp_pops: Vec<u64> = resp_log
            .iter()
            .filter_map(|e| match e {
                LinkEvent::Pop { at } => Some(at / p),
                _ => None,
            })
            .collect();
        let req_vis: Vec<u64> = self
            .sim
            .link_log(self.req_link)
            .iter()
            .filter_map(|e| match e {
                LinkEvent::Push { visible, .. } => Some(visible / p),
                _ => None,
            })
            .collect();
        let (lat, ii) = (self.cfg.latency as u64, self.cfg.interval as u64);
        let out_delay = self.out_delay as u64;
        let stages = lat - out_delay;
        for (i, w) in accepts.windows(2).enumerate() {
            if w[1] < w[0] + ii {
                errors.push(format!(
                    "accepted at cycles {} and {}: closer than the interval {ii}",
                    w[0], w[1]
                ));
            }
            // Full throughput: with the sink always ready the pipeline never freezes,
            // so a waiting request is taken as soon as the interval allows.
            if exact_latency && let Some(&v) = req_vis.get(i + 1) {
                let want = v.max(w[0] + ii);
                if w[1] != want {
                    errors.push(format!("request {} accepted at cycle {}, expected {want} (visible {v}, interval {ii})", i + 1, w[1]));
                }
            }
        }
        // Golden timing model of a frozen-on-stall pipeline: result i is ready
        // `stages` cycles after acceptance plus every cycle the pipeline was frozen
        // meanwhile (an older result waiting for room), and is pushed in the first
        // cycle from then on in which the output link has room at the start of the
        // cycle (pushes minus pops in earlier cycles below the depth).
        let depth = self.out_depth as i64;
        let room = |c: u64| {
            let pushed = pushes.iter().filter(|&&(q, _)| q < c).count() as i64;
            let popped = resp_pops.iter().filter(|&&q| q < c).count() as i64;
            pushed - popped < depth
        };
        let mut ready_at: Vec<u64> = Vec::new();
        let (mut min_l, mut max_l) = (u64::MAX, 0);
        for (i, (&a, &(q, vis))) in accepts.iter().zip(&pushes).enumerate() {
            let mut r = a + stages;
            for j in 0..i {
                let (rj, qj) = (ready_at[j], pushes[j].0);
                if qj > a && qj > rj {
                    r += qj - rj.max(a);
                }
            }
            let mut want = r;
            while !room(want) {
                want += 1;
            }
            ready_at.push(r);
            if q != want {
                errors.push(format!("result {i}: pushed at cycle {q}, the timing model says {want} (accepted {a}, ready {r})"));
            }
            let l = vis - a;
            min_l = min_l.min(l);
            max_l = max_l.max(l);
            if vis - q != out_delay {
                errors.push(format!(
                    "result {i}: link delay {} instead of {out_delay}",
                    vis - q
                ));
            }
            if exact_latency && l != lat {
                errors.push(format!(
                    "result {i}: visible {l} cycles after acceptance, not exactly the latency {lat}"
                ));
            }
        }
        if accepts.len() != pushes.len() {
            errors.push(format!(
                "{} acceptances but {} results pushed",
                accepts.len(),
                pushes.len()
            ));
        }
        let st = self.sim.unit_stats(self.dut);
        TbReport {
            unit: K::NAME,
            requests: sent.len() as u64,
            results: got.len() as u64,
            cycles: self.sim.now() / p,
            min_latency: if min_l == u64::MAX { 0 } else { min_l },
            max_latency: max_l,
            stall_cycles: st.status_cycles[2],
            errors,
            vcd_changes: 0,
            vcd_bytes: 0,
            status_cycles: st.status_cycles,
            counters: vec![],
        }
    }
}

/// The CLI testbench: directed cases first, then seeded random requests arriving
/// with probability `load` per cycle, a sink that is ready with probability
/// `ready_p`, run for `cycles` cycles of stimulus and then drained.
pub fn run_random<K: PipeKind>(opts: &TbOptions) -> Result<TbReport, TbError> {
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
    let mut tb = PipeTb::<K>::new(&opts.config, opts.sim.clone(), opts.ready_p, opts.seed)?;
    if let Some(path) = &opts.vcd {
        let tracer = Tracer::to_file(path, opts.trace.clone())?;
        tb.sim.attach_tracer(tracer)?;
    }
    let mut rng = Rng::new(opts.seed);
    let mut sent = Vec::new();
    let mut c = 0u64;
    for r in K::directed() {
        tb.send(c, r.clone());
        sent.push(r);
        c += 1;
    }
    while c < opts.cycles {
        if rng.chance(opts.load) {
            let r = K::random(&mut rng, sent.len() as u16);
            tb.send(c, r.clone());
            sent.push(r);
        }
        c += 1;
    }
    let limit = opts.cycles * 64 + 10_000;
    tb.run_to_idle(limit)?;
    let mut rep = tb.check(&sent, opts.ready_p >= 1.0);
    if (opts.vcd.is_some() || opts.sim.capture.is_some())
        && let Some(r) = tb.sim.finish_trace()
    {
        let st = r.map_err(|source| TbError::Vcd {
            what: "writing the VCD failed",
            source,
        })?;
        rep.vcd_changes = st.changes;
        rep.vcd_bytes = st.bytes;
    }
    Ok(rep)
}
