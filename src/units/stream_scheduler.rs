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
//!
//! This file holds the unit's declaration (the Verilog header names it), its
//! configuration and `eval`, a list of named steps; the steps live by concern
//! in `stream_scheduler/`: `state` (the registers and tables), `queues` (the ray
//! queues and the bucket pool), `working_set` (admission and retirement),
//! `streams` (the scene stream, the ray stream and the memory answers),
//! `distribute` (buckets and shading items to the TMs).

mod distribute;
mod queues;
mod state;
mod streams;
mod working_set;

use std::collections::BTreeMap;

use super::scene_buffer::SceneBufferCfg;
use crate::contract::{BUCKET_HEADER_BYTES, MemoryMap, RAY_BYTES, RayRec};
use crate::rtl::model::Model;
use crate::rtl::{Ctx, LinkId, Logic, Next, Ready, Status};
use serde::{Deserialize, Serialize};

use super::memory::{MemLineReq, MemLineResp};
use super::scene_buffer::SlotMap;
use super::staging_buffer::SbFill;
use super::tp::RayWrite;

pub use state::{BucketRead, Fetch, QueueDesc, SchedState, ShadePass, Stream, TmFwd, WsEntry};

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

// Memory request ids: the kind in the top bits, then its own fields.
const KIND_SHIFT: u32 = 28;
const K_INFO: u32 = 1;
const K_CHILD: u32 = 2;
const K_BUCKET: u32 = 3;
const K_WRITE: u32 = 4;
const K_QREC: u32 = 5;

