//! The lock-step simulator.
//!
//! Time is an integer number of picoseconds, shared by every clock domain (and used
//! as the VCD timescale). A step at time `t` evaluates every unit that is due at `t`
//! (in any order: the result cannot depend on it, see `link.rs`), then commits all of
//! them and every link they touched: the clock edge.
//!
//! Units sleep: after its evaluation a unit says when it next needs to run
//! ([`Next`]); a push wakes the consumer when the payload becomes visible, and a pop
//! from a full link wakes the producer. Sleeping units cost nothing, and when all
//! sleep, time jumps to the next wake-up. With `sleep: false` every unit is evaluated
//! at every edge of its clock; with `shadow: true` the extra evaluations must change
//! nothing (no register, link, status or counter), which checks the sleep contract.

mod lanes;

use std::any::Any;
use std::fmt;
use std::time::Instant;

use lanes::{AutoLanes, Balance, Crew, LanePlan, Lanes, Phase, run_lane};

use super::bits::Payload;
use super::link::{
    In, Link, LinkCfg, LinkDyn, LinkEvent, LinkId, LinkStats, Out, PortArray, Violation,
};
use super::state;
use super::trace::Tracer;
use super::unit::{Next, Status, Unit};
use crate::util::rng::Rng;

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

/// How to run.
#[derive(Clone, Debug)]
pub struct SimOptions {
    /// Skip units that sleep (the fast, normal mode).
    pub sleep: bool,
    /// Evaluate sleeping units too and fail if that would change anything.
    pub shadow: bool,
    /// Evaluate the units of each step in a seeded random order (tests).
    pub shuffle_seed: Option<u64>,
    /// Evaluation lanes (threads): 1, or N to evaluate the units of partitions
    /// 1..N-1 (see [`Sim::set_part`], [`Sim::set_lane_plan`]) on worker threads
    /// while the caller's thread evaluates those of partition N, then partition 0
    /// alone. The result is bit-identical to one thread (evaluation order never
    /// changes a result). Only with `sleep` on and `shadow` off; otherwise one
    /// thread is used. With `auto_lanes`, the most lanes the run may use.
    pub threads: usize,
    /// Choose the lane count while running (1 up to `threads`), by measuring
    /// the run's own speed (see `lanes.rs`); needs a lane plan
    /// ([`Sim::set_lane_plan`]). Results never depend on it.
    pub auto_lanes: bool,
}

/// How many evaluation threads a run uses (the command line's `--threads`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Threads {
    /// Lanes (with `auto`, the most the run may use).
    pub n: usize,
    /// Choose between 1 and `n` lanes while running (`SimOptions::auto_lanes`).
    pub auto: bool,
}

impl Threads {
    pub fn fixed(n: usize) -> Threads {
        Threads {
            n: n.max(1),
            auto: false,
        }
    }
    /// Up to the machine's cores, chosen while running.
    pub fn auto() -> Threads {
        Threads {
            n: std::thread::available_parallelism().map_or(1, |n| n.get()),
            auto: true,
        }
    }
    /// The simulator options of a run on these threads.
    pub fn sim(self) -> SimOptions {
        SimOptions {
            threads: self.n,
            auto_lanes: self.auto,
            ..SimOptions::default()
        }
    }
}

impl From<usize> for Threads {
    fn from(n: usize) -> Threads {
        Threads::fixed(n)
    }
}

impl fmt::Display for Threads {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.auto {
            write!(f, "auto (1 to {})", self.n)
        } else {
            write!(f, "{}", self.n)
        }
    }
}

impl Default for SimOptions {
    fn default() -> Self {
        SimOptions {
            sleep: true,
            shadow: false,
            shuffle_seed: None,
            threads: 1,
            auto_lanes: false,
        }
    }
}

/// Why a run stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RunEnd {
    /// Every unit sleeps with nothing scheduled.
    Idle,
    /// The time limit was reached.
    Limit,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SimError {
    /// A link monitor saw a protocol violation (a bug in a unit).
    Protocol(Vec<Violation>),
    /// A sleeping unit would have changed something if evaluated (a sleep bug).
    Shadow {
        unit: String,
        at: Time,
        what: String,
    },
    /// The netlist is not well formed.
    Elaboration(String),
    /// The waveform's size guard refused or stopped the trace (its file removed).
    Trace(String),
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Protocol(v) => {
                write!(f, "link protocol violation")?;
                for x in v {
                    write!(f, "; link '{}' at {} ps: {}", x.link, x.at, x.what)?;
                }
                Ok(())
            }
            SimError::Shadow { unit, at, what } => {
                write!(
                    f,
                    "sleeping unit '{unit}' at {at} ps would change {what} if evaluated: it must not sleep here"
                )
            }
            SimError::Elaboration(s) => write!(f, "netlist error: {s}"),
            SimError::Trace(s) => write!(f, "{s}"),
        }
    }
}
impl std::error::Error for SimError {}

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
}

/// What the step loop needs of a unit, apart from the `Slot` that its evaluation
/// changes: compact, and written only by the thread that runs the step loop.
#[derive(Clone, Copy)]
struct Sched {
    /// The unit's clock period, and how a wake-up rounds up to its edge
    /// without a divide.
    edge: EdgeOf,
    /// Last wake-up time put in the calendar (skips immediate duplicates).
    last_wake: Time,
    clock: u16,
}

/// `t.div_ceil(period)` by a multiply with the period's reciprocal: a 64-bit
/// `div` is about 30 cycles of latency on this machine (13 ns per division in a
/// dependent chain, 2 ns per multiply), and every wake-up a push sends is
/// rounded up to its consumer's clock edge.
#[derive(Clone, Copy, Debug)]
struct EdgeOf {
    period: Time,
    /// `ceil(2^64 / period)` (0 for a period of 1).
    m: u64,
    /// The largest time the multiply divides exactly: below `2^64 / period`
    /// the error of `m` stays under one period's fraction.
    exact_to: Time,
}

impl EdgeOf {
    fn new(period: Time) -> Self {
        assert!(period >= 1, "a clock period is at least 1 ps");
        if period == 1 {
            return EdgeOf {
                period,
                m: 0,
                exact_to: Time::MAX,
            };
        }
        EdgeOf {
            period,
            m: u64::MAX / period + 1,
            exact_to: u64::MAX / period,
        }
    }
    /// The cycle of the first edge at or after `t`.
    #[inline]
    fn cycle_at_or_after(&self, t: Time) -> u64 {
        if self.period == 1 {
            return t;
        }
        if t > self.exact_to {
            return t.div_ceil(self.period);
        }
        let q = ((t as u128 * self.m as u128) >> 64) as u64;
        q + (q * self.period != t) as u64
    }
}

/// Evaluations of the units of one kind (see [`Sim::evals_by_module`]).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ModuleEvals {
    pub module: &'static str,
    pub units: usize,
    pub evals: u64,
}

/// Statistics of one unit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnitStats {
    pub path: String,
    pub module: &'static str,
    /// Cycles (of the unit's clock) spent in each [`Status`], indexed by its value.
    pub status_cycles: [u64; 4],
    pub counters: Vec<(&'static str, u64)>,
}

/// The netlist's shared arrays as raw pointers, so that the two evaluation threads
/// (see [`SimOptions::threads`]) can each reach the links of their own partition
/// while the other does the same: elaboration checks that no link joins units of
/// two different partitions, so no element is ever reached from both threads.
#[derive(Clone, Copy)]
struct Net {
    links: *mut Box<dyn LinkDyn>,
    heads: *mut Time,
    space: *mut bool,
    /// One byte per link: whether its FIFO holds an entry (`heads` is not
    /// `Time::MAX`), written with `heads`. A byte, not a bit: links of one word
    /// may have consumers on both threads, and a bit would need an atomic
    /// read-modify-write (a fence that stalls this memory-bound loop, measured).
    nonempty: *mut u8,
    len: usize,
}

