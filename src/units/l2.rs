//! The L2 cache (paper Table 1: 512 KB, 32 banks): everything that is not a
//! stream goes through it (the hit record updater's read-compare-writes, the TPs'
//! shading loads and stores). It sits between line clients and the memory unit
//! with the same `MemLineReq`/`MemLineResp` types on both sides.
//!
//! - Geometry (`chip.l2`): `bytes / line_bytes` lines in `sets = lines / ways`
//!   sets of `ways`; line `i` maps to set `i mod sets` and bank `i mod banks`.
//!   Tags are whole line addresses. Replacement: least recently used per set
//!   (a per-line stamp from a running access counter), an invalid way first.
//! - Banks: each bank serves one access per cycle (a returning fill and a flush
//!   writeback take their bank's cycle first); client requests are taken
//!   round-robin from client `cycle mod clients` on (a function of absolute time,
//!   so sleeping cannot change it), the loser of a bank waits (a bank-conflict
//!   stall).
//! - Write-back. A full-line write (mask all ones) that misses allocates the line
//!   without reading it (write-allocate); a read or a partial write that misses
//!   takes a miss register (MSHR) and reads the line. Any access to a line with a
//!   live MSHR joins it as a target (a merge; `targets` per MSHR, else it waits):
//!   when the line comes back the targets are applied in arrival order (reads get
//!   the bytes as of their turn, writes merge their masked bytes), so per line the
//!   order of application is the order of acceptance, whatever the client: a read
//!   accepted after a write sees it. Hits are applied when accepted.
//! - Answers (writes too) leave `hit_latency` cycles after acceptance (or after
//!   the fill), response link included, in order per client. A client has at most
//!   `port_queue` requests accepted and not answered (then it waits).
//! - Memory side: `mem_lines_per_cycle` lanes `mem_req[j]`/`mem_resp[j]`, one
//!   request per lane per cycle (fills: tag of the first target; writebacks: tag
//!   of the line's last write); line `i` always uses lane `i mod lanes` and its
//!   answer comes back on that lane. Each lane issues the oldest queued request of
//!   its lines that may go. At most one request per line is at the memory at
//!   once, and requests for one line leave in order: the memory unit may reorder
//!   a read before an older write to the same line, so a fill waits for an
//!   earlier writeback of its line to be answered. Returning fills are taken in
//!   lane order, one per bank per cycle (a fill whose bank another lane's fill
//!   took waits in its link a cycle; with lanes dividing banks this never
//!   happens, a line's bank fixing its lane). The
//!   writeback buffer holds `writebacks` entries plus one reserved per MSHR, so a
//!   returning fill can always evict its victim (fills never block, and the
//!   memory side never waits for the clients).
//! - Flush: `flush` (`L2Flush { invalidate }`) stops accepting client requests,
//!   writes back every dirty line (up to one per lane per cycle, on distinct
//!   banks and lanes: the lowest dirty slots that qualify, looking at most at
//!   `2 x ways x lanes` of them per cycle), waits for
//!   every MSHR and memory request to finish, invalidates every line if asked,
//!   then answers on `flush_done`. The chip flushes after every run so the host
//!   reads DRAM; it invalidates when the host may write DRAM between runs.

use std::collections::VecDeque;

use crate::mem::StreamTag;
use crate::rtl::model::Model;
use crate::rtl::{Ctx, LinkId, Logic, Next, Ready, Status};
use crate::util::{div, rem};

use super::l1::Line;
use super::memory::{MemLineReq, MemLineResp};

mod config;
mod state;
pub use config::L2Cfg;
use state::free_bits;
pub use state::{L2Mshr, L2State, L2Tag, LineHasher};

crate::payload_struct! {
    /// A flush request (and its answer on `flush_done`).
    pub struct L2Flush {
        /// Also invalidate every line (the host will write DRAM).
        pub invalidate: bool,
    }
}

/// An entry of the serialisation log (`L2::enable_log`): the access as applied
/// to the cache, with the client and the cycle it was accepted.
#[derive(Clone, Debug, PartialEq)]
pub struct L2Applied {
    pub port: u16,
    pub accepted: u64,
    pub req: MemLineReq,
}

