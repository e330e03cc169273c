//! The paper's Table 2 (Dual Streaming rows) as data, and our figures next to them.
//!
//! The numbers below are facts from Shkurko et al. 2017, Table 2 (Dual Streaming
//! column group): render time, rays traced per second, energy, bandwidth, cache
//! lines in total and per stream, ray duplication. Crytek Sponza stands in for our
//! Dabrovic Sponza (the Crytek model is not available; see the scene file).

use serde::Serialize;

use crate::render::Frame;
use crate::sampling::WindowEstimate;

/// One scene's Dual Streaming figures from Table 2.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct PaperRow {
    pub scene: &'static str,
    /// Our scene file standing for it.
    pub scene_file: &'static str,
    pub render_ms: f64,
    pub mrays_per_s: f64,
    pub dram_j: f64,
    pub onchip_j: f64,
    pub compute_j: f64,
    pub bandwidth_gbs: f64,
    pub lines_m: f64,
    pub ray_lines_m: f64,
    pub scene_lines_m: f64,
    pub shading_lines_m: f64,
    pub hit_lines_m: f64,
    pub duplication: f64,
}

// Dragon Box's duplication is 3.14 in the paper: a measurement, not pi.
#[allow(clippy::approx_constant)]
pub const TABLE2: [PaperRow; 3] = [
    PaperRow {
        scene: "Dragon",
        scene_file: "dragon.toml",
        render_ms: 18.08,
        mrays_per_s: 114.8,
        dram_j: 1.15,
        onchip_j: 1.52,
        compute_j: 0.09,
        bandwidth_gbs: 140.21,
        lines_m: 39.6,
        ray_lines_m: 11.92,
        scene_lines_m: 7.54,
        shading_lines_m: 17.43,
        hit_lines_m: 2.74,
        duplication: 4.55,
    },
    PaperRow {
        scene: "Dragon Box",
        scene_file: "dragon_box.toml",
        render_ms: 66.3,
        mrays_per_s: 177.4,
        dram_j: 4.66,
        onchip_j: 6.54,
        compute_j: 0.36,
        bandwidth_gbs: 114.98,
        lines_m: 119.2,
        ray_lines_m: 45.81,
        scene_lines_m: 8.0,
        shading_lines_m: 42.38,
        hit_lines_m: 22.97,
        duplication: 3.14,
    },
    PaperRow {
        scene: "Crytek Sponza (ours: Dabrovic Sponza)",
        scene_file: "dabrovic_sponza.toml",
        render_ms: 44.6,
        mrays_per_s: 204.11,
        dram_j: 4.51,
        onchip_j: 4.14,
        compute_j: 0.32,
        bandwidth_gbs: 237.40,
        lines_m: 165.4,
        ray_lines_m: 80.56,
        scene_lines_m: 2.26,
        shading_lines_m: 45.42,
        hit_lines_m: 37.21,
        duplication: 8.55,
    },
];

/// One compared figure.
#[derive(Clone, Debug, Serialize)]
pub struct Compared {
    pub scene: String,
    /// The metric's key: snake case with its unit last (`render_time_ms`,
    /// `dram_energy_j`, `ray_stream_lines_millions`; `$ lines` are 64-byte
    /// cache lines moved between the chip and DRAM).
    pub key: &'static str,
    /// The metric as the table names it.
    pub metric: &'static str,
    pub ours: Option<f64>,
    pub paper: f64,
    /// ours / paper; none for a figure that scales with resolution on a frame
    /// of another resolution than the paper's (`scale_free`).
    pub ratio: Option<f64>,
    /// Whether the figure is a rate or a ratio (rays per second, bandwidth,
    /// duplication), comparable at any resolution; the others are totals of a
    /// frame (time, rays, energy, lines) that grow with its pixels.
    pub scale_free: bool,
    /// Whether our frame is the paper's [`PAPER_RES`].
    pub at_paper_resolution: bool,
    /// Why a figure is missing or what it covers.
    pub note: &'static str,
}

/// The paper's frames: 1024x1024 [DS17 §5.2].
pub const PAPER_RES: (u32, u32) = (1024, 1024);

/// What the table says of a total compared at another resolution.
pub const SCALES_NOTE: &str = "scales with resolution; paper at 1024x1024";

/// A compared metric's name as the table shows it, its key in the JSON
/// (snake case, the unit last: `_ms`, `_j`, `_millions`), its figure in a
/// paper row, and whether it is scale-free (a rate or a ratio).
type Metric = (&'static str, &'static str, fn(&PaperRow) -> f64, bool);

