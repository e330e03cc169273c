//! Configuration of the chip top: how many TMs and the global units' sizes and
//! latencies. Defaults are the paper's Table 1 and §5.1 where it gives a number;
//! the others are named as modelling assumptions.

use serde::{Deserialize, Serialize};

use crate::rtl::LinkCfg;
use crate::units::hit_record_updater::HitUpdaterCfg;
use crate::units::l2::L2Cfg;
use crate::units::memory::MemoryUnitCfg;
use crate::units::scene_buffer::SceneBufferCfg;
use crate::units::stream_scheduler::{MAX_STREAM_LANES, SchedulerCfg};

/// Where the shading pass between wavefronts runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Shading {
    /// On the TPs, through the TMs' global-memory ports (issue 6 stage C; the
    /// default): shading traffic and cycles are simulated.
    Tps,
    /// On the host between wavefronts, in zero cycles (stage A): only tracing is
    /// timed. Faster; the image is the same.
    Host,
}

/// Early ray termination across segments [DS17 §3, §5.4]: a ray's copies share
/// one hit record in DRAM, and reading it tells a copy that a closer hit was
/// already found elsewhere. Within a segment a ray always stops at its own hits
/// (local early termination); these read the shared record too.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EarlyTermination {
    /// No shared-record test (the paper's Table 2; the default).
    #[default]
    None,
    /// Pre-test: before a ray traverses a segment its record is read; a ray
    /// whose recorded hit is closer than its entry into the segment is dropped.
    Pre,
    /// Post-test: after a ray traverses a segment, before it is enqueued into
    /// the child segments it exits into, its record is read; exits farther
    /// than the recorded hit are not enqueued.
    Post,
    /// Both tests.
    Both,
}

impl EarlyTermination {
    pub const ALL: [EarlyTermination; 4] = [
        EarlyTermination::None,
        EarlyTermination::Pre,
        EarlyTermination::Post,
        EarlyTermination::Both,
    ];

    /// The name in the configuration and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            EarlyTermination::None => "none",
            EarlyTermination::Pre => "pre",
            EarlyTermination::Post => "post",
            EarlyTermination::Both => "both",
        }
    }

    pub fn pre(self) -> bool {
        matches!(self, EarlyTermination::Pre | EarlyTermination::Both)
    }

    pub fn post(self) -> bool {
        matches!(self, EarlyTermination::Post | EarlyTermination::Both)
    }
}

impl std::fmt::Display for EarlyTermination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The chip top.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChipCfg {
    /// Thread multiprocessors: 128 [DS17 §5.1] (TPs per TM are `tm.tps`).
    pub tms: u32,
    /// Links between the global units and the TMs.
    pub links: LinkCfg,
    /// A run with no progress for this many cycles stops with a report.
    pub watchdog_cycles: u64,
    /// The chip's memory unit: which timing model serves its lines in cycle
    /// mode (the GDDR5 of `[mem]`, or a fixed latency configured here). The
    /// image's layout is `[memory]`.
    pub memory: MemoryUnitCfg,
    pub scene_buffer: SceneBufferCfg,
    pub scheduler: SchedulerCfg,
    pub hit_updater: HitUpdaterCfg,
    pub l2: L2Cfg,
    /// `tps` (default) or `host`.
    pub shading: Shading,
    /// `none` (default), `pre`, `post` or `both`; functional mode only so far
    /// (cycle and time-sampled modes refuse another choice).
    pub early_termination: EarlyTermination,
}

impl Default for ChipCfg {
    fn default() -> Self {
        ChipCfg {
            tms: 128,
            links: LinkCfg { depth: 2, delay: 1 },
            watchdog_cycles: 200_000,
            memory: MemoryUnitCfg::default(),
            scene_buffer: SceneBufferCfg::default(),
            scheduler: SchedulerCfg::default(),
            hit_updater: HitUpdaterCfg::default(),
            l2: L2Cfg::default(),
            shading: Shading::Tps,
            early_termination: EarlyTermination::None,
        }
    }
}

