//! A fixed-latency, fixed-initiation-interval pipeline stored as a timestamped ring.
//!
//! Equivalent to `stages` stage registers of `Option<T>` with a global stall enable:
//! a request accepted (popped from the input link) in cycle `a` is pushed onto the
//! output link in cycle `a + stages` and, with an output link of delay `d`, is seen by
//! the consumer in cycle `a + stages + d`. A unit with end-to-end latency `L` therefore
//! has `stages = L - d`: the output link register *is* the pipeline's last stage, so
//! the configured latency is delivered exactly, with no invisible extra cycle.
//!
//! When the output link is full the whole pipeline freezes (the stalled result holds
//! its data, nothing advances, nothing is accepted) and resumes where it stopped.
//! Frozen cycles are accounted from timestamps, so the unit may sleep while stalled.
//! Time inside the pipeline is "local": cycles in which it was not frozen.

use std::collections::VecDeque;

use super::bits::Payload;
use super::decl::{Samples, StateDecl, StateList};
use super::link::{In, LinkCfg, Out};
use super::sim::Ctx;
use super::state::{Reg, State};
use super::unit::{Next, Status};

/// A fixed-latency pipelined unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PipeCfg {
    /// Cycles from acceptance of a request to the result being visible to the
    /// requester, including the output link register.
    pub latency: u32,
    /// Initiation interval: cycles between two acceptances.
    pub interval: u32,
}

pub struct FixedPipe<T: Payload> {
    stages: u32,
    interval: u32,
    capacity: u32,
    /// Committed contents: (local cycle of acceptance, request), oldest first.
    ring: VecDeque<(u64, T)>,
    pending_accept: Option<(u64, T)>,
    pending_exit: bool,
    /// Frozen cycles before the current freeze.
    frozen: Reg<u64>,
    /// Cycle at which the current freeze began.
    freeze_start: Reg<Option<u64>>,
    /// Local cycle of the last acceptance (initiation interval).
    last_accept: Reg<Option<u64>>,
    accepted: u64,
    emitted: u64,
    /// Cycles in which it held at least one request, frozen ones included
    /// (statistics, closed when it empties), and since when it holds some.
    occupied: u64,
    occupied_from: Option<u64>,
}

impl<T: Payload> FixedPipe<T> {
    /// `stages` >= 1 internal stages, a new request at most every `interval` >= 1 cycles.
    pub fn new(stages: u32, interval: u32) -> Self {
        assert!(
            stages >= 1 && interval >= 1,
            "validated by the unit's config"
        );
        let capacity = stages.div_ceil(interval);
        FixedPipe {
            stages,
            interval,
            capacity,
            ring: VecDeque::with_capacity(capacity as usize),
            pending_accept: None,
            pending_exit: false,
            frozen: Reg::new(0),
            freeze_start: Reg::new(None),
            last_accept: Reg::new(None),
            accepted: 0,
            emitted: 0,
            occupied: 0,
            occupied_from: None,
        }
    }

    pub fn stages(&self) -> u32 {
        self.stages
    }
    pub fn occupancy(&self) -> u32 {
        self.ring.len() as u32
    }
    pub fn accepted(&self) -> u64 {
        self.accepted
    }
    pub fn emitted(&self) -> u64 {
        self.emitted
    }
    /// Cycles in which the pipeline held a request, up to its last emptying.
    pub fn occupied_cycles(&self) -> u64 {
        self.occupied
    }

    fn ii_bits(&self) -> u32 {
        super::bits::clog2_u32(self.interval + 1)
    }

    fn local(&self, cycle: u64) -> u64 {
        match self.freeze_start.val() {
            Some(s) => s - self.frozen.val(),
            None => cycle - self.frozen.val(),
        }
    }

    /// Whether the pipeline can accept a request in cycle `c` from its state at
    /// the start of the cycle, with `out_ready` its output's registered ready
    /// (RTL: `!stall && ii_count == II && !full`, where a finished head and no
    /// room out is a stall): the condition `step_on` pops under.
    pub fn can_accept(&self, c: u64, out_ready: bool) -> bool {
        let local = self.local(c);
        let done = self
            .ring
            .front()
            .is_some_and(|(a, _)| a + self.stages as u64 <= local);
        if done && !out_ready {
            return false;
        }
        let count = self.ring.len() as u32 - done as u32;
        let interval_ok = self
            .last_accept
            .val()
            .is_none_or(|l| local >= l + self.interval as u64);
        interval_ok && count < self.capacity
    }

