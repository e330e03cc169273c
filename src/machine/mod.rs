//! The chip top (paper §4, Figure 1): N TMs of M TPs, the stream scheduler, the
//! scene buffer, the hit record updater and the memory unit, wired only through
//! declared links.
//!
//! Wiring (all links `chip.links`):
//! - host `emit`/`start` -> scheduler (stage A: the host's shading emits the rays);
//! - scheduler `fill[k]` -> TM k `fill`; TM k `ray_write` -> scheduler `ray_write[k]`;
//! - TM k `miss_req` -> scene buffer `req[k]`; scene buffer `resp[k]` -> TM k `miss_resp`;
//! - TM k `hit` -> hit record updater `hit[k]`;
//! - scheduler `slot_map` -> scene buffer;
//! - memory port 0: scheduler `mem_req[0]`/`mem_resp[0]` (ray stream, segment table);
//!   port 1: scheduler `scene_req[0]` -> memory -> scene buffer `fill[0]` (scene stream);
//!   port 2: the L2's memory side (`chip.l2.enabled`, the default), else the hit
//!   record updater and, from port 3 on, TM k's `gmem_req`/`gmem_resp`; then the
//!   scheduler's further ray lanes `mem_req[j]` and scene lanes `scene_req[j]`,
//!   j >= 1 (`chip.scheduler.ray_lines_per_cycle`, `scene_lines_per_cycle`);
//!   then the L2's further memory lanes `mem_req[j]`/`mem_resp[j]`, j >= 1
//!   (`chip.l2.mem_lines_per_cycle`, with the L2 only);
//! - L2 (`units/l2.rs`) clients: `req[0]` hit record updater, `req[1 + k]` TM k's
//!   global-memory port (the shading pass); host `flush` -> L2 -> `flush_done`
//!   (every run ends with a flush, docs/chip.md "L2");
//! - `chip.memory.model = "gddr5"`: memory `ch_req[c]`/`ch_resp[c]` <-> `chip.mem_ctrl{c}`
//!   (one per channel, on the DRAM clock; docs/chip.md "Memory timing").
//!
//! Stage A runs one wavefront at a time: the host (render/mod.rs, shading still
//! on the host: interim, stage C moves it onto the TPs through an L2) emits the
//! wavefront's rays into the root queue through the scheduler, then the chip runs
//! until every unit is idle. The DRAM image moves into the memory unit for the
//! run and back out for shading.

pub mod hdl;
pub mod host;
pub mod trace;

use std::time::Instant;

use crate::config::Config;
use crate::contract::{MemoryMap, RayRec, SparseMem};
use crate::mem::config::EnergyCfg;
use crate::mem::energy::{EnergyModel, energy_of};
use crate::mem::stats::ChannelStats;
use crate::mem::{AddrMap, MemCfg, MemReq, MemResp, StreamTag};
use crate::rtl::{ClockId, Sim, SimOptions, UnitId};
use crate::units::hit_record_updater::HitRecordUpdater;
use crate::units::l1::{L1Req, L1Resp};
use crate::units::l2::{L2, L2Flush};
use crate::units::mem_ctrl::MemCtrl;
use crate::units::memory::{MemLineReq, MemLineResp, Memory};
use crate::units::scene_buffer::{SceneBuffer, SlotMap};
use crate::units::shade::ShadeConsts;
use crate::units::staging_buffer::SbFill;
use crate::units::stream_scheduler::{StreamScheduler, WaveStart};
use crate::units::tm::{self, TmPorts, TmUnits};
use crate::units::tp::{HitUpdate, RayWrite, ShadeRegs, Tp, TpStats};
use host::Host;

/// Memory ports.
pub const PORT_SCHED: usize = 0;
pub const PORT_SCENE: usize = 1;
/// The hit record updater's port, or the L2's memory side when the chip has one.
pub const PORT_HITS: usize = 2;
pub const PORT_L2: usize = 2;

/// The GDDR5 model's figures over one wavefront (all zero with `fixed`).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct DramWave {
    /// Line reads and writes served by the controllers, per stream tag too.
    pub reads: u64,
    pub writes: u64,
    pub tag_reads: [u64; StreamTag::COUNT],
    pub tag_writes: [u64; StreamTag::COUNT],
    pub row_hits: u64,
    pub row_misses: u64,
    pub row_conflicts: u64,
    pub acts: u64,
    pub refs: u64,
    /// DRAM energy in joules with the `paper` and `physical` presets
    /// (`mem.energy`, docs/memory.md), background and refresh included.
    pub energy_paper_j: f64,
    pub energy_physical_j: f64,
}

impl DramWave {
    pub fn lines(&self) -> u64 {
        self.reads + self.writes
    }
    pub fn row_hit_rate(&self) -> f64 {
        let n = self.row_hits + self.row_misses + self.row_conflicts;
        if n == 0 {
            0.0
        } else {
            self.row_hits as f64 / n as f64
        }
    }
    /// Achieved bandwidth in GB/s over `cycles` core cycles of `core_ps`.
    pub fn bandwidth_gbs(&self, line_bytes: u64, cycles: u64, core_ps: u64) -> f64 {
        let s = cycles as f64 * core_ps as f64 * 1e-12;
        if s == 0.0 {
            0.0
        } else {
            (self.lines() * line_bytes) as f64 / s / 1e9
        }
    }
    fn sub(&self, b: &DramWave) -> DramWave {
        let mut d = DramWave {
            reads: self.reads - b.reads,
            writes: self.writes - b.writes,
            row_hits: self.row_hits - b.row_hits,
            row_misses: self.row_misses - b.row_misses,
            row_conflicts: self.row_conflicts - b.row_conflicts,
            acts: self.acts - b.acts,
            refs: self.refs - b.refs,
            energy_paper_j: self.energy_paper_j - b.energy_paper_j,
            energy_physical_j: self.energy_physical_j - b.energy_physical_j,
            ..DramWave::default()
        };
        for k in 0..StreamTag::COUNT {
            d.tag_reads[k] = self.tag_reads[k] - b.tag_reads[k];
            d.tag_writes[k] = self.tag_writes[k] - b.tag_writes[k];
        }
        d
    }
    /// Accumulates another wavefront.
    pub fn add(&mut self, o: &DramWave) {
        self.reads += o.reads;
        self.writes += o.writes;
        self.row_hits += o.row_hits;
        self.row_misses += o.row_misses;
        self.row_conflicts += o.row_conflicts;
        self.acts += o.acts;
        self.refs += o.refs;
        self.energy_paper_j += o.energy_paper_j;
        self.energy_physical_j += o.energy_physical_j;
        for k in 0..StreamTag::COUNT {
            self.tag_reads[k] += o.tag_reads[k];
            self.tag_writes[k] += o.tag_writes[k];
        }
    }
}

/// The GDDR5 side of the chip (`chip.memory.model = "gddr5"`).
struct Dram {
    clock: ClockId,
    ctrls: Vec<UnitId>,
    cfg: MemCfg,
    paper: EnergyModel,
    physical: EnergyModel,
    check: bool,
}

