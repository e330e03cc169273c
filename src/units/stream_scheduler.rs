//! The stream scheduler (paper §4.1): the working set of segments, the segment
//! streams into the scene buffer, the ray queues in DRAM, and the distribution of
//! ray buckets to the TMs' staging buffers.
//!
//! Ports:
//! - `emit` (in, `RayWrite`): new rays of a wavefront for the root segment's queue
//!   (the host's shading in stage A, the TPs' shading in stage C);
//! - `start` (in, `WaveStart`): the wavefront's rays are all emitted: close the root
//!   queue and trace;
//! - `ray_write[k]` (in): TM k's duplicates (`done` = false) and end-of-ray
//!   markers (`done` = true, sent by a TP after the ray's duplicates);
//! - `fill[k]` (out, `SbFill`): rays of a bucket into TM k's staging buffer;
//! - `slot_map` (out): a segment mapped into a scene-buffer slot;
//! - `scene_req[j]` (out): segment-stream line reads, one lane per line per
//!   cycle (`chip.scheduler.scene_lines_per_cycle` lanes); their responses go to
//!   the scene buffer's `fill[j]`, not back here;
//! - `mem_req[j]` / `mem_resp[j]`: the ray stream (bucket line writes and reads)
//!   and the segment table and child list reads (tag `other`), one lane per line
//!   per cycle each way (`chip.scheduler.ray_lines_per_cycle` lanes; a request's
//!   answer comes back on its lane).
//!
//! Policies (stage A):
//! - **Order.** Segments are admitted in increasing id among the eligible ones,
//!   which is depth-first pre-order (the data contract numbers segments so). A
//!   segment becomes eligible when its parent retires and its queue holds rays; a
//!   child with an empty queue is dropped with its whole subtree (its descendants
//!   can only get rays from it). The root is eligible when `start` arrives.
//! - **Admission** of the smallest eligible segment: its segment-table entry and
//!   child list are read (tag `other`), and its queue record once the queue has
//!   left the destination table; then it needs a free scene-buffer slot, a
//!   free stream (at most `streams` segments stream at once) and room in the
//!   destination table for all its children.
//!   It is mapped into the slot (`slot_map`) and its stream starts: one line read
//!   per `scene_req` lane per cycle, lane j serving active stream
//!   `(cycle + j) mod streams`, every line of the segment (so the scene lines
//!   equal the functional model's). A slot is reused only when its
//!   segment has retired and its stream has issued every line; late lines of an
//!   old generation are dropped by the scene buffer.
//! - **Destination table** (`dest_entries`): one entry per potential write
//!   destination, the children of the working set (paper §4.1: "the total number
//!   of children of all segments currently in the working set"), reserved at
//!   admission. When a retired parent closes a queue that holds rays, the queue's
//!   record (first bucket, bucket and ray counts; `QueueRec`) is written to DRAM
//!   (tag `other`) and its entry is freed once every write of the queue is
//!   answered; the segment waits for admission as an id in the eligible set. A
//!   segment waits for admission while its children do not fit; if nothing can
//!   free an entry (one segment with more children than entries) the chip stops
//!   with an error naming `chip.scheduler.dest_entries` (reported by the chip
//!   top, `dest_blocked`).
//! - **Queues** mirror `render/queues.rs`: buckets from a pool of row-sized chunks
//!   (a LIFO free list, lowest chunk first), a chunk per queue at a time, a bucket
//!   freed when read, a chunk when all its buckets are; a header written when a
//!   bucket is sealed (full, or its queue closed when the parent retires); a
//!   closed queue's unused buckets return at once.
//! - **Write coalescing:** each open queue has one 64 B line buffer; a ray goes
//!   into it and the line is written (a partial write of the ray bytes) when its
//!   second ray lands, when the next ray goes to another line, or when the bucket
//!   is sealed. Every line that holds a ray is written exactly once, which is the
//!   functional model's count ("a line is counted when its first ray lands").
//! - **Bucket reads:** the header line first (count and next pointer), then the
//!   other lines the rays span; the next bucket's header may be read as soon as
//!   the previous header is known. At most `bucket_reads` buckets are being read
//!   and `bucket_buffers` buckets are on chip (being read, or waiting for a TM).
//! - **Distribution:** a waiting bucket goes to the TM with no bucket in progress
//!   that has the fewest outstanding rays (handed out, end marker not back: a
//!   counter per TM), ties broken round-robin from the TM after the last one
//!   served (`next_tm`, a register that changes only when a bucket is handed
//!   out); the TM takes a waiting bucket of the segment it had last (L1 reuse,
//!   §4.1), else the oldest. Its rays go into the `fill` link one per cycle
//!   (`last` on the bucket's last ray). Shading items go out the same way when
//!   no bucket waits. (Lowest-numbered TMs first left most of a 128-TM chip idle.)
//! - **Retirement:** a working-set segment whose queue is read, whose buckets are
//!   all forwarded, and whose every forwarded ray has sent its end marker retires:
//!   its children's queues are closed (one per cycle) and those holding rays
//!   become eligible.

