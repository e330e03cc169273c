//! The memory controller testbench: driver -> `mem_ctrl` (one channel, DRAM
//! clock) -> sink, through registered links with their protocol monitors.
//!
//! Checks: every request gets exactly one response with its id, tag and
//! direction; the recorded DRAM command stream passes the independent timing
//! checker; latencies are at least the DRAM's minimum. Directed timing cases
//! (open-row hit, row conflict, tFAW, refresh) are in `tests/mem.rs` and use
//! `MemTb` directly.

use crate::testbench::TbError;
use std::collections::HashMap;

use crate::config::Config;
use crate::mem::checker;
use crate::mem::{AddrMap, Command, Loc, MemCfg, StreamTag};
use crate::rtl::{LinkId, Sim, SimOptions, Tracer, UnitId};
use crate::units::mem_ctrl::{MemCtrl, MemCtrlPorts, MemReq, MemResp};
use crate::util::rng::Rng;

use super::harness::{Driver, Sink};
use super::pipe_tb::{TbOptions, TbReport};

/// A driver, one channel controller and a sink on the DRAM clock.
pub struct MemTb {
    pub sim: Sim,
    pub driver: UnitId,
    pub dut: UnitId,
    pub sink: UnitId,
    pub req_link: LinkId,
    pub resp_link: LinkId,
    pub cfg: MemCfg,
    pub map: AddrMap,
    pub tck_ps: u64,
}

impl MemTb {
    /// Channel 0 of `cfg.mem`; the sink is ready with probability `ready_p`.
    pub fn new(cfg: &Config, opts: SimOptions, ready_p: f64, seed: u64) -> Result<MemTb, TbError> {
        // Only the memory system and its clock are used (a device preset may be
        // swapped in without a matching DRAM image, `memory`).
        cfg.mem.validate()?;
        MemCtrl::supports(&cfg.mem)?;
        let m = cfg.mem.clone();
        let tck = cfg.clocks.dram_ps;
        let mut sim = Sim::new(opts);
        let clk = sim.clock("dram", tck)?;
        let (ro, ri) = sim.link::<MemReq>("mem.req", m.ctrl.req_link);
        let (po, pi) = sim.link::<MemResp>("mem.resp", m.ctrl.resp_link);
        let driver = sim.add("tb.driver", clk, Driver::new(ro));
        let dut = sim.add(
            "tb.mem_ctrl",
            clk,
            MemCtrl::new(&m, tck, 0, MemCtrlPorts { req: ri, resp: po }),
        );
        let sink = sim.add("tb.sink", clk, Sink::new(pi, ready_p, seed));
        sim.elaborate()?;
        // After elaboration (its reset keeps the setting from then on).
        sim.unit_mut::<MemCtrl>(dut).ctrl.record_commands(true);
        sim.log_link(ro.id, true);
        let map = AddrMap::new(&m.geometry, &m.mapping)?;
        Ok(MemTb {
            sim,
            driver,
            dut,
            sink,
            req_link: ro.id,
            resp_link: po.id,
            cfg: m,
            map,
            tck_ps: tck,
        })
    }

    /// The address of a line of channel 0.
    pub fn addr(&self, bank_group: u32, bank: u32, row: u32, column: u32) -> u64 {
        self.map.encode(&Loc {
            channel: 0,
            bank_group,
            bank,
            row,
            column,
        })
    }

    /// Queues a request for the driver to push at cycle `at` or later.
    pub fn send(&mut self, at: u64, addr: u64, write: bool, tag: StreamTag, id: u32) {
        self.sim.unit_mut::<Driver<MemReq>>(self.driver).send(
            at,
            MemReq {
                addr,
                write,
                tag,
                id,
            },
        );
        self.sim.wake(self.driver);
    }

    pub fn run_to_idle(&mut self, limit_cycles: u64) -> Result<u64, TbError> {
        let t = self.sim.run_to_idle(limit_cycles * self.tck_ps)?;
        Ok(t / self.tck_ps)
    }

    /// Responses as (cycle seen by the sink, response).
    pub fn received(&self) -> &[(u64, MemResp)] {
        &self.sim.unit_ref::<Sink<MemResp>>(self.sink).got
    }

