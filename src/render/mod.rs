//! The wavefront path tracer over the DRAM image, with dual-streaming traversal in
//! functional mode (no clock) or the plain reference traversal.
//!
//! The workload is the paper's: paths of up to `bounces` (5) hit points, Lambertian
//! surfaces, a point light. Wavefront 0 holds the primary rays; shading a hit of
//! depth d emits a shadow ray to the light (any-hit) and, if d + 1 < bounces, a
//! cosine-weighted bounce ray (closest-hit), so wavefront k + 1 holds the bounce rays
//! of depth k + 1 and the shadow rays from depth k: at most two rays per pixel per
//! wavefront. Everything a unit would touch lives in the DRAM image laid out by the
//! data contract; traffic is counted per stream in 64 B lines.

pub mod output;
pub mod queues;
pub mod shade;
pub mod traverse;

use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use crate::accel::{AccelCfg, Bvh, SceneImage, Segmentation};
use crate::contract::{
    HitRec, LINE_BYTES, MemoryMap, MemoryMapCfg, PathRec, RayRec, SHADOW_BIT, SegEntry, SparseMem,
    TriRec, lines_touched,
};
use crate::scene::Scene;
use queues::{RayQueues, queue_lines_written};
use shade::{ShadeConsts, shade_reads, shade_step};
use traverse::{SegmentView, TraversalCounts, reference_trace, traverse_segment};

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
            })),
            pixels: None,
            pass_log: false,
        }
    }
}

/// How to build and run the chip in cycle mode.
#[derive(Clone, Debug, Default)]
pub struct ChipRun {
    pub config: crate::config::Config,
    pub sim: crate::rtl::SimOptions,
    /// Write a VCD waveform of the run (`render --vcd`).
    pub trace: Option<ChipTrace>,
}

/// A waveform of the chip over a window of core cycles (docs/chip.md).
#[derive(Clone, Debug, Default)]
pub struct ChipTrace {
    pub path: std::path::PathBuf,
    /// Comma-separated unit names and instance patterns
    /// (`crate::machine::trace::resolve`); empty: every unit.
    pub units: String,
    /// First and last core cycle traced (`None`: to the end).
    pub from: u64,
    pub to: Option<u64>,
    /// The size guard (`--trace-max-bytes`; 0: no limit).
    pub max_bytes: u64,
}

/// Core cycles per pixel and hit point of a cycle-mode frame on the paper's
/// 128 TMs: 7.7-8.1 measured on the Dragon Box, Dabrovic Sponza and Cornell
/// with 5 hit points (the Dragon, mostly sky: 2.9). Scales with 128 / TMs.
const CYCLES_PER_PIXEL_HIT: f64 = 8.0;

/// Wall seconds per pixel and hit point of a cycle-mode frame on a 2-core
/// machine of 2026: 0.17 (Cornell 64x64) to 0.45 ms (the Dragon Box at
/// 1024x1024, 39 minutes), about the same for any number of TMs (cycles
/// scale with 128 / TMs and the work of a cycle with TMs).
pub const WALL_S_PER_PIXEL_HIT: (f64, f64) = (0.17e-3, 0.45e-3);

/// Before a cycle-mode frame of more than five minutes: how long it takes,
/// and the faster mode.
pub fn long_frame_note(s: &crate::scene::RenderSettings, tms: u32) -> Option<String> {
    let pixels = s.width as f64 * s.height as f64;
    let hits = s.bounces as f64;
    let (lo, hi) = WALL_S_PER_PIXEL_HIT;
    let (lo, hi) = (pixels * hits * lo, pixels * hits * hi);
    if hi < 300.0 {
        return None;
    }
    let span = |s: f64| {
        if s >= 5400.0 {
            format!("{:.1} h", s / 3600.0)
        } else {
            format!("{:.0} min", s / 60.0)
        }
    };
    let cycles = estimated_frame_cycles(pixels as u64, s.bounces, tms);
    Some(format!(
        "this cycle-mode frame ({}x{}, {} hit points, about {:.0} M cycles) takes about {} to {} on a 2-core machine; --mode windows estimates its cycles, traffic and energy within about 3% in minutes (docs/speed-error.md)",
        s.width,
        s.height,
        s.bounces,
        cycles as f64 / 1e6,
        span(lo),
        span(hi)
    ))
}

/// A cycle-mode frame's core cycles, estimated before it runs (for the trace
/// guard and the long-run note).
pub fn estimated_frame_cycles(pixels: u64, hit_points: u32, tms: u32) -> u64 {
    (pixels as f64 * hit_points.max(1) as f64 * CYCLES_PER_PIXEL_HIT * 128.0 / tms.max(1) as f64)
        as u64
}

