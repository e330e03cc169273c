//! The hit record updater (paper §4.3): atomic-min updates of the 16 B hit
//! records in DRAM on the pair (t, triangle id).
//!
//! - `hit[k]`: TM k's hit updates, one accepted per cycle over all TMs
//!   (round-robin from `cycle mod tms`). An update for an index that already has
//!   a pending (not yet issued) update is merged into it: the closer (t, id) wins.
//!   Otherwise it takes a queue entry; with the queue full the TM's link fills and
//!   its TPs block (the only way they block on this unit), while other TMs'
//!   updates that merge are still accepted.
//! - Read-compare-write: the oldest pending update whose index has no
//!   read-compare-write in flight reads the record's line (tag `hit`); when the
//!   line comes back the record is compared and written (a 16 B partial write)
//!   only if the update is strictly closer. The index stays "in flight" until the
//!   write is answered, so a second update of the same record waits in the queue
//!   (merging with later ones) and reads the written value: the hazard of two
//!   in-flight read-compare-writes to one record cannot occur.

use std::collections::VecDeque;

use crate::contract::{HIT_BYTES, HitRec, LINE_BYTES};
use crate::mem::StreamTag;
use crate::rtl::decl::{Samples, StateDecl, StateList};
use crate::rtl::model::{Behavioural, Model};
use crate::rtl::{Ctx, LinkId, Logic, Next, Ready, Status, round_robin};

use super::follow::{FollowKind, Follower};
use super::l1::Line;
use super::memory::{MemLineReq, MemLineResp};
use super::tp::HitUpdate;

use serde::{Deserialize, Serialize};

/// The hit record updater.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HitUpdaterCfg {
    /// Pending updates (merged per hit index). Assumption: 64.
    pub queue: u32,
    /// Read-compare-writes in flight. Assumption: 32.
    pub in_flight: u32,
}

impl Default for HitUpdaterCfg {
    fn default() -> Self {
        HitUpdaterCfg {
            queue: 64,
            in_flight: 32,
        }
    }
}

/// `head_index`: not read yet.
const NO_HEAD: u32 = u32::MAX;

#[derive(Clone, Debug, Default)]
pub struct HruState {
    /// Pending updates in arrival order: the record indices, and beside them
    /// (same positions) the best hit so far. Two queues so that the search for a
    /// merge scans the indices alone.
    pub queue: VecDeque<u32>,
    pub queue_hit: VecDeque<HitRec>,
    /// Read-compare-writes in flight (at most `in_flight_n`, 32 by default):
    /// the record indices, and beside them (same positions) the update. A short
    /// array, not a map: "is this index in flight" is asked of every queued
    /// update each cycle, and a scan of 32 words beats a tree walk per question
    /// (order is never used).
    pub in_flight: Vec<u32>,
    pub in_flight_hit: Vec<HitRec>,
    /// Writes decided, waiting for the memory port.
    pub writes: VecDeque<MemLineReq>,
}

impl HruState {
    fn flight_pos(&self, idx: u32) -> Option<usize> {
        self.in_flight.iter().position(|&i| i == idx)
    }
    fn in_flight_has(&self, idx: u32) -> bool {
        self.in_flight.contains(&idx)
    }
    fn retire(&mut self, idx: u32) {
        let k = self.flight_pos(idx).expect("in flight");
        self.in_flight.swap_remove(k);
        self.in_flight_hit.swap_remove(k);
    }
}

impl Behavioural for HruState {
    fn declare(&self, out: &mut StateList) {
        out.items.push(StateDecl::reg("queued", 16));
        out.items.push(StateDecl::reg("in_flight", 16));
    }
    fn sample(&self, out: &mut Samples) {
        out.slot().push(self.queue.len() as u64, 16);
        out.slot().push(self.in_flight.len() as u64, 16);
    }
    fn reset(&mut self) {
        self.queue.clear();
        self.queue_hit.clear();
        self.in_flight.clear();
        self.in_flight_hit.clear();
        self.writes.clear();
    }
}