impl Net {
    fn null() -> Net {
        Net {
            links: std::ptr::null_mut::<Box<dyn LinkDyn>>(),
            heads: std::ptr::null_mut(),
            space: std::ptr::null_mut(),
            nonempty: std::ptr::null_mut(),
            len: 0,
        }
    }
    fn of(
        links: &mut [Box<dyn LinkDyn>],
        heads: &mut [Time],
        space: &mut [bool],
        nonempty: &mut [u8],
    ) -> Net {
        assert!(
            links.len() == heads.len()
                && links.len() == space.len()
                && links.len() == nonempty.len()
        );
        Net {
            links: links.as_mut_ptr(),
            heads: heads.as_mut_ptr(),
            space: space.as_mut_ptr(),
            nonempty: nonempty.as_mut_ptr(),
            len: links.len(),
        }
    }
    /// Links `first..first + n` (n <= 64) that hold an entry, as a bit mask.
    #[inline]
    fn nonempty_bits(&self, first: usize, n: usize) -> u64 {
        assert!(n <= 64 && first + n <= self.len);
        // SAFETY: in bounds (checked above); the caller passes the links of one port
        // array of the unit being evaluated, so this thread is their only writer.
        let bytes = unsafe { std::slice::from_raw_parts(self.nonempty.add(first), n) };
        let words = n / 8;
        let mut b = 0u64;
        for w in 0..words {
            // Eight 0/1 bytes to eight bits in one multiply: byte i lands on bit
            // 56 + i and every other product on a distinct lower or dropped bit (an
            // arbiter's scan of 16 ports was a loop of 16 loads, shifts and ors).
            // SAFETY: bytes `8w..8w + 8` of `bytes` (in bounds: `w < n / 8`), read
            // unaligned; a plain load instead of `chunks_exact` and `try_into`, which
            // were a tenth of the crossbar's instructions (callgrind).
            let x =
                u64::from_le(unsafe { bytes.as_ptr().add(8 * w).cast::<u64>().read_unaligned() });
            b |= (x.wrapping_mul(0x0102_0408_1020_4080) >> 56) << (8 * w);
        }
        for (k, &v) in bytes.iter().enumerate().skip(8 * words) {
            b |= ((v != 0) as u64) << k;
        }
        b
    }
    /// A shared reference to link `i`: each end changes only its own half of a
    /// link (`Link::cons`, `Link::prod`), so producer and consumer may be on two
    /// threads. The lifetime is the evaluation's (the caller's to respect).
    #[inline]
    fn link_ref<'x>(&self, i: usize) -> &'x dyn LinkDyn {
        assert!(i < self.len);
        // SAFETY: in bounds (checked); the array outlives every evaluation (it is
        // the simulator's and is not resized after elaboration), and no `&mut` to a
        // link exists while units are evaluated (only the edge takes one, on one
        // thread, after every evaluation of the step).
        unsafe { &**self.links.add(i) }
    }
    /// Link `i` for its clock edge.
    /// SAFETY: the caller's thread evaluates both ends of the link and no other
    /// reference to it is alive.
    #[inline]
    unsafe fn link_mut<'x>(&self, i: usize) -> &'x mut dyn LinkDyn {
        assert!(i < self.len);
        // SAFETY: in bounds; exclusive by the function's contract.
        unsafe { &mut **self.links.add(i) }
    }
    #[inline]
    fn typed<'x, T: Payload>(&self, id: LinkId) -> &'x Link<T> {
        let l: &'x dyn LinkDyn = self.link_ref(id.0 as usize);
        (l as &dyn Any)
            .downcast_ref::<Link<T>>()
            .expect("link payload type matches its handle")
    }
    #[inline]
    fn head(&self, i: usize) -> Time {
        assert!(i < self.len);
        // SAFETY: in bounds; read by the consumer, the only writer during a step.
        unsafe { *self.heads.add(i) }
    }
    #[inline]
    fn space(&self, i: usize) -> bool {
        assert!(i < self.len);
        // SAFETY: in bounds; read by the producer, the only writer during a step.
        unsafe { *self.space.add(i) }
    }
    /// Only the link's producer writes its `space` during a step.
    #[inline]
    fn set_space(&mut self, i: usize, space: bool) {
        assert!(i < self.len);
        // SAFETY: in bounds; one element, written only by the producer's thread.
        unsafe { *self.space.add(i) = space }
    }
    /// Only the link's consumer writes its `head` during a step.
    #[inline]
    fn set_head(&mut self, i: usize, head: Time) {
        assert!(i < self.len);
        // SAFETY: in bounds; one element, written only by the consumer's thread.
        unsafe {
            *self.heads.add(i) = head;
            *self.nonempty.add(i) = (head != Time::MAX) as u8;
        }
    }
}

/// What one evaluation thread produces in a step, merged by the main thread at the
/// clock edge.
#[derive(Default)]
struct LaneOut {
    touched: Vec<LinkId>,
    wakes: Vec<(UnitId, Time)>,
    /// (unit, its next wake-up, its cycle when it was evaluated)
    nexts: Vec<(u32, Next, u64)>,
    evals: u64,
    /// Protocol violations found at the edges of the thread's own links.
    violations: Vec<Violation>,
    /// The last (time, period, cycle) a `Ctx` was made for: consecutive units
    /// share their clock, and a 64-bit division per evaluation showed in the
    /// profile (7% of the crossbar's time).
    clock: (Time, Time, u64),
}

impl LaneOut {
    fn append(&mut self, o: &mut LaneOut) {
        self.touched.append(&mut o.touched);
        self.wakes.append(&mut o.wakes);
        self.nexts.append(&mut o.nexts);
        self.violations.append(&mut o.violations);
        self.evals += std::mem::take(&mut o.evals);
    }
}

/// What a unit sees while it is evaluated: the time, its links, and its status.
pub struct Ctx<'a> {
    now: Time,
    /// `now / period`, computed once per time and clock.
    cycle: u64,
    period: Time,
    unit: UnitId,
    /// Every link, with `LinkDyn::head_time` and `LinkDyn::has_space` of each kept
    /// current by every push, pop and commit (a pop frees space only after the edge).
    net: Net,
    touched: &'a mut Vec<LinkId>,
    wakes: &'a mut Vec<(UnitId, Time)>,
    /// Output links of this unit with a refused offer outstanding.
    stalls: &'a mut Vec<LinkId>,
    new_status: Option<Status>,
    /// The status from the next cycle on (`Ctx::set_status_from_next`).
    next_status: Option<Status>,
    link_ops: u32,
    watched: bool,
}

impl<'a> Ctx<'a> {
    #[inline]
    pub fn now(&self) -> Time {
        self.now
    }
    /// The current cycle of the unit's own clock.
    #[inline]
    pub fn cycle(&self) -> u64 {
        debug_assert_eq!(self.cycle, self.now / self.period);
        self.cycle
    }

    /// Where a round-robin arbiter over `n` requesters starts this cycle:
    /// `cycle mod n` (0 for none), a function of absolute time, so it does not
    /// depend on when the unit was evaluated. A mask when `n` is a power of two
    /// (the TPs of a TM): the crossbar's 64-bit division was 1% of the paper frame.
    #[inline]
    pub fn round_robin_start(&self, n: usize) -> usize {
        let (c, n) = (self.cycle(), n as u64);
        if n.is_power_of_two() {
            (c & (n - 1)) as usize
        } else {
            c.checked_rem(n).unwrap_or(0) as usize
        }
    }
    #[inline]
    pub fn period(&self) -> Time {
        self.period
    }
    pub fn unit(&self) -> UnitId {
        self.unit
    }
    /// Whether a tracer samples this unit's registers. A unit may run through
    /// internal states that touch no link within one evaluation (and sleep until
    /// the first that does) only when nobody watches its registers: that changes
    /// nothing outside it, but the waveform would skip the states in between.
    #[inline]
    pub fn watched(&self) -> bool {
        self.watched
    }

