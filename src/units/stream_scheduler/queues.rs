//! The ray queues (paper §4.1: a queue per destination segment, its rays in
//! DRAM in ray buckets) and the bucket pool they take buckets from: taking ray
//! writes into the destination table, write coalescing, sealing buckets and
//! closing queues (the root queue at wave start, a retired segment's children).

use crate::contract::{
    BUCKET_HEADER_BYTES, LINE_BYTES, QUEUE_REC_BYTES, QueueRec, RAY_BYTES, RayRec,
};
use crate::mem::StreamTag;
use crate::rtl::{Ctx, round_robin};

use super::super::follow::FollowKind;
use super::super::l1::Line;
use super::super::memory::MemLineReq;
use super::super::tp::RayWrite;
use super::super::tp_shade::SHADE_SEG;
use super::{K_WRITE, KIND_SHIFT, QueueDesc, SchedState, ShadePass, StreamScheduler};

impl StreamScheduler {
    /// Wave start: closes the root segment's queue and makes it eligible, or
    /// starts the shading pass that fills it.
    pub(super) fn start_wave(&mut self, ctx: &mut Ctx) -> bool {
        let mut worked = false;
        // (The host pushes `start` after its last ray: once `start` is visible with
        // the emit link empty, every ray of the wavefront has been taken.)
        if self.out_room() >= 3 && ctx.peek(&self.start).is_some() && ctx.peek(&self.emit).is_none()
        {
            let ws = ctx.pop(&self.start).expect("peeked");
            if ws.shade_pixels > 0 {
                let first = self.shade_first.min(ws.shade_pixels);
                self.st.m().shade = Some(ShadePass {
                    next: first,
                    end: ws.shade_pixels,
                    ..ShadePass::default()
                });
            } else {
                self.close(0);
                if self.st.r().dest.contains_key(&0) {
                    self.st.m().eligible.insert(0);
                }
            }
            worked = true;
        }
        worked
    }

    /// The shading pass is over when every item handed out has sent its end
    /// marker (after its rays, on the same path): the root queue is complete.
    pub(super) fn end_shade_pass(&mut self, ctx: &mut Ctx) -> bool {
        let c = ctx.cycle();
        let mut worked = false;
        let shaded = self
            .st
            .r()
            .shade
            .as_ref()
            .is_some_and(|p| p.next == p.end && p.done == p.out);
        if shaded && self.out_room() >= 3 {
            self.st.m().shade = None;
            self.last_shade_end = c;
            self.close(0);
            if self.st.r().dest.contains_key(&0) {
                self.st.m().eligible.insert(0);
            }
            worked = true;
        }
        worked
    }

    /// Takes ray writes (duplicates and end markers) into the destination
    /// table: up to `writes_per_cycle`, the TMs round-robin, then `emit`.
    pub(super) fn take_ray_writes(&mut self, ctx: &mut Ctx) -> bool {
        let c = ctx.cycle();
        let mut worked = false;
        let n = self.tms_n as usize;
        let mut taken = 0;
        let mut visible = std::mem::take(&mut self.visible);
        ctx.visible_words(&self.ray_write, &mut visible);
        let order = round_robin(&visible, c as usize % n)
            .map(Some)
            .chain(std::iter::once(None));
        for src in order {
            if taken >= self.writes_per_cycle || self.out_room() < 3 {
                break;
            }
            let w = match src {
                Some(k) => ctx.peek(&self.ray_write.at(k)).cloned(),
                None => ctx.peek(&self.emit).cloned(),
            };
            let Some(w) = w else { continue };
            if !w.done && !self.st.r().dest.contains_key(&w.seg) {
                let s = self.st.r();
                let is_reserved = s.reserved.contains_key(&w.seg);
                if !is_reserved && s.dest.len() + s.reserved.len() >= self.dest_entries as usize {
                    continue; // the table is full: the write waits in its link
                }
            }
            match src {
                Some(k) => ctx.pop(&self.ray_write.at(k)),
                None => ctx.pop(&self.emit),
            };
            if w.done {
                self.last_marker = c;
            }
            self.accept_write(&w, src, c);
            taken += 1;
            worked = true;
        }
        self.visible = visible;
        worked
    }

    /// Closes one child queue of a retired segment per cycle; one that holds
    /// rays becomes eligible.
    pub(super) fn close_child(&mut self) -> bool {
        let mut worked = false;
        if self.out_room() >= 3 && !self.st.r().closing.is_empty() {
            let s = self.st.m().closing.pop_front().expect("non-empty");
            if self.st.r().dest.contains_key(&s) {
                self.close(s);
                self.st.m().eligible.insert(s);
            } else {
                self.stats.skipped_children += 1;
            }
            worked = true;
        }
        worked
    }

