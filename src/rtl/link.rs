//! Registered links: the only way units talk.
//!
//! A link is a valid/ready FIFO of `depth` entries with a `delay` of whole producer
//! cycles: a payload pushed in cycle `t` is visible to the consumer in the cycle that
//! starts at `t + delay`. Space freed by a pop in cycle `t` is seen by the producer
//! from `t + 1` on (the credit is registered). Hence there is no combinational path
//! between units, and the order in which units are evaluated within a cycle cannot
//! change anything:
//! - a consumer never sees a push of the same cycle (it is not visible yet), and
//! - a producer's `can_push` counts pops only after the edge.
//!
//! Full throughput (one transfer per cycle) needs `depth >= delay + 1`.
//!
//! The link is also the protocol monitor: at most one push and one pop per cycle, no
//! push into a full FIFO, no pop of an invisible entry, and a producer whose offer was
//! refused must offer the *same* payload again, every cycle it is evaluated, until it
//! is taken (valid may not drop and data may not change while stalled).

use std::any::Any;
use std::collections::VecDeque;
use std::marker::PhantomData;

use serde::{Deserialize, Serialize};

use super::bits::{Bits, Payload};
use super::sim::{Time, UnitId};

/// Index of a link in the simulator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct LinkId(pub u32);

/// Consumer end of a link.
#[derive(Debug)]
pub struct In<T> {
    pub id: LinkId,
    _t: PhantomData<fn() -> T>,
}
/// Producer end of a link.
#[derive(Debug)]
pub struct Out<T> {
    pub id: LinkId,
    _t: PhantomData<fn() -> T>,
}
impl<T> Clone for In<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for In<T> {}
impl<T> Clone for Out<T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Out<T> {}
impl<T> In<T> {
    pub(crate) fn new(id: LinkId) -> Self {
        In {
            id,
            _t: PhantomData,
        }
    }
}
impl<T> Out<T> {
    pub(crate) fn new(id: LinkId) -> Self {
        Out {
            id,
            _t: PhantomData,
        }
    }
}

/// Configuration of one link.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkCfg {
    /// FIFO entries (skid buffer). Must be at least 1.
    pub depth: u32,
    /// Register stages between producer and consumer, in producer cycles. At least 1:
    /// a zero-delay link would be a combinational path.
    pub delay: u32,
}

impl Default for LinkCfg {
    /// One register stage and room for full throughput.
    fn default() -> Self {
        LinkCfg { depth: 2, delay: 1 }
    }
}

impl LinkCfg {
    pub fn validate(&self, what: &str) -> Result<(), String> {
        if self.delay == 0 {
            return Err(format!(
                "{what}: link delay 0 would be a combinational path between units; set delay >= 1"
            ));
        }
        if self.depth == 0 {
            return Err(format!(
                "{what}: link depth 0 can hold nothing; set depth >= 1"
            ));
        }
        Ok(())
    }
}

/// A transfer recorded by a link whose log is on (testbenches use it to check
/// acceptance times and latencies).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkEvent {
    /// Pushed at `at`, visible to the consumer from `visible`.
    Push { at: Time, visible: Time },
    /// Popped (accepted by the consumer) at `at`.
    Pop { at: Time },
}

/// Protocol violation found by a link monitor.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Violation {
    pub link: String,
    pub at: Time,
    pub what: String,
}

struct Entry<T> {
    visible: Time,
    data: T,
}

/// Per-link counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    pub pushes: u64,
    pub pops: u64,
    pub refused_offers: u64,
    pub max_occupancy: u32,
}

pub struct Link<T: Payload> {
    pub(crate) name: String,
    q: VecDeque<Entry<T>>,
    depth: u32,
    pub(crate) cfg: LinkCfg,
    pub(crate) delay_ps: Time,
    pops_now: u32,
    pushes_now: u32,
    /// Whether the FIFO was full at the start of this cycle (pops then wake the producer).
    full_at_start: bool,
    pub(crate) touched: bool,
    last_data: Option<T>,
    /// Payload of a refused offer that must be offered again.
    stalled: Option<T>,
    offered_now: bool,
    pub(crate) producer: Option<UnitId>,
    pub(crate) consumer: Option<UnitId>,
    pub(crate) stats: LinkStats,
    log: Option<Vec<LinkEvent>>,
    violations: Vec<Violation>,
}

impl<T: Payload> Link<T> {
    pub(crate) fn new(name: String, cfg: LinkCfg) -> Self {
        Link {
            name,
            q: VecDeque::with_capacity(cfg.depth as usize),
            depth: cfg.depth,
            cfg,
            delay_ps: 0,
            pops_now: 0,
            pushes_now: 0,
            full_at_start: false,
            touched: false,
            last_data: None,
            stalled: None,
            offered_now: false,
            producer: None,
            consumer: None,
            stats: LinkStats::default(),
            log: None,
            violations: Vec::new(),
        }
    }