    #[inline]
    fn mark(&mut self, id: LinkId, was_touched: bool) {
        if !was_touched {
            self.touched.push(id);
        }
    }

    /// The payload at the head of an input link, if one is visible this cycle.
    #[inline]
    pub fn peek<T: Payload>(&mut self, port: &In<T>) -> Option<&T> {
        let now = self.now;
        if self.net.head(port.id.0 as usize) > now {
            return None;
        }
        let l = self.net.typed::<T>(port.id);
        // SAFETY: `port` is an input of the unit being evaluated: its consumer.
        unsafe { l.cons() }.peek(now)
    }

    /// Whether an input link still holds an entry behind this cycle's pop (visible or
    /// not). A consumer that pops must look again while this holds: only a push wakes
    /// it, and the entry behind may have been pushed (and its wake-up passed) earlier.
    #[inline]
    pub fn holds_more<T: Payload>(&self, port: &In<T>) -> bool {
        let l = self.net.typed::<T>(port.id);
        // SAFETY: `port` is an input of the unit being evaluated: its consumer.
        unsafe { l.cons() }.left_after_pop() > 0
    }

    /// Whether a payload is visible at the head of an input link this cycle: a
    /// cheaper `peek(..).is_some()` for arbiters that scan many inputs (no
    /// payload-type check).
    #[inline]
    pub fn has_input<T: Payload>(&self, port: &In<T>) -> bool {
        let i = port.id.0 as usize;
        debug_assert_eq!(self.net.head(i), self.net.link_ref(i).head_time());
        self.net.head(i) <= self.now
    }

    /// Bit `i` set when `ports[i]` has a visible head this cycle (`has_input` of up
    /// to 64 ports at once, for arbiters). When the array's links are consecutive
    /// (`PortArray::consecutive_from`) the ports themselves are not loaded.
    #[inline]
    pub fn visible_mask<T: Payload>(&self, ports: &PortArray<In<T>>) -> u64 {
        assert!(ports.len() <= 64, "visible_mask takes at most 64 ports");
        match ports.consecutive_from() {
            Some(first) => {
                let m = self.visible_from(first, ports.len());
                debug_assert_eq!(m, self.visible_mask_scan(ports));
                m
            }
            None => self.visible_mask_scan(ports),
        }
    }

    /// Visible heads of links `first..first + n` (n <= 64) as a bit mask: only the
    /// non-empty ones' heads are loaded, which keeps an arbiter's scan to a word
    /// or two of the bitset.
    #[inline]
    fn visible_from(&self, first: usize, n: usize) -> u64 {
        let mut b = self.net.nonempty_bits(first, n);
        let mut m = 0u64;
        while b != 0 {
            let k = b.trailing_zeros() as usize;
            b &= b - 1;
            m |= ((self.net.head(first + k) <= self.now) as u64) << k;
        }
        m
    }

    /// `visible_mask` over any number of ports: bit `k % 64` of word `k / 64` for
    /// port `k` (`words` is resized to fit).
    pub fn visible_words<T: Payload>(&self, ports: &PortArray<In<T>>, words: &mut Vec<u64>) {
        words.clear();
        match ports.consecutive_from() {
            Some(first) => words.extend(
                (0..ports.len())
                    .step_by(64)
                    .map(|k| self.visible_from(first + k, (ports.len() - k).min(64))),
            ),
            None => words.extend(ports.chunks(64).map(|c| self.visible_mask_scan(c))),
        }
    }

    fn visible_mask_scan<T: Payload>(&self, ports: &[In<T>]) -> u64 {
        let mut m = 0u64;
        for (i, p) in ports.iter().enumerate() {
            let id = p.id.0 as usize;
            debug_assert_eq!(self.net.head(id), self.net.link_ref(id).head_time());
            m |= ((self.net.head(id) <= self.now) as u64) << i;
        }
        m
    }

    /// Takes the head of an input link (at most one per link per cycle).
    #[inline]
    pub fn pop<T: Payload>(&mut self, port: &In<T>) -> Option<T> {
        let now = self.now;
        let me = self.unit;
        let l = self.net.typed::<T>(port.id);
        debug_assert_eq!(l.consumer, Some(me), "unit pops a link it does not consume");
        // SAFETY: `port` is an input of the unit being evaluated: its consumer.
        let c = unsafe { l.cons() };
        let was = c.touched();
        let v = c.pop(now, l.depth);
        let t = c.touched();
        let head = c.head_time();
        self.net.set_head(port.id.0 as usize, head);
        self.link_ops += v.is_some() as u32;
        self.mark(port.id, was || !t);
        v
    }

    /// Whether the output link can take a payload this cycle (registered ready).
    #[inline]
    pub fn can_push<T: Payload>(&mut self, port: &Out<T>) -> bool {
        let s = self.net.space(port.id.0 as usize);
        // SAFETY: `port` is an output of the unit being evaluated: its producer.
        debug_assert_eq!(s, unsafe { self.net.typed::<T>(port.id).prod() }.can_push());
        s
    }

    /// Pushes onto an output link; pushing without `can_push` is a protocol violation.
    #[inline]
    pub fn push<T: Payload>(&mut self, port: &Out<T>, v: T) {
        let now = self.now;
        let l = self.net.typed::<T>(port.id);
        // SAFETY: `port` is an output of the unit being evaluated: its producer.
        let p = unsafe { l.prod() };
        let was = p.touched();
        let consumer = l.consumer;
        let vis = p.push(now, l.delay_ps, v);
        self.net.set_space(port.id.0 as usize, p.can_push());
        self.link_ops += 1;
        self.mark(port.id, was);
        if let (Some(vis), Some(c)) = (vis, consumer) {
            self.wakes.push((c, vis));
        }
    }

    /// Offers a payload: pushed if ready, else held by the link monitor, and the unit
    /// must offer the same payload again until it is taken. Returns whether taken.
    #[inline]
    pub fn offer<T: Payload>(&mut self, port: &Out<T>, v: T) -> bool {
        let now = self.now;
        let l = self.net.typed::<T>(port.id);
        // SAFETY: `port` is an output of the unit being evaluated: its producer.
        let p = unsafe { l.prod() };
        let was = p.touched();
        let consumer = l.consumer;
        let held = p.is_stalled();
        let vis = p.offer(now, l.delay_ps, v);
        self.net.set_space(port.id.0 as usize, p.can_push());
        // Repeating a refused offer (the payload held while stalled) changes nothing.
        if vis.is_some() || !held {
            self.link_ops += 1;
        }
        if vis.is_none() && !held {
            self.stalls.push(port.id);
        }
        self.mark(port.id, was);
        match (vis, consumer) {
            (Some(vis), Some(c)) => {
                self.wakes.push((c, vis));
                true
            }
            (Some(_), None) => true,
            _ => false,
        }
    }

    /// Declares what the unit is doing from this cycle on (for stall statistics).
    #[inline]
    pub fn set_status(&mut self, s: Status) {
        self.new_status = Some(s);
    }

    /// Declares the status from the next cycle on, after this cycle's (the one
    /// `set_status` gives, or the current one): a unit that starts to wait in the
    /// next cycle for a response that cannot come sooner can sleep until it comes
    /// instead of being evaluated once more only to say so.
    #[inline]
    pub fn set_status_from_next(&mut self, s: Status) {
        self.next_status = Some(s);
    }
}

