//! One channel's controller under DRAMsim3's rules (`mem.ctrl.policy =
//! "dramsim3"`, the `dramsim3-gddr5` preset), so that a trace replayed here and
//! through DRAMsim3 takes the same cycles. Written from DRAMsim3's description
//! of its controller (`controller.cc`, `command_queue.cc`, `channel_state.cc`,
//! `refresh.cc`); the DRAM timing itself is the shared `ChannelTiming`.
//!
//! Per DRAM cycle, in DRAMsim3's order:
//! 1. refresh falls due every tREFI; while one is due, the open banks are
//!    precharged (lowest bank first) and REF issues, and no queued command goes;
//! 2. otherwise one command from the per-bank command queues (`cmd_queue`
//!    deep), round robin from the bank after the last one that issued; within a
//!    bank the first command in queue order whose next DRAM command (ACT, PRE or
//!    the RD/WR itself) is legal. A PRE goes only for the bank's oldest command,
//!    and only if no queued command hits the open row or four column commands
//!    already hit it; a WR waits behind a queued RD to the same column;
//! 3. one transaction moves from the read queue (or the write buffer while it
//!    drains) to its bank's command queue: the oldest whose bank queue has room.
//!    A drain starts when the write buffer is full, or when it holds more than
//!    `write_low` writes and every command queue is empty, and moves the writes
//!    present at its start (it stops early at a write whose address a queued
//!    read still has to read).
//!
//! Requests: a write is acknowledged one cycle after the write buffer takes it
//! (a second write to a buffered address only takes the acknowledgement); a read
//! of a buffered write's address returns one cycle after arrival; a read of an
//! address already being read joins it. Addresses compare whole, as in DRAMsim3.
//! A request's arrival is the cycle after the one it is offered in (DRAMsim3's
//! trace CPU adds it after the memory's tick). Up to `write_low` writes may stay
//! in the buffer while nothing else is queued: DRAMsim3 writes them only when a
//! later drain starts, and neither does this model (they are acknowledged, and
//! reads of them are forwarded).
//!
//! Statistics as DRAMsim3 keeps them: read latency from arrival to the end of
//! the data (including the queueing), write latency from arrival to the end of
//! the WR's data; the per-stream latency of a write is that of its
//! acknowledgement. Queue occupancy counts the requests held in the transaction
//! queues and the command queues together.
//!
//! Stepped by events like `ChannelCtrl`: after each cycle the controller knows
//! the earliest cycle at which a command may become legal or a transaction may
//! move, and sleeps until then (`tests/mem.rs` checks this against stepping
//! every cycle).

use std::collections::{HashMap, VecDeque};

use super::books::Books;
use super::config::MemCfg;
use super::map::AddrMap;
use super::stats::ChannelStats;
use super::timing::{ChannelTiming, Command, DramCmd};
use super::{MemReq, MemResp, StreamTag};

/// Row-buffer outcome of a request, decided by the first command issued for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Class {
    Unset,
    Miss,
    Conflict,
}

/// A transaction, and once moved, its command in a bank queue.
#[derive(Clone, Debug)]
struct Trans {
    addr: u64,
    write: bool,
    bank: u32,
    row: u32,
    col: u32,
    class: Class,
}

/// A read waiting for its data (merged reads of one address share the RD).
#[derive(Clone, Copy, Debug)]
struct Waiter {
    id: u32,
    tag: StreamTag,
    arrive: u64,
}

#[derive(Clone, Debug)]
pub struct Dramsim3Ctrl {
    pub channel: u32,
    nbanks: u32,
    map: AddrMap,
    banks_per_group: u32,
    burst: u64,
    cl: u64,
    cwl: u64,
    refi: u64,
    rq_cap: usize,
    wq_cap: usize,
    cmd_cap: usize,
    idle_drain_above: usize,
    timing: ChannelTiming,
    /// Read queue and write buffer, oldest first.
    rq: Vec<Trans>,
    wq: Vec<Trans>,
    /// Per bank: its command queue in order.
    cmdq: Vec<Vec<Trans>>,
    cmds: usize,
    /// Reads not yet read by a RD, by address; writes not yet written, by
    /// address, with their arrival.
    pending_rd: HashMap<u64, Vec<Waiter>>,
    pending_wr: HashMap<u64, u64>,
    /// Writes left to move in the current drain (0: serving reads).
    draining: usize,
    /// Bank queue of the last command issued (round robin).
    rr: u32,
    /// Column commands to the open row since its ACT, per bank.
    row_hits: Vec<u32>,
    /// Requests held: reads not yet read, writes not yet written.
    reads_held: usize,
    writes_held: usize,
    resp: VecDeque<(u64, MemResp)>,
    refresh_due: u64,
    refresh_pending: bool,
    next_event: u64,
    books: Books,
    every_cycle: bool,
}

