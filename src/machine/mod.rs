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
//!
//! The chip top's code, by step: `build` (elaboration and wiring), `run` (a
//! wavefront to the end), `counts` (the figures of a run, from the units'
//! probes), `window` (time-sampling windows), `watchdog` (stuck and drain
//! reports), `follow` (following rays, `render --follow-ray`).

pub mod hdl;
pub mod host;
pub mod trace;

mod build;
mod counts;
mod error;
mod follow;
mod run;
mod watchdog;
mod window;

pub use counts::{DramWave, L2Wave, WaveCycles};
pub use error::ChipError;
pub use window::{WindowKind, WindowRun};

use crate::mem::MemCfg;
use crate::mem::energy::EnergyModel;
use crate::rtl::{ClockId, Sim, UnitId};
use crate::units::hit_record_updater::HitRecordUpdater;
use crate::units::l2::L2;
use crate::units::mem_ctrl::MemCtrl;
use crate::units::memory::Memory;
use crate::units::scene_buffer::SceneBuffer;
use crate::units::stream_scheduler::StreamScheduler;
use crate::units::tm::TmUnits;
use crate::units::tp::Tp;
use host::Host;

/// Memory ports.
pub const PORT_SCHED: usize = 0;
pub const PORT_SCENE: usize = 1;
/// The hit record updater's port, or the L2's memory side when the chip has one.
pub const PORT_HITS: usize = 2;
pub const PORT_L2: usize = 2;

/// The GDDR5 side of the chip (`chip.memory.model = "gddr5"`).
struct Dram {
    clock: ClockId,
    ctrls: Vec<UnitId>,
    cfg: MemCfg,
    paper: EnergyModel,
    physical: EnergyModel,
    check: bool,
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
    /// The rays followed (`Chip::follow`), if any.
    follow: Option<crate::units::follow::FollowLog>,
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