/// The set bits of `words` (see `Ctx::visible_words`) in round-robin order: from
/// `start` up, then from 0 up to `start`.
pub fn round_robin(words: &[u64], start: usize) -> impl Iterator<Item = usize> + '_ {
    let bits = move || {
        words.iter().enumerate().flat_map(|(w, &b)| {
            std::iter::successors((b != 0).then_some(b), |&r| {
                let r = r & (r - 1);
                (r != 0).then_some(r)
            })
            .map(move |r| w * 64 + r.trailing_zeros() as usize)
        })
    };
    bits()
        .filter(move |&k| k >= start)
        .chain(bits().take_while(move |&k| k < start))
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

    /// Adds a clock domain. Its edges are at every multiple of `period_ps`.
    pub fn clock(&mut self, name: &str, period_ps: Time) -> Result<ClockId, SimError> {
        if period_ps == 0 {
            return Err(SimError::Elaboration(format!(
                "clock '{name}' has period 0 ps; give a positive period"
            )));
        }
        self.cal.add_domain(period_ps);
        for c in &mut self.lane_cals {
            c.add_domain(period_ps);
        }
        self.clocks.push(Clock {
            name: name.into(),
            period_ps,
        });
        Ok(ClockId(self.clocks.len() as u16 - 1))
    }

    pub fn clocks(&self) -> &[Clock] {
        &self.clocks
    }

    /// Creates a link; hand its ends to the producer and the consumer.
    pub fn link<T: Payload>(&mut self, name: &str, cfg: LinkCfg) -> (Out<T>, In<T>) {
        let id = LinkId(self.links.len() as u32);
        self.links
            .push(Box::new(Link::<T>::new(name.to_string(), cfg)));
        self.heads.push(Time::MAX);
        self.space.push(true);
        self.nonempty.push(0);
        self.edged.push(Time::MAX);
        self.elaborated = false;
        (Out::new(id), In::new(id))
    }

    /// `n` links named `name(k)`, made one after the other: the producer and the
    /// consumer side of an array port, whose consecutive links let an arbiter
    /// read the non-empty flags of all its inputs at once (`Ctx::visible_mask`).
    pub fn links<T: Payload>(
        &mut self,
        n: usize,
        name: impl Fn(usize) -> String,
        cfg: LinkCfg,
    ) -> (Vec<Out<T>>, Vec<In<T>>) {
        (0..n).map(|k| self.link::<T>(&name(k), cfg)).unzip()
    }

    /// Adds a unit instance under a hierarchical path such as `chip.tm3.box_pipe`.
    pub fn add<U: Unit>(&mut self, path: &str, clock: ClockId, mut unit: U) -> UnitId {
        let period = self.clocks[clock.0 as usize].period_ps;
        unit.number_state();
        self.slots.push(Slot {
            unit: Box::new(unit),
            path: path.to_string(),
            clock,
            period,
            status: Status::WaitInput,
            since: 0,
            status_ps: [0; 4],
            evals: 0,
            out_links: Vec::new(),
            stalled_outs: Vec::new(),
            commit_all: true,
            ahead: None,
            watched: false,
        });
        self.sched.push(Sched {
            edge: EdgeOf::new(period),
            last_wake: Time::MAX,
            clock: clock.0,
        });
        self.parts.push(0);
        self.last_eval.push(Time::MAX);
        self.elaborated = false;
        UnitId(self.slots.len() as u32 - 1)
    }

    /// Puts a unit in evaluation partition 0 (the default: evaluated by the
    /// caller's thread after the others) or 1..=N for N = `threads` (evaluated
    /// concurrently with the other lanes; N on the caller's thread). Links may
    /// join any partitions: each end changes only its own half of a link. A lane
    /// plan ([`Sim::set_lane_plan`]) replaces these.
    pub fn set_part(&mut self, u: UnitId, part: u8) -> Result<(), SimError> {
        let max = self.opts.threads.max(2);
        if part as usize > max {
            return Err(SimError::Elaboration(format!(
                "unit '{}' put in partition {part}; with {} thread(s) the partitions are 0 to {max}",
                self.slots[u.0 as usize].path, self.opts.threads
            )));
        }
        self.parts[u.0 as usize] = part;
        self.elaborated = false;
        Ok(())
    }

    /// Spreads the units over the lanes by groups (a TM each, moved between
    /// lanes together by load balancing, in order and evenly spread) and a
    /// list of units for the first lane (a worker's); every other unit goes to
    /// the last lane, the caller's thread. Re-applied whenever the lane count
    /// changes (`SimOptions::auto_lanes`).
    pub fn set_lane_plan(&mut self, groups: Vec<Vec<UnitId>>, first: Vec<UnitId>) {
        self.plan = Some(LanePlan {
            groups: groups
                .into_iter()
                .map(|g| g.into_iter().map(|u| u.0).collect())
                .collect(),
            first: first.into_iter().map(|u| u.0).collect(),
        });
        self.apply_plan();
    }

    /// Partitions from the lane plan for the current lane count.
    fn apply_plan(&mut self) {
        let Some(plan) = &self.plan else { return };
        let l = if self.parallel() { self.lanes } else { 1 };
        if l < 2 {
            self.parts.iter_mut().for_each(|p| *p = 0);
        } else {
            self.parts.iter_mut().for_each(|p| *p = l as u8);
            let n = plan.groups.len().max(1);
            for (k, g) in plan.groups.iter().enumerate() {
                let part = 1 + (k * l / n) as u8;
                for &u in g {
                    self.parts[u as usize] = part;
                }
            }
            for &u in &plan.first {
                self.parts[u as usize] = 1;
            }
        }
        self.balance.lane_ns = vec![0; l.max(1)];
        self.balance.steps = 0;
        if !self.local.is_empty() {
            self.relocal();
        }
    }

    /// Whether a step may evaluate partitions on several threads.
    fn parallel(&self) -> bool {
        self.opts.threads >= 2 && self.opts.sleep && !self.opts.shadow
    }

    /// Lanes in use now (1 when the run is on one thread).
    pub fn lanes(&self) -> usize {
        if self.parallel() { self.lanes } else { 1 }
    }

    /// Steps taken so far with each lane count (index: lanes - 1).
    pub fn steps_by_lanes(&self) -> &[u64] {
        &self.steps_by_lanes
    }

    /// Times the automatic lane choice changed the count.
    pub fn lane_switches(&self) -> u64 {
        self.auto.switches
    }

    /// Tests: with `auto_lanes`, switch among the candidate lane counts every
    /// `steps` steps instead of measuring (results must not change).
    pub fn force_lane_switches(&mut self, steps: u64) {
        self.auto.forced_every = Some(steps.max(1));
    }

    /// Binds every link to its producer and consumer and checks the netlist.
    pub fn elaborate(&mut self) -> Result<(), SimError> {
        if self.elaborated {
            return Ok(());
        }
        let mut seen = std::collections::HashSet::new();
        for s in &self.slots {
            if !seen.insert(s.path.clone()) {
                return Err(SimError::Elaboration(format!(
                    "two units are named '{}'; instance paths must be unique",
                    s.path
                )));
            }
        }
        let mut ends: Vec<(Option<UnitId>, Option<UnitId>)> = vec![(None, None); self.links.len()];
        for (i, s) in self.slots.iter_mut().enumerate() {
            s.out_links.clear();
            for p in s.unit.ports() {
                let e = &mut ends[p.link.0 as usize];
                let lname = self.links[p.link.0 as usize].name().to_string();
                let (slot, role) = match p.dir {
                    super::decl::PortDir::Out => (&mut e.0, "producer"),
                    super::decl::PortDir::In => (&mut e.1, "consumer"),
                };
                if let Some(other) = slot {
                    return Err(SimError::Elaboration(format!(
                        "link '{lname}' has two {role}s ('{}' and unit #{}); a link connects exactly one producer to one consumer",
                        s.path, other.0
                    )));
                }
                *slot = Some(UnitId(i as u32));
                if p.dir == super::decl::PortDir::Out {
                    s.out_links.push(p.link);
                }
            }
        }
        for (l, (p, c)) in self.links.iter_mut().zip(&ends) {
            l.cfg()
                .validate(&format!("link '{}'", l.name()))
                .map_err(SimError::Elaboration)?;
            let (Some(p), Some(_)) = (p, c) else {
                return Err(SimError::Elaboration(format!(
                    "link '{}' has no {}; connect it to a unit (a testbench driver or sink if nothing else)",
                    l.name(),
                    if p.is_none() { "producer" } else { "consumer" }
                )));
            };
            l.set_ends(Some(*p), *c);
            l.set_delay_ps(l.cfg().delay as Time * self.slots[p.0 as usize].period);
        }
        self.local = vec![0; self.links.len()];
        self.relocal();
        // A lane's time per balancing window (the plan's partitions or `set_part`'s).
        self.balance.lane_ns = vec![0; self.lanes];
        self.elaborated = true;
        self.reset();
        Ok(())
    }

    /// Synchronous reset: every register to its reset value, links empty, time 0,
    /// every unit evaluated at time 0.
    pub fn reset(&mut self) {
        self.now = 0;
        self.stepped = false;
        self.cal.clear();
        for c in &mut self.lane_cals {
            c.clear();
        }
        self.evals = 0;
        self.steps = 0;
        self.parallel_steps = 0;
        for l in &mut self.links {
            l.reset();
        }
        self.heads.iter_mut().for_each(|h| *h = Time::MAX);
        self.nonempty.iter_mut().for_each(|b| *b = 0);
        self.edged.iter_mut().for_each(|h| *h = Time::MAX);
        for (s, l) in self.space.iter_mut().zip(&self.links) {
            *s = l.has_space();
        }
        self.out = LaneOut::default();
        for (i, s) in self.slots.iter_mut().enumerate() {
            s.unit.reset();
            s.status = Status::WaitInput;
            s.ahead = None;
            s.since = 0;
            s.status_ps = [0; 4];
            s.evals = 0;
            s.stalled_outs.clear();
            let sc = &mut self.sched[i];
            sc.last_wake = 0;
            self.last_eval[i] = Time::MAX;
            self.cal.push(sc.clock as usize, i as u32, 0);
        }
    }

    pub fn now(&self) -> Time {
        self.now
    }

    /// Current cycle of a clock.
    pub fn cycle(&self, clock: ClockId) -> u64 {
        self.now / self.clocks[clock.0 as usize].period_ps
    }

    /// Wakes a unit at its next clock edge (for testbenches that poke a unit's queue
    /// between runs).
    pub fn wake(&mut self, u: UnitId) {
        let t = if self.stepped { self.now + 1 } else { self.now };
        self.sched[u.0 as usize].at_time(&mut self.cal, u.0, t);
    }

    /// Time of the next step, if any unit is scheduled.
    fn next_time(&mut self) -> Option<Time> {
        let mut t = self.lane_cals.iter().map(|c| c.next_time()).fold(
            self.cal.next_time(),
            |a, b| match (a, b) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            },
        )?;
        let after = if self.stepped { self.now + 1 } else { self.now };
        let edge_after = |p: Time| after.div_ceil(p) * p;
        if !self.opts.sleep {
            for c in &self.clocks {
                t = t.min(edge_after(c.period_ps));
            }
        }
        if let Some(tr) = &self.tracer
            && let Some(te) = tr.next_sample_time(after, &self.clocks)
        {
            t = t.min(te);
        }
        Some(t)
    }

    /// Runs until time `limit` (ps), which becomes the current time even if every
    /// unit went to sleep before (so statistics do not depend on which edges
    /// happened to be processed). Returns `Idle` if nothing is scheduled any more.
    pub fn run(&mut self, limit: Time) -> Result<RunEnd, SimError> {
        self.run_inner(limit, false)
    }

    fn run_inner(&mut self, limit: Time, stop_when_idle: bool) -> Result<RunEnd, SimError> {
        self.elaborate()?;
        if !self.parallel() || self.tracer.is_some() {
            return self.run_loop(limit, stop_when_idle, None);
        }
        let crew = Crew::new(self.opts.threads - 1);
        self.lane_seq = 0;
        std::thread::scope(|s| {
            let crew = &crew;
            let handles: Vec<_> = (0..crew.workers.len())
                .map(|k| s.spawn(move || crew.worker_loop(k)).thread().clone())
                .collect();
            crew.threads
                .set(handles)
                .expect("a run's workers are spawned once");
            // Ends the workers however the loop ends: a panic on this thread
            // would otherwise leave the scope waiting for them forever.
            struct Quit<'c>(&'c Crew);
            impl Drop for Quit<'_> {
                fn drop(&mut self) {
                    self.0.quit();
                }
            }
            let _quit = Quit(crew);
            self.run_loop(limit, stop_when_idle, Some(crew))
        })
    }

    fn run_loop(
        &mut self,
        limit: Time,
        stop_when_idle: bool,
        crew: Option<&Crew>,
    ) -> Result<RunEnd, SimError> {
        if self.auto.on && crew.is_some() {
            self.auto.since = Some(Instant::now());
        }
        let r = self.run_steps(limit, stop_when_idle, crew);
        if let Some(t0) = self.auto.since.take() {
            self.auto.phase_ns += t0.elapsed().as_nanos() as u64;
        }
        r
    }

    fn run_steps(
        &mut self,
        limit: Time,
        stop_when_idle: bool,
        crew: Option<&Crew>,
    ) -> Result<RunEnd, SimError> {
        loop {
            match self.next_time() {
                None => {
                    if !stop_when_idle && limit > self.now {
                        self.now = limit;
                        self.stepped = false;
                    }
                    return Ok(RunEnd::Idle);
                }
                Some(t) if t > limit => {
                    if limit > self.now {
                        self.now = limit;
                        self.stepped = false;
                    }
                    return Ok(RunEnd::Limit);
                }
                Some(t) => {
                    self.step_at(t, crew)?;
                    if crew.is_some() {
                        self.steps_by_lanes[self.lanes - 1] += 1;
                        if self.auto.on {
                            self.auto_tick();
                        }
                    }
                }
            }
        }
    }

    /// One step of the automatic lane choice: at the end of a phase, measure
    /// it and go on to the next (see `AutoLanes`).
    fn auto_tick(&mut self) {
        let a = &mut self.auto;
        let steps = self.steps - a.phase_steps;
        if let Some(every) = a.forced_every {
            if steps >= every {
                a.phase_steps = self.steps;
                let next = (a.chosen + 1) % a.candidates.len();
                a.chosen = next;
                a.switches += 1;
                self.set_lanes(self.auto.candidates[next]);
            }
            return;
        }
        let Some(t0) = a.since else { return };
        // Phases are measured in wall time (a probe of a much slower lane count
        // must end after its time, not after a number of its slow steps); a
        // look at the clock every 16 steps is free beside the steps.
        if steps < lanes::PROBE_STEPS || !steps.is_multiple_of(16) {
            return;
        }
        let now = Instant::now();
        let ns = a.phase_ns + (now - t0).as_nanos() as u64;
        let min_ns = match a.phase {
            Phase::Run => lanes::PROBE.as_nanos() as u64 * a.epoch as u64,
            _ => lanes::PROBE.as_nanos() as u64,
        };
        if ns < min_ns {
            return;
        }
        let evals = (self.evals - a.phase_evals).max(1);
        let per_eval = ns as f64 / evals as f64;
        let next_lanes = match a.phase {
            Phase::Run => {
                a.phase = Phase::Base;
                None
            }
            Phase::Base => {
                a.base_ns = per_eval;
                let k = a.neighbour();
                a.phase = Phase::Probe(k);
                Some(a.candidates[k])
            }
            Phase::Probe(k) => {
                a.phase = Phase::Run;
                if per_eval < a.base_ns * lanes::PROBE_MARGIN {
                    a.chosen = k;
                    a.epoch = lanes::EPOCH_MIN;
                    a.switches += 1;
                } else {
                    a.epoch = (a.epoch * 2).min(lanes::EPOCH_MAX);
                }
                Some(a.candidates[a.chosen])
            }
        };
        a.phase_steps = self.steps;
        a.phase_evals = self.evals;
        a.phase_ns = 0;
        a.since = Some(now);
        if let Some(l) = next_lanes {
            self.set_lanes(l);
        }
    }

    /// Changes the lane count between steps (with a lane plan).
    fn set_lanes(&mut self, l: usize) {
        if l != self.lanes && self.plan.is_some() {
            self.lanes = l;
            self.apply_plan();
        }
    }

    /// Runs `n` cycles of `clock` from now.
    pub fn run_cycles(&mut self, clock: ClockId, n: u64) -> Result<RunEnd, SimError> {
        let p = self.clocks[clock.0 as usize].period_ps;
        let limit = (self.now / p + n) * p;
        self.run(limit)
    }

    /// Runs until idle, failing if that takes longer than `limit` ps.
    /// Runs until every unit sleeps with nothing scheduled or until `limit`,
    /// whichever comes first (a run cut into pieces gives the same result).
    pub fn run_until(&mut self, limit: Time) -> Result<RunEnd, SimError> {
        self.run_inner(limit, true)
    }

    pub fn run_to_idle(&mut self, limit: Time) -> Result<Time, SimError> {
        match self.run_inner(limit, true)? {
            RunEnd::Idle => Ok(self.now),
            RunEnd::Limit => Err(SimError::Elaboration(format!(
                "the design was still busy after {limit} ps; raise the limit or look for a unit that never sleeps"
            ))),
        }
    }

    fn step_at(&mut self, t: Time, crew: Option<&Crew>) -> Result<(), SimError> {
        self.now = t;
        self.stepped = true;
        self.steps += 1;
        // Units that are due (scheduled for t).
        self.due.clear();
        self.cal.take(t, &mut self.taken);
        for c in &mut self.lane_cals {
            c.take(t, &mut self.taken);
        }
        for &u in &self.taken {
            let e = &mut self.last_eval[u as usize];
            if *e != t {
                *e = t;
                self.due.push((u, true));
            }
        }
        self.taken.clear();
        // Sleep off: every unit whose clock has an edge now, due or not.
        if !self.opts.sleep {
            for (i, s) in self.sched.iter().enumerate() {
                if t.is_multiple_of(s.edge.period) && self.last_eval[i] != t {
                    self.due.push((i as u32, false));
                }
            }
        }
        if let Some(rng) = &mut self.rng {
            rng.shuffle(&mut self.due);
        }
        let mut due = std::mem::take(&mut self.due);
        if let Some(crew) = crew
            && self.lanes >= 2
        {
            // Partitions 1..=lanes on their threads, each unit committed by its
            // thread right after its evaluation (see `eval_commit`); partition 0
            // after, below.
            let parts = &self.parts;
            let lane_due = &mut self.lane_due[..self.lanes];
            lane_due.iter_mut().for_each(Vec::clear);
            due.retain(|&(u, d)| match parts[u as usize] {
                0 => true,
                p => {
                    lane_due[p as usize - 1].push((u, d));
                    false
                }
            });
            let busy = lane_due.iter().filter(|l| !l.is_empty()).count();
            if busy >= 2 {
                self.run_lanes(crew, t)?;
            } else {
                // Only one partition has work: no hand-over.
                let mut l = std::mem::take(&mut self.lane_due);
                for &(u, d) in l[..self.lanes].iter().flatten() {
                    self.eval_commit(u, d)?;
                }
                std::mem::swap(&mut l, &mut self.lane_due);
            }
        }
        if self.tracer.is_some() {
            for &(u, is_due) in &due {
                self.eval_unit(u, is_due)?;
            }
            // The waveform samples every register before the edge.
            let slots = &self.slots;
            if let Some(tr) = &mut self.tracer {
                tr.sample(t, &|i| &*slots[i].unit, &self.links);
                if let Some(why) = tr.stopped() {
                    return Err(SimError::Trace(why.to_string()));
                }
            }
            // Clock edge.
            for &(u, _) in &due {
                self.slots[u as usize].unit.commit();
            }
        } else {
            for &(u, is_due) in &due {
                self.eval_commit(u, is_due)?;
            }
        }
        self.due = due;
        self.evals += std::mem::take(&mut self.out.evals);
        let mut violations = std::mem::take(&mut self.out.violations);
        for &l in &self.out.touched {
            // Producer and consumer each list a link they touched: edge it once.
            if self.edged[l.0 as usize] == t {
                continue;
            }
            self.edged[l.0 as usize] = t;
            let link = &mut self.links[l.0 as usize];
            debug_assert!(link.touched());
            let e = link.edge(&mut violations);
            self.heads[l.0 as usize] = e.head;
            self.nonempty[l.0 as usize] = (e.head != Time::MAX) as u8;
            self.space[l.0 as usize] = e.space;
            if e.wake_producer {
                let (p, _) = link.ends();
                let p = p.expect("elaborated link has a producer");
                self.out.wakes.push((p, t + 1));
            }
        }
        self.out.touched.clear();
        if !violations.is_empty() {
            return Err(SimError::Protocol(violations));
        }
        for &(u, n, cycle) in &self.out.nexts {
            let path = &self.slots[u as usize].path;
            self.sched[u as usize].next(&mut self.cal, u, n, cycle, path);
        }
        self.out.nexts.clear();
        for (u, w) in self.out.wakes.drain(..) {
            self.sched[u.0 as usize].at_time(&mut self.cal, u.0, w);
        }
        Ok(())
    }

    /// Evaluates and commits the due units of the worker lanes on their
    /// workers and those of the last lane on this thread, at the same time.
    fn run_lanes(&mut self, crew: &Crew, t: Time) -> Result<(), SimError> {
        let l = self.lanes;
        let net = Net::of(
            &mut self.links,
            &mut self.heads,
            &mut self.space,
            &mut self.nonempty,
        );
        let lanes = Lanes {
            slots: self.slots.as_mut_ptr(),
            n_slots: self.slots.len(),
            net,
            local: self.local.as_ptr(),
            sched: self.sched.as_mut_ptr(),
            parts: self.parts.as_ptr(),
            main_cal: &mut self.cal,
            lane_cals: self.lane_cals.as_mut_ptr(),
            lanes: l as u8,
        };
        self.lane_seq += 1;
        self.parallel_steps += 1;
        let seq = self.lane_seq;
        // Worker k evaluates lane k + 1.
        let mut started = std::mem::take(&mut self.lane_started);
        started.clear();
        for k in 0..l - 1 {
            if self.lane_due[k].is_empty() {
                continue;
            }
            {
                // SAFETY: the worker is waiting for `go` and does not touch the job.
                let job = unsafe { &mut *crew.workers[k].job.get() };
                job.now = t;
                job.part = (k + 1) as u8;
                job.lanes = lanes;
                std::mem::swap(&mut job.due, &mut self.lane_due[k]);
            }
            crew.start(k, seq);
            started.push(k);
        }
        // From here until every `done`, this thread reaches slots and links only
        // through `lanes`, and only those of the last lane.
        let t0 = Instant::now();
        // SAFETY: the last lane is this thread's; each worker takes its own.
        let mut result =
            unsafe { run_lane(lanes, l as u8, &self.lane_due[l - 1], t, &mut self.out) };
        let main_ns = t0.elapsed().as_nanos() as u64;
        for &k in &started {
            crew.wait(k, seq);
            // SAFETY: the worker is done with this step and waits for the next `go`.
            let job = unsafe { &mut *crew.workers[k].job.get() };
            std::mem::swap(&mut job.due, &mut self.lane_due[k]);
            self.out.append(&mut job.out);
            self.balance.lane_ns[k] += job.lane_ns;
            result = result.and(std::mem::replace(&mut job.result, Ok(())));
        }
        self.lane_started = started;
        self.balance.lane_ns[l - 1] += main_ns;
        self.balance.steps += 1;
        if self.balance.steps >= self.balance.window {
            self.rebalance();
        }
        result
    }

    /// Load balancing every `window` parallel steps (default `BALANCE_STEPS`);
    /// `always_move` moves a group at every decision, from the partition with more
    /// groups, whatever the times (tests: a deterministic exercise of the moves).
    pub fn set_balance(&mut self, window: u64, always_move: bool) {
        self.balance.window = window.max(1);
        self.balance.always_move = always_move;
    }

    /// Groups moved between the partitions so far (see `set_lane_plan`).
    pub fn balance_moves(&self) -> u64 {
        self.balance.moves
    }

    /// Moves one group between two neighbouring lanes: every `BALANCE_STEPS`
    /// parallel steps, the boundary group of the slower lane of the pair whose
    /// times differ most goes to the other, when the gap exceeds a group's
    /// share. Wall-clock driven, and so not reproducible in speed, but results
    /// do not depend on the partition (see `set_part`).
    fn rebalance(&mut self) {
        let l = self.lanes;
        let ns = std::mem::replace(&mut self.balance.lane_ns, vec![0; l]);
        self.balance.steps = 0;
        let Some(plan) = &self.plan else { return };
        if l < 2 {
            return;
        }
        let parts = &self.parts;
        let part_of = |g: &Vec<u32>| g.first().map(|&u| parts[u as usize]);
        let count = |p: u8| plan.groups.iter().filter(|g| part_of(g) == Some(p)).count();
        // Lane k (1-based) against lane k + 1.
        let (from, to) = if self.balance.always_move {
            let k = 1 + (self.balance.moves as usize) % (l - 1);
            let (a, b) = (k as u8, k as u8 + 1);
            if count(a) >= count(b) { (a, b) } else { (b, a) }
        } else {
            let Some(k) = (1..l).max_by_key(|&k| ns[k - 1].abs_diff(ns[k])) else {
                return;
            };
            let (a, b) = (k as u8, k as u8 + 1);
            let (from, to, slow, fast) = if ns[k - 1] > ns[k] {
                (a, b, ns[k - 1], ns[k])
            } else {
                (b, a, ns[k], ns[k - 1])
            };
            // Move when the gap exceeds the cost of one group of the slower side.
            if (slow - fast) as f64 <= slow as f64 / count(from).max(1) as f64 {
                return;
            }
            (from, to)
        };
        if count(from) < 2 {
            return;
        }
        // The group at the boundary between the two lanes (TMs stay contiguous).
        let pick = if from < to {
            plan.groups.iter().rposition(|g| part_of(g) == Some(from))
        } else {
            plan.groups.iter().position(|g| part_of(g) == Some(from))
        };
        let Some(k) = pick else { return };
        for &u in &plan.groups[k].clone() {
            self.parts[u as usize] = to;
        }
        self.balance.moves += 1;
        self.relocal();
    }

    /// Recomputes which partition takes each link's edge.
    fn relocal(&mut self) {
        for (i, l) in self.links.iter().enumerate() {
            let (p, c) = l.ends();
            let pp = p.map_or(0, |p| self.parts[p.0 as usize]);
            let cp = c.map_or(0, |c| self.parts[c.0 as usize]);
            self.local[i] = if pp == cp { pp } else { 0 };
        }
    }

    /// Evaluates a unit and commits it at once: no unit reads another's registers,
    /// so that is the clock edge's result, reached while the unit's state is still
    /// in the cache. Only a tracer, which samples every register before the edge,
    /// needs the edge as a separate phase.
    fn eval_commit(&mut self, u: u32, is_due: bool) -> Result<(), SimError> {
        let (net, shadow) = self.net_for(is_due);
        let slot = &mut self.slots[u as usize];
        eval_commit_slot(slot, u, self.now, net, &mut self.out, is_due, shadow)
    }

    fn eval_unit(&mut self, u: u32, is_due: bool) -> Result<(), SimError> {
        let (net, shadow) = self.net_for(is_due);
        let slot = &mut self.slots[u as usize];
        eval_slot(slot, u, self.now, net, &mut self.out, is_due, shadow)
    }

    /// The links as an evaluation on the caller's thread sees them, and whether
    /// a unit evaluated while not due is checked as a shadow.
    fn net_for(&mut self, is_due: bool) -> (Net, bool) {
        let net = Net::of(
            &mut self.links,
            &mut self.heads,
            &mut self.space,
            &mut self.nonempty,
        );
        (net, !is_due && self.opts.shadow)
    }

    /// Evaluations so far by unit kind (Verilog module name): units of the kind
    /// and their evaluations, most evaluated first (ties by name). Where a
    /// simulation's time goes: an evaluation costs about the same whatever the
    /// unit (docs/kernel.md).
    pub fn evals_by_module(&self) -> Vec<ModuleEvals> {
        let mut m: std::collections::BTreeMap<&'static str, ModuleEvals> = Default::default();
        for s in &self.slots {
            let module = s.unit.decl().module;
            let e = m.entry(module).or_insert(ModuleEvals {
                module,
                units: 0,
                evals: 0,
            });
            e.units += 1;
            e.evals += s.evals;
        }
        let mut v: Vec<ModuleEvals> = m.into_values().collect();
        v.sort_by(|a, b| b.evals.cmp(&a.evals).then(a.module.cmp(b.module)));
        v
    }

    pub fn unit_count(&self) -> usize {
        self.slots.len()
    }

    pub fn unit_path(&self, u: UnitId) -> &str {
        &self.slots[u.0 as usize].path
    }

    pub fn unit_id(&self, path: &str) -> Option<UnitId> {
        self.slots
            .iter()
            .position(|s| s.path == path)
            .map(|i| UnitId(i as u32))
    }

    pub fn unit(&self, u: UnitId) -> &dyn Unit {
        &*self.slots[u.0 as usize].unit
    }

    /// Typed access to a unit between steps (testbenches). Wake it after changing it.
    pub fn unit_mut<U: Unit>(&mut self, u: UnitId) -> &mut U {
        let slot = &mut self.slots[u.0 as usize];
        slot.commit_all = true;
        super::unit::downcast_mut::<U>(&mut *slot.unit).expect("unit type matches")
    }

    pub fn unit_ref<U: Unit>(&self, u: UnitId) -> &U {
        super::unit::downcast_ref::<U>(&*self.slots[u.0 as usize].unit).expect("unit type matches")
    }

    pub fn unit_clock(&self, u: UnitId) -> ClockId {
        self.slots[u.0 as usize].clock
    }

    /// Status cycles integrated up to now, and the unit's counters.
    pub fn unit_stats(&self, u: UnitId) -> UnitStats {
        let s = &self.slots[u.0 as usize];
        let mut ps = s.status_ps;
        match s.ahead {
            // A status from the next cycle on, not begun yet.
            Some(a) if self.now < s.since => ps[a as usize] -= s.since - self.now,
            _ => ps[s.status as usize] += self.now - s.since,
        }
        UnitStats {
            path: s.path.clone(),
            module: s.unit.decl().module,
            status_cycles: ps.map(|x| x / s.period),
            counters: s.unit.counters(),
        }
    }

    pub fn all_stats(&self) -> Vec<UnitStats> {
        (0..self.slots.len())
            .map(|i| self.unit_stats(UnitId(i as u32)))
            .collect()
    }

    pub fn link_stats(&self) -> Vec<(String, LinkStats)> {
        self.links
            .iter()
            .map(|l| (l.name().to_string(), l.stats()))
            .collect()
    }

    pub fn link_occupancy(&self, id: LinkId) -> u32 {
        self.links[id.0 as usize].occupancy()
    }

    /// Turns on the transfer log of a link (testbenches check latencies with it).
    pub fn log_link(&mut self, id: LinkId, on: bool) {
        self.links[id.0 as usize].set_log(on);
    }

    pub fn link_log(&self, id: LinkId) -> &[LinkEvent] {
        self.links[id.0 as usize].log()
    }

    /// Attaches a VCD tracer (see [`super::trace`]).
    pub fn attach_tracer(&mut self, mut tracer: Tracer) -> Result<(), SimError> {
        self.elaborate()?;
        let units: Vec<(&str, &dyn Unit, &Clock)> = self
            .slots
            .iter()
            .map(|s| (s.path.as_str(), &*s.unit, &self.clocks[s.clock.0 as usize]))
            .collect();
        if let Err(e) = tracer.bind(&units) {
            tracer.discard();
            return Err(SimError::Elaboration(e));
        }
        if let Err(e) = tracer.check_estimate() {
            tracer.discard();
            return Err(SimError::Trace(e));
        }
        for i in tracer.unit_indices() {
            self.slots[i].watched = true;
        }
        self.tracer = Some(tracer);
        Ok(())
    }

    /// Detaches the tracer, flushing its output.
    pub fn finish_trace(&mut self) -> Option<std::io::Result<super::trace::TraceStats>> {
        let now = self.now;
        for s in &mut self.slots {
            s.watched = false;
        }
        self.tracer.take().map(|t| t.finish(now))
    }

    /// Every unit's declaration with its instance path (for hdl emission and reports).
    pub fn decls(&self) -> Vec<(String, super::decl::UnitDecl)> {
        self.slots
            .iter()
            .map(|s| (s.path.clone(), s.unit.decl()))
            .collect()
    }
}