    /// Accepts a duplicate or a marker.
    fn accept_write(&mut self, w: &RayWrite, tm: Option<usize>, c: u64) {
        if w.done
            && let Some(k) = tm
        {
            let t = &mut self.st.m().tms[k];
            t.outstanding = t.outstanding.saturating_sub(1);
        }
        if w.done && w.seg == SHADE_SEG {
            self.stats.shade_done += 1;
            self.st
                .m()
                .shade
                .as_mut()
                .expect("a shading item's end marker during a shading pass")
                .done += 1;
            return;
        }
        if w.done {
            self.stats.markers += 1;
            self.pub_done[w.seg as usize] += 1;
            let st = self.st.m();
            let e = st
                .ws
                .iter_mut()
                .find(|e| e.seg == w.seg)
                .expect("end marker of a working-set segment");
            e.rays_done += 1;
            if let Some(f) = &mut self.follow
                && f.wants(w.ray.ray_id)
            {
                f.log(c, w.ray.ray_id, FollowKind::Marker { seg: w.seg });
            }
            return;
        }
        if w.seg == 0
            && let Some(l) = &mut self.root_log
        {
            l.push(w.ray);
        }
        if !self.st.r().dest.contains_key(&w.seg) {
            let st = self.st.m();
            st.reserved.remove(&w.seg);
            st.dest.insert(w.seg, QueueDesc::default());
        }
        self.push_ray(w.seg, &w.ray);
        if let Some(f) = &mut self.follow
            && f.wants(w.ray.ray_id)
            && let Some(q) = self.st.r().dest.get(&w.seg)
        {
            let kind = FollowKind::Queued {
                seg: w.seg,
                bucket: q.tail,
                slot: q.tail_count.saturating_sub(1),
                from: tm.map(|k| k as u32),
            };
            f.log(c, w.ray.ray_id, kind);
        }
    }

    // ---- the bucket pool (mirrors render/queues.rs) ----

    fn new_bucket(&mut self, seg: u32) -> Option<u64> {
        let per_chunk = self.per_chunk;
        let st = self.st.m();
        let q = st.dest.get_mut(&seg).expect("queue exists");
        if q.chunk_left.is_empty() {
            let Some(c) = st.free_chunks.pop() else {
                st.error = Some(format!(
                    "the ray-bucket pool ran dry ({} live buckets) while queueing rays for segment {seg}; raise memory.bucket_pool_bytes",
                    st.live_buckets
                ));
                return None;
            };
            st.chunk_live[c as usize] = per_chunk as u8;
            q.chunk_left = (0..per_chunk).rev().map(|k| c * per_chunk + k).collect();
        }
        let b = q.chunk_left.pop().expect("refilled");
        st.live_buckets += 1;
        st.peak_buckets = st.peak_buckets.max(st.live_buckets);
        Some(b)
    }

    pub(super) fn free_bucket(st: &mut SchedState, per_chunk: u64, b: u64) {
        let c = (b / per_chunk) as usize;
        st.chunk_live[c] -= 1;
        if st.chunk_live[c] == 0 {
            st.free_chunks.push(c as u64);
        }
    }

    /// A write of one of queue `seg`'s lines (counted in its `writes_in_flight`).
    fn write_req(seg: u32, tag: StreamTag, addr: u64, data: Line, mask: u64) -> MemLineReq {
        MemLineReq {
            addr,
            write: true,
            tag,
            id: K_WRITE << KIND_SHIFT | seg,
            mask,
            data,
        }
    }

    fn flush_line(&mut self, seg: u32) {
        let st = self.st.m();
        let q = st.dest.get_mut(&seg).expect("queue");
        if let Some((a, data, mask)) = q.line.take() {
            q.writes_in_flight += 1;
            st.out
                .push_back(Self::write_req(seg, StreamTag::Ray, a, data, mask));
        }
    }

    fn seal(&mut self, seg: u32, bucket: u64, count: u32, next: u64) {
        let a = self.map.bucket_addr(bucket);
        let mut data = Line::default();
        data.0[0..8].copy_from_slice(&next.to_le_bytes());
        data.0[8..12].copy_from_slice(&count.to_le_bytes());
        data.0[12..16].copy_from_slice(&seg.to_le_bytes());
        let st = self.st.m();
        st.dest.get_mut(&seg).expect("queue").writes_in_flight += 1;
        st.out.push_back(Self::write_req(
            seg,
            StreamTag::Ray,
            a,
            data,
            (1u64 << BUCKET_HEADER_BYTES) - 1,
        ));
        self.stats.buckets_written += 1;
    }

