//! The L1 data cache of a TM (paper Figure 1, Table 1: 16 KB, 8 banks). Direct
//! mapped like simtrax's L1; tags are whole DRAM line addresses, so a segment slot of
//! the scene buffer reused for another treelet can never return stale bytes.
//!
//! One request port per TP (a TP has at most one load outstanding). Line `i` lives in
//! bank `i mod banks`; each bank serves one request per cycle, chosen round-robin
//! from the TP `cycle mod tps` on (a function of absolute time, so sleeping cannot
//! change the choice); the others are bank conflicts and retry. A hit is answered
//! `hit_latency` cycles after acceptance (response link included). A miss takes a miss
//! register (MSHR): a second miss to the same line joins it, a miss with none free
//! waits. One line request per cycle leaves on `miss_req`; when the line comes back
//! on `miss_resp` it is written to its slot and every waiting TP gets it at once.

use crate::rtl::bits::{Bits, Payload};
use crate::rtl::{Ctx, LinkId, Logic, Next, Ram, Ready, Status};
use crate::util::{div, rem};

use super::tm::L1Cfg;

/// One 64 B line, as bytes (packed as eight little-endian words).
#[derive(Clone, Debug, PartialEq)]
pub struct Line(pub [u8; 64]);

impl Default for Line {
    fn default() -> Self {
        Line([0; 64])
    }
}

impl Payload for Line {
    const BITS: u32 = 512;
    fn pack(&self, out: &mut Bits) {
        for w in self.0.chunks_exact(8) {
            out.push(u64::from_le_bytes(w.try_into().expect("8 bytes")), 64);
        }
    }
    fn same_bits(&self, other: &Self) -> bool {
        self.0 == other.0
    }
}

impl Line {
    pub fn u32_at(&self, off: usize) -> u32 {
        u32::from_le_bytes(self.0[off..off + 4].try_into().expect("4 bytes"))
    }
    pub fn f32_at(&self, off: usize) -> f32 {
        f32::from_bits(self.u32_at(off))
    }
}

crate::payload_struct! {
    /// A line request: the line's DRAM address (64 B aligned).
    pub struct L1Req {
        pub addr: u64,
    }
}

crate::payload_struct! {
    /// A line: its DRAM address and its bytes.
    pub struct L1Resp {
        pub addr: u64,
        pub line: Line,
    }
}

crate::payload_struct! {
    /// A miss register: the missing line and the TPs waiting for it.
    #[derive(Default)]
    pub struct Mshr {
        pub valid: bool,
        pub sent: bool,
        pub addr: u64,
        pub waiters: u32,
        /// Allocation order: the oldest unsent miss goes out first.
        pub seq: u32,
    }
}

crate::payload_struct! {
    /// A hit on its way out of the data array: the port's response slot. Its line
    /// is in `pending_line`, a separate array, so the scan of the slots every
    /// evaluation touches a few bytes per port instead of a line.
    #[derive(Default, Copy)]
    pub struct Pending {
        pub valid: bool,
        pub due: u64,
        pub addr: u64,
    }
}

crate::unit! {
    /// Per-TM L1: direct mapped, banked, DRAM-address tags, bounded miss registers.
    pub struct L1 : "l1" {
        /// `out_delay`: the delay of the `resp` links (part of `hit_latency`).
        new(cfg: &L1Cfg, out_delay: u32; ports: L1Ports) {
            let lines = cfg.bytes / cfg.line_bytes;
            let n = req.len() as u32;
        }
        params {
            bytes: u32 = cfg.bytes => "BYTES",
            banks: u32 = cfg.banks => "BANKS",
            line_bytes: u32 = cfg.line_bytes => "LINE_BYTES",
            hit_latency: u32 = cfg.hit_latency => "HIT_LATENCY",
            mshr_count: u32 = cfg.mshrs => "MSHRS"
        }
        inputs { miss_resp: L1Resp }
        outputs { miss_req: L1Req }
        in_arrays { req: L1Req }
        out_arrays { resp: L1Resp }
        state {
            // Tag = line address + 1; 0 is an invalid slot.
            tags: Ram<u64> = Ram::new(lines, 1, 0).sized_by("BYTES / LINE_BYTES"),
            data: Ram<Line> = Ram::new(lines, 1, Line::default()).sized_by("BYTES / LINE_BYTES"),
            mshr: Ram<Mshr> = Ram::new(cfg.mshrs, cfg.mshrs, Mshr::default()).sized_by("MSHRS"),
            pending: Ram<Pending> = Ram::new(n, n, Pending::default()),
            pending_line: Ram<Line> = Ram::new(n, n, Line::default()),
            next_seq: crate::rtl::Reg<u32> = 0
        }
        extra {
            out_delay: u32 = out_delay,
            stats: L1Stats = L1Stats::default(),
            log: Option<Vec<(u16, u64)>> = None,
            scratch: L1Scratch = L1Scratch::default()
        }
    }
}

