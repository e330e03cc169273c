//! Time sampling's chip side: every window on a fresh chip, on a snapshot of the
//! functional model's DRAM image. With more than one simulator thread the windows
//! run on worker threads (one chip each, single-threaded) while the functional
//! model goes on: a window reads nothing the functional model writes after its
//! snapshot, and its samples are put back in the order the windows were taken, so
//! the record is the same as with one thread.

use crate::sampling::SamplingError;
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, sync_channel};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use super::{SampleKind, WindowPlan, WindowRecord, WindowSample};
use crate::contract::Boundary;
use crate::contract::{MemoryMap, RayRec, SparseMem};
use crate::machine::WindowKind;
use crate::render::Prepared;
use crate::units::shade::{ShadeConsts, mix64};

/// What every window of a frame is built from.
struct WindowChip {
    cfg: crate::config::Config,
    map: MemoryMap,
    consts: ShadeConsts,
    segments: usize,
    sim: crate::rtl::SimOptions,
    /// When time sampling began (`WindowSample::start_s` counts from it).
    began: Instant,
}

/// One window: what the chip runs (`Chip::trace_window`) and the sample it
/// gives (`kind` in wavefront `wave`, its first measured mark `first`).
pub(super) struct WindowSpec {
    pub(super) what: WindowKind,
    pub(super) warm: u64,
    /// And at least these cycles of warm-up.
    pub(super) warm_cycles: u64,
    pub(super) measure: u64,
    pub(super) wave: usize,
    pub(super) kind: SampleKind,
    pub(super) first: u64,
}

/// A window to run on its snapshot of the image.
struct WindowJob {
    /// Its place among the frame's windows (the record's order).
    order: usize,
    mem: SparseMem,
    spec: WindowSpec,
}

type Done = (usize, Result<Option<WindowSample>, SamplingError>);

impl WindowChip {
    /// Runs one window on a fresh chip; `None` when it measured nothing.
    fn run(&self, job: WindowJob) -> Result<Option<WindowSample>, SamplingError> {
        let t = Instant::now();
        let shared;
        let cfg = if let WindowKind::Wave { l2_share, .. } = job.spec.what
            && l2_share > 1
        {
            shared = sample_config(&self.cfg, l2_share);
            &shared
        } else {
            &self.cfg
        };
        let mut chip = crate::machine::Chip::new(
            cfg,
            &self.map,
            self.segments,
            &self.consts,
            self.sim.clone(),
        )?;
        chip.enable_pass_log();
        let w = job.spec;
        let r = chip.trace_window(job.mem, w.what, (w.warm, w.warm_cycles), w.measure)?;
        Ok(r.map(|run| WindowSample {
            wave: w.wave,
            kind: w.kind,
            // A shading window's measurement starts where its warm-up really
            // ended: past the asked items (checked in steps, and run on for its
            // cycles); the lines proxy reads that range.
            first: if w.kind == SampleKind::Shade {
                w.first - w.warm + run.from
            } else {
                w.first
            },
            run,
            wall_s: t.elapsed().as_secs_f64(),
            start_s: t.duration_since(self.began).as_secs_f64(),
        }))
    }
}

/// Worker threads taking windows from a queue of at most one per worker (each
/// queued window holds a snapshot, whose pages the functional model's writes copy).
struct Pool {
    jobs: Option<SyncSender<WindowJob>>,
    done: Receiver<Done>,
    workers: Vec<JoinHandle<()>>,
}

impl Pool {
    fn new(chip: &Arc<WindowChip>, workers: usize) -> Result<Pool, SamplingError> {
        let (jobs, rx) = sync_channel::<WindowJob>(workers);
        let rx = Arc::new(Mutex::new(rx));
        let (tx, done) = std::sync::mpsc::channel::<Done>();
        let workers = (0..workers)
            .map(|k| {
                let (chip, rx, tx) = (chip.clone(), rx.clone(), tx.clone());
                std::thread::Builder::new()
                    .name(format!("window-{k}"))
                    .spawn(move || {
                        loop {
                            // The lock is held while waiting for a job only.
                            let job = rx
                                .lock()
                                .map_err(|_| ())
                                .and_then(|r| r.recv().map_err(|_| ()));
                            let Ok(job) = job else { break };
                            let order = job.order;
                            if tx.send((order, chip.run(job))).is_err() {
                                break;
                            }
                        }
                    })
                    .map_err(|e| {
                        SamplingError::Worker(format!(
                            "cannot start a time-sampling worker thread: {e}"
                        ))
                    })
            })
            .collect::<Result<Vec<_>, SamplingError>>()?;
        Ok(Pool {
            jobs: Some(jobs),
            done,
            workers,
        })
    }

