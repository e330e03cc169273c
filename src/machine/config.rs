//! Configuration of the chip top: how many TMs and the global units' sizes and
//! latencies. Defaults are the paper's Table 1 and §5.1 where it gives a number;
//! the others are named as modelling assumptions.

use serde::{Deserialize, Serialize};

use crate::rtl::LinkCfg;

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

/// Which timing model serves the memory unit's lines.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MemoryModel {
    /// Fixed latency and a bandwidth limit (the "simple memory" switch of the
    /// paper group's simulator): an explicit choice (`--memory fixed`) for
    /// tests and quick looks; it misses the DRAM's row and bank effects
    /// (docs/speed-error.md measures what that costs).
    Fixed,
    /// The memory unit routes every line by the address mapping (`mem.mapping`)
    /// to one `mem_ctrl` unit per channel (`mem.geometry.channels`, 16) on the
    /// DRAM clock (`clocks.dram_ps`): timing, bandwidth, row hits and energy come
    /// from the GDDR5 model (`[mem]`), data from the DRAM image. The default:
    /// the paper's memory system [DS17 Table 1, §5.1] ("a full memory
    /// simulator is essential"); `latency` and `bytes_per_cycle` are then unused.
    Gddr5,
}

/// The memory unit (DRAM image + timing).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MemoryUnitCfg {
    pub model: MemoryModel,
    /// `fixed`: cycles from acceptance of a line request to its response being
    /// visible to the requester (response link included). Assumption: 100 core
    /// cycles, a loaded GDDR5 access at 1 GHz.
    pub latency: u32,
    /// `fixed`: peak bandwidth in bytes per core cycle: 512 GB/s at 1 GHz
    /// [DS17 §5.1] = 512 B = 8 lines per cycle.
    pub bytes_per_cycle: u32,
    /// `gddr5`: record every DRAM command and run the independent timing checker
    /// (`mem::checker`) after every wavefront; a violation stops the run. Costs
    /// memory and time: for tests.
    pub check_timing: bool,
}

impl MemoryModel {
    /// The model by its configuration name (`fixed`, `gddr5`), e.g. from `--memory`.
    pub fn parse(s: &str) -> Result<MemoryModel, String> {
        match s {
            "fixed" => Ok(MemoryModel::Fixed),
            "gddr5" => Ok(MemoryModel::Gddr5),
            _ => Err(format!(
                "unknown memory model '{s}'; give gddr5 (the paper's GDDR5, the default) or fixed (a fixed latency)"
            )),
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            MemoryModel::Fixed => "fixed",
            MemoryModel::Gddr5 => "gddr5",
        }
    }
}

impl Default for MemoryUnitCfg {
    fn default() -> Self {
        MemoryUnitCfg {
            model: MemoryModel::Gddr5,
            latency: 100,
            bytes_per_cycle: 512,
            check_timing: false,
        }
    }
}

/// The scene buffer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SceneBufferCfg {
    /// 4 MB [DS17 Table 1].
    pub bytes: u32,
    /// One slot per segment: 64 KB, 64 slots [DS17 §5.1].
    pub slot_bytes: u32,
    /// Banks, one line per bank per cycle. Assumption: 32, like the L2 of Table 1.
    pub banks: u32,
    /// Cycles from acceptance of an L1 miss to the line visible at the L1
    /// (response link included). Assumption: 4.
    pub latency: u32,
}

impl Default for SceneBufferCfg {
    fn default() -> Self {
        SceneBufferCfg {
            bytes: 4 << 20,
            slot_bytes: 64 << 10,
            banks: 32,
            latency: 4,
        }
    }
}

impl SceneBufferCfg {
    pub fn slots(&self) -> u32 {
        self.bytes / self.slot_bytes.max(1)
    }
}

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

/// The hit record updater.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HitUpdaterCfg {
    /// Pending updates (merged per hit index). Assumption: 64.
    pub queue: u32,
    /// Read-compare-writes in flight. Assumption: 32.
    pub in_flight: u32,
}

impl Default for HitUpdaterCfg {
    fn default() -> Self {
        HitUpdaterCfg {
            queue: 64,
            in_flight: 32,
        }
    }
}