/// One traced wavefront's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct WaveCycles {
    /// Cycles from the first emitted ray to the last unit going idle.
    pub cycles: u64,
    pub rays_emitted: u64,
    pub duplicates: u64,
    pub segments_loaded: u64,
    pub box_tests: u64,
    pub tri_tests: u64,
    pub exits: u64,
    pub pops: u64,
    pub tri_hits: u64,
    pub l1_lines: u64,
    pub max_stack: u64,
    pub hits_sent: u64,
    pub lines_read: [u64; StreamTag::COUNT],
    pub lines_written: [u64; StreamTag::COUNT],
    pub hit_merged: u64,
    pub scene_buffer_stalls: u64,
    pub scene_buffer_stall_cycles: u64,
    pub scene_buffer_reads: u64,
    pub evals: u64,
    pub dram: DramWave,
    /// The shading pass before the wavefront (0 for the primary rays): pixels
    /// shaded, rays emitted (shadow ones too), bounce hits, blocked shadow rays,
    /// and its cycles (from the start to the last item's end marker).
    pub shade_items: u64,
    pub shade_rays: u64,
    pub shade_shadow_rays: u64,
    pub shade_hits: u64,
    pub shade_occluded: u64,
    pub shade_cycles: u64,
    /// Cycles from the last finished work (the last end marker of a ray or a
    /// shading item taken by the scheduler) to the run's end (every unit idle):
    /// the pass's drain (hit record writes, retirement, answers in flight),
    /// without the end-of-run L2 flush (`l2.flush_cycles`).
    pub drain_cycles: u64,
    /// Actions of the TPs' shading states (`tm.costs` shade_load, shade,
    /// shade_emit, shade_store), for the energy model.
    pub shade_uses: [u64; 4],
    /// The L2 (zero without): client accesses, hits, misses (merges included),
    /// misses merged into a live MSHR, bank-conflict stall cycles, lines filled
    /// and dirty lines written back (the end-of-run flush included).
    pub l2: L2Wave,
    /// Distribution balance: the most and fewest rays one TM got in this run,
    /// and how many TMs got any (the mean is `rays_traced / tms`).
    pub tm_rays_max: u64,
    pub tm_rays_min: u64,
    pub tms_with_rays: u64,
}

/// The L2's counters over one run.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct L2Wave {
    pub accesses: u64,
    pub hits: u64,
    pub misses: u64,
    pub merges: u64,
    pub bank_conflicts: u64,
    pub fills: u64,
    pub writebacks: u64,
    /// Cycles of the end-of-run flush (part of the run's cycles).
    pub flush_cycles: u64,
    /// Reads served by a bank already reading their line (`chip.l2.combine_reads`):
    /// accesses, but no array read of their own.
    pub combined: u64,
}

impl L2Wave {
    pub fn hit_rate(&self) -> f64 {
        if self.accesses == 0 {
            0.0
        } else {
            self.hits as f64 / self.accesses as f64
        }
    }
    /// Data-array accesses (client accesses but combined reads, fills,
    /// writebacks), for the energy.
    pub fn array_accesses(&self) -> u64 {
        self.accesses - self.combined + self.fills + self.writebacks
    }
    fn sub(&self, b: &L2Wave) -> L2Wave {
        L2Wave {
            accesses: self.accesses - b.accesses,
            hits: self.hits - b.hits,
            misses: self.misses - b.misses,
            merges: self.merges - b.merges,
            bank_conflicts: self.bank_conflicts - b.bank_conflicts,
            fills: self.fills - b.fills,
            writebacks: self.writebacks - b.writebacks,
            flush_cycles: self.flush_cycles - b.flush_cycles,
            combined: self.combined - b.combined,
        }
    }
    pub fn add(&mut self, o: &L2Wave) {
        self.accesses += o.accesses;
        self.hits += o.hits;
        self.misses += o.misses;
        self.merges += o.merges;
        self.bank_conflicts += o.bank_conflicts;
        self.fills += o.fills;
        self.writebacks += o.writebacks;
        self.flush_cycles += o.flush_cycles;
        self.combined += o.combined;
    }
}

impl WaveCycles {
    /// The counts between two snapshots of one run (`self` the later).
    fn since(&self, b: &WaveCycles) -> WaveCycles {
        let d = |a: u64, b: u64| a - b;
        WaveCycles {
            cycles: d(self.cycles, b.cycles),
            rays_emitted: 0,
            duplicates: d(self.duplicates, b.duplicates),
            segments_loaded: d(self.segments_loaded, b.segments_loaded),
            box_tests: d(self.box_tests, b.box_tests),
            tri_tests: d(self.tri_tests, b.tri_tests),
            exits: d(self.exits, b.exits),
            pops: d(self.pops, b.pops),
            tri_hits: d(self.tri_hits, b.tri_hits),
            l1_lines: d(self.l1_lines, b.l1_lines),
            max_stack: 0,
            hits_sent: d(self.hits_sent, b.hits_sent),
            lines_read: std::array::from_fn(|k| d(self.lines_read[k], b.lines_read[k])),
            lines_written: std::array::from_fn(|k| d(self.lines_written[k], b.lines_written[k])),
            hit_merged: d(self.hit_merged, b.hit_merged),
            scene_buffer_stalls: d(self.scene_buffer_stalls, b.scene_buffer_stalls),
            scene_buffer_stall_cycles: d(
                self.scene_buffer_stall_cycles,
                b.scene_buffer_stall_cycles,
            ),
            scene_buffer_reads: d(self.scene_buffer_reads, b.scene_buffer_reads),
            evals: d(self.evals, b.evals),
            dram: self.dram.sub(&b.dram),
            shade_items: d(self.shade_items, b.shade_items),
            shade_rays: d(self.shade_rays, b.shade_rays),
            shade_shadow_rays: d(self.shade_shadow_rays, b.shade_shadow_rays),
            shade_hits: d(self.shade_hits, b.shade_hits),
            shade_occluded: d(self.shade_occluded, b.shade_occluded),
            shade_cycles: 0,
            drain_cycles: 0,
            shade_uses: std::array::from_fn(|k| d(self.shade_uses[k], b.shade_uses[k])),
            l2: self.l2.sub(&b.l2),
            tm_rays_max: 0,
            tm_rays_min: 0,
            tms_with_rays: 0,
        }
    }

    /// Rays handed to the TMs in this run (duplicates included).
    pub fn rays_traced(&self) -> u64 {
        self.rays_emitted + self.duplicates
    }
    /// Most rays on one TM over the mean per TM (1 = perfectly balanced; 0 when
    /// no ray was traced).
    pub fn tm_imbalance(&self, tms: u64) -> f64 {
        let n = self.rays_traced();
        if n == 0 || tms == 0 {
            0.0
        } else {
            self.tm_rays_max as f64 * tms as f64 / n as f64
        }
    }
}

/// Cycles between two looks at a sampling window's marks: the resolution of its
/// start and end (a window spans tens of thousands of cycles).
const WINDOW_STEP: u64 = 32;

