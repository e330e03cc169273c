//! The scheduler's memory traffic (paper §4.1): the scene stream (segment lines
//! into the scene buffer's slots, one per scene lane per cycle) and the ray
//! stream (bucket reads and writes, segment info, one per ray lane per cycle),
//! with the answers that come back on the ray lanes.

use crate::contract::{BUCKET_HEADER_BYTES, LINE_BYTES, RAY_BYTES, RayRec, lines_touched};
use crate::mem::StreamTag;
use crate::rtl::Ctx;

use super::super::follow::FollowKind;
use super::super::memory::{MemLineReq, MemLineResp};
use super::super::scene_buffer::fill_id;
use super::{BucketRead, K_BUCKET, K_CHILD, K_INFO, K_QREC, K_WRITE, KIND_SHIFT, StreamScheduler};

impl StreamScheduler {
    /// Takes the memory answers, one per ray lane.
    pub(super) fn take_mem_answers(&mut self, ctx: &mut Ctx) -> bool {
        let mut worked = false;
        for j in 0..self.mem_resp.len() {
            if let Some(r) = ctx.pop(&self.mem_resp.at(j)) {
                self.answer(r, ctx.cycle());
                worked = true;
            }
        }
        worked
    }

    /// One memory answer (ray-stream line, segment info, write done).
    fn answer(&mut self, r: MemLineResp, c: u64) {
        let kind = r.id >> KIND_SHIFT;
        let low = r.id & ((1 << KIND_SHIFT) - 1);
        match kind {
            K_WRITE => self.write_answered(low),
            K_QREC => self.queue_record_arrived(r),
            K_INFO => self.segment_info_arrived(r),
            K_CHILD => self.child_line_arrived(low, r),
            K_BUCKET => self.bucket_line_arrived(low, r, c),
            _ => unreachable!("unknown memory id {:#x}", r.id),
        }
    }

    /// A line of a ray bucket being read: the header gives the count and the
    /// queue's next bucket; the last line makes the bucket ready for a TM.
    fn bucket_line_arrived(&mut self, low: u32, r: MemLineResp, c: u64) {
        let (ri, line) = ((low >> 8) as usize, low & 0xFF);
        let per_chunk = self.per_chunk;
        let map_base = self.map.buckets;
        let bucket_bytes = self.map.bucket_bytes;
        let st = self.st.m();
        let rd = st.reads[ri].as_mut().expect("read in progress");
        let o = line as usize * LINE_BYTES as usize;
        rd.bytes[o..o + LINE_BYTES as usize].copy_from_slice(&r.data.0);
        rd.got += 1;
        let mut extra_lines = Vec::new();
        if line == 0 {
            // Header: the count and the next bucket of the queue.
            let next = u64::from_le_bytes(r.data.0[0..8].try_into().expect("8"));
            let count = r.data.u32_at(8);
            rd.count = count;
            rd.lines = lines_touched(
                rd.addr,
                BUCKET_HEADER_BYTES as u64 + count as u64 * RAY_BYTES as u64,
            ) as u32;
            for k in 1..rd.lines {
                extra_lines.push(MemLineReq::read(
                    rd.addr + k as u64 * LINE_BYTES,
                    StreamTag::Ray,
                    K_BUCKET << KIND_SHIFT | (ri as u32) << 8 | k,
                ));
            }
            let seg = rd.seg;
            let w = st.ws.iter_mut().find(|w| w.seg == seg).expect("ws");
            w.head = next;
            w.header_pending = false;
        }
        st.out.extend(extra_lines);
        let rd = st.reads[ri].as_ref().expect("read");
        if rd.lines > 0 && rd.got == rd.lines {
            let rd = st.reads[ri].take().expect("read");
            let rays: Vec<RayRec> = rd.bytes[BUCKET_HEADER_BYTES as usize
                ..(BUCKET_HEADER_BYTES + rd.count * RAY_BYTES) as usize]
                .chunks_exact(RAY_BYTES as usize)
                .map(RayRec::decode)
                .collect();
            let b = (rd.addr - map_base) / bucket_bytes;
            st.live_buckets -= 1;
            Self::free_bucket(st, per_chunk, b);
            if let Some(f) = &mut self.follow {
                for r in &rays {
                    if f.wants(r.ray_id) {
                        f.log(c, r.ray_id, FollowKind::BucketRead { seg: rd.seg });
                    }
                }
            }
            st.ready.push_back((rd.seg, rays));
            self.stats.buckets_read += 1;
        }
    }

