//! `ready` on an input is the unit's "can accept this cycle": valid = 0 with
//! ready = 1 is a unit idle and waiting, valid = 1 with ready = 0 a stall,
//! and a unit that pops an input it declared itself not ready for is caught.

use dualstream::rtl::{
    Ctx, In, LinkCfg, LinkId, Logic, Next, Out, Ready, Reg, Sim, SimError, SimOptions, TraceSpec,
    Tracer,
};

use crate::chip_trace;
use crate::common::Scratch;
use crate::read::{self, Wave};

/// (valid, ready) of input `port` at every change of either.
fn handshakes(w: &Wave, port: &str) -> Vec<(u64, Option<String>, Option<String>)> {
    let (v, r) = (format!("{port}_valid"), format!("{port}_ready"));
    let mut t: Vec<u64> = [&v, &r]
        .iter()
        .flat_map(|p| w.changes.get(*p).into_iter().flatten().map(|c| c.0))
        .collect();
    t.sort_unstable();
    t.dedup();
    t.into_iter()
        .map(|t| {
            (
                t,
                w.at(&v, t).map(str::to_string),
                w.at(&r, t).map(str::to_string),
            )
        })
        .collect()
}

/// Whether (valid, ready) takes the value `(v, r)` on `port` at some time.
fn shows(w: &Wave, port: &str, v: &str, r: &str) -> bool {
    handshakes(w, port)
        .iter()
        .any(|(_, a, b)| a.as_deref() == Some(v) && b.as_deref() == Some(r))
}

/// A chip window: the TP's inputs show idle-and-waiting (valid 0, ready 1:
/// the ray input in Idle, a response input in its wait state) and not
/// ready (valid 0, ready 0: the ray input while it traverses), so ready
/// is no longer "took it" (which would never be 1 with valid 0).
#[test]
fn an_idle_input_shows_ready_without_valid() {
    let d = Scratch::new("wave-ready");
    let p = d.join("r.vcd");
    chip_trace(
        &p,
        "chip.tm0.tp0,chip.tm0.l1,chip.tm0.xbar",
        "0..20000",
        &[],
    );
    let w = read::vcd(&p);
    let tp = "chip.tm0.tp0";
    assert!(
        shows(&w, &format!("{tp}.ray"), "0", "1"),
        "TP idle, waiting for a ray"
    );
    assert!(
        shows(&w, &format!("{tp}.ray"), "0", "0"),
        "TP busy: not ready for a ray"
    );
    assert!(shows(&w, &format!("{tp}.ray"), "1", "1"), "a ray taken");
    assert!(
        shows(&w, &format!("{tp}.mem_resp"), "0", "1"),
        "TP waiting for its L1 line"
    );
    // The L1 and the crossbar wait on their TP ports too.
    assert!(shows(&w, "chip.tm0.l1.req_0", "0", "1"));
    assert!(shows(&w, "chip.tm0.xbar.tp_box_req_0", "0", "1"));
    // Over every input port: somewhere idle and ready.
    let idle_ready = w
        .order
        .iter()
        .filter_map(|p| p.strip_suffix("_ready"))
        .filter(|p| shows(&w, p, "0", "1"))
        .count();
    assert!(idle_ready >= 10, "inputs idle and ready: {idle_ready}");
}

dualstream::unit! {
    /// Offers 0, 1, 2, ... one a cycle, holding a refused one.
    pub struct Offer : "offer" {
        new(; ports: OfferPorts) {}
        params { }
        inputs { }
        outputs { out: u32 }
        state { n: Reg<u32> = 0 }
        extra { }
    }
}
impl Logic for Offer {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let n = self.n.val();
        if n < 40 && ctx.offer(&self.out, n) {
            self.n.set(n + 1);
        }
        if n < 40 { Next::Cycle } else { Next::Idle }
    }
}

dualstream::unit! {
    /// Takes a payload every other cycle: busy for one after each.
    pub struct Slow : "slow" {
        new(lie: bool; ports: SlowPorts) {}
        params { }
        inputs { inp: u32 }
        outputs { }
        state { busy: Reg<bool> = false }
        extra { lie: bool = lie }
    }
}
impl Logic for Slow {
    /// Not ready while busy (or, lying, never ready at all).
    fn can_accept(&self, _port: LinkId, _at: &Ready) -> bool {
        !self.lie && !self.busy.val()
    }
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        // The planted fault: a liar pops whatever its readiness said.
        if (self.lie || !self.busy.val()) && ctx.pop(&self.inp).is_some() {
            self.busy.set(true);
            return Next::Cycle;
        }
        self.busy.set(false);
        if ctx.holds_more(&self.inp) {
            Next::Cycle
        } else {
            Next::Idle
        }
    }
}

/// Runs the pair, checked (`SimOptions::check_ready`) or traced into `vcd`.
fn pair(lie: bool, check: bool, vcd: Option<&std::path::Path>) -> Result<Sim, SimError> {
    let mut sim = Sim::new(SimOptions {
        check_ready: check,
        ..SimOptions::default()
    });
    let c = sim.clock("core", 1000).unwrap();
    let (o, i): (Out<u32>, In<u32>) = sim.link("l", LinkCfg { depth: 2, delay: 1 });
    sim.add("tb.offer", c, Offer::new(OfferPorts { out: o }));
    sim.add("tb.slow", c, Slow::new(lie, SlowPorts { inp: i }));
    let buf = dualstream::rtl::SharedBuf::default();
    if vcd.is_some() {
        sim.attach_tracer(Tracer::new(Box::new(buf.clone()), TraceSpec::all()).unwrap())?;
    }
    sim.run(200_000)?;
    if let Some(p) = vcd {
        sim.finish_trace().unwrap().unwrap();
        std::fs::write(p, buf.bytes()).unwrap();
    }
    Ok(sim)
}

fn not_ready(r: Result<Sim, SimError>) -> bool {
    match r {
        Err(SimError::Protocol(v)) => v.iter().any(|x| {
            x.link == "l"
                && x.what
                    .contains("'tb.slow' popped while it declared itself not ready")
        }),
        Err(e) => panic!("another error: {e}"),
        Ok(_) => false,
    }
}

/// The readiness checker passes the honest unit and catches the liar, when
/// asked for and whenever the unit is traced; the honest unit's trace
/// shows its stalls (valid 1, ready 0) and its wait (valid 0, ready 1), and
/// fire is valid & ready.
#[test]
fn the_readiness_checker_catches_a_pop_without_ready() {
    let d = Scratch::new("wave-ready-check");
    let p = d.join("pair.vcd");
    pair(false, true, None).expect("honest");
    pair(false, false, Some(&p)).expect("honest, traced");
    assert!(not_ready(pair(true, true, None)), "checked");
    assert!(
        not_ready(pair(true, false, Some(&d.join("liar.vcd")))),
        "traced"
    );
    assert!(
        pair(true, false, None).is_ok(),
        "unchecked, untraced: not looked at"
    );
    let w = read::vcd(&p);
    let port = "tb.slow.inp";
    assert!(shows(&w, port, "1", "0"), "a stall while busy");
    assert!(shows(&w, port, "1", "1"), "a payload taken");
    assert!(shows(&w, port, "0", "1"), "idle at the end, waiting");
    for (t, v, r) in handshakes(&w, port) {
        let fire = w.at(&format!("{port}_fire"), t).map(str::to_string);
        let want = (v.as_deref() == Some("1") && r.as_deref() == Some("1")) as u8;
        assert_eq!(fire, Some(want.to_string()), "fire at {t}");
    }
}
