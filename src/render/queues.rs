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

use super::RenderError;
use crate::contract::{
    BUCKET_HEADER_BYTES, Boundary, BucketHeader, HIT_BYTES, MemoryMap, QueueRec, RAY_BYTES, RayRec,
    SHADOW_BIT, SparseMem, lines_touched,
};

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

    fn new_bucket(&mut self, seg: u32) -> Result<u64, RenderError> {
        let q = &mut self.queues[seg as usize];
        if q.chunk_left.is_empty() {
            let Some(c) = self.free_chunks.pop() else {
                return Err(RenderError::BucketPool(format!(
                    "the ray-bucket pool ran dry ({} live buckets) while queueing rays for segment {seg}; raise memory.bucket_pool_bytes",
                    self.live_buckets
                )));
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
    ) -> Result<(), RenderError> {
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

    /// [`RayQueues::boundary`] with segment `seg`'s queue replaced by one run
    /// of `t.run` rays in every `t.every` runs, in its order, packed into its
    /// first buckets (the scheduler reads a queue as a chain, a bucket's header
    /// naming the next, and the header latency sets a root pass's pace, so a
    /// sample walks the addresses the whole pass reads first). Runs keep
    /// neighbouring rays together. The other buckets stay allocated in the
    /// pool, as rays the pass already took would sit in its children's queues.
    /// Also the rays kept. See [`Thinning`] for which run of a group is kept
    /// and where the hit records go.
    pub fn boundary_compact(
        &self,
        mem: &SparseMem,
        map: &MemoryMap,
        seg: usize,
        t: Thinning,
    ) -> (Boundary, u64) {
        let (every, run, scatter) = (t.every, t.run.max(1), t.scatter);
        let mut b = self.boundary_inner(map);
        let q = &self.queues[seg];
        if every <= 1 || q.len == 0 {
            return (b, q.len);
        }
        let (rb, hb) = (RAY_BYTES as usize, BUCKET_HEADER_BYTES as usize);
        let rpb = self.rays_per_bucket as usize;
        let mut kept = Vec::new();
        let mut bytes = vec![0u8; rpb * rb];
        let mut i = 0u64;
        let runs = q.len.div_ceil(run);
        for &bk in &q.buckets {
            let a = map.bucket_addr(bk);
            let n = BucketHeader::read(mem, a).count as usize;
            mem.read(a + hb as u64, &mut bytes[..n * rb]);
            for r in bytes[..n * rb].chunks_exact(rb) {
                if sampled_run(i / run, runs, every, scatter) {
                    kept.push(RayRec::decode(r));
                }
                i += 1;
            }
        }
        if scatter {
            return self.pack_rays(b, map, seg, kept);
        }
        // New hit indices: each run's offsets from its first pixel's pair
        // (so a ray's shadow bit keeps its parity), the runs back to back.
        let hits = (map.path - map.hits) / HIT_BYTES as u64;
        let mut idx = Vec::with_capacity(kept.len());
        let mut cursor = 0u64;
        for run in kept.chunks(COMPACT_RUN as usize) {
            let lo = run.iter().map(|r| r.hit_index() & !1).min().expect("a run");
            let hi = run.iter().map(|r| r.hit_index()).max().expect("a run");
            idx.extend(run.iter().map(|r| cursor + r.hit_index() - lo));
            cursor += (hi - lo + 2) & !1;
        }
        if cursor > hits {
            // (Runs out of pixel order spread too far: one pair each.)
            idx = kept
                .iter()
                .enumerate()
                .map(|(j, r)| 2 * j as u64 + r.is_shadow() as u64)
                .collect();
        }
        for (r, &x) in kept.iter_mut().zip(&idx) {
            let mut h = vec![0u8; HIT_BYTES as usize];
            mem.read(map.hit_addr(r.hit_index()), &mut h);
            r.ray_id = (r.ray_id & SHADOW_BIT) | (x / 2) as u32;
            debug_assert_eq!(r.hit_index(), x);
            b.writes.push((map.hit_addr(x), h));
        }
        self.pack_rays(b, map, seg, kept)
    }

    /// `b` with queue `seg` holding just `kept`, packed into its first buckets
    /// (the chain re-linked), and the rays kept.
    fn pack_rays(
        &self,
        mut b: Boundary,
        map: &MemoryMap,
        seg: usize,
        kept: Vec<RayRec>,
    ) -> (Boundary, u64) {
        let q = &self.queues[seg];
        let rpb = self.rays_per_bucket as usize;
        let m = kept.len().div_ceil(rpb);
        for (k, rays) in kept.chunks(rpb).enumerate() {
            let a = map.bucket_addr(q.buckets[k]);
            let header = BucketHeader {
                next: if k + 1 < m {
                    map.bucket_addr(q.buckets[k + 1])
                } else {
                    0
                },
                count: rays.len() as u32,
                segment: seg as u32,
            };
            let mut w = header.encode().to_vec();
            for r in rays {
                w.extend_from_slice(&r.encode());
            }
            b.writes.push((a, w));
        }
        let r = b
            .queues
            .iter_mut()
            .find(|(s, _)| *s as usize == seg)
            .expect("the queue holds rays");
        r.1.buckets = m as u32;
        r.1.rays = kept.len() as u32;
        (b, kept.len() as u64)
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
            writes: Vec::new(),
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

/// How [`RayQueues::boundary_compact`] thins a queue: one run of `run` rays in
/// every `every`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Thinning {
    pub every: u64,
    pub run: u64,
    /// `false`: the first run of each group, each run's hit records moved
    /// next to the previous run's (copied there, spacing kept), so the kept
    /// rays share hit-record lines as in the whole queue. `true`: the run a
    /// hash of the group picks ([`sampled_run`]), hit records left in place.
    pub scatter: bool,
}

impl Thinning {
    /// A root window: runs of [`COMPACT_RUN`], packed with their hit records
    /// (a root pass reads them in order).
    pub fn root(every: u64) -> Thinning {
        Thinning {
            every,
            run: COMPACT_RUN,
            scatter: false,
        }
    }

    /// A wavefront sample traced to its end: runs of `run` rays (see
    /// [`SAMPLE_RUN`]), hashed, hit records in place. Through all of a
    /// wavefront's passes the hit records' spread over DRAM rows and banks
    /// sets the row conflicts: packed into one k-th of the rows, a sample's
    /// rows stay open (its DRAM energy low); left in place in short runs, a
    /// row is opened for a few lines (high); long runs keep the rows' fill.
    /// A fixed stride would keep the same columns of every few image rows
    /// (docs/results/2026-11-26-speed-error-short-wavefronts-over-a-sample.md).
    pub fn wave(every: u64, run: u64) -> Thinning {
        Thinning {
            every,
            run,
            scatter: true,
        }
    }
}

/// Consecutive rays a compacted queue keeps together
/// ([`RayQueues::boundary_compact`]): a bounce and a shadow ray for each of
/// four pixels, the hit records of two 64 B lines.
pub const COMPACT_RUN: u64 = 8;

/// Rays in a run of a wavefront sample ([`Thinning::wave`]), at
/// most. A DRAM row holds the hit records of 256 pixels, and a bounce
/// wavefront's queue has about 1.7 rays a pixel, not in strict pixel order,
/// so shorter runs open rows for fewer lines and read too much DRAM energy
/// (docs/results/2026-11-26-speed-error-short-wavefronts-over-a-sample.md).
pub const SAMPLE_RUN: u64 = 1024;

/// Whether run `j` of `runs` is kept when one run in `every` is: the first of
/// its group of `every`, or (`scatter`) the one a hash of the group picks
/// among the group's runs (the last group may be short).
pub fn sampled_run(j: u64, runs: u64, every: u64, scatter: bool) -> bool {
    let every = every.max(1);
    let g = j / every;
    let pick = if scatter {
        // splitmix64's finaliser: a fixed, well-spread choice per group.
        super::shade::mix64(g.wrapping_add(0x9e37_79b9_7f4a_7c15))
            % every.min(runs.saturating_sub(g * every)).max(1)
    } else {
        0
    };
    j % every == pick
}

/// Lines the functional model writes for a queue of `n` rays (ray lines coalesced
/// per line, one header per bucket), `rays_per_bucket` rays per bucket.
pub fn queue_lines_written(n: u64, rays_per_bucket: u32) -> u64 {
    let rpb = rays_per_bucket as u64;
    let line = |m: u64| lines_touched(BUCKET_HEADER_BYTES as u64, m * RAY_BYTES as u64);
    let (full, rest) = (n / rpb, n % rpb);
    full * (line(rpb) + 1) + if rest > 0 { line(rest) + 1 } else { 0 }
}

/// Lines the functional model reads for a queue of `n` rays: each bucket's
/// header and rays, buckets starting on a line.
pub fn queue_lines_read(n: u64, rays_per_bucket: u32) -> u64 {
    let rpb = rays_per_bucket as u64;
    let bucket = |m: u64| lines_touched(0, BUCKET_HEADER_BYTES as u64 + m * RAY_BYTES as u64);
    let (full, rest) = (n / rpb, n % rpb);
    full * bucket(rpb) + if rest > 0 { bucket(rest) } else { 0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::MemoryMapCfg;

    /// A compacted queue read as the scheduler reads it (the header chain from
    /// the queue record's head, after the window's writes): one run of rays in
    /// k of the original, in order, on new hit records (copies of the
    /// originals) that keep their spacing within a run and follow each other.
    #[test]
    fn a_compacted_queue_holds_one_run_in_k_with_its_hit_records() {
        let map = MemoryMap::new(&MemoryMapCfg::default(), &[8192, 8192], 1, 1, 1, 4096).unwrap();
        let mut mem = SparseMem::new(map.end);
        let mut q = RayQueues::new(&map, 2);
        let rays: Vec<RayRec> = (0..1000u32)
            .map(|i| RayRec {
                origin: glam::Vec3::new(i as f32, 0.0, 0.0),
                dir: glam::Vec3::Z,
                // Pixel i or i / 2 (a bounce and a shadow ray each).
                ray_id: if i < 500 {
                    i
                } else {
                    (250 + i / 2) | ((i % 2) * SHADOW_BIT)
                },
                entry: i,
            })
            .collect();
        for r in &rays {
            let mut h = [0u8; HIT_BYTES as usize];
            h[0..4].copy_from_slice(&(r.ray_id ^ 0xabcd).to_le_bytes());
            mem.write(map.hit_addr(r.hit_index()), &h);
            q.push(&mut mem, &map, 0, r).unwrap();
        }
        q.close(&mut mem, &map, 0);
        let (b, kept) = q.boundary_compact(&mem, &map, 0, Thinning::root(7));
        let want: Vec<&RayRec> = rays
            .iter()
            .enumerate()
            .filter(|(i, _)| (*i as u64 / COMPACT_RUN).is_multiple_of(7))
            .map(|(_, r)| r)
            .collect();
        assert_eq!(kept, want.len() as u64);
        let rec = b.queues.iter().find(|(s, _)| *s == 0).unwrap().1;
        assert_eq!(
            (rec.rays as u64, rec.buckets as u64),
            (kept, kept.div_ceil(63))
        );
        let mut m = mem.clone();
        for (a, bytes) in &b.writes {
            m.write(*a, bytes);
        }
        let (mut got, mut a) = (Vec::new(), rec.head);
        while a != 0 {
            let h = BucketHeader::read(&m, a);
            assert_eq!(h.segment, 0);
            for k in 0..h.count as u64 {
                let mut r = [0u8; RAY_BYTES as usize];
                m.read(
                    a + BUCKET_HEADER_BYTES as u64 + k * RAY_BYTES as u64,
                    &mut r,
                );
                got.push(RayRec::decode(&r));
            }
            a = h.next;
        }
        assert_eq!(got.len() as u64, kept);
        for (j, (r, o)) in got.iter().zip(&want).enumerate() {
            assert_eq!(
                (r.origin, r.entry, r.is_shadow()),
                (o.origin, o.entry, o.is_shadow())
            );
            let (mut h, mut w) = ([0u8; HIT_BYTES as usize], [0u8; HIT_BYTES as usize]);
            m.read(map.hit_addr(r.hit_index()), &mut h);
            mem.read(map.hit_addr(o.hit_index()), &mut w);
            assert_eq!(h, w, "ray {j}: its hit record came along");
            if j % COMPACT_RUN as usize > 0 {
                // Within a run, the original spacing.
                let (p, q) = (&got[j - 1], &want[j - 1]);
                assert_eq!(r.hit_index() - p.hit_index(), o.hit_index() - q.hit_index());
            } else if j > 0 {
                // Runs back to back: the next free pixel.
                let p = &got[j - 1];
                assert_eq!(r.pixel(), p.pixel() + 1, "ray {j}");
            }
        }
        // Bounce and shadow rays of one pixel share it (and a line) still.
        assert!(got.windows(2).any(|w| w[0].pixel() == w[1].pixel()));
        // Every ray kept: the queue as it is, nothing written.
        let (b, kept) = q.boundary_compact(&mem, &map, 0, Thinning::root(1));
        assert!(kept == 1000 && b.writes.is_empty());
    }

    #[test]
    fn a_hashed_sample_keeps_one_run_in_each_group() {
        for (runs, every) in [(1000u64, 16u64), (37, 5), (3, 7), (64, 1)] {
            let kept: Vec<u64> = (0..runs)
                .filter(|&j| sampled_run(j, runs, every, true))
                .collect();
            // One per group, the short last group included, inside it.
            assert_eq!(kept.len() as u64, runs.div_ceil(every), "{runs} {every}");
            for (g, &j) in kept.iter().enumerate() {
                assert_eq!(j / every, g as u64, "{runs} {every}: {kept:?}");
            }
            // Not a fixed stride (which would keep the same image columns).
            if every > 2 && runs / every > 8 {
                let offsets: std::collections::HashSet<u64> =
                    kept.iter().map(|j| j % every).collect();
                assert!(offsets.len() > 2, "{runs} {every}: {kept:?}");
            }
        }
    }
}