    /// One cycle of the pipeline on a unit's links: emit the finished head through
    /// `f` if the output has room (else freeze), then accept a new request if the
    /// interval allows. Sets the unit's status.
    pub fn step<R: Payload>(
        &mut self,
        ctx: &mut Ctx,
        input: &In<T>,
        output: &Out<R>,
        f: impl Fn(&T) -> R,
    ) -> Next {
        let c = ctx.cycle();
        let (status, next) = self.step_on(
            c,
            &mut LinkEnds {
                ctx: &mut *ctx,
                input,
                output,
            },
            f,
        );
        ctx.set_status(status);
        next
    }

    /// One cycle of the pipeline in cycle `c` between any two ends (a unit's links,
    /// or [`LocalLink`]s inside the unit that holds the pipeline): the status it
    /// would declare, and when it must be evaluated again without a new input (a
    /// frozen pipeline waits for its output to drain; a push onto its input wakes
    /// it only where that input is a link).
    pub fn step_on<R>(
        &mut self,
        c: u64,
        ends: &mut impl PipeEnds<T, R>,
        f: impl Fn(&T) -> R,
    ) -> (Status, Next) {
        let local = self.local(c);
        let mut frozen = false;
        let mut count = self.ring.len() as u32;
        if let Some((a, req)) = self.ring.front()
            && a + self.stages as u64 <= local
        {
            let result = f(req);
            if ends.offer(result) {
                self.pending_exit = true;
                self.emitted += 1;
                count -= 1;
                if let Some(s) = self.freeze_start.val() {
                    self.frozen.set(self.frozen.val() + (c - s));
                    self.freeze_start.set(None);
                }
            } else {
                frozen = true;
                if self.freeze_start.val().is_none() {
                    self.freeze_start.set(Some(c));
                }
            }
        }
        if frozen {
            return (Status::OutputBlocked, Next::Idle); // woken when the output drains
        }
        let interval_ok = self
            .last_accept
            .val()
            .is_none_or(|l| local >= l + self.interval as u64);
        let mut accepted_now = false;
        let mut waiting = false;
        if interval_ok && count < self.capacity {
            if let Some(req) = ends.pop() {
                self.pending_accept = Some((local, req));
                self.last_accept.set(Some(local));
                self.accepted += 1;
                count += 1;
                accepted_now = true;
            }
        } else if ends.has_head() {
            waiting = true;
        }
        // Earliest local cycle at which something can happen without a new input.
        let mut wake: Option<u64> = None;
        let oldest = if self.pending_exit {
            self.ring.get(1)
        } else {
            self.ring.front()
        };
        if let Some((a, _)) = oldest.or(self.pending_accept.as_ref()) {
            wake = Some(a + self.stages as u64);
        }
        // A request behind the one just taken: retry when the interval allows. With
        // none queued, the next push wakes us.
        if waiting || (accepted_now && ends.holds_more()) {
            let l = if accepted_now {
                local
            } else {
                self.last_accept
                    .val()
                    .expect("interval blocks only after an accept")
            };
            let at = l + self.interval as u64;
            wake = Some(wake.map_or(at, |w| w.min(at)));
        }
        match (count > 0, self.occupied_from) {
            (true, None) => self.occupied_from = Some(c),
            (false, Some(s)) => {
                self.occupied += c - s;
                self.occupied_from = None;
            }
            _ => {}
        }
        let status = if count > 0 {
            Status::Busy
        } else if waiting {
            Status::ResourceBusy
        } else {
            Status::WaitInput
        };
        let next = match wake {
            // Not frozen now, so local time advances with the clock from here on.
            Some(w) => Next::AtCycle(c + w.saturating_sub(local).max(1)),
            None => Next::Idle,
        };
        (status, next)
    }
}

/// The two ends of a [`FixedPipe`]: where it takes requests and puts results.
pub trait PipeEnds<T, R> {
    /// Takes the visible head of the input, if any.
    fn pop(&mut self) -> Option<T>;
    /// Whether the input has a visible head.
    fn has_head(&mut self) -> bool;
    /// Whether the input holds another entry behind this cycle's pop.
    fn holds_more(&self) -> bool;
    /// Offers a result; false if the output has no room (the pipeline freezes and
    /// offers the same result again when next stepped).
    fn offer(&mut self, r: R) -> bool;
}

struct LinkEnds<'a, 'n, T, R> {
    ctx: &'a mut Ctx<'n>,
    input: &'a In<T>,
    output: &'a Out<R>,
}

impl<T: Payload, R: Payload> PipeEnds<T, R> for LinkEnds<'_, '_, T, R> {
    #[inline]
    fn pop(&mut self) -> Option<T> {
        self.ctx.pop(self.input)
    }
    #[inline]
    fn has_head(&mut self) -> bool {
        self.ctx.peek(self.input).is_some()
    }
    #[inline]
    fn holds_more(&self) -> bool {
        self.ctx.holds_more(self.input)
    }
    #[inline]
    fn offer(&mut self, r: R) -> bool {
        self.ctx.offer(self.output, r)
    }
}

