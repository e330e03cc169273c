//! The L2's registers and arrays (`L2State`): tags, data, the miss registers
//! (MSHRs) with their address CAM, the queues towards the memory and the
//! clients, and the flush state, with the bookkeeping that keeps them in step.

use std::collections::{BTreeSet, HashMap, VecDeque};
use std::hash::{BuildHasherDefault, Hasher};

use crate::mem::StreamTag;
use crate::rtl::decl::{Samples, StateDecl, StateList};
use crate::rtl::model::Behavioural;

use crate::units::l1::Line;
use crate::units::memory::{MemLineReq, MemLineResp};

/// One cache line's tag state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct L2Tag {
    /// Line address + 1; 0 = invalid.
    pub tag: u64,
    pub dirty: bool,
    /// Last use (LRU).
    pub stamp: u64,
    /// Stream tag of the last write (for the writeback's DRAM statistics).
    pub mtag: StreamTag,
}

/// A miss register's targets (client, cycle accepted, request); its line is
/// its key in `L2State::mshr_index`.
#[derive(Clone, Debug)]
pub struct L2Mshr {
    pub targets: Vec<(u16, u64, MemLineReq)>,
}

#[derive(Clone, Debug, Default)]
pub struct L2State {
    /// Indexed by slot = set * ways + way.
    pub tags: Vec<L2Tag>,
    pub data: Vec<Line>,
    pub mshrs: Vec<Option<L2Mshr>>,
    /// The live MSHRs by line address (the MSHRs' address CAM), and a bit per
    /// free one (bit k of word k / 64): while the MSHRs are full every waiting
    /// client retries every cycle, and two scans of the MSHRs per client (is the
    /// line missing already, which one is free) were half of a shading window's
    /// time at the paper's size.
    pub mshr_index: HashMap<u64, u32, BuildHasherDefault<LineHasher>>,
    pub mshr_free: Vec<u64>,
    /// Requests towards the memory, in order.
    pub out_q: VecDeque<MemLineReq>,
    /// Lines with a request at the memory.
    pub mem_busy: BTreeSet<u64>,
    /// Writebacks in `out_q` (the writeback buffer's fill).
    pub wb_queued: u32,
    /// Per client: answers in order, with the cycle they may leave.
    pub resp_q: Vec<VecDeque<(u64, MemLineResp)>>,
    /// Bit k (of word k / 64) set while `resp_q[k]` holds an answer: the
    /// answer stage looks at those clients only, not at every client's queue.
    pub answering: Vec<u64>,
    /// Per client: requests accepted and not yet answered.
    pub outstanding: Vec<u32>,
    /// Dirty slots (the flush's priority encoder).
    pub dirty: BTreeSet<u32>,
    pub flushing: Option<bool>,
    pub stamp: u64,
}

impl L2State {
    pub(super) fn mshr_of(&self, addr: u64) -> Option<usize> {
        self.mshr_index.get(&addr).map(|&k| k as usize)
    }
    pub fn live_mshrs(&self) -> usize {
        self.mshr_index.len()
    }
    /// The lowest free MSHR.
    pub(super) fn free_mshr(&self) -> Option<usize> {
        let w = self.mshr_free.iter().position(|&w| w != 0)?;
        Some(w * 64 + self.mshr_free[w].trailing_zeros() as usize)
    }
    /// MSHR `k` takes the miss of `addr` (its register, index entry and free
    /// bit change together).
    pub(super) fn take_mshr(&mut self, k: usize, addr: u64, m: L2Mshr) {
        debug_assert!(self.mshrs[k].is_none(), "MSHR {k} is free");
        self.mshrs[k] = Some(m);
        self.mshr_index.insert(addr, k as u32);
        self.mshr_free[k / 64] &= !(1 << (k % 64));
    }
    /// Frees MSHR `k`, the miss of `addr`, and returns it.
    pub(super) fn release_mshr(&mut self, k: usize, addr: u64) -> L2Mshr {
        self.mshr_index.remove(&addr);
        self.mshr_free[k / 64] |= 1 << (k % 64);
        self.mshrs[k].take().expect("live")
    }
    /// Nothing held: no miss, no memory request, no answer, no flush.
    pub fn idle(&self) -> bool {
        self.live_mshrs() == 0
            && self.out_q.is_empty()
            && self.mem_busy.is_empty()
            && self.resp_q.iter().all(|q| q.is_empty())
            && self.flushing.is_none()
    }
}

impl Behavioural for L2State {
    fn declare(&self, out: &mut StateList) {
        // The tag, LRU and data SRAMs (8192 lines at the defaults) are memory
        // macros, left out of the skeleton like the scene buffer's data: as
        // reset register arrays they would swamp the lint tools.
        out.items
            .push(StateDecl::array("mshr_addr", 64, self.mshrs.len() as u32));
        out.items.push(StateDecl::reg("mshrs_live", 16));
        out.items.push(StateDecl::reg("mem_queued", 16));
        out.items.push(StateDecl::reg("flushing", 1));
    }
    fn sample(&self, out: &mut Samples) {
        out.slot().push(self.live_mshrs() as u64, 16);
        out.slot().push(self.out_q.len() as u64, 16);
        out.slot().push(self.flushing.is_some() as u64, 1);
    }
    fn reset(&mut self) {
        self.tags.iter_mut().for_each(|t| *t = L2Tag::default());
        self.data.iter_mut().for_each(|d| *d = Line::default());
        self.mshrs.iter_mut().for_each(|m| *m = None);
        self.mshr_index.clear();
        self.mshr_free = free_bits(self.mshrs.len());
        self.out_q.clear();
        self.mem_busy.clear();
        self.wb_queued = 0;
        self.resp_q.iter_mut().for_each(|q| q.clear());
        self.answering.iter_mut().for_each(|w| *w = 0);
        self.outstanding.iter_mut().for_each(|o| *o = 0);
        self.dirty.clear();
        self.flushing = None;
        self.stamp = 0;
    }
}

/// `n` MSHRs, all free (see `L2State::mshr_free`).
pub(super) fn free_bits(n: usize) -> Vec<u64> {
    (0..n.div_ceil(64))
        .map(|w| match n - w * 64 {
            r if r >= 64 => u64::MAX,
            r => (1u64 << r) - 1,
        })
        .collect()
}

/// Hashes a line address for `L2State::mshr_index`: the line index times an
/// odd constant (SipHash, the default, is built to resist attacks this table
/// never sees, at several times the cost).
#[derive(Clone, Copy, Debug, Default)]
pub struct LineHasher(u64);

impl Hasher for LineHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0.rotate_left(8) ^ b as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (x >> 6).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}
