//! The scene buffer (paper §4.2): a read-only on-chip memory of `slots` segment
//! slots, filled only by the stream scheduler's segment streams and read by the
//! TMs' L1 miss ports through a crossbar.
//!
//! - `slot_map` (from the scheduler): slot `slot` now holds the segment at `base`
//!   of `lines` lines, generation `generation`; every line of the slot becomes invalid.
//! - `fill[j]` (from the memory unit's scene ports, one lane per line per cycle,
//!   `chip.scheduler.scene_lines_per_cycle`): a streamed line; its id is
//!   `generation << 24 | slot << 16 | line`. A line of an older generation (the segment
//!   retired before its stream finished) is dropped (`stale_fills`).
//! - `req[k]` / `resp[k]`: TM k's L1 miss port. The address is looked up in the
//!   slot table (an associative match on the 64 slots' ranges); a line that is
//!   not streamed in yet (or a segment not mapped yet) waits at the head of the
//!   link: counted once as a `stall` and in `stall_cycles` until it arrives.
//! - Banks: line `i` of a slot is in bank `i mod banks`; each bank serves one
//!   request per cycle, round-robin from TM `cycle mod tms`; the losers are bank
//!   conflicts and retry. A served line is visible at the L1 `latency` cycles
//!   after acceptance (response link included).

use std::collections::VecDeque;

use crate::contract::LINE_BYTES;
use crate::rtl::decl::{Samples, StateDecl, StateList};
use crate::rtl::model::{Behavioural, Model};
use crate::rtl::{Ctx, LinkId, Logic, Next, Payload, Ready, Status};

use super::l1::{L1Req, L1Resp, Line};
use super::memory::MemLineResp;

use serde::{Deserialize, Serialize};

/// The scene buffer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneBufferCfg {
    /// 4 MB [DS17 Table 1].
    pub bytes: u32,
    /// One slot per segment: 64 KB, 64 slots [DS17 §5.1].
    pub slot_bytes: u32,
    /// Banks, one line per bank per cycle. Assumption: 32, like the L2 of Table 1.
    pub banks: u32,
    /// Cycles from acceptance of an L1 miss to the line visible at the L1
    /// (response link included). Assumption: 4.
    pub latency: u32,
}

impl Default for SceneBufferCfg {
    fn default() -> Self {
        SceneBufferCfg {
            bytes: 4 << 20,
            slot_bytes: 64 << 10,
            banks: 32,
            latency: 4,
        }
    }
}

impl SceneBufferCfg {
    pub fn slots(&self) -> u32 {
        self.bytes / self.slot_bytes.max(1)
    }
}

crate::payload_struct! {
    /// The scheduler maps a segment into a slot.
    pub struct SlotMap {
        pub slot: u16,
        pub generation: u8,
        pub base: u64,
        pub lines: u32,
    }
}

/// Encodes a scene-stream line id.
pub fn fill_id(generation: u8, slot: u16, line: u32) -> u32 {
    (generation as u32) << 24 | (slot as u32) << 16 | line
}

#[derive(Clone, Debug, Default)]
pub struct Slot {
    pub base: u64,
    pub lines: u32,
    pub generation: u8,
    pub mapped: bool,
    pub valid: Vec<bool>,
    pub data: Vec<Line>,
}

#[derive(Clone, Debug, Default)]
pub struct SceneBufferState {
    pub slots: Vec<Slot>,
    /// Per TM: responses in flight (cycle pushed, response).
    pub out: Vec<VecDeque<(u64, L1Resp)>>,
    /// Per TM: the cycle its head request first waited for a line, if it waits.
    pub wait_since: Vec<Option<u64>>,
}

impl Behavioural for SceneBufferState {
    fn declare(&self, out: &mut StateList) {
        out.items.push(StateDecl::reg("waiting", 16));
        out.items.push(StateDecl::array(
            "slot_table",
            SlotMap::BITS,
            self.slots.len() as u32,
        ));
        // One valid bit per line, a word per slot.
        let lines = self.slots.first().map_or(1, |s| s.valid.len() as u32);
        out.items.push(StateDecl::array(
            "line_valid",
            lines.max(1),
            self.slots.len() as u32,
        ));
    }
    fn sample(&self, out: &mut Samples) {
        let w = self.wait_since.iter().filter(|w| w.is_some()).count();
        out.slot().push(w as u64, 16);
    }
    fn reset(&mut self) {
        for s in &mut self.slots {
            s.mapped = false;
            s.valid.iter_mut().for_each(|v| *v = false);
        }
        self.out.iter_mut().for_each(|q| q.clear());
        self.wait_since.iter_mut().for_each(|w| *w = None);
    }
}

