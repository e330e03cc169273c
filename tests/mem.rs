//! The memory system: timing checker on random traffic, streaming vs random
//! bandwidth, directed timing cases, bad input, and the unit == fast path check.

use dualstream::mem::config::{CtrlPolicy, MemCfg};
use dualstream::mem::replay::{ReplayOptions, replay};
use dualstream::mem::trace::{TraceReq, generate};

fn one_channel(mut m: MemCfg) -> MemCfg {
    m.geometry.channels = 1;
    m
}

fn run(m: &MemCfg, tck: u64, reqs: &[TraceReq]) -> dualstream::mem::MemReport {
    let r = replay(
        m,
        tck,
        reqs,
        &ReplayOptions {
            check: true,
            preset: "test".into(),
            ..ReplayOptions::default()
        },
    )
    .unwrap();
    r.report
}

#[test]
fn random_traffic_has_no_timing_violations() {
    for (m, tck) in [
        (one_channel(MemCfg::paper()), 500),
        (MemCfg::paper(), 500),
        (MemCfg::dramsim3_gddr5(), 667),
    ] {
        for (kind, wf) in [("random", 0.3), ("mixed", 0.0), ("stream", 0.5)] {
            let reqs = generate(kind, 6000, 7, &m, 0, wf).unwrap();
            let rep = run(&m, tck, &reqs);
            let v = rep.violations.as_ref().unwrap();
            assert!(
                v.is_empty(),
                "{kind}: {} violations: {:?}",
                v.len(),
                &v[..v.len().min(5)]
            );
            assert_eq!(rep.total.requests(), 6000);
            assert!(rep.total.refs > 0 || rep.cycles < m.timing.refi as u64);
            println!("{kind}\n{rep}");
        }
    }
}

/// The scheduler decides from per-bank queues; in debug builds (`cargo test`)
/// every decision is checked against the plain FR-FCFS scan over the whole queue
/// in age order (`ChannelCtrl::pick` panics on a difference). Run it where the
/// two could part: tiny queues and response buffer (the scan itself decides while
/// the buffer is full), frequent write drains, 16 banks in one group, the
/// flat-bank mapping, and throttled traffic with refreshes in idle time.
#[test]
fn scheduler_decisions_equal_the_plain_scan() {
    let mut small = one_channel(MemCfg::paper());
    small.ctrl.read_queue = 8;
    small.ctrl.write_queue = 12;
    small.ctrl.write_high = 8;
    small.ctrl.write_low = 3;
    small.ctrl.resp_buffer = 2;
    // DRAMsim3's device (16 banks in one group) under FR-FCFS.
    let mut flat = MemCfg::dramsim3_gddr5();
    flat.ctrl.policy = CtrlPolicy::Frfcfs;
    let mut map1 = one_channel(MemCfg::paper());
    map1.mapping = "row:bank:channel:column".into();
    for (m, tck) in [(small, 500), (flat, 667), (map1, 500)] {
        for (kind, wf, interval) in [("random", 0.3, 0), ("mixed", 0.0, 2), ("stream", 0.5, 0)] {
            let reqs = generate(kind, 3000, 3, &m, interval, wf).unwrap();
            let rep = run(&m, tck, &reqs);
            assert_eq!(rep.violations.as_ref().unwrap().len(), 0, "{kind}");
            assert_eq!(rep.total.requests(), 3000, "{kind}");
        }
    }
}

/// Unthrottled sequential reads on one channel of the paper's memory, spread
/// over bank groups by the default mapping, reach >= 90% of the channel's peak
/// with nearly every request a row hit; uniform random reads reach far less.
#[test]
fn streaming_reaches_peak_and_random_does_not() {
    for (m, tck) in [
        (one_channel(MemCfg::paper()), 500),
        (MemCfg::dramsim3_gddr5(), 667),
    ] {
        let stream = run(&m, tck, &generate("stream", 20_000, 1, &m, 0, 0.0).unwrap());
        let random = run(&m, tck, &generate("random", 5_000, 1, &m, 0, 0.0).unwrap());
        let s = stream.bandwidth_gbs() / stream.peak_gbs();
        let r = random.bandwidth_gbs() / random.peak_gbs();
        println!(
            "{}: stream {:.1}% of peak, hit rate {:.1}%; random {:.1}%, hit rate {:.1}%",
            m.mapping,
            100.0 * s,
            100.0 * stream.total.row_hit_rate(),
            100.0 * r,
            100.0 * random.total.row_hit_rate()
        );
        if m.geometry.line_bytes == 64 {
            assert!(s >= 0.90, "stream reached only {:.1}% of peak", 100.0 * s);
            assert!(stream.total.row_hit_rate() > 0.98);
        }
        assert!(r < 0.5 * s, "random {r} should be far below stream {s}");
        assert!(random.total.row_hit_rate() < 0.1);
    }
}

