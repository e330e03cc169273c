//! What a unit sees while it is evaluated ([`Ctx`]: the time, its links, its
//! status) and the evaluation itself (`eval_slot`, `eval_commit_slot`): the body
//! of a step for one unit, on whichever thread runs it, with what it produces
//! (`LaneOut`) left for the clock edge.

use super::network::Net;
use super::{SimError, Slot, Time, UnitId};
use crate::rtl::bits::Payload;
use crate::rtl::link::{In, LinkId, Out, PortArray, Violation};
use crate::rtl::state;
use crate::rtl::unit::{Next, Status};

/// What one evaluation thread produces in a step, merged by the main thread at the
/// clock edge.
#[derive(Default)]
pub(super) struct LaneOut {
    pub(super) touched: Vec<LinkId>,
    pub(super) wakes: Vec<(UnitId, Time)>,
    /// (unit, its next wake-up, its cycle when it was evaluated)
    pub(super) nexts: Vec<(u32, Next, u64)>,
    pub(super) evals: u64,
    /// Protocol violations found at the edges of the thread's own links.
    pub(super) violations: Vec<Violation>,
    /// The last (time, period, cycle) a `Ctx` was made for: consecutive units
    /// share their clock, so they share one 64-bit division (docs/results/2026-11-26-kernel-committing-where-the-state-is-and-the-cycle-once-per-clock.md).
    clock: (Time, Time, u64),
}

impl LaneOut {
    pub(super) fn append(&mut self, o: &mut LaneOut) {
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
    /// Where the links popped go when the unit's readiness is checked.
    popped: Option<&'a mut Vec<LinkId>>,
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
    /// (the TPs of a TM), to spare the crossbar a 64-bit division per evaluation
    /// (docs/results/2026-11-26-kernel-the-paper-frame-s-profile-and-what-did-not-help.md).
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
        if let (Some(p), true) = (&mut self.popped, v.is_some()) {
            p.push(port.id);
        }
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

/// Evaluates a unit and takes its clock edge at once, on this thread (see
/// [`Sim::eval_commit`](super::Sim::eval_commit)): the edge commits only the registers the evaluation
/// wrote, unless the unit was changed from outside since its last edge.
#[inline]
pub(super) fn eval_commit_slot(
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
pub(super) fn eval_slot(
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
    let check = slot.check_ready.0 <= t && t <= slot.check_ready.1 && !shadow;
    if check {
        ready_before(slot, t, out.clock.2, net);
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
        popped: check.then_some(&mut slot.popped),
    };
    let next = slot.unit.eval(&mut ctx);
    let (new_status, next_status, link_ops) = (ctx.new_status, ctx.next_status, ctx.link_ops);
    if check {
        popped_while_ready(slot, t, net, &mut out.violations);
    }
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

/// The unit's readiness on each input at the start of cycle `cycle` (time
/// `t`), before its evaluation changes anything.
fn ready_before(slot: &mut Slot, t: Time, cycle: u64, net: Net) {
    // The unit reads only its own outputs' space (its thread is their producer).
    let out_ready = |l: LinkId| net.link_ref(l.0 as usize).space_at_start();
    let at = crate::rtl::Ready::new(cycle, &out_ready);
    let unit = &*slot.unit;
    slot.ready_pre.clear();
    slot.ready_pre
        .extend(slot.in_links.iter().map(|&l| unit.can_accept(l, &at)));
    slot.ready_at = t;
}

/// A pop of an input the unit declared not ready for is a violation: its
/// waveform's `ready` would be low while it takes the payload.
fn popped_while_ready(slot: &mut Slot, t: Time, net: Net, violations: &mut Vec<Violation>) {
    for l in slot.popped.drain(..) {
        let k = slot.in_links.iter().position(|&i| i == l);
        if k.is_some_and(|k| !slot.ready_pre[k]) {
            violations.push(Violation {
                link: net.link_ref(l.0 as usize).name().to_string(),
                at: t,
                what: format!(
                    "'{}' popped while it declared itself not ready (can_accept was false at the start of the cycle)",
                    slot.path
                ),
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::round_robin;

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
