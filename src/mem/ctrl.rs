//! One channel's memory controller: read and write queues, FR-FCFS scheduling with
//! an open-page policy, write drain between watermarks, all-bank refresh every
//! tREFI, and a response buffer. Stepped by events: `step(c)` issues at most one
//! command in cycle `c` (one command bus) and computes the next cycle at which
//! anything can become legal, so nothing is polled cycle by cycle.
//!
//! Scheduling (FR-FCFS, Rixner et al. 2000; HWREF §5.2): among the queue being
//! served, the oldest request whose column command (a row hit) is legal now goes
//! first; otherwise the oldest request whose ACT or PRE is legal now. A PRE is held
//! back while a request in the served queue still hits the open row (row-hit
//! preserving, as simtrax). Reads are served unless the write queue reached
//! `write_high` (then writes drain down to `write_low`) or no read is waiting.
//! A refresh, once due, precharges every bank and then issues REF; nothing else
//! issues meanwhile.
//!
//! Queues: requests live in a slab of slots; each queue keeps its slots in age
//! order, and per bank (`bank_q`) with the number that hit the bank's open row,
//! so one decision looks at the banks that hold requests (each bank's oldest
//! request and oldest row hit are the only candidates) instead of every request.
//! `pick_scan` is the plain FR-FCFS scan over the whole queue in age order: it
//! decides while the response buffer is full (the one case where a bank's oldest
//! hit may be held back) and, in debug builds, checks every other decision.
//!
//! The same code runs inside the `mem_ctrl` unit (through its links) and in the
//! trace replay (called directly); `tests/mem.rs` checks that they agree.
//!
//! Idle refresh: when the controller holds nothing, the unit sleeps without
//! waking for refreshes; the refreshes that fell in the idle time are issued at
//! their own cycles (`advance_to`) when the next request arrives or a report is
//! made, so statistics, energy and the command log are as if it had stayed awake.

use std::collections::VecDeque;

use super::books::Books;
use super::config::MemCfg;
use super::map::AddrMap;
use super::stats::ChannelStats;
use super::timing::{ChannelTiming, Command, DramCmd};
use super::{MemReq, MemResp};
use crate::rtl::bits::clog2_u32;
use crate::rtl::decl::{Samples, StateDecl, StateList};
use crate::rtl::{Payload, State};

mod schedule;

/// Row-buffer outcome of a request, decided by the first command it needed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Class {
    Unset,
    Miss,
    Conflict,
}

#[derive(Clone, Debug)]
struct Entry {
    req: MemReq,
    /// Arrival order within the controller (FR-FCFS age).
    seq: u64,
    bank: u32,
    row: u32,
    /// First burst of the line within the row.
    col: u32,
    arrive: u64,
    bursts_done: u32,
    class: Class,
}

/// What to issue; `Col`, `Act` and `Pre` name the request's slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Choice {
    Col(usize),
    Act(usize),
    Pre(usize),
    PreForRefresh(u32),
    Ref,
}

/// Values of the traced registers at the start of the current cycle.
#[derive(Clone, Copy, Debug, Default)]
struct Traced {
    rq: u32,
    wq: u32,
    resp: u32,
    drain: bool,
    refresh: bool,
}