crate::unit! {
    /// Stream scheduler: working set, segment streams, ray queues, bucket distribution.
    pub struct StreamScheduler : "stream_scheduler" {
        /// For `segments` segments of the scene laid out by `map`.
        new(
            cfg: &SchedulerCfg,
            sb: &SceneBufferCfg,
            map: &MemoryMap,
            segments: usize;
            ports: StreamSchedulerPorts
        ) {
            assert_eq!(
                mem_req.len(),
                mem_resp.len(),
                "one memory response lane per request lane"
            );
            let per_chunk = map.row_bytes / map.bucket_bytes;
            let chunks = map.bucket_count / per_chunk;
            let tms = fill.len();
        }
        params {
            tms_n: u32 = tms as u32 => "TMS",
            streams_n: u32 = cfg.streams => "STREAMS",
            slots_n: u32 = sb.slots() => "SLOTS",
            dest_entries: u32 = cfg.dest_entries => "DEST_ENTRIES",
            writes_per_cycle: u32 = cfg.ray_writes_per_cycle => "WRITES_PER_CYCLE",
            bucket_buffers: u32 = cfg.bucket_buffers => "BUCKET_BUFFERS",
            mem_queue: u32 = cfg.mem_queue => "MEM_QUEUE",
            ray_lanes: u32 = mem_req.len() as u32 => "RAY_LINES_PER_CYCLE",
            scene_lanes: u32 = scene_req.len() as u32 => "SCENE_LINES_PER_CYCLE"
        }
        inputs { emit: RayWrite, start: WaveStart }
        outputs { slot_map: SlotMap }
        in_arrays { ray_write: RayWrite, mem_resp: MemLineResp }
        out_arrays { fill: SbFill, mem_req: MemLineReq, scene_req: MemLineReq }
        state {
            st: Model<SchedState> = SchedState {
                cap_dest: cfg.dest_entries,
                cap_streams: cfg.streams,
                ..SchedState::fresh(chunks, sb.slots() as usize, tms, cfg.bucket_reads as usize)
            }
        }
        extra {
            map: MemoryMap = map.clone(),
            rays_per_bucket: u32 =
                ((map.bucket_bytes - BUCKET_HEADER_BYTES as u64) / RAY_BYTES as u64) as u32,
            per_chunk: u64 = per_chunk,

            pub_enqueued: Vec<u64> = vec![0; segments],
            pub_done: Vec<u64> = vec![0; segments],
            last_shade_end: u64 = 0,
            // First pixel of the next shading pass (0 but in a sampling window,
            // `Chip::trace_window`): simulation control, not hardware.
            shade_first: u32 = 0,
            // Cycle the last end marker (a ray's or a shading item's) arrived:
            // the chip's last finished work, for the drain figure.
            last_marker: u64 = 0,
            root_log: Option<Vec<RayRec>> = None,
            // Admission and retirement of every segment pass (`--pass-log`): a
            // probe, not hardware. Admission cycles of the working set by segment.
            pass_log: Option<(BTreeMap<u32, u64>, Vec<PassEvent>)> = None,
            tm_rays: Vec<u64> = vec![0; tms],
            stats: SchedStats = SchedStats::default(),
            // `--follow-ray`: a probe, not hardware (`units/follow.rs`).
            follow: Option<super::follow::Follower> = None,
            // Scratch: the TMs with a visible ray write this cycle.
            visible: Vec<u64> = Vec::new()
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
    /// Logs the followed rays' events here (`units/follow.rs`).
    pub fn follow(&mut self, f: super::follow::Follower) {
        self.follow = Some(f);
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

    fn out_room(&self) -> usize {
        (self.mem_queue as usize).saturating_sub(self.st.r().out.len())
    }
}

impl Logic for StreamScheduler {
    /// Nothing after an error. The memory answers always; a wave start and
    /// the ray writes while the memory request queue has room for what they
    /// may queue (a write for a segment not in the destination table also
    /// needs a free entry: its segment decides).
    fn can_accept(&self, port: LinkId, _at: &Ready) -> bool {
        if self.st.r().error.is_some() {
            return false;
        }
        self.mem_resp.index_of(port).is_some() || self.out_room() >= 3
    }

    /// One cycle, in this order (each step sees what the ones before it did).
    fn eval(&mut self, ctx: &mut Ctx) -> Next {
        if self.st.r().error.is_some() {
            ctx.set_status(Status::WaitInput);
            return Next::Idle;
        }
        let mut worked = false;
        worked |= self.take_mem_answers(ctx);
        worked |= self.start_wave(ctx);
        worked |= self.end_shade_pass(ctx);
        worked |= self.take_ray_writes(ctx);
        worked |= self.close_child();
        worked |= self.fetch_segment_info();
        worked |= self.fetch_queue_record();
        worked |= self.send_slot_map(ctx);
        let Some(admitted) = self.admit(ctx) else {
            return Next::Idle; // stopped: the destination table can never fit it
        };
        worked |= admitted;
        worked |= self.stream_scene(ctx);
        worked |= self.start_bucket_read();
        worked |= self.issue_ray_stream(ctx);
        worked |= self.hand_out(ctx.cycle());
        worked |= self.fill_staging_buffers(ctx);
        worked |= self.retire(ctx);

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

/// What the chip top reads of the scheduler after (or during) a run: its event
/// counters and the cycles of the last finished work. A probe, not hardware:
/// the scheduler's internals can change without the chip top changing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SchedulerProbe {
    pub stats: SchedStats,
    /// Cycle the last shading pass ended (its last item's end marker).
    pub last_shade_end: u64,
    /// Cycle the last end marker (a ray's or a shading item's) arrived.
    pub last_marker: u64,
}

impl StreamScheduler {
    /// The counters and last-work cycles (see [`SchedulerProbe`]).
    pub fn probe(&self) -> SchedulerProbe {
        SchedulerProbe {
            stats: self.stats,
            last_shade_end: self.last_shade_end,
            last_marker: self.last_marker,
        }
    }
    /// Rays finished (end markers) in this wavefront, by segment (cleared by
    /// `new_wave`). A slice, not a copy: sampling windows look at it every
    /// few cycles.
    pub fn done_by_segment(&self) -> &[u64] {
        &self.pub_done
    }
    /// Rays enqueued in this wavefront, by segment (cleared by `new_wave`).
    pub fn enqueued_by_segment(&self) -> &[u64] {
        &self.pub_enqueued
    }
    /// The memory map the scheduler lays its queues out by.
    pub fn memory_map(&self) -> &MemoryMap {
        &self.map
    }
    /// Destination table entries (`chip.scheduler.dest_entries`).
    pub fn dest_entries(&self) -> u32 {
        self.dest_entries
    }
}