/// Event counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct L2Stats {
    /// Client requests accepted.
    pub accesses: u64,
    pub hits: u64,
    /// Misses (a new MSHR, a merge into a live one, or a full-line write allocated).
    pub misses: u64,
    /// Misses that joined a live MSHR.
    pub merges: u64,
    /// Request-cycles lost to another access on the same bank.
    pub bank_conflicts: u64,
    /// Request-cycles waiting for a free MSHR, target or writeback entry.
    pub mshr_stalls: u64,
    /// Lines read from memory, and dirty lines written back.
    pub fills: u64,
    pub writebacks: u64,
    pub flushes: u64,
    /// Reads served by a bank already reading the same line that cycle.
    pub combined: u64,
}

crate::unit! {
    /// L2: banked set-associative write-back cache between line clients and the memory unit.
    pub struct L2 : "l2" {
        /// `req[k]`/`resp[k]`: client k; `mem_req[j]`/`mem_resp[j]`: memory lane j
        /// (`cfg.mem_lines_per_cycle` of them); `out_delay`: the response links' delay
        /// (part of `hit_latency`).
        new(cfg: &L2Cfg, out_delay: u32; ports: L2Ports) {
            assert_eq!(req.len(), resp.len(), "one response port per client");
            assert_eq!(
                mem_req.len(),
                cfg.mem_lines_per_cycle as usize,
                "one memory request port per lane (chip.l2.mem_lines_per_cycle)"
            );
            assert_eq!(mem_req.len(), mem_resp.len(), "one answer port per lane");
            let lines = (cfg.bytes / cfg.line_bytes) as usize;
            let n = req.len();
        }
        params {
            bytes: u32 = cfg.bytes => "BYTES",
            banks: u32 = cfg.banks => "BANKS",
            ways: u32 = cfg.ways => "WAYS",
            line_bytes: u32 = cfg.line_bytes => "LINE_BYTES",
            hit_latency: u32 = cfg.hit_latency => "HIT_LATENCY",
            mshr_count: u32 = cfg.mshrs => "MSHRS",
            targets: u32 = cfg.targets => "TARGETS",
            writebacks: u32 = cfg.writebacks => "WRITEBACKS",
            port_queue: u32 = cfg.port_queue => "PORT_QUEUE",
            mem_lanes: u32 = cfg.mem_lines_per_cycle => "MEM_LANES",
            bank_hash: u32 = cfg.bank_hash as u32 => "BANK_HASH",
            combine_reads: u32 = cfg.combine_reads as u32 => "COMBINE_READS"
        }
        inputs { flush: L2Flush }
        outputs { flush_done: L2Flush }
        in_arrays { req: MemLineReq, mem_resp: MemLineResp }
        out_arrays { resp: MemLineResp, mem_req: MemLineReq }
        state {
            st: Model<L2State> = L2State {
                tags: vec![L2Tag::default(); lines],
                data: vec![Line::default(); lines],
                mshrs: vec![None; cfg.mshrs as usize],
                mshr_free: free_bits(cfg.mshrs as usize),
                resp_q: vec![VecDeque::new(); n],
                answering: vec![0; n.div_ceil(64)],
                outstanding: vec![0; n],
                ..L2State::default()
            }
        }
        extra {
            out_delay: u32 = out_delay,
            stats: L2Stats = L2Stats::default(),
            log: Option<Vec<L2Applied>> = None,
            bank_use: Vec<u64> = Vec::new(),
            visible: Vec<u64> = Vec::new()
        }
    }
}

/// A bank not used this cycle, and one used by anything but a read (neither is a
/// line address: those are multiples of the line size).
const FREE: u64 = u64::MAX;
const BUSY: u64 = u64::MAX - 1;

/// What one evaluation did, for its status and its next evaluation.
#[derive(Clone, Copy, Debug, Default)]
struct Outcome {
    worked: bool,
    /// A request or a fill could not be served: try again next cycle.
    waiting: bool,
    /// An output is full.
    blocked: bool,
    /// The earliest answer queued for a client.
    next_due: Option<u64>,
}

impl Outcome {
    /// An answer is due at `d`.
    fn due(&mut self, d: u64) {
        self.next_due = Some(self.next_due.map_or(d, |x: u64| x.min(d)));
    }
}

