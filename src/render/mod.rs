//! The wavefront path tracer over the DRAM image, with dual-streaming traversal in
//! functional mode (no clock), the plain reference traversal, or the chip in
//! cycle mode (`cycle.rs`).
//!
//! The workload is the paper's: paths of up to `bounces` (5) hit points, Lambertian
//! surfaces, a point light. Wavefront 0 holds the primary rays; shading a hit of
//! depth d emits a shadow ray to the light (any-hit) and, if d + 1 < bounces, a
//! cosine-weighted bounce ray (closest-hit), so wavefront k + 1 holds the bounce rays
//! of depth k + 1 and the shadow rays from depth k: at most two rays per pixel per
//! wavefront. Everything a unit would touch lives in the DRAM image laid out by the
//! data contract; traffic is counted per stream in 64 B lines.

mod cycle;
pub mod early_term;
pub mod energy;
mod error;
mod frame;
pub mod header;
pub mod output;
mod prepare;
pub mod queues;
mod trace;
pub mod traverse;

pub use cycle::{
    ChipFrame, ChipRun, ChipTrace, VcdInfo, WALL_S_PER_PIXEL_HIT, by_lanes, estimated_frame_cycles,
    long_frame_note,
};
pub use error::RenderError;
pub use frame::{AccelInfo, Frame, Progress, WaveStats};
pub use prepare::{Prepared, prepare};
pub use trace::trace_rays;

use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use crate::accel::AccelCfg;
use crate::contract::{HitRec, MemoryMapCfg, PathRec, RayRec, TriRec, lines_touched};
use crate::scene::Scene;
use crate::units::shade;
use queues::{RayQueues, queue_lines_written};
use shade::{ShadeConsts, shade_reads, shade_step};
use trace::{dump, emit, trace_functional, trace_reference, verify};

/// How rays are traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Dual streaming, functional: segment queues, duplication, no clock.
    Functional,
    /// The plain reference traversal (no streams).
    Reference,
    /// Dual streaming on the cycle-level chip (`src/machine/`): every wavefront
    /// is traced by the chip from the DRAM image. Stage A: shading (and ray
    /// generation) is still this host code between wavefronts (interim; stage C
    /// moves it onto the TPs through an L2).
    Cycle,
}

/// Everything that decides a render besides the scene.
#[derive(Clone, Debug, Default)]
pub struct RenderCfg {
    pub accel: AccelCfg,
    pub memory: MemoryMapCfg,
    /// Check every ray's result against the reference traversal.
    pub verify: bool,
    /// Write each wavefront's rays and hit records here (see the data contract).
    pub dump_rays: Option<std::path::PathBuf>,
    /// Cycle mode: the chip's configuration (its `accel` and `memory` are
    /// replaced by the two above) and the simulator options. `None`: defaults.
    pub chip: Option<Box<ChipRun>>,
    /// Render only these pixels (raster indices, increasing; `None`: all). They
    /// are traced as a dense frame of their own (ray and path `i` is the `i`-th
    /// listed pixel), each with the camera ray and random numbers it has in the
    /// whole frame, so its radiance is the whole frame's; the others stay black.
    /// For sampled simulation (`bench speed-error`).
    pub pixels: Option<Vec<u32>>,
    /// Cycle mode: record every segment pass's admission and retirement
    /// ([`Frame::passes`]).
    pub pass_log: bool,
}

impl RenderCfg {
    /// Early ray termination: the chip configuration's choice (`none` without one).
    pub fn early_termination(&self) -> crate::config::EarlyTermination {
        self.chip
            .as_ref()
            .map_or(Default::default(), |r| r.config.chip.early_termination)
    }

    /// A frame of `config`'s chip (its `accel` and `memory` too) with the
    /// simulator options `sim`: nothing checked, dumped or logged.
    pub fn for_chip(config: &crate::config::Config, sim: crate::rtl::SimOptions) -> RenderCfg {
        RenderCfg {
            accel: config.accel.clone(),
            memory: config.memory.clone(),
            verify: false,
            dump_rays: None,
            chip: Some(Box::new(ChipRun {
                config: config.clone(),
                sim,
                trace: None,
                follow: None,
                capture: None,
            })),
            pixels: None,
            pass_log: false,
        }
    }
}