/// What a waveform holds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct VcdInfo {
    pub units: u64,
    pub signals: u64,
    pub changes: u64,
    pub bytes: u64,
}

/// Cycle-mode figures of a frame.
#[derive(Clone, Debug, Serialize)]
pub struct ChipFrame {
    /// Shading ran on the TPs (`chip.shading = "tps"`), so the cycles include it.
    pub shading_on_tps: bool,
    pub tms: u32,
    pub tps_per_tm: u32,
    /// Per wavefront: cycles and the chip's own counts.
    pub waves: Vec<crate::machine::WaveCycles>,
    pub total_cycles: u64,
    /// Wall time of the chip simulation (tracing only) and simulated cycles/s.
    pub sim_wall_s: f64,
    pub cycles_per_s: f64,
    /// `chip.memory.model`: "fixed" or "gddr5".
    pub memory_model: String,
    /// Core clock period (ps) and line size, for bandwidths.
    pub core_ps: u64,
    pub line_bytes: u64,
    /// `gddr5`: the controllers' figures over the whole frame (sum of `waves`).
    pub dram: Option<crate::machine::DramWave>,
    /// The waveform written (`ChipRun::trace`).
    pub vcd: Option<VcdInfo>,
    /// The simulator's evaluations by unit kind over the frame, most first
    /// (where its time went; they depend on the kernel, not the chip's results).
    pub evals_by_module: Vec<crate::rtl::ModuleEvals>,
    /// Simulator steps taken with 1, 2, ... evaluation lanes (`--threads`; how
    /// the run spent its time, not a result).
    pub sim_steps_by_lanes: Vec<u64>,
}

impl ChipFrame {
    /// Achieved DRAM bandwidth (GB/s) over the traced cycles (`gddr5`).
    pub fn dram_bandwidth_gbs(&self) -> Option<f64> {
        self.dram
            .map(|d| d.bandwidth_gbs(self.line_bytes, self.total_cycles, self.core_ps))
    }
}

/// Where a render is, for progress reporting.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    pub wave: usize,
    /// Upper bound on wavefronts (hit points per path + 1).
    pub waves_max: usize,
    /// Rays of this wavefront (unique).
    pub rays: u64,
    /// Ray-segment traversals done and known so far in this wavefront.
    pub done: u64,
    pub known: u64,
}

/// Counts of one wavefront (or of a frame, summed).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct WaveStats {
    pub rays: u64,
    pub bounce_rays: u64,
    pub shadow_rays: u64,
    /// Rays enqueued into any segment, the initial one included.
    pub enqueues: u64,
    pub segments_loaded: u64,
    pub traversal: TraversalCounts,
    pub ray_lines_read: u64,
    pub ray_lines_written: u64,
    pub scene_lines: u64,
    pub hit_lines_read: u64,
    pub hit_lines_written: u64,
    pub shading_lines: u64,
    pub hits: u64,
    pub occluded: u64,
}

impl WaveStats {
    fn add(&mut self, o: &WaveStats) {
        self.rays += o.rays;
        self.bounce_rays += o.bounce_rays;
        self.shadow_rays += o.shadow_rays;
        self.enqueues += o.enqueues;
        self.segments_loaded += o.segments_loaded;
        self.traversal += o.traversal;
        self.ray_lines_read += o.ray_lines_read;
        self.ray_lines_written += o.ray_lines_written;
        self.scene_lines += o.scene_lines;
        self.hit_lines_read += o.hit_lines_read;
        self.hit_lines_written += o.hit_lines_written;
        self.shading_lines += o.shading_lines;
        self.hits += o.hits;
        self.occluded += o.occluded;
    }
    /// Enqueues per unique ray (the paper's ray duplication).
    pub fn duplication(&self) -> f64 {
        if self.rays == 0 {
            0.0
        } else {
            self.enqueues as f64 / self.rays as f64
        }
    }
    pub fn ray_lines(&self) -> u64 {
        self.ray_lines_read + self.ray_lines_written
    }
    pub fn hit_lines(&self) -> u64 {
        self.hit_lines_read + self.hit_lines_written
    }
    pub fn total_lines(&self) -> u64 {
        self.ray_lines() + self.scene_lines + self.hit_lines() + self.shading_lines
    }
    /// DRAM bytes per ray (the paper's Table 3).
    pub fn bytes_per_ray(&self) -> f64 {
        if self.rays == 0 {
            0.0
        } else {
            (self.total_lines() * LINE_BYTES) as f64 / self.rays as f64
        }
    }
}

