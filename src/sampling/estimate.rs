//! Time sampling's estimate of a frame's chip figures from its windows and
//! the functional model's counts.

use crate::sampling::SamplingError;
use serde::Serialize;

use super::analytic::{FrameParts, line_write_j};
use super::counts::Count::*;
use super::counts::Counts;
use super::parts::Parts;
use super::{
    KindTime, WindowPlan, WindowRecord, WindowsProgress, render_cfg, render_windows_progress,
};
use crate::config::Config;
use crate::render::{self, Frame, RenderCfg};
use crate::rtl::Threads;
use crate::scene::Scene;
use crate::units::memory::MemoryModel;

/// One part of a time-sampled frame as [`windowed_parts`] estimated it: per
/// wavefront the `root` pass, the `head` (the admissions after it simulated
/// whole), the scaled `rest`, the `tail`; per pass `shade`; `emit` (ray
/// generation). `first..end`: admission ordinals of a trace part (the root is
/// 0..1), else 0..0.
#[derive(Clone, Debug, Serialize)]
pub struct WindowPart {
    pub wave: usize,
    pub part: &'static str,
    pub first: u64,
    pub end: u64,
    pub cycles: f64,
    pub lines: f64,
    pub dram_j: f64,
    /// Not simulated: the part's proxy times the measured wavefronts' ratio
    /// (`WindowPlan::wave_every`).
    pub borrowed: bool,
}

/// A time-sampled frame's estimate (with its relative standard error of cycles,
/// lines and energy, if known) and the estimate by part of the frame.
struct Windowed {
    breakdown: Vec<WindowPart>,
    estimate: WindowEstimate,
}

/// The estimate of the frame `f`, rendered in functional mode with windows
/// that recorded `rec`, by part ([`Parts::of`]) and in all. Per wavefront,
/// the trace is its head (the root window scaled by its rays, then the
/// passes up to `head` simulated as is), its tail (simulated as is) and
/// between them the rest, scaled from the measured windows by the proxy
/// (`seg_proxy`) of the rest over that of the work the windows did (rays
/// finished by segment); each shading pass is its head as is and its windows
/// scaled by the items left over the measured items. Also the relative
/// standard error of the rest's cycles, lines and DRAM energy from the
/// windows' spread (`None` where a wavefront had fewer than two windows).
fn windowed_parts(c: &Config, f: &Frame, rec: &WindowRecord) -> Result<Windowed, SamplingError> {
    let wb_j = line_write_j(c)?;
    let Parts {
        mut total,
        parts,
        var,
        se_known,
        ..
    } = Parts::of(c, rec, wb_j)?;
    // The ray and scene streams: the chip moves exactly the functional model's
    // lines (the same buckets written and read, the same segments loaded, in
    // any timing: `tests/chip.rs` checks every wavefront's counts), so they are
    // taken from it rather than estimated. The hit records and the shading
    // pass go through the L2, whose filtering the windows measure.
    total[RayLines] = f.total.ray_lines() as f64;
    total[SceneLines] = f.total.scene_lines as f64;
    let e = onchip_energy(c, f, &total);
    let p = FrameParts {
        cycles: total[Cycles],
        ray_lines: total[RayLines],
        scene_lines: total[SceneLines],
        hit_lines: total[HitLines],
        shading_lines: total[ShadingLines],
        onchip_j: e.compute_j + e.onchip_j,
        dram_j: total[DramPaperJ],
    };
    let f3 = p.combine();
    let se = se_known.then(|| std::array::from_fn(|k| var[k].sqrt() / f3[k].max(1e-30)));
    Ok(Windowed {
        breakdown: parts,
        estimate: WindowEstimate {
            cycles: total[Cycles],
            ray_lines: total[RayLines],
            scene_lines: total[SceneLines],
            hit_lines: total[HitLines],
            shading_lines: total[ShadingLines],
            dram_paper_j: total[DramPaperJ],
            dram_physical_j: total[DramPhysicalJ],
            onchip_j: e.onchip_j,
            compute_j: e.compute_j,
            rel_se: se,
            windows: rec.samples.len(),
            chip_s: rec.chip_s,
            chip_s_by_kind: rec.chip_s_by_kind(),
            core_ps: c.clocks.core_ps,
            rays: f.total.rays,
        },
    })
}

/// On-chip energy: the functional frame's traversal with the estimated global
/// units' activity (`total`), as a cycle frame would have it.
fn onchip_energy(c: &Config, f: &Frame, total: &Counts) -> crate::energy::Energy {
    let mut g = f.clone();
    let mut w = crate::machine::WaveCycles {
        scene_buffer_reads: total[SceneBufferReads].round() as u64,
        shade_uses: crate::energy::ShadeUses {
            shade_load: total[ShadeLoad].round() as u64,
            shade: total[Shade].round() as u64,
            shade_emit: total[ShadeEmit].round() as u64,
            shade_store: total[ShadeStore].round() as u64,
        },
        ..Default::default()
    };
    w.l2.accesses = total[L2Accesses].round() as u64;
    g.chip = Some(render::ChipFrame {
        shading_on_tps: true,
        tms: c.chip.tms,
        tps_per_tm: c.tm.tps,
        waves: vec![w],
        total_cycles: total[Cycles].round() as u64,
        sim_wall_s: 0.0,
        cycles_per_s: 0.0,
        memory_model: "gddr5".into(),
        core_ps: c.clocks.core_ps,
        line_bytes: crate::contract::LINE_BYTES,
        dram: None,
        vcd: None,
        captured: Vec::new(),
        follow: None,
        evals_by_module: Vec::new(),
        sim_steps_by_lanes: Vec::new(),
    });
    crate::render::energy::frame_energy(c, &g)
}

