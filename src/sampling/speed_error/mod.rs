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
//! estimated from the line counts ([`super::dram_energy_estimate`]).

mod modes;
mod reference;
mod table;
mod tiles;

pub use reference::{PartCheck, Reference, RunPasses, check_parts, part_table};
pub use table::{plot, table};
pub use tiles::tile_sample;

use crate::config::Config;
use crate::render::{self, Frame, Mode};
use crate::rtl::Threads;
use crate::sampling::SamplingError;
use crate::scene::Scene;

use super::analytic::figures;
use super::{WindowPlan, default_windows, render_cfg};
use modes::Study;

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

fn total_energy(c: &Config, f: &Frame, cycles: f64) -> Result<f64, SamplingError> {
    Ok(figures(c, f, cycles)?[2])
}

fn render_pixels(
    scene: &Scene,
    mode: Mode,
    c: &Config,
    pixels: Option<Vec<u32>>,
    threads: Threads,
) -> Result<Frame, SamplingError> {
    let rc = render_cfg(c, pixels, threads);
    Ok(render::render(scene, mode, &rc, &mut |_| {})?)
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
pub fn run(
    scene: &Scene,
    config: &Config,
    o: &SpeedErrorOpts,
) -> Result<Vec<ModeResult>, SamplingError> {
    run_progress(scene, config, o, &mut |_, _, _| {})
}

/// [`run`], calling `progress` before each run of the study (its index, the
/// runs, what it is).
pub fn run_progress(
    scene: &Scene,
    config: &Config,
    o: &SpeedErrorOpts,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<Vec<ModeResult>, SamplingError> {
    if let Some(m) = &o.modes {
        for x in m {
            if !MODES.contains(&x.as_str()) {
                return Err(SamplingError::Invalid(format!(
                    "--modes: unknown mode '{x}'; choose from {}",
                    MODES.join(", ")
                )));
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
        return Err(SamplingError::Invalid(format!(
            "--small-tms {} must be between 1 and chip.tms - 1 ({}); choose a smaller chip",
            o.small_tms,
            config.chip.tms.saturating_sub(1)
        )));
    }
    let samples = if want("sampled") {
        tile_samples(scene, o)?
    } else {
        Vec::new()
    };
    let steps = [
        true,
        want("cycle-fixed"),
        want("functional+estimate") || want("sampled"),
        want("small-chip") || want("small-chips-fit"),
        want("quarter-pixels"),
        want("sampled"),
        want("windows"),
    ];
    let total = steps.iter().filter(|&&x| x).count();
    let mut k = 0;
    let mut step = |what: &str| {
        progress(k, total, what);
        k += 1;
    };
    // The reference: rendered here, or read back from a finished run.
    step("reference");
    let mut s = Study::new(scene, config, o)?;
    if want("cycle-fixed") {
        step("cycle-fixed");
        s.cycle_fixed()?;
    }
    // The functional frame and its estimate (also the sampled modes' auxiliary).
    let functional = if want("functional+estimate") || want("sampled") {
        step("functional+estimate");
        Some(s.functional(want("functional+estimate"))?)
    } else {
        None
    };
    if want("small-chip") || want("small-chips-fit") {
        step("small chips");
        s.small_chips(want("small-chip"), want("small-chips-fit"))?;
    }
    if want("quarter-pixels") {
        step("quarter-pixels");
        s.quarter_pixels()?;
    }
    if let Some(f) = functional.filter(|_| want("sampled")) {
        step("sampled");
        s.sampled(f, &samples)?;
    }
    if want("windows") {
        step("windows");
        s.windows()?;
    }
    Ok(s.out)
}

/// The `sampled` mode's disjoint tile samples (`--subsets` of one tile in
/// `--sample-every`).
fn tile_samples(scene: &Scene, o: &SpeedErrorOpts) -> Result<Vec<Vec<u32>>, SamplingError> {
    if o.sample_every == 0 {
        return Err(SamplingError::Invalid(
            "--sample-every 0 keeps nothing; give 1 (every tile) or more".into(),
        ));
    }
    if o.subsets == 0 || o.subsets > o.sample_every {
        return Err(SamplingError::Invalid(format!(
            "--subsets {} must be between 1 and --sample-every ({}): the samples are disjoint",
            o.subsets, o.sample_every
        )));
    }
    let (w, h) = (scene.settings.width, scene.settings.height);
    (0..o.subsets)
        .map(|s| tile_sample(w, h, o.tile, o.sample_every, s * o.sample_every / o.subsets))
        .collect()
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