/// Facts about the acceleration structure.
#[derive(Clone, Debug, Serialize)]
pub struct AccelInfo {
    pub triangles: u64,
    pub bvh_nodes: u64,
    pub bvh_depth: u32,
    pub segments: u64,
    pub scene_bytes: u64,
    pub children_min: u64,
    pub children_mean: f64,
    pub children_max: u64,
    pub segment_bytes_mean: f64,
    pub bvh_build_s: f64,
    pub segment_build_s: f64,
    /// Why the BVH was built by the binned-SAH fallback rather than PLOC (absent,
    /// and not in the statistics, for a PLOC tree).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bvh_fallback: Option<String>,
}

/// A rendered frame.
#[derive(Clone, Debug, Serialize)]
pub struct Frame {
    pub scene: String,
    pub mode: Mode,
    pub width: u32,
    pub height: u32,
    #[serde(skip)]
    pub radiance: Vec<Vec3>,
    pub accel: AccelInfo,
    pub waves: Vec<WaveStats>,
    pub total: WaveStats,
    pub duplication: f64,
    pub bytes_per_ray: f64,
    pub wall_s: f64,
    pub trace_s: f64,
    pub verified_rays: u64,
    pub dram_resident_mb: f64,
    /// Compute and on-chip energy of the TMs implied by the traversal (set by the
    /// caller from the energy table and the TP cost table; functional mode only).
    pub energy: Option<crate::energy::Energy>,
    /// Cycle mode only.
    pub chip: Option<ChipFrame>,
    /// Cycle mode with [`RenderCfg::pass_log`]: per chip run, the segment passes
    /// in retirement order.
    #[serde(skip)]
    pub passes: Vec<Vec<crate::units::stream_scheduler::PassEvent>>,
}

/// The scene built for the chip: BVH, segments and the DRAM image.
pub struct Prepared {
    pub bvh: Bvh,
    pub seg: Segmentation,
    pub map: MemoryMap,
    pub mem: SparseMem,
    pub image: SceneImage,
    pub info: AccelInfo,
}

/// Builds the BVH and the segments and writes the scene stream into a fresh image.
pub fn prepare(scene: &Scene, cfg: &RenderCfg) -> Result<Prepared, String> {
    cfg.memory.validate()?;
    cfg.accel.validate(cfg.memory.row_bytes)?;
    let bvh = Bvh::build(&scene.triangles, &cfg.accel.bvh)?;
    let t0 = Instant::now();
    let seg = Segmentation::build(&bvh, cfg.accel.segment_bytes)?;
    let segment_build_s = t0.elapsed().as_secs_f64();
    let bytes: Vec<u32> = seg.segments.iter().map(|s| s.bytes).collect();
    let pixels = scene.settings.width as u64 * scene.settings.height as u64;
    let map = MemoryMap::new(
        &cfg.memory,
        &bytes,
        SceneImage::children_total(&seg),
        scene.triangles.len() as u64,
        scene.materials.len() as u64,
        pixels,
    )?;
    let mut mem = SparseMem::new(map.capacity);
    let image = SceneImage::write(
        &mut mem,
        &map,
        &scene.triangles,
        &scene.tri_material,
        &bvh,
        &seg,
    );
    for (i, m) in scene.materials.iter().enumerate() {
        let a = map.materials + i as u64 * 16;
        mem.write_f32(a, m.albedo.x);
        mem.write_f32(a + 4, m.albedo.y);
        mem.write_f32(a + 8, m.albedo.z);
    }
    let kids: Vec<u64> = seg
        .segments
        .iter()
        .map(|s| s.children.len() as u64)
        .collect();
    let info = AccelInfo {
        triangles: scene.triangles.len() as u64,
        bvh_nodes: bvh.nodes.len() as u64,
        bvh_depth: bvh.depth,
        segments: seg.segments.len() as u64,
        scene_bytes: bytes.iter().map(|&b| b as u64).sum(),
        children_min: kids.iter().copied().min().unwrap_or(0),
        children_mean: kids.iter().sum::<u64>() as f64 / kids.len().max(1) as f64,
        children_max: kids.iter().copied().max().unwrap_or(0),
        segment_bytes_mean: bytes.iter().map(|&b| b as f64).sum::<f64>()
            / bytes.len().max(1) as f64,
        bvh_build_s: bvh.build_time.as_secs_f64(),
        segment_build_s,
        bvh_fallback: match &bvh.builder {
            crate::accel::BvhBuilder::Ploc => None,
            crate::accel::BvhBuilder::BinnedSah { reason } => Some(reason.clone()),
        },
    };
    Ok(Prepared {
        bvh,
        seg,
        map,
        mem,
        image,
        info,
    })
}

/// Reads and updates a hit record with atomic-min semantics on (t, id).
fn update_hit(mem: &mut SparseMem, map: &MemoryMap, idx: u64, h: HitRec, st: &mut WaveStats) {
    let a = map.hit_addr(idx);
    let cur = HitRec::read(mem, a);
    st.hit_lines_read += 1;
    if h.closer_than(&cur) {
        h.write(mem, a);
        st.hit_lines_written += 1;
    }
}