/// Per-evaluation working copies, kept between evaluations only so that a busy
/// cycle allocates nothing (cleared at the start of every `eval`; not state).
#[derive(Clone, Debug, Default)]
pub struct L1Scratch {
    mshr: Vec<Mshr>,
    mshr_dirty: Vec<bool>,
    pend: Vec<Option<Pending>>,
    bank_busy: Vec<bool>,
}

/// What one evaluation did, for its status and its next evaluation.
#[derive(Clone, Copy, Debug, Default)]
struct Outcome {
    worked: bool,
    /// A request could not be served (bank, slot, MSHRs): try again next cycle.
    waiting: bool,
    /// Only an output is full; the pop that frees it wakes us, so we sleep
    /// meanwhile (re-offering changes nothing).
    blocked: bool,
    /// An input popped this cycle holds another entry (only a push wakes us).
    more: bool,
    /// The earliest hit still in the data array.
    next_due: Option<u64>,
}

/// Event counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct L1Stats {
    pub accesses: u64,
    pub hits: u64,
    pub misses: u64,
    /// Misses that joined a line already missing.
    pub merged: u64,
    /// Request-cycles lost to another TP on the same bank.
    pub bank_conflicts: u64,
    /// Request-cycles waiting for a free miss register.
    pub mshr_stalls: u64,
    pub fills: u64,
}

impl L1 {
    /// Records every accepted request as (port, address) (tests read the order).
    pub fn enable_log(&mut self) {
        self.log = Some(Vec::new());
    }

    fn lines(&self) -> u64 {
        div(self.bytes as u64, self.line_bytes as u64)
    }
    fn bank_of(&self, addr: u64) -> u32 {
        rem(div(addr, self.line_bytes as u64), self.banks as u64) as u32
    }
    /// Slot of a line: bank-major, so a bank is one contiguous SRAM.
    fn slot_of(&self, addr: u64) -> u32 {
        let i = div(addr, self.line_bytes as u64);
        let banks = self.banks as u64;
        let per_bank = div(self.lines(), banks);
        (rem(i, banks) * per_bank + rem(div(i, banks), per_bank)) as u32
    }

    /// The miss registers and response slots as working copies for this
    /// evaluation (written back by `end_cycle`).
    fn begin_cycle(&mut self) -> L1Scratch {
        let n = self.req.len();
        let mut s = std::mem::take(&mut self.scratch);
        s.mshr.clear();
        s.mshr
            .extend((0..self.mshr_count).map(|k| self.mshr.read(k).clone()));
        s.mshr_dirty.clear();
        s.mshr_dirty.resize(s.mshr.len(), false);
        s.pend.clear();
        s.pend.resize(n, None);
        s
    }

    /// A line from the miss port: fill its slot, answer its waiters now.
    fn accept_fill(&mut self, ctx: &mut Ctx, s: &mut L1Scratch, o: &mut Outcome) -> Option<L1Resp> {
        let n = self.req.len();
        let mshr = &mut s.mshr;
        let f = ctx.peek(&self.miss_resp).cloned()?;
        let k = mshr.iter().position(|m| m.valid && m.addr == f.addr);
        let k = k.expect("a line comes back only for a miss register");
        let ok = (0..n).all(|p| mshr[k].waiters & (1 << p) == 0 || ctx.can_push(&self.resp.at(p)));
        if !ok {
            o.blocked = true;
            return None;
        }
        ctx.pop(&self.miss_resp);
        o.more |= ctx.holds_more(&self.miss_resp);
        let slot = self.slot_of(f.addr);
        self.tags.write(slot, f.addr + 1);
        self.data.write(slot, f.line.clone());
        for p in 0..n {
            if mshr[k].waiters & (1 << p) != 0 {
                ctx.push(&self.resp.at(p), f.clone());
            }
        }
        mshr[k] = Mshr::default();
        s.mshr_dirty[k] = true;
        self.stats.fills += 1;
        o.worked = true;
        Some(f)
    }

