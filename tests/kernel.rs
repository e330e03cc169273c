//! The simulation kernel's contract: evaluation order and sleeping never change a
//! result (cycles, statistics, waveform), the link monitors catch protocol bugs,
//! shadow evaluation catches sleep bugs, and clock domains share one time base.

use dualstream::config::Config;
use dualstream::rtl::{
    Ctx, Declared, In, LinkCfg, Logic, Next, Out, Reg, RunEnd, Sim, SimError, SimOptions, Status,
    TraceSpec, Tracer,
};
use dualstream::testbench::{Driver, Sink};
use dualstream::units::box_pipe::{BoxPipe, BoxPipePorts, BoxReq};
use dualstream::units::divider::{DivReq, Divider, DividerPorts};
use dualstream::units::tri_pipe::{TriPipe, TriPipePorts, TriReq};
use dualstream::util::rng::Rng;
use glam::Vec3;

/// Everything a run produces that must not depend on evaluation order or sleeping.
#[derive(Debug, PartialEq)]
struct Outcome {
    end_ps: u64,
    stats: Vec<dualstream::rtl::UnitStats>,
    links: Vec<(String, dualstream::rtl::link::LinkStats)>,
    vcd_hash: u64,
    vcd_len: usize,
}

/// Two TMs' worth of shared units (box pipe, two triangle pipes, divider) with
/// drivers and back-pressuring sinks, a second clock domain, and random stimulus.
fn design(opts: SimOptions, seed: u64) -> Outcome {
    let cfg = Config::default();
    let mut sim = Sim::new(opts);
    let core = sim.clock("core", 1000).unwrap();
    let fast = sim.clock("dram", 500).unwrap();
    let link = cfg.links.tm;
    let mut rng = Rng::new(seed);
    let mut drivers = Vec::new();
    for tm in 0..2 {
        let (o, i) = sim.link::<BoxReq>(&format!("tm{tm}.box_req"), link);
        let (ro, ri) = sim.link(&format!("tm{tm}.box_resp"), link);
        let d = sim.add(&format!("chip.tm{tm}.box_driver"), core, Driver::new(o));
        sim.add(
            &format!("chip.tm{tm}.box_pipe"),
            core,
            BoxPipe::new(&cfg.box_pipe, link.delay, BoxPipePorts { req: i, resp: ro }),
        );
        sim.add(
            &format!("chip.tm{tm}.box_sink"),
            core,
            Sink::new(ri, 0.7, seed + tm),
        );
        drivers.push((d, 0));
        for k in 0..2 {
            let (o, i) = sim.link::<TriReq>(&format!("tm{tm}.tri{k}_req"), link);
            let (ro, ri) = sim.link(&format!("tm{tm}.tri{k}_resp"), link);
            let d = sim.add(&format!("chip.tm{tm}.tri_driver{k}"), core, Driver::new(o));
            sim.add(
                &format!("chip.tm{tm}.tri_pipe{k}"),
                core,
                TriPipe::new(&cfg.tri_pipe, link.delay, TriPipePorts { req: i, resp: ro }),
            );
            sim.add(
                &format!("chip.tm{tm}.tri_sink{k}"),
                core,
                Sink::new(ri, 0.5, seed * 7 + k),
            );
            drivers.push((d, 1));
        }
        // The divider's consumer runs on the 2 GHz clock: a cross-domain link.
        let (o, i) = sim.link::<DivReq>(&format!("tm{tm}.div_req"), link);
        let (ro, ri) = sim.link(&format!("tm{tm}.div_resp"), LinkCfg { depth: 3, delay: 2 });
        let d = sim.add(&format!("chip.tm{tm}.div_driver"), core, Driver::new(o));
        sim.add(
            &format!("chip.tm{tm}.divider"),
            core,
            Divider::new(&cfg.divider, 2, DividerPorts { req: i, resp: ro }),
        );
        sim.add(
            &format!("chip.tm{tm}.div_sink"),
            fast,
            Sink::new(ri, 0.3, seed ^ 99),
        );
        drivers.push((d, 2));
    }
    let buf = dualstream::rtl::SharedBuf::default();
    // Two threads: each TM's units on a thread of their own, except its sinks,
    // which run on the other thread (links between the threads), and no waveform
    // (a traced run uses one thread).
    let threads = sim.options().threads >= 2;
    if threads {
        for u in 0..sim.unit_count() {
            let id = dualstream::rtl::UnitId(u as u32);
            let path = sim.unit_path(id);
            let part = if path.starts_with("chip.tm0.") != path.contains("sink") {
                1
            } else {
                2
            };
            sim.set_part(id, part).unwrap();
        }
    } else {
        sim.attach_tracer(Tracer::new(Box::new(buf.clone()), TraceSpec::all()).unwrap())
            .unwrap();
    }
    for &(d, kind) in &drivers {
        for n in 0..60u64 {
            let at = rng.below(400);
            let p = Vec3::new(
                rng.range_f32(-2.0, 2.0),
                rng.range_f32(-2.0, 2.0),
                rng.range_f32(-2.0, 2.0),
            );
            match kind {
                0 => sim.unit_mut::<Driver<BoxReq>>(d).send(
                    at + n,
                    BoxReq {
                        origin: p * 3.0,
                        inv_dir: Vec3::ONE / (-p),
                        t_min: 0.0,
                        t_max: 100.0,
                        bmin: Vec3::splat(-1.0),
                        bmax: Vec3::splat(1.0),
                        tag: n as u16,
                    },
                ),
                1 => sim.unit_mut::<Driver<TriReq>>(d).send(
                    at + n,
                    TriReq {
                        origin: p * 3.0,
                        dir: -p,
                        t_min: 0.0,
                        t_max: 100.0,
                        v0: Vec3::new(-1.0, -1.0, 0.0),
                        v1: Vec3::new(1.0, -1.0, 0.0),
                        v2: Vec3::new(0.0, 1.0, 0.0),
                        tri_id: n as u32,
                        tag: n as u16,
                    },
                ),
                _ => sim.unit_mut::<Driver<DivReq>>(d).send(
                    at + n,
                    DivReq {
                        dir: p,
                        tag: n as u16,
                    },
                ),
            }
        }
        sim.wake(d);
    }
    sim.run_to_idle(10_000_000_000).expect("runs clean");
    if threads {
        assert!(
            sim.parallel_steps > 0,
            "two threads never evaluated in parallel"
        );
    } else {
        sim.finish_trace().unwrap().unwrap();
    }
    let vcd = buf.0.lock().unwrap().clone();
    Outcome {
        end_ps: sim.now(),
        stats: sim.all_stats(),
        links: sim.link_stats(),
        vcd_hash: dualstream::util::fnv1a(&vcd),
        vcd_len: vcd.len(),
    }
}