crate::unit! {
    /// Scene buffer: segment slots streamed in by the scheduler, read by the L1s.
    pub struct SceneBuffer : "scene_buffer" {
        new(cfg: &SceneBufferCfg, out_delay: u32; ports: SceneBufferPorts) {
            let n = req.len();
            let slot_lines = cfg.slot_bytes / LINE_BYTES as u32;
            let slots = (0..cfg.slots())
                .map(|_| Slot {
                    valid: vec![false; slot_lines as usize],
                    data: vec![Line::default(); slot_lines as usize],
                    ..Slot::default()
                })
                .collect();
        }
        params {
            slots_n: u32 = cfg.slots() => "SLOTS",
            slot_lines: u32 = slot_lines => "SLOT_LINES",
            banks: u32 = cfg.banks => "BANKS",
            latency: u32 = cfg.latency => "LATENCY",
            tms: u32 = n as u32 => "TMS"
        }
        inputs { slot_map: SlotMap }
        outputs { }
        in_arrays { req: L1Req, fill: MemLineResp }
        out_arrays { resp: L1Resp }
        state {
            st: Model<SceneBufferState> = SceneBufferState {
                slots,
                out: vec![VecDeque::new(); n],
                wait_since: vec![None; n],
            }
        }
        extra {
            out_delay: u32 = out_delay,
            reads: u64 = 0,
            fills: u64 = 0,
            stale_fills: u64 = 0,
            stalls: u64 = 0,
            stall_cycles: u64 = 0,
            bank_conflicts: u64 = 0
        }
    }
}

impl SceneBuffer {
    /// (slot, line) holding `addr`, if mapped.
    fn find(&self, addr: u64) -> Option<(usize, u32)> {
        self.st.r().slots.iter().enumerate().find_map(|(k, s)| {
            (s.mapped && addr >= s.base && addr < s.base + s.lines as u64 * LINE_BYTES)
                .then(|| (k, ((addr - s.base) / LINE_BYTES) as u32))
        })
    }

    /// Requests waiting or responses in flight.
    pub fn busy(&self) -> bool {
        let s = self.st.r();
        s.out.iter().any(|q| !q.is_empty()) || s.wait_since.iter().any(|w| w.is_some())
    }
}