/// The compared metrics, in table order.
const METRICS: [Metric; 14] = [
    ("render time (ms)", "render_time_ms", |r| r.render_ms, false),
    (
        "rays traced per second (M)",
        "rays_per_s_millions",
        |r| r.mrays_per_s,
        true,
    ),
    (
        "rays traced (M)",
        "rays_traced_millions",
        |r| r.render_ms * r.mrays_per_s / 1000.0,
        false,
    ),
    ("DRAM energy (J)", "dram_energy_j", |r| r.dram_j, false),
    (
        "DRAM energy, physical preset (J)",
        "dram_energy_physical_j",
        |r| r.dram_j,
        false,
    ),
    (
        "on-chip memory energy (J)",
        "onchip_energy_j",
        |r| r.onchip_j,
        false,
    ),
    (
        "compute energy (J)",
        "compute_energy_j",
        |r| r.compute_j,
        false,
    ),
    (
        "average bandwidth (GB/s)",
        "bandwidth_gb_per_s",
        |r| r.bandwidth_gbs,
        true,
    ),
    (
        "$ lines transferred (M)",
        "lines_millions",
        |r| r.lines_m,
        false,
    ),
    (
        "ray stream $ lines (M)",
        "ray_stream_lines_millions",
        |r| r.ray_lines_m,
        false,
    ),
    (
        "scene stream $ lines (M)",
        "scene_stream_lines_millions",
        |r| r.scene_lines_m,
        false,
    ),
    (
        "shading $ lines (M)",
        "shading_lines_millions",
        |r| r.shading_lines_m,
        false,
    ),
    (
        "hit record $ lines (M)",
        "hit_record_lines_millions",
        |r| r.hit_lines_m,
        false,
    ),
    (
        "ray duplication",
        "ray_duplication",
        |r| r.duplication,
        true,
    ),
];

