//! The scheduler's registers and tables: the destination table (ray queues),
//! the working set, the admission fetch, the bucket reads and buffers, the
//! scene streams, the per-TM distribution state and the bucket pool.

use std::collections::{BTreeMap, BTreeSet, VecDeque};

use crate::contract::{QueueRec, RayRec, SegEntry};
use crate::rtl::decl::{Samples, StateDecl, StateList};
use crate::rtl::model::Behavioural;

use super::super::l1::Line;
use super::super::memory::MemLineReq;
use super::super::scene_buffer::SlotMap;

/// A shading pass being handed out: pixels `next..end` are left, `out` items were
/// forwarded and `done` of them have sent their end marker.
#[derive(Clone, Debug, Default)]
pub struct ShadePass {
    pub next: u32,
    pub end: u32,
    pub out: u64,
    pub done: u64,
}

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
    pub(super) fn fresh(chunks: u64, slots: usize, tms: usize, reads: usize) -> Self {
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