crate::unit! {
    /// Hit record updater: merged atomic-min read-compare-writes of hit records.
    pub struct HitRecordUpdater : "hit_record_updater" {
        /// `hits_base`: the hit-record region of the memory map.
        new(cfg: &HitUpdaterCfg, hits_base: u64; ports: HitRecordUpdaterPorts) {
            let tms = hit.len();
        }
        params {
            tms: u32 = tms as u32 => "TMS",
            // The hit-record region's base address (the memory map's; in
            // hardware a register the host sets per frame).
            hits_base: u64 = hits_base => "HITS_BASE",
            queue_n: u32 = cfg.queue => "QUEUE",
            in_flight_n: u32 = cfg.in_flight => "IN_FLIGHT"
        }
        inputs { mem_resp: MemLineResp }
        outputs { mem_req: MemLineReq }
        in_arrays { hit: HitUpdate }
        state { st: Model<HruState> = HruState::default() }
        extra {
            updates: u64 = 0,
            merged: u64 = 0,
            reads: u64 = 0,
            writes: u64 = 0,
            hazard_waits: u64 = 0,
            // Scratch: the TMs with a visible update this cycle.
            visible: Vec<u64> = Vec::new(),
            // Simulation only: the record index of each TM's head update once
            // read (`NO_HEAD` until then), forgotten when it is popped (only this
            // unit pops those links, so a head stays until then). With the queue
            // full every waiting TM's head is looked at each cycle for a merge;
            // with the index at hand that no longer loads 128 links.
            head_index: Vec<u32> = vec![NO_HEAD; tms],
            // `--follow-ray`: a probe, not hardware (`units/follow.rs`).
            follow: Option<Follower> = None
        }
    }
}

impl HitRecordUpdater {
    /// Logs the followed rays' events here (`units/follow.rs`).
    pub fn follow(&mut self, f: Follower) {
        self.follow = Some(f);
    }

    /// Logs `kind` if hit record `index` is a followed ray's.
    #[inline]
    fn note(&mut self, c: u64, index: u32, kind: impl FnOnce() -> FollowKind) {
        if let Some(f) = &mut self.follow
            && let Some(id) = f.wants_hit(index)
        {
            f.log(c, id, kind());
        }
    }

    fn addr(&self, index: u32) -> u64 {
        self.hits_base + index as u64 * HIT_BYTES as u64
    }

    pub fn busy(&self) -> bool {
        let s = self.st.r();
        !s.queue.is_empty() || !s.in_flight.is_empty() || !s.writes.is_empty()
    }
}