    /// Appends a ray to a queue; needs 3 free memory-queue entries.
    fn push_ray(&mut self, seg: u32, ray: &RayRec) {
        let rpb = self.rays_per_bucket;
        let full = {
            let q = &self.st.r().dest[&seg];
            !q.has_tail || q.tail_count == rpb
        };
        if full {
            let Some(b) = self.new_bucket(seg) else {
                return;
            };
            let (prev, had) = {
                let q = &self.st.r().dest[&seg];
                (q.tail, q.has_tail)
            };
            if had {
                self.flush_line(seg);
                self.seal(seg, prev, rpb, self.map.bucket_addr(b));
            }
            let ba = self.map.bucket_addr(b);
            let q = self.st.m().dest.get_mut(&seg).expect("queue");
            if !had {
                q.head = ba;
            }
            q.tail = b;
            q.has_tail = true;
            q.tail_count = 0;
            q.buckets += 1;
        }
        let (slot, line_a) = {
            let q = &self.st.r().dest[&seg];
            let slot = self.map.bucket_addr(q.tail)
                + BUCKET_HEADER_BYTES as u64
                + q.tail_count as u64 * RAY_BYTES as u64;
            (slot, slot & !(LINE_BYTES - 1))
        };
        if matches!(&self.st.r().dest[&seg].line, Some((a, _, _)) if *a != line_a) {
            self.flush_line(seg);
        }
        let off = (slot - line_a) as usize;
        let bytes = ray.encode();
        let q = self.st.m().dest.get_mut(&seg).expect("queue");
        let (_, data, mask) = q.line.get_or_insert_with(|| (line_a, Line::default(), 0));
        data.0[off..off + RAY_BYTES as usize].copy_from_slice(&bytes);
        *mask |= ((1u64 << RAY_BYTES) - 1) << off;
        q.tail_count += 1;
        q.len += 1;
        if off + RAY_BYTES as usize == LINE_BYTES as usize {
            self.flush_line(seg);
        }
        self.stats.enqueues += 1;
        self.pub_enqueued[seg as usize] += 1;
    }

    /// Seals a queue's open bucket (its parent is done), returns its chunk's
    /// unused buckets and writes its queue record; needs 3 free memory-queue
    /// entries.
    fn close(&mut self, seg: u32) {
        if !self.st.r().dest.contains_key(&seg) {
            return;
        }
        self.flush_line(seg);
        let (tail, has, n) = {
            let q = &self.st.r().dest[&seg];
            (q.tail, q.has_tail, q.tail_count)
        };
        if has {
            self.seal(seg, tail, n, 0);
        }
        let per_chunk = self.per_chunk;
        let a = self.map.queue_rec_addr(seg);
        let st = self.st.m();
        let q = st.dest.get_mut(&seg).expect("queue");
        q.closed = true;
        let left = std::mem::take(&mut q.chunk_left);
        // The closed queue is no write destination any more: its record goes to
        // DRAM, and its table entry is freed when every write of it is answered.
        let rec = QueueRec {
            head: q.head,
            buckets: u32::try_from(q.buckets).expect("buckets of one queue fit 32 bits"),
            rays: u32::try_from(q.len).expect("rays of one queue fit 32 bits"),
        };
        q.writes_in_flight += 1;
        let line_a = a & !(LINE_BYTES - 1);
        let off = (a - line_a) as usize;
        let mut data = Line::default();
        data.0[off..off + QUEUE_REC_BYTES as usize].copy_from_slice(&rec.encode());
        st.out.push_back(Self::write_req(
            seg,
            StreamTag::Other,
            line_a,
            data,
            ((1u64 << QUEUE_REC_BYTES) - 1) << off,
        ));
        for b in left {
            Self::free_bucket(st, per_chunk, b);
        }
    }
    /// A write of queue `low` was answered; a closed queue's entry frees with
    /// its last one (its record is in DRAM).
    pub(super) fn write_answered(&mut self, low: u32) {
        let st = self.st.m();
        if let Some(q) = st.dest.get_mut(&low) {
            q.writes_in_flight -= 1;
            if q.closed && q.writes_in_flight == 0 {
                // Its record is in DRAM: the entry is free.
                st.dest.remove(&low);
            }
        }
    }
}
