//! Testbench components: a scripted driver and a back-pressuring sink. They are not
//! hardware, so they implement `Declared` by hand (ports only, no Verilog).

use crate::testbench::TbError;
use std::collections::VecDeque;

use crate::rtl::decl::{Samples, StateList};
use crate::rtl::{
    Ctx, Declared, In, Logic, Next, Out, Payload, PortDecl, PortDir, SharedBuf, Sim, Status,
    Tracer, UnitDecl, UnitStats,
};

use super::pipe_tb::{TbOptions, TbReport};

fn decl(module: &'static str, ports: Vec<PortDecl>) -> UnitDecl {
    UnitDecl {
        module,
        source: file!(),
        doc: "testbench component",
        params: vec![],
        ports,
        state: StateList::default().items,
    }
}

/// A testbench component has one port and no hardware state: its declaration is
/// that port alone (no Verilog is emitted for it).
macro_rules! tb_component {
    ($ty:ident, $module:literal, $field:ident, $dir:ident, |$s:ident| $reset:block) => {
        impl<T: Payload> Declared for $ty<T> {
            fn decl(&self) -> UnitDecl {
                decl($module, self.ports())
            }
            fn ports(&self) -> Vec<PortDecl> {
                vec![PortDecl {
                    name: stringify!($field),
                    dir: PortDir::$dir,
                    width: T::BITS,
                    ty: T::sv_type(),
                    fields: T::field_list(),
                    link: self.$field.id,
                }]
            }
            fn sample_state(&self, _cycle: u64, _out: &mut Samples) {}
            fn commit_state(&mut self) {}
            #[allow(unused_variables)]
            fn reset_state(&mut self) {
                let $s = self;
                $reset
            }
            fn state_pending(&self) -> bool {
                false
            }
        }
    };
}

/// Pushes scripted payloads in order, each no earlier than its cycle, honouring
/// back-pressure (a refused payload is offered again until taken).
pub struct Driver<T: Payload> {
    pub out: Out<T>,
    script: VecDeque<(u64, T)>,
    pub sent: u64,
}

impl<T: Payload> Driver<T> {
    pub fn new(out: Out<T>) -> Self {
        Driver {
            out,
            script: VecDeque::new(),
            sent: 0,
        }
    }
    /// Queues a payload for cycle `at` or later (poke). Wake the unit afterwards.
    pub fn send(&mut self, at: u64, v: T) {
        self.script.push_back((at, v));
    }
    pub fn pending(&self) -> usize {
        self.script.len()
    }
}

tb_component!(Driver, "tb_driver", out, Out, |_s| {});

impl<T: Payload> Logic for Driver<T> {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let Some((at, v)) = self.script.front() else {
            ctx.set_status(Status::WaitInput);
            return Next::Idle;
        };
        if *at > c {
            ctx.set_status(Status::WaitInput);
            return Next::AtCycle(*at);
        }
        if ctx.offer(&self.out, v.clone()) {
            self.script.pop_front();
            self.sent += 1;
            ctx.set_status(Status::Busy);
            Next::Cycle // busy this cycle only: re-evaluate to wait or send again
        } else {
            ctx.set_status(Status::OutputBlocked);
            Next::Idle // woken when the link drains
        }
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![("sent", self.sent)]
    }
}

/// Takes payloads when its ready pattern allows and records them with the cycle.
/// The pattern is a pure function of the absolute cycle and the seed, so it does
/// not depend on how often the sink is evaluated.
pub struct Sink<T: Payload> {
    pub inp: In<T>,
    /// Probability of being ready in a cycle (1.0: always).
    pub ready_p: f64,
    pub seed: u64,
    /// Not ready before this cycle (a consumer that starts late).
    pub from: u64,
    pub got: Vec<(u64, T)>,
}

impl<T: Payload> Sink<T> {
    pub fn new(inp: In<T>, ready_p: f64, seed: u64) -> Self {
        Sink {
            inp,
            ready_p,
            seed,
            from: 0,
            got: Vec::new(),
        }
    }
    /// The same sink, not ready before `cycle`.
    pub fn ready_from(mut self, cycle: u64) -> Self {
        self.from = cycle;
        self
    }
    pub fn ready(&self, cycle: u64) -> bool {
        if cycle < self.from {
            return false;
        }
        if self.ready_p >= 1.0 {
            return true;
        }
        let mut r =
            crate::util::rng::Rng::new(self.seed ^ cycle.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        r.chance(self.ready_p)
    }
}

tb_component!(Sink, "tb_sink", inp, In, |s| {
    s.got.clear();
});

impl<T: Payload> Logic for Sink<T> {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        if ctx.peek(&self.inp).is_none() {
            ctx.set_status(Status::WaitInput);
            return Next::Idle;
        }
        if !self.ready(c) {
            ctx.set_status(Status::ResourceBusy);
            let mut n = (c + 1).max(self.from);
            while !self.ready(n) {
                n += 1;
            }
            return Next::AtCycle(n);
        }
        let v = ctx.pop(&self.inp).expect("peeked");
        self.got.push((c, v));
        ctx.set_status(Status::Busy);
        Next::Cycle // another payload may already be waiting behind it
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![("received", self.got.len() as u64)]
    }
}