#[derive(Clone, Debug)]
pub struct ChannelCtrl {
    pub channel: u32,
    /// What `reset` rebuilds from.
    cfg: MemCfg,
    tck_ps: u64,
    nbanks: u32,
    map: AddrMap,
    banks_per_group: u32,
    bursts_per_line: u32,
    burst: u64,
    cl: u64,
    cwl: u64,
    refi: u64,
    rq_cap: usize,
    wq_cap: usize,
    resp_cap: usize,
    write_high: usize,
    write_low: usize,
    row_bits: u32,
    bank_bits: u32,
    col_bits: u32,
    timing: ChannelTiming,
    /// Queued requests by slot; `free` holds the unused slots.
    slots: Vec<Entry>,
    free: Vec<u16>,
    /// Slots of the read (0) and write (1) queue in age order.
    order: [Vec<u16>; 2],
    /// Per queue and bank (`q * nbanks + bank`): slots in age order, and how
    /// many of them hit the bank's open row.
    bank_q: Vec<Vec<u16>>,
    hits: Vec<u16>,
    /// Per queue: banks with at least one request.
    nonempty: [u64; 2],
    next_seq: u64,
    /// Requests whose last burst has issued, by cycle their data ends.
    resp: VecDeque<(u64, MemResp)>,
    drain: bool,
    refresh_due: u64,
    refresh_pending: bool,
    next_event: u64,
    last_cmd: Option<Command>,
    books: Books,
    /// Something changed this cycle (the edge commits it); `pre` holds what the
    /// traced registers showed before the change.
    dirty: bool,
    pre: Traced,
}

impl ChannelCtrl {
    /// A controller for channel `channel` of `cfg` (validated) at `tck_ps`.
    pub fn new(cfg: &MemCfg, tck_ps: u64, channel: u32) -> Self {
        let g = &cfg.geometry;
        let map = AddrMap::new(g, &cfg.mapping).expect("validated mapping");
        assert!(g.banks() <= 64, "bank masks are 64 bits");
        assert!(
            cfg.ctrl.read_queue + cfg.ctrl.write_queue < u16::MAX as u32,
            "queue slots are 16 bits"
        );
        ChannelCtrl {
            channel,
            cfg: cfg.clone(),
            tck_ps,
            nbanks: g.banks(),
            map,
            banks_per_group: g.banks_per_group,
            bursts_per_line: g.bursts_per_line(),
            burst: g.burst_cycles() as u64,
            cl: cfg.timing.cl as u64,
            cwl: cfg.timing.cwl as u64,
            refi: cfg.timing.refi as u64,
            rq_cap: cfg.ctrl.read_queue as usize,
            wq_cap: cfg.ctrl.write_queue as usize,
            resp_cap: cfg.ctrl.resp_buffer as usize,
            write_high: cfg.ctrl.write_high as usize,
            write_low: cfg.ctrl.write_low as usize,
            row_bits: clog2_u32(g.rows),
            bank_bits: clog2_u32(g.banks()),
            col_bits: clog2_u32(g.columns),
            timing: ChannelTiming::new(&cfg.timing, g),
            slots: Vec::with_capacity((cfg.ctrl.read_queue + cfg.ctrl.write_queue) as usize),
            free: Vec::new(),
            order: [
                Vec::with_capacity(cfg.ctrl.read_queue as usize),
                Vec::with_capacity(cfg.ctrl.write_queue as usize),
            ],
            bank_q: vec![Vec::new(); 2 * g.banks() as usize],
            hits: vec![0; 2 * g.banks() as usize],
            nonempty: [0; 2],
            next_seq: 0,
            resp: VecDeque::with_capacity(cfg.ctrl.resp_buffer as usize),
            drain: false,
            refresh_due: cfg.timing.refi as u64,
            refresh_pending: false,
            next_event: cfg.timing.refi as u64,
            last_cmd: None,
            books: Books::new(cfg, tck_ps),
            dirty: false,
            pre: Traced::default(),
        }
    }

    /// Records every issued command (for the timing checker).
    pub fn record_commands(&mut self, on: bool) {
        self.books.log = on.then(Vec::new);
    }
    pub fn commands(&self) -> &[Command] {
        self.books.log.as_deref().unwrap_or(&[])
    }

