//! Running the chip in windows of a functional frame: the hooks that time
//! sampling puts into `render`'s functional trace ([`FunctionalHooks`]). At the
//! root pass of each wavefront they decide how it is measured (in windows,
//! borrowed from its neighbours, or over a sample of its rays); at the later
//! segment boundaries they hand the chip its windows (`windows.rs`).

use super::error::hook;
use super::record::WorkSoFar;
use super::windows::{WindowSpec, Windows};
use super::{
    BORROW_ALIKE, ROOT_STEADY_TENTHS, SAMPLE_BORROW_FROM, SampleKind, SegWork, WindowPlan,
    WindowRecord,
};
use crate::contract::RayRec;
use crate::render::queues::{self, RayQueues};
use crate::render::{self, Frame, FunctionalHooks, Prepared, RenderCfg, RenderError, WaveStats};
use crate::sampling::SamplingError;
use crate::scene::Scene;
use crate::units::shade::{next_f32, pixel_seed};

/// Renders `scene` in functional mode while the chip (`rc.chip`, as is)
/// measures the windows of `plan`: the frame and what the windows recorded.
pub fn render_windows(
    scene: &Scene,
    rc: &RenderCfg,
    plan: &WindowPlan,
) -> Result<(Frame, WindowRecord), SamplingError> {
    render_windows_progress(scene, rc, plan, &mut |_| {})
}

/// How far time sampling is: the functional frame's wavefront and segment
/// pass (segments go in depth-first id order), the windows answered and taken.
#[derive(Clone, Copy, Debug, Default)]
pub struct WindowsProgress {
    pub wave: usize,
    /// Wavefronts at most (hit points per path + 1).
    pub waves_max: usize,
    pub segment: u32,
    pub segments: u32,
    pub windows_done: usize,
    pub windows_taken: usize,
}

/// [`render_windows`], calling `progress` before each segment pass.
pub fn render_windows_progress(
    scene: &Scene,
    rc: &RenderCfg,
    plan: &WindowPlan,
    progress: &mut dyn FnMut(&WindowsProgress),
) -> Result<(Frame, WindowRecord), SamplingError> {
    let et = rc.early_termination();
    if et != crate::config::EarlyTermination::None {
        // The windows run the chip, which has no early termination yet.
        return Err(SamplingError::Invalid(render::only_functional(et)));
    }
    let mut hooks = Sampling {
        plan,
        rc,
        run: None,
        record: None,
        progress,
    };
    let frame = render::render_with_hooks(scene, rc, &mut |_| {}, &mut hooks)?;
    let record = hooks.record.ok_or_else(|| {
        SamplingError::Uncovered("the functional frame ended before its time sampling did".into())
    })?;
    Ok((frame, record))
}

/// Time sampling of one frame, as [`FunctionalHooks`].
struct Sampling<'a> {
    plan: &'a WindowPlan,
    rc: &'a RenderCfg,
    /// Built once the frame is laid out.
    run: Option<Run>,
    /// What the windows recorded, once the frame is traced.
    record: Option<WindowRecord>,
    progress: &'a mut dyn FnMut(&WindowsProgress),
}

/// Time sampling under way.
struct Run {
    plan: WindowPlan,
    windows: Windows,
    /// The frame's last possible wavefront (its bounce count).
    last: usize,
    pixels: u32,
    /// The rays of the last wavefront traced in windows (see `BORROW_ALIKE`).
    traced_rays: Option<u64>,
    /// Whether the last wavefront was one traced over a sample (see there).
    last_sampled: bool,
    wave: Wave,
}

/// What time sampling knows of the wavefront being traced.
struct Wave {
    segs: Vec<SegWork>,
    /// Segment passes admitted so far.
    ord: u64,
    tail_started: bool,
    tail_from: Option<u64>,
    /// Decided at the root pass, from the wavefront's rays.
    measured: bool,
    /// Decided there too: a wavefront too short to hold a window after its
    /// head is simulated whole from its second admission.
    whole: bool,
    /// The pass under way: its segment, its rays and the work before it.
    prev: Option<(u32, u64, WorkSoFar)>,
}

impl Default for Wave {
    fn default() -> Self {
        Wave {
            segs: Vec::new(),
            ord: 0,
            tail_started: false,
            tail_from: None,
            measured: true,
            whole: false,
            prev: None,
        }
    }
}

