//! The study's modes, each against the reference: one row apiece (two for
//! `sampled`), in the order [`super::run`] takes them.

use serde::Serialize;

use crate::sampling::SamplingError;

use super::reference::rel;
use super::{ModeResult, PartCheck, Reference, RunPasses, SpeedErrorOpts, check_parts, mean_se};
use super::{render_pixels, total_energy};
use crate::config::Config;
use crate::render::{self, Frame, Mode};
use crate::sampling::analytic::{FrameParts, figures, parts};
use crate::sampling::{
    SampleKind, TimeSampled, WindowPart, WindowRecord, estimate, render_cfg, time_sampled,
};
use crate::scene::Scene;
use crate::units::memory::MemoryModel;

/// The comparison under way: the reference and the rows so far.
pub(super) struct Study<'a> {
    scene: &'a Scene,
    config: &'a Config,
    o: &'a SpeedErrorOpts,
    /// `config` on GDDR5.
    gddr5: Config,
    r: Reference,
    /// The reference's frame, when rendered here (not read back).
    rendered: Option<Frame>,
    pub(super) out: Vec<ModeResult>,
}

fn cycles_of(f: &Frame) -> f64 {
    f.chip.as_ref().map_or(0, |c| c.total_cycles) as f64
}

impl<'a> Study<'a> {
    /// The reference, rendered here (with its pass log, for the windows
    /// mode's check by part) or read back from a finished run, as the first row.
    pub(super) fn new(
        scene: &'a Scene,
        config: &'a Config,
        o: &'a SpeedErrorOpts,
    ) -> Result<Study<'a>, SamplingError> {
        let mut gddr5 = config.clone();
        gddr5.chip.memory.model = MemoryModel::Gddr5;
        let (rendered, r) = match &o.reference {
            Some(r) => (None, r.clone()),
            None => {
                let mut rc = render_cfg(&gddr5, None, o.threads);
                rc.pass_log = true;
                let f = render::render(scene, Mode::Cycle, &rc, &mut |_| {})?;
                let cycles = cycles_of(&f);
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
        let mut s = Study {
            scene,
            config,
            o,
            gddr5,
            r,
            rendered,
            out: Vec::new(),
        };
        let r = &s.r;
        let row = [r.cycles, r.lines, r.energy_j];
        let note = if s.rendered.is_some() {
            "reference: the chip with GDDR5"
        } else {
            "reference: the chip with GDDR5, read from --reference"
        };
        s.push("cycle", s.r.wall_s, row, Some(true), None, note);
        Ok(s)
    }

    /// Whether a mode's image equals the reference's on the pixels it renders: bit for
    /// bit against a rendered reference, as 8-bit sRGB against a reference's PNG,
    /// unknown without either.
    fn same_image(&self, f: &Frame, pixels: Option<&[u32]>) -> Option<bool> {
        let all: Vec<u32>;
        let pix = match pixels {
            Some(p) => p,
            None => {
                all = (0..f.radiance.len() as u32).collect();
                &all
            }
        };
        if let Some(rf) = &self.rendered {
            Some(
                pix.iter()
                    .all(|&p| f.radiance[p as usize] == rf.radiance[p as usize]),
            )
        } else {
            self.r.rgb8.as_ref().map(|png| {
                pix.iter().all(|&p| {
                    let i = 3 * p as usize;
                    render::output::rgb8(f.radiance[p as usize])[..] == png[i..i + 3]
                })
            })
        }
    }

    /// A mode that traces the whole frame traces exactly the reference's rays; if not,
    /// the reference is another frame (seed, bounces, scene file) and no error means
    /// anything.
    fn same_rays(&self, f: &Frame) -> Result<(), SamplingError> {
        if f.total.rays != self.r.rays {
            return Err(SamplingError::Reference(format!(
                "this frame traces {} rays, the reference {}: the reference was rendered with another scene, seed, bounce count or config; re-render it with this one",
                f.total.rays, self.r.rays
            )));
        }
        Ok(())
    }

    /// A mode's row: its wall time and figures against the reference's.
    fn push(
        &mut self,
        mode: &str,
        wall: f64,
        [cycles, lines, energy]: [f64; 3],
        same: Option<bool>,
        est_err: Option<[f64; 3]>,
        note: &str,
    ) {
        let r = &self.r;
        self.out.push(ModeResult {
            mode: mode.into(),
            wall_s: wall,
            speedup: r.wall_s / wall.max(1e-9),
            cycles,
            lines,
            energy_j: energy,
            err_cycles: rel(cycles, r.cycles),
            err_lines: rel(lines, r.lines),
            err_energy: rel(energy, r.energy_j),
            image_identical: same,
            est_err,
            note: note.into(),
            by_part: Vec::new(),
        })
    }

    /// `cycle-fixed`: the chip with the fixed-latency memory.
    pub(super) fn cycle_fixed(&mut self) -> Result<(), SamplingError> {
        let mut fixed = self.config.clone();
        fixed.chip.memory.model = MemoryModel::Fixed;
        let f = render_pixels(self.scene, Mode::Cycle, &fixed, None, self.o.threads)?;
        self.same_rays(&f)?;
        let cyc = cycles_of(&f);
        let same = self.same_image(&f, None);
        self.push(
            "cycle-fixed",
            f.wall_s,
            figures(&fixed, &f, cyc)?,
            same,
            None,
            "fixed-latency memory; DRAM energy estimated from lines",
        );
        Ok(())
    }

    /// The functional frame and its estimate, as a row (`row`) and for the
    /// sampled modes: its wall time and figures by part.
    pub(super) fn functional(&mut self, row: bool) -> Result<(f64, FrameParts), SamplingError> {
        let f = render_pixels(
            self.scene,
            Mode::Functional,
            self.config,
            None,
            self.o.threads,
        )?;
        self.same_rays(&f)?;
        let est = estimate(&self.gddr5, &f).cycles;
        let full_parts = parts(&self.gddr5, &f, est)?;
        let fig = full_parts.combine();
        if row {
            let same = self.same_image(&f, None);
            self.push(
                "functional+estimate",
                f.wall_s,
                fig,
                same,
                None,
                "no clock; cycles = per-wave max of resource bounds",
            );
        }
        Ok((f.wall_s, full_parts))
    }

    /// `small-chip` (`one`): a chip of `--small-tms` TMs, cycles scaled;
    /// `small-chips-fit` (`fit`): that and one of twice the TMs, fitted.
    pub(super) fn small_chips(&mut self, one: bool, fit: bool) -> Result<(), SamplingError> {
        let (o, config, t) = (self.o, self.config, self.o.threads);
        let mut small = self.gddr5.clone();
        small.chip.tms = o.small_tms;
        let f = render_pixels(self.scene, Mode::Cycle, &small, None, t)?;
        self.same_rays(&f)?;
        let scale = o.small_tms as f64 / config.chip.tms as f64;
        let c1 = cycles_of(&f);
        if one {
            let cyc = c1 * scale;
            let same = self.same_image(&f, None);
            self.push(
                "small-chip",
                f.wall_s,
                figures(&small, &f, cyc)?,
                same,
                None,
                &format!("{} TMs, cycles x {scale}", o.small_tms),
            );
        }
        // Two small chips, s and 2s TMs, fit cycles = a + b / TMs (a serial part and
        // a part that divides over the TMs), evaluated at the full TM count.
        let (s1, s2) = (o.small_tms, 2 * o.small_tms);
        if fit && s2 < config.chip.tms {
            let mut small2 = self.gddr5.clone();
            small2.chip.tms = s2;
            let f2 = render_pixels(self.scene, Mode::Cycle, &small2, None, t)?;
            let c2 = cycles_of(&f2);
            let b = (c1 - c2) / (1.0 / s1 as f64 - 1.0 / s2 as f64);
            let a = c2 - b / s2 as f64;
            let cyc = (a + b / config.chip.tms as f64).max(0.0);
            let fig = figures(&small2, &f2, cyc)?;
            let same = self.same_image(&f2, None);
            let note = format!("{s1} and {s2} TMs ({c1:.0}, {c2:.0} cycles), a + b/TMs");
            self.push(
                "small-chips-fit",
                f.wall_s + f2.wall_s,
                fig,
                same,
                None,
                &note,
            );
        }
        Ok(())
    }

    /// `quarter-pixels`: a frame of half the width and height, scaled.
    pub(super) fn quarter_pixels(&mut self) -> Result<(), SamplingError> {
        let (w, h) = (self.scene.settings.width, self.scene.settings.height);
        let mut quarter = self.scene.clone();
        quarter.settings.width = (w / 2).max(1);
        quarter.settings.height = (h / 2).max(1);
        let ratio = (w * h) as f64 / (quarter.settings.width * quarter.settings.height) as f64;
        let f = render_pixels(&quarter, Mode::Cycle, &self.gddr5, None, self.o.threads)?;
        let cyc = cycles_of(&f);
        let fig = [
            cyc * ratio,
            f.total.total_lines() as f64 * ratio,
            total_energy(&self.gddr5, &f, cyc)? * ratio,
        ];
        self.push(
            "quarter-pixels",
            f.wall_s,
            fig,
            None,
            None,
            &format!(
                "{}x{} frame, everything x {ratio}",
                quarter.settings.width, quarter.settings.height
            ),
        );
        Ok(())
    }

    /// `sampled` and `sampled-scaled` over the tile `samples`, with the
    /// functional frame's wall time and figures by part (`functional`).
    pub(super) fn sampled(
        &mut self,
        (func_wall, full_parts): (f64, FrameParts),
        samples: &[Vec<u32>],
    ) -> Result<(), SamplingError> {
        let (scene, o, t) = (self.scene, self.o, self.o.threads);
        let gddr5 = &self.gddr5;
        let (w, h) = (scene.settings.width, scene.settings.height);
        // Per sample: the cycle model's figures, and per part (cycles, each stream's
        // lines, energy) their ratio to the functional model's on the same pixels,
        // applied to the functional whole frame's part. By part, because the parts
        // scale differently with the pixels: the scene stream not at all, while the
        // L2 filters only hit-record and shading lines, so one ratio of the totals
        // carries a small frame's mix of streams into the whole frame's.
        let mut wall = func_wall;
        let (mut ratio, mut scaled) = (Vec::new(), Vec::new());
        let mut same = Some(true);
        for pix in samples {
            let frac = pix.len() as f64 / (w * h) as f64;
            let fc = render_pixels(scene, Mode::Cycle, gddr5, Some(pix.clone()), t)?;
            let ff = render_pixels(scene, Mode::Functional, self.config, Some(pix.clone()), t)?;
            wall += fc.wall_s + ff.wall_s;
            same = match (same, self.same_image(&fc, Some(pix))) {
                (Some(a), Some(b)) => Some(a && b),
                _ => None,
            };
            let cyc = cycles_of(&fc);
            let pc = parts(gddr5, &fc, cyc)?;
            let est = estimate(gddr5, &ff).cycles;
            let pf = parts(gddr5, &ff, est)?;
            // A part the functional sample lacks contributes the whole frame's own.
            let by_part = full_parts.zip3(&pc, &pf, |full, pc, pf| {
                let r = if pf > 0.0 { pc / pf } else { 1.0 };
                full * r
            });
            ratio.push(by_part.combine());
            scaled.push(pc.combine().map(|x| x / frac));
        }
        let m = samples.len();
        let note = format!(
            "{m} sample(s) of one {0}x{0} tile in {1} ({2:.1}% of the pixels each)",
            o.tile,
            o.sample_every,
            100.0 * samples[0].len() as f64 / (w * h) as f64
        );
        let r = mean_se(&ratio);
        self.push(
            "sampled",
            wall,
            r.0,
            same,
            r.1,
            &format!("{note}; functional frame x cycle/functional of the samples, by part"),
        );
        let sc = mean_se(&scaled);
        self.push(
            "sampled-scaled",
            wall - func_wall,
            sc.0,
            same,
            sc.1,
            &format!("{note}; x the pixel ratio"),
        );
        Ok(())
    }

    /// `windows`: time sampling, with its check by part against a reference
    /// with a pass log and its window log (`--window-log`).
    pub(super) fn windows(&mut self) -> Result<(), SamplingError> {
        let o = self.o;
        let TimeSampled {
            frame: f,
            estimate: est,
            parts,
            record,
        } = time_sampled(self.scene, &self.gddr5, o.threads, &o.windows)?;
        self.same_rays(&f)?;
        let checks = check_parts(&parts, &self.r);
        if let Some(path) = &o.window_log {
            write_window_log(path, &parts, &checks, &record)?;
        }
        let same = self.same_image(&f, None);
        self.push(
            "windows",
            f.wall_s,
            [
                est.cycles,
                est.lines(),
                est.dram_paper_j + est.onchip_j + est.compute_j,
            ],
            same,
            est.rel_se,
            &windows_note(o, &record),
        );
        if let Some(row) = self.out.last_mut() {
            row.by_part = checks;
        }
        Ok(())
    }
}

/// Every window's measurement, the functional passes and the estimate by
/// part, as JSON (`--window-log`).
fn write_window_log(
    path: &std::path::Path,
    parts: &[WindowPart],
    checks: &[PartCheck],
    record: &WindowRecord,
) -> Result<(), SamplingError> {
    #[derive(Serialize)]
    struct Log<'a> {
        parts: &'a [WindowPart],
        checks: &'a [PartCheck],
        record: &'a WindowRecord,
    }
    let log = Log {
        parts,
        checks,
        record,
    };
    let text = serde_json::to_string(&log).expect("window log serialises");
    std::fs::write(path, text).map_err(|e| {
        let msg = format!(
            "cannot write the window log '{}': {e}; choose a writable --window-log",
            path.display()
        );
        SamplingError::File(crate::util::FileError::new(path, e, msg))
    })
}

/// The `windows` row's note: how many windows of which kinds, and the plan.
fn windows_note(o: &SpeedErrorOpts, rec: &WindowRecord) -> String {
    let wp = &o.windows;
    format!(
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
    )
}