    /// Nothing queued, in flight or waiting to be returned.
    pub fn is_idle(&self) -> bool {
        self.order[0].is_empty() && self.order[1].is_empty() && self.resp.is_empty()
    }
    pub fn can_accept(&self, write: bool) -> bool {
        if write {
            self.order[1].len() < self.wq_cap
        } else {
            self.order[0].len() < self.rq_cap
        }
    }
    pub fn queue_lengths(&self) -> (usize, usize, usize) {
        (self.order[0].len(), self.order[1].len(), self.resp.len())
    }
    /// The next cycle at which `step` may do something (refresh included).
    pub fn next_event(&self) -> u64 {
        self.next_event
    }
    /// Data-end cycle of the oldest response, if any.
    pub fn next_response(&self) -> Option<u64> {
        self.resp.front().map(|r| r.0)
    }
    /// The command issued in cycle `c`, if any.
    pub fn command_at(&self, c: u64) -> Option<Command> {
        self.last_cmd.filter(|x| x.cycle == c)
    }

    fn touch(&mut self) {
        if !self.dirty {
            self.dirty = true;
            self.pre = self.traced();
        }
    }
    fn traced(&self) -> Traced {
        Traced {
            rq: self.order[0].len() as u32,
            wq: self.order[1].len() as u32,
            resp: self.resp.len() as u32,
            drain: self.drain,
            refresh: self.refresh_pending,
        }
    }

    /// Queue occupancy integrals up to (not including) cycle `c`.
    fn occ_integrate(&mut self, c: u64) {
        self.books
            .occupancy(c, self.order[0].len(), self.order[1].len());
    }
    /// Background (standby) time up to cycle `c`.
    fn bg_integrate(&mut self, c: u64) {
        self.books.background(c, self.timing.open_banks() > 0);
    }

    fn update_drain(&mut self) {
        if self.drain {
            if self.order[1].len() <= self.write_low {
                self.drain = false;
            }
        } else if self.order[1].len() >= self.write_high {
            self.drain = true;
        }
    }

    /// Takes a request into its queue at cycle `c` (the caller checked
    /// `can_accept`). It is considered from cycle `c + 1` on, as if registered.
    pub fn accept(&mut self, c: u64, req: MemReq) {
        self.touch();
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
        let e = Entry {
            seq: self.next_seq,
            bank: loc.flat_bank(self.banks_per_group),
            row: loc.row,
            col: loc.column * self.bursts_per_line,
            arrive: c,
            bursts_done: 0,
            class: Class::Unset,
            req,
        };
        self.next_seq += 1;
        self.occ_integrate(c + 1);
        let q = e.req.write as usize;
        let len = self.order[q].len() + 1;
        if e.req.write {
            assert!(len <= self.wq_cap, "write queue overflow");
            self.books.stats.wq_max = self.books.stats.wq_max.max(len as u32);
        } else {
            assert!(len <= self.rq_cap, "read queue overflow");
            self.books.stats.rq_max = self.books.stats.rq_max.max(len as u32);
        }
        let qb = q * self.nbanks as usize + e.bank as usize;
        if self.timing.open_row(e.bank) == Some(e.row) {
            self.hits[qb] += 1;
        }
        self.nonempty[q] |= 1 << e.bank;
        let s = match self.free.pop() {
            Some(s) => {
                self.slots[s as usize] = e;
                s
            }
            None => {
                self.slots.push(e);
                (self.slots.len() - 1) as u16
            }
        };
        self.order[q].push(s);
        self.bank_q[qb].push(s);
        self.update_drain();
        self.next_event = self.next_event.min(c + 1);
    }

    /// The oldest response whose data has ended by cycle `c`.
    pub fn peek_response(&self, c: u64) -> Option<&MemResp> {
        self.resp.front().filter(|r| r.0 <= c).map(|r| &r.1)
    }
    /// Removes the oldest response if its data ends by `ready_by`; it leaves in
    /// cycle `now` (a unit hands it to a link `delay` cycles before the data end,
    /// so the requester sees it exactly then). A full buffer may unblock.
    pub fn pop_response(&mut self, now: u64, ready_by: u64) -> Option<MemResp> {
        if self.resp.front().is_none_or(|r| r.0 > ready_by) {
            return None;
        }
        self.touch();
        // Only a full buffer holds a command back; otherwise nothing changes.
        if self.resp.len() >= self.resp_cap {
            self.next_event = self.next_event.min(now);
        }
        self.resp.pop_front().map(|r| r.1)
    }