    /// Every DRAM command issued up to `end` (refreshes of idle time included).
    pub fn commands(&self, end: u64) -> Vec<Command> {
        self.sim
            .unit_ref::<MemCtrl>(self.dut)
            .ctrl
            .commands_until(end)
    }

    pub fn check_timing(&self, end: u64) -> Vec<String> {
        checker::check(
            &self.commands(end),
            &self.cfg.timing,
            &self.cfg.geometry,
            end,
        )
    }
}

/// Random reads and writes to channel 0 with back-pressure (`dualstream tb mem_ctrl`).
pub fn run_random(opts: &TbOptions) -> Result<TbReport, TbError> {
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
    let mut tb = MemTb::new(&opts.config, opts.sim.clone(), opts.ready_p, opts.seed)?;
    if let Some(path) = &opts.vcd {
        let tracer = Tracer::to_file(path, opts.trace.clone())?;
        tb.sim.attach_tracer(tracer)?;
    }
    let g = tb.cfg.geometry.clone();
    let mut rng = Rng::new(opts.seed);
    let mut sent = HashMap::new();
    let mut id = 0u32;
    // A few hot rows make hits, misses and conflicts all likely.
    let rows: Vec<u32> = (0..4).map(|_| rng.below(g.rows as u64) as u32).collect();
    for c in 0..opts.cycles {
        if !rng.chance(opts.load) {
            continue;
        }
        let addr = tb.addr(
            rng.below(g.bank_groups as u64) as u32,
            rng.below(g.banks_per_group as u64) as u32,
            rows[rng.below(rows.len() as u64) as usize],
            rng.below(g.lines_per_row()) as u32,
        );
        let write = rng.chance(0.3);
        let tag = StreamTag::ALL[rng.below(StreamTag::COUNT as u64) as usize];
        tb.send(c, addr, write, tag, id);
        sent.insert(id, (write, tag));
        id += 1;
    }
    let end = tb.run_to_idle(opts.cycles * 200 + 100_000)?;
    let mut errors = Vec::new();
    let mut seen = HashMap::new();
    let mut min_lat = u64::MAX;
    let mut max_lat = 0;
    let pushes: Vec<u64> = tb
        .sim
        .link_log(tb.req_link)
        .iter()
        .filter_map(|e| match e {
            crate::rtl::LinkEvent::Push { at, .. } => Some(*at / tb.tck_ps),
            _ => None,
        })
        .collect();
    for (c, r) in tb.received() {
        match sent.get(&r.id) {
            None => errors.push(format!("response with unknown id {}", r.id)),
            Some(&(w, t)) if w != r.write || t != r.tag => errors.push(format!(
                "response {} has write {} tag {:?}, request had {w} {t:?}",
                r.id, r.write, r.tag
            )),
            _ => {}
        }
        if seen.insert(r.id, *c).is_some() {
            errors.push(format!("two responses for id {}", r.id));
        }
        if let Some(&p) = pushes.get(r.id as usize) {
            let lat = c - p;
            min_lat = min_lat.min(lat);
            max_lat = max_lat.max(lat);
        }
    }
    if seen.len() != sent.len() {
        errors.push(format!(
            "{} requests sent, {} answered",
            sent.len(),
            seen.len()
        ));
    }
    // The shortest possible: a write to an open row (CWL + burst) plus the
    // request link and the cycle in the queue.
    let floor = (tb.cfg.timing.cwl + g.burst_cycles()) as u64;
    if min_lat != u64::MAX && min_lat < floor {
        errors.push(format!(
            "a response came {min_lat} cycles after its request, below CWL + burst = {floor}"
        ));
    }
    for v in tb.check_timing(end).into_iter().take(20) {
        errors.push(format!("timing: {v}"));
    }
    let st = tb.sim.unit_stats(tb.dut);
    let mut rep = TbReport {
        unit: "mem_ctrl",
        requests: sent.len() as u64,
        results: seen.len() as u64,
        cycles: end,
        min_latency: if min_lat == u64::MAX { 0 } else { min_lat },
        max_latency: max_lat,
        stall_cycles: st.status_cycles[2] + st.status_cycles[3],
        errors,
        vcd_changes: 0,
        vcd_bytes: 0,
        status_cycles: st.status_cycles,
        counters: vec![],
    };
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
