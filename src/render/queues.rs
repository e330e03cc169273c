//! Ray queues: one per segment, each a linked list of ray buckets in DRAM, allocated
//! from a bucket pool in whole-row chunks (four 2 KB buckets per 8 KB row) so a
//! queue's buckets stream as rows. A bucket goes back to the pool once it is read;
//! a chunk returns to the free list when all its buckets have.
//!
//! Header discipline (the data contract): a bucket's header is written when the
//! bucket is sealed — when it is full, or when its queue is closed because its
//! parent segment is done — with the ray count and the address of the next bucket
//! (0 for the last). Counting the traffic: slots are written as rays arrive, two
//! 32 B rays per 64 B line; the header costs one line write; reading a bucket reads
//! the lines of its header and its rays.

use crate::contract::{
    BUCKET_HEADER_BYTES, BucketHeader, MemoryMap, QueueRec, RAY_BYTES, RayRec, SparseMem,
    lines_touched,
};

/// The ray stream between two segments of a wavefront, in the order the functional
/// model takes them: every queue holding rays (all closed: their parents are done)
/// as the record the stream scheduler reads, and the bucket pool. What a chip needs
/// to take the wavefront over at that point (`Chip::trace_window`).
#[derive(Clone, Debug, Default)]
pub struct Boundary {
    pub queues: Vec<(u32, QueueRec)>,
    pub free_chunks: Vec<u64>,
    pub chunk_live: Vec<u8>,
    pub live_buckets: u64,
    /// Bucket headers to rewrite (address, next bucket's address or 0) before
    /// the chip reads them: a thinned queue's chain (`boundary_strided`).
    pub relink: Vec<(u64, u64)>,
}

/// Traffic of the ray stream, in 64 B lines.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct RayTraffic {
    pub lines_read: u64,
    pub lines_written: u64,
    pub buckets_read: u64,
    pub buckets_written: u64,
}

#[derive(Clone, Debug, Default)]
struct Queue {
    /// Buckets of this queue in order (their indices in the pool).
    buckets: std::collections::VecDeque<u64>,
    /// Rays in the open (last) bucket.
    tail_count: u32,
    /// Remaining unused buckets of the chunk this queue is filling.
    chunk_left: Vec<u64>,
    len: u64,
}

pub struct RayQueues {
    queues: Vec<Queue>,
    free_chunks: Vec<u64>,
    /// Live (not yet freed) buckets per chunk.
    chunk_live: Vec<u8>,
    per_chunk: u64,
    rays_per_bucket: u32,
    pub traffic: RayTraffic,
    pub enqueued: u64,
    pub peak_buckets: u64,
    live_buckets: u64,
    /// Cycle mode: the queues live on the chip; rays pushed to the root queue are
    /// handed over here instead (see [`RayQueues::divert`]).
    diverted: Option<Vec<RayRec>>,
}

impl RayQueues {
    pub fn new(map: &MemoryMap, segments: usize) -> RayQueues {
        let per_chunk = map.row_bytes / map.bucket_bytes;
        let chunks = map.bucket_count / per_chunk;
        RayQueues {
            queues: vec![Queue::default(); segments],
            // Lowest chunk first (LIFO stack: push in reverse).
            free_chunks: (0..chunks).rev().collect(),
            chunk_live: vec![0; chunks as usize],
            per_chunk,
            rays_per_bucket: ((map.bucket_bytes - BUCKET_HEADER_BYTES as u64) / RAY_BYTES as u64)
                as u32,
            traffic: RayTraffic::default(),
            enqueued: 0,
            peak_buckets: 0,
            live_buckets: 0,
            diverted: None,
        }
    }

    /// Cycle mode: the chip's stream scheduler keeps the queues; from now on the
    /// host's pushes (root-queue rays from ray generation and shading) are
    /// collected for the chip instead of written into buckets, and closes are
    /// the chip's business.
    pub fn divert(&mut self) {
        self.diverted = Some(Vec::new());
    }

    /// The rays pushed since the last call (cycle mode).
    pub fn take_diverted(&mut self) -> Vec<RayRec> {
        self.diverted
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }

    pub fn len(&self, seg: u32) -> u64 {
        self.queues[seg as usize].len
    }

    /// Queues holding rays (segments with work pending).
    pub fn pending(&self) -> usize {
        self.queues.iter().filter(|q| q.len > 0).count()
    }