/// Evaluates a unit and takes its clock edge at once, on this thread (see
/// [`Sim::eval_commit`]): the edge commits only the registers the evaluation
/// wrote, unless the unit was changed from outside since its last edge.
#[inline]
fn eval_commit_slot(
    slot: &mut Slot,
    u: u32,
    t: Time,
    net: Net,
    out: &mut LaneOut,
    is_due: bool,
    shadow: bool,
) -> Result<(), SimError> {
    state::take_written();
    eval_slot(slot, u, t, net, out, is_due, shadow)?;
    let written = state::take_written();
    if std::mem::take(&mut slot.commit_all) {
        slot.unit.commit();
    } else {
        slot.unit.commit_written(written);
    }
    // A register written but not marked would stay pending past its edge.
    debug_assert!(
        !slot.unit.state_pending(),
        "{}: a register changes after its edge (written mask {written:#x})",
        slot.path
    );
    Ok(())
}

/// Evaluates one unit (the body of a step for it): builds its context, runs its
/// logic, re-checks its held offers and records its status and next wake-up.
#[allow(clippy::too_many_arguments)]
fn eval_slot(
    slot: &mut Slot,
    u: u32,
    t: Time,
    net: Net,
    out: &mut LaneOut,
    is_due: bool,
    shadow: bool,
) -> Result<(), SimError> {
    let before = if shadow {
        Some(slot.unit.counters())
    } else {
        None
    };
    if out.clock.0 != t || out.clock.1 != slot.period {
        out.clock = (t, slot.period, t / slot.period);
    }
    let mut ctx = Ctx {
        now: t,
        cycle: out.clock.2,
        period: slot.period,
        unit: UnitId(u),
        net,
        touched: &mut out.touched,
        wakes: &mut out.wakes,
        stalls: &mut slot.stalled_outs,
        new_status: None,
        next_status: None,
        link_ops: 0,
        watched: slot.watched,
    };
    let next = slot.unit.eval(&mut ctx);
    let (new_status, next_status, link_ops) = (ctx.new_status, ctx.next_status, ctx.link_ops);
    if !slot.stalled_outs.is_empty() {
        let touched = &mut out.touched;
        slot.stalled_outs.retain(|&l| {
            // The unit is the producer of its stalled outputs.
            let link = net.link_ref(l.0 as usize);
            if link.check_offer_held(t) {
                touched.push(l);
            }
            link.is_stalled()
        });
    }
    if shadow {
        let what = if link_ops > 0 {
            Some("a link (it pushed, popped or offered)".to_string())
        } else if slot.unit.state_pending() {
            Some("its registers".to_string())
        } else if let Some(s) = new_status.or(next_status).filter(|&s| s != slot.status) {
            Some(format!(
                "its status ({} -> {})",
                slot.status.name(),
                s.name()
            ))
        } else if before.as_ref() != Some(&slot.unit.counters()) {
            Some("its counters".to_string())
        } else {
            None
        };
        if let Some(what) = what {
            return Err(SimError::Shadow {
                unit: slot.path.clone(),
                at: t,
                what,
            });
        }
        return Ok(());
    }
    if let Some(s) = new_status
        && s != slot.status
    {
        slot.status_ps[slot.status as usize] += t - slot.since;
        slot.status = s;
        slot.since = t;
    }
    if let Some(s) = next_status
        && s != slot.status
    {
        // Credited ahead: no evaluation comes before the next cycle.
        let from = t + slot.period;
        slot.status_ps[slot.status as usize] += from - slot.since;
        slot.ahead = Some(slot.status);
        slot.status = s;
        slot.since = from;
    }
    if is_due {
        slot.evals += 1;
        out.evals += 1;
        out.nexts.push((u, next, out.clock.2));
    }
    Ok(())
}