mod unit {

    use dualstream::config::Config;
    use dualstream::mem::replay::{ReplayOptions, replay};
    use dualstream::mem::trace::{TraceReq, generate};
    use dualstream::mem::{Command, DramCmd, StreamTag};
    use dualstream::rtl::{SimOptions, TraceSpec, Tracer};
    use dualstream::testbench::mem_ctrl_tb::MemTb;
    use dualstream::util::rng::Rng;

    fn tb(cfg: &Config) -> MemTb {
        MemTb::new(cfg, SimOptions::default(), 1.0, 1).unwrap()
    }
    fn got(tb: &MemTb, id: u32) -> u64 {
        tb.received().iter().find(|(_, r)| r.id == id).unwrap().0
    }
    fn cmds_after(tb: &MemTb, end: u64, from: u64, kind: DramCmd) -> Vec<Command> {
        tb.commands(end)
            .into_iter()
            .filter(|c| c.cycle >= from && c.kind == kind)
            .collect()
    }

    /// Pushed at `p`: visible and accepted at p + 1, first command at p + 2.
    const FIRST_CMD: u64 = 2;

    #[test]
    fn open_row_hit_returns_after_cl_plus_the_burst_and_a_conflict_costs_trp_trcd() {
        let cfg = Config::default();
        let m = &cfg.mem;
        let t = &m.timing;
        let (burst, bpl) = (
            m.geometry.burst_cycles() as u64,
            m.geometry.bursts_per_line() as u64,
        );
        // The bursts of one line go to one bank group: tCCD_L apart.
        let line = (bpl - 1) * (t.ccd_l as u64).max(burst) + t.cl as u64 + burst;
        let mut b = tb(&cfg);
        b.send(0, b.addr(0, 0, 5, 0), false, StreamTag::Ray, 0); // opens row 5
        b.send(1000, b.addr(0, 0, 5, 1), false, StreamTag::Ray, 1); // hit
        b.send(2000, b.addr(0, 0, 9, 0), false, StreamTag::Scene, 2); // conflict
        let end = b.run_to_idle(100_000).unwrap();
        let miss = FIRST_CMD + t.rcd_rd as u64 + line;
        assert_eq!(got(&b, 0), miss, "closed bank: ACT, tRCD, then the line");
        assert_eq!(got(&b, 1), 1000 + FIRST_CMD + line, "open row: CL + burst");
        let rd = cmds_after(&b, end, 1000, DramCmd::Rd);
        assert_eq!(got(&b, 1) - rd[0].cycle, line);
        assert_eq!(
            got(&b, 2) - 2000,
            FIRST_CMD + (t.rp + t.rcd_rd) as u64 + line,
            "conflict: PRE, tRP, ACT, tRCD, then the line"
        );
        let s = b.sim.unit_stats(b.dut);
        let count = |k: &str| s.counters.iter().find(|c| c.0 == k).unwrap().1;
        assert_eq!(
            (
                count("row_hits"),
                count("row_misses"),
                count("row_conflicts")
            ),
            (1, 1, 1)
        );
        assert!(b.check_timing(end).is_empty());
        // The same on DRAMsim3's device: one 128 B burst per line, CL + 2. The
        // unit schedules FR-FCFS: it refuses DRAMsim3's controller rules.
        let mut c2 = Config::default();
        let (mem, tck) = dualstream::mem::MemCfg::preset("dramsim3-gddr5").unwrap();
        c2.mem = mem;
        c2.clocks.dram_ps = tck;
        let e = MemTb::new(&c2, SimOptions::default(), 1.0, 1)
            .err()
            .unwrap();
        assert!(
            matches!(
                e,
                dualstream::testbench::TbError::Unit(dualstream::units::UnitError::Unsupported(_))
            ),
            "{e:?}"
        );
        let e = e.to_string();
        assert!(
            e.contains("policy = \"dramsim3\"") && e.contains("frfcfs"),
            "{e}"
        );
        c2.mem.ctrl.policy = dualstream::mem::config::CtrlPolicy::Frfcfs;
        let mut b = tb(&c2);
        b.send(0, b.addr(0, 0, 5, 0), false, StreamTag::Ray, 0);
        b.send(1000, b.addr(0, 0, 5, 1), false, StreamTag::Ray, 1);
        b.run_to_idle(100_000).unwrap();
        assert_eq!(got(&b, 1), 1000 + FIRST_CMD + 24 + 2);
    }

