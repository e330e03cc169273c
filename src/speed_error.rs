//! `dualstream bench speed-error`: every faster way of getting a frame's figures,
//! with its wall time and its error against the full cycle model (the chip with the
//! GDDR5 memory, `chip.memory.model = "gddr5"`) on the same scene and config.
//!
//! Modes:
//! - `cycle` — the reference: the chip, GDDR5, every pixel;
//! - `cycle-fixed` — the chip with the fixed-latency memory (no DRAM timing);
//! - `functional+estimate` — functional dual streaming (no clock) and a first-order
//!   timing estimate from its traffic and operation counts ([`estimate`]);
//! - `small-chip` — the chip with fewer TMs, cycles scaled linearly to the full TM
//!   count (the question being whether that is ever accurate);
//! - `small-chips-fit` — two small chips (s and 2s TMs), cycles fitted as
//!   a + b / TMs and evaluated at the full count (when 2s < `chip.tms`);
//! - `quarter-pixels` — the cycle model on a frame of half the width and height,
//!   every count and the cycles scaled by the pixel ratio (4);
//! - `sampled` — the cycle model on `subsets` disjoint samples of the frame's tiles
//!   (one T x T tile in k each, [`tile_sample`]), each traced as a frame of its own
//!   with the pixels' own rays; two estimates from the same runs: `sampled` (a ratio
//!   estimator: the functional model's figures for the whole frame times the mean
//!   over the samples of cycle-model / functional-model figures, the functional
//!   cycles being [`estimate`]) and `sampled-scaled` (the samples' figures times
//!   the pixel ratio). Each states its sampling error as the standard error of the
//!   mean over the samples (relative), next to its actual error.
//!
//! Energy everywhere is compute + on-chip ([`crate::render::energy::frame_energy`]) + DRAM
//! with the `paper` preset; where the mode has no DRAM timing its DRAM energy is
//! estimated from the line counts ([`dram_energy_estimate`]).

use crate::config::Config;
use crate::render::{self, Frame, Mode, RenderCfg};
use crate::rtl::Threads;
use crate::scene::Scene;
use crate::units::memory::MemoryModel;
use serde::Serialize;
use std::fmt::Write;
use std::path::Path;

/// One mode's figures and errors (relative, signed: (mode - reference) / reference).
#[derive(Clone, Debug, serde::Serialize)]
pub struct ModeResult {
    pub mode: String,
    pub wall_s: f64,
    pub speedup: f64,
    pub cycles: f64,
    pub lines: f64,
    pub energy_j: f64,
    pub err_cycles: f64,
    pub err_lines: f64,
    pub err_energy: f64,
    /// Whether the mode's image equals the reference's bit for bit (`None`: it
    /// renders a different frame; sampled modes: on the pixels they render).
    pub image_identical: Option<bool>,
    /// The mode's own estimate of its relative error (one standard error) in
    /// cycles, lines and energy, where it has one (sampled modes).
    pub est_err: Option<[f64; 3]>,
    pub note: String,
    /// `windows` with a reference pass log: the estimate by part against it.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub by_part: Vec<PartCheck>,
}

/// A first-order timing estimate of a functional frame: per wavefront the largest
/// of its resource bounds (DRAM bandwidth, the ray and scene streams' lines per
/// cycle, box and triangle pipelines, TP occupancy), plus the shading pass's bounds.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Estimate {
    pub cycles: f64,
    /// Per wavefront: the binding bound's name and its cycles.
    pub binding: Vec<(&'static str, f64)>,
}

/// Peak DRAM bytes per core cycle (all channels, every beat used).
fn peak_bytes_per_cycle(c: &Config) -> f64 {
    let g = &c.mem.geometry;
    let per_ck = g.channels as f64 * g.bus_bits as f64 / 8.0 * g.transfers_per_ck as f64;
    per_ck * c.clocks.core_ps as f64 / c.clocks.dram_ps as f64
}

/// See [`Estimate`]. Uses only counts that do not depend on timing.
pub fn estimate(c: &Config, f: &Frame) -> Estimate {
    let line = crate::contract::LINE_BYTES as f64;
    let tms = c.chip.tms as f64;
    let tps = tms * c.tm.tps as f64;
    let peak = peak_bytes_per_cycle(c);
    let k = &c.tm.costs;
    let mut e = Estimate::default();
    for w in &f.waves {
        let t = &w.traversal;
        // TP occupancy: every state's listed cycles plus the pipeline latency a TP
        // waits for its test's result, spread over all TPs.
        let tp_cycles = (k.fetch.cycles as u64 + k.init.cycles as u64 + k.finish.cycles as u64)
            * w.enqueues
            + k.pop.cycles as u64 * t.pops
            + k.exit.cycles as u64 * t.exits
            + (k.node_fetch.cycles + k.box_issue.cycles + k.node_push.cycles + c.box_pipe.latency)
                as u64
                * t.nodes
            + (k.tri_fetch.cycles + k.tri_issue.cycles + k.tri_result.cycles + c.tri_pipe.latency)
                as u64
                * t.tri_tests;
        let bounds = [
            ("DRAM bandwidth", w.total_lines() as f64 * line / peak),
            (
                "ray stream",
                w.ray_lines() as f64 / c.chip.scheduler.ray_lines_per_cycle as f64,
            ),
            (
                "scene stream",
                w.scene_lines as f64 / c.chip.scheduler.scene_lines_per_cycle as f64,
            ),
            (
                "box pipes",
                t.nodes as f64 * c.box_pipe.interval as f64 / tms,
            ),
            (
                "triangle pipes",
                t.tri_tests as f64 * c.tri_pipe.interval as f64 / (tms * c.tm.tri_pipes as f64),
            ),
            ("TP occupancy", tp_cycles as f64 / tps),
        ];
        let (name, cyc) = bounds
            .into_iter()
            .fold(("", 0.0), |a, b| if b.1 > a.1 { b } else { a });
        // Shading: one item per path still alive, its loads and stores at DRAM
        // latency on one TP each (a latency-bound pass), or bandwidth-bound.
        let shade = (w.shading_lines as f64 * line / peak).max(
            (w.hits + w.occluded) as f64 / tps
                * (k.shade_load.cycles + k.shade.cycles + k.shade_store.cycles) as f64,
        );
        e.binding.push((name, cyc));
        e.cycles += cyc + shade;
    }
    e
}

/// The `paper` preset's DRAM energy model, the bursts per line and the lines
/// per DRAM row.
fn paper_dram(c: &Config) -> Result<(crate::mem::energy::EnergyModel, f64, f64), String> {
    preset_dram(c, "paper")
}

/// [`paper_dram`] for the DRAM energy preset `preset` (`paper`, `physical`).
fn preset_dram(
    c: &Config,
    preset: &str,
) -> Result<(crate::mem::energy::EnergyModel, f64, f64), String> {
    let g = &c.mem.geometry;
    let m = crate::mem::energy::EnergyModel::new(
        &crate::mem::config::EnergyCfg::by_name(preset, g)?,
        &c.mem.timing,
        g.burst_cycles(),
        c.clocks.dram_ps,
    );
    let line = crate::contract::LINE_BYTES as f64;
    let bursts_per_line = line / (g.bus_bits as f64 / 8.0 * g.burst_length as f64);
    Ok((m, bursts_per_line, c.memory.row_bytes as f64 / line))
}

/// DRAM energy (J, `paper` preset) of `lines` line transfers over `cycles` core
/// cycles when no DRAM timing was simulated: the bursts of every line, one activate
/// per row of lines, refresh and active standby for the whole time on every channel.
pub fn dram_energy_estimate(c: &Config, f: &Frame, cycles: f64) -> Result<f64, String> {
    let g = &c.mem.geometry;
    let (m, bursts_per_line, lines_per_row) = paper_dram(c)?;
    let t = &f.total;
    let reads =
        (t.ray_lines_read + t.scene_lines + t.hit_lines_read) as f64 + t.shading_lines as f64 / 2.0;
    let writes = t.total_lines() as f64 - reads;
    // Streams, hit records and path state are all walked in address order (by
    // segment, bucket, ray id or pixel), so one activate per row of lines.
    let acts = t.total_lines() as f64 / lines_per_row;
    let dram_cycles = cycles * c.clocks.core_ps as f64 / c.clocks.dram_ps as f64;
    let refs = dram_cycles / c.mem.timing.refi as f64 * g.channels as f64;
    let pj = reads * bursts_per_line * (m.rd_burst_pj + m.rd_io_pj)
        + writes * bursts_per_line * m.wr_burst_pj
        + acts * m.act_pre_pj
        + refs * m.ref_pj
        + dram_cycles * g.channels as f64 * m.act_stby_pj;
    Ok(pj * 1e-12)
}

/// DRAM energy (J) of writing one line, `paper` and `physical` preset: its
/// bursts and a share of an activate (lines written back in address order share
/// rows).
fn line_write_j(c: &Config) -> Result<[f64; 2], String> {
    let j = |preset| -> Result<f64, String> {
        let (m, bursts_per_line, lines_per_row) = preset_dram(c, preset)?;
        Ok((bursts_per_line * m.wr_burst_pj + m.act_pre_pj / lines_per_row) * 1e-12)
    };
    Ok([j("paper")?, j("physical")?])
}

fn total_energy(c: &Config, f: &Frame, cycles: f64) -> Result<f64, String> {
    Ok(figures(c, f, cycles)?[2])
}

fn render_pixels(
    scene: &Scene,
    mode: Mode,
    c: &Config,
    pixels: Option<Vec<u32>>,
    threads: Threads,
) -> Result<Frame, String> {
    let rc = render_cfg(c, pixels, threads);
    render::render(scene, mode, &rc, &mut |_| {})
}