/// What a sampling window runs (see [`Chip::trace_window`]).
pub enum WindowKind {
    /// The rest of a wavefront from a segment boundary; marks are admissions.
    Trace(crate::contract::Boundary),
    /// The host emitting these rays into the root queue; marks are rays taken.
    Emit(Vec<RayRec>),
    /// The shading pass over pixels `first..pixels`, its rays into the bucket
    /// pool `pool` (its queues empty); marks are finished shading items.
    Shade {
        first: u32,
        pixels: u32,
        pool: crate::contract::Boundary,
    },
    /// A wavefront's root pass (the boundary's root queue, perhaps compacted);
    /// marks are the rays finished in the root segment. The window runs to the
    /// pass's end, at the next admission (its children's) or the wavefront's
    /// end; the measurement is a stretch of it, at most to its last ray
    /// finished.
    Root(crate::contract::Boundary),
    /// A short wavefront (too few passes for a window between them) over a
    /// sample of its root queue, from its root pass to its end; marks are the
    /// rays finished in any segment (ray visits). The measured stretch is chosen
    /// once the wavefront is over: from the first look at which a fraction
    /// `tenths.0 / 10` of its visits were done to the first at `tenths.1 / 10`,
    /// looking every `step` visits.
    /// Its chip is built with `l2_share` of the configured L2 (see
    /// `WindowPlan::wave_l2_share`).
    Wave {
        boundary: crate::contract::Boundary,
        tenths: (u64, u64),
        step: u64,
        l2_share: u32,
    },
}

/// A sampling window's measurement.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct WindowRun {
    /// The chip's counts over the measured stretch (cycles, lines, DRAM, ...).
    pub counts: WaveCycles,
    /// Marks in the measured stretch (admissions or shading items).
    pub marks: u64,
    /// Marks of the warm-up (at least the asked ones: it is checked in steps,
    /// and runs on for its cycles).
    pub from: u64,
    /// The wavefront (or shading pass) ended inside the measurement, so `counts`
    /// include its drain.
    pub ended: bool,
    /// The warm-up's counts (simulated but not measured).
    pub warm: WaveCycles,
    /// Dirty L2 lines at the measurement's end less those at its start, by
    /// stream tag: writebacks the stretch owes (a dirty line is written back
    /// once, later), which an abandoned window never sees.
    pub dirtied: [i64; StreamTag::COUNT],
    /// The segment passes the window retired, warm-up included (cycles from the
    /// window's start; the measurement starts at `warm.cycles`).
    pub passes: Vec<crate::units::stream_scheduler::PassEvent>,
    /// Rays finished (end markers) in the measured stretch, by segment: the
    /// work the stretch did, however its passes straddle its ends. (A
    /// [`WindowKind::Wave`]: over the whole run, which its estimate scales.)
    pub done: Vec<(u32, u64)>,
    /// A root window's counts from the measured stretch's end to the pass's
    /// end (it runs to the end: `warm`, `counts` and `after` are the pass).
    pub after: WaveCycles,
}

/// The chip, elaborated once per frame.
pub struct Chip {
    pub sim: Sim,
    pub clock: ClockId,
    pub tms: Vec<TmUnits>,
    pub scheduler: UnitId,
    pub scene_buffer: UnitId,
    pub hit_updater: UnitId,
    pub memory: UnitId,
    pub host: UnitId,
    /// The L2 (`chip.l2.enabled`), and whether its end-of-run flush also
    /// invalidates (host shading writes DRAM between runs).
    pub l2: Option<UnitId>,
    l2_invalidate: bool,
    /// Cycles spent in L2 flushes so far.
    flush_cycles: u64,
    dram: Option<Dram>,
    watchdog: u64,
    segments: usize,
    wave: u32,
    /// Simulated cycles and wall time of the traced wavefronts.
    pub total_cycles: u64,
    pub wall_s: f64,
    /// The most stack entries a traversal of this scene's segments can need
    /// (`Segmentation::stack_bound`), when the caller knows it: named in the
    /// error if a TP's stack overflows.
    pub stack_need: Option<u32>,
    /// TP scratchpad bytes and stack entry bytes (`tm.*`), for that error.
    stack_cfg: (u32, u32),
}

/// The one place each unit type is found in the simulation (a downcast);
/// everything else reads a unit through its probe (`probe()` and named
/// accessors in the unit's file), so a unit's internals can change without the
/// chip top changing.
impl Chip {
    fn sched(&self) -> &StreamScheduler {
        self.sim.unit_ref(self.scheduler)
    }
    fn sched_mut(&mut self) -> &mut StreamScheduler {
        self.sim.unit_mut(self.scheduler)
    }
    fn memory_unit(&self) -> &Memory {
        self.sim.unit_ref(self.memory)
    }
    fn memory_unit_mut(&mut self) -> &mut Memory {
        self.sim.unit_mut(self.memory)
    }
    fn scene_buffer_unit(&self) -> &SceneBuffer {
        self.sim.unit_ref(self.scene_buffer)
    }
    fn hit_updater_unit(&self) -> &HitRecordUpdater {
        self.sim.unit_ref(self.hit_updater)
    }
    fn l2_unit(&self) -> Option<&L2> {
        self.l2.map(|u| self.sim.unit_ref(u))
    }
    fn host_mut(&mut self) -> &mut Host {
        self.sim.unit_mut(self.host)
    }
    /// Every TP of every TM, TM by TM.
    fn tps(&self) -> impl Iterator<Item = UnitId> + '_ {
        self.tms.iter().flat_map(|t| t.tps.iter().copied())
    }
    fn tp(&self, u: UnitId) -> &Tp {
        self.sim.unit_ref(u)
    }
    fn tp_mut(&mut self, u: UnitId) -> &mut Tp {
        self.sim.unit_mut(u)
    }
    fn ctrl(&self, u: UnitId) -> &MemCtrl {
        self.sim.unit_ref(u)
    }
}

