//! The working set (paper §4.1): admission of the smallest eligible segment
//! (its segment-table entry, child list and queue record read from DRAM, then a
//! scene-buffer slot, a scene stream and destination-table entries for its
//! children) and retirement of a segment whose rays are all done.

use crate::contract::{
    LINE_BYTES, QUEUE_REC_BYTES, QueueRec, SEG_ENTRY_BYTES, SegEntry, lines_touched,
};
use crate::mem::StreamTag;
use crate::rtl::{Ctx, Status};

use super::super::memory::{MemLineReq, MemLineResp};
use super::super::scene_buffer::SlotMap;
use super::{
    Fetch, K_CHILD, K_INFO, K_QREC, KIND_SHIFT, PassEvent, Stream, StreamScheduler, WsEntry,
};

impl StreamScheduler {
    /// Admission, first read: the smallest eligible segment's segment-table
    /// entry (its child list is read when the entry arrives).
    pub(super) fn fetch_segment_info(&mut self) -> bool {
        let mut worked = false;
        if self.st.r().fetch.is_none() && !self.st.r().eligible.is_empty() && self.out_room() >= 1 {
            let st = self.st.m();
            let s = st.eligible.pop_first().expect("non-empty");
            st.fetch = Some(Fetch {
                seg: s,
                entry: None,
                child_lines: Vec::new(),
                children: None,
                rec_asked: false,
                rec: None,
            });
            let a = self.map.seg_entry_addr(s);
            debug_assert!(
                (a % LINE_BYTES) + SEG_ENTRY_BYTES as u64 <= LINE_BYTES,
                "entries do not straddle lines"
            );
            st.out
                .push_back(MemLineReq::read(a, StreamTag::Other, K_INFO << KIND_SHIFT));
            worked = true;
        }
        worked
    }

    /// Admission, second read: the segment's queue record, once the queue's
    /// writes (the record's too) are answered.
    pub(super) fn fetch_queue_record(&mut self) -> bool {
        let mut worked = false;
        let ask = self.st.r().fetch.as_ref().and_then(|f| {
            (!f.rec_asked && !self.st.r().dest.contains_key(&f.seg)).then_some(f.seg)
        });
        if let Some(s) = ask
            && self.out_room() >= 1
        {
            let a = self.map.queue_rec_addr(s);
            let st = self.st.m();
            st.fetch.as_mut().expect("fetch").rec_asked = true;
            st.out.push_back(MemLineReq::read(
                a & !(LINE_BYTES - 1),
                StreamTag::Other,
                K_QREC << KIND_SHIFT,
            ));
            worked = true;
        }
        worked
    }

    /// Sends the admitted segment's slot mapping to the scene buffer.
    pub(super) fn send_slot_map(&mut self, ctx: &mut Ctx) -> bool {
        let mut worked = false;
        if let Some(pm) = self.st.r().pending_map.clone()
            && ctx.can_push(&self.slot_map)
        {
            ctx.push(&self.slot_map, pm);
            self.st.m().pending_map = None;
            worked = true;
        }
        worked
    }

    /// Admits the fetched segment into the working set when a scene-buffer
    /// slot, a scene stream and destination entries for its children are free;
    /// `None` if it never can (the chip stops with the error).
    pub(super) fn admit(&mut self, ctx: &mut Ctx) -> Option<bool> {
        let c = ctx.cycle();
        let mut worked = false;
        let ready_fetch = self
            .st
            .r()
            .fetch
            .as_ref()
            .is_some_and(|f| f.children.is_some());
        if ready_fetch && self.st.r().pending_map.is_none() {
            let s = self.st.r();
            let f = s.fetch.as_ref().expect("fetch");
            let e = f.entry.expect("entry");
            let kids = e.child_count as usize;
            let slot = s.slot_free.iter().position(|&x| x);
            let q_ready = f.rec.is_some();
            let dest_ok = s.dest.len() + s.reserved.len() + kids <= self.dest_entries as usize;
            let stream_ok = s.streams.len() < self.streams_n as usize;
            if kids > self.dest_entries as usize {
                // No amount of waiting frees enough entries: stop with the fix.
                let msg = format!(
                    "segment {} has {kids} children, more than the destination table holds (chip.scheduler.dest_entries = {}): raise it to at least {kids}",
                    f.seg, self.dest_entries
                );
                self.st.m().error = Some(msg);
                ctx.set_status(Status::WaitInput);
                return None;
            }
            let blocked_now = !dest_ok;
            if blocked_now != s.dest_blocked {
                self.st.m().dest_blocked = blocked_now;
                worked = true;
            }
            if let (Some(slot), true, true, true) = (slot, q_ready, dest_ok, stream_ok) {
                let st = self.st.m();
                let f = st.fetch.take().expect("fetch");
                let q = f.rec.expect("queue record");
                let generation = st.slot_gen[slot].wrapping_add(1);
                st.slot_gen[slot] = generation;
                st.slot_free[slot] = false;
                st.slot_streaming[slot] = true;
                let lines = lines_touched(e.base, e.bytes as u64) as u32;
                st.pending_map = Some(SlotMap {
                    slot: slot as u16,
                    generation,
                    base: e.base,
                    lines,
                });
                st.streams.push(Stream {
                    slot: slot as u16,
                    generation,
                    base: e.base,
                    lines,
                    next: 0,
                });
                let children = f.children.expect("children");
                for &k in &children {
                    st.reserved.insert(k, f.seg);
                }
                st.ws.push(WsEntry {
                    seg: f.seg,
                    slot: slot as u16,
                    entry: e,
                    children,
                    head: q.head,
                    buckets_left: q.buckets as u64,
                    header_pending: false,
                    buckets_on_chip: 0,
                    rays_fwd: 0,
                    rays_done: 0,
                });
                self.stats.segments_loaded += 1;
                self.stats.scene_lines += lines as u64;
                if let Some((adm, _)) = &mut self.pass_log {
                    adm.insert(f.seg, c);
                }
                worked = true;
            }
        }
        Some(worked)
    }