/// Scheduling unit `u`, this record's unit, in a calendar. Every wake-up is kept
/// (a unit may be woken by a link before the time it asked for, and must still
/// run at that time); duplicates of one time are skipped.
impl Sched {
    /// At cycle `c` of the unit's clock.
    #[inline]
    fn at_cycle(&mut self, cal: &mut super::calendar::Calendar, u: u32, c: u64) {
        let t = c * self.edge.period;
        if t != self.last_wake {
            self.last_wake = t;
            cal.push_cycle(self.clock as usize, u, c, t);
        }
    }

    /// At the unit's first clock edge at or after `t`.
    #[inline]
    fn at_time(&mut self, cal: &mut super::calendar::Calendar, u: u32, t: Time) {
        let c = self.edge.cycle_at_or_after(t);
        self.at_cycle(cal, u, c);
    }

    /// Where the unit (`path`), evaluated in `cycle` of its clock, asked to run
    /// next (`n`).
    #[inline]
    fn next(
        &mut self,
        cal: &mut super::calendar::Calendar,
        u: u32,
        n: Next,
        cycle: u64,
        path: &str,
    ) {
        let c = match n {
            Next::Cycle => cycle + 1,
            Next::AtCycle(c) => {
                assert!(
                    c > cycle,
                    "unit '{path}' asked to wake at cycle {c}, which is not in the future"
                );
                c
            }
            Next::Idle => return,
        };
        self.at_cycle(cal, u, c);
    }
}

