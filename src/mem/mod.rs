//! The memory system: a GDDR5 device and controller model, after the paper's
//! 16 x 32-bit GDDR5 at 8 Gb/s (DS17 §5.1) and the hardware reference sheet §2, 3, 5.
//!
//! - `config`: geometry, timing (DRAM cycles), mapping, queues, energy presets;
//! - `map`: address -> channel, bank group, bank, row, column;
//! - `timing`: the scheduler's earliest-legal-time state per channel;
//! - `ctrl`: one channel's controller (FR-FCFS, open page, write drain with
//!   watermarks, refresh), stepped by events; the `mem_ctrl` unit wraps it;
//! - `dramsim3`: one channel's controller under DRAMsim3's rules (transaction
//!   queues, per-bank command queues, writes acknowledged when buffered), for
//!   the `dramsim3-gddr5` preset's trace replay;
//! - `checker`: an independent timing checker over the recorded command log;
//! - `energy`, `stats`: Micron-equation energy and the statistics report;
//! - `trace`, `replay`: DRAMsim3 trace format, generators, and the in-order replay.

pub mod bench;
mod books;
pub mod checker;
pub mod config;
pub mod ctrl;
pub mod dramsim3;
pub mod energy;
mod error;
pub mod map;
pub mod replay;
pub mod stats;
pub mod timing;
pub mod trace;

pub use config::MemCfg;
pub use ctrl::ChannelCtrl;
pub use error::MemError;
pub use map::{AddrMap, Loc};
pub use stats::MemReport;
pub use timing::{Command, DramCmd};

crate::fsm_states! {
    /// Which stream a memory request belongs to, so the paper's per-stream line
    /// counts (DS17 Fig. 8) fall out of the controller.
    pub enum StreamTag { Ray, Scene, Hit, Shading, Other }
}

/// Serialises a per-stream array (indexed by [`StreamTag`]) as an object keyed
/// by stream name (`{"ray": .., "scene": .., "hit": .., "shading": .., "other": ..}`),
/// so a statistics file names what each count is.
pub fn per_stream<S: serde::Serializer>(
    v: &[u64; StreamTag::COUNT],
    s: S,
) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut m = s.serialize_map(Some(StreamTag::COUNT))?;
    for t in StreamTag::ALL {
        m.serialize_entry(t.name(), &v[t as usize])?;
    }
    m.end()
}

impl StreamTag {
    pub const COUNT: usize = 5;
    pub const ALL: [StreamTag; StreamTag::COUNT] = [
        StreamTag::Ray,
        StreamTag::Scene,
        StreamTag::Hit,
        StreamTag::Shading,
        StreamTag::Other,
    ];
    pub fn name(self) -> &'static str {
        match self {
            StreamTag::Ray => "ray",
            StreamTag::Scene => "scene",
            StreamTag::Hit => "hit",
            StreamTag::Shading => "shading",
            StreamTag::Other => "other",
        }
    }
}

crate::payload_struct! {
    /// A memory request: one line at `addr` (line aligned; low bits ignored).
    pub struct MemReq {
        pub addr: u64,
        pub write: bool,
        pub tag: StreamTag,
        /// Chosen by the requester; returned in the response.
        pub id: u32,
    }
}

crate::payload_struct! {
    /// A completed request: read data returned (the data itself lives in the
    /// chip's memory image) or write done.
    pub struct MemResp {
        pub id: u32,
        pub write: bool,
        pub tag: StreamTag,
    }
}