/// Renders a frame; `progress` is called after each bucket of rays.
pub fn render(
    scene: &Scene,
    mode: Mode,
    cfg: &RenderCfg,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Frame, RenderError> {
    render_hooked(scene, mode, cfg, progress, None)
}

/// What may act at the points of a functional frame where the chip can take
/// the work over: time sampling (`crate::sampling`) implements it. Every
/// method may fail the frame with its error.
pub trait FunctionalHooks {
    /// The frame is laid out (`p`) and its `pixels` chosen; no ray yet.
    fn begin(&mut self, scene: &Scene, p: &Prepared, pixels: u32) -> Result<(), RenderError>;
    /// Ray generation is done: the primary rays of the pixels `sample`
    /// (raster indices; ray and path `i` is `sample[i]`) are in the root queue.
    fn generated(&mut self, scene: &Scene, p: &Prepared, sample: &[u32])
    -> Result<(), RenderError>;
    /// Before each segment pass of wavefront `wave` that holds rays (segment
    /// `s`, admitted in depth-first order), and once after its last
    /// (`u32::MAX`).
    fn segment(
        &mut self,
        wave: usize,
        s: u32,
        p: &mut Prepared,
        q: &RayQueues,
        st: &WaveStats,
    ) -> Result<(), RenderError>;
    /// Wavefront `wave` is traced; its shading pass comes next.
    fn traced(&mut self, wave: usize, p: &Prepared, q: &RayQueues) -> Result<(), RenderError>;
    /// A shading pass is done: the shading lines it moved for each pixel
    /// (at most 255).
    fn shaded(&mut self, lines: Vec<u8>);
    /// The frame is traced and shaded.
    fn end(&mut self) -> Result<(), RenderError>;
}

/// [`render`] in functional mode with `hooks` called at its take-over points.
pub fn render_with_hooks(
    scene: &Scene,
    cfg: &RenderCfg,
    progress: &mut dyn FnMut(&Progress),
    hooks: &mut dyn FunctionalHooks,
) -> Result<Frame, RenderError> {
    render_hooked(scene, Mode::Functional, cfg, progress, Some(hooks))
}

/// [`render`], with `hooks` (functional mode) called at its take-over points:
/// ray generation, then each wavefront's segment passes and its shading.
fn render_hooked(
    scene: &Scene,
    mode: Mode,
    cfg: &RenderCfg,
    progress: &mut dyn FnMut(&Progress),
    mut hooks: Option<&mut dyn FunctionalHooks>,
) -> Result<Frame, RenderError> {
    scene.settings.validate()?;
    let start = Instant::now();
    let mut f = FrameRun::new(scene, mode, cfg)?;
    if let Some(h) = hooks.as_deref_mut() {
        h.begin(scene, &f.p, f.pixels)?;
    }
    if let Some(dir) = &cfg.dump_rays {
        std::fs::create_dir_all(dir).map_err(|e| {
            let msg = format!(
                "cannot create '{}': {e}; choose a writable --dump-rays directory",
                dir.display()
            );
            RenderError::File(crate::util::FileError::new(dir, e, msg))
        })?;
    }
    f.generate()?;
    if let Some(h) = hooks.as_deref_mut() {
        h.generated(scene, &f.p, &f.sample)?;
    }
    while !f.work.is_empty() {
        if !f.wavefront(progress, hooks.as_deref_mut())? {
            break;
        }
    }
    if let Some(h) = hooks {
        h.end()?;
    }
    f.finish(start)
}

/// A frame being rendered: its DRAM image and queues, and what it counted.
struct FrameRun<'a> {
    scene: &'a Scene,
    mode: Mode,
    cfg: &'a RenderCfg,
    p: Prepared,
    q: RayQueues,
    /// Path `i` (and its rays) is path `i % spp` of pixel `sample[i / spp]`
    /// (raster index).
    sample: Vec<u32>,
    spp: u32,
    /// Paths (the sample's pixels times `spp`).
    pixels: u32,
    /// Cycle mode.
    chip: Option<cycle::FrameChip>,
    /// The finished wavefronts, and the one under way.
    waves: Vec<WaveStats>,
    st: WaveStats,
    /// The paths still going (pixel ids), to shade after this wavefront.
    work: Vec<u32>,
    trace_s: f64,
    verified: u64,
    /// This wavefront's rays, kept to verify or dump them (`keep`).
    keep: bool,
    rays_this_wave: Vec<RayRec>,
    /// Cycle mode with `cfg.pass_log`.
    passes: Vec<Vec<crate::units::stream_scheduler::PassEvent>>,
}