fn render_cfg(c: &Config, pixels: Option<Vec<u32>>, threads: Threads) -> RenderCfg {
    RenderCfg {
        pixels,
        ..RenderCfg::for_chip(c, threads.sim())
    }
}

/// The pixels of one tile sample: the `tile` x `tile` tiles `(tx, ty)` with
/// `(tx + 3 ty) mod every == offset`, in raster order. Shifting each tile row by 3
/// spreads the kept tiles over the frame (a plain `index mod every` keeps whole
/// columns when `every` divides the tiles per row); the `every` offsets partition
/// the frame.
pub fn tile_sample(w: u32, h: u32, tile: u32, every: u32, offset: u32) -> Result<Vec<u32>, String> {
    if tile == 0 || tile > w.min(h) {
        return Err(format!(
            "--tile {tile} must be between 1 and the frame's smaller side ({}); choose a smaller tile",
            w.min(h)
        ));
    }
    if every == 0 {
        return Err("--sample-every 0 keeps nothing; give 1 (every tile) or more".into());
    }
    let keep = |x: u32, y: u32| ((x / tile) + 3 * (y / tile)) % every == offset % every;
    let v: Vec<u32> = (0..h)
        .flat_map(|y| (0..w).filter(move |&x| keep(x, y)).map(move |x| y * w + x))
        .collect();
    if v.is_empty() {
        return Err(format!(
            "a {w}x{h} frame has too few {tile}x{tile} tiles for one in {every}; use a smaller --tile or --sample-every"
        ));
    }
    Ok(v)
}

/// A cycle-mode reference read back from a finished run (`render --mode cycle
/// --stats f.json --out f.png` with GDDR5), so that a paper-size comparison need not
/// re-run a reference that takes half an hour. Its figures are formed exactly as the
/// bench forms them from a frame it renders itself.
#[derive(Clone, Debug)]
pub struct Reference {
    pub cycles: f64,
    pub lines: f64,
    pub energy_j: f64,
    pub wall_s: f64,
    /// Rays traced: every mode that traces the whole frame must trace exactly these.
    pub rays: u64,
    /// The reference's PNG (8-bit sRGB, row-major RGB), when given.
    pub rgb8: Option<Vec<u8>>,
    /// Per chip run: its shading pass's cycles, and (from its pass log) its
    /// segment passes' admission cycles in admission order and its last
    /// retirement. For the `windows` mode's check by part.
    pub shade_cycles: Vec<u64>,
    pub passes: Option<Vec<RunPasses>>,
}

/// One chip run of a reference's pass log: admission cycles in order, last
/// retirement.
#[derive(Clone, Debug, Default)]
pub struct RunPasses {
    pub admits: Vec<u64>,
    pub end: u64,
}

impl RunPasses {
    /// The reference's cycles of the admissions `first..end` (`end` past the
    /// last: to the run's last retirement).
    fn span(&self, first: u64, end: u64) -> f64 {
        let at = |k: u64| {
            self.admits
                .get(k as usize)
                .copied()
                .unwrap_or(self.end)
                .max(self.admits.first().copied().unwrap_or(0))
        };
        at(end).saturating_sub(at(first)) as f64
    }

    fn of_frame(f: &Frame) -> Vec<RunPasses> {
        f.passes
            .iter()
            .map(|run| {
                let mut admits: Vec<u64> = run.iter().map(|p| p.admit).collect();
                admits.sort_unstable();
                RunPasses {
                    admits,
                    end: run.iter().map(|p| p.retire).max().unwrap_or(0),
                }
            })
            .collect()
    }
}

/// Signed relative error of `x` against the reference `r` (0 for a zero reference).
fn rel(x: f64, r: f64) -> f64 {
    if r == 0.0 { 0.0 } else { (x - r) / r }
}

/// One part of the `windows` estimate next to the reference's (with a pass log).
#[derive(Clone, Debug, Serialize)]
pub struct PartCheck {
    pub wave: usize,
    pub part: &'static str,
    pub first: u64,
    pub end: u64,
    pub borrowed: bool,
    pub cycles: f64,
    pub ref_cycles: f64,
    pub err: f64,
}

/// Each trace and shading part of a `windows` estimate against the reference:
/// a trace part's reference cycles are those between the admissions that bound
/// it in the reference's run of that wavefront (a part's passes overlap the
/// next part's, as a pass lives for about 64 admissions), a shading pass's are
/// the reference's shading cycles of the next run. Empty without a pass log.
pub fn check_parts(parts: &[WindowPart], r: &Reference) -> Vec<PartCheck> {
    let Some(runs) = &r.passes else {
        return Vec::new();
    };
    parts
        .iter()
        .filter_map(|p| {
            let refc = match p.part {
                "shade" => *r.shade_cycles.get(p.wave + 1)? as f64,
                "emit" => return None,
                _ => runs.get(p.wave)?.span(p.first, p.end),
            };
            Some(PartCheck {
                wave: p.wave,
                part: p.part,
                first: p.first,
                end: p.end,
                borrowed: p.borrowed,
                cycles: p.cycles,
                ref_cycles: refc,
                err: rel(p.cycles, refc),
            })
        })
        .collect()
}

/// [`check_parts`] as a table.
pub fn part_table(checks: &[PartCheck]) -> String {
    use std::fmt::Write;
    let mut s = String::from(
        "by part (windows against the reference's pass log):\nwave  part   admissions      estimate     reference      err\n",
    );
    for c in checks {
        let span = if c.part == "shade" {
            "-".to_string()
        } else {
            format!("{}..{}", c.first, c.end)
        };
        let _ = writeln!(
            s,
            "{:>4}  {:<5}  {:<11}  {:>12.0}  {:>12.0}  {:>+6.1}%{}",
            c.wave,
            c.part,
            span,
            c.cycles,
            c.ref_cycles,
            100.0 * c.err,
            if c.borrowed { "  borrowed" } else { "" }
        );
    }
    s
}

impl Reference {
    /// Reads `stats` (and `png`) and checks that they are a GDDR5 cycle-mode frame of
    /// this scene, resolution and chip.
    pub fn load(
        stats: &Path,
        png: Option<&Path>,
        scene: &Scene,
        c: &Config,
    ) -> Result<Self, String> {
        let name = stats.display();
        let text = std::fs::read_to_string(stats)
            .map_err(|e| format!("cannot read the reference '{name}': {e}"))?;
        let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
            format!(
                "the reference '{name}' is not JSON ({e}); give the file `render --stats` wrote"
            )
        })?;
        let num = |path: &str| -> Result<f64, String> {
            v.pointer(path).and_then(|x| x.as_f64()).ok_or_else(|| {
                format!("the reference '{name}' has no number at {path}; give the --stats file of a `render --mode cycle` run")
            })
        };
        let text_at = |path: &str| v.pointer(path).and_then(|x| x.as_str()).unwrap_or("");
        let (w, h) = (scene.settings.width, scene.settings.height);
        let mut wrong = Vec::new();
        if text_at("/mode") != "cycle" {
            wrong.push(format!("mode '{}', not cycle", text_at("/mode")));
        }
        if text_at("/chip/memory_model") != "gddr5" {
            wrong.push(format!(
                "memory model '{}', not gddr5",
                text_at("/chip/memory_model")
            ));
        }
        if text_at("/scene") != scene.name {
            wrong.push(format!(
                "scene '{}', not '{}'",
                text_at("/scene"),
                scene.name
            ));
        }
        let (rw, rh) = (num("/width")? as u32, num("/height")? as u32);
        if (rw, rh) != (w, h) {
            wrong.push(format!("{rw}x{rh}, not {w}x{h}"));
        }
        let (tms, tps) = (num("/chip/tms")? as u32, num("/chip/tps_per_tm")? as u32);
        if (tms, tps) != (c.chip.tms, c.tm.tps) {
            wrong.push(format!(
                "{tms} x {tps} TPs, not {} x {}",
                c.chip.tms, c.tm.tps
            ));
        }
        if !wrong.is_empty() {
            return Err(format!(
                "the reference '{name}' does not match this comparison ({}); render it with `render --mode cycle` (GDDR5, the default memory) on the same scene, --res and config",
                wrong.join(", ")
            ));
        }
        let lines = [
            "ray_lines_read",
            "ray_lines_written",
            "scene_lines",
            "hit_lines_read",
            "hit_lines_written",
            "shading_lines",
        ]
        .iter()
        .map(|k| num(&format!("/total/{k}")))
        .sum::<Result<f64, String>>()?;
        let rgb8 = match png {
            None => None,
            Some(p) => {
                let img = image::open(p)
                    .map_err(|e| format!("cannot read the reference image '{}': {e}", p.display()))?
                    .to_rgb8();
                if img.dimensions() != (w, h) {
                    return Err(format!(
                        "the reference image '{}' is {}x{}, not {w}x{h}; give the PNG of the same run",
                        p.display(),
                        img.width(),
                        img.height()
                    ));
                }
                Some(img.into_raw())
            }
        };
        Ok(Reference {
            cycles: num("/chip/total_cycles")?,
            lines,
            energy_j: num("/energy/compute_j")?
                + num("/energy/onchip_j")?
                + num("/chip/dram/energy_paper_j")?,
            wall_s: num("/wall_s")?,
            rays: num("/total/rays")? as u64,
            rgb8,
            shade_cycles: v
                .pointer("/chip/waves")
                .and_then(|w| w.as_array())
                .map(|w| {
                    w.iter()
                        .map(|x| x["shade_cycles"].as_u64().unwrap_or(0))
                        .collect()
                })
                .unwrap_or_default(),
            passes: None,
        })
    }

    /// Reads the reference's pass log (`render --mode cycle --pass-log`), for
    /// the `windows` mode's check by part.
    pub fn read_passes(&mut self, csv: &Path) -> Result<(), String> {
        let name = csv.display();
        let text = std::fs::read_to_string(csv)
            .map_err(|e| format!("cannot read the reference's pass log '{name}': {e}"))?;
        let mut runs: Vec<RunPasses> = Vec::new();
        for (i, line) in text.lines().enumerate().skip(1) {
            let f: Vec<u64> = line
                .split(',')
                .map(|x| x.trim().parse::<u64>())
                .collect::<Result<_, _>>()
                .map_err(|_| {
                    format!("the pass log '{name}', line {}: '{line}' is not run,segment,rays,admit,retire; give the file `render --pass-log` wrote", i + 1)
                })?;
            let [run, _, _, admit, retire] = f[..] else {
                return Err(format!(
                    "the pass log '{name}', line {}: {} fields, not 5 (run,segment,rays,admit,retire)",
                    i + 1,
                    f.len()
                ));
            };
            let run = run as usize;
            if runs.len() <= run {
                runs.resize_with(run + 1, RunPasses::default);
            }
            runs[run].admits.push(admit);
            runs[run].end = runs[run].end.max(retire);
        }
        if runs.is_empty() {
            return Err(format!(
                "the pass log '{name}' holds no segment pass; give the file `render --mode cycle --pass-log` wrote"
            ));
        }
        for r in &mut runs {
            r.admits.sort_unstable();
        }
        self.passes = Some(runs);
        Ok(())
    }
}