    fn violation(&mut self, at: Time, what: String) {
        self.touched = true;
        self.violations.push(Violation {
            link: self.name.clone(),
            at,
            what,
        });
    }

    /// The head entry if it is visible at `now` and not yet popped this cycle.
    #[inline]
    pub(crate) fn peek(&self, now: Time) -> Option<&T> {
        if self.pops_now > 0 {
            return None;
        }
        self.q.front().filter(|e| e.visible <= now).map(|e| &e.data)
    }

    /// See [`LinkDyn::head_time`].
    #[inline]
    pub(crate) fn head_time(&self) -> Time {
        match self.q.front() {
            Some(e) if self.pops_now == 0 => e.visible,
            _ => Time::MAX,
        }
    }

    /// Pops the head; returns the payload and whether the producer must be woken.
    #[inline]
    pub(crate) fn pop(&mut self, now: Time) -> Option<T> {
        if self.pops_now > 0 {
            self.violation(
                now,
                "second pop in one cycle (a link moves one payload per cycle)".into(),
            );
            return None;
        }
        let e = self.q.front().filter(|e| e.visible <= now)?;
        let data = e.data.clone();
        self.pops_now = 1;
        self.full_at_start = self.q.len() as u32 - self.pushes_now >= self.depth;
        self.stats.pops += 1;
        if let Some(log) = &mut self.log {
            log.push(LinkEvent::Pop { at: now });
        }
        self.touched = true;
        Some(data)
    }

    /// Space at the start of this cycle, minus this cycle's push.
    #[inline]
    pub(crate) fn can_push(&self) -> bool {
        self.pushes_now == 0 && (self.q.len() as u32) < self.depth
    }

    /// Pushes; returns the time the payload becomes visible.
    #[inline]
    pub(crate) fn push(&mut self, now: Time, data: T) -> Option<Time> {
        if !self.can_push() {
            let why = if self.pushes_now > 0 {
                "second push in one cycle"
            } else {
                "push into a full FIFO (ready was low)"
            };
            self.violation(now, why.into());
            return None;
        }
        if let Some(s) = self.stalled.take()
            && !s.same_bits(&data)
        {
            self.violation(
                now,
                "payload changed while stalled (valid data must hold until ready)".into(),
            );
        }
        let visible = now + self.delay_ps;
        self.q.push_back(Entry {
            visible,
            data: data.clone(),
        });
        self.last_data = Some(data);
        self.pushes_now = 1;
        self.offered_now = true;
        self.stats.pushes += 1;
        self.stats.max_occupancy = self.stats.max_occupancy.max(self.q.len() as u32);
        if let Some(log) = &mut self.log {
            log.push(LinkEvent::Push { at: now, visible });
        }
        self.touched = true;
        Some(visible)
    }

    pub(crate) fn is_stalled(&self) -> bool {
        self.stalled.is_some()
    }

    /// Offer: push if there is space, else remember the payload as stalled.
    #[inline]
    pub(crate) fn offer(&mut self, now: Time, data: T) -> Option<Time> {
        if self.can_push() {
            return self.push(now, data);
        }
        if let Some(s) = &self.stalled
            && !s.same_bits(&data)
        {
            self.violation(
                now,
                "payload changed while stalled (valid data must hold until ready)".into(),
            );
        }
        if self.stalled.is_none() {
            self.stats.refused_offers += 1;
        }
        self.stalled = Some(data);
        self.offered_now = true;
        self.touched = true;
        None
    }
}

/// What a link's clock edge reports to the simulator.
pub(crate) struct EdgeResult {
    /// A pop made room in a FIFO that was full: wake the producer.
    pub wake_producer: bool,
    /// `head_time` after the edge.
    pub head: Time,
    /// `can_push` after the edge.
    pub space: bool,
}