    /// Hits whose data array access is done leave on their port.
    fn answer_hits(&mut self, ctx: &mut Ctx, s: &mut L1Scratch, o: &mut Outcome) {
        let c = ctx.cycle();
        for (p, slot) in s.pend.iter_mut().enumerate() {
            let e = *self.pending.read(p as u32);
            if !e.valid {
                continue;
            }
            if e.due <= c {
                let r = L1Resp {
                    addr: e.addr,
                    line: self.pending_line.read(p as u32).clone(),
                };
                if ctx.offer(&self.resp.at(p), r) {
                    *slot = Some(Pending::default());
                    o.worked = true;
                } else {
                    o.blocked = true;
                }
            } else {
                o.next_due = Some(o.next_due.map_or(e.due, |d: u64| d.min(e.due)));
            }
        }
    }

    /// TP requests: one per bank per cycle, round-robin from TP `c mod n`; a hit
    /// enters the data array, a miss takes or joins a miss register.
    fn accept_requests(
        &mut self,
        ctx: &mut Ctx,
        s: &mut L1Scratch,
        o: &mut Outcome,
        filled: &Option<L1Resp>,
    ) {
        let c = ctx.cycle();
        let n = self.req.len();
        let (mshr, bank_busy) = (&mut s.mshr, &mut s.bank_busy);
        bank_busy.clear();
        bank_busy.resize(self.banks as usize, false);
        let start = ctx.round_robin_start(n);
        let visible = if n <= 64 {
            ctx.visible_mask(&self.req)
        } else {
            u64::MAX
        };
        for p in (start..n).chain(0..start) {
            if p < 64 && visible >> p & 1 == 0 {
                continue;
            }
            let Some(r) = ctx.peek(&self.req.at(p)).cloned() else {
                continue;
            };
            let b = self.bank_of(r.addr) as usize;
            // A port has one response slot; a TP has one load outstanding anyway.
            let slot_busy = self.pending.read(p as u32).valid && s.pend[p].is_none();
            if bank_busy[b] || slot_busy {
                self.stats.bank_conflicts += bank_busy[b] as u64;
                o.waiting = true;
                continue;
            }
            let slot = self.slot_of(r.addr);
            let hit_line = match filled {
                Some(f) if f.addr == r.addr => Some(f.line.clone()),
                _ if *self.tags.read(slot) == r.addr + 1 => Some(self.data.read(slot).clone()),
                _ => None,
            };
            match hit_line {
                Some(line) => {
                    bank_busy[b] = true;
                    ctx.pop(&self.req.at(p));
                    o.more |= ctx.holds_more(&self.req.at(p));
                    self.stats.hits += 1;
                    let due = c + (self.hit_latency - self.out_delay) as u64;
                    if due == c {
                        ctx.push(&self.resp.at(p), L1Resp { addr: r.addr, line });
                    } else {
                        s.pend[p] = Some(Pending {
                            valid: true,
                            due,
                            addr: r.addr,
                        });
                        self.pending_line.write(p as u32, line);
                        o.next_due = Some(o.next_due.map_or(due, |d| d.min(due)));
                    }
                }
                None => {
                    let same = mshr.iter().position(|m| m.valid && m.addr == r.addr);
                    let k = same.or_else(|| mshr.iter().position(|m| !m.valid));
                    let Some(k) = k else {
                        self.stats.mshr_stalls += 1;
                        o.waiting = true;
                        continue;
                    };
                    bank_busy[b] = true;
                    ctx.pop(&self.req.at(p));
                    o.more |= ctx.holds_more(&self.req.at(p));
                    self.stats.misses += 1;
                    if same.is_some() {
                        self.stats.merged += 1;
                    } else {
                        let seq = self.next_seq.val();
                        self.next_seq.set(seq.wrapping_add(1));
                        mshr[k] = Mshr {
                            valid: true,
                            sent: false,
                            addr: r.addr,
                            waiters: 0,
                            seq,
                        };
                    }
                    mshr[k].waiters |= 1 << p;
                    s.mshr_dirty[k] = true;
                }
            }
            self.stats.accesses += 1;
            if let Some(log) = &mut self.log {
                log.push((p as u16, r.addr));
            }
            o.worked = true;
        }
    }