impl Chip {
    /// Builds the chip for a scene laid out by `map` with `segments` segments.
    pub fn new(
        cfg: &Config,
        map: &MemoryMap,
        segments: usize,
        shade: &ShadeConsts,
        opts: SimOptions,
    ) -> Result<Chip, String> {
        cfg.validate()?;
        let ch = &cfg.chip;
        let mut sim = Sim::new(opts);
        let clock = sim
            .clock("core", cfg.clocks.core_ps)
            .map_err(|e| e.to_string())?;
        let l = ch.links;
        let n = ch.tms as usize;
        // Memory ports.
        let mut mreq_o = Vec::new();
        let mut mreq_i = Vec::new();
        let mut mresp_o = Vec::new();
        let mut mresp_i = Vec::new();
        let with_l2 = ch.l2.enabled;
        let port2 = if with_l2 { "l2" } else { "hits" };
        for (k, who) in ["sched", "scene", port2].iter().enumerate() {
            let (a, b) = sim.link::<MemLineReq>(&format!("chip.mem_req{k}_{who}"), l);
            mreq_o.push(Some(a));
            mreq_i.push(b);
            let (a, b) = sim.link::<MemLineResp>(&format!("chip.mem_resp{k}_{who}"), l);
            mresp_o.push(a);
            mresp_i.push(Some(b));
        }
        // Further stream lanes (one memory port per line per cycle): their links
        // now, their memory ports after the TMs' (ports 0-2 stay the first lanes).
        let (mut lane_req_o, mut lane_req_i, mut lane_resp_o, mut lane_resp_i) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (who, lanes) in [
            ("sched", ch.scheduler.ray_lines_per_cycle),
            ("scene", ch.scheduler.scene_lines_per_cycle),
        ] {
            for j in 1..lanes {
                let (a, b) = sim.link::<MemLineReq>(&format!("chip.mem_req_{who}{j}"), l);
                lane_req_o.push(a);
                lane_req_i.push(b);
                let (a, b) = sim.link::<MemLineResp>(&format!("chip.mem_resp_{who}{j}"), l);
                lane_resp_o.push(a);
                lane_resp_i.push(b);
            }
        }
        let ray_extra = ch.scheduler.ray_lines_per_cycle as usize - 1;
        let mut lane_req_o = lane_req_o.into_iter();
        let mut lane_resp_i = lane_resp_i.into_iter();
        let sched_req: Vec<_> = std::iter::once(mreq_o[PORT_SCHED].take().expect("port"))
            .chain(lane_req_o.by_ref().take(ray_extra))
            .collect();
        let sched_resp: Vec<_> = std::iter::once(mresp_i[PORT_SCHED].take().expect("port"))
            .chain(lane_resp_i.by_ref().take(ray_extra))
            .collect();
        let scene_req: Vec<_> = std::iter::once(mreq_o[PORT_SCENE].take().expect("port"))
            .chain(lane_req_o)
            .collect();
        let scene_fill: Vec<_> = std::iter::once(mresp_i[PORT_SCENE].take().expect("port"))
            .chain(lane_resp_i)
            .collect();
        let (emit_o, emit_i) = sim.link::<RayWrite>("chip.emit", l);
        let (start_o, start_i) = sim.link::<WaveStart>("chip.start", l);
        let (map_o, map_i) = sim.link::<SlotMap>("chip.slot_map", l);
        // One kind of TM link at a time: each array port (the scheduler's
        // `ray_write`, the hit record updater's `hit`, the L2's clients) then has
        // consecutive links, so an arbiter finds its visible inputs in a word of
        // the non-empty bitset instead of loading every link's head.
        macro_rules! per_tm {
            ($t:ty, $name:literal) => {
                sim.links::<$t>(n, |k| format!("chip.tm{k}_{}", $name), l)
            };
        }
        let (fill_o, fill_i) = per_tm!(SbFill, "fill");
        let (miss_o, sbq_i) = per_tm!(L1Req, "miss_req");
        let (sbr_o, miss_i) = per_tm!(L1Resp, "miss_resp");
        let (rw_o, rw_i) = per_tm!(RayWrite, "ray_write");
        let (hit_o, hit_i) = per_tm!(HitUpdate, "hit");
        // The hit record updater is the L2's client 0, the TMs 1..: its links go
        // right before the TMs'.
        let hru_l2_req = with_l2.then(|| sim.link::<MemLineReq>("chip.l2_req0_hits", l));
        let (gq_o, mut gmem_i) = per_tm!(MemLineReq, "gmem_req");
        let hru_l2_resp = with_l2.then(|| sim.link::<MemLineResp>("chip.l2_resp0_hits", l));
        let (mut gmem_o, gr_i) = per_tm!(MemLineResp, "gmem_resp");
        let tm_ports: Vec<TmPorts> = (0..n)
            .map(|k| TmPorts {
                fill: fill_i[k],
                miss_req: miss_o[k],
                miss_resp: miss_i[k],
                ray_write: rw_o[k],
                hit: hit_o[k],
                gmem_req: gq_o[k],
                gmem_resp: gr_i[k],
            })
            .collect();
        // The L2 between its clients and memory port 2.
        let mut l2_unit = None;
        let mut host_unit = Host::new(emit_o, start_o);
        let (mut l2_lane_req_i, mut l2_lane_resp_o) = (Vec::new(), Vec::new());
        let (hru_req, hru_resp) = if with_l2 {
            // The L2's memory lanes: lane 0 is port 2, the further ones are
            // appended after the scheduler's lanes.
            let mut l2_mreq = vec![mreq_o[PORT_L2].take().expect("port")];
            let mut l2_mresp = vec![mresp_i[PORT_L2].take().expect("port")];
            for j in 1..ch.l2.mem_lines_per_cycle {
                let (a, b) = sim.link::<MemLineReq>(&format!("chip.mem_req_l2_lane{j}"), l);
                l2_mreq.push(a);
                l2_lane_req_i.push(b);
                let (a, b) = sim.link::<MemLineResp>(&format!("chip.mem_resp_l2_lane{j}"), l);
                l2_lane_resp_o.push(a);
                l2_mresp.push(b);
            }
            let (ho, hi) = hru_l2_req.expect("made with the L2");
            let (hro, hri) = hru_l2_resp.expect("made with the L2");
            let (fo, fi) = sim.link::<L2Flush>("chip.l2_flush", l);
            let (fdo, fdi) = sim.link::<L2Flush>("chip.l2_flush_done", l);
            host_unit = host_unit.with_flush(fo, fdi);
            let mut reqs = vec![hi];
            reqs.append(&mut gmem_i);
            let mut resps = vec![hro];
            resps.append(&mut gmem_o);
            l2_unit = Some(L2::new(
                &ch.l2, l.delay, reqs, resps, l2_mreq, l2_mresp, fi, fdo,
            ));
            (ho, hri)
        } else {
            (
                mreq_o[PORT_HITS].take().expect("port"),
                mresp_i[PORT_HITS].take().expect("port"),
            )
        };
        let host = sim.add("chip.host", clock, host_unit);
        let scheduler = sim.add(
            "chip.scheduler",
            clock,
            StreamScheduler::new(
                &ch.scheduler,
                &ch.scene_buffer,
                map,
                segments,
                emit_i,
                start_i,
                sched_resp,
                map_o,
                scene_req,
                sched_req,
                rw_i,
                fill_o,
            ),
        );
        let scene_buffer = sim.add(
            "chip.scene_buffer",
            clock,
            SceneBuffer::new(&ch.scene_buffer, l.delay, map_i, scene_fill, sbq_i, sbr_o),
        );
        let hit_updater = sim.add(
            "chip.hit_updater",
            clock,
            HitRecordUpdater::new(&ch.hit_updater, map.hits, hit_i, hru_req, hru_resp),
        );
        let l2 = l2_unit.map(|u| sim.add("chip.l2", clock, u));
        // Without the L2 the TMs' global-memory ports (the shading pass) go to
        // the memory too (empty with it).
        mreq_i.extend(gmem_i);
        mresp_o.extend(gmem_o);
        mreq_i.extend(lane_req_i);
        mresp_o.extend(lane_resp_o);
        mreq_i.extend(l2_lane_req_i);
        mresp_o.extend(l2_lane_resp_o);
        let mut memory_unit = Memory::new(
            &ch.memory,
            l.delay,
            SparseMem::new(map.capacity),
            mreq_i,
            mresp_o,
        );
        let mut dram = None;
        if ch.memory.model == crate::units::memory::MemoryModel::Gddr5 {
            let m = &cfg.mem;
            MemCtrl::supports(m)?;
            let dclk = sim
                .clock("dram", cfg.clocks.dram_ps)
                .map_err(|e| e.to_string())?;
            let amap = AddrMap::new(&m.geometry, &m.mapping)?;
            let mut ch_req = Vec::new();
            let mut ch_resp = Vec::new();
            let mut ctrls = Vec::new();
            for c in 0..m.geometry.channels {
                let (qo, qi) = sim.link::<MemReq>(&format!("chip.dram_req{c}"), m.ctrl.req_link);
                let (ro, ri) = sim.link::<MemResp>(&format!("chip.dram_resp{c}"), m.ctrl.resp_link);
                let mut u = MemCtrl::new(m, cfg.clocks.dram_ps, c, qi, ro);
                u.ctrl.record_commands(ch.memory.check_timing);
                ctrls.push(sim.add(&format!("chip.mem_ctrl{c}"), dclk, u));
                ch_req.push(qo);
                ch_resp.push(ri);
            }
            memory_unit = memory_unit.with_channels(amap, ch_req, ch_resp);
            let g = &m.geometry;
            let em = |name: &str| -> Result<EnergyModel, String> {
                Ok(EnergyModel::new(
                    &EnergyCfg::by_name(name, g)?,
                    &m.timing,
                    g.burst_cycles(),
                    cfg.clocks.dram_ps,
                ))
            };
            dram = Some(Dram {
                clock: dclk,
                ctrls,
                cfg: m.clone(),
                paper: em("paper")?,
                physical: em("physical")?,
                check: ch.memory.check_timing,
            });
        }
        let memory = sim.add("chip.memory", clock, memory_unit);
        let mut tms = Vec::with_capacity(n);
        let tm_spec = cfg.tm_spec();
        for (k, ports) in tm_ports.into_iter().enumerate() {
            tms.push(tm::build(
                &mut sim,
                clock,
                &tm_spec,
                &format!("chip.tm{k}"),
                ports,
            ));
        }
        // Several evaluation lanes: the TMs spread over them, the first lane (a
        // worker's) also takes the hit record updater and the scene buffer, the
        // last (this thread's) the other global units (the DRAM controllers' own
        // clock edges then need no hand-over) and the step's bookkeeping.
        if n >= 2 {
            sim.set_lane_plan(
                tms.iter().map(|t| t.all().collect()).collect(),
                vec![hit_updater, scene_buffer],
            );
        }
        sim.elaborate().map_err(|e| e.to_string())?;
        let mut chip = Chip {
            sim,
            clock,
            tms,
            scheduler,
            scene_buffer,
            hit_updater,
            memory,
            host,
            l2,
            l2_invalidate: ch.shading == crate::config::Shading::Host,
            flush_cycles: 0,
            dram,
            watchdog: ch.watchdog_cycles,
            segments,
            wave: 0,
            stack_need: None,
            stack_cfg: (cfg.tm.scratchpad_bytes, cfg.tm.stack_entry_bytes),
            total_cycles: 0,
            wall_s: 0.0,
        };
        let shading = ShadeRegs::new(*shade, map);
        for u in chip.tps().collect::<Vec<_>>() {
            chip.tp_mut(u).set_shading(Some(shading));
        }
        Ok(chip)
    }