/// Offers payloads from a fixed pool with probability `activity` per cycle (1.0:
/// every cycle), forever or until `limit` have been sent. Whether cycle `c` has a
/// request is a pure function of the seed and `c`, so the generator sleeps between
/// requests and its schedule does not depend on evaluation.
pub struct LoadGen<T: Payload> {
    pub out: Out<T>,
    pool: Vec<T>,
    activity: f64,
    seed: u64,
    limit: u64,
    /// The payload being offered (held while the link is full).
    pending: Option<T>,
    pub sent: u64,
}

impl<T: Payload> LoadGen<T> {
    pub fn new(out: Out<T>, pool: Vec<T>, activity: f64, seed: u64, limit: u64) -> Self {
        assert!(!pool.is_empty() && activity > 0.0);
        LoadGen {
            out,
            pool,
            activity,
            seed,
            limit,
            pending: None,
            sent: 0,
        }
    }
    fn fires(&self, c: u64) -> bool {
        self.activity >= 1.0 || {
            let mut r =
                crate::util::rng::Rng::new(self.seed ^ c.wrapping_mul(0xD1B5_4A32_D192_ED03));
            r.chance(self.activity)
        }
    }
    fn next_fire(&self, mut c: u64) -> u64 {
        while !self.fires(c) {
            c += 1;
        }
        c
    }
}

tb_component!(LoadGen, "tb_loadgen", out, Out, |s| {
    s.pending = None;
    s.sent = 0;
});

impl<T: Payload> Logic for LoadGen<T> {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        if self.sent >= self.limit {
            ctx.set_status(Status::WaitInput);
            return Next::Idle;
        }
        if self.pending.is_none() {
            if !self.fires(c) {
                ctx.set_status(Status::WaitInput);
                return Next::AtCycle(self.next_fire(c + 1));
            }
            self.pending = Some(self.pool[(self.sent % self.pool.len() as u64) as usize].clone());
        }
        let v = self.pending.clone().expect("set above");
        if ctx.offer(&self.out, v) {
            self.pending = None;
            self.sent += 1;
            ctx.set_status(Status::Busy);
            Next::Cycle
        } else {
            ctx.set_status(Status::OutputBlocked);
            Next::Idle
        }
    }
    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![("sent", self.sent)]
    }
}

/// Attaches a bench's waveform: into `buf` (the invariance tests) if given,
/// else to the file `opts.vcd` names, if any.
pub fn attach_trace(
    sim: &mut Sim,
    opts: &TbOptions,
    buf: Option<&SharedBuf>,
) -> Result<(), TbError> {
    if let Some(buf) = buf {
        let t = Tracer::new(Box::new(buf.clone()), opts.trace.clone())?;
        sim.attach_tracer(t)?;
    } else if let Some(path) = &opts.vcd {
        let t = Tracer::to_file(path, opts.trace.clone())?;
        sim.attach_tracer(t)?;
    }
    Ok(())
}

/// Closes the waveform, if any, and records its size in `rep`.
pub fn finish_trace(sim: &mut Sim, mut rep: TbReport) -> Result<TbReport, TbError> {
    if let Some(s) = close_trace(sim)? {
        rep.vcd_changes = s.changes;
        rep.vcd_bytes = s.bytes;
    }
    Ok(rep)
}

/// Closes the waveform, if any: what it wrote.
pub fn close_trace(sim: &mut Sim) -> Result<Option<crate::rtl::TraceStats>, TbError> {
    sim.finish_trace()
        .transpose()
        .map_err(|source| TbError::Vcd {
            what: "writing the VCD failed",
            source,
        })
}

/// A unit's counter by name (0 if it has none of that name).
pub fn counter(st: &UnitStats, name: &str) -> u64 {
    st.counters
        .iter()
        .find(|(k, _)| *k == name)
        .map_or(0, |(_, v)| *v)
}