/// Renders a frame; `progress` is called after each bucket of rays.
pub fn render(
    scene: &Scene,
    mode: Mode,
    cfg: &RenderCfg,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Frame, String> {
    render_hooked(scene, mode, cfg, progress, None)
}

/// What may act at the points of a functional frame where the chip can take
/// the work over: time sampling (`crate::sampling`) implements it. Every
/// method may fail the frame with its error.
pub trait FunctionalHooks {
    /// The frame is laid out (`p`) and its `pixels` chosen; no ray yet.
    fn begin(&mut self, scene: &Scene, p: &Prepared, pixels: u32) -> Result<(), String>;
    /// Ray generation is done: the primary rays of the pixels `sample`
    /// (raster indices; ray and path `i` is `sample[i]`) are in the root queue.
    fn generated(&mut self, scene: &Scene, p: &Prepared, sample: &[u32]) -> Result<(), String>;
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
    ) -> Result<(), String>;
    /// Wavefront `wave` is traced; its shading pass comes next.
    fn traced(&mut self, wave: usize, p: &Prepared, q: &RayQueues) -> Result<(), String>;
    /// A shading pass is done: the shading lines it moved for each pixel
    /// (at most 255).
    fn shaded(&mut self, lines: Vec<u8>);
    /// The frame is traced and shaded.
    fn end(&mut self) -> Result<(), String>;
}

/// [`render`] in functional mode with `hooks` called at its take-over points.
pub fn render_with_hooks(
    scene: &Scene,
    cfg: &RenderCfg,
    progress: &mut dyn FnMut(&Progress),
    hooks: &mut dyn FunctionalHooks,
) -> Result<Frame, String> {
    render_hooked(scene, Mode::Functional, cfg, progress, Some(hooks))
}