    /// Every TP's counters added up, in one pass over the TPs (a snapshot needs
    /// a dozen of them; looking each up by name built every TP's counter list a
    /// dozen times, 8% of a small frame's instructions).
    fn tp_totals(&self) -> TpStats {
        let mut t = TpStats::default();
        for u in self.tps() {
            t.add(self.tp(u).probe());
        }
        t
    }

    /// The controllers' statistics up to now, all channels merged.
    pub fn dram_stats(&self) -> Option<ChannelStats> {
        let d = self.dram.as_ref()?;
        let end = self.sim.cycle(d.clock);
        let mut t = ChannelStats::default();
        for &u in &d.ctrls {
            t.merge(&self.ctrl(u).stats_at(end));
        }
        Some(t)
    }

    /// Timing-checker violations on every channel's command log so far (needs
    /// `chip.memory.check_timing`; empty otherwise and with `fixed`).
    pub fn dram_violations(&self) -> Vec<String> {
        let Some(d) = self.dram.as_ref() else {
            return Vec::new();
        };
        let end = self.sim.cycle(d.clock);
        let mut v = Vec::new();
        for (k, &u) in d.ctrls.iter().enumerate() {
            let log = self.ctrl(u).commands_until(end);
            for x in crate::mem::checker::check(&log, &d.cfg.timing, &d.cfg.geometry, end) {
                v.push(format!("channel {k}: {x}"));
            }
        }
        v
    }

    fn dram_snapshot(&self) -> DramWave {
        let (Some(d), Some(t)) = (self.dram.as_ref(), self.dram_stats()) else {
            return DramWave::default();
        };
        let mut w = DramWave {
            reads: t.reads,
            writes: t.writes,
            row_hits: t.row_hits,
            row_misses: t.row_misses,
            row_conflicts: t.row_conflicts,
            acts: t.acts,
            refs: t.refs,
            energy_paper_j: energy_of(&t, &d.paper).total(),
            energy_physical_j: energy_of(&t, &d.physical).total(),
            ..DramWave::default()
        };
        for k in 0..StreamTag::COUNT {
            w.tag_reads[k] = t.per_tag[k].reads;
            w.tag_writes[k] = t.per_tag[k].writes;
        }
        w
    }

    fn snapshot(&self) -> WaveCycles {
        let s = &self.sim;
        let mem = self.memory_unit().probe();
        let sb = self.scene_buffer_unit().probe();
        let sched = self.sched().probe();
        let hru = self.hit_updater_unit().probe();
        let tp = self.tp_totals();
        WaveCycles {
            cycles: s.cycle(self.clock),
            rays_emitted: 0,
            duplicates: sched.stats.enqueues,
            segments_loaded: sched.stats.segments_loaded,
            box_tests: tp.box_tests,
            tri_tests: tp.tri_tests,
            exits: tp.exits,
            pops: tp.uses_of("pop"),
            tri_hits: tp.tri_hits,
            l1_lines: tp.l1_loads,
            max_stack: 0,
            hits_sent: tp.hits,
            lines_read: mem.lines_read,
            lines_written: mem.lines_written,
            hit_merged: hru.merged,
            scene_buffer_stalls: sb.stalls,
            scene_buffer_stall_cycles: sb.stall_cycles,
            scene_buffer_reads: sb.reads,
            evals: s.evals,
            dram: self.dram_snapshot(),
            shade_items: tp.shade_items,
            shade_rays: tp.shade_rays,
            shade_shadow_rays: tp.shade_shadow_rays,
            shade_hits: tp.shade_hits,
            shade_occluded: tp.shade_occluded,
            // The cycle the last shading pass ended (see `run_wave`).
            shade_cycles: sched.last_shade_end,
            drain_cycles: 0,
            shade_uses: ["shade_load", "shade", "shade_emit", "shade_store"].map(|n| tp.uses_of(n)),
            l2: self.l2_unit().map_or(L2Wave::default(), |u| {
                let st = u.probe().stats;
                L2Wave {
                    accesses: st.accesses,
                    hits: st.hits,
                    misses: st.misses,
                    merges: st.merges,
                    bank_conflicts: st.bank_conflicts,
                    fills: st.fills,
                    writebacks: st.writebacks,
                    flush_cycles: self.flush_cycles,
                    combined: st.combined,
                }
            }),
            tm_rays_max: 0,
            tm_rays_min: 0,
            tms_with_rays: 0,
        }
    }