impl Logic for HitRecordUpdater {
    /// The memory port while a record is in flight. A TM's update port
    /// always: with room in the queue it takes any update, and a full queue
    /// still merges one for a record it holds (the update's index decides).
    fn can_accept(&self, port: LinkId, _at: &Ready) -> bool {
        port != self.mem_resp.id || !self.st.r().in_flight.is_empty()
    }

    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        let n = self.tms as usize;
        let mut worked = false;
        let mut full = false;
        // A memory answer: compare a read record, or retire a written one.
        if let Some(r) = ctx.pop(&self.mem_resp) {
            let idx = r.id;
            let st = self.st.m();
            if r.write {
                st.retire(idx);
                self.note(c, idx, || FollowKind::HitWritten);
            } else {
                let k = st.flight_pos(idx).expect("in flight");
                let h = st.in_flight_hit[k];
                let off = ((self.hits_base + idx as u64 * HIT_BYTES as u64) % LINE_BYTES) as usize;
                let cur = HitRec {
                    t: r.data.f32_at(off),
                    tri_id: r.data.u32_at(off + 4),
                    u: r.data.f32_at(off + 8),
                    v: r.data.f32_at(off + 12),
                };
                let written = h.closer_than(&cur);
                if written {
                    let mut data = Line::default();
                    data.0[off..off + 4].copy_from_slice(&h.t.to_le_bytes());
                    data.0[off + 4..off + 8].copy_from_slice(&h.tri_id.to_le_bytes());
                    data.0[off + 8..off + 12].copy_from_slice(&h.u.to_le_bytes());
                    data.0[off + 12..off + 16].copy_from_slice(&h.v.to_le_bytes());
                    st.writes.push_back(MemLineReq {
                        addr: r.addr,
                        write: true,
                        tag: StreamTag::Hit,
                        id: idx,
                        mask: 0xFFFF << off,
                        data,
                    });
                } else {
                    st.retire(idx);
                }
                self.note(c, idx, || FollowKind::HitCompared {
                    t: h.t,
                    tri_id: h.tri_id,
                    old_t: cur.t,
                    old_tri: cur.tri_id,
                    written,
                });
            }
            worked = true;
        }
        // One memory request per cycle: a decided write first, else the oldest
        // pending update whose record is not in flight.
        if ctx.can_push(&self.mem_req) {
            if !self.st.r().writes.is_empty() {
                let w = self.st.m().writes.pop_front().expect("non-empty");
                ctx.push(&self.mem_req, w);
                self.writes += 1;
                worked = true;
            } else if self.st.r().in_flight.len() < self.in_flight_n as usize {
                let pick = {
                    let s = self.st.r();
                    s.queue.iter().position(|&i| !s.in_flight_has(i))
                };
                if let Some(k) = pick {
                    if k > 0 {
                        self.hazard_waits += 1;
                    }
                    let st = self.st.m();
                    let idx = st.queue.remove(k).expect("picked");
                    let h = st.queue_hit.remove(k).expect("beside");
                    st.in_flight.push(idx);
                    st.in_flight_hit.push(h);
                    let a = self.addr(idx);
                    ctx.push(&self.mem_req, MemLineReq::read(a, StreamTag::Hit, idx));
                    self.note(c, idx, || FollowKind::HitRead);
                    self.reads += 1;
                    worked = true;
                }
            }
        }
        // One update accepted per cycle, round-robin over the TMs with one.
        let mut visible = std::mem::take(&mut self.visible);
        ctx.visible_words(&self.hit, &mut visible);
        for k in round_robin(&visible, c as usize % n) {
            let index = match self.head_index[k] {
                NO_HEAD => {
                    let i = ctx.peek(&self.hit.at(k)).expect("visible").index;
                    self.head_index[k] = i;
                    i
                }
                i => i,
            };
            let pos = self.st.r().queue.iter().position(|&i| i == index);
            match pos {
                Some(p) => {
                    let u = ctx.pop(&self.hit.at(k)).expect("visible");
                    self.head_index[k] = NO_HEAD;
                    let e = &mut self.st.m().queue_hit[p];
                    if u.hit.closer_than(e) {
                        *e = u.hit;
                    }
                    self.note(c, u.index, || FollowKind::HitQueued {
                        tm: k as u32,
                        t: u.hit.t,
                        tri_id: u.hit.tri_id,
                        merged: true,
                    });
                    self.merged += 1;
                }
                None if self.st.r().queue.len() < self.queue_n as usize => {
                    let u = ctx.pop(&self.hit.at(k)).expect("visible");
                    self.head_index[k] = NO_HEAD;
                    let st = self.st.m();
                    st.queue.push_back(u.index);
                    st.queue_hit.push_back(u.hit);
                    self.note(c, u.index, || FollowKind::HitQueued {
                        tm: k as u32,
                        t: u.hit.t,
                        tri_id: u.hit.tri_id,
                        merged: false,
                    });
                }
                None => {
                    // Queue full: this TM waits, another TM's update may still
                    // merge (whether it can must not depend on the cycle's
                    // round-robin start, or sleeping would change the result).
                    full = true;
                    continue;
                }
            }
            self.updates += 1;
            worked = true;
            full = false;
            break;
        }
        self.visible = visible;
        ctx.set_status(if full {
            Status::ResourceBusy
        } else if worked || self.busy() {
            Status::Busy
        } else {
            Status::WaitInput
        });
        // Pending work that can proceed next cycle; else memory answers wake us.
        let s = self.st.r();
        let can_issue = !s.writes.is_empty()
            || (s.in_flight.len() < self.in_flight_n as usize
                && s.queue.iter().any(|&i| !s.in_flight_has(i)));
        if worked || can_issue {
            Next::Cycle
        } else {
            Next::Idle
        }
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("updates", self.updates),
            ("merged", self.merged),
            ("reads", self.reads),
            ("writes", self.writes),
            ("hazard_waits", self.hazard_waits),
        ]
    }

    fn reset_counters(&mut self) {
        // Called on reset too, when the links are emptied.
        self.head_index.iter_mut().for_each(|h| *h = NO_HEAD);
        self.updates = 0;
        self.merged = 0;
        self.reads = 0;
        self.writes = 0;
        self.hazard_waits = 0;
    }
}

/// What the chip top reads of the hit record updater: its event counters and
/// what it holds (a probe, not hardware).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HitUpdaterProbe {
    pub updates: u64,
    pub merged: u64,
    pub reads: u64,
    pub writes: u64,
    pub hazard_waits: u64,
    /// Updates queued, and read-compare-writes in flight.
    pub queued: usize,
    pub in_flight: usize,
}

impl HitRecordUpdater {
    /// The counters and occupancy (see [`HitUpdaterProbe`]).
    pub fn probe(&self) -> HitUpdaterProbe {
        let s = self.st.r();
        HitUpdaterProbe {
            updates: self.updates,
            merged: self.merged,
            reads: self.reads,
            writes: self.writes,
            hazard_waits: self.hazard_waits,
            queued: s.queue.len(),
            in_flight: s.in_flight.len(),
        }
    }
}