/// How `L2::admit` would take a request.
#[derive(Clone, Copy, Debug)]
enum Admit {
    /// Joins the miss of MSHR k.
    Merge(usize),
    /// Hits in this slot.
    Hit(usize),
    /// A whole-line write allocated in this slot.
    Allocate(usize),
    /// A new miss in MSHR k.
    Miss(usize),
}

/// Applies the masked bytes of a write to a line.
fn merge(line: &mut Line, r: &MemLineReq) {
    if r.mask == u64::MAX {
        line.0 = r.data.0;
        return;
    }
    for i in 0..64 {
        if r.mask >> i & 1 == 1 {
            line.0[i] = r.data.0[i];
        }
    }
}

impl L2 {
    /// Records every access as applied (tests replay the order).
    pub fn enable_log(&mut self) {
        self.log = Some(Vec::new());
    }

    pub fn busy(&self) -> bool {
        !self.st.r().idle()
    }

    /// Dirty lines held, by the stream tag of their last write: each will be
    /// written back once (time sampling counts them where they were dirtied).
    pub fn dirty_by_tag(&self) -> [u64; StreamTag::COUNT] {
        let st = self.st.r();
        let mut n = [0; StreamTag::COUNT];
        for &slot in &st.dirty {
            n[st.tags[slot as usize].mtag as usize] += 1;
        }
        n
    }

    fn sets(&self) -> u64 {
        (self.bytes / self.line_bytes / self.ways) as u64
    }
    fn line_index(&self, addr: u64) -> u64 {
        div(addr, self.line_bytes as u64)
    }
    /// The memory lane of a line (a function of its address only).
    fn lane_of(&self, addr: u64) -> usize {
        rem(self.line_index(addr), self.mem_lanes as u64) as usize
    }
    /// The bank of a line: its index modulo the banks, or (`chip.l2.bank_hash`)
    /// the XOR of all its bank-index-wide bit fields, so strided accesses (TM k
    /// reading pixel 16 k + i) spread over the banks instead of piling onto two.
    fn bank_of(&self, addr: u64) -> usize {
        let line = self.line_index(addr);
        let b = self.banks as u64;
        if self.bank_hash == 0 || b == 1 {
            return rem(line, b) as usize;
        }
        let bits = 64 - (b - 1).leading_zeros();
        let (mut h, mut x) = (0u64, line);
        while x != 0 {
            h ^= x & ((1u64 << bits) - 1);
            x >>= bits;
        }
        rem(h, b) as usize
    }
    /// The set of a line: its bank's sets are `bank`, `bank + banks`, ... (so a
    /// slot's bank is its set mod banks), the one picked by the line index above
    /// the bank. Without the hash this is the line index modulo the sets.
    fn set_of(&self, addr: u64) -> usize {
        let b = self.banks as u64;
        let per_bank = div(self.sets(), b);
        let line = self.line_index(addr);
        (rem(div(line, b), per_bank) * b + self.bank_of(addr) as u64) as usize
    }
    fn slot_bank(&self, slot: u32) -> usize {
        (slot as usize / self.ways as usize) % self.banks as usize
    }
    /// The slot holding `addr`, if cached.
    fn find(&self, addr: u64) -> Option<usize> {
        let w = self.ways as usize;
        let base = self.set_of(addr) * w;
        (base..base + w).find(|&s| self.st.r().tags[s].tag == addr + 1)
    }
    /// The way to replace in `addr`'s set: an invalid one, else the LRU.
    fn victim(&self, addr: u64) -> usize {
        let w = self.ways as usize;
        let base = self.set_of(addr) * w;
        let t = &self.st.r().tags;
        (base..base + w)
            .find(|&s| t[s].tag == 0)
            .unwrap_or_else(|| (base..base + w).min_by_key(|&s| t[s].stamp).expect("ways"))
    }

    fn touch(&mut self, slot: usize) {
        let st = self.st.m();
        st.stamp += 1;
        st.tags[slot].stamp = st.stamp;
    }

