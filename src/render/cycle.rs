//! Cycle mode: the chip (`src/machine/`) traces every wavefront from the DRAM
//! image; how a frame's chip is built and run, and what it reports.

use serde::Serialize;

use super::queues::{RayQueues, queue_lines_written};
use super::{Prepared, RenderCfg, RenderError, WaveStats, shade_consts};

/// How to build and run the chip in cycle mode.
#[derive(Clone, Debug, Default)]
pub struct ChipRun {
    pub config: crate::config::Config,
    pub sim: crate::rtl::SimOptions,
    /// Write a VCD waveform of the run (`render --vcd`).
    pub trace: Option<ChipTrace>,
    /// Follow these rays (wavefront, ray id) through the chip (`render
    /// --follow-ray`): their events are in [`ChipFrame::follow`].
    pub follow: Option<Vec<(u32, u32)>>,
    /// Capture vectors (`render --capture`, docs/rtl.md): `filter` holds the
    /// unit names as `--capture` takes them (`crate::machine::trace::resolve_capture`).
    pub capture: Option<crate::rtl::trace::CaptureSpec>,
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
    /// Sample every unit at every edge (`TraceSpec::every_edge`).
    pub every_edge: bool,
    /// Which signals the file holds (`TraceSpec::show`).
    pub show: crate::rtl::trace::Show,
}

/// Core cycles per pixel and hit point of a cycle-mode frame on the paper's
/// 128 TMs, from the measured frames (docs/table2.md, "What a cycle-mode frame
/// costs"); a scene that is mostly sky costs less. Scales with 128 / TMs.
const CYCLES_PER_PIXEL_HIT: f64 = 8.0;

/// Wall seconds per pixel and hit point of a cycle-mode frame on the
/// project's 2-core machine, the cheapest and the dearest frame measured
/// (docs/table2.md, "What a cycle-mode frame costs"); about the same for any
/// number of TMs (cycles scale with 128 / TMs and the work of a cycle with TMs).
pub const WALL_S_PER_PIXEL_HIT: (f64, f64) = (0.17e-3, 0.45e-3);

/// Before a cycle-mode frame of more than five minutes: how long it takes,
/// and the faster mode.
pub fn long_frame_note(s: &crate::scene::RenderSettings, tms: u32) -> Option<String> {
    let pixels = s.width as f64 * s.height as f64 * s.spp as f64;
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
    /// The vector files written (`ChipRun::capture`; not a statistic).
    #[serde(skip)]
    pub captured: Vec<crate::rtl::trace::CaptureFile>,
    /// The followed rays' events in cycle order (`ChipRun::follow`; not a
    /// statistic).
    #[serde(skip)]
    pub follow: Option<Vec<crate::units::follow::FollowEvent>>,
    /// The simulator's evaluations by unit kind over the frame, most first
    /// (where its time went; they depend on the kernel, not the chip's results).
    pub evals_by_module: Vec<crate::rtl::ModuleEvals>,
    /// Simulator steps taken with 1, 2, ... evaluation lanes (`--threads`; how
    /// the run spent its time, not a result); in the JSON an object,
    /// `{"lanes_1": .., "lanes_2": ..}`.
    #[serde(serialize_with = "by_lanes")]
    pub sim_steps_by_lanes: Vec<u64>,
}

/// `[a, b]` as `{"lanes_1": a, "lanes_2": b}`.
pub fn by_lanes<S: serde::Serializer>(v: &[u64], s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut m = s.serialize_map(Some(v.len()))?;
    for (k, n) in v.iter().enumerate() {
        m.serialize_entry(&format!("lanes_{}", k + 1), n)?;
    }
    m.end()
}

impl ChipFrame {
    /// Achieved DRAM bandwidth (GB/s) over the traced cycles (`gddr5`).
    pub fn dram_bandwidth_gbs(&self) -> Option<f64> {
        self.dram
            .map(|d| d.bandwidth_gbs(self.line_bytes, self.total_cycles, self.core_ps))
    }
}

