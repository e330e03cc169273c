//! The cycle-mode reference of the speed/error study, rendered or read back
//! from a finished run, and the `windows` estimate's check by part against it.

use std::path::Path;

use serde::Serialize;

use crate::config::Config;
use crate::render::Frame;
use crate::sampling::SamplingError;
use crate::sampling::WindowPart;
use crate::scene::Scene;
use crate::util::FileError;

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

    pub(super) fn of_frame(f: &Frame) -> Vec<RunPasses> {
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
pub(super) fn rel(x: f64, r: f64) -> f64 {
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
    ) -> Result<Self, SamplingError> {
        let name = stats.display();
        let text = std::fs::read_to_string(stats).map_err(|e| {
            let msg = format!("cannot read the reference '{name}': {e}");
            SamplingError::File(FileError::new(stats, e, msg))
        })?;
        let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| {
            SamplingError::Reference(format!(
                "the reference '{name}' is not JSON ({e}); give the file `render --stats` wrote"
            ))
        })?;
        let num = |path: &str| -> Result<f64, SamplingError> {
            v.pointer(path).and_then(|x| x.as_f64()).ok_or_else(|| {
                SamplingError::Reference(format!("the reference '{name}' has no number at {path}; give the --stats file of a `render --mode cycle` run"))
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
            return Err(SamplingError::Reference(format!(
                "the reference '{name}' does not match this comparison ({}); render it with `render --mode cycle` (GDDR5, the default memory) on the same scene, --res and config",
                wrong.join(", ")
            )));
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
        .sum::<Result<f64, SamplingError>>()?;
        let rgb8 = match png {
            None => None,
            Some(p) => {
                let img = image::open(p)
                    .map_err(|e| {
                        SamplingError::Reference(format!(
                            "cannot read the reference image '{}': {e}",
                            p.display()
                        ))
                    })?
                    .to_rgb8();
                if img.dimensions() != (w, h) {
                    return Err(SamplingError::Reference(format!(
                        "the reference image '{}' is {}x{}, not {w}x{h}; give the PNG of the same run",
                        p.display(),
                        img.width(),
                        img.height()
                    )));
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
    pub fn read_passes(&mut self, csv: &Path) -> Result<(), SamplingError> {
        let name = csv.display();
        let text = std::fs::read_to_string(csv).map_err(|e| {
            let msg = format!("cannot read the reference's pass log '{name}': {e}");
            SamplingError::File(FileError::new(csv, e, msg))
        })?;
        let mut runs: Vec<RunPasses> = Vec::new();
        for (i, line) in text.lines().enumerate().skip(1) {
            let f: Vec<u64> = line
                .split(',')
                .map(|x| x.trim().parse::<u64>())
                .collect::<Result<_, _>>()
                .map_err(|_| {
                    SamplingError::Reference(format!("the pass log '{name}', line {}: '{line}' is not run,segment,rays,admit,retire; give the file `render --pass-log` wrote", i + 1))
                })?;
            let [run, _, _, admit, retire] = f[..] else {
                return Err(SamplingError::Reference(format!(
                    "the pass log '{name}', line {}: {} fields, not 5 (run,segment,rays,admit,retire)",
                    i + 1,
                    f.len()
                )));
            };
            let run = run as usize;
            if runs.len() <= run {
                runs.resize_with(run + 1, RunPasses::default);
            }
            runs[run].admits.push(admit);
            runs[run].end = runs[run].end.max(retire);
        }
        if runs.is_empty() {
            return Err(SamplingError::Reference(format!(
                "the pass log '{name}' holds no segment pass; give the file `render --mode cycle --pass-log` wrote"
            )));
        }
        for r in &mut runs {
            r.admits.sort_unstable();
        }
        self.passes = Some(runs);
        Ok(())
    }
}