use std::collections::{BTreeMap, BTreeSet, VecDeque};

use super::scene_buffer::SceneBufferCfg;
use crate::contract::{
    BUCKET_HEADER_BYTES, LINE_BYTES, MemoryMap, QUEUE_REC_BYTES, QueueRec, RAY_BYTES, RayRec,
    SEG_ENTRY_BYTES, SegEntry, lines_touched,
};
use crate::mem::StreamTag;
use crate::rtl::decl::{Samples, StateDecl, StateList};
use crate::rtl::model::{Behavioural, Model};
use crate::rtl::{Ctx, In, Logic, Next, Out, Status, round_robin};
use serde::{Deserialize, Serialize};

use super::l1::Line;
use super::memory::{MemLineReq, MemLineResp};
use super::scene_buffer::{SlotMap, fill_id};
use super::staging_buffer::{SbFill, SbHeader};
use super::tp::RayWrite;
use super::tp_shade::SHADE_SEG;

/// Most memory ports one stream may have (`ray_lines_per_cycle`,
/// `scene_lines_per_cycle`).
pub const MAX_STREAM_LANES: u32 = 16;

/// The stream scheduler.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SchedulerCfg {
    /// Segments streamed into the scene buffer at once: 8 [DS17 §4.1].
    pub streams: u32,
    /// Destination table: the working set's potential write destinations (its
    /// segments' children; closed queues wait in DRAM as queue records): about a
    /// thousand [DS17 §4.1].
    pub dest_entries: u32,
    /// Ray writes (duplicates and end markers) accepted per cycle from the TMs.
    /// Assumption: 4.
    pub ray_writes_per_cycle: u32,
    /// Buckets being read from DRAM at once. Assumption: 8.
    pub bucket_reads: u32,
    /// On-chip bucket buffers (read from DRAM, not yet forwarded to a TM), at
    /// 2 KB each. Assumption: 16.
    pub bucket_buffers: u32,
    /// Line requests queued towards the memory (ray stream). Assumption: 32.
    pub mem_queue: u32,
    /// Ray-stream lines (bucket reads, coalesced bucket writes, segment info)
    /// the scheduler issues and takes answers for per cycle: one memory port
    /// (`mem_req[j]`/`mem_resp[j]`) per line. 4 (256 GB/s at 1 GHz): the paper's
    /// ray stream averages 1.8 lines per cycle (San Miguel 146.34 M lines in
    /// 79.61 ms, Crytek Sponza 80.56 M in 44.6 ms, [DS17 Table 2]), more than one
    /// port carries, and bursts at admission need more; with
    /// `scene_lines_per_cycle` the two streams can reach the GDDR5 peak of
    /// 512 GB/s = 8 lines per cycle [DS17 §5.1], so the DRAM, not the ports,
    /// limits them.
    pub ray_lines_per_cycle: u32,
    /// Scene-stream lines the scheduler issues per cycle: one memory port per
    /// line (`scene_req[j]`, answered into the scene buffer's `fill[j]`). 4: the
    /// paper's scene stream averages up to 1.3 lines per cycle (Dragon Sponza
    /// 54.31 M lines in 40.93 ms) and comes in bursts of whole segments when
    /// they are admitted; 4 + 4 lanes match the 8-line GDDR5 peak.
    pub scene_lines_per_cycle: u32,
}

impl Default for SchedulerCfg {
    fn default() -> Self {
        SchedulerCfg {
            streams: 8,
            dest_entries: 1024,
            ray_writes_per_cycle: 4,
            bucket_reads: 8,
            bucket_buffers: 16,
            mem_queue: 32,
            ray_lines_per_cycle: 4,
            scene_lines_per_cycle: 4,
        }
    }
}