impl Dramsim3Ctrl {
    /// A controller for channel `channel` of `cfg` (validated, policy
    /// `dramsim3`) at `tck_ps`.
    pub fn new(cfg: &MemCfg, tck_ps: u64, channel: u32) -> Self {
        let g = &cfg.geometry;
        let map = AddrMap::new(g, &cfg.mapping).expect("validated mapping");
        assert!(g.banks() <= 64, "at most 64 banks");
        assert_eq!(g.bursts_per_line(), 1, "validated: one burst per request");
        Dramsim3Ctrl {
            channel,
            nbanks: g.banks(),
            map,
            banks_per_group: g.banks_per_group,
            burst: g.burst_cycles() as u64,
            cl: cfg.timing.cl as u64,
            cwl: cfg.timing.cwl as u64,
            refi: cfg.timing.refi as u64,
            rq_cap: cfg.ctrl.read_queue as usize,
            wq_cap: cfg.ctrl.write_queue as usize,
            cmd_cap: cfg.ctrl.cmd_queue as usize,
            idle_drain_above: cfg.ctrl.write_low as usize,
            timing: ChannelTiming::new(&cfg.timing, g),
            rq: Vec::with_capacity(cfg.ctrl.read_queue as usize),
            wq: Vec::with_capacity(cfg.ctrl.write_queue as usize),
            cmdq: vec![Vec::with_capacity(cfg.ctrl.cmd_queue as usize); g.banks() as usize],
            cmds: 0,
            pending_rd: HashMap::new(),
            pending_wr: HashMap::new(),
            draining: 0,
            rr: 0,
            row_hits: vec![0; g.banks() as usize],
            reads_held: 0,
            writes_held: 0,
            resp: VecDeque::new(),
            refresh_due: cfg.timing.refi as u64,
            refresh_pending: false,
            next_event: cfg.timing.refi as u64,
            books: Books::new(cfg, tck_ps),
            every_cycle: false,
        }
    }

    /// Records every issued command (for the timing checker).
    pub fn record_commands(&mut self, on: bool) {
        self.books.log = on.then(Vec::new);
    }

    /// Nothing can happen until a request arrives: no response to return, no
    /// read or command queued, and no drain due (up to `write_low` writes may
    /// stay buffered, as in DRAMsim3).
    pub fn is_idle(&self) -> bool {
        self.resp.is_empty()
            && self.rq.is_empty()
            && self.cmds == 0
            && self.draining == 0
            && !self.drain_trigger()
    }
    pub fn can_accept(&self, write: bool) -> bool {
        if write {
            self.wq.len() < self.wq_cap
        } else {
            self.rq.len() < self.rq_cap
        }
    }
    /// Read queue, write buffer and command queue entries of `bank`.
    pub fn queue_lengths(&self, bank: u32) -> (usize, usize, usize) {
        (self.rq.len(), self.wq.len(), self.cmdq[bank as usize].len())
    }
    pub fn next_event(&self) -> u64 {
        self.next_event
    }
    pub fn next_response(&self) -> Option<u64> {
        self.resp.front().map(|r| r.0)
    }

    /// Removes the oldest response if its data ends by `ready_by`.
    pub fn pop_response(&mut self, _now: u64, ready_by: u64) -> Option<MemResp> {
        if self.resp.front().is_none_or(|r| r.0 > ready_by) {
            return None;
        }
        self.resp.pop_front().map(|r| r.1)
    }

    fn occ_integrate(&mut self, c: u64) {
        self.books.occupancy(c, self.reads_held, self.writes_held);
    }
    fn bg_integrate(&mut self, c: u64) {
        self.books.background(c, self.timing.open_banks() > 0);
    }