    /// Runs every event before cycle `c` (used after sleeping while idle).
    pub fn advance_to(&mut self, c: u64) {
        while self.next_event < c {
            let e = self.next_event;
            self.step(e);
        }
    }

    /// One cycle of the scheduler: issues at most one command. Does nothing
    /// before `next_event`.
    pub fn step(&mut self, c: u64) {
        if c < self.next_event {
            return;
        }
        self.touch();
        if c >= self.refresh_due {
            self.refresh_pending = true;
        }
        match self.pick(c) {
            Ok(ch) => {
                self.apply(c, ch);
                self.next_event = c + 1;
            }
            Err(wake) => self.next_event = wake.min(self.refresh_due.max(c + 1)),
        }
    }

    /// After cycle `c`'s command and request: if `step` is due in the next
    /// cycle, finds now whether a command can go then and, if none can, when
    /// one may, so that the controller is not evaluated only to learn that.
    /// Exact: nothing but the controller's own evaluations changes its state,
    /// and a request arriving meanwhile wakes it (`accept` brings the next event
    /// back). Left to `step` when a refresh falls due or the response buffer is
    /// full (its hand-over may unblock a command).
    pub fn look_ahead(&mut self, c: u64) {
        let n = c + 1;
        if self.next_event != n
            || self.refresh_pending
            || n >= self.refresh_due
            || self.resp.len() >= self.resp_cap
        {
            return;
        }
        if let Err(wake) = self.pick(n) {
            self.next_event = wake.min(self.refresh_due.max(n + 1));
        }
    }

    /// The queue being served: writes while draining or when no read waits.
    #[inline]
    fn serving_writes(&self) -> bool {
        self.drain || (self.order[0].is_empty() && !self.order[1].is_empty())
    }

    fn command(&mut self, c: u64, kind: DramCmd, bank: u32, row: u32, column: u32) {
        if matches!(kind, DramCmd::Act | DramCmd::Pre) {
            self.bg_integrate(c);
        }
        self.timing.issue(c, kind, bank, row);
        // Keep the per-bank hit counts of both queues in step with the open row.
        let nb = self.nbanks as usize;
        match kind {
            DramCmd::Act => {
                for q in 0..2 {
                    let qb = q * nb + bank as usize;
                    let n = self.bank_q[qb]
                        .iter()
                        .filter(|&&s| self.slots[s as usize].row == row)
                        .count();
                    self.hits[qb] = n as u16;
                }
            }
            DramCmd::Pre => {
                self.hits[bank as usize] = 0;
                self.hits[nb + bank as usize] = 0;
            }
            _ => {}
        }
        let cmd = self.books.issued(c, kind, bank, row, column);
        self.last_cmd = Some(cmd);
    }

    fn apply(&mut self, c: u64, ch: Choice) {
        let writes = self.serving_writes();
        match ch {
            Choice::Ref => {
                self.command(c, DramCmd::Ref, 0, 0, 0);
                self.refresh_pending = false;
                self.refresh_due += self.refi;
            }
            Choice::PreForRefresh(b) => {
                let row = self.timing.open_row(b).expect("open");
                self.command(c, DramCmd::Pre, b, row, 0);
            }
            Choice::Act(s) | Choice::Pre(s) => {
                let e = &mut self.slots[s];
                let (bank, row) = (e.bank, e.row);
                if let Choice::Act(_) = ch {
                    if e.class == Class::Unset {
                        e.class = Class::Miss;
                    }
                    self.command(c, DramCmd::Act, bank, row, 0);
                } else {
                    e.class = Class::Conflict;
                    let open = self.timing.open_row(bank).expect("open");
                    self.command(c, DramCmd::Pre, bank, open, 0);
                }
            }
            Choice::Col(s) => {
                let e = &mut self.slots[s];
                let (bank, row, col) = (e.bank, e.row, e.col + e.bursts_done);
                e.bursts_done += 1;
                let first = e.bursts_done == 1;
                let last = e.bursts_done == self.bursts_per_line;
                let class = e.class;
                let kind = if writes { DramCmd::Wr } else { DramCmd::Rd };
                self.command(c, kind, bank, row, col);
                if first {
                    match class {
                        Class::Unset => self.books.stats.row_hits += 1,
                        Class::Miss => self.books.stats.row_misses += 1,
                        Class::Conflict => self.books.stats.row_conflicts += 1,
                    }
                }
                if last {
                    self.complete(c, s, writes);
                }
            }
        }
    }