#[test]
fn order_and_sleeping_change_nothing() {
    let base = design(SimOptions::default(), 5);
    assert!(base.end_ps > 1_000_000, "the design did real work");
    assert!(base.vcd_len > 10_000);
    let modes = [
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
            shuffle_seed: Some(1),
            threads: 1,
            auto_lanes: false,
            check_ready: true,
            capture: None,
        },
        SimOptions {
            sleep: true,
            shadow: false,
            shuffle_seed: Some(2),
            threads: 1,
            auto_lanes: false,
            check_ready: true,
            capture: None,
        },
        SimOptions {
            sleep: false,
            shadow: true,
            shuffle_seed: Some(3),
            threads: 1,
            auto_lanes: false,
            check_ready: true,
            capture: None,
        },
    ];
    for m in modes {
        let o = design(m.clone(), 5);
        assert_eq!(o, base, "mode {m:?} changed the outcome");
    }
    // And the check has teeth: different stimulus gives a different outcome.
    assert_ne!(design(SimOptions::default(), 6).vcd_hash, base.vcd_hash);
}

// ---- deliberately broken units, to show the monitors catch them ----

dualstream::unit! {
    /// Pushes every cycle without looking at ready.
    pub struct Pusher : "pusher" {
        new(change_payload: bool, drop_valid: bool; ports: PusherPorts) {}
        params { }
        inputs { }
        outputs { out: u32 }
        state { n: Reg<u32> = 0 }
        extra { change_payload: bool = change_payload, drop_valid: bool = drop_valid }
    }
}

