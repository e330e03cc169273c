//! The lock-step simulator.
//!
//! Time is an integer number of picoseconds, shared by every clock domain (and used
//! as the VCD timescale). A step at time `t` evaluates every unit that is due at `t`
//! (in any order: the result cannot depend on it, see `link.rs`), then commits all of
//! them and every link they touched: the clock edge.
//!
//! Units sleep: after its evaluation a unit says when it next needs to run
//! ([`Next`](super::unit::Next)); a push wakes the consumer when the payload
//! becomes visible, and a pop from a full link wakes the producer. Sleeping units
//! cost nothing, and when all sleep, time jumps to the next wake-up. With
//! `sleep: false` every unit is evaluated at every edge of its clock; with
//! `shadow: true` the extra evaluations must change nothing (no register, link,
//! status or counter), which checks the sleep contract.
//!
//! The simulator's state ([`Sim`], and a unit's `Slot`) is here; the code is
//! split by what it does: `builder` (clocks, links, units, elaboration, reset),
//! `context` (what a unit sees while it is evaluated, and its evaluation),
//! `network` (the flat link arrays both ends reach), `scheduling` (wake-ups and
//! the calendars), `stepping` (the run loop and one step: evaluate, then the
//! clock edge), `partition` (which lane evaluates which unit, and a parallel
//! step), `lanes` (the worker threads) and `observe` (statistics, tracing and
//! access to units between runs); `options` holds how to run and why a run stops.

mod builder;
mod context;
mod lanes;
mod network;
mod observe;
mod options;
mod partition;
mod scheduling;
mod stepping;

use context::LaneOut;
use lanes::{AutoLanes, Balance, LanePlan};
use scheduling::Sched;

use super::link::{LinkDyn, LinkId};
use super::trace::Tracer;
use super::unit::{Status, Unit};
use crate::util::rng::Rng;

pub use context::{Ctx, round_robin};
pub use observe::{ModuleEvals, UnitStats};
pub use options::{RunEnd, SimError, SimOptions, Threads};

/// Simulation time in picoseconds.
pub type Time = u64;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct UnitId(pub u32);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockId(pub u16);

#[derive(Clone, Debug)]
pub struct Clock {
    pub name: String,
    pub period_ps: Time,
}

/// A slot's `check_ready` when its readiness is not checked.
const NO_CHECK: (Time, Time) = (Time::MAX, 0);

// What every evaluation reads comes first, in one cache line (`align(64)`): a
// slot is cold when its unit is due, and its fields in Rust's own order put the
// status two lines after the period.
#[repr(C, align(64))]
struct Slot {
    unit: Box<dyn Unit>,
    /// Output links with a refused offer that must be repeated (the monitor checks
    /// only these after each evaluation, not every output link).
    stalled_outs: Vec<LinkId>,
    period: Time,
    evals: u64,
    status: Status,
    /// The unit was changed from outside (`Sim::unit_mut`), so registers it did
    /// not write in its evaluation may be pending: its next edge commits all.
    commit_all: bool,
    /// The status credited up to `since` when `since` is ahead of the last
    /// evaluation (a status from the next cycle on): stats read before then take
    /// the credit back.
    ahead: Option<Status>,
    /// A tracer samples this unit's registers (`Ctx::watched`).
    watched: bool,
    clock: ClockId,
    since: Time,
    status_ps: [Time; 4],
    path: String,
    out_links: Vec<LinkId>,
    /// The unit's input links, in declaration order.
    in_links: Vec<LinkId>,
    /// Check the unit's readiness (`Logic::can_accept`) at its pops: with
    /// `SimOptions::check_ready` (the whole run), or when a tracer shows it
    /// (its window, where the waveform needs the readiness from before the
    /// evaluation): the first and last time checked (`NO_CHECK`: none).
    check_ready: (Time, Time),
    /// Readiness of each of `in_links` at the start of the cycle of the last
    /// checked evaluation (`ready_at`), before the unit changed anything.
    ready_pre: Vec<bool>,
    ready_at: Time,
    /// Links the unit popped in a checked evaluation.
    popped: Vec<LinkId>,
}

