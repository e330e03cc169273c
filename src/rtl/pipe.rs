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
use super::link::{In, Out};
use super::sim::Ctx;
use super::state::{Reg, State};
use super::unit::{Next, Status};

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

    fn ii_bits(&self) -> u32 {
        super::bits::clog2_u32(self.interval + 1)
    }

    fn local(&self, cycle: u64) -> u64 {
        match self.freeze_start.val() {
            Some(s) => s - self.frozen.val(),
            None => cycle - self.frozen.val(),
        }
    }

    /// One cycle of the pipeline: emit the finished head through `f` if the output
    /// has room (else freeze), then accept a new request if the interval allows.
    pub fn step<R: Payload>(
        &mut self,
        ctx: &mut Ctx,
        input: &In<T>,
        output: &Out<R>,
        f: impl Fn(&T) -> R,
    ) -> Next {
        let c = ctx.cycle();
        let local = self.local(c);
        let mut frozen = false;
        let mut count = self.ring.len() as u32;
        if let Some((a, req)) = self.ring.front()
            && a + self.stages as u64 <= local
        {
            let result = f(req);
            if ctx.offer(output, result) {
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
            ctx.set_status(Status::OutputBlocked);
            return Next::Idle; // woken when the output link drains
        }
        let interval_ok = self
            .last_accept
            .val()
            .is_none_or(|l| local >= l + self.interval as u64);
        let mut accepted_now = false;
        let mut waiting = false;
        if interval_ok && count < self.capacity {
            if let Some(req) = ctx.pop(input) {
                self.pending_accept = Some((local, req));
                self.last_accept.set(Some(local));
                self.accepted += 1;
                count += 1;
                accepted_now = true;
            }
        } else if ctx.peek(input).is_some() {
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
        if waiting || (accepted_now && ctx.holds_more(input)) {
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
        ctx.set_status(if count > 0 {
            Status::Busy
        } else if waiting {
            Status::ResourceBusy
        } else {
            Status::WaitInput
        });
        match wake {
            // Not frozen now, so local time advances with the clock from here on.
            Some(w) => Next::AtCycle(c + w.saturating_sub(local).max(1)),
            None => Next::Idle,
        }
    }
}

impl<T: Payload> State for FixedPipe<T> {
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
    }
    fn pending_change(&self) -> bool {
        self.pending_exit
            || self.pending_accept.is_some()
            || self.frozen.pending_change()
            || self.freeze_start.pending_change()
            || self.last_accept.pending_change()
    }
}