impl FunctionalHooks for Sampling<'_> {
    fn begin(&mut self, scene: &Scene, p: &Prepared, pixels: u32) -> Result<(), RenderError> {
        self.start(scene, p, pixels).map_err(hook)
    }

    fn generated(
        &mut self,
        scene: &Scene,
        p: &Prepared,
        sample: &[u32],
    ) -> Result<(), RenderError> {
        match self.run.as_mut() {
            Some(r) => r.emit_window(scene, p, sample).map_err(hook),
            None => Ok(()),
        }
    }

    fn segment(
        &mut self,
        wave: usize,
        s: u32,
        p: &mut Prepared,
        q: &RayQueues,
        st: &WaveStats,
    ) -> Result<(), RenderError> {
        let Some(r) = self.run.as_mut() else {
            return Ok(());
        };
        let (windows_done, windows_taken) = r.windows.counts();
        (self.progress)(&WindowsProgress {
            wave,
            waves_max: r.last + 1,
            segment: s.min(p.seg.segments.len() as u32),
            segments: p.seg.segments.len() as u32,
            windows_done,
            windows_taken,
        });
        r.segment(wave, s, p, q, st).map_err(hook)
    }

    fn traced(&mut self, wave: usize, p: &Prepared, q: &RayQueues) -> Result<(), RenderError> {
        match self.run.as_mut() {
            Some(r) => r.traced(wave, p, q).map_err(hook),
            None => Ok(()),
        }
    }

    fn shaded(&mut self, lines: Vec<u8>) {
        if let Some(r) = self.run.as_mut() {
            r.windows.rec.shade_lines.push(lines);
        }
    }

    fn end(&mut self) -> Result<(), RenderError> {
        if let Some(r) = self.run.take() {
            self.record = Some(r.windows.finish().map_err(hook)?);
        }
        Ok(())
    }
}

impl Sampling<'_> {
    /// The frame is laid out: checks the plan and builds the windows' chip.
    fn start(&mut self, scene: &Scene, p: &Prepared, pixels: u32) -> Result<(), SamplingError> {
        self.plan.validate()?;
        if scene.settings.spp != 1 {
            return Err(SamplingError::Invalid(format!(
                "time sampling traces one path per pixel, not spp {}; use --spp 1, or --mode cycle for several",
                scene.settings.spp
            )));
        }
        let run = self.rc.chip.as_deref().cloned().unwrap_or_default();
        let mut c = run.config;
        c.accel = self.rc.accel.clone();
        c.memory = self.rc.memory.clone();
        if c.chip.shading != crate::config::Shading::Tps {
            return Err(SamplingError::Invalid(
                "time sampling needs the shading pass on the TPs (chip.shading = \"tps\")".into(),
            ));
        }
        let mut w = Windows::new(
            self.plan.clone(),
            c,
            p.map.clone(),
            render::shade_consts(scene, p),
            p.seg.segments.len(),
            run.sim,
            pixels,
        )?;
        w.rec.final_wave = scene.settings.bounces as usize;
        self.run = Some(Run {
            plan: self.plan.clone(),
            windows: w,
            last: scene.settings.bounces as usize,
            pixels,
            traced_rays: None,
            last_sampled: false,
            wave: Wave::default(),
        });
        Ok(())
    }
}

impl Run {
    /// The host emitting the primary rays: a window over the first pixels of
    /// `sample`, with the camera rays they have in the frame.
    fn emit_window(
        &mut self,
        scene: &Scene,
        p: &Prepared,
        sample: &[u32],
    ) -> Result<(), SamplingError> {
        let (w, h) = (scene.settings.width, scene.settings.height);
        let root_entry = p.image.root_entry.encode();
        let n = (self.plan.shade_warm.saturating_add(self.plan.shade_measure))
            .min(self.pixels as u64) as u32;
        let rays = (0..n)
            .map(|pix| {
                let real = sample[pix as usize];
                let mut rng = pixel_seed(scene.settings.seed, real);
                let jitter = (next_f32(&mut rng), next_f32(&mut rng));
                let (o, d) = scene.camera.ray(real % w, real / w, w, h, jitter);
                RayRec {
                    origin: o,
                    dir: d,
                    ray_id: pix,
                    entry: root_entry,
                }
            })
            .collect();
        self.windows.emit_window(p, rays)
    }