/// The modes besides the reference (`--modes`; `sampled` gives two rows).
pub const MODES: [&str; 7] = [
    "cycle-fixed",
    "functional+estimate",
    "small-chip",
    "small-chips-fit",
    "quarter-pixels",
    "sampled",
    "windows",
];

/// Options of the comparison.
#[derive(Clone, Debug)]
pub struct SpeedErrorOpts {
    /// TMs of the `small-chip` mode.
    pub small_tms: u32,
    /// `sampled`: keep one tile in this many (k) per sample.
    pub sample_every: u32,
    /// `sampled`: tile side in pixels.
    pub tile: u32,
    /// `sampled`: disjoint samples (each its own cycle run; 2 or more give the
    /// sampling error).
    pub subsets: u32,
    /// The modes to run besides the reference (`None`: all of [`MODES`]).
    pub modes: Option<Vec<String>>,
    /// Simulator threads of the cycle runs (every mode, the reference too).
    pub threads: Threads,
    /// A finished reference run to compare with instead of rendering one.
    pub reference: Option<Reference>,
    /// `windows`: the time-sampling plan.
    pub windows: render::WindowPlan,
    /// `windows`: write every window's measurement and the functional passes
    /// (JSON) here.
    pub window_log: Option<std::path::PathBuf>,
}

impl Default for SpeedErrorOpts {
    fn default() -> Self {
        SpeedErrorOpts {
            small_tms: 8,
            sample_every: 16,
            tile: 16,
            subsets: 2,
            modes: None,
            threads: Threads::fixed(1),
            reference: None,
            windows: default_windows(),
            window_log: None,
        }
    }
}

/// The default time-sampling plan (chosen at the paper's size, docs/speed-error.md):
/// wavefronts 0, 1, 3 and the last traced in windows, the others borrowing
/// their neighbours' ratios; in each, the root pass over about 64 K rays (32 K
/// after the first wavefront); the first 16 segment passes; then 64
/// admissions measured after 96 of warm-up (one and a half turnovers of the
/// scene buffer's 64 slots) every 1024; the tail from 8 pending queues; four
/// shading windows of 2048 items after 4096 and at least 16384 cycles, after
/// the first 16384, each at a hashed place in its quarter of the pass. A
/// wavefront too short for windows is traced over a sample of about 64 K of
/// its rays on an eighth of the L2; from the fourth on, one alike the last
/// measured (and after another sampled one) borrows the samples of the third
/// wavefront on instead.
pub fn default_windows() -> render::WindowPlan {
    render::WindowPlan {
        head: 16,
        root_rays: 65536,
        bounce_root_rays: 32768,
        wave_rays: 65536,
        wave_l2_share: 8,
        wave_ray_share: 0.15,
        wave_whole: 0,
        warm: 96,
        measure: 64,
        every: 1024,
        shade_windows: 4,
        shade_warm: 4096,
        shade_measure: 2048,
        shade_warm_cycles: 16384,
        shade_head: 16384,
        tail_pending: 8,
        tail_warm: 0,
        wave_every: 2,
    }
}

/// First-order cycles of one segment pass from its functional work: the largest
/// of the bounds `estimate` takes per wavefront. The proxy time sampling scales by.
fn seg_proxy(c: &Config, w: &render::SegWork) -> f64 {
    let line = crate::contract::LINE_BYTES as f64;
    let tms = c.chip.tms as f64;
    let tps = tms * c.tm.tps as f64;
    let k = &c.tm.costs;
    let tp = (k.fetch.cycles + k.init.cycles + k.finish.cycles) as f64 * w.rays as f64
        + k.pop.cycles as f64 * w.pops as f64
        + k.exit.cycles as f64 * w.exits as f64
        + (k.node_fetch.cycles + k.box_issue.cycles + k.node_push.cycles + c.box_pipe.latency)
            as f64
            * w.nodes as f64
        + (k.tri_fetch.cycles + k.tri_issue.cycles + k.tri_result.cycles + c.tri_pipe.latency)
            as f64
            * w.tri_tests as f64;
    [
        (w.scene_lines + w.ray_lines + w.hit_lines) as f64 * line / peak_bytes_per_cycle(c),
        w.ray_lines as f64 / c.chip.scheduler.ray_lines_per_cycle as f64,
        w.scene_lines as f64 / c.chip.scheduler.scene_lines_per_cycle as f64,
        w.nodes as f64 * c.box_pipe.interval as f64 / tms,
        w.tri_tests as f64 * c.tri_pipe.interval as f64 / (tms * c.tm.tri_pipes as f64),
        tp / tps,
    ]
    .into_iter()
    .fold(0.0, f64::max)
}

/// Each of [`window_counts`]' functional proxy for one segment pass: the
/// first-order cycles for the cycles, DRAM energy and the shading actions; the
/// functional model's own lines for each stream; box and triangle tests for the
/// scene-buffer reads (L1 misses); hit-record lines for the L2.
fn seg_proxies(c: &Config, w: &render::SegWork) -> [f64; WCOUNTS] {
    let cyc = seg_proxy(c, w);
    [
        cyc,
        w.ray_lines as f64,
        w.scene_lines as f64,
        w.hit_lines as f64,
        0.0,
        cyc,
        (w.nodes + w.tri_tests) as f64,
        w.hit_lines as f64,
        0.0,
        0.0,
        0.0,
        0.0,
        cyc,
    ]
}

/// What time sampling scales, per window: cycles; lines of the ray, scene, hit and
/// shading streams; DRAM energy (`paper`); scene-buffer reads, L2 array accesses
/// and the four shading actions (for the on-chip energy); DRAM energy
/// (`physical`, scaled as the `paper` one: [`DRAM_J`]).
const WCOUNTS: usize = 13;

/// The counts that are DRAM energy (`paper`, `physical` preset): they go with
/// time as well as lines, so they share the cycles' proxies.
const DRAM_J: [usize; 2] = [5, 12];

/// A window's counts; the writebacks it owes (`WindowRun::dirtied`) are added to
/// their stream's lines and charged `wb_j` each.
fn window_counts(r: &crate::machine::WindowRun, wb_j: [f64; 2]) -> [f64; WCOUNTS] {
    wave_counts(&r.counts, &r.dirtied, wb_j)
}

/// [`window_counts`] of counts `w` owing the writebacks `dirtied`.
fn wave_counts(
    w: &crate::machine::WaveCycles,
    dirtied: &[i64; crate::mem::StreamTag::COUNT],
    wb_j: [f64; 2],
) -> [f64; WCOUNTS] {
    use crate::mem::StreamTag as T;
    let l = |t: T| {
        (w.lines_read[t as usize] + w.lines_written[t as usize]) as f64 + dirtied[t as usize] as f64
    };
    let owed: i64 = dirtied.iter().sum();
    [
        w.cycles as f64,
        l(T::Ray),
        l(T::Scene),
        l(T::Hit),
        l(T::Shading),
        w.dram.energy_paper_j + owed as f64 * wb_j[0],
        w.scene_buffer_reads as f64,
        w.l2.array_accesses() as f64,
        w.shade_uses[0] as f64,
        w.shade_uses[1] as f64,
        w.shade_uses[2] as f64,
        w.shade_uses[3] as f64,
        w.dram.energy_physical_j + owed as f64 * wb_j[1],
    ]
}