/// The L2 cache (`units/l2.rs`): everything that is not a stream goes through it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct L2Cfg {
    /// `false`: the hit record updater and the TMs' global-memory ports go
    /// straight to memory ports (to measure the L2's effect).
    pub enabled: bool,
    /// 512 KB [DS17 Table 1].
    pub bytes: u32,
    /// 32 banks [DS17 Table 1], one access per bank per cycle.
    pub banks: u32,
    /// 64 B, the DRAM line of the data contract.
    pub line_bytes: u32,
    /// Assumption: 8 ways (a common L2 associativity; 32 sets per bank at the
    /// defaults). The hit records and path states are large arrays whose lines are
    /// touched once per pass each, so associativity matters little; 8 keeps the
    /// tag compare small.
    pub ways: u32,
    /// Cycles from acceptance to the answer visible at the client (response link
    /// included). Assumption: 10 (a 512 KB banked SRAM at 1 GHz plus the crossbar).
    pub hit_latency: u32,
    /// Miss registers. Assumption: 64.
    pub mshrs: u32,
    /// Accesses merged into one miss register. Assumption: 8.
    pub targets: u32,
    /// Writeback buffer entries (plus one reserved per MSHR). Assumption: 16.
    pub writebacks: u32,
    /// Requests per client accepted and not yet answered. Assumption: 64.
    pub port_queue: u32,
    /// Lines per cycle between the L2 and the memory (fills and writebacks, the
    /// end-of-run flush too): one memory port (lane) each, a line always on lane
    /// `line index mod lanes` (docs/chip.md "L2"). 4 (256 GB/s at 1 GHz): half
    /// the 8 lines per cycle of the paper's 512 GB/s GDDR5 (§5.1), the other half
    /// left to the two streams; one lane (64 GB/s) bounded the shading pass and
    /// made every end-of-run flush write back one line per cycle. 1 to 16.
    pub mem_lines_per_cycle: u32,
    /// Bank index = XOR of the line index's bank-wide bit fields (true) or the
    /// line index modulo the banks (false). Assumption: hashed, as banked GPU L2s
    /// do, so strided line sequences spread over the banks (cornell 128x128 on
    /// 128 x 16 with GDDR5: 476,011 cycles with modulo, 467,173 hashed).
    pub bank_hash: bool,
    /// A bank serving a read of a line serves other clients' reads of the same
    /// line in that cycle too (one array read, the data multicast). Assumption:
    /// on; shading's clients read the same triangles and materials, and about
    /// two thirds of the bank conflicts were such same-line reads (cornell
    /// 128x128).
    pub combine_reads: bool,
}

impl Default for L2Cfg {
    fn default() -> Self {
        L2Cfg {
            enabled: true,
            bytes: 512 << 10,
            banks: 32,
            line_bytes: 64,
            ways: 8,
            hit_latency: 10,
            mshrs: 64,
            targets: 8,
            writebacks: 16,
            port_queue: 64,
            mem_lines_per_cycle: 4,
            bank_hash: true,
            combine_reads: true,
        }
    }
}