crate::payload_struct! {
    /// Start wavefront `wave`: its rays are in the root queue (`shade_pixels` = 0:
    /// the host emitted them on `emit`), or the shading pass over pixels
    /// `0..shade_pixels` on the TPs emits them first.
    pub struct WaveStart {
        pub wave: u32,
        pub shade_pixels: u32,
    }
}

/// A shading pass being handed out: pixels `next..end` are left, `out` items were
/// forwarded and `done` of them have sent their end marker.
#[derive(Clone, Debug, Default)]
pub struct ShadePass {
    pub next: u32,
    pub end: u32,
    pub out: u64,
    pub done: u64,
}

const KIND_SHIFT: u32 = 28;
const K_INFO: u32 = 1;
const K_CHILD: u32 = 2;
const K_BUCKET: u32 = 3;
const K_WRITE: u32 = 4;
const K_QREC: u32 = 5;

/// One ray queue (a destination table entry).
#[derive(Clone, Debug, Default)]
pub struct QueueDesc {
    /// Address of the first unread bucket (0: none).
    pub head: u64,
    /// Pool index of the open (last) bucket.
    pub tail: u64,
    pub has_tail: bool,
    pub tail_count: u32,
    pub len: u64,
    pub buckets: u64,
    /// Unused buckets of this queue's chunk (taken from the back).
    pub chunk_left: Vec<u64>,
    /// The line being coalesced: (line address, bytes, byte mask).
    pub line: Option<(u64, Line, u64)>,
    pub writes_in_flight: u32,
    pub closed: bool,
}

/// A segment in the working set.
#[derive(Clone, Debug)]
pub struct WsEntry {
    pub seg: u32,
    pub slot: u16,
    pub entry: SegEntry,
    pub children: Vec<u32>,
    /// Next bucket to read (0: none left, or its address is not known yet).
    pub head: u64,
    pub buckets_left: u64,
    /// A header read of this queue is in flight (the next address is unknown).
    pub header_pending: bool,
    /// Buckets being read, waiting, or being forwarded.
    pub buckets_on_chip: u32,
    pub rays_fwd: u64,
    pub rays_done: u64,
}

/// Segment info being fetched for admission.
#[derive(Clone, Debug)]
pub struct Fetch {
    pub seg: u32,
    pub entry: Option<SegEntry>,
    pub child_lines: Vec<Option<Line>>,
    pub children: Option<Vec<u32>>,
    /// The queue record was asked for (once the queue has left the table).
    pub rec_asked: bool,
    pub rec: Option<QueueRec>,
}

#[derive(Clone, Debug)]
pub struct BucketRead {
    pub seg: u32,
    pub addr: u64,
    pub count: u32,
    pub lines: u32,
    pub got: u32,
    pub bytes: Vec<u8>,
}

#[derive(Clone, Debug)]
pub struct Stream {
    pub slot: u16,
    pub generation: u8,
    pub base: u64,
    pub lines: u32,
    pub next: u32,
}

#[derive(Clone, Debug, Default)]
pub struct TmFwd {
    /// (segment, rays, next position)
    pub cur: Option<(u32, Vec<RayRec>, usize)>,
    pub last_seg: Option<u32>,
    /// Rays and shading items handed to this TM whose end marker has not come
    /// back yet (a counter per TM: what the distribution balances).
    pub outstanding: u32,
}

/// Everything the scheduler holds.
#[derive(Clone, Debug, Default)]
pub struct SchedState {
    pub dest: BTreeMap<u32, QueueDesc>,
    /// Children of working-set segments without a queue yet: child -> parent.
    pub reserved: BTreeMap<u32, u32>,
    pub eligible: BTreeSet<u32>,
    pub fetch: Option<Fetch>,
    pub ws: Vec<WsEntry>,
    pub slot_free: Vec<bool>,
    pub slot_gen: Vec<u8>,
    pub slot_streaming: Vec<bool>,
    pub streams: Vec<Stream>,
    pub reads: Vec<Option<BucketRead>>,
    pub ready: VecDeque<(u32, Vec<RayRec>)>,
    pub tms: Vec<TmFwd>,
    /// Round-robin pointer of the distribution: the TM after the one that got
    /// the last bucket (changes only when a bucket is handed out).
    pub next_tm: u32,
    pub out: VecDeque<MemLineReq>,
    pub closing: VecDeque<u32>,
    pub pending_map: Option<SlotMap>,
    pub shade: Option<ShadePass>,
    // bucket pool
    pub free_chunks: Vec<u64>,
    pub chunk_live: Vec<u8>,
    pub live_buckets: u64,
    pub peak_buckets: u64,
    pub error: Option<String>,
    pub dest_blocked: bool,
    /// Declared sizes (for the Verilog arrays).
    pub cap_dest: u32,
    pub cap_streams: u32,
}