fn render_hooked(
    scene: &Scene,
    mode: Mode,
    cfg: &RenderCfg,
    progress: &mut dyn FnMut(&Progress),
    mut hooks: Option<&mut dyn FunctionalHooks>,
) -> Result<Frame, String> {
    scene.settings.validate()?;
    let start = Instant::now();
    let mut p = prepare(scene, cfg)?;
    let (w, h) = (scene.settings.width, scene.settings.height);
    let sample: Vec<u32> = match &cfg.pixels {
        None => (0..w * h).collect(),
        Some(v) => {
            if v.is_empty() {
                return Err("the pixel sample is empty; keep at least one pixel".into());
            }
            if let Some(k) = v.windows(2).position(|x| x[0] >= x[1]) {
                return Err(format!(
                    "the pixel sample is not increasing at entry {} ({} then {}); list each pixel once, in raster order",
                    k + 1,
                    v[k],
                    v[k + 1]
                ));
            }
            if v[v.len() - 1] >= w * h {
                return Err(format!(
                    "the pixel sample lists pixel {}, outside the {w}x{h} frame",
                    v[v.len() - 1]
                ));
            }
            v.clone()
        }
    };
    let pixels = sample.len() as u32;
    let nseg = p.seg.segments.len();
    let mut q = RayQueues::new(&p.map, nseg);
    let root_entry = p.image.root_entry.encode();
    let mut chip = None;
    let mut chip_waves = Vec::new();
    let mut chip_cfg = crate::config::Config::default();
    if mode == Mode::Cycle {
        let run = cfg.chip.as_deref().cloned().unwrap_or_default();
        chip_cfg = run.config;
        chip_cfg.accel = cfg.accel.clone();
        chip_cfg.memory = cfg.memory.clone();
        let consts = shade_consts(scene, &p);
        let mut c = crate::machine::Chip::new(&chip_cfg, &p.map, nseg, &consts, run.sim)?;
        c.stack_need = Some(p.seg.stack_bound(&p.bvh));
        if let Some(t) = &run.trace {
            let paths: Vec<String> = (0..c.sim.unit_count())
                .map(|i| c.sim.unit_path(crate::rtl::UnitId(i as u32)).to_string())
                .collect();
            let paths: Vec<&str> = paths.iter().map(String::as_str).collect();
            let filter = crate::machine::trace::resolve(&t.units, &paths)?;
            let spec = crate::machine::trace::spec(
                filter,
                t.from,
                t.to,
                chip_cfg.clocks.core_ps,
                t.max_bytes,
            );
            let mut tracer = crate::rtl::Tracer::to_file(&t.path, spec)?;
            // Twice the frame's estimated cycles: the guard projects the bytes
            // written to the window's end.
            let cycles =
                estimated_frame_cycles(pixels as u64, scene.settings.bounces, chip_cfg.chip.tms);
            tracer.expect_end(2 * cycles * chip_cfg.clocks.core_ps);
            c.sim.attach_tracer(tracer).map_err(|e| e.to_string())?;
        }
        if cfg.verify || cfg.dump_rays.is_some() {
            c.enable_root_log();
        }
        if cfg.pass_log {
            c.enable_pass_log();
        }
        chip = Some(c);
        q.divert();
    }
    if let Some(h) = hooks.as_deref_mut() {
        h.begin(scene, &p, pixels)?;
    }
    // Cycle mode with shading on the TPs: every chip run after the first shades the
    // finished wavefront and traces the one it emits.
    let tp_shading =
        mode == Mode::Cycle && chip_cfg.chip.shading == crate::machine::config::Shading::Tps;
    let rpb = cfg.memory.rays_per_bucket();
    let mut waves = Vec::new();
    let mut trace_s = 0.0;
    let mut verified = 0u64;
    let mut rays_this_wave: Vec<RayRec> = Vec::new();
    let mut passes = Vec::new();
    let keep = cfg.verify || cfg.dump_rays.is_some();
    if let Some(dir) = &cfg.dump_rays {
        std::fs::create_dir_all(dir).map_err(|e| {
            format!(
                "cannot create '{}': {e}; choose a writable --dump-rays directory",
                dir.display()
            )
        })?;
    }

    // Ray generation: path state and primary rays into the root segment's queue.
    let mut st = WaveStats::default();
    for (pix, &real) in (0..pixels).zip(&sample) {
        let (o, d, path) = shade::primary_path(&scene.camera, scene.settings.seed, real, w, h);
        let ray = RayRec {
            origin: o,
            dir: d,
            ray_id: pix,
            entry: root_entry,
        };
        emit(&mut p, &mut q, &mut st, &ray, keep, &mut rays_this_wave)?;
        path.write(&mut p.mem, p.map.path_addr(pix as u64));
        st.shading_lines += 1;
    }
    let mut work: Vec<u32> = (0..pixels).collect();
    q.close(&mut p.mem, &p.map, 0);
    if let Some(h) = hooks.as_deref_mut() {
        h.generated(scene, &p, &sample)?;
    }

    while !work.is_empty() {
        let mut prog = Progress {
            wave: waves.len(),
            waves_max: scene.settings.bounces as usize + 1,
            rays: st.rays,
            done: 0,
            known: st.enqueues,
        };
        progress(&prog);
        let t0 = Instant::now();
        let (r0, w0) = (q.traffic.lines_read, q.traffic.lines_written);
        match mode {
            Mode::Functional => {
                let wave = waves.len();
                let mut hook = |s: u32, p: &mut Prepared, q: &RayQueues, st: &WaveStats| match hooks
                    .as_deref_mut()
                {
                    Some(h) => h.segment(wave, s, p, q, st),
                    None => Ok(()),
                };
                trace_functional(
                    &mut p,
                    &mut q,
                    &mut st,
                    &mut |done, known| {
                        prog.done = done;
                        prog.known = known;
                        progress(&prog)
                    },
                    &mut hook,
                )?;
                if let Some(h) = hooks.as_deref_mut() {
                    h.traced(wave, &p, &q)?;
                }
            }
            Mode::Reference => trace_reference(&mut p, &mut q, scene, &mut st),
            Mode::Cycle => {
                let chip = chip.as_mut().expect("built for cycle mode");
                let w = if tp_shading && !waves.is_empty() {
                    chip.shade_and_trace(&mut p.mem, pixels)?
                } else {
                    let rays = q.take_diverted();
                    chip.trace_wave(&mut p.mem, &rays)?
                };
                if tp_shading {
                    if keep {
                        rays_this_wave = chip.take_root_log();
                    }
                    if let Some(prev) = waves.last_mut() {
                        add_chip_shading(prev, &mut st, &w, rpb);
                    }
                }
                let last = tp_shading && w.rays_emitted == 0;
                if !last {
                    add_chip_wave(&mut st, &w, rpb);
                }
                chip_waves.push(w);
                if cfg.pass_log {
                    passes.push(chip.take_pass_log());
                }
                if last {
                    // The shading pass of the last wavefront emitted nothing.
                    trace_s += t0.elapsed().as_secs_f64();
                    break;
                }
            }
        }
        trace_s += t0.elapsed().as_secs_f64();
        if cfg.verify {
            verified += verify(&p, scene, &rays_this_wave)?;
        }
        if let Some(dir) = &cfg.dump_rays {
            dump(dir, waves.len(), &p, &rays_this_wave)?;
        }
        rays_this_wave.clear();
        if tp_shading {
            // The next chip run shades this wavefront on the TPs.
            waves.push(st);
            st = WaveStats::default();
            continue;
        }
        // Shading (produces the next wavefront into the root queue).
        let mut next_work = Vec::new();
        let mut next = WaveStats::default();
        // Time sampling scales a shading pass's windows by its lines per pixel.
        let mut lines = hooks.is_some().then(|| vec![1u8; pixels as usize]);
        for &pix in &work {
            let before = st.shading_lines;
            shade_pixel(
                &mut p,
                &mut q,
                scene,
                pix,
                &mut st,
                &mut next,
                keep,
                &mut rays_this_wave,
                &mut next_work,
            )?;
            if let Some(l) = lines.as_mut() {
                l[pix as usize] = (st.shading_lines - before).min(u8::MAX as u64) as u8;
            }
        }
        if let (Some(h), Some(l)) = (hooks.as_deref_mut(), lines) {
            h.shaded(l);
        }
        q.close(&mut p.mem, &p.map, 0);
        st.ray_lines_read += q.traffic.lines_read - r0;
        st.ray_lines_written += q.traffic.lines_written - w0;
        if mode == Mode::Cycle {
            // The functional model counts a wavefront's root-queue writes with the
            // shading that emits them (the previous wavefront; ray generation's
            // nowhere); the chip writes them while tracing. Same attribution here.
            let emitted = next.rays;
            st.ray_lines_written += queue_lines_written(emitted, rpb);
        }
        waves.push(st);
        st = next;
        work = next_work;
    }
    if let Some(h) = hooks {
        h.end()?;
    }
    let mut total = WaveStats::default();
    for wv in &waves {
        total.add(wv);
    }
    let mut vcd = None;
    if let Some(c) = chip.as_mut()
        && let Some(r) = c.sim.finish_trace()
    {
        let t = r.map_err(|e| format!("writing the VCD file failed: {e}"))?;
        vcd = Some(VcdInfo {
            units: t.units,
            signals: t.signals,
            changes: t.changes,
            bytes: t.bytes,
        });
    }
    let mut radiance = vec![Vec3::ZERO; (w * h) as usize];
    for (pix, &real) in (0..pixels).zip(&sample) {
        radiance[real as usize] = PathRec::read(&p.mem, p.map.path_addr(pix as u64)).radiance;
    }
    Ok(Frame {
        passes,
        scene: scene.name.clone(),
        mode,
        width: w,
        height: h,
        radiance,
        accel: p.info.clone(),
        duplication: total.duplication(),
        bytes_per_ray: total.bytes_per_ray(),
        waves,
        total,
        wall_s: start.elapsed().as_secs_f64(),
        trace_s,
        verified_rays: verified,
        energy: None,
        dram_resident_mb: p.mem.resident_bytes() as f64 / (1 << 20) as f64,
        chip: chip.map(|c| ChipFrame {
            shading_on_tps: tp_shading,
            tms: chip_cfg.chip.tms,
            tps_per_tm: chip_cfg.tm.tps,
            total_cycles: c.total_cycles,
            sim_wall_s: c.wall_s,
            cycles_per_s: c.total_cycles as f64 / c.wall_s.max(1e-9),
            memory_model: chip_cfg.chip.memory.model.name().into(),
            core_ps: chip_cfg.clocks.core_ps,
            line_bytes: crate::contract::LINE_BYTES,
            dram: (chip_cfg.chip.memory.model == crate::machine::config::MemoryModel::Gddr5).then(
                || {
                    let mut t = crate::machine::DramWave::default();
                    for w in &chip_waves {
                        t.add(&w.dram);
                    }
                    t
                },
            ),
            waves: chip_waves,
            vcd,
            evals_by_module: c.sim.evals_by_module(),
            sim_steps_by_lanes: c.sim.steps_by_lanes().to_vec(),
        }),
    })
}