    /// The oldest unsent miss leaves on the miss port.
    fn issue_miss(&mut self, ctx: &mut Ctx, s: &mut L1Scratch, o: &mut Outcome) {
        let mshr = &mut s.mshr;
        let oldest = mshr
            .iter()
            .enumerate()
            .filter(|(_, m)| m.valid && !m.sent)
            .min_by_key(|(_, m)| m.seq)
            .map(|(k, _)| k);
        if let Some(k) = oldest {
            if ctx.can_push(&self.miss_req) {
                ctx.push(&self.miss_req, L1Req { addr: mshr[k].addr });
                mshr[k].sent = true;
                s.mshr_dirty[k] = true;
                o.worked = true;
            } else {
                o.blocked = true;
            }
        }
    }

    /// Writes the changed miss registers and response slots back; returns
    /// whether a miss is still waiting to be sent.
    fn end_cycle(&mut self, mut s: L1Scratch) -> bool {
        let unsent = s.mshr.iter().any(|m| m.valid && !m.sent);
        for (k, m) in s.mshr.drain(..).enumerate() {
            if s.mshr_dirty[k] {
                self.mshr.write(k as u32, m);
            }
        }
        for (p, e) in s.pend.drain(..).enumerate() {
            if let Some(e) = e {
                self.pending.write(p as u32, e);
            }
        }
        self.scratch = s;
        unsent
    }

    /// The evaluation's status and when the L1 must be evaluated next.
    fn settle(&self, ctx: &mut Ctx, o: &Outcome, unsent: bool) -> Next {
        ctx.set_status(if o.worked {
            Status::Busy
        } else if o.waiting || o.blocked {
            Status::ResourceBusy
        } else {
            Status::WaitInput
        });
        if o.worked && !o.waiting && !o.blocked && !o.more && !unsent {
            // Everything visible was served and nothing is left to send: the next
            // cycle would find nothing to do but wait for the hits in the data
            // array, a push or a line. Sleep till the first hit is due, waiting for
            // input from the next cycle on.
            ctx.set_status_from_next(Status::WaitInput);
            o.next_due.map_or(Next::Idle, Next::AtCycle)
        } else if o.worked || o.waiting {
            Next::Cycle
        } else if let Some(d) = o.next_due {
            Next::AtCycle(d)
        } else {
            Next::Idle
        }
    }
}

impl Logic for L1 {
    /// A TP's port while its response slot is free or its hit leaves this
    /// cycle (whether its bank is free and, on a miss, a miss register, its
    /// address decides); the miss port while a miss is outstanding.
    fn can_accept(&self, port: LinkId, at: &Ready) -> bool {
        if port == self.miss_resp.id {
            return (0..self.mshr_count).any(|k| self.mshr.read(k).valid);
        }
        let Some(p) = self.req.index_of(port) else {
            return false;
        };
        let e = self.pending.read(p as u32);
        !e.valid || (e.due <= at.cycle() && at.out_ready(&self.resp.at(p)))
    }

    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let mut o = Outcome::default();
        let mut s = self.begin_cycle();
        let filled = self.accept_fill(ctx, &mut s, &mut o);
        self.answer_hits(ctx, &mut s, &mut o);
        self.accept_requests(ctx, &mut s, &mut o, &filled);
        self.issue_miss(ctx, &mut s, &mut o);
        let unsent = self.end_cycle(s);
        self.settle(ctx, &o, unsent)
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        let s = &self.stats;
        vec![
            ("accesses", s.accesses),
            ("hits", s.hits),
            ("misses", s.misses),
            ("merged", s.merged),
            ("bank_conflicts", s.bank_conflicts),
            ("mshr_stalls", s.mshr_stalls),
            ("fills", s.fills),
        ]
    }

    fn reset_counters(&mut self) {
        self.stats = L1Stats::default();
        if let Some(l) = &mut self.log {
            l.clear();
        }
    }
}