    /// Scene stream: one segment line per scene lane per cycle
    /// (`scene_lines_per_cycle`), lane j serving stream (cycle + j) mod streams.
    pub(super) fn stream_scene(&mut self, ctx: &mut Ctx) -> bool {
        let c = ctx.cycle();
        let mut worked = false;
        // The mapping goes out first (the scene buffer must know the slot).
        let mut issued = 0;
        for j in 0..self.scene_req.len() {
            if self.st.r().streams.is_empty() || !ctx.can_push(&self.scene_req.at(j)) {
                continue;
            }
            let k = (c as usize + j) % self.st.r().streams.len();
            let s = &self.st.r().streams[k];
            let mapped_first = self
                .st
                .r()
                .pending_map
                .as_ref()
                .is_none_or(|m| m.slot != s.slot);
            if mapped_first {
                let st = self.st.m();
                let s = &mut st.streams[k];
                let req = MemLineReq::read(
                    s.base + s.next as u64 * LINE_BYTES,
                    StreamTag::Scene,
                    fill_id(s.generation, s.slot, s.next),
                );
                s.next += 1;
                if s.next == s.lines {
                    let slot = s.slot as usize;
                    st.streams.remove(k);
                    st.slot_streaming[slot] = false;
                    // A retired segment's slot frees when its stream is done.
                    if !st.ws.iter().any(|w| w.slot as usize == slot) {
                        st.slot_free[slot] = true;
                    }
                }
                ctx.push(&self.scene_req.at(j), req);
                issued += 1;
                worked = true;
            }
        }
        self.stats.scene_lines_peak = self.stats.scene_lines_peak.max(issued);
        worked
    }

    /// Ray stream in: starts reading the next ray bucket of a working-set queue
    /// (its header line first).
    pub(super) fn start_bucket_read(&mut self) -> bool {
        let mut worked = false;
        let on_chip: u32 = self.st.r().ws.iter().map(|w| w.buckets_on_chip).sum();
        let free_read = self.st.r().reads.iter().position(|r| r.is_none());
        let cand = self
            .st
            .r()
            .ws
            .iter()
            .position(|w| w.head != 0 && !w.header_pending);
        if let (Some(ri), Some(wi), true, true) = (
            free_read,
            cand,
            on_chip < self.bucket_buffers,
            self.out_room() >= 1,
        ) {
            let bb = self.map.bucket_bytes as usize;
            let st = self.st.m();
            let w = &mut st.ws[wi];
            let addr = w.head;
            w.head = 0;
            w.header_pending = true;
            w.buckets_left -= 1;
            w.buckets_on_chip += 1;
            st.reads[ri] = Some(BucketRead {
                seg: w.seg,
                addr,
                count: 0,
                lines: 0,
                got: 0,
                bytes: vec![0; bb],
            });
            st.out.push_back(MemLineReq::read(
                addr,
                StreamTag::Ray,
                K_BUCKET << KIND_SHIFT | (ri as u32) << 8,
            ));
            worked = true;
        }
        worked
    }

    /// Ray stream out: the queued line requests in order, one per ray lane per
    /// cycle (`ray_lines_per_cycle`).
    pub(super) fn issue_ray_stream(&mut self, ctx: &mut Ctx) -> bool {
        let mut worked = false;
        let mut issued = 0;
        for j in 0..self.mem_req.len() {
            if !self.st.r().out.is_empty() && ctx.can_push(&self.mem_req.at(j)) {
                let r = self.st.m().out.pop_front().expect("non-empty");
                ctx.push(&self.mem_req.at(j), r);
                issued += 1;
                worked = true;
            }
        }
        self.stats.ray_lines_peak = self.stats.ray_lines_peak.max(issued);
        worked
    }
}