    /// Stops taking windows and waits for the workers; with `raise`, a worker's
    /// panic goes on here, as it would have on the caller's thread.
    fn stop(&mut self, raise: bool) {
        self.jobs = None;
        for w in self.workers.drain(..) {
            if let Err(p) = w.join()
                && raise
            {
                std::panic::resume_unwind(p);
            }
        }
    }
}

impl Drop for Pool {
    fn drop(&mut self) {
        // On an early return (an error elsewhere) the running windows finish
        // and are dropped; a panic while already unwinding is not raised again.
        self.stop(false);
    }
}

/// Time sampling's windows of one frame, and what they measured.
pub(super) struct Windows {
    pub(super) plan: WindowPlan,
    chip: Arc<WindowChip>,
    pool: Option<Pool>,
    /// Windows taken, and windows whose result is in.
    sent: usize,
    got: Vec<(usize, WindowSample)>,
    answered: usize,
    pub(super) rec: WindowRecord,
}

impl Windows {
    /// `sim.threads` above one runs that many windows at once, each chip on one
    /// thread.
    pub(super) fn new(
        plan: WindowPlan,
        cfg: crate::config::Config,
        map: MemoryMap,
        consts: ShadeConsts,
        segments: usize,
        sim: crate::rtl::SimOptions,
        pixels: u32,
    ) -> Result<Windows, SamplingError> {
        let share = plan.wave_l2_share;
        if plan.wave_rays > 0 && cfg.chip.l2.enabled {
            let l2 = sample_config(&cfg, share.max(1)).chip.l2;
            if share == 0 || l2.bytes * share != cfg.chip.l2.bytes {
                return Err(SamplingError::Invalid(format!(
                    "--window-wave-l2 {share}: a wavefront sample's L2 is chip.l2.bytes ({}) divided by it; give a divisor of it",
                    cfg.chip.l2.bytes
                )));
            }
            l2.validate(cfg.chip.links.delay).map_err(|e| {
                SamplingError::Invalid(format!("--window-wave-l2 {share} leaves the sample an impossible L2 ({e}); give a smaller share"))
            })?;
        }
        let workers = sim.threads;
        let chip = Arc::new(WindowChip {
            cfg,
            map,
            consts,
            segments,
            sim: crate::rtl::SimOptions { threads: 1, ..sim },
            began: Instant::now(),
        });
        let pool = if workers > 1 {
            Some(Pool::new(&chip, workers)?)
        } else {
            None
        };
        let head = plan.head;
        Ok(Windows {
            plan,
            chip,
            pool,
            sent: 0,
            got: Vec::new(),
            answered: 0,
            rec: WindowRecord {
                pixels,
                head,
                ..WindowRecord::default()
            },
        })
    }

    /// Windows answered and windows taken so far.
    pub(super) fn counts(&self) -> (usize, usize) {
        (self.answered, self.sent)
    }

    /// Takes window `spec` on a snapshot of the image now and records what it
    /// measures.
    pub(super) fn run(&mut self, p: &Prepared, spec: WindowSpec) -> Result<(), SamplingError> {
        let job = WindowJob {
            order: self.sent,
            mem: p.mem.clone(),
            spec,
        };
        self.sent += 1;
        match &self.pool {
            None => {
                let r = self.chip.run(job);
                self.keep(self.sent - 1, r)
            }
            Some(pool) => {
                let jobs = pool.jobs.as_ref().expect("open until finish");
                if jobs.send(job).is_err() {
                    return Err(self.worker_lost());
                }
                self.collect(false)
            }
        }
    }