    pub fn is_empty(&self, seg: u32) -> bool {
        self.len(seg) == 0
    }

    fn new_bucket(&mut self, seg: u32) -> Result<u64, String> {
        let q = &mut self.queues[seg as usize];
        if q.chunk_left.is_empty() {
            let Some(c) = self.free_chunks.pop() else {
                return Err(format!(
                    "the ray-bucket pool ran dry ({} live buckets) while queueing rays for segment {seg}; raise memory.bucket_pool_bytes",
                    self.live_buckets
                ));
            };
            self.chunk_live[c as usize] = self.per_chunk as u8;
            q.chunk_left = (0..self.per_chunk)
                .rev()
                .map(|k| c * self.per_chunk + k)
                .collect();
        }
        let b = q.chunk_left.pop().expect("refilled above");
        q.buckets.push_back(b);
        q.tail_count = 0;
        self.live_buckets += 1;
        self.peak_buckets = self.peak_buckets.max(self.live_buckets);
        Ok(b)
    }

    fn free_bucket(&mut self, b: u64) {
        let c = (b / self.per_chunk) as usize;
        self.chunk_live[c] -= 1;
        if self.chunk_live[c] == 0 {
            self.free_chunks.push(c as u64);
        }
    }

    fn seal(
        &mut self,
        mem: &mut SparseMem,
        map: &MemoryMap,
        seg: u32,
        bucket: u64,
        count: u32,
        next: u64,
    ) {
        BucketHeader {
            next,
            count,
            segment: seg,
        }
        .write(mem, map.bucket_addr(bucket));
        self.traffic.lines_written += 1;
        self.traffic.buckets_written += 1;
    }

    /// Appends a ray to a segment's queue.
    pub fn push(
        &mut self,
        mem: &mut SparseMem,
        map: &MemoryMap,
        seg: u32,
        ray: &RayRec,
    ) -> Result<(), String> {
        if let Some(d) = &mut self.diverted {
            debug_assert_eq!(seg, 0, "the host emits into the root queue only");
            d.push(*ray);
            return Ok(());
        }
        let full = {
            let q = &self.queues[seg as usize];
            q.buckets.is_empty() || q.tail_count == self.rays_per_bucket
        };
        if full {
            let prev = self.queues[seg as usize].buckets.back().copied();
            let b = self.new_bucket(seg)?;
            if let Some(p) = prev {
                let n = self.rays_per_bucket;
                self.seal(mem, map, seg, p, n, map.bucket_addr(b));
            }
        }
        let q = &mut self.queues[seg as usize];
        let b = *q.buckets.back().expect("has a tail");
        let slot = map.bucket_addr(b)
            + BUCKET_HEADER_BYTES as u64
            + q.tail_count as u64 * RAY_BYTES as u64;
        ray.write(mem, slot);
        // Writes are coalesced into lines: a line is written when its first ray lands.
        if slot.is_multiple_of(64) || q.tail_count == 0 {
            self.traffic.lines_written += lines_touched(slot, RAY_BYTES as u64);
        }
        q.tail_count += 1;
        q.len += 1;
        self.enqueued += 1;
        Ok(())
    }

    /// Seals the open bucket of a queue (its parent is done: no more rays come).
    pub fn close(&mut self, mem: &mut SparseMem, map: &MemoryMap, seg: u32) {
        if self.diverted.is_some() {
            return;
        }
        let q = &self.queues[seg as usize];
        if let Some(&b) = q.buckets.back() {
            let n = q.tail_count;
            self.seal(mem, map, seg, b, n, 0);
        }
        // Unused buckets of the chunk go back to the pool.
        let left = std::mem::take(&mut self.queues[seg as usize].chunk_left);
        for b in left {
            self.free_bucket(b);
        }
    }

