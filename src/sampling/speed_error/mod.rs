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
//! Energy everywhere is compute + on-chip ([`crate::energy::frame_energy`]) + DRAM
//! with the `paper` preset; where the mode has no DRAM timing its DRAM energy is
//! estimated from the line counts ([`super::dram_energy_estimate`]).

mod reference;
mod table;
mod tiles;

pub use reference::{PartCheck, Reference, RunPasses, check_parts, part_table};
pub use table::{plot, table};
pub use tiles::tile_sample;

use crate::config::Config;
use crate::machine::config::MemoryModel;
use crate::render::{self, Frame, Mode};
use crate::rtl::Threads;
use crate::scene::Scene;
use serde::Serialize;

use super::analytic::{combine, figures, parts};
use super::{
    SampleKind, TimeSampled, WindowPart, WindowPlan, WindowRecord, default_windows, estimate,
    render_cfg, time_sampled,
};
use reference::rel;

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
    pub windows: WindowPlan,
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
            record,
        } = time_sampled(scene, &gddr5, t, &o.windows)?;
        same_rays(&f)?;
        let rec = &record;
        let checks = check_parts(&parts, &r);
        if let Some(path) = &o.window_log {
            #[derive(Serialize)]
            struct Log<'a> {
                parts: &'a [WindowPart],
                checks: &'a [PartCheck],
                record: &'a WindowRecord,
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
                    .filter(|s| s.kind == SampleKind::Wave)
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
                                .any(|s| s.wave == w && s.kind == SampleKind::Wave)
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