/// A pipeline between two [`LocalLink`]s in cycle `now`.
pub struct LocalEnds<'a, T, R> {
    pub now: u64,
    pub input: &'a mut LocalLink<T>,
    pub output: &'a mut LocalLink<R>,
}

impl<T: Clone, R> PipeEnds<T, R> for LocalEnds<'_, T, R> {
    #[inline]
    fn pop(&mut self) -> Option<T> {
        self.input.pop(self.now)
    }
    #[inline]
    fn has_head(&mut self) -> bool {
        self.input.peek(self.now).is_some()
    }
    #[inline]
    fn holds_more(&self) -> bool {
        self.input.holds_more()
    }
    #[inline]
    fn offer(&mut self, r: R) -> bool {
        if !self.output.can_push() {
            return false;
        }
        self.output.push(self.now, r);
        true
    }
}

/// A link's rules kept inside one unit, between two of its own stages (the
/// crossbar and the ray-box pipeline it holds): a FIFO of `depth` entries, a push
/// in cycle `t` visible from `t + delay`, room freed by a pop in cycle `t` seen
/// from `t + 1`, at most one push and one pop per cycle. The same timing as a
/// kernel link of that configuration, as plain data: no edge, no wake-up, no
/// monitor (the unit's own code is the only user).
pub struct LocalLink<T> {
    depth: u32,
    delay: u64,
    /// Committed entries: (cycle from which visible, payload), oldest first.
    q: VecDeque<(u64, T)>,
    /// This cycle's push (joins at the edge).
    pending: Option<(u64, T)>,
    /// Whether this cycle popped the head (it leaves at the edge).
    popped: bool,
}

impl<T> LocalLink<T> {
    pub fn new(cfg: LinkCfg) -> Self {
        LocalLink {
            depth: cfg.depth,
            delay: cfg.delay as u64,
            q: VecDeque::with_capacity(cfg.depth as usize),
            pending: None,
            popped: false,
        }
    }
    /// Room at the start of this cycle, and no push yet this cycle.
    #[inline]
    pub fn can_push(&self) -> bool {
        self.pending.is_none() && (self.q.len() as u32) < self.depth
    }
    /// Pushes in cycle `now` (the caller checked `can_push`).
    #[inline]
    pub fn push(&mut self, now: u64, v: T) {
        debug_assert!(self.can_push(), "push without room");
        self.pending = Some((now + self.delay, v));
    }
    /// The head if it is visible in cycle `now` and not popped this cycle.
    #[inline]
    pub fn peek(&self, now: u64) -> Option<&T> {
        if self.popped {
            return None;
        }
        self.q.front().filter(|e| e.0 <= now).map(|e| &e.1)
    }
    /// Pops the head if it is visible in cycle `now`.
    #[inline]
    pub fn pop(&mut self, now: u64) -> Option<T>
    where
        T: Clone,
    {
        let v = self.peek(now).cloned()?;
        self.popped = true;
        Some(v)
    }
    /// Whether an entry is left behind this cycle's pop (visible or not).
    #[inline]
    pub fn holds_more(&self) -> bool {
        self.q.len() > self.popped as usize
    }
    /// Whether this cycle's pop freed room in a full FIFO (its producer may push
    /// again from the next cycle on).
    #[inline]
    pub fn freed_full(&self) -> bool {
        self.popped && self.q.len() as u32 >= self.depth
    }
    /// The cycle from which the first entry after this cycle's pop (this cycle's
    /// push if the FIFO has none) is visible.
    #[inline]
    pub fn next_visible(&self) -> Option<u64> {
        self.q
            .get(self.popped as usize)
            .or(self.pending.as_ref())
            .map(|e| e.0)
    }
    /// Whether the FIFO held nothing at the start of this cycle.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }
}