    /// Before each segment pass that holds rays (`s`; `u32::MAX` after the
    /// last): records the functional work of the pass before it and hands the
    /// chip the window that starts here, if any.
    fn segment(
        &mut self,
        wave: usize,
        s: u32,
        p: &mut Prepared,
        q: &RayQueues,
        st: &WaveStats,
    ) -> Result<(), SamplingError> {
        let now = WorkSoFar::of(st, q);
        if let Some((seg, rays, b)) = self.wave.prev.take() {
            self.wave.segs.push(now.since(&b, seg, rays));
        }
        if s == u32::MAX {
            return Ok(());
        }
        self.wave.prev = Some((s, q.len(s), now));
        let k = self.wave.ord;
        self.wave.ord += 1;
        if k == 0 {
            self.root_pass(wave, s, p, q)
        } else {
            self.trace_window(wave, k, p, q)
        }
    }

    /// The wavefront's root pass (segment `s`, its first admission): decides
    /// how the wavefront is measured and runs its sample or its root window.
    fn root_pass(
        &mut self,
        wave: usize,
        s: u32,
        p: &mut Prepared,
        q: &RayQueues,
    ) -> Result<(), SamplingError> {
        let plan = &self.plan;
        let last = self.last;
        // Borrowing needs neighbours alike: a wavefront whose rays
        // differ from the last measured one's by more than
        // `BORROW_ALIKE` is measured (an open scene's wavefronts
        // shrink, and a smaller one is more latency-bound).
        let rays = q.len(s);
        let alike =
            |m: Option<u64>| m.is_some_and(|m| rays.abs_diff(m) as f64 <= BORROW_ALIKE * m as f64);
        // Its passes: the last wavefront's, else one per segment.
        let rec = &self.windows.rec;
        let expect = rec.segs.last().map_or(p.seg.segments.len(), |s| s.len()) as u64;
        let whole = expect <= plan.first_window_start();
        // A short wavefront of many rays is traced over a
        // sample from its root pass to its end, unless it
        // borrows (below).
        let sampled = whole
            && plan.wave_rays > 0
            && rays > plan.wave_rays
            && plan.sample_streams_rays(
                rays,
                rec.segs.last().map(|s| s.as_slice()),
                expect,
                p.info.segment_bytes_mean,
            );
        // A sampled one between the third and the last borrows
        // from the sampled ones from the third on
        // (`windowed_parts`), so only right after
        // one: the first bounce's rays (from the primary hits)
        // cost more per visit than the later ones'
        // (docs/results/2026-11-28-speed-error-sampled-wavefronts-that-borrow.md).
        let measured = if sampled {
            plan.wave_every <= 1
                || wave <= SAMPLE_BORROW_FROM
                || wave >= last
                || !self.last_sampled
                || !alike(self.traced_rays)
        } else {
            plan.measures_wave(wave, last) || !alike(self.traced_rays)
        };
        self.wave.whole = whole;
        self.wave.measured = measured;
        self.last_sampled = sampled;
        if sampled && measured {
            self.traced_rays = Some(rays);
            self.wave_sample(wave, s, rays, p, q)?;
            // The first `wave_whole` of them from the second
            // on are simulated whole as well (root window and
            // the rest as the head), to correct the others.
            if !(1..=self.plan.wave_whole).contains(&(wave as u64)) {
                self.wave.tail_started = true;
                return Ok(());
            }
        }
        let plan = &self.plan;
        // Between the second wavefront and the last a root pass
        // is borrowed: by the ratio of its neighbours' root
        // windows if its rays are alike theirs, else on the line
        // through them (`root_between`: a smaller
        // root pass costs more per ray). A small one
        // (`WindowPlan::root_whole`) is simulated whole: cheap,
        // and so latency-bound that neither holds (docs/speed-error.md,
        // "Time sampling": borrowed wavefronts; docs/results/2026-11-26-speed-error-root-passes-on-a-line.md).
        let root = measured && (plan.measures_root(wave, last) || rays <= plan.root_whole());
        if measured {
            self.traced_rays = Some(rays);
        }
        if !root {
            return Ok(());
        }
        self.root_window(wave, s, p, q)
    }

