//! Time sampling: a sampling window takes a wavefront (or a shading pass) over
//! mid-flight, warms up and measures a stretch of it (`Chip::trace_window`).

use crate::contract::{RayRec, SparseMem};
use crate::mem::StreamTag;

use super::{Chip, ChipError, WaveCycles};

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

impl Chip {
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
    ) -> Result<Option<WindowRun>, ChipError> {
        self.window_inner(mem, kind, warm, measure)
    }

    fn window_inner(
        &mut self,
        mem: SparseMem,
        kind: WindowKind,
        (warm, warm_cycles): (u64, u64),
        measure: u64,
    ) -> Result<Option<WindowRun>, ChipError> {
        self.load_window(mem, &kind);
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

    /// Sets a window up: the boundary's queue records and writes into the
    /// image `mem`, which the memory unit takes, and the scheduler (taking the
    /// wavefront over) or the host (emitting, or starting a shading pass)
    /// woken.
    fn load_window(&mut self, mut mem: SparseMem, kind: &WindowKind) {
        if let WindowKind::Trace(b) | WindowKind::Root(b) | WindowKind::Wave { boundary: b, .. } =
            kind
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
        match kind {
            WindowKind::Trace(b) | WindowKind::Root(b) | WindowKind::Wave { boundary: b, .. } => {
                self.sched_mut().resume(b);
                self.sim.wake(self.scheduler);
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
    }

    /// The rest of [`WindowKind::Wave`] (set up by `window_inner`): runs the
    /// wavefront to its end, looking at its visits (rays finished in any
    /// segment) every `step`, and measures the stretch between the looks at
    /// `tenths` of the visits it did in all (the total is known only at the
    /// end). Its L2 started empty, so all it leaves dirty is owed.
    fn wave_window(
        &mut self,
        tenths: (u64, u64),
        step: u64,
    ) -> Result<Option<WindowRun>, ChipError> {
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
    fn window_step(&mut self) -> Result<crate::rtl::RunEnd, ChipError> {
        let period = self.sim.clocks()[self.clock.0 as usize].period_ps;
        let end = self.sim.run_until(self.sim.now() + WINDOW_STEP * period)?;
        match self.sched().error() {
            Some(e) => Err(ChipError::Scheduler(e.to_string())),
            None => Ok(end),
        }
    }

    /// A window's cycles without progress after one more step, or an error
    /// once they pass 64 watchdog periods.
    fn window_watchdog(&self, idle_run: u64) -> Result<u64, ChipError> {
        let idle_run = idle_run + WINDOW_STEP;
        if idle_run > self.watchdog.max(WINDOW_STEP) * 64 {
            return Err(self.stuck(
                "a sampling window did not reach its marks",
                ChipError::Watchdog,
            ));
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
}