/// Where a borrowed root pass of `rays` lies between the root windows of the
/// nearest measured wavefronts before and after it (`before` and `after` rays):
/// the fraction of the way from the one to the other, if it lies between them
/// (no extrapolation) and its rays are alike neither's (within
/// [`render::BORROW_ALIKE`]: a pass alike a window costs what it does per ray,
/// so it takes their ratio, as in the Dragon Box's bounce wavefronts). Its
/// cycles and DRAM energy are then interpolated on the line through the two:
/// measured on the Dragon at 1024x1024 (reference pass log, wavefronts 1 and 5
/// at 767,169 and 6,115 rays), the line puts the roots of wavefronts 2-4 at
/// -4.6%, -11.8% and -11.3% (-0.2% of the frame's cycles), where the ratio of
/// wavefront 1 would put them at -7% to -22%: a smaller root pass costs more
/// per ray, as its start-up and drain weigh more.
pub fn root_between(rays: f64, before: f64, after: f64) -> Option<f64> {
    let (lo, hi) = (before.min(after), before.max(after));
    let alike = |m: f64| (rays - m).abs() <= render::BORROW_ALIKE * m;
    ((lo..=hi).contains(&rays) && !alike(before) && !alike(after))
        .then(|| (rays - before) / (after - before))
}

/// `t += k x`, count by count.
fn add(t: &mut [f64; WCOUNTS], x: &[f64; WCOUNTS], k: f64) {
    for i in 0..WCOUNTS {
        t[i] += x[i] * k;
    }
}

/// A short wavefront's estimate from its [`render::SampleKind::Wave`] window,
/// which traced one run of rays in k of its root queue to the wavefront's end.
/// The visits (rays finished in a segment) it left out cost the cycles and the
/// DRAM energy (which goes with time and rows as well as lines) per visit of
/// its steady stretch: its start-up and drain are the wavefront's once. Its
/// other counts are scaled by the functional work: the wavefront's over that of
/// the visits the window made (each pass's proxy by its share of rays done),
/// but the scene lines by the passes (a pass loads its segment however few
/// rays it has), and the writebacks it owes once (the L2 holds as many at the
/// wavefront's end).
fn wave_window(
    smp: &render::WindowSample,
    segs: &[render::SegWork],
    proxy: &[[f64; WCOUNTS]],
    index: &std::collections::HashMap<u32, usize>,
    wb_j: [f64; 2],
) -> [f64; WCOUNTS] {
    let r = &smp.run;
    let none = [0; crate::mem::StreamTag::COUNT];
    let plain = |w| wave_counts(w, &none, wb_j);
    let mut t = plain(&r.counts);
    add(&mut t, &plain(&r.warm), 1.0);
    add(&mut t, &plain(&r.after), 1.0);
    let owed = wave_counts(&Default::default(), &r.dirtied, wb_j);
    let steady = plain(&r.counts);
    let visits: u64 = r.done.iter().map(|d| d.1).sum();
    let all: u64 = segs.iter().map(|s| s.rays).sum();
    let left = all.saturating_sub(visits) as f64;
    let (mut full, mut did) = ([0.0; WCOUNTS], [0.0; WCOUNTS]);
    for p in proxy {
        add(&mut full, p, 1.0);
    }
    for &(sg, d) in &r.done {
        if let Some(&i) = index.get(&sg)
            && segs[i].rays > 0
        {
            let share = d as f64 / segs[i].rays as f64;
            add(&mut did, &proxy[i], share);
            did[2] += proxy[i][2] * (1.0 - share);
        }
    }
    std::array::from_fn(|i| {
        if i == 0 || DRAM_J.contains(&i) {
            let rate = if r.marks > 0 {
                steady[i] / r.marks as f64
            } else {
                0.0
            };
            t[i] + left * rate + owed[i]
        } else {
            let j = if did[i] > 0.0 { i } else { 0 };
            let k = if did[j] > 0.0 { full[j] / did[j] } else { 1.0 };
            t[i] * k + owed[i]
        }
    })
}

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

/// A wavefront's rest (its passes between head and tail): the passes, their
/// summed proxies, the windows' summed counts and proxies, and each window's.
struct Rest {
    wave: usize,
    passes: std::ops::Range<usize>,
    proxy: [f64; WCOUNTS],
    x: [f64; WCOUNTS],
    px: [f64; WCOUNTS],
    ratios: Vec<([f64; WCOUNTS], [f64; WCOUNTS])>,
}

/// A time-sampled frame's estimate (with its relative standard error of cycles,
/// lines and energy, if known) and the estimate by part of the frame.
struct Windowed {
    breakdown: Vec<WindowPart>,
    estimate: WindowEstimate,
}