impl Logic for Pusher {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let n = self.n.val();
        if self.change_payload || self.drop_valid {
            // Offer n; when refused, misbehave on the next cycle.
            if self.drop_valid && n % 2 == 1 {
                self.n.set(n + 1);
                return Next::Cycle; // valid dropped while the link was stalled
            }
            // A new payload every cycle: changes a refused payload while stalled.
            ctx.offer(&self.out, n);
            self.n.set(n + 1);
        } else {
            ctx.push(&self.out, n);
            self.n.set(n + 1);
        }
        Next::Cycle
    }
}

dualstream::unit! {
    /// Never takes anything.
    pub struct Deaf : "deaf" {
        new(; ports: DeafPorts) {}
        params { }
        inputs { inp: u32 }
        outputs { }
        state { }
        extra { }
    }
}
impl Logic for Deaf {
    fn eval(&mut self, _ctx: &mut Ctx) -> Next {
        Next::Idle
    }
}

fn broken(change_payload: bool, drop_valid: bool) -> Result<RunEnd, SimError> {
    let mut sim = Sim::default();
    let c = sim.clock("core", 1000).unwrap();
    let (o, i) = sim.link::<u32>("l", LinkCfg { depth: 2, delay: 1 });
    sim.add(
        "p",
        c,
        Pusher::new(change_payload, drop_valid, PusherPorts { out: o }),
    );
    sim.add("d", c, Deaf::new(DeafPorts { inp: i }));
    sim.run(20_000)
}

#[test]
fn monitor_catches_push_into_full_link() {
    match broken(false, false) {
        Err(SimError::Protocol(v)) => assert!(v[0].what.contains("full"), "{v:?}"),
        other => panic!("expected a protocol violation, got {other:?}"),
    }
}

#[test]
fn monitor_catches_payload_change_while_stalled() {
    match broken(true, false) {
        Err(SimError::Protocol(v)) => assert!(v[0].what.contains("changed while stalled"), "{v:?}"),
        other => panic!("expected a protocol violation, got {other:?}"),
    }
}

#[test]
fn monitor_catches_valid_dropped_while_stalled() {
    match broken(false, true) {
        Err(SimError::Protocol(v)) => {
            assert!(v.iter().any(|x| x.what.contains("valid dropped")), "{v:?}")
        }
        other => panic!("expected a protocol violation, got {other:?}"),
    }
}

dualstream::unit! {
    /// Counts every evaluation but claims to be idle: a sleep bug.
    pub struct Sleeper : "sleeper" {
        new(; ports: SleeperPorts) {}
        params { }
        inputs { }
        outputs { }
        state { count: Reg<u32> = 0 }
        extra { }
    }
}
impl Logic for Sleeper {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        self.count.set(self.count.val() + 1);
        ctx.set_status(Status::Busy);
        Next::AtCycle(ctx.cycle() + 10)
    }
}

#[test]
fn shadow_evaluation_catches_a_sleep_bug() {
    let run = |shadow: bool| {
        let mut sim = Sim::new(SimOptions {
            sleep: !shadow,
            shadow,
            shuffle_seed: None,
            threads: 1,
            auto_lanes: false,
            check_ready: true,
            capture: None,
        });
        let c = sim.clock("core", 1000).unwrap();
        sim.add("s", c, Sleeper::new(SleeperPorts {}));
        sim.run(50_000)
    };
    assert!(
        matches!(run(false), Ok(RunEnd::Limit)),
        "without shadow the bug goes unnoticed"
    );
    match run(true) {
        Err(SimError::Shadow { unit, what, .. }) => {
            assert_eq!(unit, "s");
            assert!(what.contains("registers"), "{what}");
        }
        other => panic!("expected a shadow error, got {other:?}"),
    }
}