    fn respond(&mut self, done: u64, r: MemResp) {
        let pos = self
            .resp
            .iter()
            .rposition(|x| x.0 <= done)
            .map_or(0, |p| p + 1);
        self.resp.insert(pos, (done, r));
    }

    /// A read returned at `done` (its data end, or a forwarded write's value).
    fn read_done(&mut self, done: u64, w: Waiter) {
        let lat = done - w.arrive;
        let s = &mut self.books.stats;
        s.reads += 1;
        s.read_latency.add(lat);
        let t = &mut s.per_tag[w.tag as usize];
        t.reads += 1;
        t.latency_sum += lat;
        t.latency_max = t.latency_max.max(lat);
        self.respond(
            done,
            MemResp {
                id: w.id,
                write: false,
                tag: w.tag,
            },
        );
    }

    /// Takes a request offered in cycle `c` (the caller checked `can_accept`);
    /// it arrives in cycle `c + 1`, when it may move to its command queue.
    pub fn accept(&mut self, c: u64, req: MemReq) {
        let arrive = c + 1;
        let loc = match self.map.decode(req.addr) {
            Ok(l) => l,
            Err(_) => {
                self.books.stats.bad_addresses += 1;
                self.map.decode_unchecked(req.addr % self.map.capacity())
            }
        };
        if loc.channel != self.channel {
            self.books.stats.bad_addresses += 1;
        }
        self.occ_integrate(arrive);
        let t = Trans {
            addr: req.addr,
            write: req.write,
            bank: loc.flat_bank(self.banks_per_group),
            row: loc.row,
            col: loc.column,
            class: Class::Unset,
        };
        if req.write {
            assert!(self.wq.len() < self.wq_cap, "write buffer overflow");
            if let std::collections::hash_map::Entry::Vacant(v) = self.pending_wr.entry(req.addr) {
                v.insert(arrive);
                self.wq.push(t);
                self.writes_held += 1;
                self.books.stats.wq_max = self.books.stats.wq_max.max(self.writes_held as u32);
            }
            // Acknowledged when the buffer holds it.
            let s = &mut self.books.stats;
            s.writes += 1;
            let tg = &mut s.per_tag[req.tag as usize];
            tg.writes += 1;
            tg.latency_sum += 1;
            tg.latency_max = tg.latency_max.max(1);
            self.respond(
                arrive + 1,
                MemResp {
                    id: req.id,
                    write: true,
                    tag: req.tag,
                },
            );
        } else {
            assert!(self.rq.len() < self.rq_cap, "read queue overflow");
            let w = Waiter {
                id: req.id,
                tag: req.tag,
                arrive,
            };
            if self.pending_wr.contains_key(&req.addr) {
                self.read_done(arrive + 1, w);
            } else {
                let list = self.pending_rd.entry(req.addr).or_default();
                list.push(w);
                if list.len() == 1 {
                    self.rq.push(t);
                    self.reads_held += 1;
                    self.books.stats.rq_max = self.books.stats.rq_max.max(self.reads_held as u32);
                }
            }
        }
        self.next_event = self.next_event.min(arrive);
    }

    /// Runs every event before cycle `c` (used after sleeping while idle).
    pub fn advance_to(&mut self, c: u64) {
        while self.next_event < c {
            let e = self.next_event;
            self.step(e);
        }
    }

    /// One DRAM cycle: at most one command, then at most one transaction moved.
    /// Does nothing before `next_event`.
    pub fn step(&mut self, c: u64) {
        if c < self.next_event {
            return;
        }
        if c >= self.refresh_due {
            self.refresh_pending = true;
        }
        let floor = self.timing.act_floor();
        if let Some((b, i, kind)) = self.pick(c, floor) {
            self.apply(c, b, i, kind);
        }
        self.schedule();
        let mut wake = self.command_wake(self.timing.act_floor());
        if !self.refresh_pending {
            wake = wake.min(self.refresh_due);
        }
        if self.schedule_would_act() {
            wake = c + 1;
        }
        self.next_event = if self.every_cycle {
            c + 1
        } else {
            wake.max(c + 1)
        };
    }