    /// Evicts `slot` (queues its writeback if dirty).
    fn evict(&mut self, slot: usize) {
        let t = self.st.r().tags[slot];
        if t.tag != 0 && t.dirty {
            let st = self.st.m();
            st.out_q.push_back(MemLineReq {
                addr: t.tag - 1,
                write: true,
                tag: t.mtag,
                id: 0,
                mask: u64::MAX,
                data: st.data[slot].clone(),
            });
            st.wb_queued += 1;
            st.dirty.remove(&(slot as u32));
            self.stats.writebacks += 1;
        }
        self.st.m().tags[slot] = L2Tag::default();
    }

    /// Applies one access to a cached slot and queues its answer, due at `due`.
    fn apply(&mut self, slot: usize, port: u16, accepted: u64, r: MemLineReq, due: u64) {
        let st = self.st.m();
        let mut data = Line::default();
        if r.write {
            merge(&mut st.data[slot], &r);
            st.tags[slot].dirty = true;
            st.tags[slot].mtag = r.tag;
            st.dirty.insert(slot as u32);
        } else {
            data = st.data[slot].clone();
        }
        st.answering[port as usize / 64] |= 1 << (port % 64);
        st.resp_q[port as usize].push_back((
            due,
            MemLineResp {
                addr: r.addr,
                write: r.write,
                tag: r.tag,
                id: r.id,
                data,
            },
        ));
        self.touch(slot);
        if let Some(log) = &mut self.log {
            log.push(L2Applied {
                port,
                accepted,
                req: r,
            });
        }
    }

    /// A line from the memory: install it, apply its MSHR's targets.
    fn fill(&mut self, f: MemLineResp, c: u64) {
        let k = self
            .st
            .r()
            .mshr_of(f.addr)
            .expect("a line comes back only for a miss register");
        let st = self.st.m();
        let m = st.release_mshr(k, f.addr);
        let slot = self.victim(f.addr);
        self.evict(slot);
        let st = self.st.m();
        st.tags[slot] = L2Tag {
            tag: f.addr + 1,
            dirty: false,
            stamp: 0,
            mtag: m.targets[0].2.tag,
        };
        st.data[slot] = f.data;
        self.stats.fills += 1;
        let due = c + (self.hit_latency - self.out_delay) as u64;
        for (port, acc, r) in m.targets {
            self.apply(slot, port, acc, r, due);
        }
    }

    /// How a request for `addr` would be taken this cycle (`whole`: it writes
    /// the whole line), or `None` if it must wait for an MSHR, a target or a
    /// writeback entry. A waiting request is judged without copying it.
    fn admit(&self, addr: u64, whole: bool) -> Option<Admit> {
        let st = self.st.r();
        if let Some(k) = st.mshr_of(addr) {
            let m = st.mshrs[k].as_ref().expect("live");
            return (m.targets.len() < self.targets as usize).then_some(Admit::Merge(k));
        }
        if let Some(slot) = self.find(addr) {
            return Some(Admit::Hit(slot));
        }
        if whole {
            // Write-allocate: the whole line is written, nothing to read.
            let slot = self.victim(addr);
            let t = st.tags[slot];
            if t.tag != 0 && t.dirty && st.wb_queued >= self.writebacks {
                return None;
            }
            return Some(Admit::Allocate(slot));
        }
        st.free_mshr().map(Admit::Miss)
    }

    /// Takes client `p`'s request `r` in cycle `c` the way `admit` decided.
    fn take(&mut self, p: usize, r: &MemLineReq, c: u64, how: Admit) {
        let due = c + (self.hit_latency - self.out_delay) as u64;
        let addr = r.addr;
        let port = p as u16;
        match how {
            Admit::Merge(k) => {
                self.st.m().mshrs[k]
                    .as_mut()
                    .expect("live")
                    .targets
                    .push((port, c, r.clone()));
                self.stats.misses += 1;
                self.stats.merges += 1;
            }
            Admit::Hit(slot) => {
                self.apply(slot, port, c, r.clone(), due);
                self.stats.hits += 1;
            }
            Admit::Allocate(slot) => {
                self.evict(slot);
                self.st.m().tags[slot] = L2Tag {
                    tag: addr + 1,
                    dirty: false,
                    stamp: 0,
                    mtag: r.tag,
                };
                self.apply(slot, port, c, r.clone(), due);
                self.stats.misses += 1;
            }
            Admit::Miss(k) => {
                let st = self.st.m();
                st.take_mshr(
                    k,
                    addr,
                    L2Mshr {
                        targets: vec![(port, c, r.clone())],
                    },
                );
                st.out_q.push_back(MemLineReq::read(addr, r.tag, k as u32));
                self.stats.misses += 1;
            }
        }
        self.st.m().outstanding[p] += 1;
        self.stats.accesses += 1;
    }