#[cfg(test)]
mod tests {
    use super::{EdgeOf, round_robin};

    #[test]
    fn edge_of_is_div_ceil() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for p in [
            1u64,
            2,
            3,
            7,
            64,
            667,
            1000,
            1250,
            1_000_003,
            (1 << 20) + 1,
            1 << 40,
        ] {
            let e = EdgeOf::new(p);
            let mut ts = vec![
                0,
                1,
                p - 1,
                p,
                p + 1,
                e.exact_to,
                e.exact_to.saturating_add(1),
            ];
            ts.extend([u64::MAX - 1, u64::MAX]);
            for k in [1u64, 2, 3, 1 << 20, 66_000_000, 1 << 40] {
                if let Some(m) = k.checked_mul(p) {
                    ts.extend([m - 1, m, m.saturating_add(1)]);
                }
            }
            for _ in 0..10_000 {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                ts.push(x);
                ts.push(x >> 20);
                ts.push((x >> 24) / p * p);
            }
            for t in ts {
                assert_eq!(e.cycle_at_or_after(t), t.div_ceil(p), "t = {t}, period {p}");
            }
        }
    }

    #[test]
    fn round_robin_visits_set_bits_from_start_then_wraps() {
        // Bits 3, 64, 70 and 127 of two words.
        let w = [1u64 << 3, 1 | 1 << 6 | 1 << 63];
        let all = |s| round_robin(&w, s).collect::<Vec<_>>();
        assert_eq!(all(0), [3, 64, 70, 127]);
        assert_eq!(all(4), [64, 70, 127, 3]);
        assert_eq!(all(70), [70, 127, 3, 64]);
        assert_eq!(all(128), [3, 64, 70, 127]);
        assert!(round_robin(&[0, 0], 5).next().is_none());
    }
}