/// Cycle mode with shading on the TPs: what a chip run's shading pass did goes to
/// the wavefront it shaded (`prev`: hits, blocked shadow rays, shading lines and,
/// as in functional mode, the root-queue writes of the rays it emitted); the rays
/// it emitted start the new wavefront's counts (`st`).
pub(super) fn add_chip_shading(
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
pub(super) fn add_chip_wave(st: &mut WaveStats, w: &crate::machine::WaveCycles, rpb: u32) {
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

/// A cycle-mode frame's chip, its configuration and its runs so far.
pub(super) struct FrameChip {
    pub(super) chip: crate::machine::Chip,
    cfg: crate::config::Config,
    /// Shading on the TPs: every chip run after the first shades the finished
    /// wavefront and traces the one it emits.
    pub(super) tp_shading: bool,
    /// Per chip run: cycles and the chip's own counts.
    pub(super) waves: Vec<crate::machine::WaveCycles>,
    /// The followed rays' log (`ChipRun::follow`).
    follow: Option<crate::units::follow::FollowLog>,
}

impl FrameChip {
    /// The chip of `cfg` (its `accel` and `memory` from `cfg` too) over the
    /// image `p`, with its waveform, root log and pass log as asked.
    pub(super) fn new(
        scene: &crate::scene::Scene,
        cfg: &RenderCfg,
        p: &Prepared,
        pixels: u32,
    ) -> Result<FrameChip, RenderError> {
        let run = cfg.chip.as_deref().cloned().unwrap_or_default();
        let mut chip_cfg = run.config;
        chip_cfg.accel = cfg.accel.clone();
        chip_cfg.memory = cfg.memory.clone();
        let consts = shade_consts(scene, p);
        let nseg = p.seg.segments.len();
        let mut c = crate::machine::Chip::new(&chip_cfg, &p.map, nseg, &consts, run.sim)?;
        c.stack_need = Some(p.seg.stack_bound(&p.bvh));
        if let Some(t) = &run.trace {
            let paths: Vec<String> = (0..c.sim.unit_count())
                .map(|i| c.sim.unit_path(crate::rtl::UnitId(i as u32)).to_string())
                .collect();
            let paths: Vec<&str> = paths.iter().map(String::as_str).collect();
            let filter = crate::machine::trace::resolve(&t.units, &paths)?;
            let spec = crate::rtl::TraceSpec {
                every_edge: t.every_edge,
                show: t.show,
                ..crate::machine::trace::spec(
                    filter,
                    t.from,
                    t.to,
                    chip_cfg.clocks.core_ps,
                    t.max_bytes,
                )
            };
            let mut tracer = crate::rtl::Tracer::to_file(&t.path, spec)?;
            // Twice the frame's estimated cycles: the guard projects the bytes
            // written to the window's end.
            let cycles =
                estimated_frame_cycles(pixels as u64, scene.settings.bounces, chip_cfg.chip.tms);
            tracer.expect_end(2 * cycles * chip_cfg.clocks.core_ps);
            c.sim.attach_tracer(tracer)?;
        }
        if let Some(cap) = &run.capture {
            let paths: Vec<String> = (0..c.sim.unit_count())
                .map(|i| c.sim.unit_path(crate::rtl::UnitId(i as u32)).to_string())
                .collect();
            let paths: Vec<&str> = paths.iter().map(String::as_str).collect();
            let filter = crate::machine::trace::resolve_capture(&cap.filter, &paths)?;
            c.sim.attach_capture(&crate::rtl::trace::CaptureSpec {
                filter,
                ..cap.clone()
            })?;
        }
        if cfg.verify || cfg.dump_rays.is_some() {
            c.enable_root_log();
        }
        if cfg.pass_log {
            c.enable_pass_log();
        }
        let follow = match &run.follow {
            Some(t) => {
                check_follow(t, scene.settings.bounces, pixels)?;
                Some(c.follow(t.clone()))
            }
            None => None,
        };
        let tp_shading = chip_cfg.chip.shading == crate::config::Shading::Tps;
        Ok(FrameChip {
            chip: c,
            cfg: chip_cfg,
            tp_shading,
            waves: Vec::new(),
            follow,
        })
    }

    /// One chip run: with shading on the TPs and a wavefront before
    /// (`!first`), its shading pass and the trace of the rays it emits; else
    /// the trace of the rays the host put into the root queue (`q`).
    pub(super) fn run(
        &mut self,
        q: &mut RayQueues,
        mem: &mut crate::contract::SparseMem,
        pixels: u32,
        first: bool,
        tick: &mut dyn FnMut(u64),
    ) -> Result<crate::machine::WaveCycles, RenderError> {
        if self.tp_shading && !first {
            Ok(self.chip.shade_and_trace_ticking(mem, pixels, tick)?)
        } else {
            let rays = q.take_diverted();
            Ok(self.chip.trace_wave_ticking(mem, &rays, tick)?)
        }
    }

    /// An error if none of the followed rays was ever queued (a ray of a
    /// wavefront its path did not reach: its pixel's shading may still show).
    pub(super) fn check_followed(&self, targets: &[(u32, u32)]) -> Result<(), RenderError> {
        match (&self.follow, targets.first()) {
            (Some(log), Some(&(wave, ray_id))) if !log.any_queued() => {
                Err(RenderError::NoSuchRay {
                    wave,
                    ray_id,
                    why: format!(
                        "the chip never traced it: the pixel's path has no such ray (paths end when a ray leaves the scene or after the last hit point; wavefront {wave} holds a bounce ray only before the last); follow an earlier wavefront, the shadow ray (an `s` suffix) or the pixel (--follow-pixel)"
                    ),
                })
            }
            _ => Ok(()),
        }
    }

    /// Closes the waveform, if one is written, with named markers at the
    /// followed rays' key events.
    pub(super) fn finish_trace(&mut self) -> Result<Option<VcdInfo>, RenderError> {
        if let Some(log) = &self.follow {
            let ps = self.cfg.clocks.core_ps;
            let markers = log
                .events()
                .iter()
                .filter(|e| is_key(&e.kind))
                .map(|e| (e.cycle * ps, marker_name(e)))
                .collect();
            self.chip.sim.set_trace_markers(markers);
        }
        let Some(r) = self.chip.sim.finish_trace() else {
            return Ok(None);
        };
        let t = r.map_err(RenderError::Vcd)?;
        Ok(Some(VcdInfo {
            units: t.units,
            signals: t.signals,
            changes: t.changes,
            bytes: t.bytes,
        }))
    }

    /// The frame's chip figures.
    pub(super) fn frame(self, vcd: Option<VcdInfo>) -> ChipFrame {
        let (c, chip_cfg) = (self.chip, self.cfg);
        ChipFrame {
            shading_on_tps: self.tp_shading,
            tms: chip_cfg.chip.tms,
            tps_per_tm: chip_cfg.tm.tps,
            total_cycles: c.total_cycles,
            sim_wall_s: c.wall_s,
            cycles_per_s: c.total_cycles as f64 / c.wall_s.max(1e-9),
            memory_model: chip_cfg.chip.memory.model.name().into(),
            core_ps: chip_cfg.clocks.core_ps,
            line_bytes: crate::contract::LINE_BYTES,
            dram: (chip_cfg.chip.memory.model == crate::units::memory::MemoryModel::Gddr5).then(
                || {
                    let mut t = crate::machine::DramWave::default();
                    for w in &self.waves {
                        t.add(&w.dram);
                    }
                    t
                },
            ),
            waves: self.waves,
            vcd,
            captured: c.sim.captured(),
            follow: self.follow.map(|l| l.events()),
            evals_by_module: c.sim.evals_by_module(),
            sim_steps_by_lanes: c.sim.steps_by_lanes().to_vec(),
        }
    }
}

/// Checks the rays to follow against the frame: wavefronts `0..=bounces`,
/// pixels `0..pixels`, no shadow ray in wavefront 0.
fn check_follow(targets: &[(u32, u32)], bounces: u32, pixels: u32) -> Result<(), RenderError> {
    use crate::contract::SHADOW_BIT;
    for &(wave, ray_id) in targets {
        let bad = |why: String| RenderError::NoSuchRay { wave, ray_id, why };
        if wave > bounces {
            return Err(bad(format!(
                "the frame has wavefronts 0..={bounces} (one per hit point after the primary rays; --bounces)"
            )));
        }
        let pixel = ray_id & !SHADOW_BIT;
        if pixel >= pixels {
            return Err(bad(format!(
                "ray ids are pixel indices 0..{pixels} (y * width + x), plus {SHADOW_BIT:#x} for a shadow ray"
            )));
        }
        if wave == 0 && ray_id & SHADOW_BIT != 0 {
            return Err(bad(
                "wavefront 0 holds the primary rays only; shadow rays start in wavefront 1".into(),
            ));
        }
    }
    Ok(())
}

/// The events a waveform's named markers go at: where the ray enters a
/// queue, a TP, the hit record, and its pixel's shading.
fn is_key(k: &crate::units::follow::FollowKind) -> bool {
    use crate::units::follow::FollowKind::*;
    matches!(
        k,
        Queued { .. } | Taken { .. } | Finish { .. } | HitCompared { .. } | ShadeTaken { .. }
    )
}

/// A named marker's name: the ray, the event, the unit (`w1 0x89 taken seg3 chip.tm2.tp5`).
fn marker_name(e: &crate::units::follow::FollowEvent) -> String {
    let seg = e.kind.seg().map_or(String::new(), |s| format!(" seg{s}"));
    format!(
        "w{} {:#x} {}{seg} {}",
        e.wave,
        e.ray_id,
        e.kind.name(),
        e.unit
    )
}