impl Logic for SceneBuffer {
    /// The mapping and fill ports always (lines are written as they come); a
    /// TM's request port while its response queue has room, or makes it
    /// this cycle (whether its line is there and its bank free, its address
    /// decides).
    fn can_accept(&self, port: LinkId, at: &Ready) -> bool {
        let Some(k) = self.req.index_of(port) else {
            return true;
        };
        let q = &self.st.r().out[k];
        let cap = self.latency as usize + 2;
        q.len() < cap
            || q.front().is_some_and(|(d, _)| *d <= at.cycle()) && at.out_ready(&self.resp.at(k))
    }

    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let n = self.tms as usize;
        let mut worked = false;
        let mut blocked = false;
        // Control first: a new mapping, then the streamed lines (one per lane). The
        // scheduler maps a slot before it streams into it, so a fill never
        // precedes its mapping.
        if let Some(m) = ctx.pop(&self.slot_map) {
            let s = &mut self.st.m().slots[m.slot as usize];
            s.base = m.base;
            s.lines = m.lines;
            s.generation = m.generation;
            s.mapped = true;
            s.valid.iter_mut().for_each(|v| *v = false);
            worked = true;
        }
        for j in 0..self.fill.len() {
            let Some(f) = ctx.pop(&self.fill.at(j)) else {
                continue;
            };
            let (generation, slot, line) = (
                (f.id >> 24) as u8,
                (f.id >> 16 & 0xFF) as usize,
                f.id & 0xFFFF,
            );
            let s = &mut self.st.m().slots[slot];
            if s.mapped && s.generation == generation {
                s.valid[line as usize] = true;
                s.data[line as usize] = f.data;
                self.fills += 1;
            } else {
                self.stale_fills += 1;
            }
            worked = true;
        }
        // Responses due.
        for k in 0..n {
            if let Some((d, _)) = self.st.r().out[k].front()
                && *d <= c
            {
                if ctx.can_push(&self.resp.at(k)) {
                    let (_, r) = self.st.m().out[k].pop_front().expect("due");
                    ctx.push(&self.resp.at(k), r);
                    worked = true;
                } else {
                    blocked = true;
                }
            }
        }
        // Crossbar: one request per bank per cycle, round-robin from TM `c mod n`.
        let mut bank_busy = vec![false; self.banks as usize];
        let mut retry = false;
        let due = c + self.latency as u64 - self.out_delay as u64;
        let cap = self.latency as usize + 2;
        for j in 0..n {
            let k = (c as usize + j) % n;
            let Some(addr) = ctx.peek(&self.req.at(k)).map(|r| r.addr) else {
                continue;
            };
            let hit = self
                .find(addr)
                .filter(|&(s, l)| self.st.r().slots[s].valid[l as usize]);
            let Some((s, l)) = hit else {
                if self.st.r().wait_since[k].is_none() {
                    self.st.m().wait_since[k] = Some(c);
                    self.stalls += 1;
                }
                continue;
            };
            let b = (l % self.banks) as usize;
            if bank_busy[b] {
                self.bank_conflicts += 1;
                retry = true;
                continue;
            }
            if self.st.r().out[k].len() >= cap {
                retry = true;
                continue;
            }
            bank_busy[b] = true;
            ctx.pop(&self.req.at(k));
            let line = self.st.r().slots[s].data[l as usize].clone();
            let st = self.st.m();
            if let Some(since) = st.wait_since[k].take() {
                self.stall_cycles += c - since;
            }
            st.out[k].push_back((
                due,
                L1Resp {
                    addr: addr & !(LINE_BYTES - 1),
                    line,
                },
            ));
            self.reads += 1;
            worked = true;
        }
        let waiting = self.st.r().wait_since.iter().any(|w| w.is_some());
        ctx.set_status(if blocked {
            Status::OutputBlocked
        } else if retry {
            Status::ResourceBusy
        } else if worked || self.busy() {
            Status::Busy
        } else {
            Status::WaitInput
        });
        if worked || retry {
            return Next::Cycle;
        }
        // Waiting requests are woken by the fill or mapping that serves them.
        let _ = waiting;
        let next = self
            .st
            .r()
            .out
            .iter()
            .filter_map(|q| q.front().map(|(d, _)| *d))
            .filter(|&d| d > c)
            .min();
        match next {
            Some(d) => Next::AtCycle(d),
            None => Next::Idle,
        }
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("reads", self.reads),
            ("fills", self.fills),
            ("stale_fills", self.stale_fills),
            ("stalls", self.stalls),
            ("stall_cycles", self.stall_cycles),
            ("bank_conflicts", self.bank_conflicts),
        ]
    }

    fn reset_counters(&mut self) {
        self.reads = 0;
        self.fills = 0;
        self.stale_fills = 0;
        self.stalls = 0;
        self.stall_cycles = 0;
        self.bank_conflicts = 0;
    }
}

/// What the chip top reads of the scene buffer: its event counters (a probe,
/// not hardware).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SceneBufferProbe {
    pub reads: u64,
    pub fills: u64,
    pub stale_fills: u64,
    pub stalls: u64,
    pub stall_cycles: u64,
    pub bank_conflicts: u64,
}

impl SceneBuffer {
    /// The counters (see [`SceneBufferProbe`]).
    pub fn probe(&self) -> SceneBufferProbe {
        SceneBufferProbe {
            reads: self.reads,
            fills: self.fills,
            stale_fills: self.stale_fills,
            stalls: self.stalls,
            stall_cycles: self.stall_cycles,
            bank_conflicts: self.bank_conflicts,
        }
    }
}