    /// The first request in `out_q` for lane `lane` whose line has nothing at
    /// the memory and no older request queued.
    fn issuable(&self, lane: usize) -> Option<usize> {
        // No set of seen lines: a line has one lane, so "no older request for the
        // line" is a scan of the entries ahead (the queue is short; this runs
        // every cycle per lane).
        let st = self.st.r();
        let q = &st.out_q;
        (0..q.len()).find(|&i| {
            let a = q[i].addr;
            self.lane_of(a) == lane
                && !st.mem_busy.contains(&a)
                && !q.iter().take(i).any(|o| o.addr == a)
        })
    }
    fn any_issuable(&self) -> bool {
        (0..self.mem_lanes as usize).any(|j| self.issuable(j).is_some())
    }

    /// The memory's answers, one per lane in lane order: a fill (takes its
    /// bank, or waits a cycle if another lane's fill took it) or a writeback's
    /// ack.
    fn take_memory_answers(&mut self, ctx: &mut Ctx, bank: &mut [u64], o: &mut Outcome) {
        let c = ctx.cycle();
        for j in 0..self.mem_resp.len() {
            let Some(f) = ctx.peek(&self.mem_resp.at(j)) else {
                continue;
            };
            let (write, b) = (f.write, self.bank_of(f.addr));
            if !write && (bank[b] != FREE) {
                o.waiting = true;
                continue;
            }
            let f = ctx.pop(&self.mem_resp.at(j)).expect("peeked");
            self.st.m().mem_busy.remove(&f.addr);
            if !write {
                bank[b] = BUSY;
                self.fill(f, c);
            }
            o.worked = true;
        }
    }

    /// Answers whose time has come leave, one per client per cycle.
    fn answer_clients(&mut self, ctx: &mut Ctx, o: &mut Outcome) {
        let c = ctx.cycle();
        for w in 0..self.st.r().answering.len() {
            let mut bits = self.st.r().answering[w];
            while bits != 0 {
                let p = w * 64 + bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let head = self.st.r().resp_q[p].front().map(|(d, _)| *d);
                let d = head.expect("a client marked answering has an answer queued");
                if d > c {
                    o.due(d);
                    continue;
                }
                if !ctx.can_push(&self.resp.at(p)) {
                    o.blocked = true;
                    continue;
                }
                let st = self.st.m();
                let (_, r) = st.resp_q[p].pop_front().expect("head");
                st.outstanding[p] -= 1;
                ctx.push(&self.resp.at(p), r);
                o.worked = true;
                match st.resp_q[p].front() {
                    Some(&(d, _)) => o.due(d),
                    None => st.answering[w] &= !(1 << (p % 64)),
                }
            }
        }
    }

    /// A flush request starts a flush (none while one runs).
    fn accept_flush(&mut self, ctx: &mut Ctx, o: &mut Outcome) {
        if self.st.r().flushing.is_none()
            && let Some(f) = ctx.pop(&self.flush)
        {
            self.st.m().flushing = Some(f.invalidate);
            self.stats.flushes += 1;
            o.worked = true;
        }
    }