/// Cycle mode with shading on the TPs: what a chip run's shading pass did goes to
/// the wavefront it shaded (`prev`: hits, blocked shadow rays, shading lines and,
/// as in functional mode, the root-queue writes of the rays it emitted); the rays
/// it emitted start the new wavefront's counts (`st`).
fn add_chip_shading(
    prev: &mut WaveStats,
    st: &mut WaveStats,
    w: &crate::machine::WaveCycles,
    rpb: u32,
) {
    use crate::mem::StreamTag;
    let sh = StreamTag::Shading as usize;
    prev.hits += w.shade_hits;
    prev.occluded += w.shade_occluded;
    prev.shading_lines += w.lines_read[sh] + w.lines_written[sh];
    prev.ray_lines_written += queue_lines_written(w.rays_emitted, rpb);
    st.rays += w.rays_emitted;
    st.shadow_rays += w.shade_shadow_rays;
    st.bounce_rays += w.rays_emitted - w.shade_shadow_rays;
    st.enqueues += w.rays_emitted;
}

/// Adds a chip-traced wavefront's counts to the wavefront's statistics, with the
/// functional model's attribution of the root queue's writes (see `render`).
fn add_chip_wave(st: &mut WaveStats, w: &crate::machine::WaveCycles, rpb: u32) {
    use crate::mem::StreamTag;
    st.enqueues += w.duplicates;
    st.segments_loaded += w.segments_loaded;
    st.traversal.box_tests += w.box_tests;
    st.traversal.nodes += w.box_tests / 2;
    st.traversal.tri_tests += w.tri_tests;
    st.traversal.exits += w.exits;
    st.traversal.pops += w.pops;
    st.traversal.tri_hits += w.tri_hits;
    st.traversal.l1_lines += w.l1_lines;
    st.traversal.max_stack = st.traversal.max_stack.max(w.max_stack);
    st.scene_lines += w.lines_read[StreamTag::Scene as usize];
    st.ray_lines_read += w.lines_read[StreamTag::Ray as usize];
    st.ray_lines_written +=
        w.lines_written[StreamTag::Ray as usize] - queue_lines_written(w.rays_emitted, rpb);
    st.hit_lines_read += w.lines_read[StreamTag::Hit as usize];
    st.hit_lines_written += w.lines_written[StreamTag::Hit as usize];
}