impl L2Cfg {
    /// Checks the cache's geometry and sizes; `link_delay` is part of `hit_latency`.
    pub fn validate(&self, link_delay: u32) -> Result<(), String> {
        if self.line_bytes != 64 {
            return Err(format!(
                "chip.l2.line_bytes = {}: the data contract's DRAM line is 64 B; give 64",
                self.line_bytes
            ));
        }
        if self.banks == 0 || self.ways == 0 {
            return Err("chip.l2.banks and chip.l2.ways must be at least 1".into());
        }
        let unit = self.banks as u64 * self.ways as u64 * self.line_bytes as u64;
        if self.bytes == 0 || !(self.bytes as u64).is_multiple_of(unit) {
            return Err(format!(
                "chip.l2.bytes = {} is not a positive multiple of banks x ways x line_bytes = {} x {} x {} = {unit}; every bank needs whole sets",
                self.bytes, self.banks, self.ways, self.line_bytes
            ));
        }
        if self.hit_latency <= link_delay {
            return Err(format!(
                "chip.l2.hit_latency = {} must exceed the response link delay ({link_delay}, chip.links.delay), which is part of it",
                self.hit_latency
            ));
        }
        for (name, v) in [
            ("mshrs", self.mshrs),
            ("targets", self.targets),
            ("writebacks", self.writebacks),
            ("port_queue", self.port_queue),
        ] {
            if v == 0 {
                return Err(format!("chip.l2.{name} = 0: give at least 1"));
            }
        }
        if self.mem_lines_per_cycle == 0 || self.mem_lines_per_cycle > MAX_STREAM_LANES {
            return Err(format!(
                "chip.l2.mem_lines_per_cycle = {}: give 1 to {MAX_STREAM_LANES} lines per cycle (one memory port each; 8 lines per cycle is already the 512 GB/s GDDR5 peak)",
                self.mem_lines_per_cycle
            ));
        }
        Ok(())
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
    pub memory: MemoryUnitCfg,
    pub scene_buffer: SceneBufferCfg,
    pub scheduler: SchedulerCfg,
    pub hit_updater: HitUpdaterCfg,
    pub l2: L2Cfg,
    /// `tps` (default) or `host`.
    pub shading: Shading,
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
        }
    }
}

impl ChipCfg {
    /// Checks the chip against itself and the segment size `segment_bytes`.
    pub fn validate(&self, segment_bytes: u32) -> Result<(), String> {
        if self.tms == 0 || self.tms > 4096 {
            return Err(format!(
                "chip.tms = {}: give 1 to 4096 thread multiprocessors",
                self.tms
            ));
        }
        self.links.validate("chip.links")?;
        let d = self.links.delay;
        if self.memory.latency <= d {
            return Err(format!(
                "chip.memory.latency = {} must exceed the response link delay ({d}, chip.links.delay), which is part of it",
                self.memory.latency
            ));
        }
        if self.memory.bytes_per_cycle < 64 {
            return Err(format!(
                "chip.memory.bytes_per_cycle = {}: at least one 64 B line per cycle",
                self.memory.bytes_per_cycle
            ));
        }
        let sb = &self.scene_buffer;
        if sb.slot_bytes < segment_bytes {
            return Err(format!(
                "chip.scene_buffer.slot_bytes = {} is smaller than one segment (accel.segment_bytes = {segment_bytes}); a slot must hold a whole segment",
                sb.slot_bytes
            ));
        }
        if !sb.slot_bytes.is_multiple_of(64) || sb.slots() == 0 {
            return Err(format!(
                "chip.scene_buffer: {} B of {} B slots hold no slot; the buffer must hold at least one whole-line slot",
                sb.bytes, sb.slot_bytes
            ));
        }
        if sb.banks == 0 || !sb.banks.is_power_of_two() {
            return Err(format!(
                "chip.scene_buffer.banks = {} must be a power of two",
                sb.banks
            ));
        }
        if sb.latency <= d {
            return Err(format!(
                "chip.scene_buffer.latency = {} must exceed the response link delay ({d}, chip.links.delay)",
                sb.latency
            ));
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
                return Err(format!("chip.scheduler.{name} = 0: give at least 1"));
            }
        }
        for (name, v) in [
            ("ray_lines_per_cycle", s.ray_lines_per_cycle),
            ("scene_lines_per_cycle", s.scene_lines_per_cycle),
        ] {
            if v > MAX_STREAM_LANES {
                return Err(format!(
                    "chip.scheduler.{name} = {v}: at most {MAX_STREAM_LANES} lines per cycle (one memory port each; 8 lines per cycle is already the 512 GB/s GDDR5 peak)"
                ));
            }
        }
        if s.mem_queue < 4 {
            return Err(format!(
                "chip.scheduler.mem_queue = {}: at least 4 (one ray write may need a line, a header and a next line)",
                s.mem_queue
            ));
        }
        if self.hit_updater.queue == 0 || self.hit_updater.in_flight == 0 {
            return Err("chip.hit_updater.queue and in_flight must be at least 1".into());
        }
        self.l2.validate(d)?;
        if self.watchdog_cycles == 0 {
            return Err("chip.watchdog_cycles = 0: give a positive number of cycles".into());
        }
        Ok(())
    }
}