impl<'a> FrameRun<'a> {
    /// Lays the scene out, checks the pixel sample and, in cycle mode, builds
    /// the chip.
    fn new(scene: &'a Scene, mode: Mode, cfg: &'a RenderCfg) -> Result<FrameRun<'a>, RenderError> {
        let p = prepare(scene, cfg)?;
        let sample = pixel_sample(cfg, scene.settings.width, scene.settings.height)?;
        let spp = scene.settings.spp;
        let pixels = sample.len() as u32 * spp;
        if spp > 1 && cfg.chip.as_ref().is_some_and(|r| r.follow.is_some()) {
            return Err(RenderError::Invalid(
                "following a ray names it by pixel; render with one path per pixel (--spp 1)"
                    .into(),
            ));
        }
        if mode != Mode::Cycle && cfg.chip.as_ref().is_some_and(|r| r.follow.is_some()) {
            return Err(RenderError::Invalid(
                "following a ray records the chip's events: render in cycle mode".into(),
            ));
        }
        let et = cfg.early_termination();
        if mode != Mode::Functional && et != crate::config::EarlyTermination::None {
            return Err(RenderError::Invalid(only_functional(et)));
        }
        let mut q = RayQueues::new(&p.map, p.seg.segments.len());
        let chip = if mode == Mode::Cycle {
            let c = cycle::FrameChip::new(scene, cfg, &p, pixels)?;
            q.divert();
            Some(c)
        } else {
            None
        };
        Ok(FrameRun {
            scene,
            mode,
            cfg,
            p,
            q,
            sample,
            spp,
            pixels,
            chip,
            waves: Vec::new(),
            st: WaveStats::default(),
            work: Vec::new(),
            trace_s: 0.0,
            verified: 0,
            keep: cfg.verify || cfg.dump_rays.is_some(),
            rays_this_wave: Vec::new(),
            passes: Vec::new(),
        })
    }

    /// Cycle mode with shading on the TPs: every chip run after the first
    /// shades the finished wavefront and traces the one it emits.
    fn tp_shading(&self) -> bool {
        self.chip.as_ref().is_some_and(|c| c.tp_shading)
    }

    /// Ray generation: path state and primary rays into the root segment's queue.
    fn generate(&mut self) -> Result<(), RenderError> {
        let (scene, p) = (self.scene, &mut self.p);
        let (w, h) = (scene.settings.width, scene.settings.height);
        let root_entry = p.image.root_entry.encode();
        for pix in 0..self.pixels {
            let (real, k) = (self.sample[(pix / self.spp) as usize], pix % self.spp);
            let seed = shade::sample_seed(scene.settings.seed, k);
            let (o, d, path) = shade::primary_path(&scene.camera, seed, real, w, h);
            let ray = RayRec {
                origin: o,
                dir: d,
                ray_id: pix,
                entry: root_entry,
            };
            emit(
                p,
                &mut self.q,
                &mut self.st,
                &ray,
                self.keep,
                &mut self.rays_this_wave,
            )?;
            path.write(&mut p.mem, p.map.path_addr(pix as u64));
            self.st.shading_lines += 1;
        }
        self.work = (0..self.pixels).collect();
        self.q.close(&mut p.mem, &p.map, 0);
        Ok(())
    }

    /// Traces one wavefront, checks it and shades it; `false` once the frame
    /// is done before its shading (cycle mode: the last shading pass on the
    /// TPs emitted nothing).
    fn wavefront<'h>(
        &mut self,
        progress: &mut dyn FnMut(&Progress),
        mut hooks: Option<&mut (dyn FunctionalHooks + 'h)>,
    ) -> Result<bool, RenderError> {
        let mut prog = Progress {
            wave: self.waves.len(),
            waves_max: self.scene.settings.bounces as usize + 1,
            rays: self.st.rays,
            done: 0,
            known: self.st.enqueues,
            cycles: self.chip.as_ref().map_or(0, |c| c.chip.total_cycles),
        };
        progress(&prog);
        let t0 = Instant::now();
        let traffic = (self.q.traffic.lines_read, self.q.traffic.lines_written);
        match self.mode {
            Mode::Functional => {
                self.trace_functional(&mut prog, progress, hooks.as_deref_mut())?;
            }
            Mode::Reference => trace_reference(&mut self.p, &mut self.q, self.scene, &mut self.st),
            Mode::Cycle => {
                if self.trace_on_chip(&mut prog, progress)? {
                    // The shading pass of the last wavefront emitted nothing.
                    self.trace_s += t0.elapsed().as_secs_f64();
                    return Ok(false);
                }
            }
        }
        self.trace_s += t0.elapsed().as_secs_f64();
        self.check_wave()?;
        if self.tp_shading() {
            // The next chip run shades this wavefront on the TPs.
            self.waves.push(self.st);
            self.st = WaveStats::default();
            return Ok(true);
        }
        self.shade_wave(traffic, hooks)?;
        Ok(true)
    }

    /// Dual streaming, functional, with `hooks` at every segment pass.
    fn trace_functional<'h>(
        &mut self,
        prog: &mut Progress,
        progress: &mut dyn FnMut(&Progress),
        mut hooks: Option<&mut (dyn FunctionalHooks + 'h)>,
    ) -> Result<(), RenderError> {
        let wave = self.waves.len();
        let mut hook =
            |s: u32, p: &mut Prepared, q: &RayQueues, st: &WaveStats| match hooks.as_deref_mut() {
                Some(h) => h.segment(wave, s, p, q, st),
                None => Ok(()),
            };
        trace_functional(
            &mut self.p,
            &mut self.q,
            &mut self.st,
            self.cfg.early_termination(),
            &early_term::Rules::EXACT,
            &mut |done, known| {
                prog.done = done;
                prog.known = known;
                progress(prog)
            },
            &mut hook,
        )?;
        if let Some(h) = hooks {
            h.traced(wave, &self.p, &self.q)?;
        }
        Ok(())
    }

    /// Cycle mode: one chip run (the last wavefront's shading on the TPs, if
    /// there, then this wavefront's trace) and its counts; `true` if it was
    /// the last (its shading emitted nothing).
    fn trace_on_chip(
        &mut self,
        prog: &mut Progress,
        progress: &mut dyn FnMut(&Progress),
    ) -> Result<bool, RenderError> {
        let chip = self.chip.as_mut().expect("built for cycle mode");
        let first = self.waves.is_empty();
        let mut tick = |cycles| {
            prog.cycles = cycles;
            progress(prog)
        };
        let w = chip.run(&mut self.q, &mut self.p.mem, self.pixels, first, &mut tick)?;
        let rpb = self.cfg.memory.rays_per_bucket();
        if chip.tp_shading {
            if self.keep {
                self.rays_this_wave = chip.chip.take_root_log();
            }
            if let Some(prev) = self.waves.last_mut() {
                cycle::add_chip_shading(prev, &mut self.st, &w, rpb);
            }
        }
        let last = chip.tp_shading && w.rays_emitted == 0;
        if !last {
            cycle::add_chip_wave(&mut self.st, &w, rpb);
        }
        chip.waves.push(w);
        if self.cfg.pass_log {
            self.passes.push(chip.chip.take_pass_log());
        }
        Ok(last)
    }

    /// Checks this wavefront's rays against the reference (`--verify`) and
    /// dumps them (`--dump-rays`).
    fn check_wave(&mut self) -> Result<(), RenderError> {
        if self.cfg.verify {
            self.verified += verify(&self.p, self.scene, &self.rays_this_wave)?;
        }
        if let Some(dir) = &self.cfg.dump_rays {
            dump(dir, self.waves.len(), &self.p, &self.rays_this_wave)?;
        }
        self.rays_this_wave.clear();
        Ok(())
    }

    /// The host's shading pass: shades every path still going and emits the
    /// next wavefront into the root queue. `(r0, w0)`: the ray stream's lines
    /// read and written before this wavefront's trace.
    fn shade_wave<'h>(
        &mut self,
        (r0, w0): (u64, u64),
        hooks: Option<&mut (dyn FunctionalHooks + 'h)>,
    ) -> Result<(), RenderError> {
        let mut next_work = Vec::new();
        let mut next = WaveStats::default();
        // Time sampling scales a shading pass's windows by its lines per pixel.
        let mut lines = hooks.is_some().then(|| vec![1u8; self.pixels as usize]);
        for &pix in &self.work {
            let before = self.st.shading_lines;
            shade_pixel(
                &mut self.p,
                &mut self.q,
                self.scene,
                pix,
                &mut self.st,
                &mut next,
                self.keep,
                &mut self.rays_this_wave,
                &mut next_work,
            )?;
            if let Some(l) = lines.as_mut() {
                l[pix as usize] = (self.st.shading_lines - before).min(u8::MAX as u64) as u8;
            }
        }
        if let (Some(h), Some(l)) = (hooks, lines) {
            h.shaded(l);
        }
        let (p, q, st) = (&mut self.p, &mut self.q, &mut self.st);
        q.close(&mut p.mem, &p.map, 0);
        st.ray_lines_read += q.traffic.lines_read - r0;
        st.ray_lines_written += q.traffic.lines_written - w0;
        if self.mode == Mode::Cycle {
            // The functional model counts a wavefront's root-queue writes with the
            // shading that emits them (the previous wavefront; ray generation's
            // nowhere); the chip writes them while tracing. Same attribution here.
            let emitted = next.rays;
            st.ray_lines_written += queue_lines_written(emitted, self.cfg.memory.rays_per_bucket());
        }
        self.waves.push(self.st);
        self.st = next;
        self.work = next_work;
        Ok(())
    }

    /// The frame: its totals, its image and, in cycle mode, the chip's figures.
    fn finish(mut self, start: Instant) -> Result<Frame, RenderError> {
        let mut total = WaveStats::default();
        for wv in &self.waves {
            total.add(wv);
        }
        if let (Some(c), Some(t)) = (
            self.chip.as_ref(),
            self.cfg.chip.as_ref().and_then(|r| r.follow.as_ref()),
        ) {
            c.check_followed(t)?;
        }
        let vcd = match self.chip.as_mut() {
            Some(c) => c.finish_trace()?,
            None => None,
        };
        let (w, h) = (self.scene.settings.width, self.scene.settings.height);
        let p = &self.p;
        let mut radiance = vec![Vec3::ZERO; (w * h) as usize];
        let spp = self.spp;
        for (i, &real) in self.sample.iter().enumerate() {
            // The pixel's paths averaged in linear radiance (one: as it is).
            let first = i as u64 * spp as u64;
            let path = |k: u64| PathRec::read(&p.mem, p.map.path_addr(first + k)).radiance;
            radiance[real as usize] = if spp == 1 {
                path(0)
            } else {
                (0..spp as u64).map(path).sum::<Vec3>() / spp as f32
            };
        }
        Ok(Frame {
            passes: self.passes,
            scene: self.scene.name.clone(),
            mode: self.mode,
            early_termination: self.cfg.early_termination(),
            width: w,
            height: h,
            spp,
            radiance,
            accel: p.info.clone(),
            duplication: total.duplication(),
            bytes_per_ray: total.bytes_per_ray(),
            waves: self.waves,
            total,
            wall_s: start.elapsed().as_secs_f64(),
            trace_s: self.trace_s,
            verified_rays: self.verified,
            energy: None,
            dram_resident_mb: p.mem.resident_bytes() as f64 / (1 << 20) as f64,
            chip: self.chip.map(|c| c.frame(vcd)),
        })
    }
}