    /// Takes slot `s` out of queue `q` and its bank list (it hits the open row).
    fn remove(&mut self, s: usize, q: usize) {
        let bank = self.slots[s].bank;
        // A scan of 16-bit slot numbers (no indirection; usually near the front).
        let order = &mut self.order[q];
        let i = order.iter().position(|&x| x as usize == s).expect("queued");
        order.remove(i);
        let qb = q * self.nbanks as usize + bank as usize;
        let list = &mut self.bank_q[qb];
        let j = list.iter().position(|&x| x as usize == s).expect("queued");
        list.remove(j);
        if list.is_empty() {
            self.nonempty[q] &= !(1 << bank);
        }
        debug_assert!(self.hits[qb] > 0, "a completed request hits the open row");
        self.hits[qb] -= 1;
        self.free.push(s as u16);
    }

    /// The last burst of the request in slot `s` issued in cycle `c`.
    fn complete(&mut self, c: u64, s: usize, write: bool) {
        self.occ_integrate(c + 1);
        self.remove(s, write as usize);
        let e = &self.slots[s];
        let lat = if write { self.cwl } else { self.cl };
        let done = c + lat + self.burst;
        let latency = done - e.arrive;
        let (tag_i, id, tag) = (e.req.tag as usize, e.req.id, e.req.tag);
        let s = &mut self.books.stats;
        let tagst = &mut s.per_tag[tag_i];
        if write {
            s.writes += 1;
            s.write_latency.add(latency);
            tagst.writes += 1;
        } else {
            s.reads += 1;
            s.read_latency.add(latency);
            tagst.reads += 1;
        }
        tagst.latency_sum += latency;
        tagst.latency_max = tagst.latency_max.max(latency);
        let resp = MemResp { id, write, tag };
        // Keep the buffer ordered by data end (a write's data ends sooner).
        let pos = self
            .resp
            .iter()
            .rposition(|r| r.0 <= done)
            .map_or(0, |p| p + 1);
        self.resp.insert(pos, (done, resp));
        debug_assert!(self.resp.len() <= self.resp_cap, "response buffer overflow");
        self.update_drain();
    }
    /// Statistics up to cycle `end`, with refreshes due before `end` issued and
    /// background energy integrated (the controller itself is not changed).
    pub fn stats_at(&self, end: u64) -> ChannelStats {
        let mut me = self.clone();
        me.books.log = None;
        me.advance_to(end);
        let active = me.timing.open_banks() > 0;
        me.books
            .stats_at(end, me.order[0].len(), me.order[1].len(), active)
    }

    /// The command log including refreshes due before `end`.
    pub fn commands_until(&self, end: u64) -> Vec<Command> {
        let mut me = self.clone();
        if me.books.log.is_none() {
            return Vec::new();
        }
        me.advance_to(end);
        me.books.log.take().unwrap_or_default()
    }

    /// Counters for the unit's statistics.
    pub fn counters(&self) -> Vec<(&'static str, u64)> {
        let s = &self.books.stats;
        vec![
            ("reads", s.reads),
            ("writes", s.writes),
            ("row_hits", s.row_hits),
            ("row_misses", s.row_misses),
            ("row_conflicts", s.row_conflicts),
            ("act", s.acts),
            ("pre", s.pres),
            ("rd", s.rd_bursts),
            ("wr", s.wr_bursts),
            ("ref", s.refs),
            ("bad_addresses", s.bad_addresses),
        ]
    }