    /// A flush in progress: write back up to one dirty line per lane (the
    /// lowest slots on free banks and distinct lanes, from a window of the
    /// lowest `2 x ways x lanes`); with none left, finish.
    fn flush_step(&mut self, ctx: &mut Ctx, inv: bool, bank: &mut [u64], o: &mut Outcome) {
        let lanes = self.mem_lanes as usize;
        let window = 2 * self.ways as usize * lanes;
        let mut lane_used = vec![false; lanes];
        let mut picked = Vec::new();
        for &slot in self.st.r().dirty.iter().take(window) {
            if picked.len() == lanes
                || self.st.r().wb_queued as usize + picked.len() >= self.writebacks as usize
            {
                break;
            }
            let b = self.slot_bank(slot);
            let lane = self.lane_of(self.st.r().tags[slot as usize].tag - 1);
            if bank[b] == FREE && !lane_used[lane] {
                bank[b] = BUSY;
                lane_used[lane] = true;
                picked.push(slot);
            }
        }
        if !self.st.r().dirty.is_empty() {
            if picked.is_empty() {
                o.waiting = true;
            }
            for slot in picked {
                let st = self.st.m();
                let t = &mut st.tags[slot as usize];
                t.dirty = false;
                let wb = MemLineReq {
                    addr: t.tag - 1,
                    write: true,
                    tag: t.mtag,
                    id: 0,
                    mask: u64::MAX,
                    data: st.data[slot as usize].clone(),
                };
                st.out_q.push_back(wb);
                st.wb_queued += 1;
                st.dirty.remove(&slot);
                self.stats.writebacks += 1;
                o.worked = true;
            }
        } else {
            self.finish_flush(ctx, inv, o);
        }
    }

    /// No dirty line left: once every MSHR, memory request and answer is done,
    /// invalidate if asked and answer on `flush_done`.
    fn finish_flush(&mut self, ctx: &mut Ctx, inv: bool, o: &mut Outcome) {
        let s = self.st.r();
        let drained = s.live_mshrs() == 0
            && s.out_q.is_empty()
            && s.mem_busy.is_empty()
            && s.resp_q.iter().all(|q| q.is_empty());
        if drained {
            if ctx.can_push(&self.flush_done) {
                let st = self.st.m();
                if inv {
                    st.tags.iter_mut().for_each(|t| *t = L2Tag::default());
                }
                st.flushing = None;
                ctx.push(&self.flush_done, L2Flush { invalidate: inv });
                o.worked = true;
            } else {
                o.blocked = true;
            }
        }
    }

    /// Client requests, one per bank, round-robin from client `c mod n`: a hit,
    /// a merge into a live MSHR, a new miss or a whole-line allocation.
    fn accept_requests(&mut self, ctx: &mut Ctx, bank: &mut [u64], o: &mut Outcome) {
        let c = ctx.cycle();
        let n = self.req.len();
        let start = ctx.round_robin_start(n);
        // The clients with a visible request, in round-robin order: a scan of
        // their links' flags, not a peek at each of the clients.
        let mut visible = std::mem::take(&mut self.visible);
        ctx.visible_words(&self.req, &mut visible);
        for p in crate::rtl::round_robin(&visible, start) {
            // Not cloned (a request carries a line): most of them only wait.
            let r = ctx.peek(&self.req.at(p)).expect("visible");
            let (addr, write, whole) = (r.addr, r.write, r.write && r.mask == u64::MAX);
            let b = self.bank_of(addr);
            let combined = !write && self.combine_reads != 0 && bank[b] == addr;
            if bank[b] != FREE && !combined {
                self.stats.bank_conflicts += 1;
                o.waiting = true;
                continue;
            }
            if self.st.r().outstanding[p] >= self.port_queue {
                o.waiting = true;
                continue;
            }
            let Some(how) = self.admit(addr, whole) else {
                self.stats.mshr_stalls += 1;
                o.waiting = true;
                continue;
            };
            self.take(p, r, c, how);
            ctx.pop(&self.req.at(p));
            if combined {
                self.stats.combined += 1;
            }
            bank[b] = if write { BUSY } else { addr };
            o.worked = true;
            if let Some(&(d, _)) = self.st.r().resp_q[p].front() {
                o.due(d);
            }
        }
        self.visible = visible;
    }

    /// One request to the memory per lane.
    fn issue_memory_requests(&mut self, ctx: &mut Ctx, o: &mut Outcome) {
        for j in 0..self.mem_req.len() {
            let Some(i) = self.issuable(j) else { continue };
            if ctx.can_push(&self.mem_req.at(j)) {
                let st = self.st.m();
                let r = st.out_q.remove(i).expect("issuable");
                if r.write {
                    st.wb_queued -= 1;
                }
                st.mem_busy.insert(r.addr);
                ctx.push(&self.mem_req.at(j), r);
                o.worked = true;
            } else {
                o.blocked = true;
            }
        }
    }