    #[test]
    fn tfaw_holds_the_fifth_activate() {
        let mut cfg = Config::default();
        cfg.mem.timing.faw = 50; // four tRRD gaps (40) no longer cover it
        let t = cfg.mem.timing.clone();
        let mut b = tb(&cfg);
        for i in 0..5u32 {
            b.send(
                i as u64,
                b.addr(i % 4, i / 4, 3, 0),
                false,
                StreamTag::Ray,
                i,
            );
        }
        let end = b.run_to_idle(100_000).unwrap();
        let acts: Vec<u64> = cmds_after(&b, end, 0, DramCmd::Act)
            .iter()
            .map(|c| c.cycle)
            .collect();
        assert_eq!(acts.len(), 5);
        for k in 1..4 {
            assert_eq!(acts[k] - acts[k - 1], t.rrd_s as u64, "tRRD between ACTs");
        }
        assert_eq!(acts[4] - acts[0], t.faw as u64, "the fifth waits for tFAW");
        assert!(b.check_timing(end).is_empty());
    }

    #[test]
    fn refresh_blocks_the_banks() {
        let cfg = Config::default();
        let t = &cfg.mem.timing;
        let refi = t.refi as u64;
        let mut b = tb(&cfg);
        b.send(0, b.addr(1, 2, 7, 0), false, StreamTag::Hit, 0); // row 7 stays open
        // Arrives as the refresh falls due: the open row is closed, REF issued,
        // and the request waits tRFC before it may activate again.
        b.send(
            refi - FIRST_CMD,
            b.addr(1, 2, 7, 1),
            false,
            StreamTag::Hit,
            1,
        );
        let end = b.run_to_idle(100_000).unwrap();
        let refs = cmds_after(&b, end, 0, DramCmd::Ref);
        let pre = cmds_after(&b, end, refi, DramCmd::Pre);
        let act = cmds_after(&b, end, refi, DramCmd::Act);
        assert_eq!(
            pre[0].cycle, refi,
            "the open bank is precharged when REF is due"
        );
        assert_eq!(refs[0].cycle, refi + t.rp as u64);
        assert_eq!(
            act[0].cycle,
            refs[0].cycle + t.rfc as u64,
            "no ACT before tRFC"
        );
        assert!(b.check_timing(end).is_empty());
    }

    /// Random stimulus with writes, bursts that fill the queues, and idle gaps
    /// longer than tREFI.
    fn stimulus(b: &mut MemTb, seed: u64, n: u32) {
        let g = b.cfg.geometry.clone();
        let mut rng = Rng::new(seed);
        let mut c = 0;
        for id in 0..n {
            c += match rng.below(10) {
                0 => 5000,
                1..=4 => 0,
                _ => rng.below(8),
            };
            let addr = b.addr(
                rng.below(g.bank_groups as u64) as u32,
                rng.below(g.banks_per_group as u64) as u32,
                rng.below(3) as u32,
                rng.below(g.lines_per_row()) as u32,
            );
            let tag = StreamTag::ALL[rng.below(5) as usize];
            b.send(c, addr, rng.chance(0.3), tag, id);
        }
    }