/// A frame's chip figures as time sampling estimates them (the `windows` mode):
/// what the chip with GDDR5 would report for the frame, from its windows and the
/// functional model's counts. Its error against the cycle model on the paper
/// scenes is measured in `docs/speed-error.md`; `rel_se` is its own estimate.
#[derive(Clone, Debug, Default, Serialize)]
pub struct WindowEstimate {
    pub cycles: f64,
    /// DRAM lines of each stream: rays, scene, hit records, shading.
    pub ray_lines: f64,
    pub scene_lines: f64,
    pub hit_lines: f64,
    pub shading_lines: f64,
    /// DRAM energy, `paper` and `physical` preset.
    pub dram_paper_j: f64,
    pub dram_physical_j: f64,
    /// On-chip memory and compute energy with the estimated global units' activity.
    pub onchip_j: f64,
    pub compute_j: f64,
    /// One relative standard error of the cycles, lines and energy from the
    /// windows' spread (`None` with fewer than two windows per wavefront).
    pub rel_se: Option<[f64; 3]>,
    /// Windows simulated, and their summed wall time, in all and by kind.
    pub windows: usize,
    pub chip_s: f64,
    pub chip_s_by_kind: Vec<KindTime>,
    /// Core clock period (ps), and the rays the frame traced.
    pub core_ps: u64,
    pub rays: u64,
}

impl WindowEstimate {
    /// DRAM lines of every stream.
    pub fn lines(&self) -> f64 {
        self.ray_lines + self.scene_lines + self.hit_lines + self.shading_lines
    }
    /// Render time (ms) at the core clock.
    pub fn time_ms(&self) -> f64 {
        self.cycles * self.core_ps as f64 * 1e-9
    }
    /// Rays traced per second (millions) at that time.
    pub fn mrays_per_s(&self) -> f64 {
        self.rays as f64 / (self.time_ms() * 1e-3).max(1e-30) / 1e6
    }
    /// The windows' own standard error as text, where they have one.
    pub fn se_text(&self) -> Option<String> {
        self.rel_se.map(|[c, l, j]| {
            format!(
                "own standard error (windows' spread): cycles {:.1}%, lines {:.1}%, energy {:.1}%",
                100.0 * c,
                100.0 * l,
                100.0 * j
            )
        })
    }
    /// Average DRAM bandwidth (GB/s) over that time.
    pub fn bandwidth_gbs(&self) -> f64 {
        self.lines() * crate::contract::LINE_BYTES as f64 / (self.time_ms() * 1e-3).max(1e-30) / 1e9
    }
}

/// A frame rendered by the functional model with time sampling's windows on the
/// chip with GDDR5: the frame (its image is the cycle model's), the estimate of
/// the cycle model's figures, and the estimate by part.
pub struct TimeSampled {
    pub frame: Frame,
    pub estimate: WindowEstimate,
    pub parts: Vec<WindowPart>,
    /// What the windows recorded.
    pub record: WindowRecord,
}

/// Renders `scene` with time sampling (`plan`) on `threads` simulator threads
/// (above one: that many windows side by side), with `config`'s chip on GDDR5.
pub fn time_sampled(
    scene: &Scene,
    config: &Config,
    threads: impl Into<Threads>,
    plan: &WindowPlan,
) -> Result<TimeSampled, SamplingError> {
    time_sampled_with(
        scene,
        config,
        render_cfg(config, None, threads.into()),
        plan,
    )
}

/// [`time_sampled`] with the rest of the render's settings from `rc` (its
/// checks, its ray dumps, its chip's simulator options); its chip is
/// `config`'s on GDDR5 and its windows `plan`'s.
pub fn time_sampled_with(
    scene: &Scene,
    config: &Config,
    rc: RenderCfg,
    plan: &WindowPlan,
) -> Result<TimeSampled, SamplingError> {
    time_sampled_progress(scene, config, rc, plan, &mut |_| {})
}

/// [`time_sampled_with`], calling `progress` as [`render_windows_progress`].
pub fn time_sampled_progress(
    scene: &Scene,
    config: &Config,
    mut rc: RenderCfg,
    plan: &WindowPlan,
    progress: &mut dyn FnMut(&WindowsProgress),
) -> Result<TimeSampled, SamplingError> {
    plan.validate()?;
    let mut gddr5 = config.clone();
    gddr5.chip.memory.model = MemoryModel::Gddr5;
    match rc.chip.as_mut() {
        Some(ch) => ch.config = gddr5.clone(),
        None => rc.chip = render_cfg(&gddr5, None, Threads::fixed(1)).chip,
    }
    let (frame, record) = render_windows_progress(scene, &rc, plan, progress)?;
    let w = windowed_parts(&gddr5, &frame, &record)?;
    Ok(TimeSampled {
        frame,
        estimate: w.estimate,
        parts: w.breakdown,
        record,
    })
}