    fn keep(
        &mut self,
        order: usize,
        r: Result<Option<WindowSample>, SamplingError>,
    ) -> Result<(), SamplingError> {
        self.answered += 1;
        if let Some(s) = r? {
            self.rec.chip_s += s.wall_s;
            self.got.push((order, s));
        }
        Ok(())
    }

    /// Takes in the results that are there (`wait`: all that are owed).
    fn collect(&mut self, wait: bool) -> Result<(), SamplingError> {
        while self.answered < self.sent {
            let pool = self.pool.as_ref().expect("only with workers");
            let (order, r) = if wait {
                match pool.done.recv() {
                    Ok(d) => d,
                    Err(_) => return Err(self.worker_lost()),
                }
            } else {
                match pool.done.try_recv() {
                    Ok(d) => d,
                    Err(TryRecvError::Empty) => return Ok(()),
                    Err(TryRecvError::Disconnected) => return Err(self.worker_lost()),
                }
            };
            self.keep(order, r)?;
        }
        Ok(())
    }

    /// A worker died (a panic): close the pool, which raises it here.
    fn worker_lost(&mut self) -> SamplingError {
        if let Some(p) = self.pool.as_mut() {
            p.stop(true);
        }
        SamplingError::Worker("a time-sampling worker thread stopped without a result".into())
    }

    /// Waits for every window and returns the record, its samples in the order
    /// the windows were taken. `chip_s` is the windows' summed wall time (more
    /// than the frame's when they ran side by side).
    pub(super) fn finish(mut self) -> Result<WindowRecord, SamplingError> {
        if let Some(p) = self.pool.as_mut() {
            p.jobs = None;
            self.collect(true)?;
        }
        if let Some(p) = self.pool.as_mut() {
            p.stop(true);
        }
        self.got.sort_by_key(|(o, _)| *o);
        self.rec.samples = self.got.drain(..).map(|(_, s)| s).collect();
        Ok(self.rec)
    }

    /// The host emitting the primary rays: its first `rays`, measured after the
    /// shading windows' warm-up (emission is the same for every ray).
    pub(super) fn emit_window(
        &mut self,
        p: &Prepared,
        rays: Vec<RayRec>,
    ) -> Result<(), SamplingError> {
        let (mut warm, measure) = (self.plan.shade_warm, self.plan.shade_measure);
        if (rays.len() as u64) < warm.saturating_add(measure) {
            // A frame smaller than the window: all of it, measured.
            warm = 0;
        }
        let spec = WindowSpec {
            what: WindowKind::Emit(rays),
            warm,
            warm_cycles: 0,
            measure,
            wave: 0,
            kind: SampleKind::Emit,
            first: warm,
        };
        self.run(p, spec)
    }

    /// The shading pass after wavefront `wave`: windows spread over the pixels,
    /// each with the bucket pool as the wavefront left it (`pool`, no queue
    /// holding rays), where the pass's rays go.
    pub(super) fn shade_windows(
        &mut self,
        p: &Prepared,
        wave: usize,
        pixels: u32,
        pool: &Boundary,
    ) -> Result<(), SamplingError> {
        // The pass's start as is (its first `shade_head` items: the caches and
        // the memory's queues fill), then windows over the other pixels.
        let head = self.plan.shade_head.min(pixels as u64) as u32;
        let span = self.plan.shade_warm.saturating_add(self.plan.shade_measure);
        let plan: Vec<(u32, u64, u64, SampleKind)> = (head > 0)
            .then_some((0, 0, head as u64, SampleKind::ShadeHead))
            .into_iter()
            .chain(
                shade_window_starts(head, pixels, self.plan.shade_windows, span, wave)
                    .into_iter()
                    .map(|first| {
                        (
                            first,
                            self.plan.shade_warm,
                            self.plan.shade_measure,
                            SampleKind::Shade,
                        )
                    }),
            )
            .collect();
        for (first, warm, measure, kind) in plan {
            let what = WindowKind::Shade {
                first,
                pixels,
                pool: pool.clone(),
            };
            let spec = WindowSpec {
                what,
                warm,
                warm_cycles: if kind == SampleKind::Shade {
                    self.plan.shade_warm_cycles
                } else {
                    0
                },
                measure,
                wave,
                kind,
                first: first as u64 + warm,
            };
            self.run(p, spec)?;
        }
        Ok(())
    }
}