/// Two threads (one TM each, the sinks on the other thread) end at the same time
/// with the same statistics of every unit and link as one.
#[test]
fn two_threads_change_nothing() {
    let untraced = |o: Outcome| Outcome {
        vcd_hash: 0,
        vcd_len: 0,
        ..o
    };
    let base = untraced(design(SimOptions::default(), 5));
    let two = design(
        SimOptions {
            threads: 2,
            ..SimOptions::default()
        },
        5,
    );
    assert_eq!(two.vcd_len, 0);
    assert!(base == untraced(two), "two threads changed the outcome");
}

/// A well-behaved `Pusher` on `out`.
fn pusher(out: Out<u32>) -> Pusher {
    Pusher::new(false, false, PusherPorts { out })
}

#[test]
fn netlist_errors_are_named() {
    let mut sim = Sim::default();
    let c = sim.clock("core", 1000).unwrap();
    let (o, i) = sim.link::<u32>("l", LinkCfg::default());
    let p = sim.add("p", c, pusher(o));
    sim.add("d", c, Deaf::new(DeafPorts { inp: i }));
    assert!(
        sim.set_part(p, 3)
            .unwrap_err()
            .to_string()
            .contains("the partitions are 0 to 2")
    );

    let mut sim = Sim::default();
    let c = sim.clock("core", 1000).unwrap();
    let (o, _i) = sim.link::<u32>("dangling", LinkCfg::default());
    sim.add("p", c, pusher(o));
    let e = sim.run(1000).unwrap_err().to_string();
    assert!(e.contains("dangling") && e.contains("no consumer"), "{e}");

    let mut sim = Sim::default();
    let c = sim.clock("core", 1000).unwrap();
    let (o, i) = sim.link::<u32>("zero", LinkCfg { depth: 1, delay: 0 });
    sim.add("p", c, pusher(o));
    sim.add("d", c, Deaf::new(DeafPorts { inp: i }));
    let e = sim.run(1000).unwrap_err().to_string();
    assert!(e.contains("combinational"), "{e}");

    assert!(Sim::default().clock("bad", 0).is_err());
}

/// The waveform's refusals are told apart by variant: a filter that matches no
/// unit (a netlist error, the units listed) and a trace over its size limit.
#[test]
fn trace_refusals_are_variants() {
    use dualstream::rtl::TraceError;
    let traced = |spec: TraceSpec| {
        let mut sim = Sim::default();
        let c = sim.clock("core", 1000).unwrap();
        let (o, i) = sim.link::<u32>("l", LinkCfg::default());
        sim.add("p", c, pusher(o));
        sim.add("d", c, Deaf { inp: i });
        sim.attach_tracer(Tracer::new(Box::new(std::io::sink()), spec).unwrap())
    };
    let e = traced(TraceSpec {
        filter: "nosuch".into(),
        ..TraceSpec::all()
    })
    .unwrap_err();
    match &e {
        SimError::TraceBind(TraceError::NoUnit { filter, units }) => {
            assert_eq!(filter, "nosuch");
            assert_eq!(units, &["p", "d"]);
        }
        e => panic!("expected no unit matching, got {e:?}"),
    }
    assert!(
        e.to_string().starts_with("netlist error: no unit matches"),
        "{e}"
    );
    let e = traced(TraceSpec {
        to: 1_000_000_000,
        max_bytes: 1,
        ..TraceSpec::all()
    })
    .unwrap_err();
    assert!(
        matches!(e, SimError::Trace(TraceError::Oversized(_))),
        "{e:?}"
    );
    assert!(e.to_string().contains("over the limit of"), "{e}");
    assert!(traced(TraceSpec::all()).is_ok());
}