impl ChipCfg {
    /// Checks the chip against itself and the segment size `segment_bytes`.
    pub fn validate(&self, segment_bytes: u32) -> Result<(), super::ConfigError> {
        if self.tms == 0 || self.tms > 4096 {
            return Err(super::ConfigError::Impossible(format!(
                "chip.tms = {}: give 1 to 4096 thread multiprocessors",
                self.tms
            )));
        }
        self.links.validate("chip.links")?;
        let d = self.links.delay;
        if self.memory.latency <= d {
            return Err(super::ConfigError::Impossible(format!(
                "chip.memory.latency = {} must exceed the response link delay ({d}, chip.links.delay), which is part of it",
                self.memory.latency
            )));
        }
        if self.memory.bytes_per_cycle < 64 {
            return Err(super::ConfigError::Impossible(format!(
                "chip.memory.bytes_per_cycle = {}: at least one 64 B line per cycle",
                self.memory.bytes_per_cycle
            )));
        }
        let sb = &self.scene_buffer;
        if sb.slot_bytes < segment_bytes {
            return Err(super::ConfigError::Impossible(format!(
                "chip.scene_buffer.slot_bytes = {} is smaller than one segment (accel.segment_bytes = {segment_bytes}); a slot must hold a whole segment",
                sb.slot_bytes
            )));
        }
        if !sb.slot_bytes.is_multiple_of(64) || sb.slots() == 0 {
            return Err(super::ConfigError::Impossible(format!(
                "chip.scene_buffer: {} B of {} B slots hold no slot; the buffer must hold at least one whole-line slot",
                sb.bytes, sb.slot_bytes
            )));
        }
        if sb.banks == 0 || !sb.banks.is_power_of_two() {
            return Err(super::ConfigError::Impossible(format!(
                "chip.scene_buffer.banks = {} must be a power of two",
                sb.banks
            )));
        }
        if sb.latency <= d {
            return Err(super::ConfigError::Impossible(format!(
                "chip.scene_buffer.latency = {} must exceed the response link delay ({d}, chip.links.delay)",
                sb.latency
            )));
        }
        let s = &self.scheduler;
        for (name, v) in [
            ("streams", s.streams),
            ("dest_entries", s.dest_entries),
            ("ray_writes_per_cycle", s.ray_writes_per_cycle),
            ("bucket_reads", s.bucket_reads),
            ("bucket_buffers", s.bucket_buffers),
            ("ray_lines_per_cycle", s.ray_lines_per_cycle),
            ("scene_lines_per_cycle", s.scene_lines_per_cycle),
        ] {
            if v == 0 {
                return Err(super::ConfigError::Impossible(format!(
                    "chip.scheduler.{name} = 0: give at least 1"
                )));
            }
        }
        for (name, v) in [
            ("ray_lines_per_cycle", s.ray_lines_per_cycle),
            ("scene_lines_per_cycle", s.scene_lines_per_cycle),
        ] {
            if v > MAX_STREAM_LANES {
                return Err(super::ConfigError::Impossible(format!(
                    "chip.scheduler.{name} = {v}: at most {MAX_STREAM_LANES} lines per cycle (one memory port each; 8 lines per cycle is already the 512 GB/s GDDR5 peak)"
                )));
            }
        }
        if s.mem_queue < 4 {
            return Err(super::ConfigError::Impossible(format!(
                "chip.scheduler.mem_queue = {}: at least 4 (one ray write may need a line, a header and a next line)",
                s.mem_queue
            )));
        }
        if self.hit_updater.queue == 0 || self.hit_updater.in_flight == 0 {
            return Err(super::ConfigError::Impossible(
                "chip.hit_updater.queue and in_flight must be at least 1".into(),
            ));
        }
        self.l2.validate(d)?;
        if self.watchdog_cycles == 0 {
            return Err(super::ConfigError::Impossible(
                "chip.watchdog_cycles = 0: give a positive number of cycles".into(),
            ));
        }
        Ok(())
    }
}