    /// The command to issue in cycle `c`: (bank, index in its queue, command);
    /// a refresh's PRE or REF has no queue entry.
    fn pick(&self, c: u64, floor: u64) -> Option<(u32, usize, DramCmd)> {
        let t = &self.timing;
        if self.refresh_pending {
            if t.open_banks() == 0 {
                return (t.earliest_ref() <= c).then_some((0, usize::MAX, DramCmd::Ref));
            }
            return (0..self.nbanks)
                .find(|&b| t.open_row(b).is_some() && t.earliest_pre(b) <= c)
                .map(|b| (b, usize::MAX, DramCmd::Pre));
        }
        for k in 1..=self.nbanks {
            let b = (self.rr + k) % self.nbanks;
            if let Some((i, kind)) = self.first_ready(b, c, floor) {
                return Some((b, i, kind));
            }
        }
        None
    }

    /// A write behind a queued read of the same column waits for it.
    fn write_waits(q: &[Trans], i: usize) -> bool {
        let e = &q[i];
        q[..i]
            .iter()
            .any(|p| !p.write && p.row == e.row && p.col == e.col)
    }

    /// The bank's oldest command that misses may precharge only if no queued
    /// command hits the open row, or four column commands already hit it.
    fn pre_allowed(&self, b: u32, open: u32) -> bool {
        let q = &self.cmdq[b as usize];
        q[0].row != open && (self.row_hits[b as usize] >= 4 || q.iter().all(|p| p.row != open))
    }

    /// The first command of bank `b`'s queue, in order, whose next DRAM command
    /// is legal in cycle `c`.
    fn first_ready(&self, b: u32, c: u64, floor: u64) -> Option<(usize, DramCmd)> {
        let q = &self.cmdq[b as usize];
        if q.is_empty() {
            return None;
        }
        let t = &self.timing;
        let Some(open) = t.open_row(b) else {
            // Every command needs the same ACT timing: the oldest goes.
            return (t.earliest_act_after(b, floor) <= c).then_some((0, DramCmd::Act));
        };
        for (i, e) in q.iter().enumerate() {
            if e.row == open {
                if t.earliest_col(b, e.write) <= c && !(e.write && Self::write_waits(q, i)) {
                    return Some((i, if e.write { DramCmd::Wr } else { DramCmd::Rd }));
                }
            } else if i == 0 && t.earliest_pre(b) <= c && self.pre_allowed(b, open) {
                return Some((0, DramCmd::Pre));
            }
        }
        None
    }

    /// The earliest cycle at which `pick` may find a command, the state as it is
    /// (only issued commands and arriving requests change it).
    fn command_wake(&self, floor: u64) -> u64 {
        let t = &self.timing;
        if self.refresh_pending {
            if t.open_banks() == 0 {
                return t.earliest_ref();
            }
            return (0..self.nbanks)
                .filter(|&b| t.open_row(b).is_some())
                .map(|b| t.earliest_pre(b))
                .min()
                .unwrap_or(u64::MAX);
        }
        let mut wake = u64::MAX;
        for b in 0..self.nbanks {
            let q = &self.cmdq[b as usize];
            if q.is_empty() {
                continue;
            }
            match t.open_row(b) {
                None => wake = wake.min(t.earliest_act_after(b, floor)),
                Some(open) => {
                    for (i, e) in q.iter().enumerate() {
                        if e.row == open && !(e.write && Self::write_waits(q, i)) {
                            wake = wake.min(t.earliest_col(b, e.write));
                        }
                    }
                    if self.pre_allowed(b, open) {
                        wake = wake.min(t.earliest_pre(b));
                    }
                }
            }
        }
        wake
    }

    fn command(&mut self, c: u64, kind: DramCmd, bank: u32, row: u32, column: u32) {
        if matches!(kind, DramCmd::Act | DramCmd::Pre) {
            self.bg_integrate(c);
        }
        self.timing.issue(c, kind, bank, row);
        self.books.issued(c, kind, bank, row, column);
    }