dualstream::unit! {
    /// Sends its cycle number once per `every` cycles.
    pub struct Ticker : "ticker" {
        /// `count` times.
        new(every: u64, count: u64; ports: TickerPorts) {}
        params { }
        inputs { }
        outputs { out: u64 }
        state { }
        extra { every: u64 = every, left: u64 = count }
    }
}
impl Logic for Ticker {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        if self.left == 0 {
            return Next::Idle;
        }
        if ctx.cycle().is_multiple_of(self.every) && ctx.can_push(&self.out) {
            ctx.push(&self.out, ctx.now());
            self.left -= 1;
        }
        Next::AtCycle((ctx.cycle() / self.every + 1) * self.every)
    }
}

#[test]
fn clock_domains_share_one_time_base() {
    // A 1.5 GHz-ish DRAM clock (tCK = 667 ps) feeding a 1 GHz consumer through a
    // 2-stage link: the payload is visible 2 producer cycles later and taken at the
    // consumer's first edge from then on.
    let mut sim = Sim::default();
    let dram = sim.clock("dram", 667).unwrap();
    let core = sim.clock("core", 1000).unwrap();
    let (o, i) = sim.link::<u64>("x", LinkCfg { depth: 4, delay: 2 });
    sim.add("t", dram, Ticker::new(3, 5, TickerPorts { out: o }));
    let s = sim.add("s", core, Sink::new(i, 1.0, 0));
    sim.run_to_idle(1_000_000).unwrap();
    let got = &sim.unit_ref::<Sink<u64>>(s).got;
    assert_eq!(got.len(), 5);
    for (cycle, sent_ps) in got {
        let visible = sent_ps + 2 * 667;
        assert_eq!(*cycle, visible.div_ceil(1000), "sent at {sent_ps} ps");
    }
}

#[test]
fn stall_counters_integrate_absolute_time() {
    // A pipeline fed once: busy for its latency, then waiting; the totals must add up
    // to the elapsed cycles however few times it was evaluated.
    let cfg = Config::default();
    let mut sim = Sim::default();
    let c = sim.clock("core", 1000).unwrap();
    let (o, i) = sim.link::<BoxReq>("req", cfg.links.tm);
    let (ro, ri) = sim.link("resp", cfg.links.tm);
    let d = sim.add("drv", c, Driver::new(o));
    let p = sim.add(
        "box",
        c,
        BoxPipe::new(&cfg.box_pipe, 1, BoxPipePorts { req: i, resp: ro }),
    );
    sim.add("sink", c, Sink::new(ri, 1.0, 0));
    let r = BoxReq {
        origin: Vec3::ZERO,
        inv_dir: Vec3::ONE,
        t_min: 0.0,
        t_max: 1.0,
        bmin: Vec3::ONE,
        bmax: Vec3::ONE,
        tag: 0,
    };
    sim.unit_mut::<Driver<BoxReq>>(d).send(0, r);
    sim.wake(d);
    sim.run(100_000).unwrap();
    let st = sim.unit_stats(p);
    assert_eq!(st.status_cycles.iter().sum::<u64>(), 100, "{st:?}");
    // Accepted at cycle 1, pushed at cycle 8 (latency 8 includes the link): busy 7.
    assert_eq!(st.status_cycles[0], 7, "{st:?}");
    assert!(
        sim.evals < 20,
        "sleeping units cost nothing: {} evaluations",
        sim.evals
    );
    let _ = Pusher::decl;
    let _: Option<In<u8>> = None;
    let _: Option<Out<u8>> = None;
}