    /// The evaluation's status and when the L2 must be evaluated next.
    fn settle(&self, ctx: &mut Ctx, o: &Outcome) -> Next {
        let c = ctx.cycle();
        ctx.set_status(if o.blocked {
            Status::OutputBlocked
        } else if o.waiting {
            Status::ResourceBusy
        } else if o.worked || self.busy() {
            Status::Busy
        } else {
            Status::WaitInput
        });
        if o.worked || o.waiting || o.blocked || self.any_issuable() {
            Next::Cycle
        } else if let Some(d) = o.next_due {
            Next::AtCycle(d.max(c + 1))
        } else {
            // Memory answers, requests and flushes wake us.
            Next::Idle
        }
    }
}

impl Logic for L2 {
    /// The flush port while no flush runs; a memory lane while a line is out
    /// at the memory (a fill also needs its bank, which its address picks); a
    /// client while no flush runs (or one may end this cycle) and its answer
    /// queue has room, or makes it this cycle (bank and miss registers: its
    /// address decides).
    fn can_accept(&self, port: LinkId, at: &Ready) -> bool {
        let st = self.st.r();
        if port == self.flush.id {
            return st.flushing.is_none();
        }
        if self.mem_resp.index_of(port).is_some() {
            return !st.mem_busy.is_empty();
        }
        let Some(p) = self.req.index_of(port) else {
            return false;
        };
        let answers = st.resp_q[p].front().is_some_and(|(d, _)| *d <= at.cycle())
            && at.out_ready(&self.resp.at(p));
        // A flush with no dirty line left may finish this cycle (if the rest
        // has drained by then), and requests are taken after it.
        let flush_ends = st.dirty.is_empty() && at.out_ready(&self.flush_done);
        (st.flushing.is_none() || flush_ends) && (st.outstanding[p] < self.port_queue || answers)
    }

    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let mut o = Outcome::default();
        // This cycle's use of each bank: FREE, BUSY, or the line a read took it
        // for (reads of that line may join, `chip.l2.combine_reads`). Reused, so
        // the per-cycle path does not allocate.
        let mut bank = std::mem::take(&mut self.bank_use);
        bank.clear();
        bank.resize(self.banks as usize, FREE);
        self.take_memory_answers(ctx, &mut bank, &mut o);
        self.answer_clients(ctx, &mut o);
        self.accept_flush(ctx, &mut o);
        if let Some(inv) = self.st.r().flushing {
            self.flush_step(ctx, inv, &mut bank, &mut o);
        }
        // No client request is taken while flushing.
        if self.st.r().flushing.is_none() {
            self.accept_requests(ctx, &mut bank, &mut o);
        } else if self.req.iter().any(|q| ctx.peek(q).is_some()) {
            o.waiting = true;
        }
        self.issue_memory_requests(ctx, &mut o);
        self.bank_use = bank;
        self.settle(ctx, &o)
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        let s = &self.stats;
        vec![
            ("accesses", s.accesses),
            ("hits", s.hits),
            ("misses", s.misses),
            ("merges", s.merges),
            ("bank_conflicts", s.bank_conflicts),
            ("mshr_stalls", s.mshr_stalls),
            ("fills", s.fills),
            ("writebacks", s.writebacks),
            ("flushes", s.flushes),
            ("combined", s.combined),
        ]
    }

    fn reset_counters(&mut self) {
        self.stats = L2Stats::default();
        if let Some(l) = &mut self.log {
            l.clear();
        }
    }
}

/// What the chip top reads of the L2: its event counters and what it holds (a
/// probe, not hardware).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct L2Probe {
    pub stats: L2Stats,
    /// Live MSHRs, requests queued towards the memory, lines at the memory.
    pub live_mshrs: usize,
    pub mem_queued: usize,
    pub at_memory: usize,
}

impl L2 {
    /// The counters and occupancy (see [`L2Probe`]).
    pub fn probe(&self) -> L2Probe {
        let st = self.st.r();
        L2Probe {
            stats: self.stats,
            live_mshrs: st.live_mshrs(),
            mem_queued: st.out_q.len(),
            at_memory: st.mem_busy.len(),
        }
    }
}
