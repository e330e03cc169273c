//! Running the chip: one wavefront (or a shading pass and the wavefront it
//! emits) to the end, in watchdog windows, and the scheduler's logs.

use std::time::Instant;

use crate::contract::{RayRec, SparseMem};

use super::{Chip, ChipError, WaveCycles};

/// Core cycles between two progress ticks of a chip run: a few a second
/// at the chip's simulated speed (about 50 K cycles/s on the paper's 128 TMs).
pub const TICK_CYCLES: u64 = 10_000;

impl Chip {
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
    ) -> Result<WaveCycles, ChipError> {
        self.run_wave(mem, rays, 0, &mut |_| {})
    }

    /// [`Chip::trace_wave`], calling `tick` with the core cycle reached
    /// about every [`TICK_CYCLES`] (progress; the run is the same).
    pub fn trace_wave_ticking(
        &mut self,
        mem: &mut SparseMem,
        rays: &[RayRec],
        tick: &mut dyn FnMut(u64),
    ) -> Result<WaveCycles, ChipError> {
        self.run_wave(mem, rays, 0, tick)
    }

    /// The shading pass of the finished wavefront over pixels `0..pixels` on the
    /// TPs, then the wavefront it emits (nothing, after the last one).
    pub fn shade_and_trace(
        &mut self,
        mem: &mut SparseMem,
        pixels: u32,
    ) -> Result<WaveCycles, ChipError> {
        self.run_wave(mem, &[], pixels, &mut |_| {})
    }

    /// [`Chip::shade_and_trace`], calling `tick` as [`Chip::trace_wave_ticking`].
    pub fn shade_and_trace_ticking(
        &mut self,
        mem: &mut SparseMem,
        pixels: u32,
        tick: &mut dyn FnMut(u64),
    ) -> Result<WaveCycles, ChipError> {
        self.run_wave(mem, &[], pixels, tick)
    }

    fn run_wave(
        &mut self,
        mem: &mut SparseMem,
        rays: &[RayRec],
        shade_pixels: u32,
        tick: &mut dyn FnMut(u64),
    ) -> Result<WaveCycles, ChipError> {
        let t0 = Instant::now();
        self.memory_unit_mut().swap_image(mem);
        let before = self.snapshot();
        let tm_before = self.sched_tm_rays();
        self.sched_mut().new_wave();
        let wave = self.wave;
        if let Some(f) = &self.follow {
            f.set_wave(wave);
        }
        self.host_mut().load(rays.to_vec(), wave, shade_pixels);
        self.sim.wake(self.host);
        self.wave += 1;
        let mut res = self.run_until_idle(tick);
        if res.is_ok() && self.l2.is_some() {
            // The host reads DRAM next: write the L2's dirty lines back (its
            // cycles count in the run).
            let inv = self.l2_invalidate;
            let c0 = self.sim.cycle(self.clock);
            self.host_mut().request_flush(inv);
            self.sim.wake(self.host);
            res = self.run_until_idle(tick);
            self.flush_cycles += self.sim.cycle(self.clock) - c0;
        }
        self.memory_unit_mut().swap_image(mem);
        res?;
        let after = self.snapshot();
        self.wall_s += t0.elapsed().as_secs_f64();
        let last_marker = self.sched().probe().last_marker;
        let mut w = WaveCycles::of_wave(
            &before,
            &after,
            rays.len() as u64,
            shade_pixels,
            last_marker,
        );
        self.add_distribution(&mut w, &tm_before);
        self.total_cycles += w.cycles;
        self.check_drained()?;
        self.check_dram_timing()?;
        Ok(w)
    }

    /// Runs until every unit sleeps with nothing scheduled, in steps of
    /// [`TICK_CYCLES`] (each calls `tick`), checking for progress every
    /// watchdog window. Stopping at a step's end and going on is the same
    /// run as not stopping (`docs/kernel.md`).
    fn run_until_idle(&mut self, tick: &mut dyn FnMut(u64)) -> Result<(), ChipError> {
        let period = self.sim.clocks()[self.clock.0 as usize].period_ps;
        let mut last_progress = self.progress();
        let mut window_end = self.sim.now() + self.watchdog * period;
        loop {
            let limit = (self.sim.now() + TICK_CYCLES * period).min(window_end);
            let end = self
                .sim
                .run_to_idle(limit)
                .map(|_| true)
                .or_else(|e| match e {
                    crate::rtl::SimError::Busy { .. } => Ok(false),
                    e => Err(e),
                })?;
            if let Some(e) = self.sched().error() {
                return Err(ChipError::Scheduler(e.to_string()));
            }
            if end {
                return Ok(());
            }
            tick(self.sim.cycle(self.clock));
            if self.sim.now() < window_end {
                continue;
            }
            window_end = self.sim.now() + self.watchdog * period;
            let p = self.progress();
            if p == last_progress {
                return Err(self.stuck(
                    &format!(
                        "no progress for {} cycles (chip.watchdog_cycles)",
                        self.watchdog
                    ),
                    ChipError::Watchdog,
                ));
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
}