    fn sched_tm_rays(&self) -> Vec<u64> {
        self.sched().tm_rays().to_vec()
    }

    /// Units holding work, and what they wait for (the watchdog's report).
    pub fn holding(&self) -> Vec<String> {
        let mut v = Vec::new();
        let sch = self.sched();
        if !sch.idle() {
            v.push(format!("chip.scheduler: {}", sch.holding()));
        }
        if self.scene_buffer_unit().busy() {
            v.push("chip.scene_buffer: L1 misses wait for lines not streamed in, or responses in flight".into());
        }
        let h = self.hit_updater_unit();
        if h.busy() {
            let p = h.probe();
            v.push(format!(
                "chip.hit_updater: {} queued, {} read-compare-writes in flight",
                p.queued, p.in_flight
            ));
        }
        if let Some(l2) = self.l2_unit()
            && l2.busy()
        {
            let p = l2.probe();
            v.push(format!(
                "chip.l2: {} MSHRs live, {} memory requests queued, {} at the memory",
                p.live_mshrs, p.mem_queued, p.at_memory
            ));
        }
        let m = self.memory_unit().probe();
        if m.in_flight > 0 {
            v.push(format!("chip.memory: {} requests in flight", m.in_flight));
        }
        for (k, t) in self.tms.iter().enumerate() {
            let busy = t.tps.iter().filter(|&&u| self.tp(u).holds_work()).count();
            if busy > 0 {
                v.push(format!("chip.tm{k}: {busy} TPs hold a ray"));
            }
        }
        v
    }

    /// Records every segment pass's admission and retirement (see
    /// `take_pass_log`).
    pub fn enable_pass_log(&mut self) {
        self.sched_mut().enable_pass_log();
    }
    /// The segment passes retired since the last call.
    pub fn take_pass_log(&mut self) -> Vec<crate::units::stream_scheduler::PassEvent> {
        self.sched_mut().take_pass_log()
    }

    /// Records the rays written into the root queue (see `take_root_log`).
    pub fn enable_root_log(&mut self) {
        self.sched_mut().enable_root_log();
    }
    /// The rays written into the root queue since the last call.
    pub fn take_root_log(&mut self) -> Vec<RayRec> {
        self.sched_mut().take_root_log()
    }

    /// Traces one wavefront: `rays` into the root queue, run until idle. The DRAM
    /// image is lent to the memory unit for the run.
    pub fn trace_wave(
        &mut self,
        mem: &mut SparseMem,
        rays: &[RayRec],
    ) -> Result<WaveCycles, String> {
        self.run_wave(mem, rays, 0)
    }

    /// The shading pass of the finished wavefront over pixels `0..pixels` on the
    /// TPs, then the wavefront it emits (nothing, after the last one).
    pub fn shade_and_trace(
        &mut self,
        mem: &mut SparseMem,
        pixels: u32,
    ) -> Result<WaveCycles, String> {
        self.run_wave(mem, &[], pixels)
    }

    fn run_wave(
        &mut self,
        mem: &mut SparseMem,
        rays: &[RayRec],
        shade_pixels: u32,
    ) -> Result<WaveCycles, String> {
        let t0 = Instant::now();
        self.memory_unit_mut().swap_image(mem);
        let before = self.snapshot();
        let tm_before = self.sched_tm_rays();
        self.sched_mut().new_wave();
        let wave = self.wave;
        self.host_mut().load(rays.to_vec(), wave, shade_pixels);
        self.sim.wake(self.host);
        self.wave += 1;
        let mut res = self.run_until_idle();
        if res.is_ok() && self.l2.is_some() {
            // The host reads DRAM next: write the L2's dirty lines back (its
            // cycles count in the run).
            let inv = self.l2_invalidate;
            let c0 = self.sim.cycle(self.clock);
            self.host_mut().request_flush(inv);
            self.sim.wake(self.host);
            res = self.run_until_idle();
            self.flush_cycles += self.sim.cycle(self.clock) - c0;
        }
        self.memory_unit_mut().swap_image(mem);
        res?;
        let after = self.snapshot();
        self.wall_s += t0.elapsed().as_secs_f64();
        let mut w = WaveCycles {
            cycles: after.cycles - before.cycles,
            rays_emitted: rays.len() as u64 + after.shade_rays - before.shade_rays,
            duplicates: after.duplicates
                - before.duplicates
                - rays.len() as u64
                - (after.shade_rays - before.shade_rays),
            shade_items: after.shade_items - before.shade_items,
            shade_rays: after.shade_rays - before.shade_rays,
            shade_shadow_rays: after.shade_shadow_rays - before.shade_shadow_rays,
            shade_hits: after.shade_hits - before.shade_hits,
            shade_occluded: after.shade_occluded - before.shade_occluded,
            shade_uses: std::array::from_fn(|k| after.shade_uses[k] - before.shade_uses[k]),
            shade_cycles: if shade_pixels > 0 {
                after.shade_cycles - before.cycles
            } else {
                0
            },
            segments_loaded: after.segments_loaded - before.segments_loaded,
            box_tests: after.box_tests - before.box_tests,
            tri_tests: after.tri_tests - before.tri_tests,
            exits: after.exits - before.exits,
            pops: after.pops - before.pops,
            tri_hits: after.tri_hits - before.tri_hits,
            l1_lines: after.l1_lines - before.l1_lines,
            max_stack: 0,
            hits_sent: after.hits_sent - before.hits_sent,
            lines_read: [0; StreamTag::COUNT],
            lines_written: [0; StreamTag::COUNT],
            hit_merged: after.hit_merged - before.hit_merged,
            scene_buffer_stalls: after.scene_buffer_stalls - before.scene_buffer_stalls,
            scene_buffer_stall_cycles: after.scene_buffer_stall_cycles
                - before.scene_buffer_stall_cycles,
            scene_buffer_reads: after.scene_buffer_reads - before.scene_buffer_reads,
            evals: after.evals - before.evals,
            dram: after.dram.sub(&before.dram),
            l2: after.l2.sub(&before.l2),
            // The end-of-run L2 flush is not the pass draining: it is counted
            // apart (`l2.flush_cycles`).
            drain_cycles: after.cycles
                - (after.l2.flush_cycles - before.l2.flush_cycles)
                - self.sched().probe().last_marker.max(before.cycles),
            tm_rays_max: 0,
            tm_rays_min: 0,
            tms_with_rays: 0,
        };
        for k in 0..StreamTag::COUNT {
            w.lines_read[k] = after.lines_read[k] - before.lines_read[k];
            w.lines_written[k] = after.lines_written[k] - before.lines_written[k];
        }
        let per_tm: Vec<u64> = self
            .sched_tm_rays()
            .iter()
            .zip(&tm_before)
            .map(|(a, b)| a - b)
            .collect();
        w.tm_rays_max = per_tm.iter().copied().max().unwrap_or(0);
        w.tm_rays_min = per_tm.iter().copied().min().unwrap_or(0);
        w.tms_with_rays = per_tm.iter().filter(|&&r| r > 0).count() as u64;
        w.max_stack = self
            .tps()
            .map(|u| self.tp(u).probe().max_stack)
            .max()
            .unwrap_or(0);
        self.total_cycles += w.cycles;
        self.check_drained()?;
        if self.dram.as_ref().is_some_and(|d| d.check) {
            let v = self.dram_violations();
            if !v.is_empty() {
                return Err(format!(
                    "{} DRAM timing violations (chip.memory.check_timing), first: {}",
                    v.len(),
                    v[0]
                ));
            }
        }
        Ok(w)
    }