impl<T: Payload> State for LocalLink<T> {
    type Init = Self;
    fn from_init(init: Self) -> Self {
        init
    }
    fn declare(&self, name: &str, out: &mut StateList) {
        out.items.push(StateDecl::reg(
            format!("{name}_count"),
            super::bits::clog2_u32(self.depth + 1),
        ));
        out.items.push(StateDecl::reg(format!("{name}_valid"), 1));
        out.items
            .push(StateDecl::reg(format!("{name}_data"), T::BITS));
        // The FIFO's storage (not traced: the head above is what its reader sees).
        out.items
            .push(StateDecl::array(format!("{name}_mem"), T::BITS, self.depth));
    }
    /// The FIFO as the consumer sees it in cycle `cycle`: entries, whether the
    /// head is visible, and its payload (held while not visible).
    fn sample(&self, cycle: u64, out: &mut Samples) {
        out.slot()
            .push(self.q.len() as u64, super::bits::clog2_u32(self.depth + 1));
        let head = self.q.front().filter(|e| e.0 <= cycle);
        out.slot().push(head.is_some() as u64, 1);
        let d = out.slot();
        match head {
            Some(e) => e.1.pack(d),
            None => d.clear(),
        }
    }
    /// Empty, as built.
    fn sample_reset(&self, out: &mut Samples) {
        let cfg = LinkCfg {
            depth: self.depth,
            delay: self.delay as u32,
        };
        LocalLink::<T>::new(cfg).sample(0, out);
    }
    fn commit(&mut self) {
        if self.popped {
            self.q.pop_front();
            self.popped = false;
        }
        if let Some(e) = self.pending.take() {
            self.q.push_back(e);
        }
    }
    fn reset(&mut self) {
        self.q.clear();
        self.pending = None;
        self.popped = false;
    }
    fn pending_change(&self) -> bool {
        self.popped || self.pending.is_some()
    }
    /// A head not yet visible becomes so with time.
    fn moves(&self, cycle: u64) -> bool {
        self.q.front().is_some_and(|e| e.0 > cycle)
    }
}

impl<T: Payload> State for FixedPipe<T> {
    type Init = Self;
    fn from_init(init: Self) -> Self {
        init
    }
    /// Its registers mark nothing: the pipeline is committed at every edge.
    fn number(&mut self, _bit: u64) {
        self.frozen.number(0);
        self.freeze_start.number(0);
        self.last_accept.number(0);
    }
    fn declare(&self, name: &str, out: &mut StateList) {
        out.items
            .push(StateDecl::reg(format!("{name}_stage_valid"), self.stages));
        out.items.push(StateDecl::reg(format!("{name}_frozen"), 1));
        out.items
            .push(StateDecl::reg(format!("{name}_ii_count"), self.ii_bits()));
        out.items.push(StateDecl::array(
            format!("{name}_stage_data"),
            T::BITS,
            self.stages,
        ));
    }
    /// Rebuilds the stage-register view: bit k is set when stage k holds a request.
    fn sample(&self, cycle: u64, out: &mut Samples) {
        let local = self.local(cycle);
        let v = out.slot();
        let mut bits = vec![0u64; self.stages.div_ceil(64) as usize];
        for (a, _) in &self.ring {
            // Accepted in local cycle a: in stage 0 during a + 1, in the last stage
            // (and pushed out) during a + stages, where it stays while frozen.
            let k = (local - a).clamp(1, self.stages as u64) - 1;
            bits[(k / 64) as usize] |= 1 << (k % 64);
        }
        let mut left = self.stages;
        for w in bits {
            let n = left.min(64);
            v.push(w, n);
            left -= n;
        }
        out.slot().push(self.freeze_start.val().is_some() as u64, 1);
        // The interval counter of RTL: cycles since the last acceptance, saturating.
        let since = self.last_accept.val().map_or(self.interval as u64, |l| {
            (local - l).min(self.interval as u64)
        });
        out.slot().push(since, self.ii_bits());
    }
    /// Empty, as built (its interval counter saturated: ready to accept).
    fn sample_reset(&self, out: &mut Samples) {
        FixedPipe::<T>::new(self.stages, self.interval).sample(0, out);
    }
    /// Requests advance through the stages, and the interval counter counts
    /// up to saturation, with time alone.
    fn moves(&self, cycle: u64) -> bool {
        let local = self.local(cycle);
        !self.ring.is_empty()
            || self
                .last_accept
                .val()
                .is_some_and(|l| local - l < self.interval as u64)
    }
    fn commit(&mut self) {
        if self.pending_exit {
            self.ring.pop_front();
            self.pending_exit = false;
        }
        if let Some(x) = self.pending_accept.take() {
            self.ring.push_back(x);
        }
        debug_assert!(
            self.ring.len() as u32 <= self.capacity,
            "pipeline over capacity"
        );
        self.frozen.commit();
        self.freeze_start.commit();
        self.last_accept.commit();
    }
    fn reset(&mut self) {
        self.ring.clear();
        self.pending_accept = None;
        self.pending_exit = false;
        self.frozen.reset();
        self.freeze_start.reset();
        self.last_accept.reset();
        self.accepted = 0;
        self.emitted = 0;
        self.occupied = 0;
        self.occupied_from = None;
    }
    fn pending_change(&self) -> bool {
        self.pending_exit
            || self.pending_accept.is_some()
            || self.frozen.pending_change()
            || self.freeze_start.pending_change()
            || self.last_accept.pending_change()
    }
}