    fn apply(&mut self, c: u64, b: u32, i: usize, kind: DramCmd) {
        let bi = b as usize;
        match kind {
            DramCmd::Ref => {
                self.command(c, DramCmd::Ref, 0, 0, 0);
                self.refresh_pending = false;
                self.refresh_due += self.refi;
            }
            DramCmd::Pre => {
                let open = self.timing.open_row(b).expect("open");
                if i != usize::MAX {
                    self.cmdq[bi][i].class = Class::Conflict;
                }
                self.row_hits[bi] = 0;
                self.command(c, DramCmd::Pre, b, open, 0);
            }
            DramCmd::Act => {
                let e = &mut self.cmdq[bi][i];
                if e.class == Class::Unset {
                    e.class = Class::Miss;
                }
                let row = e.row;
                self.command(c, DramCmd::Act, b, row, 0);
            }
            DramCmd::Rd | DramCmd::Wr => {
                self.occ_integrate(c + 1);
                let e = self.cmdq[bi].remove(i);
                self.cmds -= 1;
                self.row_hits[bi] += 1;
                match e.class {
                    Class::Unset => self.books.stats.row_hits += 1,
                    Class::Miss => self.books.stats.row_misses += 1,
                    Class::Conflict => self.books.stats.row_conflicts += 1,
                }
                self.command(c, kind, b, e.row, e.col);
                if kind == DramCmd::Rd {
                    self.reads_held -= 1;
                    let done = c + self.cl + self.burst;
                    for w in self.pending_rd.remove(&e.addr).expect("a pending read") {
                        self.read_done(done, w);
                    }
                } else {
                    self.writes_held -= 1;
                    let arrive = self.pending_wr.remove(&e.addr).expect("a pending write");
                    self.books
                        .stats
                        .write_latency
                        .add(c + self.cwl + self.burst - arrive);
                }
            }
            DramCmd::Nop => {}
        }
        if i != usize::MAX {
            self.rr = b;
        }
    }

    /// DRAMsim3's drain trigger: a full write buffer, or more than `write_low`
    /// writes with nothing in the command queues.
    fn drain_trigger(&self) -> bool {
        self.wq.len() >= self.wq_cap || (self.wq.len() > self.idle_drain_above && self.cmds == 0)
    }

    /// Moves at most one transaction to its bank's command queue.
    fn schedule(&mut self) {
        if self.draining == 0 && self.drain_trigger() {
            self.draining = self.wq.len();
        }
        let writes = self.draining > 0;
        let q = if writes { &self.wq } else { &self.rq };
        let Some(i) = q
            .iter()
            .position(|t| self.cmdq[t.bank as usize].len() < self.cmd_cap)
        else {
            return;
        };
        if writes {
            if self.pending_rd.contains_key(&self.wq[i].addr) {
                // Read before write: serve reads until the read has gone.
                self.draining = 0;
                return;
            }
            self.draining -= 1;
        }
        let t = if writes {
            self.wq.remove(i)
        } else {
            self.rq.remove(i)
        };
        self.cmdq[t.bank as usize].push(t);
        self.cmds += 1;
    }

    /// Whether `schedule` in the next cycle changes anything, the state as it is.
    fn schedule_would_act(&self) -> bool {
        if self.draining == 0 && self.drain_trigger() {
            return true;
        }
        let q = if self.draining > 0 {
            &self.wq
        } else {
            &self.rq
        };
        q.iter()
            .any(|t| self.cmdq[t.bank as usize].len() < self.cmd_cap)
    }

    /// Statistics up to cycle `end`, with the events due before `end` run and
    /// background energy integrated (the controller itself is not changed).
    pub fn stats_at(&self, end: u64) -> ChannelStats {
        let mut me = self.clone();
        me.books.log = None;
        me.advance_to(end);
        let active = me.timing.open_banks() > 0;
        me.books
            .stats_at(end, me.reads_held, me.writes_held, active)
    }

    /// The command log including the events due before `end`.
    pub fn commands_until(&self, end: u64) -> Vec<Command> {
        let mut me = self.clone();
        if me.books.log.is_none() {
            return Vec::new();
        }
        me.advance_to(end);
        me.books.log.take().unwrap_or_default()
    }

    /// Evaluates every cycle instead of sleeping until the computed next event
    /// (a check of that computation: the outcome must not change).
    pub fn set_every_cycle(&mut self, on: bool) {
        self.every_cycle = on;
    }
}
