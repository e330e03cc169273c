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
use std::cell::UnsafeCell;
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

/// Either end of a link, named by its id (`In` or `Out`).
pub trait PortEnd: Copy {
    fn link(&self) -> LinkId;
    fn of_link(id: LinkId) -> Self;
}
impl<T> PortEnd for In<T> {
    fn link(&self) -> LinkId {
        self.id
    }
    fn of_link(id: LinkId) -> Self {
        In::new(id)
    }
}
impl<T> PortEnd for Out<T> {
    fn link(&self) -> LinkId {
        self.id
    }
    fn of_link(id: LinkId) -> Self {
        Out::new(id)
    }
}

/// A unit's array of ports of one payload type (`in_arrays` / `out_arrays` of
/// `unit!`: one per TP, say). When their links are consecutive, as `Sim::link`
/// creates a port array's links, port `k` is the first link plus `k`: `at` and
/// the arbiters' masks (`Ctx::visible_mask`) then need not load the ports from
/// their heap vector, a cache miss per array and evaluation
/// (docs/results/2026-11-26-kernel-port-arrays-that-know-their-links.md).
#[derive(Clone, Debug)]
pub struct PortArray<P> {
    ports: Vec<P>,
    /// The first port's link, if every port `k`'s link is that plus `k`.
    first: Option<u32>,
}

impl<P: PortEnd> From<Vec<P>> for PortArray<P> {
    fn from(ports: Vec<P>) -> Self {
        let first = ports.first().map(|p| p.link().0);
        let consecutive = first.is_some_and(|f| {
            ports
                .iter()
                .enumerate()
                .all(|(k, p)| p.link().0 as usize == f as usize + k)
        });
        PortArray {
            first: first.filter(|_| consecutive),
            ports,
        }
    }
}

impl<P> std::ops::Deref for PortArray<P> {
    type Target = [P];
    fn deref(&self) -> &[P] {
        &self.ports
    }
}