/// Type-erased link interface used by the simulator for commit and tracing.
pub(crate) trait LinkDyn: Any + Send {
    fn name(&self) -> &str;
    /// Clock edge: moves this cycle's violations to `violations`, retires this
    /// cycle's pop, and tells the simulator what it mirrors (one virtual call per
    /// touched link and edge).
    fn edge(&mut self, violations: &mut Vec<Violation>) -> EdgeResult;
    fn sample_consumer(&self, now: Time, out: [&mut Bits; 3]);
    fn sample_producer(&self, out: [&mut Bits; 3]);
    fn ends(&self) -> (Option<UnitId>, Option<UnitId>);
    fn set_ends(&mut self, producer: Option<UnitId>, consumer: Option<UnitId>);
    fn set_delay_ps(&mut self, ps: Time);
    fn cfg(&self) -> LinkCfg;
    fn reset(&mut self);
    fn check_offer_held(&mut self, now: Time) -> bool;
    fn is_stalled(&self) -> bool;
    /// When the head becomes visible to the consumer: `Time::MAX` if the FIFO is
    /// empty or its head was popped this cycle (the simulator keeps these in one flat
    /// array so that `Ctx::has_input` is a load, not a virtual call).
    fn head_time(&self) -> Time;
    /// `can_push` (kept by the simulator in a flat array like `head_time`).
    fn has_space(&self) -> bool;
    fn stats(&self) -> LinkStats;
    fn occupancy(&self) -> u32;
    fn set_log(&mut self, on: bool);
    fn log(&self) -> &[LinkEvent];
}

impl<T: Payload> LinkDyn for Link<T> {
    fn name(&self) -> &str {
        &self.name
    }
    fn edge(&mut self, violations: &mut Vec<Violation>) -> EdgeResult {
        if !self.violations.is_empty() {
            violations.append(&mut self.violations);
        }
        // Retire this cycle's pop; a pop that made room in a full FIFO wakes the
        // producer.
        let wake_producer = self.pops_now > 0 && self.full_at_start;
        if self.pops_now > 0 {
            self.q.pop_front();
        }
        self.pops_now = 0;
        self.pushes_now = 0;
        self.offered_now = false;
        self.full_at_start = false;
        self.touched = false;
        EdgeResult {
            wake_producer,
            head: self.head_time(),
            space: self.can_push(),
        }
    }
    fn sample_consumer(&self, now: Time, out: [&mut Bits; 3]) {
        let [valid, ready, data] = out;
        let head = self.q.front().filter(|e| e.visible <= now);
        valid.push(head.is_some() as u64, 1);
        ready.push((self.pops_now > 0) as u64, 1);
        match head {
            Some(e) => e.data.pack(data),
            None => data.clear(), // empty = hold the previous value
        }
    }
    fn sample_producer(&self, out: [&mut Bits; 3]) {
        let [valid, ready, data] = out;
        valid.push((self.pushes_now > 0 || self.stalled.is_some()) as u64, 1);
        let start_len = self.q.len() as u32 - self.pushes_now;
        ready.push((start_len < self.depth) as u64, 1);
        if let Some(s) = &self.stalled {
            s.pack(data);
        } else if self.pushes_now > 0 {
            self.last_data
                .as_ref()
                .expect("pushed this cycle")
                .pack(data);
        } else {
            data.clear();
        }
    }
    fn ends(&self) -> (Option<UnitId>, Option<UnitId>) {
        (self.producer, self.consumer)
    }
    fn set_ends(&mut self, producer: Option<UnitId>, consumer: Option<UnitId>) {
        self.producer = producer;
        self.consumer = consumer;
    }
    fn set_delay_ps(&mut self, ps: Time) {
        self.delay_ps = ps;
    }
    fn cfg(&self) -> LinkCfg {
        self.cfg
    }
    fn reset(&mut self) {
        self.q.clear();
        self.pops_now = 0;
        self.pushes_now = 0;
        self.full_at_start = false;
        self.touched = false;
        self.last_data = None;
        self.stalled = None;
        self.offered_now = false;
        self.stats = LinkStats::default();
        if let Some(l) = &mut self.log {
            l.clear();
        }
        self.violations.clear();
    }
    /// Called after the producer's evaluation: a stalled offer must be repeated.
    fn check_offer_held(&mut self, now: Time) -> bool {
        if self.stalled.is_some() && !self.offered_now {
            self.violation(
                now,
                "valid dropped while stalled (a refused payload must be offered until taken)"
                    .into(),
            );
            self.stalled = None;
            return true;
        }
        false
    }
    fn stats(&self) -> LinkStats {
        self.stats
    }
    fn is_stalled(&self) -> bool {
        self.stalled.is_some()
    }
    #[inline]
    fn head_time(&self) -> Time {
        self.head_time()
    }
    #[inline]
    fn has_space(&self) -> bool {
        self.can_push()
    }
    fn occupancy(&self) -> u32 {
        self.q.len() as u32
    }
    fn set_log(&mut self, on: bool) {
        self.log = if on { Some(Vec::new()) } else { None };
    }
    fn log(&self) -> &[LinkEvent] {
        self.log.as_deref().unwrap_or(&[])
    }
}