/// Why a mode other than functional refuses early termination `et`.
pub fn only_functional(et: crate::config::EarlyTermination) -> String {
    format!(
        "early termination `{et}` is in functional mode only so far; use --mode functional or early_termination = \"none\""
    )
}

/// The pixels a frame renders (ray and path `i` is the `i`-th): all of them,
/// or `cfg.pixels` once checked.
fn pixel_sample(cfg: &RenderCfg, w: u32, h: u32) -> Result<Vec<u32>, RenderError> {
    let Some(v) = &cfg.pixels else {
        return Ok((0..w * h).collect());
    };
    if v.is_empty() {
        return Err(RenderError::Invalid(
            "the pixel sample is empty; keep at least one pixel".into(),
        ));
    }
    if let Some(k) = v.windows(2).position(|x| x[0] >= x[1]) {
        return Err(RenderError::Invalid(format!(
            "the pixel sample is not increasing at entry {} ({} then {}); list each pixel once, in raster order",
            k + 1,
            v[k],
            v[k + 1]
        )));
    }
    if v[v.len() - 1] >= w * h {
        return Err(RenderError::Invalid(format!(
            "the pixel sample lists pixel {}, outside the {w}x{h} frame",
            v[v.len() - 1]
        )));
    }
    Ok(v.clone())
}