/// The simulator.
pub struct Sim {
    clocks: Vec<Clock>,
    slots: Vec<Slot>,
    sched: Vec<Sched>,
    /// Every unit's evaluation partition (see [`Sim::set_part`]).
    parts: Vec<u8>,
    /// Every unit's last evaluation time (skips duplicate calendar entries):
    /// apart from `Sched`, which the worker writes, as only this thread reads it.
    last_eval: Vec<Time>,
    links: Vec<Box<dyn LinkDyn>>,
    /// Head visibility time of every link (see `Ctx::heads`).
    heads: Vec<Time>,
    /// Whether every link can take a push (see `Ctx::space`).
    space: Vec<bool>,
    /// Whether every link's FIFO holds an entry (see `Net`).
    nonempty: Vec<u8>,
    /// Time of every link's last edge (a link touched at both ends is listed twice).
    edged: Vec<Time>,
    /// Per link: the partition of both its ends (1 or 2; its thread then takes its
    /// edge too), or 0 (ends in different partitions, or in partition 0).
    local: Vec<u8>,
    now: Time,
    /// Whether the step at `now` has been processed.
    stepped: bool,
    cal: super::calendar::Calendar,
    /// The worker lanes' own calendars (lane k at k - 1): with several lanes
    /// each schedules its own units' next evaluations while it runs (the last
    /// lane, the caller's thread, in `cal`), so that bookkeeping is not serial;
    /// a step takes from all of them.
    lane_cals: Vec<super::calendar::Calendar>,
    opts: SimOptions,
    rng: Option<Rng>,
    elaborated: bool,
    due: Vec<(u32, bool)>,
    taken: Vec<u32>,
    tracer: Option<Tracer>,
    /// The vectors being captured (`--capture`), a tracer of its own, and the
    /// files it wrote once finished.
    capture: Option<Tracer>,
    captured: crate::rtl::trace::Written,
    /// This thread's evaluation results of the current step.
    out: LaneOut,
    /// Due units of each lane (lane k at k - 1).
    lane_due: Vec<Vec<(u32, bool)>>,
    /// Steps handed to the workers in the current run.
    lane_seq: u64,
    /// Lanes in use now (1: one thread).
    lanes: usize,
    /// The worker lanes handed the current step (kept for its allocation).
    lane_started: Vec<usize>,
    /// How units spread over the lanes, if the builder said.
    plan: Option<LanePlan>,
    balance: Balance,
    auto: AutoLanes,
    /// Steps taken with each lane count (index: lanes - 1).
    steps_by_lanes: Vec<u64>,
    /// Unit evaluations so far (due ones, not shadow ones).
    pub evals: u64,
    /// Steps (distinct times) processed so far.
    pub steps: u64,
    /// Steps whose partitions 1 and 2 were evaluated on two threads.
    pub parallel_steps: u64,
}

impl Default for Sim {
    fn default() -> Self {
        Sim::new(SimOptions::default())
    }
}

impl Sim {
    pub fn new(opts: SimOptions) -> Self {
        let rng = opts.shuffle_seed.map(Rng::new);
        let opts = SimOptions {
            threads: opts.threads.max(1),
            ..opts
        };
        Sim {
            clocks: Vec::new(),
            slots: Vec::new(),
            sched: Vec::new(),
            parts: Vec::new(),
            last_eval: Vec::new(),
            links: Vec::new(),
            heads: Vec::new(),
            space: Vec::new(),
            nonempty: Vec::new(),
            edged: Vec::new(),
            local: Vec::new(),
            now: 0,
            stepped: false,
            cal: super::calendar::Calendar::new(),
            lane_cals: (1..opts.threads.max(1))
                .map(|_| super::calendar::Calendar::new())
                .collect(),
            taken: Vec::new(),
            opts: opts.clone(),
            rng,
            elaborated: false,
            due: Vec::new(),
            tracer: None,
            capture: None,
            captured: Default::default(),
            out: LaneOut::default(),
            lane_due: vec![Vec::new(); opts.threads.max(2)],
            lane_seq: 0,
            lanes: if opts.auto_lanes {
                1
            } else {
                opts.threads.max(1)
            },
            lane_started: Vec::new(),
            plan: None,
            balance: Balance::default(),
            auto: AutoLanes::new(opts.auto_lanes, opts.threads.max(1)),
            steps_by_lanes: vec![0; opts.threads.max(1)],
            evals: 0,
            steps: 0,
            parallel_steps: 0,
        }
    }

    pub fn options(&self) -> &SimOptions {
        &self.opts
    }
}