/// Our figure for each of [`METRICS`] (none where this frame cannot give it)
/// and what it covers or why it is missing.
type Ours = [(Option<f64>, &'static str); 14];

/// What the chip's on-chip memory energy covers.
const CHIP_ONCHIP: &str = "TMs (tests, divider, TP instructions, L1, staging buffer, RF, I-fetch, local store), L2, scene buffer";
const COMPUTE: &str = "box and triangle tests, divider, TP arithmetic";
const PAPER_RAYS: &str = "paper: time x rate";

/// Our figures for one frame next to the paper's row.
pub fn compare(row: &PaperRow, f: &Frame) -> Vec<Compared> {
    let t = &f.total;
    let m = |x: u64| Some(x as f64 / 1e6);
    let cycle = "needs --mode cycle or windows (the chip with GDDR5)";
    let chip = f.chip.as_ref();
    let dram = chip.and_then(|c| c.dram);
    let ms = chip.map(|c| c.total_cycles as f64 * c.core_ps as f64 * 1e-9);
    let mrays = ms
        .filter(|&t| t > 0.0)
        .map(|t| f.total.rays as f64 / (t * 1e-3) / 1e6);
    let partial = if chip.is_some() {
        CHIP_ONCHIP
    } else {
        "TMs only (tests, divider, TP instructions, L1, staging buffer, RF, I-fetch, local store)"
    };
    let e = f.energy.as_ref();
    let or_cycle = |v: Option<f64>, note: &'static str| (v, if v.is_some() { note } else { cycle });
    let ours: Ours = [
        or_cycle(ms, "cycles x core clock"),
        or_cycle(mrays, ""),
        (m(t.rays), PAPER_RAYS),
        or_cycle(
            dram.map(|d| d.energy_paper_j),
            "preset paper (physical: next row)",
        ),
        or_cycle(
            dram.map(|d| d.energy_physical_j),
            "preset physical (datasheet currents)",
        ),
        (e.map(|e| e.onchip_j), partial),
        (e.map(|e| e.compute_j), COMPUTE),
        or_cycle(chip.and_then(|c| c.dram_bandwidth_gbs()), ""),
        (m(t.total_lines()), ""),
        (m(t.ray_lines()), ""),
        (m(t.scene_lines), ""),
        (m(t.shading_lines), ""),
        (m(t.hit_lines()), ""),
        (Some(f.duplication), ""),
    ];
    to_compared(row, f, ours)
}

/// [`compare`] for a frame rendered with time sampling (`--mode windows`): the
/// chip's figures (time, rays per second, DRAM energy, bandwidth, the hit-record
/// and shading lines, on-chip energy) are the windows' estimate of the cycle
/// model's, marked as such; the ray and scene streams are the functional
/// model's counts, which the chip moves exactly.
pub fn compare_sampled(row: &PaperRow, f: &Frame, w: &WindowEstimate) -> Vec<Compared> {
    let est = "time sampling's estimate of the cycle model";
    let exact = "the functional model's count (the chip's exactly)";
    let m = |x: f64| Some(x / 1e6);
    let ours: Ours = [
        (Some(w.time_ms()), "estimated cycles x core clock"),
        (Some(w.mrays_per_s()), est),
        (m(f.total.rays as f64), PAPER_RAYS),
        (
            Some(w.dram_paper_j),
            "preset paper (physical: next row); estimated",
        ),
        (
            Some(w.dram_physical_j),
            "preset physical (datasheet currents); estimated",
        ),
        (Some(w.onchip_j), CHIP_ONCHIP),
        (Some(w.compute_j), COMPUTE),
        (Some(w.bandwidth_gbs()), est),
        (m(w.lines()), est),
        (m(w.ray_lines), exact),
        (m(w.scene_lines), exact),
        (m(w.shading_lines), est),
        (m(w.hit_lines), est),
        (Some(f.duplication), ""),
    ];
    to_compared(row, f, ours)
}

fn to_compared(row: &PaperRow, f: &Frame, ours: Ours) -> Vec<Compared> {
    let at_paper_resolution = (f.width, f.height) == PAPER_RES;
    METRICS
        .iter()
        .zip(ours)
        .map(|(&(metric, key, paper, scale_free), (ours, note))| {
            let paper = paper(row);
            Compared {
                scene: row.scene.to_string(),
                key,
                metric,
                ours,
                paper,
                ratio: ours
                    .filter(|_| scale_free || at_paper_resolution)
                    .map(|o| o / paper),
                scale_free,
                at_paper_resolution,
                note,
            }
        })
        .collect()
}

/// The side-by-side table as text.
pub fn table(rows: &[Compared]) -> String {
    let mut s = String::new();
    let mut scene = "";
    for r in rows {
        if r.scene != scene {
            scene = &r.scene;
            s += &format!(
                "\n{}\n  {:<30} {:>12} {:>12} {:>10}\n",
                r.scene, "", "ours", "paper", "ours/paper"
            );
        }
        let (o, q) = match (r.ours, r.ratio) {
            (Some(o), Some(q)) => (format!("{o:.3}"), format!("{q:.2}")),
            (Some(o), None) => (format!("{o:.3}"), "-".to_string()),
            _ => ("-".to_string(), "-".to_string()),
        };
        // A total at another resolution: no ratio, and the table says why.
        let note = match (r.ours, r.scale_free || r.at_paper_resolution) {
            (Some(_), false) if r.note.is_empty() => SCALES_NOTE.to_string(),
            (Some(_), false) => format!("{SCALES_NOTE}; {}", r.note),
            _ => r.note.to_string(),
        };
        s += &format!(
            "  {:<30} {:>12} {:>12.3} {:>10}  {}\n",
            r.metric, o, r.paper, q, note
        );
    }
    s
}

/// The paper-style figures for the compared rows: render time (Figure 4) and DRAM
/// energy (Figure 5) when the rows come from the chip, ray duplication (Figure 7)
/// and cache lines per stream (Figure 8), ours beside the paper's. Returns
/// (file name, SVG text).
pub fn figures(rows: &[Compared]) -> Vec<(String, String)> {
    use super::svg::{Group, grouped_bars};
    let scenes: Vec<String> = {
        let mut v: Vec<String> = Vec::new();
        for r in rows {
            if !v.contains(&r.scene) {
                v.push(r.scene.clone());
            }
        }
        v
    };
    let get =
        |scene: &str, metric: &str| rows.iter().find(|r| r.scene == scene && r.metric == metric);
    let short = |s: &str| s.split(" (").next().unwrap_or(s).to_string();
    let dup: Vec<Group> = scenes
        .iter()
        .filter_map(|s| {
            let r = get(s, "ray duplication")?;
            Some(Group {
                label: short(s),
                values: vec![r.ours.unwrap_or(0.0), r.paper],
            })
        })
        .collect();
    let mut out = Vec::new();
    // Figures 4 and 5 (render time, DRAM energy per frame) exist only for rows
    // that came from the chip (`--mode cycle`).
    for (file, title, unit, metric) in [
        (
            "fig4_render_time.svg",
            "Render time per frame (Figure 4)",
            "ms",
            "render time (ms)",
        ),
        (
            "fig5_dram_energy.svg",
            "DRAM energy per frame (Figure 5)",
            "J",
            "DRAM energy (J)",
        ),
    ] {
        let groups: Vec<Group> = scenes
            .iter()
            .filter_map(|s| {
                let r = get(s, metric)?;
                Some(Group {
                    label: short(s),
                    values: vec![r.ours?, r.paper],
                })
            })
            .collect();
        if !groups.is_empty() {
            out.push((
                file.to_string(),
                grouped_bars(title, unit, &["ours", "paper"], &groups),
            ));
        }
    }
    out.push((
        "fig7_ray_duplication.svg".to_string(),
        grouped_bars(
            "Ray duplication (Figure 7)",
            "enqueues per ray",
            &["ours", "paper"],
            &dup,
        ),
    ));
    let streams = [
        "ray stream $ lines (M)",
        "scene stream $ lines (M)",
        "shading $ lines (M)",
        "hit record $ lines (M)",
    ];
    let mut groups = Vec::new();
    for s in &scenes {
        for (who, pick) in [("ours", true), ("paper", false)] {
            let values: Vec<f64> = streams
                .iter()
                .map(|m| {
                    get(s, m).map_or(0.0, |r| if pick { r.ours.unwrap_or(0.0) } else { r.paper })
                })
                .collect();
            groups.push(Group {
                label: format!("{} {who}", short(s)),
                values,
            });
        }
    }
    out.push((
        "fig8_memory_traffic.svg".to_string(),
        grouped_bars(
            "Memory traffic per stream (Figure 8)",
            "64 B lines (M)",
            &["ray", "scene", "shading", "hit record"],
            &groups,
        ),
    ));
    out
}