    #[test]
    fn sleeping_and_evaluation_order_change_nothing() {
        let cfg = Config::default();
        let run = |opts: SimOptions| {
            let mut b = MemTb::new(&cfg, opts, 0.6, 9).unwrap();
            let buf = dualstream::rtl::SharedBuf::default();
            b.sim
                .attach_tracer(Tracer::new(Box::new(buf.clone()), TraceSpec::all()).unwrap())
                .unwrap();
            stimulus(&mut b, 4, 600);
            let end = b.run_to_idle(1_000_000).unwrap();
            b.sim.finish_trace().unwrap().unwrap();
            let vcd = buf.0.lock().unwrap().clone();
            let hash = vcd.iter().fold(0xcbf29ce484222325u64, |h, &x| {
                (h ^ x as u64).wrapping_mul(0x100000001b3)
            });
            assert!(b.check_timing(end).is_empty());
            (
                end,
                b.sim.all_stats(),
                b.sim.link_stats(),
                b.commands(end),
                b.received().to_vec(),
                hash,
                vcd.len(),
            )
        };
        let base = run(SimOptions::default());
        assert_eq!(base.4.len(), 600);
        for opts in [
            SimOptions {
                sleep: false,
                shadow: false,
                shuffle_seed: None,
                threads: 1,
                auto_lanes: false,
                check_ready: true,
                capture: None,
            },
            SimOptions {
                sleep: false,
                shadow: true,
                shuffle_seed: None,
                threads: 1,
                auto_lanes: false,
                check_ready: true,
                capture: None,
            },
            SimOptions {
                sleep: true,
                shadow: false,
                shuffle_seed: Some(3),
                threads: 1,
                auto_lanes: false,
                check_ready: true,
                capture: None,
            },
        ] {
            assert!(run(opts.clone()) == base, "{opts:?} changed the outcome");
        }
    }

    /// A controller whose response link stalls with requests queued (its response
    /// buffer full, nothing to issue before the refresh deadline) and that then
    /// drains leaves no wake-up behind at the refresh deadline: the run ends
    /// within a read latency of the last response (it ended at tREFI, holding a
    /// chip's pass open, before the fix).
    #[test]
    fn a_stalled_controller_goes_idle_right_after_its_last_response() {
        let cfg = Config::default();
        let m = &cfg.mem;
        let n = m.ctrl.resp_buffer + m.ctrl.read_queue / 2;
        let mut b = MemTb::new(&cfg, SimOptions::default(), 0.05, 3).unwrap();
        for id in 0..n {
            let a = b.addr(id % 4, 0, 1, id / 4);
            b.send(0, a, false, StreamTag::Ray, id);
        }
        let end = b.run_to_idle(1_000_000).unwrap();
        assert_eq!(b.received().len(), n as usize);
        let last = b.received().iter().map(|r| r.0).max().unwrap();
        assert!(
            last < m.timing.refi as u64,
            "the stall must end before the refresh falls due ({last})"
        );
        let read = (m.timing.cl + m.geometry.burst_cycles()) as u64;
        assert!(
            end <= last + read,
            "idle at {end}, last response at {last}: a stale wake-up"
        );
    }

    /// The trace replay (the fast path) calls the controller directly; it must give
    /// the unit's cycles exactly: same commands, same completion times.
    #[test]
    fn replay_fast_path_equals_the_unit() {
        let cfg = Config::default();
        let mut b = tb(&cfg);
        let mut rng = Rng::new(5);
        let base = generate("mixed", 3000, 2, &cfg.mem, 0, 0.0).unwrap();
        let mut reqs = Vec::new();
        let mut c = 0;
        for (i, r) in base.iter().enumerate() {
            let mut l = b.map.decode(r.addr).unwrap();
            l.channel = 0;
            let addr = b.map.encode(&l);
            c += if rng.chance(0.01) { 6000 } else { rng.below(3) };
            b.send(c, addr, r.write, StreamTag::Other, i as u32);
            // The request link's delay: the unit sees it one cycle later.
            reqs.push(TraceReq {
                addr,
                write: r.write,
                cycle: c + cfg.mem.ctrl.req_link.delay as u64,
            });
        }
        let end = b.run_to_idle(10_000_000).unwrap();
        let r = replay(
            &cfg.mem,
            cfg.clocks.dram_ps,
            &reqs,
            &ReplayOptions {
                check: true,
                preset: "paper".into(),
                ..ReplayOptions::default()
            },
        )
        .unwrap();
        assert_eq!(r.report.violations.as_ref().unwrap().len(), 0);
        let unit_cmds = b.commands(end.max(r.report.cycles));
        let fast_cmds = &r.commands[0];
        assert_eq!(unit_cmds.len(), fast_cmds.len());
        assert!(unit_cmds == *fast_cmds, "command streams differ");
        let mut u: Vec<(u32, u64)> = b.received().iter().map(|(c, r)| (r.id, *c)).collect();
        let mut f = r.completions.clone();
        u.sort();
        f.sort();
        assert_eq!(u, f);
    }
}