    /// Reads and frees the next bucket of a queue, appending its rays to `out`.
    /// Follows the header's next pointer, as the stream scheduler does.
    pub fn pop_bucket(
        &mut self,
        mem: &SparseMem,
        map: &MemoryMap,
        seg: u32,
        out: &mut Vec<RayRec>,
    ) -> bool {
        let Some(b) = self.queues[seg as usize].buckets.pop_front() else {
            return false;
        };
        let a = map.bucket_addr(b);
        let h = BucketHeader::read(mem, a);
        debug_assert_eq!(h.segment, seg, "bucket belongs to its queue");
        if let Some(&n) = self.queues[seg as usize].buckets.front() {
            debug_assert_eq!(h.next, map.bucket_addr(n), "linked list matches");
        }
        let mut bytes = vec![0u8; h.count as usize * RAY_BYTES as usize];
        mem.read(a + BUCKET_HEADER_BYTES as u64, &mut bytes);
        out.extend(bytes.chunks_exact(RAY_BYTES as usize).map(RayRec::decode));
        self.traffic.lines_read += lines_touched(
            a,
            BUCKET_HEADER_BYTES as u64 + h.count as u64 * RAY_BYTES as u64,
        );
        self.traffic.buckets_read += 1;
        let q = &mut self.queues[seg as usize];
        q.len -= h.count as u64;
        self.live_buckets -= 1;
        self.free_bucket(b);
        true
    }

    /// The queues and the pool as they stand (see [`Boundary`]); queues still open
    /// are a modelling error, since the chip could not take them over.
    pub fn boundary(&self, map: &MemoryMap) -> Boundary {
        self.boundary_inner(map)
    }

    /// [`RayQueues::boundary`] with segment `seg`'s queue thinned to one bucket
    /// in `every` (a root window: the pass over a sample of its rays, spread over
    /// the queue since its rays come in pixel order). The kept buckets are
    /// chained by rewriting their headers (`Boundary::relink`, written into the
    /// window's snapshot of the image); the others stay allocated in the pool, as rays
    /// the pass already took would sit in its children's queues. Also the rays
    /// kept.
    pub fn boundary_strided(&self, map: &MemoryMap, seg: usize, every: usize) -> (Boundary, u64) {
        let mut b = self.boundary_inner(map);
        let q = &self.queues[seg];
        if every <= 1 || q.len == 0 {
            return (b, q.len);
        }
        let kept: Vec<usize> = (0..q.buckets.len()).step_by(every).collect();
        let last = q.buckets.len() - 1;
        let rpb = self.rays_per_bucket as u64;
        let tail = q.len - last as u64 * rpb;
        let rays: u64 = kept
            .iter()
            .map(|&i| if i == last { tail } else { rpb })
            .sum();
        for (j, &i) in kept.iter().enumerate() {
            let next = kept
                .get(j + 1)
                .map_or(0, |&n| map.bucket_addr(q.buckets[n]));
            b.relink.push((map.bucket_addr(q.buckets[i]), next));
        }
        let r = b
            .queues
            .iter_mut()
            .find(|(s, _)| *s as usize == seg)
            .expect("the queue holds rays");
        r.1.buckets = kept.len() as u32;
        r.1.rays = rays as u32;
        (b, rays)
    }

    fn boundary_inner(&self, map: &MemoryMap) -> Boundary {
        let mut queues = Vec::new();
        for (s, q) in self.queues.iter().enumerate() {
            if q.len == 0 {
                continue;
            }
            debug_assert!(q.chunk_left.is_empty(), "segment {s}: queue still open");
            queues.push((
                s as u32,
                QueueRec {
                    head: map.bucket_addr(*q.buckets.front().expect("rays in buckets")),
                    buckets: q.buckets.len() as u32,
                    rays: q.len as u32,
                },
            ));
        }
        Boundary {
            queues,
            free_chunks: self.free_chunks.clone(),
            chunk_live: self.chunk_live.clone(),
            live_buckets: self.live_buckets,
            relink: Vec::new(),
        }
    }

    pub fn rays_per_bucket(&self) -> u32 {
        self.rays_per_bucket
    }

    /// Buckets currently holding rays.
    pub fn live_buckets(&self) -> u64 {
        self.live_buckets
    }
}

/// Lines the functional model writes for a queue of `n` rays (ray lines coalesced
/// per line, one header per bucket), `rays_per_bucket` rays per bucket.
pub fn queue_lines_written(n: u64, rays_per_bucket: u32) -> u64 {
    let rpb = rays_per_bucket as u64;
    let line = |m: u64| lines_touched(BUCKET_HEADER_BYTES as u64, m * RAY_BYTES as u64);
    let (full, rest) = (n / rpb, n % rpb);
    full * (line(rpb) + 1) + if rest > 0 { line(rest) + 1 } else { 0 }
}