impl Behavioural for SchedState {
    fn declare(&self, out: &mut StateList) {
        out.items.push(StateDecl::reg("working_set", 8));
        out.items.push(StateDecl::reg("streams_active", 8));
        out.items.push(StateDecl::reg("queues", 16));
        out.items.push(StateDecl::reg("buckets_ready", 8));
        out.items.push(StateDecl::reg("mem_queued", 8));
        out.items.push(StateDecl::reg("next_eligible", 32));
        out.items.push(StateDecl::reg("next_tm", 16));
        // Destination table entry: head and tail pointers, counts, line buffer mask.
        out.items
            .push(StateDecl::array("dest_table", 224, self.cap_dest.max(1)));
        // Stream: slot, generation, base, lines, next line.
        out.items.push(StateDecl::array(
            "stream_table",
            16 + 8 + 64 + 32 + 32,
            self.cap_streams.max(1),
        ));
    }
    fn sample(&self, out: &mut Samples) {
        out.slot().push(self.ws.len() as u64, 8);
        out.slot().push(self.streams.len() as u64, 8);
        out.slot().push(self.dest.len() as u64, 16);
        out.slot().push(self.ready.len() as u64, 8);
        out.slot().push(self.out.len() as u64, 8);
        out.slot()
            .push(self.eligible.first().map_or(u32::MAX, |&s| s) as u64, 32);
        out.slot().push(self.next_tm as u64, 16);
    }
    fn reset(&mut self) {
        // Rebuilt by the owner (`StreamScheduler::fresh_state`) at construction;
        // a reset between frames keeps the pool geometry.
        let chunks = self.chunk_live.len() as u64;
        let slots = self.slot_free.len();
        let tms = self.tms.len();
        let reads = self.reads.len();
        let (d, st) = (self.cap_dest, self.cap_streams);
        *self = SchedState::fresh(chunks, slots, tms, reads);
        self.cap_dest = d;
        self.cap_streams = st;
    }
}

impl SchedState {
    fn fresh(chunks: u64, slots: usize, tms: usize, reads: usize) -> Self {
        SchedState {
            slot_free: vec![true; slots],
            slot_gen: vec![0; slots],
            slot_streaming: vec![false; slots],
            reads: vec![None; reads],
            tms: vec![TmFwd::default(); tms],
            free_chunks: (0..chunks).rev().collect(),
            chunk_live: vec![0; chunks as usize],
            ..SchedState::default()
        }
    }
}

crate::unit! {
    /// Stream scheduler: working set, segment streams, ray queues, bucket distribution.
    pub struct StreamScheduler : "stream_scheduler" {
        params {
            tms_n: u32 => "TMS",
            streams_n: u32 => "STREAMS",
            slots_n: u32 => "SLOTS",
            dest_entries: u32 => "DEST_ENTRIES",
            writes_per_cycle: u32 => "WRITES_PER_CYCLE",
            bucket_buffers: u32 => "BUCKET_BUFFERS",
            mem_queue: u32 => "MEM_QUEUE",
            ray_lanes: u32 => "RAY_LINES_PER_CYCLE",
            scene_lanes: u32 => "SCENE_LINES_PER_CYCLE"
        }
        inputs { emit: RayWrite, start: WaveStart }
        outputs { slot_map: SlotMap }
        in_arrays { ray_write: RayWrite, mem_resp: MemLineResp }
        out_arrays { fill: SbFill, mem_req: MemLineReq, scene_req: MemLineReq }
        state { st: Model<SchedState> }
        extra {
            map: MemoryMap,
            rays_per_bucket: u32,
            per_chunk: u64,

            pub_enqueued: Vec<u64>,
            pub_done: Vec<u64>,
            last_shade_end: u64,
            // First pixel of the next shading pass (0 but in a sampling window,
            // `Chip::trace_window`): simulation control, not hardware.
            shade_first: u32,
            // Cycle the last end marker (a ray's or a shading item's) arrived:
            // the chip's last finished work, for the drain figure.
            last_marker: u64,
            root_log: Option<Vec<RayRec>>,
            // Admission and retirement of every segment pass (`--pass-log`): a
            // probe, not hardware. Admission cycles of the working set by segment.
            pass_log: Option<(BTreeMap<u32, u64>, Vec<PassEvent>)>,
            tm_rays: Vec<u64>,
            stats: SchedStats,
            // Scratch: the TMs with a visible ray write this cycle.
            visible: Vec<u64>
        }
    }
}