#[test]
fn bad_configs_and_traces_are_named() {
    use dualstream::config::Config;
    let e = Config::from_toml("[mem.timing]\ntRC = 50\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("tRC = 50 < tRAS + tRP"), "{e}");
    let e = Config::from_toml("[mem.geometry]\nchannels = 0\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("channels = 0"), "{e}");
    let e = Config::from_toml("[mem.geometry]\nrows = 1000\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("power of two"), "{e}");
    let e = Config::from_toml("[mem]\nmapping = \"row:bank:chan:column\"\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("'chan'"), "{e}");
    let e = Config::from_toml("[mem.ctrl]\nwrite_low = 50\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("watermarks"), "{e}");
    let e = Config::from_toml("[mem.timing]\ntCL = 3\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("tCL"), "{e}");
    let e = Config::from_toml("[mem.ctrl]\npolicy = \"fifo\"\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("fifo") && e.contains("dramsim3"), "{e}");
    // DRAMsim3's rules: one burst per request, and a drain at a full buffer.
    let mut d3 = MemCfg::paper();
    d3.ctrl.policy = CtrlPolicy::Dramsim3;
    d3.ctrl.write_high = d3.ctrl.write_queue;
    let e = d3.validate().unwrap_err().to_string();
    assert!(
        e.contains("one burst per request") && e.contains("line_bytes = 32"),
        "{e}"
    );
    let mut d3 = MemCfg::dramsim3_gddr5();
    d3.ctrl.write_high = 16;
    let e = d3.validate().unwrap_err().to_string();
    assert!(
        e.contains("write_high = 16 must equal write_queue = 32"),
        "{e}"
    );
    // The DRAM image and the device agree on the row and the capacity.
    let d = Config::default();
    assert_eq!(d.memory.row_bytes, d.mem.geometry.row_bytes());
    assert_eq!(d.memory.capacity_bytes, d.mem.geometry.capacity());
    let e = Config::from_toml("[mem.geometry]\ncolumns = 128\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("memory.row_bytes = 8192") && e.contains("mem.geometry.columns"),
        "{e}"
    );
    let e = Config::from_toml("[mem.geometry]\nrows = 8192\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("memory.capacity_bytes") && e.contains("mem.geometry"),
        "{e}"
    );
    let half = Config::from_toml(&format!(
        "[mem.geometry]\nrows = {}\n[memory]\ncapacity_bytes = {}\n",
        d.mem.geometry.rows / 2,
        d.memory.capacity_bytes / 2
    ));
    assert!(half.is_ok(), "{:?}", half.err());
    let m = MemCfg::paper();
    let bad = [TraceReq {
        addr: m.geometry.capacity(),
        write: false,
        cycle: 0,
    }];
    let e = replay(&m, 500, &bad, &ReplayOptions::default())
        .err()
        .unwrap();
    assert!(matches!(e, dualstream::mem::MemError::Address(_)), "{e:?}");
    assert!(
        e.to_string().contains("beyond the configured capacity"),
        "{e}"
    );
}

/// The `dramsim3-gddr5` preset follows DRAMsim3's rules (`mem::dramsim3`); each
/// test here fails on the preset's FR-FCFS controller with four bank groups.
mod dramsim3 {
    use dualstream::mem::config::MemCfg;
    use dualstream::mem::replay::{ReplayOptions, Replayed, replay};
    use dualstream::mem::trace::{TraceReq, generate};
    use dualstream::mem::{AddrMap, DramCmd, Loc};

    fn preset() -> (MemCfg, u64) {
        MemCfg::preset("dramsim3-gddr5").unwrap()
    }
    fn checked(m: &MemCfg, tck: u64, reqs: &[TraceReq], every_cycle: bool) -> Replayed {
        let r = replay(
            m,
            tck,
            reqs,
            &ReplayOptions {
                check: true,
                preset: "dramsim3-gddr5".into(),
                every_cycle,
            },
        )
        .unwrap();
        let v = r.report.violations.as_ref().unwrap();
        assert!(v.is_empty(), "{:?}", &v[..v.len().min(5)]);
        r
    }
    fn at(m: &MemCfg, bank: u32, row: u32, column: u32) -> u64 {
        AddrMap::new(&m.geometry, &m.mapping).unwrap().encode(&Loc {
            channel: 0,
            bank_group: 0,
            bank,
            row,
            column,
        })
    }
    fn req(addr: u64, write: bool, cycle: u64) -> TraceReq {
        TraceReq { addr, write, cycle }
    }

    /// `bankgroup_enable = false` folds the ini's 4 x 4 banks into one group, and
    /// DRAMsim3 then applies tCCD_S between all column commands: row hits in one
    /// bank, in banks 0 and 1 (one of the ini's groups) and in banks 0 and 4
    /// (two of them) all go tCCD_S = 2 cycles apart, not tCCD_L = 3.
    #[test]
    fn column_commands_are_tccd_s_apart_in_every_bank() {
        let (m, tck) = preset();
        assert_eq!((m.geometry.bank_groups, m.geometry.banks()), (1, 16));
        for banks in [&[0u32][..], &[0, 1], &[0, 4]] {
            let n = banks.len();
            let reqs: Vec<TraceReq> = (0..48)
                .map(|i| req(at(&m, banks[i % n], 3, (i / n) as u32), false, 0))
                .collect();
            let r = checked(&m, tck, &reqs, false);
            let cmds = &r.commands[0];
            let last_act = cmds.iter().rfind(|c| c.kind == DramCmd::Act);
            let from = last_act.unwrap().cycle + m.timing.rcd_rd as u64;
            let rd: Vec<u64> = cmds
                .iter()
                .filter(|c| c.kind == DramCmd::Rd && c.cycle >= from)
                .map(|c| c.cycle)
                .collect();
            assert!(rd.len() >= 40, "{banks:?}: {} reads", rd.len());
            for w in rd.windows(2) {
                assert_eq!(w[1] - w[0], m.timing.ccd_s as u64, "{banks:?}: {rd:?}");
            }
        }
    }

    /// A write is acknowledged one cycle after the write buffer takes it (it is
    /// offered in cycle c, arrives in c + 1, acknowledged in c + 2), long before
    /// its WR; a read of a buffered write's address returns as fast, without a
    /// RD. Nine writes start a drain (more than 8 with nothing queued); eight
    /// stay in the buffer, unwritten, as in DRAMsim3.
    #[test]
    fn a_write_is_acknowledged_when_the_write_buffer_takes_it() {
        let (m, tck) = preset();
        for n in [9u64, 8] {
            let mut reqs: Vec<TraceReq> = (0..n)
                .map(|i| req(at(&m, i as u32, 1, 0), true, i))
                .collect();
            reqs.push(req(reqs[0].addr, false, n));
            let r = checked(&m, tck, &reqs, false);
            for &(id, cycle) in &r.completions {
                assert_eq!(cycle, reqs[id as usize].cycle + 2, "request {id}");
            }
            assert_eq!(r.completions.len() as u64, n + 1);
            let kinds = |k| r.commands[0].iter().filter(|c| c.kind == k).count() as u64;
            assert_eq!(kinds(DramCmd::Rd), 0, "the read is forwarded");
            let t = &r.report.total;
            assert_eq!((t.writes, t.reads), (n, 1));
            if n == 9 {
                assert_eq!(kinds(DramCmd::Wr), 9);
                let first_wr = r.commands[0].iter().find(|c| c.kind == DramCmd::Wr);
                assert!(first_wr.unwrap().cycle > 2 + m.timing.rcd_wr as u64);
            } else {
                assert_eq!(kinds(DramCmd::Wr), 0, "8 writes stay buffered");
            }
        }
    }

    /// Reads to one bank fill the 32-entry read queue and the bank's 8-entry
    /// command queue: 40 reads held, where one 32-entry queue holds 32.
    #[test]
    fn a_bank_queues_8_commands_behind_the_32_transactions() {
        let (m, tck) = preset();
        assert_eq!((m.ctrl.read_queue, m.ctrl.cmd_queue), (32, 8));
        let reqs: Vec<TraceReq> = (0..100).map(|i| req(at(&m, 5, i, 0), false, 0)).collect();
        let r = checked(&m, tck, &reqs, false);
        assert_eq!(r.report.total.rq_max, 40);
        assert_eq!(r.report.total.reads, 100);
        // Two banks: twice the command queues.
        let reqs: Vec<TraceReq> = (0..100)
            .map(|i| req(at(&m, 5 + i % 2, i, 0), false, 0))
            .collect();
        assert_eq!(checked(&m, tck, &reqs, false).report.total.rq_max, 48);
    }

    /// The controller sleeps until the next cycle at which a command may become
    /// legal or a transaction may move; evaluating every cycle instead changes
    /// nothing (report, commands, completions), with idle gaps beyond tREFI.
    #[test]
    fn sleeping_between_events_equals_evaluating_every_cycle() {
        let (m, tck) = preset();
        let mut small = m.clone();
        small.ctrl.read_queue = 6;
        small.ctrl.write_queue = 5;
        small.ctrl.write_high = 5;
        small.ctrl.write_low = 2;
        small.ctrl.cmd_queue = 2;
        for cfg in [&m, &small] {
            // The last: bursts of 40 requests 4500 cycles apart (> tREFI).
            for (kind, wf, n, interval) in [
                ("random", 0.3, 2000, 0),
                ("mixed", 0.0, 2000, 0),
                ("stream", 0.5, 2000, 0),
                ("random", 0.3, 400, 0),
            ] {
                let mut reqs = generate(kind, n, 5, &MemCfg::paper(), interval, wf).unwrap();
                if n == 400 {
                    for (i, r) in reqs.iter_mut().enumerate() {
                        r.cycle = (i as u64 / 40) * 4500;
                    }
                }
                let a = checked(cfg, tck, &reqs, false);
                let b = checked(cfg, tck, &reqs, true);
                assert!(a.report == b.report, "{kind}: reports differ");
                assert!(a.commands == b.commands, "{kind}: commands differ");
                assert_eq!(a.completions, b.completions, "{kind}");
                assert_eq!(a.report.total.requests(), n);
                assert!(a.report.total.refs > 0);
            }
        }
    }

    /// Traces made as `dualstream dram --generate random|stream` makes them (the
    /// default config: 64 B lines, seed 1) and replayed on the preset take the
    /// cycles DRAMsim3 takes on the same 1 M-request traces, per request
    /// (random 11,755,866 within 0.1%, stream about 2,092,000; random average
    /// read latency 1,313 cycles; docs/memory.md), within 2% on the first 50 K.
    #[test]
    fn replayed_traces_take_dramsim3s_cycles() {
        let (m, tck) = preset();
        let n = 50_000;
        for (kind, dramsim3_per_request, latency) in [
            ("random", 11_755_866.0 / 1e6, Some(1313.0)),
            ("stream", 2_092_000.0 / 1e6, None),
        ] {
            let reqs = generate(kind, n, 1, &MemCfg::paper(), 0, 0.0).unwrap();
            let r = replay(&m, tck, &reqs, &ReplayOptions::default())
                .unwrap()
                .report;
            let want = dramsim3_per_request * n as f64;
            let got = r.cycles as f64;
            println!("{kind}: {got} cycles, DRAMsim3 {want:.0}; {r}");
            assert!(
                (got / want - 1.0).abs() < 0.02,
                "{kind}: {got} cycles, DRAMsim3 {want:.0}"
            );
            if let Some(l) = latency {
                let mean = r.total.read_latency.mean();
                assert!((mean / l - 1.0).abs() < 0.05, "{kind}: read latency {mean}");
            }
        }
    }
}
