//! Running the chip: one wavefront (or a shading pass and the wavefront it
//! emits) to the end, in watchdog windows, and the scheduler's logs.

use std::time::Instant;

use crate::contract::{RayRec, SparseMem};
use crate::mem::StreamTag;

use super::{Chip, WaveCycles};

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
}