dualstream::unit! {
    /// Pushes when there is room on cycles chosen by a hash of the cycle and its seed.
    pub struct Burst : "burst" {
        new(seed: u64; ports: BurstPorts) {}
        params { seed: u64 = seed => "SEED" }
        inputs { }
        outputs { out: u32 }
        state { }
        extra { }
    }
}
impl Logic for Burst {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let h = (c ^ self.seed).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 60;
        if h < 5 && ctx.can_push(&self.out) {
            ctx.push(&self.out, c as u32);
        }
        Next::Cycle
    }
}

dualstream::unit! {
    /// An arbiter's view of a port array: `visible_mask` / `visible_words` against
    /// `has_input` port by port; pops a pseudo-random subset so links fill and drain.
    pub struct MaskCheck : "mask_check" {
        new(; ports: MaskCheckPorts) {}
        params { }
        inputs { }
        outputs { }
        in_arrays { ins: u32 }
        state { }
        extra { mismatches: u64 = 0, seen_bits: u64 = 0, widest: u32 = 0 }
    }
}
impl Logic for MaskCheck {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let mut words = Vec::new();
        ctx.visible_words(&self.ins, &mut words);
        for (k, p) in self.ins.iter().enumerate() {
            let bit = words[k / 64] >> (k % 64) & 1 == 1;
            if bit != ctx.has_input(p) {
                self.mismatches += 1;
            }
        }
        if self.ins.len() <= 64 && ctx.visible_mask(&self.ins) != words[0] {
            self.mismatches += 1;
        }
        for (k, p) in self.ins.iter().enumerate() {
            if ctx.has_input(p) && !(c + k as u64).is_multiple_of(3) {
                ctx.pop(p);
                self.seen_bits += 1;
                self.widest = self.widest.max(k as u32 + 1);
            }
        }
        Next::Cycle
    }
}

/// The arbiters' bit masks (packed eight links per multiply) agree with `has_input`
/// on port arrays of every remainder, wider than a word, with entries in flight,
/// whether the array's links are consecutive (`PortArray::at` and the masks then
/// compute the links) or not (reversed: they read the ports).
#[test]
fn visible_masks_match_has_input() {
    for (n, reversed) in [1usize, 7, 8, 13, 16, 23, 64, 130]
        .into_iter()
        .flat_map(|n| [(n, false), (n, true)])
    {
        let mut sim = Sim::new(SimOptions::default());
        let c = sim.clock("core", 1000).unwrap();
        let mut ins = Vec::new();
        for k in 0..n {
            let (o, i) = sim.link::<u32>(&format!("l{k}"), LinkCfg { depth: 4, delay: 2 });
            sim.add(
                &format!("b{k}"),
                c,
                Burst::new(k as u64 * 77 + n as u64, BurstPorts { out: o }),
            );
            ins.push(i);
        }
        if reversed {
            ins.reverse();
        }
        // The unit's port array, as `MaskCheck::new` makes it.
        let arr: dualstream::rtl::PortArray<_> = ins.clone().into();
        assert_eq!(arr.consecutive_from().is_some(), !reversed || n == 1);
        for k in 0..n {
            assert_eq!(arr.at(k).id, arr[k].id);
        }
        let id = sim.add("check", c, MaskCheck::new(MaskCheckPorts { ins }));
        sim.run(3_000_000).unwrap();
        let u = dualstream::rtl::unit::downcast_ref::<MaskCheck>(sim.unit(id)).unwrap();
        assert_eq!(u.mismatches, 0, "{n} ports, reversed {reversed}");
        assert!(
            u.seen_bits > 100 * n as u64,
            "{n} ports: too few entries taken"
        );
        assert_eq!(u.widest as usize, n, "{n} ports: the last port never seen");
    }
}