/// Puts a new ray into the root segment's queue and resets its hit record.
fn emit(
    p: &mut Prepared,
    q: &mut RayQueues,
    st: &mut WaveStats,
    ray: &RayRec,
    keep: bool,
    list: &mut Vec<RayRec>,
) -> Result<(), String> {
    q.push(&mut p.mem, &p.map, 0, ray)?;
    HitRec::NONE.write(&mut p.mem, p.map.hit_addr(ray.hit_index()));
    st.hit_lines_written += 1;
    st.rays += 1;
    st.enqueues += 1;
    if ray.is_shadow() {
        st.shadow_rays += 1;
    } else {
        st.bounce_rays += 1;
    }
    if keep {
        list.push(*ray);
    }
    Ok(())
}

/// Dual streaming, functional: segments in depth-first order, each loaded once if
/// its queue has rays; every ray of the queue traverses the segment locally and is
/// duplicated into the queue of each child segment it exits into.
/// `hook` is called before each segment that holds rays (with its id) and once at
/// the end (with `u32::MAX`).
fn trace_functional(
    p: &mut Prepared,
    q: &mut RayQueues,
    st: &mut WaveStats,
    progress: &mut dyn FnMut(u64, u64),
    hook: &mut SegHook,
) -> Result<(), String> {
    let mut done = 0u64;
    let mut rays = Vec::new();
    let mut stack = Vec::new();
    let mut exits: Vec<(u32, u32)> = Vec::new();
    for s in 0..p.seg.segments.len() as u32 {
        if q.is_empty(s) {
            // No rays: the segment and (since rays come only from parents) its whole
            // subtree are skipped.
            continue;
        }
        hook(s, p, q, st)?;
        let e = SegEntry::read(&p.mem, p.map.seg_entry_addr(s));
        let view = SegmentView::load(&p.mem, e.base, s, e.nodes, e.tris);
        st.segments_loaded += 1;
        st.scene_lines += lines_touched(e.base, e.bytes as u64);
        while {
            rays.clear();
            q.pop_bucket(&p.mem, &p.map, s, &mut rays)
        } {
            for ray in &rays {
                exits.clear();
                let best =
                    traverse_segment(&view, ray, &mut stack, &mut st.traversal, |seg, entry| {
                        exits.push((seg, entry))
                    });
                for &(cs, entry) in &exits {
                    q.push(&mut p.mem, &p.map, cs, &RayRec { entry, ..*ray })?;
                    st.enqueues += 1;
                }
                if best.is_hit() {
                    update_hit(&mut p.mem, &p.map, ray.hit_index(), best, st);
                }
            }
            done += rays.len() as u64;
            progress(done, st.enqueues);
        }
        for k in 0..e.child_count {
            let c = p
                .mem
                .read_u32(p.map.child_list + (e.first_child + k) as u64 * 4);
            q.close(&mut p.mem, &p.map, c);
        }
    }
    hook(u32::MAX, p, q, st)
}

type SegHook<'a> = dyn FnMut(u32, &mut Prepared, &RayQueues, &WaveStats) -> Result<(), String> + 'a;