    /// A short wavefront traced over a sample of its root queue (`rays` of
    /// them in segment `s`) from its root pass to its end.
    fn wave_sample(
        &mut self,
        wave: usize,
        s: u32,
        rays: u64,
        p: &Prepared,
        q: &RayQueues,
    ) -> Result<(), SamplingError> {
        let plan = &self.plan;
        let every = rays.div_ceil(plan.wave_rays);
        let (b, kept) = q.boundary_compact(
            &p.mem,
            &p.map,
            s as usize,
            queues::Thinning::wave(every, plan.sample_run()),
        );
        let spec = WindowSpec {
            what: crate::machine::WindowKind::Wave {
                boundary: b,
                tenths: ROOT_STEADY_TENTHS,
                // About 160 looks for ten visits a ray.
                step: (kept / 16).max(1),
                l2_share: plan.wave_l2_share,
            },
            warm: 0,
            warm_cycles: 0,
            measure: 0,
            wave,
            kind: SampleKind::Wave,
            first: rays - kept,
        };
        self.windows.run(p, spec)
    }

    /// The root pass (every ray of the wavefront, in segment `s`): whole, or
    /// over one ray in `every` of its queue, packed.
    fn root_window(
        &mut self,
        wave: usize,
        s: u32,
        p: &Prepared,
        q: &RayQueues,
    ) -> Result<(), SamplingError> {
        let n = q.len(s);
        let every = n.div_ceil(self.plan.root_window_rays(wave));
        let (b, kept) =
            q.boundary_compact(&p.mem, &p.map, s as usize, queues::Thinning::root(every));
        let spec = WindowSpec {
            what: crate::machine::WindowKind::Root(b),
            warm: (kept * ROOT_STEADY_TENTHS.0 / 10).max(1),
            warm_cycles: 0,
            measure: kept * (ROOT_STEADY_TENTHS.1 - ROOT_STEADY_TENTHS.0) / 10,
            wave,
            kind: SampleKind::Root,
            first: n - kept,
        };
        self.windows.run(p, spec)
    }

    /// At admission `k` (after the root pass): the head, a window or the
    /// tail starts here, or nothing.
    fn trace_window(
        &mut self,
        wave: usize,
        k: u64,
        p: &Prepared,
        q: &RayQueues,
    ) -> Result<(), SamplingError> {
        if self.wave.tail_started {
            return Ok(());
        }
        let plan = &self.plan;
        let pending = q.pending() as u64;
        let tail_now = k >= plan.head && pending <= plan.tail_pending;
        let (warm, measure, kind) = if self.wave.whole && !tail_now {
            // No window would fit before the wavefront ends: all
            // of it after the root pass is measured as its head.
            self.wave.tail_started = true;
            (0, u64::MAX, SampleKind::Trace)
        } else if k == 1 && plan.head > 1 {
            (0, plan.head - 1, SampleKind::Trace)
        } else if tail_now {
            // The wavefront's tail: too few queues left to fill the
            // chip, so the passes go by their dependency chain rather
            // than the throughput the windows measure; measured to
            // the end.
            self.wave.tail_started = true;
            self.wave.tail_from = Some(k + plan.tail_warm);
            (plan.tail_warm, u64::MAX, SampleKind::Tail)
        } else if k + plan.warm >= plan.head
            && (k + plan.warm - plan.head).is_multiple_of(plan.every)
        {
            (plan.warm, plan.measure, SampleKind::Trace)
        } else {
            return Ok(());
        };
        if !self.wave.measured {
            // Borrowed: the tail's start is all this wavefront records.
            return Ok(());
        }
        let spec = WindowSpec {
            what: crate::machine::WindowKind::Trace(q.boundary(&p.map)),
            warm,
            warm_cycles: 0,
            measure,
            wave,
            kind,
            first: k + warm,
        };
        self.windows.run(p, spec)
    }

    /// After wavefront `wave`'s trace: its record, then the windows of the
    /// shading pass that follows, with the bucket pool as the trace left it.
    fn traced(&mut self, wave: usize, p: &Prepared, q: &RayQueues) -> Result<(), SamplingError> {
        let Wave {
            segs,
            tail_from,
            measured,
            whole,
            ..
        } = std::mem::take(&mut self.wave);
        let rec = &mut self.windows.rec;
        rec.tail_from
            .push(tail_from.map_or(segs.len() as u64, |t| t.min(segs.len() as u64)));
        rec.measured.push(measured);
        rec.whole.push(whole);
        rec.segs.push(segs);
        let pool = q.boundary(&p.map);
        self.windows.shade_windows(p, wave, self.pixels, &pool)
    }
}
