//! What a render gives the user: the PNG, the Table-2-style summary, the JSON.

use super::header::{Headed, RunHeader};
use std::path::Path;

use super::{Frame, RenderError};
use crate::util::FileError;

/// Display transform: clamp to [0, 1] and encode with the sRGB curve.
fn encode(x: f32) -> u8 {
    let x = if x.is_finite() {
        x.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// A pixel's radiance as the PNG stores it (8-bit sRGB).
pub fn rgb8(c: glam::Vec3) -> [u8; 3] {
    [encode(c.x), encode(c.y), encode(c.z)]
}

pub fn write_png(frame: &Frame, path: &Path) -> Result<(), RenderError> {
    let mut buf = Vec::with_capacity(frame.radiance.len() * 3);
    for c in &frame.radiance {
        buf.extend_from_slice(&rgb8(*c));
    }
    image::save_buffer(
        path,
        &buf,
        frame.width,
        frame.height,
        image::ColorType::Rgb8,
    )
    .map_err(|source| RenderError::Png {
        path: path.to_path_buf(),
        source,
    })
}

/// The frame's linear radiance as a PFM (Portable Float Map: `PF`, width
/// and height, `-1` for little-endian, then 32-bit floats RGB, the bottom
/// row first): unclamped and unencoded, for comparing with another
/// renderer's output numerically (ImageMagick, OpenImageIO, pbrt's `imgtool`
/// and Mitsuba read it).
pub fn write_pfm(frame: &Frame, path: &Path) -> Result<(), RenderError> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut buf = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
    buf.reserve(w * h * 12);
    for y in (0..h).rev() {
        for c in &frame.radiance[y * w..(y + 1) * w] {
            for x in [c.x, c.y, c.z] {
                buf.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    std::fs::write(path, buf).map_err(|e| {
        let msg = format!(
            "cannot write the HDR image '{}': {e}; choose a writable --hdr",
            path.display()
        );
        RenderError::File(FileError::new(path, e, msg))
    })
}

/// The segment passes of a cycle-mode frame (`RenderCfg::pass_log`) as CSV, one
/// row per pass in retirement order: the chip run (run k > 0 shades wavefront
/// k - 1, then traces wavefront k), the segment, its rays, and the core cycles
/// it was admitted (took a scene-buffer slot) and retired.
pub fn write_pass_log(frame: &Frame, path: &Path) -> Result<(), RenderError> {
    use std::fmt::Write;
    let mut s = String::from("run,segment,rays,admit,retire\n");
    for (run, passes) in frame.passes.iter().enumerate() {
        for p in passes {
            let _ = writeln!(s, "{run},{},{},{},{}", p.seg, p.rays, p.admit, p.retire);
        }
    }
    std::fs::write(path, s).map_err(|e| {
        let msg = format!(
            "cannot write the pass log '{}': {e}; choose a writable --pass-log",
            path.display()
        );
        RenderError::File(FileError::new(path, e, msg))
    })
}

/// The frame's statistics as JSON (`--stats`), after `header` if given, to
/// `path` or (`None`) stdout.
pub fn write_json(
    frame: &Frame,
    header: Option<&RunHeader>,
    path: Option<&Path>,
) -> Result<(), RenderError> {
    write_stats(frame, header, path)
}

/// Writes `stats` as pretty JSON to `path` (`--stats`; `None`: stdout), with
/// `header` as its first key.
pub fn write_stats(
    stats: &impl serde::Serialize,
    header: Option<&RunHeader>,
    path: Option<&Path>,
) -> Result<(), RenderError> {
    let text = match header {
        Some(header) => serde_json::to_string_pretty(&Headed {
            header,
            body: stats,
        }),
        None => serde_json::to_string_pretty(stats),
    }
    .expect("stats serialise");
    let Some(path) = path else {
        println!("{text}");
        return Ok(());
    };
    std::fs::write(path, text).map_err(|e| {
        let msg = format!(
            "cannot write the statistics '{}': {e}; choose a writable --stats",
            path.display()
        );
        RenderError::File(FileError::new(path, e, msg))
    })
}

fn m(x: u64) -> String {
    format!("{:.3}", x as f64 / 1e6)
}

/// The paper's Table 2 rows that functional mode can give (no time or energy yet).
pub fn summary(f: &Frame) -> String {
    let t = &f.total;
    let mut s = String::new();
    s += &format!(
        "scene {} ({} triangles), {}x{}, mode {:?}\n",
        f.scene, f.accel.triangles, f.width, f.height, f.mode
    );
    s += &format!(
        "  BVH: {} nodes, depth {}, built in {:.2} s; {} segments ({:.1} KB mean), children per segment min/mean/max {}/{:.1}/{}\n",
        f.accel.bvh_nodes,
        f.accel.bvh_depth,
        f.accel.bvh_build_s,
        f.accel.segments,
        f.accel.segment_bytes_mean / 1024.0,
        f.accel.children_min,
        f.accel.children_mean,
        f.accel.children_max
    );
    s += &format!("  wavefronts {}\n", f.waves.len());
    if f.spp > 1 {
        s += &format!(
            "  paths per pixel {} (rays and every count below are of all {} paths)\n",
            f.spp,
            f.width as u64 * f.height as u64 * f.spp as u64
        );
    }
    s += &format!("  {:<34} {:>12}\n", "rays traced (M)", m(t.rays));
    s += &format!(
        "  {:<34} {:>12}\n",
        "  of which shadow rays (M)",
        m(t.shadow_rays)
    );
    s += &format!("  {:<34} {:>12.2}\n", "ray duplication", f.duplication);
    s += &format!(
        "  {:<34} {:>12}   ($: {}-byte cache lines between the chip and DRAM)\n",
        "$ lines transferred (M)",
        m(t.total_lines()),
        crate::contract::LINE_BYTES
    );
    s += &format!(
        "  {:<34} {:>12}\n",
        "  ray stream $ lines (M)",
        m(t.ray_lines())
    );
    s += &format!(
        "  {:<34} {:>12}\n",
        "  scene stream $ lines (M)",
        m(t.scene_lines)
    );
    s += &format!(
        "  {:<34} {:>12}\n",
        "  shading $ lines (M)",
        m(t.shading_lines)
    );
    s += &format!(
        "  {:<34} {:>12}\n",
        "  hit record $ lines (M)",
        m(t.hit_lines())
    );
    s += &format!("  {:<34} {:>12.1}\n", "DRAM bytes per ray", f.bytes_per_ray);
    s += &format!("  {:<34} {:>12}\n", "segments loaded", t.segments_loaded);
    s += &format!(
        "  {:<34} {:>12}\n",
        "box tests (M)",
        m(t.traversal.box_tests)
    );
    s += &format!(
        "  {:<34} {:>12}\n",
        "triangle tests (M)",
        m(t.traversal.tri_tests)
    );
    s += &format!(
        "  {:<34} {:>12}\n",
        "max traversal stack (entries)", t.traversal.max_stack
    );
    if f.early_termination != crate::config::EarlyTermination::None {
        s += &early_summary(f);
    }
    s += &format!(
        "  wall {:.2} s (tracing {:.2} s), DRAM image {:.1} MB resident\n",
        f.wall_s, f.trace_s, f.dram_resident_mb
    );
    if let Some(e) = &f.energy {
        s += &energy_summary(f, e);
    }
    if f.verified_rays > 0 {
        s += &format!(
            "  verified: all {} rays agree with the reference traversal\n",
            f.verified_rays
        );
    }
    if let Some(c) = &f.chip {
        s += &chip_summary(c);
        s += &frame_headline(f, c);
    }
    s
}

/// The early-termination rows of [`summary`]: what the tests read and stopped,
/// and each stream's lines with the tests and without them.
fn early_summary(f: &Frame) -> String {
    let (t, e) = (&f.total, &f.total.early);
    let mut s = format!(
        "  {:<34} {:>12}\n",
        "early termination", f.early_termination
    );
    for (name, v) in [
        ("  hit records read", e.records_read.to_string()),
        ("  rays dropped, pre-test", e.rays_dropped.to_string()),
        (
            "  enqueues avoided, post-test",
            e.enqueues_avoided.to_string(),
        ),
        (
            "  box tests avoided, net",
            (e.box_tests_avoided as i64 - e.pre_box_tests as i64).to_string(),
        ),
        ("  triangle tests avoided", e.tri_tests_avoided.to_string()),
        ("  segment loads avoided", e.segments_removed.to_string()),
    ] {
        s += &format!("  {name:<34} {v:>12}\n");
    }
    s += &format!(
        "  {:<34} {:>12} {:>12}\n",
        "  $ lines (M), with / without:", "with", "without"
    );
    let hit_without = t.hit_lines() + e.hit_lines_removed - e.records_read - e.hit_lines_added;
    for (name, with, without) in [
        (
            "ray stream",
            t.ray_lines(),
            t.ray_lines() + e.ray_lines_removed,
        ),
        (
            "scene stream",
            t.scene_lines,
            t.scene_lines + e.scene_lines_removed,
        ),
        ("hit record", t.hit_lines(), hit_without),
    ] {
        s += &format!(
            "  {:<34} {:>12} {:>12}\n",
            format!("    {name}"),
            m(with),
            m(without)
        );
    }
    s
}

/// The chip frame's figures in the paper's terms, last so they are what a
/// user reads first: time at the core clock, rays per second, DRAM bandwidth
/// and energy.
fn frame_headline(f: &Frame, c: &super::ChipFrame) -> String {
    let secs = c.total_cycles as f64 * c.core_ps as f64 * 1e-12;
    let mut s = format!(
        "frame: {:.3} ms ({} cycles at {:.2} GHz), {:.1} M rays/s",
        secs * 1e3,
        c.total_cycles,
        1e3 / c.core_ps as f64,
        if secs > 0.0 {
            f.total.rays as f64 / secs / 1e6
        } else {
            0.0
        }
    );
    if let (Some(bw), Some(d)) = (c.dram_bandwidth_gbs(), &c.dram) {
        s += &format!(
            ", DRAM {bw:.1} GB/s, {} (paper preset)",
            crate::mem::stats::joules(d.energy_paper_j)
        );
    }
    s.push('\n');
    s
}

/// The energy rows of [`summary`]: the TMs' compute and on-chip energy, by part.
fn energy_summary(f: &Frame, e: &crate::energy::Energy) -> String {
    let mut s = String::new();
    s += &format!(
        "  {:<34} {:>12.4}\n",
        "compute energy, TMs (J)", e.compute_j
    );
    s += &format!(
        "  {:<34} {:>12.4}\n",
        "on-chip memory energy, TMs (J)", e.onchip_j
    );
    for (k, j) in &e.parts {
        s += &format!("    {:<32} {:>12.4}\n", k, j);
    }
    if let Some(l) = e.leakage_j {
        s += &format!("  {:<34} {:>12.4}\n", "SRAM leakage (J, not in totals)", l);
    }
    if f.chip.as_ref().is_some_and(|c| c.dram.is_some()) {
        s += "  (DRAM energy: the gddr5 figures below; L2 and scene buffer counted in cycle mode only)\n";
    } else {
        s += "  (DRAM energy needs the DRAM model: --mode cycle (GDDR5 unless --memory fixed), or --mode windows (estimated, minutes at 1024x1024); the L2 and the scene buffer are counted there only)\n";
    }
    s
}

/// The chip's rows of [`summary`] (cycle mode): each run, then the frame's totals.
fn chip_summary(c: &super::ChipFrame) -> String {
    let mut s = String::new();
    s += &format!(
        "  chip {} TMs x {} TPs ({})\n",
        c.tms,
        c.tps_per_tm,
        if c.shading_on_tps {
            "shading on the TPs: every run after the first shades the previous wavefront, then traces"
        } else {
            "shading on the host between wavefronts, untimed"
        }
    );
    for (k, w) in c.waves.iter().enumerate() {
        s += &run_summary(c, k, w);
    }
    s += &format!("  {:<34} {:>12}\n", "total cycles", c.total_cycles);
    s += &format!("  {:<34} {:>12}\n", "memory timing model", c.memory_model);
    let mut l2 = crate::machine::L2Wave::default();
    c.waves.iter().for_each(|w| l2.add(&w.l2));
    if l2.accesses > 0 {
        s += &format!(
            "  {:<34} {:>12}\n  {:<34} {:>12.1}\n  {:<34} {:>12}\n",
            "L2 accesses",
            l2.accesses,
            "L2 hit rate (%)",
            100.0 * l2.hit_rate(),
            "L2 fills / writebacks",
            format!("{} / {}", l2.fills, l2.writebacks)
        );
    }
    let lines: u64 = c
        .waves
        .iter()
        .map(|w| w.lines_read.iter().sum::<u64>() + w.lines_written.iter().sum::<u64>())
        .sum();
    let secs = c.total_cycles as f64 * c.core_ps as f64 * 1e-12;
    s += &format!(
        "  {:<34} {:>12.1}\n",
        "memory unit bandwidth (GB/s)",
        if secs > 0.0 {
            (lines * c.line_bytes) as f64 / secs / 1e9
        } else {
            0.0
        }
    );
    if let Some(d) = &c.dram {
        s += &format!(
            "  {:<34} {:>12}\n  {:<34} {:>12.1}\n  {:<34} {:>11.1}%\n  {:<34} {:>12}\n  {:<34} {:>12}\n",
            "DRAM lines (read + written)",
            d.lines(),
            "DRAM bandwidth (GB/s)",
            c.dram_bandwidth_gbs().unwrap_or(0.0),
            "DRAM row-hit rate",
            100.0 * d.row_hit_rate(),
            "DRAM energy, paper preset",
            crate::mem::stats::joules(d.energy_paper_j),
            "DRAM energy, physical preset",
            crate::mem::stats::joules(d.energy_physical_j)
        );
    }
    s += &format!(
        "  chip simulation {:.2} s, {:.0} simulated cycles/s{}\n",
        c.sim_wall_s,
        c.cycles_per_s,
        lanes_note(&c.sim_steps_by_lanes)
    );
    let evals: u64 = c.evals_by_module.iter().map(|e| e.evals).sum();
    if evals > 0 {
        let top: Vec<String> = c
            .evals_by_module
            .iter()
            .take(6)
            .map(|e| format!("{} {:.0}%", e.module, 100.0 * e.evals as f64 / evals as f64))
            .collect();
        s += &format!(
            "  unit evaluations {:.1} M, {:.1} per cycle: {}\n",
            evals as f64 / 1e6,
            evals as f64 / c.total_cycles.max(1) as f64,
            top.join(", ")
        );
    }
    s
}

/// Chip run `k` of [`chip_summary`]: its cycles and counts, L2, TMs and DRAM.
fn run_summary(c: &super::ChipFrame, k: usize, w: &crate::machine::WaveCycles) -> String {
    let mut s = String::new();
    s += &format!(
        "    run {k}: {:>10} cycles (shading {:>8}, drain {:>5})  {:>8} rays  {:>8} duplicates  {:>5} segments  scene-buffer stalls {} ({} cycles)  hit updates merged {}\n",
        w.cycles,
        w.shade_cycles,
        w.drain_cycles,
        w.rays_emitted,
        w.duplicates,
        w.segments_loaded,
        w.scene_buffer_stalls,
        w.scene_buffer_stall_cycles,
        w.hit_merged
    );
    if w.l2.accesses > 0 {
        s += &format!(
            "      L2: {:>8} accesses ({} combined)  hits {:>5.1}%  {} misses ({} merged)  {} bank-conflict stalls  {} fills  {} writebacks  flush {} cycles\n",
            w.l2.accesses,
            w.l2.combined,
            100.0 * w.l2.hit_rate(),
            w.l2.misses,
            w.l2.merges,
            w.l2.bank_conflicts,
            w.l2.fills,
            w.l2.writebacks,
            w.l2.flush_cycles
        );
    }
    if w.rays_traced() > 0 {
        s += &format!(
            "      TMs: {}/{} got rays, rays per TM min {} max {} (max/mean {:.2})\n",
            w.tms_with_rays,
            c.tms,
            w.tm_rays_min,
            w.tm_rays_max,
            w.tm_imbalance(c.tms as u64)
        );
    }
    if c.dram.is_some() {
        s += &format!(
            "      DRAM: {:>9} lines  {:>7.1} GB/s  row hits {:>5.1}%  energy {} (paper) {} (physical)\n",
            w.dram.lines(),
            w.dram.bandwidth_gbs(c.line_bytes, w.cycles, c.core_ps),
            100.0 * w.dram.row_hit_rate(),
            crate::mem::stats::joules(w.dram.energy_paper_j),
            crate::mem::stats::joules(w.dram.energy_physical_j)
        );
    }
    s
}

/// How a multi-lane run spent its steps (`--threads`), e.g. ", lanes: 1 62%, 2 38%".
fn lanes_note(steps: &[u64]) -> String {
    let total: u64 = steps.iter().sum();
    if total == 0 || steps.len() < 2 {
        return String::new();
    }
    let parts: Vec<String> = steps
        .iter()
        .enumerate()
        .filter(|&(_, &n)| n > 0)
        .map(|(k, &n)| format!("{} {:.0}%", k + 1, 100.0 * n as f64 / total as f64))
        .collect();
    format!(", steps by evaluation lanes: {}", parts.join(", "))
}