    fn queue_bits(&self) -> (u32, u32, u32) {
        (
            clog2_u32(self.rq_cap as u32 + 1),
            clog2_u32(self.wq_cap as u32 + 1),
            clog2_u32(self.resp_cap as u32 + 1),
        )
    }
}

/// The controller's clocked state as the waveform and the Verilog skeleton see it:
/// queue occupancies, modes, the command issued this cycle, and the queue and
/// open-row memories (not traced).
impl State for ChannelCtrl {
    type Init = Self;
    fn from_init(init: Self) -> Self {
        init
    }
    fn declare(&self, _name: &str, out: &mut StateList) {
        let (rb, wb, pb) = self.queue_bits();
        out.items.push(StateDecl::reg("rd_count", rb));
        out.items.push(StateDecl::reg("wr_count", wb));
        out.items.push(StateDecl::reg("done_count", pb));
        out.items.push(StateDecl::reg("write_drain", 1));
        out.items.push(StateDecl::reg("refresh_pending", 1));
        let mut cmd = StateDecl::reg("cmd", DramCmd::BITS);
        cmd.enum_names = DramCmd::enum_names();
        cmd.ty = Some(DramCmd::sv_type());
        out.items.push(cmd);
        out.items
            .push(StateDecl::reg("cmd_bank", self.bank_bits.max(1)));
        out.items.push(StateDecl::reg("cmd_row", self.row_bits));
        out.items.push(StateDecl::reg("cmd_col", self.col_bits));
        out.items.push(StateDecl::array(
            "rd_queue",
            MemReq::BITS,
            self.rq_cap as u32,
        ));
        out.items.push(StateDecl::array(
            "wr_queue",
            MemReq::BITS,
            self.wq_cap as u32,
        ));
        out.items.push(StateDecl::array(
            "done_buf",
            MemResp::BITS,
            self.resp_cap as u32,
        ));
        out.items.push(StateDecl::array(
            "open_row",
            self.row_bits + 1,
            1 << self.bank_bits,
        ));
    }
    fn sample(&self, cycle: u64, out: &mut Samples) {
        let (rb, wb, pb) = self.queue_bits();
        let v = if self.dirty { self.pre } else { self.traced() };
        out.slot().push(v.rq as u64, rb);
        out.slot().push(v.wq as u64, wb);
        out.slot().push(v.resp as u64, pb);
        out.slot().push(v.drain as u64, 1);
        out.slot().push(v.refresh as u64, 1);
        let c = self.command_at(cycle);
        out.slot()
            .push(c.map_or(DramCmd::Nop, |c| c.kind) as u64, DramCmd::BITS);
        out.slot()
            .push(c.map_or(0, |c| c.bank) as u64, self.bank_bits.max(1));
        out.slot()
            .push(c.map_or(0, |c| c.row) as u64, self.row_bits);
        out.slot()
            .push(c.map_or(0, |c| c.column) as u64, self.col_bits);
    }
    /// Idle, as built (what `reset` rebuilds).
    fn sample_reset(&self, out: &mut Samples) {
        ChannelCtrl::new(&self.cfg, self.tck_ps, self.channel).sample(0, out);
    }
    fn commit(&mut self) {
        self.dirty = false;
    }
    fn reset(&mut self) {
        let log = self.books.log.is_some();
        *self = ChannelCtrl::new(&self.cfg, self.tck_ps, self.channel);
        self.record_commands(log);
    }
    fn pending_change(&self) -> bool {
        self.dirty
    }
    /// The last command shows in its own cycle only: the view moves until
    /// that cycle has passed.
    fn moves(&self, cycle: u64) -> bool {
        self.last_cmd.is_some_and(|x| x.cycle >= cycle)
    }
}