    /// Time sampling: the chip takes a wavefront over at a segment boundary of the
    /// functional model (`b`: the queues holding rays and the bucket pool, laid out
    /// in `mem`), runs `warm` admissions to fill the working set, then measures the
    /// next `measure` admissions (or, with `kind` = [`WindowKind::Shade`], the
    /// shading pass over `0..pixels` from item `warm` to item `warm + measure`),
    /// and stops. The window is a sample, not a finished wavefront: the chip is
    /// spent (its state is abandoned mid-flight), and so is `mem`, a snapshot of
    /// the functional model's image (`SparseMem::clone`), which carries on as if
    /// the window had not run.
    /// `None` when the wavefront ends before the measurement starts; a measurement
    /// cut short by the wavefront's end covers the rest of it (`WindowRun::ended`).
    pub fn trace_window(
        mut self,
        mem: SparseMem,
        kind: WindowKind,
        warm: (u64, u64),
        measure: u64,
    ) -> Result<Option<WindowRun>, String> {
        self.window_inner(mem, kind, warm, measure)
    }

    fn window_inner(
        &mut self,
        mut mem: SparseMem,
        kind: WindowKind,
        (warm, warm_cycles): (u64, u64),
        measure: u64,
    ) -> Result<Option<WindowRun>, String> {
        let sch = self.scheduler;
        if let WindowKind::Trace(b) | WindowKind::Root(b) | WindowKind::Wave { boundary: b, .. } =
            &kind
        {
            let map = self.sched().memory_map().clone();
            for (s, rec) in &b.queues {
                mem.write(map.queue_rec_addr(*s), &rec.encode());
            }
            for (a, bytes) in &b.writes {
                mem.write(*a, bytes);
            }
        }
        self.memory_unit_mut().set_image(mem);
        match &kind {
            WindowKind::Trace(b) | WindowKind::Root(b) | WindowKind::Wave { boundary: b, .. } => {
                self.sched_mut().resume(b);
                self.sim.wake(sch);
            }
            WindowKind::Emit(rays) => {
                self.host_mut().load(rays.clone(), 0, 0);
                self.sim.wake(self.host);
            }
            WindowKind::Shade {
                first,
                pixels,
                pool,
            } => {
                let u = self.sched_mut();
                u.resume(pool);
                u.shade_from(*first);
                self.host_mut().load(Vec::new(), 1, *pixels);
                self.sim.wake(self.host);
            }
        }
        // What is counted, and when the stretch is over without the wavefront's
        // end: all rays emitted, or all items of a shading pass done (the chip
        // would go on to trace what was emitted).
        let (mark, all) = match &kind {
            WindowKind::Trace(_) => (0, u64::MAX),
            WindowKind::Emit(rays) => (1, rays.len() as u64),
            WindowKind::Shade { first, pixels, .. } => (2, (pixels - first.min(pixels)) as u64),
            // At a wavefront's start only the root queue holds rays.
            WindowKind::Root(b) => (3, b.queues.iter().map(|(_, q)| q.rays as u64).sum()),
            WindowKind::Wave { tenths, step, .. } => return self.wave_window(*tenths, *step),
        };
        let root = mark == 3;
        let count = |c: &Chip| {
            let u = c.sched();
            let st = u.stats();
            [
                st.segments_loaded,
                st.enqueues,
                st.shade_done,
                u.done_by_segment().first().copied().unwrap_or(0),
            ][mark]
        };
        // A root window's pass is over when its children are admitted (it is
        // checked in steps, so their first rays may have gone out).
        let root_over = |c: &Chip| root && c.sched().stats().segments_loaded >= 2;
        let period = self.sim.clocks()[self.clock.0 as usize].period_ps;
        let start = self.snapshot();
        let owed = |a: &[u64; StreamTag::COUNT], b: &[u64; StreamTag::COUNT]| {
            std::array::from_fn(|k| b[k] as i64 - a[k] as i64)
        };
        let mut from: Option<(WaveCycles, u64, [u64; StreamTag::COUNT])> = None;
        // A root window's measured stretch, once over (it runs on to the end).
        let mut stretch: Option<(WaveCycles, u64)> = None;
        let mut done0 = Vec::new();
        let mut idle_run = 0u64;
        let t0 = self.sim.now();
        loop {
            let n = count(self);
            if from.is_none() && n >= warm && self.sim.now() - t0 >= warm_cycles * period {
                // A root window's L2 started empty: all it dirties is owed.
                let d0 = if root {
                    [0; StreamTag::COUNT]
                } else {
                    self.l2_dirty()
                };
                from = Some((self.snapshot(), n, d0));
                done0 = self.sched().done_by_segment().to_vec();
            }
            if from.is_none() && n >= all {
                return Ok(None);
            }
            if let Some((a, n0, d0)) = &from
                && stretch.is_none()
                && (n >= n0.saturating_add(measure) || n >= all)
            {
                if root {
                    stretch = Some((self.snapshot(), n));
                } else {
                    return Ok(Some(WindowRun {
                        counts: self.snapshot().since(a),
                        marks: n - n0,
                        from: *n0,
                        ended: n >= all,
                        warm: a.since(&start),
                        dirtied: owed(d0, &self.l2_dirty()),
                        passes: self.take_pass_log(),
                        done: self.done_since(&done0),
                        after: WaveCycles::default(),
                    }));
                }
            }
            let end = self.window_step()?;
            if end == crate::rtl::RunEnd::Idle || root_over(self) {
                let Some((a, n0, d0)) = &from else {
                    return Ok(None);
                };
                let now = self.snapshot();
                let (b, n1) = stretch.unwrap_or((now, count(self)));
                return Ok(Some(WindowRun {
                    counts: b.since(a),
                    marks: n1 - n0,
                    from: *n0,
                    ended: true,
                    warm: a.since(&start),
                    dirtied: owed(d0, &self.l2_dirty()),
                    passes: self.take_pass_log(),
                    done: self.done_since(&done0),
                    after: now.since(&b),
                }));
            }
            idle_run = self.window_watchdog(idle_run)?;
            if count(self) > n {
                idle_run = 0;
            }
        }
    }