    /// Retires one working-set segment per cycle whose queue is read, whose
    /// buckets are forwarded and whose rays have all sent their end marker: its
    /// children's queues are closed (`close_child`).
    pub(super) fn retire(&mut self, ctx: &mut Ctx) -> bool {
        let c = ctx.cycle();
        let mut worked = false;
        let done = self.st.r().ws.iter().position(|w| {
            w.head == 0
                && !w.header_pending
                && w.buckets_left == 0
                && w.buckets_on_chip == 0
                && w.rays_done == w.rays_fwd
        });
        if let Some(i) = done {
            let st = self.st.m();
            let w = st.ws.remove(i);
            if !st.slot_streaming[w.slot as usize] {
                st.slot_free[w.slot as usize] = true;
            }
            for &k in &w.children {
                st.reserved.remove(&k);
                st.closing.push_back(k);
            }
            self.stats.retired += 1;
            if let Some((adm, log)) = &mut self.pass_log {
                log.push(PassEvent {
                    seg: w.seg,
                    rays: w.rays_done,
                    admit: adm.remove(&w.seg).unwrap_or(c),
                    retire: c,
                });
            }
            worked = true;
        }
        worked
    }

    /// The queue record of the segment being fetched.
    pub(super) fn queue_record_arrived(&mut self, r: MemLineResp) {
        let st = self.st.m();
        let f = st.fetch.as_mut().expect("fetch in progress");
        let off = (self.map.queue_rec_addr(f.seg) % LINE_BYTES) as usize;
        f.rec = Some(QueueRec::decode(
            &r.data.0[off..off + QUEUE_REC_BYTES as usize],
        ));
    }

    /// The segment-table entry of the segment being fetched: read its child list.
    pub(super) fn segment_info_arrived(&mut self, r: MemLineResp) {
        let st = self.st.m();
        let f = st.fetch.as_mut().expect("fetch in progress");
        let off = (self.map.seg_entry_addr(f.seg) % LINE_BYTES) as usize;
        let e = SegEntry::decode(&r.data.0[off..off + SEG_ENTRY_BYTES as usize]);
        let a = self.map.child_list + e.first_child as u64 * 4;
        let n = lines_touched(a, e.child_count as u64 * 4);
        f.entry = Some(e);
        f.child_lines = vec![None; n as usize];
        if n == 0 {
            f.children = Some(Vec::new());
        }
        for k in 0..n {
            st.out.push_back(MemLineReq::read(
                (a & !(LINE_BYTES - 1)) + k * LINE_BYTES,
                StreamTag::Other,
                K_CHILD << KIND_SHIFT | k as u32,
            ));
        }
    }

    /// Line `low` of the child list of the segment being fetched.
    pub(super) fn child_line_arrived(&mut self, low: u32, r: MemLineResp) {
        let st = self.st.m();
        let f = st.fetch.as_mut().expect("fetch in progress");
        f.child_lines[low as usize] = Some(r.data);
        if f.child_lines.iter().all(|l| l.is_some()) {
            let e = f.entry.expect("entry first");
            let a = self.map.child_list + e.first_child as u64 * 4;
            let base = a & !(LINE_BYTES - 1);
            let kids = (0..e.child_count as u64)
                .map(|k| {
                    let x = a + 4 * k - base;
                    let l = f.child_lines[(x / LINE_BYTES) as usize]
                        .as_ref()
                        .expect("all lines");
                    l.u32_at((x % LINE_BYTES) as usize)
                })
                .collect();
            f.children = Some(kids);
        }
    }
}