/// The reference: every ray of the root queue traced through the whole BVH.
fn trace_reference(p: &mut Prepared, q: &mut RayQueues, scene: &Scene, st: &mut WaveStats) {
    let mut rays = Vec::new();
    while q.pop_bucket(&p.mem, &p.map, 0, &mut rays) {}
    for ray in &rays {
        let best = traverse::reference_trace_counted(
            &p.bvh,
            &scene.triangles,
            ray.origin,
            ray.dir,
            ray.is_shadow(),
            &mut st.traversal,
        );
        if best.is_hit() {
            update_hit(&mut p.mem, &p.map, ray.hit_index(), best, st);
        }
    }
}

/// Compares every hit record of the wavefront with the reference traversal:
/// the closest (t, id) for bounce rays, occluded or not for shadow rays.
fn verify(p: &Prepared, scene: &Scene, rays: &[RayRec]) -> Result<u64, String> {
    for ray in rays {
        let got = HitRec::read(&p.mem, p.map.hit_addr(ray.hit_index()));
        let want = reference_trace(
            &p.bvh,
            &scene.triangles,
            ray.origin,
            ray.dir,
            ray.is_shadow(),
        );
        let same = if ray.is_shadow() {
            got.is_hit() == want.is_hit()
        } else {
            got.tri_id == want.tri_id && got.t.to_bits() == want.t.to_bits()
        };
        if !same {
            return Err(format!(
                "ray {:#x} (origin {:?}, dir {:?}): traced {:?}, reference {:?}",
                ray.ray_id, ray.origin, ray.dir, got, want
            ));
        }
    }
    Ok(rays.len() as u64)
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
) -> Result<(), String> {
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

/// Traces a batch of rays (origin, direction, shadow?) as one wavefront and returns
/// their hit records, read back from the DRAM image. Ray i gets pixel id i, so the
/// batch may hold at most one bounce and one shadow ray per index (tests use it to
/// aim rays at shared edges and vertices).
pub fn trace_rays(
    scene: &Scene,
    cfg: &RenderCfg,
    mode: Mode,
    rays: &[(Vec3, Vec3, bool)],
) -> Result<(Vec<HitRec>, WaveStats), String> {
    let mut sc = scene.clone();
    // Room for one hit-record pair per ray.
    sc.settings.width = rays.len().max(1) as u32;
    sc.settings.height = 1;
    let mut p = prepare(&sc, cfg)?;
    let mut q = RayQueues::new(&p.map, p.seg.segments.len());
    let mut st = WaveStats::default();
    let root = p.image.root_entry.encode();
    let recs: Vec<RayRec> = rays
        .iter()
        .enumerate()
        .map(|(i, &(o, d, sh))| RayRec {
            origin: o,
            dir: d,
            ray_id: i as u32 | if sh { SHADOW_BIT } else { 0 },
            entry: root,
        })
        .collect();
    let mut unused = Vec::new();
    for r in &recs {
        emit(&mut p, &mut q, &mut st, r, false, &mut unused)?;
    }
    q.close(&mut p.mem, &p.map, 0);
    match mode {
        Mode::Functional => trace_functional(
            &mut p,
            &mut q,
            &mut st,
            &mut |_, _| {},
            &mut |_, _, _, _| Ok(()),
        )?,
        Mode::Reference => trace_reference(&mut p, &mut q, &sc, &mut st),
        Mode::Cycle => {
            return Err(
                "trace_rays runs functional or reference mode; render a frame for cycle mode"
                    .into(),
            );
        }
    }
    Ok((
        recs.iter()
            .map(|r| HitRec::read(&p.mem, p.map.hit_addr(r.hit_index())))
            .collect(),
        st,
    ))
}

/// Writes a wavefront's rays (32 B ray records) and their hit records (16 B), in the
/// same order, as `wave<k>_rays.bin` and `wave<k>_hits.bin` (data contract layouts).
fn dump(dir: &std::path::Path, wave: usize, p: &Prepared, rays: &[RayRec]) -> Result<(), String> {
    let mut rb = Vec::with_capacity(rays.len() * 32);
    let mut hb = Vec::with_capacity(rays.len() * 16);
    for r in rays {
        for f in [
            r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z,
        ] {
            rb.extend_from_slice(&f.to_le_bytes());
        }
        rb.extend_from_slice(&r.ray_id.to_le_bytes());
        rb.extend_from_slice(&r.entry.to_le_bytes());
        let h = HitRec::read(&p.mem, p.map.hit_addr(r.hit_index()));
        hb.extend_from_slice(&h.t.to_le_bytes());
        hb.extend_from_slice(&h.tri_id.to_le_bytes());
        hb.extend_from_slice(&h.u.to_le_bytes());
        hb.extend_from_slice(&h.v.to_le_bytes());
    }
    for (name, bytes) in [
        (format!("wave{wave}_rays.bin"), rb),
        (format!("wave{wave}_hits.bin"), hb),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, bytes)
            .map_err(|e| format!("cannot write '{}': {e}", path.display()))?;
    }
    Ok(())
}