dualstream::unit! {
    /// Sends one request at cycle 2 and waits for its answer: asleep from the
    /// next cycle on (`ahead`), or looking once more in the next cycle to say it
    /// waits, as a unit without `set_status_from_next` would.
    pub struct Asker : "asker" {
        new(ahead: bool; ports: AskerPorts) {}
        params { }
        inputs { resp: u64 }
        outputs { req: u64 }
        state { }
        extra { ahead: bool = ahead, sent: bool = false }
    }
}
impl Logic for Asker {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        if !self.sent {
            if ctx.cycle() < 2 {
                ctx.set_status(Status::WaitInput);
                return Next::AtCycle(2);
            }
            ctx.push(&self.req, ctx.cycle());
            self.sent = true;
            ctx.set_status(Status::Busy);
            if self.ahead {
                ctx.set_status_from_next(Status::ResourceBusy);
                return Next::Idle;
            }
            return Next::Cycle;
        }
        if ctx.pop(&self.resp).is_some() {
            ctx.set_status(Status::WaitInput);
        } else if ctx.cycle() > 0 {
            ctx.set_status(Status::ResourceBusy);
        }
        Next::Idle
    }
}

dualstream::unit! {
    /// Answers every request as it arrives.
    pub struct Echo : "echo" {
        new(; ports: EchoPorts) {}
        params { }
        inputs { inp: u64 }
        outputs { out: u64 }
        state { }
        extra { }
    }
}
impl Logic for Echo {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        if ctx.has_input(&self.inp) && ctx.can_push(&self.out) {
            let v = ctx.pop(&self.inp).unwrap();
            ctx.push(&self.out, v);
        }
        Next::Idle
    }
}

#[test]
fn a_status_from_the_next_cycle_counts_as_an_evaluation_then_would() {
    // Two askers, one sleeping through its wait with the status declared ahead,
    // one evaluated in the next cycle to declare it: their status cycles must be
    // the same whenever they are read (also in the cycle of the request, before
    // the status ahead begins), and the sleeper must pass the shadow check.
    for opts in [
        SimOptions::default(),
        SimOptions {
            sleep: false,
            shadow: true,
            ..SimOptions::default()
        },
    ] {
        let mut sim = Sim::new(opts);
        let c = sim.clock("core", 1000).unwrap();
        let mut askers = Vec::new();
        for ahead in [true, false] {
            let (qo, qi) = sim.link::<u64>(&format!("req{ahead}"), LinkCfg { depth: 2, delay: 3 });
            let (ro, ri) = sim.link::<u64>(&format!("resp{ahead}"), LinkCfg { depth: 2, delay: 2 });
            let a = sim.add(
                &format!("asker{ahead}"),
                c,
                Asker::new(ahead, AskerPorts { resp: ri, req: qo }),
            );
            sim.add(
                &format!("echo{ahead}"),
                c,
                Echo::new(EchoPorts { inp: qi, out: ro }),
            );
            askers.push(a);
        }
        for cycle in 0..12u64 {
            sim.run(cycle * 1000).unwrap();
            let (a, b) = (sim.unit_stats(askers[0]), sim.unit_stats(askers[1]));
            assert_eq!(a.status_cycles, b.status_cycles, "cycle {cycle}");
            assert_eq!(a.status_cycles.iter().sum::<u64>(), cycle, "{a:?}");
        }
        // Sent at 2, seen by the echo at 5, answered, seen at 7: busy in cycle 2,
        // waiting for the answer in cycles 3-6.
        let st = sim.unit_stats(askers[0]).status_cycles;
        assert_eq!(st[Status::Busy as usize], 1, "{st:?}");
        assert_eq!(st[Status::ResourceBusy as usize], 4, "{st:?}");
        // The evaluations by kind add up, most first, with two units a kind.
        let by = sim.evals_by_module();
        assert_eq!(by.iter().map(|e| e.evals).sum::<u64>(), sim.evals, "{by:?}");
        assert!(by.windows(2).all(|w| w[0].evals >= w[1].evals), "{by:?}");
        let mut kinds: Vec<_> = by.iter().map(|e| (e.module, e.units)).collect();
        kinds.sort();
        assert_eq!(kinds, [("asker", 2), ("echo", 2)]);
    }
}