    /// The rest of [`WindowKind::Wave`] (set up by `window_inner`): runs the
    /// wavefront to its end, looking at its visits (rays finished in any
    /// segment) every `step`, and measures the stretch between the looks at
    /// `tenths` of the visits it did in all (the total is known only at the
    /// end). Its L2 started empty, so all it leaves dirty is owed.
    fn wave_window(&mut self, tenths: (u64, u64), step: u64) -> Result<Option<WindowRun>, String> {
        let visits = |c: &Chip| -> u64 { c.sched().done_by_segment().iter().sum() };
        let start = self.snapshot();
        let done0 = self.sched().done_by_segment().to_vec();
        let v0 = visits(self);
        let mut looks: Vec<(u64, WaveCycles)> = Vec::new();
        let mut next = 0u64;
        let mut idle_run = 0u64;
        loop {
            let end = self.window_step()?;
            let n = visits(self) - v0;
            if n >= next {
                looks.push((n, self.snapshot()));
                next = n + step.max(1);
                idle_run = 0;
            }
            if end == crate::rtl::RunEnd::Idle {
                break;
            }
            idle_run = self.window_watchdog(idle_run)?;
        }
        let total = visits(self) - v0;
        if total == 0 {
            return Ok(None);
        }
        let now = self.snapshot();
        let at = |t: u64| {
            let want = total * t / 10;
            looks
                .iter()
                .find(|(n, _)| *n >= want)
                .cloned()
                .unwrap_or((total, now))
        };
        let ((n0, a), (n1, b)) = (at(tenths.0), at(tenths.1));
        Ok(Some(WindowRun {
            counts: b.since(&a),
            marks: n1 - n0,
            from: n0,
            ended: true,
            warm: a.since(&start),
            dirtied: self.l2_dirty().map(|x| x as i64),
            passes: self.take_pass_log(),
            done: self.done_since(&done0),
            after: now.since(&b),
        }))
    }

    /// Runs a sampling window for [`WINDOW_STEP`] cycles: how the run ended,
    /// or the scheduler's error.
    fn window_step(&mut self) -> Result<crate::rtl::RunEnd, String> {
        let period = self.sim.clocks()[self.clock.0 as usize].period_ps;
        let end = self
            .sim
            .run_until(self.sim.now() + WINDOW_STEP * period)
            .map_err(|e| e.to_string())?;
        match self.sched().error() {
            Some(e) => Err(e.to_string()),
            None => Ok(end),
        }
    }

    /// A window's cycles without progress after one more step, or an error
    /// once they pass 64 watchdog periods.
    fn window_watchdog(&self, idle_run: u64) -> Result<u64, String> {
        let idle_run = idle_run + WINDOW_STEP;
        if idle_run > self.watchdog.max(WINDOW_STEP) * 64 {
            return Err(self.stuck("a sampling window did not reach its marks"));
        }
        Ok(idle_run)
    }

    /// Rays finished (end markers) since the counts `d0`, by segment.
    fn done_since(&self, d0: &[u64]) -> Vec<(u32, u64)> {
        let d = self.sched().done_by_segment();
        d.iter()
            .zip(d0)
            .enumerate()
            .filter(|(_, (a, b))| a > b)
            .map(|(s, (a, b))| (s as u32, a - b))
            .collect()
    }

    /// Dirty L2 lines by stream tag (none without an L2).
    fn l2_dirty(&self) -> [u64; StreamTag::COUNT] {
        self.l2_unit()
            .map_or([0; StreamTag::COUNT], |u| u.dirty_by_tag())
    }

    /// Runs in watchdog windows until every unit sleeps with nothing scheduled.
    fn run_until_idle(&mut self) -> Result<(), String> {
        let period = self.sim.clocks()[self.clock.0 as usize].period_ps;
        let mut last_progress = self.progress();
        loop {
            let limit = self.sim.now() + self.watchdog * period;
            let end = self
                .sim
                .run_to_idle(limit)
                .map(|_| true)
                .or_else(|e| match e {
                    crate::rtl::SimError::Elaboration(m) if m.contains("still busy") => Ok(false),
                    e => Err(e.to_string()),
                })?;
            if let Some(e) = self.sched().error() {
                return Err(e.to_string());
            }
            if end {
                return Ok(());
            }
            let p = self.progress();
            if p == last_progress {
                return Err(self.stuck(&format!(
                    "no progress for {} cycles (chip.watchdog_cycles)",
                    self.watchdog
                )));
            }
            last_progress = p;
        }
    }

    /// A monotonic measure of work done (memory answers, rays forwarded, markers).
    fn progress(&self) -> (u64, u64, u64, u64) {
        let st = self.sched().stats();
        (
            self.memory_unit().probe().responses,
            st.rays_forwarded,
            st.markers + st.shade_done,
            self.scene_buffer_unit().probe().reads,
        )
    }

    fn stuck(&self, why: &str) -> String {
        // A TP whose stack overflowed stops for good; the chip then starves.
        // That is the cause to report, not the starvation.
        let overflowed: Vec<String> = self
            .tms
            .iter()
            .enumerate()
            .flat_map(|(k, t)| {
                t.tps
                    .iter()
                    .enumerate()
                    .filter(|&(_, &u)| self.tp(u).overflowed())
                    .map(move |(j, _)| format!("chip.tm{k}.tp{j}"))
            })
            .collect();
        if let Some(first) = overflowed.first() {
            let (pad, entry) = self.stack_cfg;
            let need = match self.stack_need {
                Some(n) => format!(
                    "; this scene's segments can need up to {n} entries: tm.scratchpad_bytes = {} holds them",
                    n * entry
                ),
                None => String::new(),
            };
            return format!(
                "the traversal stack of {first} overflowed at cycle {} ({} TPs overflowed): \
                 tm.scratchpad_bytes = {pad} holds {} entries of tm.stack_entry_bytes = {entry}; \
                 raise tm.scratchpad_bytes{need}",
                self.sim.cycle(self.clock),
                overflowed.len(),
                pad / entry.max(1),
            );
        }
        let mut msg = format!(
            "the chip is stuck at cycle {}: {why}",
            self.sim.cycle(self.clock)
        );
        let sch = self.sched();
        if sch.dest_blocked() {
            msg.push_str(&format!(
                "; the destination table is full (chip.scheduler.dest_entries = {}): raise it",
                sch.dest_entries()
            ));
        }
        msg.push_str("; units holding work:");
        for h in self.holding() {
            msg.push_str("\n  ");
            msg.push_str(&h);
        }
        msg
    }

    /// Nothing is lost: asserted after every wavefront.
    fn check_drained(&self) -> Result<(), String> {
        let s = &self.sim;
        let sch = self.sched();
        let held = self.holding();
        if !held.is_empty() {
            return Err(self.stuck("every unit sleeps but work is left (a deadlock)"));
        }
        for seg in 0..self.segments {
            let (enq, done) = (sch.enqueued_by_segment()[seg], sch.done_by_segment()[seg]);
            if enq != done {
                return Err(format!(
                    "segment {seg}: {enq} rays enqueued but {done} processed in this wavefront"
                ));
            }
        }
        if sch.live_buckets() != 0 {
            return Err(format!(
                "{} ray buckets were not freed at the end of the wavefront",
                sch.live_buckets()
            ));
        }
        let m = self.memory_unit().probe();
        if m.requests != m.responses {
            return Err("a memory request was not answered".into());
        }
        for (i, (name, _)) in s.link_stats().into_iter().enumerate() {
            if s.link_occupancy(crate::rtl::LinkId(i as u32)) > 0 {
                return Err(format!(
                    "link '{name}' still holds data at the end of the wavefront"
                ));
            }
        }
        Ok(())
    }
}