/// The time-sampled frame's parts (as [`parts`]) from the functional frame `f`
/// rendered with windows. Per wavefront, the trace is its head (the root window
/// scaled by its rays, then the passes up to `head` simulated as is), its tail
/// (simulated as is) and between them the rest, scaled from the measured windows
/// by the proxy (`seg_proxy`) of the rest over that of the work the windows did
/// (rays finished by segment); each shading pass is its head as is and its
/// windows scaled by the items left over the measured items. Also the relative standard
/// error of the rest's cycles, lines and DRAM energy from the windows' spread
/// (`None` where a wavefront had fewer than two windows).
fn windowed_parts(c: &Config, f: &Frame) -> Result<Windowed, String> {
    let rec = f
        .windows
        .as_ref()
        .ok_or("the functional frame was rendered without windows")?;
    let wb_j = line_write_j(c)?;
    let mut total = [0.0; WCOUNTS];
    // Per measured wavefront, per trace part (root, head, rest, tail, and the
    // whole of one traced over a sample), the measured counts and their
    // proxies, for the wavefronts (or root passes) that borrow them, and pooled
    // for a wavefront too short to hold a window.
    type Pair = ([f64; WCOUNTS], [f64; WCOUNTS]);
    let mut measured: Vec<(usize, [Pair; 5])> = Vec::new();
    let mut pool_part = |k: usize, wave: usize, x: &[f64; WCOUNTS], px: &[f64; WCOUNTS]| {
        if measured.last().is_none_or(|m| m.0 != wave) {
            measured.push((wave, [([0.0; WCOUNTS], [0.0; WCOUNTS]); 5]));
        }
        let m = &mut measured.last_mut().expect("pushed").1[k];
        add(&mut m.0, x, 1.0);
        add(&mut m.1, px, 1.0);
    };
    let mut parts = Vec::new();
    let part = |wave, part, first, end, t: &[f64; WCOUNTS]| WindowPart {
        wave,
        part,
        first,
        end,
        cycles: t[0],
        lines: t[1] + t[2] + t[3] + t[4],
        dram_j: t[5],
        borrowed: false,
    };
    let sum = |r: &[[f64; WCOUNTS]]| {
        let mut t = [0.0; WCOUNTS];
        for x in r {
            add(&mut t, x, 1.0);
        }
        t
    };
    // Per segment pass of each wavefront, each count's functional proxy
    // (`seg_proxies`).
    let proxies: Vec<Vec<[f64; WCOUNTS]>> = rec
        .segs
        .iter()
        .map(|segs| segs.iter().map(|s| seg_proxies(c, s)).collect())
        .collect();
    // A root pass's cost goes with its rays (a root window is scaled by them):
    // its proxy for the cycles and the DRAM energy, where the first-order bound
    // follows the box tests and misjudges the root from one wavefront to the
    // next (Dragon Box 256x256: 1.35-1.43 cycles per ray in every bounce
    // wavefront, the bound's ratio off by up to 20%).
    let root_proxy = |wave: usize| {
        let mut p = proxies[wave][0];
        let rays = rec.segs[wave][0].rays as f64;
        p[0] = rays;
        for j in DRAM_J {
            p[j] = rays;
        }
        p
    };
    let mut per_wave = Vec::new();
    // Short wavefronts traced over a sample, and the whole and sampled
    // figures of those simulated both ways.
    let mut sampled: Vec<(usize, [f64; WCOUNTS])> = Vec::new();
    let (mut whole_sum, mut thin_sum) = ([0.0; WCOUNTS], [0.0; WCOUNTS]);
    let mut borrowers = Vec::new();
    // The wavefronts whose root pass borrows.
    let mut root_borrowers = Vec::new();
    for (wave, segs) in rec.segs.iter().enumerate() {
        if !rec.measured.get(wave).copied().unwrap_or(true) {
            borrowers.push(wave);
            continue;
        }
        let proxy = &proxies[wave];
        let index: std::collections::HashMap<u32, usize> =
            segs.iter().enumerate().map(|(i, s)| (s.seg, i)).collect();
        // A short wavefront traced over a sample from its root pass to its end
        // (`WindowPlan::wave_rays`): the whole wavefront is one part, once the
        // wavefronts also simulated whole (`WindowPlan::wave_whole`) say how
        // far off such samples are.
        let thin = rec
            .samples
            .iter()
            .find(|s| s.wave == wave && s.kind == render::SampleKind::Wave)
            .map(|smp| wave_window(smp, segs, proxy, &index, wb_j));
        let calibrates = thin.is_some()
            && rec
                .samples
                .iter()
                .any(|s| s.wave == wave && s.kind == render::SampleKind::Root);
        if let Some(t) = thin
            && !calibrates
        {
            // Lent whole to those that borrow (`SAMPLE_BORROW_FROM`).
            pool_part(4, wave, &t, &sum(proxy));
            sampled.push((wave, t));
            continue;
        }
        // The head: the root pass (its window on one run of rays in k of the
        // queue, see `WindowPlan::root_rays`), then the window from the next
        // segment on, if any (measured whole).
        let mut head = [0.0; WCOUNTS];
        let mut head_end = 0usize;
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == render::SampleKind::Root)
        {
            // The window ends with the root pass (or before the children, if
            // it sent no ray on); the rest is measured after it.
            head_end = 1;
            let r = &smp.run;
            if r.marks == 0 {
                continue;
            }
            let plain = |w| wave_counts(w, &[0; crate::mem::StreamTag::COUNT], wb_j);
            let mut root = window_counts(r, wb_j);
            add(&mut root, &plain(&r.warm), 1.0);
            add(&mut root, &plain(&r.after), 1.0);
            // The rays it left out: as many cycles and joules each as in its
            // steady stretch (the DRAM's energy goes with time as well as
            // lines, and with the rows the lines fall in); the rest by the
            // rays (its rays are spread over the queue, the stretch's are
            // not), its segment's lines once.
            let left = smp.first as f64;
            let kept = segs.first().map_or(0, |s| s.rays) as f64 - left;
            let k = left / kept.max(1.0);
            let steady = plain(&r.counts);
            let timed =
                [0, DRAM_J[0], DRAM_J[1]].map(|i| root[i] + left * steady[i] / r.marks as f64);
            let scene = root[2];
            for x in root.iter_mut() {
                *x *= 1.0 + k;
            }
            root[2] -= k * scene;
            (root[0], root[DRAM_J[0]], root[DRAM_J[1]]) = (timed[0], timed[1], timed[2]);
            add(&mut head, &root, 1.0);
            if !segs.is_empty() {
                pool_part(0, wave, &root, &root_proxy(wave));
            }
            parts.push(part(wave, "root", 0, 1, &root));
        }
        if head_end == 0 && !segs.is_empty() {
            // No root window here: the root pass is borrowed, the rest is
            // measured after it all the same.
            root_borrowers.push(wave);
            head_end = 1;
        }
        // The tail, measured to the end, as is.
        let mut tail_start = segs.len();
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == render::SampleKind::Tail)
        {
            let t = window_counts(&smp.run, wb_j);
            add(&mut total, &t, 1.0);
            tail_start = (smp.first as usize).clamp(head_end.min(segs.len()), segs.len());
            pool_part(3, wave, &t, &sum(&proxy[tail_start..]));
            parts.push(part(wave, "tail", tail_start as u64, segs.len() as u64, &t));
        }
        let (mut x, mut px) = ([0.0; WCOUNTS], [0.0; WCOUNTS]);
        let mut ratios = Vec::new();
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == render::SampleKind::Trace)
        {
            let a = (smp.first as usize).min(segs.len());
            let b = (a + smp.run.marks as usize).min(segs.len());
            let wc = window_counts(&smp.run, wb_j);
            if a == 1 && head_end == 1 {
                // Right after the root pass, with no warm-up: the head's rest.
                add(&mut head, &wc, 1.0);
                head_end = b;
                pool_part(1, wave, &wc, &sum(&proxy[a..b]));
                parts.push(part(wave, "head", a as u64, b as u64, &wc));
                continue;
            }
            // The work the stretch did: each segment's proxy by the share of
            // its rays finished in it (passes straddle the stretch's ends, and
            // with 64 in flight the admissions alone are bursty); by the
            // admitted passes where the window did not say.
            let p = if smp.run.done.is_empty() {
                sum(&proxy[a..b])
            } else {
                let mut t = [0.0; WCOUNTS];
                for &(sg, d) in &smp.run.done {
                    if let Some(&i) = index.get(&sg)
                        && segs[i].rays > 0
                    {
                        add(&mut t, &proxy[i], d as f64 / segs[i].rays as f64);
                    }
                }
                t
            };
            add(&mut x, &wc, 1.0);
            add(&mut px, &p, 1.0);
            if p[0] > 0.0 {
                ratios.push((wc, p));
            }
        }
        add(&mut total, &head, 1.0);
        if let Some(t) = thin
            && calibrates
        {
            // Simulated whole after its root window: all of it is the head.
            add(&mut whole_sum, &head, 1.0);
            add(&mut thin_sum, &t, 1.0);
        }
        let rest = sum(&proxy[head_end.min(tail_start)..tail_start]);
        per_wave.push(Rest {
            wave,
            passes: head_end.min(tail_start)..tail_start,
            proxy: rest,
            x,
            px,
            ratios,
        });
        pool_part(2, wave, &x, &px);
    }
    // A sampled wavefront's counts by the ratio whole / sample of those
    // simulated both ways (none: as sampled).
    let correct = |t: &[f64; WCOUNTS]| -> [f64; WCOUNTS] {
        std::array::from_fn(|i| {
            if thin_sum[i] > 0.0 {
                t[i] * whole_sum[i] / thin_sum[i]
            } else {
                t[i]
            }
        })
    };
    for (wave, t) in &sampled {
        let c = correct(t);
        add(&mut total, &c, 1.0);
        parts.push(part(*wave, "wave", 0, rec.segs[*wave].len() as u64, &c));
    }
    // Part `k` summed over the measured wavefronts that have it and pass `ok`:
    // the nearest before and after `wave` (`all`: every one).
    // The nearest measured wavefronts before and after `wave` that have part `k`
    // and pass `ok`.
    let neighbours = |k: usize, wave: usize, ok: &dyn Fn(usize) -> bool| {
        let has = |m: &&(usize, [Pair; 5])| m.1[k].1[0] > 0.0 && ok(m.0);
        (
            measured.iter().rev().filter(|m| m.0 < wave).find(has),
            measured.iter().filter(|m| m.0 > wave).find(has),
        )
    };
    let nearest = |k: usize, wave: usize, all: bool, ok: &dyn Fn(usize) -> bool| {
        let picked: Vec<&(usize, [Pair; 5])> = if all {
            measured
                .iter()
                .filter(|m| m.1[k].1[0] > 0.0 && ok(m.0))
                .collect()
        } else {
            let (before, after) = neighbours(k, wave, ok);
            before.into_iter().chain(after).collect()
        };
        let (mut x, mut px) = ([0.0; WCOUNTS], [0.0; WCOUNTS]);
        for m in picked {
            add(&mut x, &m.1[k].0, 1.0);
            add(&mut px, &m.1[k].1, 1.0);
        }
        (px[0] > 0.0).then_some((x, px))
    };
    // Pooled over the frame, for a wavefront too short to hold a window.
    let (pool_x, pool_p) = nearest(2, 0, true, &|_| true).unwrap_or_default();
    // Each count of the rest scaled from windows `x` with proxies `px`: each by
    // its own proxy, the cycles' where the windows saw none of it.
    let scale = |rest: &[f64; WCOUNTS], x: &[f64; WCOUNTS], px: &[f64; WCOUNTS]| {
        std::array::from_fn::<f64, WCOUNTS, _>(|i| {
            let j = if px[i] > 0.0 { i } else { 0 };
            x[i] * rest[j] / px[j]
        })
    };
    // Cycles, lines and DRAM energy of a scaled rest: the lines of the hit
    // records and the shading pass only, as the frame's ray and scene streams
    // are the functional model's counts (below).
    let figs = |t: &[f64; WCOUNTS]| [t[0], t[3] + t[4], t[5]];
    let mut var = [0.0; 3];
    // The spread is the rest windows'; with none (every wavefront simulated
    // whole) there is nothing to spread.
    let mut se_known = per_wave.iter().any(|w| w.proxy[0] > 0.0);
    for w in &per_wave {
        let (rest, x, px) = (&w.proxy, &w.x, &w.px);
        if rest[0] == 0.0 {
            continue;
        }
        let (x, px) = if px[0] > 0.0 {
            (x, px)
        } else {
            (&pool_x, &pool_p)
        };
        if px[0] == 0.0 {
            return Err(
                "time sampling measured no window after the head; lower --window-every".into(),
            );
        }
        let r = scale(rest, x, px);
        add(&mut total, &r, 1.0);
        let (a, b) = (w.passes.start as u64, w.passes.end as u64);
        parts.push(part(w.wave, "rest", a, b, &r));
        // Variance of the rest from the spread of what each window alone would
        // say of it.
        let n = w.ratios.len();
        if n >= 2 {
            let each: Vec<[f64; 3]> = w
                .ratios
                .iter()
                .map(|(w, p)| figs(&scale(rest, w, p)))
                .collect();
            for k in 0..3 {
                let m = each.iter().map(|e| e[k]).sum::<f64>() / n as f64;
                let v = each.iter().map(|e| (e[k] - m).powi(2)).sum::<f64>() / (n - 1) as f64;
                var[k] += v / n as f64;
            }
        } else {
            se_known = false;
        }
    }
    // The wavefronts traced in no window: each part its proxy times the ratio
    // of the nearest measured wavefronts before and after it among those that
    // carry both bounce and shadow rays (neither the first nor the last, if
    // there are such; else any).
    for &wave in &borrowers {
        let middle = |v: usize| v > 0 && v < rec.final_wave;
        let (segs, proxy) = (&rec.segs[wave], &proxies[wave]);
        let n = segs.len();
        // A wavefront too short for a window is one part after its root, as in
        // its measured neighbours.
        let whole = rec.whole.get(wave).copied().unwrap_or(false);
        // One that borrows after a sampled one (`render`'s hook): its whole
        // proxy times the ratio of the nearest sampled wavefronts before and
        // after it from `SAMPLE_BORROW_FROM` on (not the last, if there are
        // others), one part, its root pass in it as in theirs.
        let from = render::SAMPLE_BORROW_FROM;
        if whole && neighbours(4, wave, &|v| v >= from).0.is_some() {
            let (x, px) = nearest(4, wave, false, &|v| v >= from && v < rec.final_wave)
                .or_else(|| nearest(4, wave, false, &|v| v >= from))
                .expect("a sampled wavefront before it");
            let t = correct(&scale(&sum(proxy), &x, &px));
            add(&mut total, &t, 1.0);
            parts.push(WindowPart {
                borrowed: true,
                ..part(wave, "wave", 0, n as u64, &t)
            });
            continue;
        }
        let head_end = if whole {
            n
        } else {
            (rec.head.max(1) as usize).min(n)
        };
        let tail_start =
            (rec.tail_from.get(wave).copied().unwrap_or(n as u64) as usize).clamp(head_end, n);
        if n > 0 {
            root_borrowers.push(wave);
        }
        let ranges = [
            (1, "head", n.min(1)..head_end),
            (2, "rest", head_end..tail_start),
            (3, "tail", tail_start..n),
        ];
        for (k, name, r) in ranges {
            let p = sum(&proxy[r.clone()]);
            if p[0] == 0.0 {
                continue;
            }
            // The measured wavefronts' part, else (never measured: a tail no
            // measured wavefront had, a head of one admission) their rest,
            // else their head (all of a wavefront simulated whole).
            let Some((x, px)) = [k, 2, 1]
                .into_iter()
                .flat_map(|j| [(j, true), (j, false)])
                .find_map(|(j, mid)| {
                    nearest(j, wave, false, if mid { &middle } else { &|_| true })
                })
            else {
                return Err(format!(
                    "time sampling: wavefront {wave} borrows the measured wavefronts' ratios, but none was measured; lower --window-waves"
                ));
            };
            let t = scale(&p, &x, &px);
            add(&mut total, &t, 1.0);
            parts.push(WindowPart {
                borrowed: true,
                ..part(wave, name, r.start as u64, r.end as u64, &t)
            });
        }
    }
    // Borrowed root passes: by the rays, as the nearest root windows before and
    // after (a root pass's cost per ray is about the same in every wavefront
    // after the first whose rays are alike: 1.30-1.39 cycles per ray at the
    // paper's size in the Dragon Box), the first's only if no other has one.
    // Between two root windows whose rays differ (an open scene's wavefronts
    // shrink), the cycles and DRAM energy lie on the line through them: a
    // smaller root pass costs more per ray (its start-up and drain weigh
    // more), see [`root_between`].
    for &wave in &root_borrowers {
        let (x, px) = nearest(0, wave, false, &|v| v > 0)
            .or_else(|| nearest(0, wave, false, &|_| true))
            .ok_or_else(|| {
                format!("time sampling: wavefront {wave} borrows its root pass, but no wavefront took a root window")
            })?;
        let mut t = scale(&root_proxy(wave), &x, &px);
        // Each neighbour's root window: its rays (the proxy's cycles) and counts.
        if let (Some(b), Some(a)) = neighbours(0, wave, &|v| v > 0) {
            let ((bx, bp), (ax, ap)) = (&b.1[0], &a.1[0]);
            let rays = rec.segs[wave][0].rays as f64;
            if let Some(f) = root_between(rays, bp[0], ap[0]) {
                for i in [0, DRAM_J[0], DRAM_J[1]] {
                    t[i] = bx[i] + f * (ax[i] - bx[i]);
                }
            }
        }
        add(&mut total, &t, 1.0);
        parts.push(WindowPart {
            borrowed: true,
            ..part(wave, "root", 0, 1, &t)
        });
    }
    // Shading passes: the head as is, the other items by the windows.
    let passes = rec
        .samples
        .iter()
        .filter(|s| {
            matches!(
                s.kind,
                render::SampleKind::Shade | render::SampleKind::ShadeHead
            )
        })
        .map(|s| s.wave)
        .max();
    for wave in 0..passes.map_or(0, |m| m + 1) {
        // The work of the items from `a` on, `n` of them: their shading lines
        // in the functional pass (a path that was done costs the chip its
        // read, an active one its hit records, triangle and material too: in
        // a later bounce of an open scene most pixels are done, and windows
        // over the sky and over the model differ by far more than their
        // items), else the items.
        let lines = rec.shade_lines.get(wave).filter(|l| !l.is_empty());
        let work = |a: u64, n: u64| -> f64 {
            match lines {
                Some(l) => {
                    let a = (a as usize).min(l.len());
                    let b = a.saturating_add(n as usize).min(l.len());
                    l[a..b].iter().map(|&x| x as f64).sum()
                }
                None => n as f64,
            }
        };
        let mut left = work(0, rec.pixels as u64);
        let mut pass = [0.0; WCOUNTS];
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == render::SampleKind::ShadeHead)
        {
            add(&mut pass, &window_counts(&smp.run, wb_j), 1.0);
            left -= work(smp.first, smp.run.marks);
        }
        let (mut x, mut n) = ([0.0; WCOUNTS], 0.0);
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == render::SampleKind::Shade)
        {
            add(&mut x, &window_counts(&smp.run, wb_j), 1.0);
            n += work(smp.first, smp.run.marks);
        }
        if n > 0.0 && left > 0.0 {
            add(&mut pass, &x, left / n);
        }
        add(&mut total, &pass, 1.0);
        parts.push(part(wave, "shade", 0, 0, &pass));
    }
    // Ray generation: the host emits every primary ray (one per pixel). Its lines
    // go by `render`'s attribution, as in the cycle frame: the root queue's writes
    // nowhere, a hit record reset and a path state written per pixel.
    for smp in rec
        .samples
        .iter()
        .filter(|s| s.kind == render::SampleKind::Emit)
    {
        if smp.run.marks > 0 {
            let k = rec.pixels as f64 / smp.run.marks as f64;
            let mut e = window_counts(&smp.run, wb_j).map(|x| x * k);
            e[1] = 0.0;
            e[3] += rec.pixels as f64;
            e[4] += rec.pixels as f64;
            add(&mut total, &e, 1.0);
            parts.push(part(0, "emit", 0, 0, &e));
        }
    }
    // Wavefront by wavefront, its trace parts in admission order, then its
    // shading pass; the ray generation last.
    parts.sort_by_key(|p| (p.part == "emit", p.wave, p.part == "shade", p.first));
    // The ray and scene streams: the chip moves exactly the functional model's
    // lines (the same buckets written and read, the same segments loaded, in
    // any timing: `tests/chip.rs` checks every wavefront's counts), so they are
    // taken from it rather than estimated. The hit records and the shading
    // pass go through the L2, whose filtering the windows measure.
    total[1] = f.total.ray_lines() as f64;
    total[2] = f.total.scene_lines as f64;
    // On-chip energy: the functional frame's traversal with the estimated global
    // units' activity, as a cycle frame would have it.
    let mut g = f.clone();
    let mut w = crate::machine::WaveCycles {
        scene_buffer_reads: total[6].round() as u64,
        shade_uses: std::array::from_fn(|k| total[8 + k].round() as u64),
        ..Default::default()
    };
    w.l2.accesses = total[7].round() as u64;
    g.chip = Some(render::ChipFrame {
        shading_on_tps: true,
        tms: c.chip.tms,
        tps_per_tm: c.tm.tps,
        waves: vec![w],
        total_cycles: total[0].round() as u64,
        sim_wall_s: 0.0,
        cycles_per_s: 0.0,
        memory_model: "gddr5".into(),
        core_ps: c.clocks.core_ps,
        line_bytes: crate::contract::LINE_BYTES,
        dram: None,
        vcd: None,
        evals_by_module: Vec::new(),
        sim_steps_by_lanes: Vec::new(),
    });
    let e = crate::render::energy::frame_energy(c, &g);
    let p = [
        total[0],
        total[1],
        total[2],
        total[3],
        total[4],
        e.compute_j + e.onchip_j,
        total[5],
    ];
    let f3 = combine(&p);
    let se = se_known.then(|| std::array::from_fn(|k| var[k].sqrt() / f3[k].max(1e-30)));
    Ok(Windowed {
        breakdown: parts,
        estimate: WindowEstimate {
            cycles: total[0],
            ray_lines: total[1],
            scene_lines: total[2],
            hit_lines: total[3],
            shading_lines: total[4],
            dram_paper_j: total[DRAM_J[0]],
            dram_physical_j: total[DRAM_J[1]],
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
    pub chip_s_by_kind: Vec<render::KindTime>,
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
}

/// Renders `scene` with time sampling (`plan`) on `threads` simulator threads
/// (above one: that many windows side by side), with `config`'s chip on GDDR5.
pub fn time_sampled(
    scene: &Scene,
    config: &Config,
    threads: impl Into<Threads>,
    plan: &render::WindowPlan,
) -> Result<TimeSampled, String> {
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
    mut rc: RenderCfg,
    plan: &render::WindowPlan,
) -> Result<TimeSampled, String> {
    plan.validate()?;
    let mut gddr5 = config.clone();
    gddr5.chip.memory.model = MemoryModel::Gddr5;
    rc.windows = Some(plan.clone());
    match rc.chip.as_mut() {
        Some(ch) => ch.config = gddr5.clone(),
        None => rc.chip = render_cfg(&gddr5, None, Threads::fixed(1)).chip,
    }
    let frame = render::render(scene, Mode::Functional, &rc, &mut |_| {})?;
    let w = windowed_parts(&gddr5, &frame)?;
    Ok(TimeSampled {
        frame,
        estimate: w.estimate,
        parts: w.breakdown,
    })
}

/// Runs the reference and the chosen modes on `scene` with `config` (its memory
/// model is set per mode).
pub fn run(scene: &Scene, config: &Config, o: &SpeedErrorOpts) -> Result<Vec<ModeResult>, String> {
    if let Some(m) = &o.modes {
        for x in m {
            if !MODES.contains(&x.as_str()) {
                return Err(format!(
                    "--modes: unknown mode '{x}'; choose from {}",
                    MODES.join(", ")
                ));
            }
        }
    }
    let want = |m: &str| o.modes.as_ref().is_none_or(|v| v.iter().any(|x| x == m));
    if want("windows") {
        // Before the reference, which may take long.
        o.windows.validate()?;
    }
    if (want("small-chip") || want("small-chips-fit"))
        && (o.small_tms == 0 || o.small_tms >= config.chip.tms)
    {
        return Err(format!(
            "--small-tms {} must be between 1 and chip.tms - 1 ({}); choose a smaller chip",
            o.small_tms,
            config.chip.tms.saturating_sub(1)
        ));
    }
    let (w, h) = (scene.settings.width, scene.settings.height);
    let mut samples = Vec::new();
    if want("sampled") {
        if o.sample_every == 0 {
            return Err("--sample-every 0 keeps nothing; give 1 (every tile) or more".into());
        }
        if o.subsets == 0 || o.subsets > o.sample_every {
            return Err(format!(
                "--subsets {} must be between 1 and --sample-every ({}): the samples are disjoint",
                o.subsets, o.sample_every
            ));
        }
        for s in 0..o.subsets {
            samples.push(tile_sample(
                w,
                h,
                o.tile,
                o.sample_every,
                s * o.sample_every / o.subsets,
            )?);
        }
    }
    let t = o.threads;
    let mut gddr5 = config.clone();
    gddr5.chip.memory.model = MemoryModel::Gddr5;
    // The reference: rendered here, or read back from a finished run.
    let (rendered, r) = match &o.reference {
        Some(r) => (None, r.clone()),
        None => {
            // With its pass log, for the windows mode's check by part.
            let mut rc = render_cfg(&gddr5, None, t);
            rc.pass_log = true;
            let f = render::render(scene, Mode::Cycle, &rc, &mut |_| {})?;
            let cycles = f.chip.as_ref().map_or(0, |c| c.total_cycles) as f64;
            let r = Reference {
                cycles,
                lines: f.total.total_lines() as f64,
                energy_j: total_energy(&gddr5, &f, cycles)?,
                wall_s: f.wall_s,
                rays: f.total.rays,
                rgb8: None,
                shade_cycles: f
                    .chip
                    .as_ref()
                    .map(|c| c.waves.iter().map(|w| w.shade_cycles).collect())
                    .unwrap_or_default(),
                passes: Some(RunPasses::of_frame(&f)),
            };
            (Some(f), r)
        }
    };
    let (ref_cycles, ref_lines, ref_energy) = (r.cycles, r.lines, r.energy_j);
    // Whether a mode's image equals the reference's on the pixels it renders: bit for
    // bit against a rendered reference, as 8-bit sRGB against a reference's PNG,
    // unknown without either.
    let same_image = |f: &Frame, pixels: Option<&[u32]>| -> Option<bool> {
        let all: Vec<u32>;
        let pix = match pixels {
            Some(p) => p,
            None => {
                all = (0..f.radiance.len() as u32).collect();
                &all
            }
        };
        if let Some(rf) = &rendered {
            Some(
                pix.iter()
                    .all(|&p| f.radiance[p as usize] == rf.radiance[p as usize]),
            )
        } else {
            r.rgb8.as_ref().map(|png| {
                pix.iter().all(|&p| {
                    let i = 3 * p as usize;
                    render::output::rgb8(f.radiance[p as usize])[..] == png[i..i + 3]
                })
            })
        }
    };
    // A mode that traces the whole frame traces exactly the reference's rays; if not,
    // the reference is another frame (seed, bounces, scene file) and no error means
    // anything.
    let same_rays = |f: &Frame| -> Result<(), String> {
        if f.total.rays != r.rays {
            return Err(format!(
                "this frame traces {} rays, the reference {}: the reference was rendered with another scene, seed, bounce count or config; re-render it with this one",
                f.total.rays, r.rays
            ));
        }
        Ok(())
    };
    let mut out = Vec::new();
    let mut push = |mode: &str,
                    wall: f64,
                    [cycles, lines, energy]: [f64; 3],
                    same: Option<bool>,
                    est_err: Option<[f64; 3]>,
                    note: &str| {
        out.push(ModeResult {
            mode: mode.into(),
            wall_s: wall,
            speedup: r.wall_s / wall.max(1e-9),
            cycles,
            lines,
            energy_j: energy,
            err_cycles: rel(cycles, ref_cycles),
            err_lines: rel(lines, ref_lines),
            err_energy: rel(energy, ref_energy),
            image_identical: same,
            est_err,
            note: note.into(),
            by_part: Vec::new(),
        })
    };
    push(
        "cycle",
        r.wall_s,
        [ref_cycles, ref_lines, ref_energy],
        Some(true),
        None,
        if rendered.is_some() {
            "reference: the chip with GDDR5"
        } else {
            "reference: the chip with GDDR5, read from --reference"
        },
    );
    let cycles_of = |f: &Frame| f.chip.as_ref().map_or(0, |c| c.total_cycles) as f64;

    if want("cycle-fixed") {
        let mut fixed = config.clone();
        fixed.chip.memory.model = MemoryModel::Fixed;
        let f = render_pixels(scene, Mode::Cycle, &fixed, None, t)?;
        same_rays(&f)?;
        let cyc = cycles_of(&f);
        push(
            "cycle-fixed",
            f.wall_s,
            figures(&fixed, &f, cyc)?,
            same_image(&f, None),
            None,
            "fixed-latency memory; DRAM energy estimated from lines",
        );
    }

    // The functional frame and its estimate (also the sampled modes' auxiliary).
    let mut functional = None;
    if want("functional+estimate") || want("sampled") {
        let f = render_pixels(scene, Mode::Functional, config, None, t)?;
        same_rays(&f)?;
        let est = estimate(&gddr5, &f).cycles;
        let full_parts = parts(&gddr5, &f, est)?;
        let fig = combine(&full_parts);
        if want("functional+estimate") {
            push(
                "functional+estimate",
                f.wall_s,
                fig,
                same_image(&f, None),
                None,
                "no clock; cycles = per-wave max of resource bounds",
            );
        }
        functional = Some((f.wall_s, full_parts));
    }

    let mut fit = None;
    if want("small-chip") || want("small-chips-fit") {
        let mut small = gddr5.clone();
        small.chip.tms = o.small_tms;
        let f = render_pixels(scene, Mode::Cycle, &small, None, t)?;
        same_rays(&f)?;
        let scale = o.small_tms as f64 / config.chip.tms as f64;
        let c1 = cycles_of(&f);
        if want("small-chip") {
            let cyc = c1 * scale;
            push(
                "small-chip",
                f.wall_s,
                figures(&small, &f, cyc)?,
                same_image(&f, None),
                None,
                &format!("{} TMs, cycles x {scale}", o.small_tms),
            );
        }
        // Two small chips, s and 2s TMs, fit cycles = a + b / TMs (a serial part and
        // a part that divides over the TMs), evaluated at the full TM count.
        let (s1, s2) = (o.small_tms, 2 * o.small_tms);
        if want("small-chips-fit") && s2 < config.chip.tms {
            let mut small2 = gddr5.clone();
            small2.chip.tms = s2;
            let f2 = render_pixels(scene, Mode::Cycle, &small2, None, t)?;
            let c2 = cycles_of(&f2);
            let b = (c1 - c2) / (1.0 / s1 as f64 - 1.0 / s2 as f64);
            let a = c2 - b / s2 as f64;
            let cyc = (a + b / config.chip.tms as f64).max(0.0);
            fit = Some((
                f.wall_s + f2.wall_s,
                figures(&small2, &f2, cyc)?,
                same_image(&f2, None),
                format!("{s1} and {s2} TMs ({c1:.0}, {c2:.0} cycles), a + b/TMs"),
            ));
        }
    }
    if let Some((wall, fig, same, note)) = fit {
        push("small-chips-fit", wall, fig, same, None, &note);
    }

    if want("quarter-pixels") {
        let mut quarter = scene.clone();
        quarter.settings.width = (w / 2).max(1);
        quarter.settings.height = (h / 2).max(1);
        let ratio = (w * h) as f64 / (quarter.settings.width * quarter.settings.height) as f64;
        let f = render_pixels(&quarter, Mode::Cycle, &gddr5, None, t)?;
        let cyc = cycles_of(&f);
        push(
            "quarter-pixels",
            f.wall_s,
            [
                cyc * ratio,
                f.total.total_lines() as f64 * ratio,
                total_energy(&gddr5, &f, cyc)? * ratio,
            ],
            None,
            None,
            &format!(
                "{}x{} frame, everything x {ratio}",
                quarter.settings.width, quarter.settings.height
            ),
        );
    }

    if let Some((func_wall, full_parts)) = functional.filter(|_| want("sampled")) {
        // Per sample: the cycle model's figures, and per part (cycles, each stream's
        // lines, energy) their ratio to the functional model's on the same pixels,
        // applied to the functional whole frame's part. By part, because the parts
        // scale differently with the pixels: the scene stream not at all, while the
        // L2 filters only hit-record and shading lines, so one ratio of the totals
        // carries a small frame's mix of streams into the whole frame's.
        let mut wall = func_wall;
        let (mut ratio, mut scaled) = (Vec::new(), Vec::new());
        let mut same = Some(true);
        for pix in &samples {
            let frac = pix.len() as f64 / (w * h) as f64;
            let fc = render_pixels(scene, Mode::Cycle, &gddr5, Some(pix.clone()), t)?;
            let ff = render_pixels(scene, Mode::Functional, config, Some(pix.clone()), t)?;
            wall += fc.wall_s + ff.wall_s;
            same = match (same, same_image(&fc, Some(pix))) {
                (Some(a), Some(b)) => Some(a && b),
                _ => None,
            };
            let cyc = cycles_of(&fc);
            let pc = parts(&gddr5, &fc, cyc)?;
            let est = estimate(&gddr5, &ff).cycles;
            let pf = parts(&gddr5, &ff, est)?;
            // A part the functional sample lacks contributes the whole frame's own.
            let by_part: [f64; 7] = std::array::from_fn(|i| {
                let r = if pf[i] > 0.0 { pc[i] / pf[i] } else { 1.0 };
                full_parts[i] * r
            });
            ratio.push(combine(&by_part));
            scaled.push(combine(&pc).map(|x| x / frac));
        }
        let m = samples.len();
        let note = format!(
            "{m} sample(s) of one {0}x{0} tile in {1} ({2:.1}% of the pixels each)",
            o.tile,
            o.sample_every,
            100.0 * samples[0].len() as f64 / (w * h) as f64
        );
        let r = mean_se(&ratio);
        push(
            "sampled",
            wall,
            r.0,
            same,
            r.1,
            &format!("{note}; functional frame x cycle/functional of the samples, by part"),
        );
        let sc = mean_se(&scaled);
        push(
            "sampled-scaled",
            wall - func_wall,
            sc.0,
            same,
            sc.1,
            &format!("{note}; x the pixel ratio"),
        );
    }
    if want("windows") {
        let TimeSampled {
            frame: f,
            estimate: est,
            parts,
        } = time_sampled(scene, &gddr5, t, &o.windows)?;
        same_rays(&f)?;
        let rec = f.windows.as_ref().expect("rendered with windows");
        let checks = check_parts(&parts, &r);
        if let Some(path) = &o.window_log {
            #[derive(Serialize)]
            struct Log<'a> {
                parts: &'a [WindowPart],
                checks: &'a [PartCheck],
                record: &'a render::WindowRecord,
            }
            let log = Log {
                parts: &parts,
                checks: &checks,
                record: rec,
            };
            let text = serde_json::to_string(&log).expect("window log serialises");
            std::fs::write(path, text).map_err(|e| {
                format!(
                    "cannot write the window log '{}': {e}; choose a writable --window-log",
                    path.display()
                )
            })?;
        }
        let wp = &o.windows;
        push(
            "windows",
            f.wall_s,
            [
                est.cycles,
                est.lines(),
                est.dram_paper_j + est.onchip_j + est.compute_j,
            ],
            same_image(&f, None),
            est.rel_se,
            &format!(
                "time sampling: {} windows ({:.0} s in the chips, summed over {} at a time); {}{}{}: the first {} segment passes, then {} measured after {} of warm-up every {}; {} shading windows of {} items after {} and {} cycles",
                rec.samples.len(),
                rec.chip_s,
                o.threads.n,
                match rec
                    .samples
                    .iter()
                    .filter(|s| s.kind == render::SampleKind::Wave)
                    .count()
                {
                    0 => String::new(),
                    n => format!(
                        "{n} short wavefronts traced over a sample of about {} rays on 1/{} of the L2, ",
                        wp.wave_rays, wp.wave_l2_share
                    ),
                },
                // Too short for windows and not sampled (few rays, or a
                // sample that would stream more scene than rays).
                match (0..rec.whole.len())
                    .filter(|&w| {
                        rec.whole[w]
                            && rec.measured.get(w).copied().unwrap_or(true)
                            && !rec
                                .samples
                                .iter()
                                .any(|s| s.wave == w && s.kind == render::SampleKind::Wave)
                    })
                    .count()
                {
                    0 => String::new(),
                    n => format!("{n} short wavefronts simulated whole after their root window, "),
                },
                match rec.measured.iter().filter(|m| !**m).count() {
                    0 => "per wavefront".to_string(),
                    n => format!(
                        "{n} of {} wavefronts borrowed from their neighbours, in the others",
                        rec.measured.len()
                    ),
                },
                wp.head,
                wp.measure,
                wp.warm,
                wp.every,
                wp.shade_windows,
                wp.shade_measure,
                wp.shade_warm,
                wp.shade_warm_cycles
            ),
        );
        if let Some(row) = out.last_mut() {
            row.by_part = checks;
        }
    }
    Ok(out)
}

/// A frame's figures by part, for the ratio estimator: cycles (given: simulated or
/// estimated); DRAM lines of the ray stream, the scene stream, the hit records and
/// the shading pass; compute + on-chip energy; DRAM energy.
fn parts(c: &Config, f: &Frame, cycles: f64) -> Result<[f64; 7], String> {
    let t = &f.total;
    let e = crate::render::energy::frame_energy(c, f);
    let dram = match f.chip.as_ref().and_then(|ch| ch.dram) {
        Some(d) => d.energy_paper_j,
        None => dram_energy_estimate(c, f, cycles)?,
    };
    Ok([
        cycles,
        t.ray_lines() as f64,
        t.scene_lines as f64,
        t.hit_lines() as f64,
        t.shading_lines as f64,
        e.compute_j + e.onchip_j,
        dram,
    ])
}

/// Cycles, DRAM lines and energy from [`parts`].
fn combine(p: &[f64; 7]) -> [f64; 3] {
    [p[0], p[1] + p[2] + p[3] + p[4], p[5] + p[6]]
}

/// A frame's cycles (given: simulated or estimated), DRAM lines and energy.
fn figures(c: &Config, f: &Frame, cycles: f64) -> Result<[f64; 3], String> {
    Ok(combine(&parts(c, f, cycles)?))
}

/// Mean of each component over the samples and its relative standard error
/// (`None` with fewer than two samples).
fn mean_se(v: &[[f64; 3]]) -> ([f64; 3], Option<[f64; 3]>) {
    let n = v.len() as f64;
    let mean = [0, 1, 2].map(|i| v.iter().map(|x| x[i]).sum::<f64>() / n);
    if v.len() < 2 {
        return (mean, None);
    }
    let se = [0, 1, 2].map(|i| {
        let var = v.iter().map(|x| (x[i] - mean[i]).powi(2)).sum::<f64>() / (n - 1.0);
        if mean[i] == 0.0 {
            0.0
        } else {
            (var / n).sqrt() / mean[i].abs()
        }
    });
    (mean, Some(se))
}

/// The comparison as a text table.
pub fn table(rows: &[ModeResult]) -> String {
    let mut s = format!(
        "{:<20} {:>9} {:>8} {:>13} {:>9} {:>9} {:>9}  {:<20}  {:<6} note\n",
        "mode",
        "wall (s)",
        "speedup",
        "cycles",
        "err cyc",
        "err lines",
        "err J",
        "own estimate (1 SE)",
        "image"
    );
    for r in rows {
        let own = r.est_err.map_or("-".to_string(), |e| {
            format!(
                "±{:.1}/{:.1}/{:.1}%",
                e[0] * 100.0,
                e[1] * 100.0,
                e[2] * 100.0
            )
        });
        let _ = writeln!(
            s,
            "{:<20} {:>9.2} {:>7.1}x {:>13.0} {:>+8.1}% {:>+8.1}% {:>+8.1}%  {:<20}  {:<6} {}",
            r.mode,
            r.wall_s,
            r.speedup,
            r.cycles,
            r.err_cycles * 100.0,
            r.err_lines * 100.0,
            r.err_energy * 100.0,
            own,
            match r.image_identical {
                Some(true) => "same",
                Some(false) => "DIFF",
                None => "-",
            },
            r.note
        );
    }
    s
}

/// Speedup (log scale) against the absolute error in cycles, one point per mode.
pub fn plot(rows: &[ModeResult]) -> String {
    let (w, h, left, bottom, top, right) = (640.0, 400.0, 70.0, 50.0, 40.0, 160.0);
    let max_err = rows
        .iter()
        .map(|r| r.err_cycles.abs() * 100.0)
        .fold(1.0f64, f64::max);
    let max_sp = rows.iter().map(|r| r.speedup).fold(10.0f64, f64::max);
    let lmax = max_sp.log10().ceil().max(1.0);
    let (pw, ph) = (w - left - right, h - top - bottom);
    let x = |sp: f64| left + sp.max(1e-3).log10().clamp(-1.0, lmax) / lmax * pw;
    let y = |e: f64| top + ph - e / max_err * ph;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{}" y="22" text-anchor="middle" font-size="15">Speed against error (cycles)</text>"#,
        left + pw / 2.0
    );
    let _ = writeln!(
        s,
        r#"<line x1="{left}" y1="{}" x2="{}" y2="{}" stroke="black"/><line x1="{left}" y1="{top}" x2="{left}" y2="{}" stroke="black"/>"#,
        top + ph,
        left + pw,
        top + ph,
        top + ph
    );
    for d in 0..=lmax as i32 {
        let sp = 10f64.powi(d);
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{sp}x</text>"#,
            x(sp),
            top + ph + 18.0
        );
    }
    let _ = writeln!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">speedup over cycle mode (log)</text>"#,
        left + pw / 2.0,
        h - 10.0
    );
    for i in 0..=4 {
        let e = max_err * i as f64 / 4.0;
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="end">{e:.1}%</text>"#,
            left - 6.0,
            y(e) + 4.0
        );
    }
    for r in rows {
        let (px, py) = (x(r.speedup), y(r.err_cycles.abs() * 100.0));
        let _ = writeln!(
            s,
            r##"<circle cx="{px:.1}" cy="{py:.1}" r="5" fill="#4477aa"/><text x="{:.1}" y="{:.1}">{}</text>"##,
            px + 8.0,
            py + 4.0,
            r.mode
        );
    }
    s += "</svg>\n";
    s
}