impl<P: PortEnd> PortArray<P> {
    /// Port `k`.
    #[inline]
    pub fn at(&self, k: usize) -> P {
        match self.first {
            Some(f) => {
                assert!(k < self.ports.len(), "port {k} of {}", self.ports.len());
                debug_assert_eq!(self.ports[k].link().0, f + k as u32);
                P::of_link(LinkId(f + k as u32))
            }
            None => self.ports[k],
        }
    }
    /// Which port of the array is on link `l`, if any (a subtraction when the
    /// links are consecutive).
    #[inline]
    pub fn index_of(&self, l: LinkId) -> Option<usize> {
        match self.first {
            Some(f) => {
                let k = l.0.checked_sub(f)? as usize;
                (k < self.ports.len()).then_some(k)
            }
            None => self.ports.iter().position(|p| p.link() == l),
        }
    }
    /// The first port's link when the ports' links are consecutive.
    #[inline]
    pub fn consecutive_from(&self) -> Option<usize> {
        self.first.map(|f| f as usize)
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
    pub fn validate(&self, what: &str) -> Result<(), super::SimError> {
        let bad = |why| super::SimError::LinkCfg {
            what: what.to_string(),
            why,
        };
        if self.delay == 0 {
            return Err(bad(
                "link delay 0 would be a combinational path between units; set delay >= 1",
            ));
        }
        if self.depth == 0 {
            return Err(bad("link depth 0 can hold nothing; set depth >= 1"));
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

/// What the consumer changes during a cycle: the FIFO itself is only read (a pop is
/// retired at the edge), so the producer's half never touches it.
#[repr(C)]
pub(crate) struct ConsSide<T> {
    q: VecDeque<Entry<T>>,
    pops_now: u32,
    /// Whether the FIFO was full at the start of this cycle (pops then wake the producer).
    full_at_start: bool,
    touched: bool,
    pops: u64,
    /// Boxed: rare (testbenches), and a link's size is cache footprint.
    #[allow(clippy::box_collection)]
    log: Option<Box<Vec<LinkEvent>>>,
    violations: Vec<(Time, String)>,
}

/// What the producer changes during a cycle: this cycle's push waits here for the
/// edge (it is not visible before), so the consumer's half never sees it.
// The flags and counters every push and edge reads first, the payloads (a line
// is 64 bytes) after them.
#[repr(C)]
pub(crate) struct ProdSide<T> {
    /// Whether the FIFO had room at the start of this cycle (set at the edge).
    space_at_start: bool,
    touched: bool,
    offered_now: bool,
    pushes: u64,
    refused_offers: u64,
    /// Boxed as `ConsSide::log`.
    #[allow(clippy::box_collection)]
    log: Option<Box<Vec<LinkEvent>>>,
    violations: Vec<(Time, String)>,
    pending: Option<Entry<T>>,
    /// Payload of a refused offer that must be offered again.
    stalled: Option<T>,
}

/// A link: its two halves are each changed only by the unit at that end, so the
/// producer and the consumer may be evaluated on two threads at once (see
/// `Sim`'s `Net`); the clock edge, on one thread, joins them.
// What the edge reads first, then the two halves (the consumer's, which the
// edge reads next, then the producer's); the name and the configuration last.
#[repr(C)]
pub struct Link<T: Payload> {
    pub(crate) depth: u32,
    max_occupancy: u32,
    /// Merged transfer log of both halves (filled at the edge); boxed as
    /// `ConsSide::log`.
    #[allow(clippy::box_collection)]
    log: Option<Box<Vec<LinkEvent>>>,
    pub(crate) delay_ps: Time,
    pub(crate) producer: Option<UnitId>,
    pub(crate) consumer: Option<UnitId>,
    cons: UnsafeCell<ConsSide<T>>,
    prod: UnsafeCell<ProdSide<T>>,
    pub(crate) name: String,
    pub(crate) cfg: LinkCfg,
    /// The last payload popped, kept while a tracer watches the link
    /// (`keep_last`): what a port shows as data when none is at its head
    /// (`LinkDyn::sample_held`). Boxed and reused: untraced links pay a flag.
    last: Option<Box<T>>,
    keep_last: bool,
}

// SAFETY: between edges the consumer half is reached only by the consumer's thread
// and the producer half only by the producer's (`Link::cons`, `Link::prod`); the
// rest is written only with `&mut Link` (elaboration, the edge, reset), when no
// thread holds a half. Payloads are `Send`.
unsafe impl<T: Payload> Sync for Link<T> {}

impl<T: Payload> Link<T> {
    pub(crate) fn new(name: String, cfg: LinkCfg) -> Self {
        Link {
            name,
            depth: cfg.depth,
            cfg,
            last: None,
            keep_last: false,
            delay_ps: 0,
            producer: None,
            consumer: None,
            max_occupancy: 0,
            log: None,
            cons: UnsafeCell::new(ConsSide {
                q: VecDeque::with_capacity(cfg.depth as usize),
                pops_now: 0,
                full_at_start: false,
                touched: false,
                pops: 0,
                log: None,
                violations: Vec::new(),
            }),
            prod: UnsafeCell::new(ProdSide {
                pending: None,
                space_at_start: true,
                touched: false,
                stalled: None,
                offered_now: false,
                pushes: 0,
                refused_offers: 0,
                log: None,
                violations: Vec::new(),
            }),
        }
    }

    /// The consumer's half.
    /// SAFETY: only the link's consumer, on its evaluation thread, may call this
    /// between edges, and it must not hold two results at once.
    #[inline]
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn cons(&self) -> &mut ConsSide<T> {
        // SAFETY: see the function's contract.
        unsafe { &mut *self.cons.get() }
    }

    /// The producer's half (contract as `cons`, for the producer).
    #[inline]
    #[allow(clippy::mut_from_ref)]
    pub(crate) unsafe fn prod(&self) -> &mut ProdSide<T> {
        // SAFETY: see the function's contract.
        unsafe { &mut *self.prod.get() }
    }

    fn cons_ref(&self) -> &ConsSide<T> {
        // SAFETY: used only between steps or at the edge (one thread, no half out).
        unsafe { &*self.cons.get() }
    }
    fn prod_ref(&self) -> &ProdSide<T> {
        // SAFETY: as `cons_ref`.
        unsafe { &*self.prod.get() }
    }
}

impl<T> ConsSide<T> {
    pub(crate) fn touched(&self) -> bool {
        self.touched
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

    /// Entries in the FIFO that this cycle's pop (if any) leaves behind, visible or
    /// not (this cycle's push joins at the edge and is not counted).
    #[inline]
    pub(crate) fn left_after_pop(&self) -> usize {
        self.q.len() - self.pops_now as usize
    }

    /// Pops the head if it is visible (the entry leaves the FIFO at the edge).
    #[inline]
    pub(crate) fn pop(&mut self, now: Time, depth: u32) -> Option<T>
    where
        T: Clone,
    {
        if self.pops_now > 0 {
            self.touched = true;
            self.violations.push((
                now,
                "second pop in one cycle (a link moves one payload per cycle)".into(),
            ));
            return None;
        }
        let e = self.q.front().filter(|e| e.visible <= now)?;
        let data = e.data.clone();
        self.pops_now = 1;
        self.full_at_start = self.q.len() as u32 >= depth;
        self.pops += 1;
        if let Some(log) = &mut self.log {
            log.push(LinkEvent::Pop { at: now });
        }
        self.touched = true;
        Some(data)
    }
}

impl<T: Payload> ProdSide<T> {
    fn violation(&mut self, at: Time, what: &str) {
        self.touched = true;
        self.violations.push((at, what.into()));
    }

    /// Space at the start of this cycle, minus this cycle's push.
    #[inline]
    pub(crate) fn can_push(&self) -> bool {
        self.pending.is_none() && self.space_at_start
    }

    /// Pushes; returns the time the payload becomes visible.
    #[inline]
    pub(crate) fn push(&mut self, now: Time, delay_ps: Time, data: T) -> Option<Time> {
        if !self.can_push() {
            let why = if self.pending.is_some() {
                "second push in one cycle"
            } else {
                "push into a full FIFO (ready was low)"
            };
            self.violation(now, why);
            return None;
        }
        if let Some(s) = self.stalled.take()
            && !s.same_bits(&data)
        {
            self.violation(
                now,
                "payload changed while stalled (valid data must hold until ready)",
            );
        }
        let visible = now + delay_ps;
        self.pending = Some(Entry { visible, data });
        self.offered_now = true;
        self.pushes += 1;
        if let Some(log) = &mut self.log {
            log.push(LinkEvent::Push { at: now, visible });
        }
        self.touched = true;
        Some(visible)
    }

    pub(crate) fn is_stalled(&self) -> bool {
        self.stalled.is_some()
    }

    pub(crate) fn touched(&self) -> bool {
        self.touched
    }

    /// Offer: push if there is space, else remember the payload as stalled.
    #[inline]
    pub(crate) fn offer(&mut self, now: Time, delay_ps: Time, data: T) -> Option<Time> {
        if self.can_push() {
            return self.push(now, delay_ps, data);
        }
        if let Some(s) = &self.stalled
            && !s.same_bits(&data)
        {
            self.violation(
                now,
                "payload changed while stalled (valid data must hold until ready)",
            );
        }
        if self.stalled.is_none() {
            self.refused_offers += 1;
        }
        self.stalled = Some(data);
        self.offered_now = true;
        self.touched = true;
        None
    }

    /// Called after the producer's evaluation: a stalled offer must be repeated.
    fn check_offer_held(&mut self, now: Time) -> bool {
        if self.stalled.is_some() && !self.offered_now {
            self.violation(
                now,
                "valid dropped while stalled (a refused payload must be offered until taken)",
            );
            self.stalled = None;
            return true;
        }
        false
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
pub(crate) trait LinkDyn: Any + Send + Sync {
    fn name(&self) -> &str;
    /// Whether either half was touched since the last edge.
    fn touched(&self) -> bool;
    /// Clock edge: moves this cycle's violations to `violations`, retires this
    /// cycle's pop, enqueues this cycle's push, and tells the simulator what it
    /// mirrors (one virtual call per touched link and edge).
    fn edge(&mut self, violations: &mut Vec<Violation>) -> EdgeResult;
    /// `valid`, `ready`, `data` of the consumer's port: `ready` is whether
    /// it popped when the head is visible, else `ready_idle` (the consumer's
    /// `can_accept`).
    fn sample_consumer(&self, now: Time, ready_idle: bool, out: [&mut Bits; 3]);
    /// Whether the FIFO had room at the start of this cycle (the producer's
    /// registered ready).
    fn space_at_start(&self) -> bool;
    fn sample_producer(&self, out: [&mut Bits; 3]);
    /// The data a port with no payload shows (it holds the last one it
    /// showed), for the first value of a trace window: at the consumer the
    /// last payload popped, at the producer the last pushed; zeros before
    /// any (the reset value). Needs `set_keep_last` from before the pops.
    fn sample_held(&self, consumer: bool, data: &mut Bits);
    /// Keeps the last payload popped (a tracer watches the link).
    fn set_keep_last(&mut self, on: bool);
    /// The payload's fields, for the waveform (`Payload::field_list`).
    fn fields(&self) -> Vec<super::bits::Field>;
    fn ends(&self) -> (Option<UnitId>, Option<UnitId>);
    fn set_ends(&mut self, producer: Option<UnitId>, consumer: Option<UnitId>);
    fn set_delay_ps(&mut self, ps: Time);
    fn cfg(&self) -> LinkCfg;
    fn reset(&mut self);
    /// See `ProdSide::check_offer_held`; only the producer's thread may call this
    /// between edges.
    fn check_offer_held(&self, now: Time) -> bool;
    /// Only the producer's thread may call this between edges.
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
    fn touched(&self) -> bool {
        self.cons_ref().touched || self.prod_ref().touched
    }
    fn edge(&mut self, violations: &mut Vec<Violation>) -> EdgeResult {
        let name = &self.name;
        let c = self.cons.get_mut();
        let p = self.prod.get_mut();
        if !c.violations.is_empty() || !p.violations.is_empty() {
            for (at, what) in c.violations.drain(..).chain(p.violations.drain(..)) {
                violations.push(Violation {
                    link: name.clone(),
                    at,
                    what,
                });
            }
        }
        if let Some(log) = &mut self.log {
            log.extend(c.log.iter_mut().flat_map(|l| l.drain(..)));
            log.extend(p.log.iter_mut().flat_map(|l| l.drain(..)));
        }
        // Enqueue this cycle's push, then retire this cycle's pop; a pop that made
        // room in a full FIFO wakes the producer.
        if let Some(e) = p.pending.take() {
            c.q.push_back(e);
            self.max_occupancy = self.max_occupancy.max(c.q.len() as u32);
        }
        let wake_producer = c.pops_now > 0 && c.full_at_start;
        if c.pops_now > 0 {
            let e = c.q.pop_front();
            if self.keep_last
                && let Some(e) = e
            {
                match &mut self.last {
                    Some(b) => **b = e.data,
                    None => self.last = Some(Box::new(e.data)),
                }
            }
        }
        c.pops_now = 0;
        p.offered_now = false;
        c.full_at_start = false;
        c.touched = false;
        p.touched = false;
        p.space_at_start = (c.q.len() as u32) < self.depth;
        EdgeResult {
            wake_producer,
            head: c.head_time(),
            space: p.can_push(),
        }
    }
    fn sample_consumer(&self, now: Time, ready_idle: bool, out: [&mut Bits; 3]) {
        let [valid, ready, data] = out;
        let c = self.cons_ref();
        let head = c.q.front().filter(|e| e.visible <= now);
        valid.push(head.is_some() as u64, 1);
        let r = if head.is_some() {
            c.pops_now > 0
        } else {
            ready_idle
        };
        ready.push(r as u64, 1);
        match head {
            Some(e) => e.data.pack(data),
            None => data.clear(), // empty = hold the previous value
        }
    }
    fn sample_producer(&self, out: [&mut Bits; 3]) {
        let [valid, ready, data] = out;
        let p = self.prod_ref();
        valid.push((p.pending.is_some() || p.stalled.is_some()) as u64, 1);
        ready.push(p.space_at_start as u64, 1);
        if let Some(s) = &p.stalled {
            s.pack(data);
        } else if let Some(e) = &p.pending {
            e.data.pack(data);
        } else {
            data.clear();
        }
    }
    fn space_at_start(&self) -> bool {
        self.prod_ref().space_at_start
    }
    fn sample_held(&self, consumer: bool, data: &mut Bits) {
        data.clear();
        // FIFO order: the last pushed is the tail while there is one.
        let tail = (!consumer)
            .then(|| self.cons_ref().q.back().map(|e| &e.data))
            .flatten();
        match tail.or(self.last.as_deref()) {
            Some(v) => v.pack(data),
            None => {
                let mut left = T::BITS;
                while left > 0 {
                    data.push(0, left.min(64));
                    left -= left.min(64);
                }
            }
        }
    }
    fn set_keep_last(&mut self, on: bool) {
        self.keep_last = on;
        if !on {
            self.last = None;
        }
    }
    fn fields(&self) -> Vec<super::bits::Field> {
        T::field_list()
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
        let c = self.cons.get_mut();
        c.q.clear();
        c.pops_now = 0;
        c.full_at_start = false;
        c.touched = false;
        c.pops = 0;
        c.violations.clear();
        let p = self.prod.get_mut();
        p.pending = None;
        p.space_at_start = self.depth > 0;
        p.touched = false;
        p.stalled = None;
        p.offered_now = false;
        p.pushes = 0;
        p.refused_offers = 0;
        p.violations.clear();
        self.last = None;
        self.max_occupancy = 0;
        if let Some(l) = &mut self.log {
            l.clear();
        }
        for l in [&mut c.log, &mut p.log].into_iter().flatten() {
            l.clear();
        }
    }
    fn check_offer_held(&self, now: Time) -> bool {
        // SAFETY: called by the producer's thread after its evaluation (see trait).
        unsafe { self.prod() }.check_offer_held(now)
    }
    fn stats(&self) -> LinkStats {
        let (c, p) = (self.cons_ref(), self.prod_ref());
        LinkStats {
            pushes: p.pushes,
            pops: c.pops,
            refused_offers: p.refused_offers,
            max_occupancy: self.max_occupancy,
        }
    }
    fn is_stalled(&self) -> bool {
        // SAFETY: called by the producer's thread (see trait).
        unsafe { self.prod() }.is_stalled()
    }
    #[inline]
    fn head_time(&self) -> Time {
        self.cons_ref().head_time()
    }
    #[inline]
    fn has_space(&self) -> bool {
        self.prod_ref().can_push()
    }
    fn occupancy(&self) -> u32 {
        let (c, p) = (self.cons_ref(), self.prod_ref());
        c.q.len() as u32 + p.pending.is_some() as u32
    }
    fn set_log(&mut self, on: bool) {
        self.log = on.then(Box::default);
        self.cons.get_mut().log = on.then(Box::default);
        self.prod.get_mut().log = on.then(Box::default);
    }
    fn log(&self) -> &[LinkEvent] {
        self.log.as_deref().map_or(&[], |l| l.as_slice())
    }
}