/// The chip a wavefront sample runs on: `cfg` with `1 / l2_share` of its L2
/// (see `WindowPlan::wave_l2_share`).
fn sample_config(cfg: &crate::config::Config, l2_share: u32) -> crate::config::Config {
    let mut c = cfg.clone();
    c.chip.l2.bytes /= l2_share;
    c
}

/// Where the `n` shading windows of wavefront `wave`'s pass start: one at a
/// hashed place in each of `n` equal strata of the pixels after the head,
/// leaving `span` items (warm-up and measurement) in its stratum where there
/// is room. Not at a fixed place in each: the pass's row activations swing
/// with a period of tens of thousands of items (the path-state, hit-record
/// and ray-bucket streams drift through the DRAM banks against each other),
/// and equal strata put every window at the same phase of it. In a stratum of
/// at least 16 spans the last window starts in its first seven eighths: a
/// warm-up that also waits for cycles takes more items than `span` says, and
/// one that runs out of items measures nothing, leaving its stratum unsampled
/// (docs/results/2026-11-26-speed-error-shading-windows-at-hashed-places.md).
pub(super) fn shade_window_starts(
    head: u32,
    pixels: u32,
    n: u32,
    span: u64,
    wave: usize,
) -> Vec<u32> {
    let rest = pixels.saturating_sub(head) as u64;
    (0..n as u64)
        .map(|j| {
            let (a, b) = (j * rest / n as u64, (j + 1) * rest / n as u64);
            let last = j + 1 == n as u64;
            let reserve = if last && b - a >= span.saturating_mul(16) {
                (b - a) / 8
            } else {
                0
            };
            let room = (b - a).saturating_sub(span + reserve) + 1;
            let at = mix64(((wave as u64) << 32 | j) ^ 0x5348_4144_4557_494e) % room;
            head + (a + at) as u32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::shade_window_starts;

    #[test]
    fn shading_windows_fall_in_their_strata_at_spread_phases() {
        let (head, pixels, span) = (16384u32, 1u32 << 20, 6144u64);
        let mut phases = Vec::new();
        for wave in 0..6 {
            let n = 16;
            let s = shade_window_starts(head, pixels, n, span, wave);
            assert_eq!(s.len(), n as usize);
            let len = (pixels - head) / n;
            for (j, &x) in s.iter().enumerate() {
                let a = head + j as u32 * len;
                assert!(x >= a && x as u64 + span <= (a + len) as u64, "{j}: {x}");
            }
            // Strata of 64 K items, about one period of the activations'
            // swing: a start at a fixed place in each would put all 96 at one
            // phase of it.
            phases.extend(s.iter().map(|&x| (x - head) % len));
        }
        // In strata of at least 16 spans the last window leaves an eighth of
        // its stratum for a warm-up that takes more items than asked.
        for wave in 0..64 {
            let s = shade_window_starts(head, pixels, 4, span, wave);
            let len = ((pixels - head) / 4) as u64;
            assert!(
                s[3] as u64 + span + len / 8 <= pixels as u64,
                "wave {wave}: {s:?}"
            );
        }
        phases.sort_unstable();
        let len = (pixels - head) / 16;
        let quarters: Vec<usize> = (0..4)
            .map(|q| phases.iter().filter(|&&p| p * 4 / len == q).count())
            .collect();
        assert!(quarters.iter().all(|&c| c >= 12), "{quarters:?}");
        // Another wavefront, other places; the same one, the same places.
        assert_ne!(
            shade_window_starts(head, pixels, 2, span, 0),
            shade_window_starts(head, pixels, 2, span, 1)
        );
        assert_eq!(
            shade_window_starts(head, pixels, 2, span, 3),
            shade_window_starts(head, pixels, 2, span, 3)
        );
        // A stratum shorter than the span: its start.
        assert_eq!(shade_window_starts(10, 30, 2, 100, 0), vec![10, 20]);
    }
}