/// One segment pass as the scheduler saw it (`--pass-log`): admitted (slot
/// taken) and retired (every ray's end marker back) at these core cycles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct PassEvent {
    pub seg: u32,
    pub rays: u64,
    pub admit: u64,
    pub retire: u64,
}

/// Event counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SchedStats {
    pub segments_loaded: u64,
    pub scene_lines: u64,
    pub enqueues: u64,
    pub markers: u64,
    pub buckets_written: u64,
    pub buckets_read: u64,
    pub buckets_forwarded: u64,
    pub rays_forwarded: u64,
    pub same_segment_picks: u64,
    pub retired: u64,
    pub skipped_children: u64,
    /// Shading work items forwarded and finished (end markers).
    pub shade_items: u64,
    pub shade_done: u64,
    /// Most ray-stream (`mem_req`) and scene-stream (`scene_req`) lines issued in
    /// one cycle (at most the lanes).
    pub ray_lines_peak: u64,
    pub scene_lines_peak: u64,
}

impl StreamScheduler {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        cfg: &SchedulerCfg,
        sb: &SceneBufferCfg,
        map: &MemoryMap,
        segments: usize,
        emit: In<RayWrite>,
        start: In<WaveStart>,
        mem_resp: Vec<In<MemLineResp>>,
        slot_map: Out<SlotMap>,
        scene_req: Vec<Out<MemLineReq>>,
        mem_req: Vec<Out<MemLineReq>>,
        ray_write: Vec<In<RayWrite>>,
        fill: Vec<Out<SbFill>>,
    ) -> Self {
        assert_eq!(
            mem_req.len(),
            mem_resp.len(),
            "one memory response lane per request lane"
        );
        let per_chunk = map.row_bytes / map.bucket_bytes;
        let chunks = map.bucket_count / per_chunk;
        let tms = fill.len();
        StreamScheduler {
            tms_n: tms as u32,
            streams_n: cfg.streams,
            slots_n: sb.slots(),
            dest_entries: cfg.dest_entries,
            writes_per_cycle: cfg.ray_writes_per_cycle,
            bucket_buffers: cfg.bucket_buffers,
            mem_queue: cfg.mem_queue,
            ray_lanes: mem_req.len() as u32,
            scene_lanes: scene_req.len() as u32,
            emit,
            start,
            mem_resp: mem_resp.into(),
            slot_map,
            scene_req: scene_req.into(),
            mem_req: mem_req.into(),
            ray_write: ray_write.into(),
            fill: fill.into(),
            st: Model::new(SchedState {
                cap_dest: cfg.dest_entries,
                cap_streams: cfg.streams,
                ..SchedState::fresh(chunks, sb.slots() as usize, tms, cfg.bucket_reads as usize)
            }),
            map: map.clone(),
            rays_per_bucket: ((map.bucket_bytes - BUCKET_HEADER_BYTES as u64) / RAY_BYTES as u64)
                as u32,
            per_chunk,
            pub_enqueued: vec![0; segments],
            pub_done: vec![0; segments],
            last_shade_end: 0,
            shade_first: 0,
            last_marker: 0,
            root_log: None,
            pass_log: None,
            tm_rays: vec![0; tms],
            stats: SchedStats::default(),
            visible: Vec::new(),
        }
    }

    /// Nothing left to do (wavefront finished, every request answered).
    pub fn idle(&self) -> bool {
        let s = self.st.r();
        s.dest.is_empty()
            && s.eligible.is_empty()
            && s.fetch.is_none()
            && s.ws.is_empty()
            && s.streams.is_empty()
            && s.reads.iter().all(|r| r.is_none())
            && s.ready.is_empty()
            && s.tms.iter().all(|t| t.cur.is_none())
            && s.out.is_empty()
            && s.closing.is_empty()
            && s.pending_map.is_none()
            && s.shade.is_none()
    }

    /// What it holds, for the watchdog.
    pub fn holding(&self) -> String {
        let s = self.st.r();
        let ws: Vec<String> =
            s.ws.iter()
                .map(|w| {
                    format!(
                        "seg {} (fwd {}, done {}, buckets left {}, on chip {})",
                        w.seg, w.rays_fwd, w.rays_done, w.buckets_left, w.buckets_on_chip
                    )
                })
                .collect();
        format!(
            "{}working set [{}], eligible {:?}, fetching {:?}, queues {}, streams {}, bucket reads {}, ready buckets {}, TMs forwarding {}, memory queue {}, closing {}{}",
            s.shade.as_ref().map_or(String::new(), |p| format!(
                "shading pass (pixels {}..{} left, items out {}, done {}), ",
                p.next, p.end, p.out, p.done
            )),
            ws.join(", "),
            s.eligible.iter().take(8).collect::<Vec<_>>(),
            s.fetch.as_ref().map(|f| f.seg),
            s.dest.len(),
            s.streams.len(),
            s.reads.iter().filter(|r| r.is_some()).count(),
            s.ready.len(),
            s.tms.iter().filter(|t| t.cur.is_some()).count(),
            s.out.len(),
            s.closing.len(),
            if s.dest_blocked {
                " (admission waits for the destination table)"
            } else {
                ""
            }
        )
    }

    pub fn error(&self) -> Option<&str> {
        self.st.r().error.as_deref()
    }
    pub fn dest_blocked(&self) -> bool {
        self.st.r().dest_blocked
    }
    pub fn stats(&self) -> SchedStats {
        self.stats
    }
    /// Rays handed to each TM (cumulative; shading items not counted).
    pub fn tm_rays(&self) -> &[u64] {
        &self.tm_rays
    }
    pub fn live_buckets(&self) -> u64 {
        self.st.r().live_buckets
    }
    /// Records every ray written into the root queue (for `--verify`; a probe
    /// on the ray writes, not hardware).
    pub fn enable_root_log(&mut self) {
        self.root_log = Some(Vec::new());
    }
    /// Records every segment pass: admission, retirement, rays (a probe).
    pub fn enable_pass_log(&mut self) {
        self.pass_log = Some(Default::default());
    }
    /// The passes retired since the last call, in retirement order.
    pub fn take_pass_log(&mut self) -> Vec<PassEvent> {
        self.pass_log
            .as_mut()
            .map(|(_, v)| std::mem::take(v))
            .unwrap_or_default()
    }
    pub fn take_root_log(&mut self) -> Vec<RayRec> {
        self.root_log
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default()
    }

    /// Takes a wavefront over between two segments (`Chip::trace_window`): the
    /// queues that hold rays become eligible (their records are in DRAM, so they are
    /// read at admission as for any queue that left the destination table) and the
    /// bucket pool is the one that laid them out. Only on a fresh scheduler.
    pub fn resume(&mut self, b: &crate::contract::Boundary) {
        assert!(self.idle(), "resume on an idle scheduler");
        assert_eq!(
            b.chunk_live.len(),
            self.st.r().chunk_live.len(),
            "the same bucket pool"
        );
        let st = self.st.m();
        st.eligible = b.queues.iter().map(|&(s, _)| s).collect();
        st.free_chunks = b.free_chunks.clone();
        st.chunk_live = b.chunk_live.clone();
        st.live_buckets = b.live_buckets;
        crate::rtl::State::commit(&mut self.st);
    }

    /// A sampling window's shading pass starts at pixel `first` (see `shade_first`).
    pub fn shade_from(&mut self, first: u32) {
        self.shade_first = first;
    }

    /// Clears the per-segment wavefront counts.
    pub fn new_wave(&mut self) {
        self.pub_enqueued.iter_mut().for_each(|x| *x = 0);
        self.pub_done.iter_mut().for_each(|x| *x = 0);
    }

    /// The free TM (no bucket in progress) with the fewest outstanding rays,
    /// the first from `next_tm` on a tie.
    fn pick_tm(&self) -> Option<usize> {
        let s = self.st.r();
        let n = s.tms.len();
        let mut best: Option<(u32, usize)> = None;
        for j in 0..n {
            let k = (s.next_tm as usize + j) % n;
            let t = &s.tms[k];
            if t.cur.is_none() && best.is_none_or(|(o, _)| t.outstanding < o) {
                best = Some((t.outstanding, k));
            }
        }
        best.map(|(_, k)| k)
    }

    fn out_room(&self) -> usize {
        (self.mem_queue as usize).saturating_sub(self.st.r().out.len())
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

    fn free_bucket(st: &mut SchedState, per_chunk: u64, b: u64) {
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

    /// One memory answer (ray-stream line, segment info, write done).
    fn answer(&mut self, r: MemLineResp) {
        let kind = r.id >> KIND_SHIFT;
        let low = r.id & ((1 << KIND_SHIFT) - 1);
        match kind {
            K_WRITE => {
                let st = self.st.m();
                if let Some(q) = st.dest.get_mut(&low) {
                    q.writes_in_flight -= 1;
                    if q.closed && q.writes_in_flight == 0 {
                        // Its record is in DRAM: the entry is free.
                        st.dest.remove(&low);
                    }
                }
            }
            K_QREC => {
                let st = self.st.m();
                let f = st.fetch.as_mut().expect("fetch in progress");
                let off = (self.map.queue_rec_addr(f.seg) % LINE_BYTES) as usize;
                f.rec = Some(QueueRec::decode(
                    &r.data.0[off..off + QUEUE_REC_BYTES as usize],
                ));
            }
            K_INFO => {
                let st = self.st.m();
                let f = st.fetch.as_mut().expect("fetch in progress");
                let off = (self.map.seg_entry_addr(f.seg) % LINE_BYTES) as usize;
                let e = seg_entry_from_line(&r.data, off);
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
            K_CHILD => {
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
            K_BUCKET => {
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
                    st.ready.push_back((rd.seg, rays));
                    self.stats.buckets_read += 1;
                }
            }
            _ => unreachable!("unknown memory id {:#x}", r.id),
        }
    }

    /// Accepts a duplicate or a marker.
    fn accept_write(&mut self, w: &RayWrite, tm: Option<usize>) {
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
    }
}

fn seg_entry_from_line(l: &Line, off: usize) -> SegEntry {
    let u64_at = |o: usize| u64::from_le_bytes(l.0[o..o + 8].try_into().expect("8 bytes"));
    SegEntry {
        base: u64_at(off),
        bytes: l.u32_at(off + 8),
        nodes: l.u32_at(off + 12),
        tris: l.u32_at(off + 16),
        parent: l.u32_at(off + 20),
        first_child: l.u32_at(off + 24),
        child_count: l.u32_at(off + 28),
    }
}

impl Logic for StreamScheduler {
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        let c = ctx.cycle();
        if self.st.r().error.is_some() {
            ctx.set_status(Status::WaitInput);
            return Next::Idle;
        }
        let mut worked = false;

        // 1. Memory answers: one per lane.
        for j in 0..self.mem_resp.len() {
            if let Some(r) = ctx.pop(&self.mem_resp.at(j)) {
                self.answer(r);
                worked = true;
            }
        }

        // 2. Wave start: close the root queue, make it eligible.
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
        // 2b. The shading pass is over when every item handed out has sent its end
        // marker (after its rays, on the same path): the root queue is complete.
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

        // 3. Ray writes: up to `writes_per_cycle`, TMs round-robin, then `emit`.
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
            self.accept_write(&w, src);
            taken += 1;
            worked = true;
        }
        self.visible = visible;

        // 4. Closing the children of retired segments, one per cycle.
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

        // 5. Admission: fetch the smallest eligible segment's info, then admit it.
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
        // The queue record, once the queue's writes (the record's too) are answered.
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
        if let Some(pm) = self.st.r().pending_map.clone()
            && ctx.can_push(&self.slot_map)
        {
            ctx.push(&self.slot_map, pm);
            self.st.m().pending_map = None;
            worked = true;
        }
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
                return Next::Idle;
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

        // 6. Segment streams: one scene line per lane per cycle
        // (`scene_lines_per_cycle`), lane j serving stream (cycle + j) mod streams.
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

        // 7. Bucket reads: start the next bucket of a working-set queue.
        {
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
        }

        // 8. Memory requests in queue order, one per lane per cycle
        // (`ray_lines_per_cycle`).
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

        // 9. Distribution to the TMs' staging buffers: each waiting bucket (or,
        // when none waits, a bucket's worth of shading items) goes to the free TM
        // (no bucket in progress) with the fewest outstanding rays, ties broken
        // round-robin from `next_tm`.
        loop {
            let shade_left = self.st.r().shade.as_ref().is_some_and(|p| p.next < p.end);
            if self.st.r().ready.is_empty() && !shade_left {
                break;
            }
            let Some(k) = self.pick_tm() else { break };
            let st = self.st.m();
            st.next_tm = ((k + 1) % n) as u32;
            if st.ready.is_empty() {
                // Shading items (pixels, a bucket's worth at a time).
                let rpb = self.rays_per_bucket;
                let p = st.shade.as_mut().expect("shading");
                let m = rpb.min(p.end - p.next);
                let items = (p.next..p.next + m)
                    .map(|pix| RayRec {
                        origin: glam::Vec3::ZERO,
                        dir: glam::Vec3::ZERO,
                        ray_id: pix,
                        entry: 0,
                    })
                    .collect();
                p.next += m;
                p.out += m as u64;
                self.stats.shade_items += m as u64;
                st.tms[k].outstanding += m;
                st.tms[k].cur = Some((SHADE_SEG, items, 0));
            } else {
                // A bucket of the segment the TM had last (L1 reuse, §4.1), else
                // the oldest.
                let last = st.tms[k].last_seg;
                let pick = last
                    .and_then(|s| st.ready.iter().position(|(rs, _)| *rs == s))
                    .inspect(|_| self.stats.same_segment_picks += 1)
                    .unwrap_or(0);
                let (seg, rays) = st.ready.remove(pick).expect("picked");
                let w = st.ws.iter_mut().find(|w| w.seg == seg).expect("ws");
                w.rays_fwd += rays.len() as u64;
                self.stats.buckets_forwarded += 1;
                self.tm_rays[k] += rays.len() as u64;
                st.tms[k].outstanding += rays.len() as u32;
                st.tms[k].cur = Some((seg, rays, 0));
                st.tms[k].last_seg = Some(seg);
            }
            worked = true;
        }
        for k in 0..n {
            let shade_item = self.st.r().tms[k]
                .cur
                .as_ref()
                .is_some_and(|c| c.0 == SHADE_SEG);
            if shade_item && ctx.can_push(&self.fill.at(k)) {
                let st = self.st.m();
                let hdr = SbHeader {
                    seg: SHADE_SEG,
                    base: 0,
                    nodes: 0,
                };
                let (_, items, pos) = st.tms[k].cur.as_mut().expect("cur");
                let last = *pos + 1 == items.len();
                let ray = items[*pos];
                *pos += 1;
                if last {
                    st.tms[k].cur = None;
                }
                ctx.push(&self.fill.at(k), SbFill { ray, hdr, last });
                worked = true;
            } else if self.st.r().tms[k].cur.is_some() && ctx.can_push(&self.fill.at(k)) {
                let st = self.st.m();
                let seg = st.tms[k].cur.as_ref().expect("cur").0;
                let w = st.ws.iter_mut().find(|w| w.seg == seg).expect("ws");
                let hdr = SbHeader {
                    seg,
                    base: w.entry.base,
                    nodes: w.entry.nodes,
                };
                let (_, rays, pos) = st.tms[k].cur.as_mut().expect("cur");
                let last = *pos + 1 == rays.len();
                let ray = rays[*pos];
                *pos += 1;
                if last {
                    st.tms[k].cur = None;
                    w.buckets_on_chip -= 1;
                }
                ctx.push(&self.fill.at(k), SbFill { ray, hdr, last });
                self.stats.rays_forwarded += 1;
                worked = true;
            }
        }

        // 10. Retirement (one per cycle): queue read, buckets forwarded, rays done.
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

        ctx.set_status(if worked {
            Status::Busy
        } else if self.idle() {
            Status::WaitInput
        } else {
            Status::ResourceBusy
        });
        // Nothing changed: nothing will until an input arrives or an output drains.
        if worked { Next::Cycle } else { Next::Idle }
    }

    fn counters(&self) -> Vec<(&'static str, u64)> {
        let s = &self.stats;
        vec![
            ("segments_loaded", s.segments_loaded),
            ("scene_lines", s.scene_lines),
            ("enqueues", s.enqueues),
            ("markers", s.markers),
            ("buckets_written", s.buckets_written),
            ("buckets_read", s.buckets_read),
            ("buckets_forwarded", s.buckets_forwarded),
            ("rays_forwarded", s.rays_forwarded),
            ("same_segment_picks", s.same_segment_picks),
            ("retired", s.retired),
            ("skipped_children", s.skipped_children),
            ("shade_items", s.shade_items),
            ("shade_done", s.shade_done),
            ("ray_lines_peak", s.ray_lines_peak),
            ("scene_lines_peak", s.scene_lines_peak),
        ]
    }

    fn reset_counters(&mut self) {
        self.stats = SchedStats::default();
        self.tm_rays.iter_mut().for_each(|x| *x = 0);
    }
}