/// Shades one pixel's rays of the finished wavefront and emits its next rays.
#[allow(clippy::too_many_arguments)]
fn shade_pixel(
    p: &mut Prepared,
    q: &mut RayQueues,
    scene: &Scene,
    pix: u32,
    st: &mut WaveStats,
    next: &mut WaveStats,
    keep: bool,
    list: &mut Vec<RayRec>,
    next_work: &mut Vec<u32>,
) -> Result<(), RenderError> {
    let pa = p.map.path_addr(pix as u64);
    let path = PathRec::read(&p.mem, pa);
    st.shading_lines += 1;
    let (reads_shadow, reads_bounce) = shade_reads(&path);
    let read_hit = |p: &Prepared, st: &mut WaveStats, idx: u64| {
        st.shading_lines += 1;
        HitRec::read(&p.mem, p.map.hit_addr(idx))
    };
    let shadow_hit = reads_shadow.then(|| read_hit(p, st, pix as u64 * 2 + 1));
    let bounce_hit = reads_bounce.then(|| read_hit(p, st, pix as u64 * 2));
    let mut surface = None;
    if let Some(h) = bounce_hit.filter(|h| h.is_hit()) {
        let ti = p.mem.read_u32(p.map.tri_index + h.tri_id as u64 * 4);
        let ta = p.map.scene + ti as u64 * 16;
        let tri = TriRec::read(&p.mem, ta);
        let ma = p.map.materials + tri.material as u64 * 16;
        let albedo = Vec3::new(
            p.mem.read_f32(ma),
            p.mem.read_f32(ma + 4),
            p.mem.read_f32(ma + 8),
        );
        st.shading_lines += 1 + lines_touched(ta, 48) + 1;
        surface = Some((tri, albedo));
    }
    let c = shade_consts(scene, p);
    let out = shade_step(
        &c,
        pix,
        path,
        shadow_hit,
        bounce_hit,
        surface.as_ref().map(|(t, a)| (t, *a)),
    );
    st.occluded += out.occluded as u64;
    st.hits += out.hit as u64;
    for r in [out.shadow, out.bounce].into_iter().flatten() {
        emit(p, q, next, &r, keep, list)?;
    }
    let path = out.path;
    path.write(&mut p.mem, pa);
    st.shading_lines += 1;
    if path.flags != 0 {
        next_work.push(pix);
    }
    Ok(())
}

/// The shading pass's constants for `scene` laid out in `p`.
pub fn shade_consts(scene: &Scene, p: &Prepared) -> ShadeConsts {
    ShadeConsts {
        light_pos: scene.light.position,
        light_intensity: scene.light.intensity,
        sky: scene.sky,
        bounces: scene.settings.bounces,
        root_entry: p.image.root_entry.encode(),
    }
}
