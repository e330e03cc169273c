//! First-order figures of a functional frame with no clock: its cycles from
//! resource bounds ([`estimate`]) and its DRAM energy from its line counts
//! ([`dram_energy_estimate`]); a frame's figures by part.

use crate::config::Config;
use crate::render::Frame;
use crate::sampling::SamplingError;

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
pub(super) fn peak_bytes_per_cycle(c: &Config) -> f64 {
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
fn paper_dram(c: &Config) -> Result<(crate::mem::energy::EnergyModel, f64, f64), SamplingError> {
    preset_dram(c, "paper")
}

/// [`paper_dram`] for the DRAM energy preset `preset` (`paper`, `physical`).
fn preset_dram(
    c: &Config,
    preset: &str,
) -> Result<(crate::mem::energy::EnergyModel, f64, f64), SamplingError> {
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
pub fn dram_energy_estimate(c: &Config, f: &Frame, cycles: f64) -> Result<f64, SamplingError> {
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
pub(super) fn line_write_j(c: &Config) -> Result<[f64; 2], SamplingError> {
    let j = |preset| -> Result<f64, SamplingError> {
        let (m, bursts_per_line, lines_per_row) = preset_dram(c, preset)?;
        Ok((bursts_per_line * m.wr_burst_pj + m.act_pre_pj / lines_per_row) * 1e-12)
    };
    Ok([j("paper")?, j("physical")?])
}

/// A frame's figures by part, for the ratio estimator ([`parts`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct FrameParts {
    /// Simulated or estimated.
    pub cycles: f64,
    /// DRAM lines of the ray stream, the scene stream, the hit records and the
    /// shading pass.
    pub ray_lines: f64,
    pub scene_lines: f64,
    pub hit_lines: f64,
    pub shading_lines: f64,
    /// Compute + on-chip energy.
    pub onchip_j: f64,
    /// DRAM energy (`paper` preset).
    pub dram_j: f64,
}

impl FrameParts {
    /// Cycles, DRAM lines and energy.
    pub(super) fn combine(&self) -> [f64; 3] {
        [
            self.cycles,
            self.ray_lines + self.scene_lines + self.hit_lines + self.shading_lines,
            self.onchip_j + self.dram_j,
        ]
    }

    /// Each part `f(self's, a's, b's)`.
    pub(super) fn zip3(&self, a: &Self, b: &Self, f: impl Fn(f64, f64, f64) -> f64) -> Self {
        FrameParts {
            cycles: f(self.cycles, a.cycles, b.cycles),
            ray_lines: f(self.ray_lines, a.ray_lines, b.ray_lines),
            scene_lines: f(self.scene_lines, a.scene_lines, b.scene_lines),
            hit_lines: f(self.hit_lines, a.hit_lines, b.hit_lines),
            shading_lines: f(self.shading_lines, a.shading_lines, b.shading_lines),
            onchip_j: f(self.onchip_j, a.onchip_j, b.onchip_j),
            dram_j: f(self.dram_j, a.dram_j, b.dram_j),
        }
    }
}

/// A frame's figures by part, `cycles` given (simulated or estimated), the DRAM
/// energy simulated or else estimated from the lines.
pub(super) fn parts(c: &Config, f: &Frame, cycles: f64) -> Result<FrameParts, SamplingError> {
    let t = &f.total;
    let e = crate::render::energy::frame_energy(c, f);
    let dram = match f.chip.as_ref().and_then(|ch| ch.dram) {
        Some(d) => d.energy_paper_j,
        None => dram_energy_estimate(c, f, cycles)?,
    };
    Ok(FrameParts {
        cycles,
        ray_lines: t.ray_lines() as f64,
        scene_lines: t.scene_lines as f64,
        hit_lines: t.hit_lines() as f64,
        shading_lines: t.shading_lines as f64,
        onchip_j: e.compute_j + e.onchip_j,
        dram_j: dram,
    })
}

/// A frame's cycles (given: simulated or estimated), DRAM lines and energy.
pub(super) fn figures(c: &Config, f: &Frame, cycles: f64) -> Result<[f64; 3], SamplingError> {
    Ok(parts(c, f, cycles)?.combine())
}
