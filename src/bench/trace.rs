//! `dualstream bench trace`: what a waveform costs. One cycle frame untraced,
//! then the same frame with the whole chip traced over a window of core
//! cycles, and with only the stream scheduler and TM 0, each as VCD and as
//! FST, written to a temporary file: wall time, its ratio to the untraced
//! frame, value changes and their rate, bytes. Results and images are the
//! same with and without a trace (the tests check it); this measures time.

use std::time::Instant;

use serde::Serialize;

use super::threads::BenchError;
use crate::config::Config;
use crate::render::{self, ChipTrace, Mode, RenderCfg};
use crate::rtl::SimOptions;

#[derive(Clone, Debug, Serialize)]
pub struct TraceRun {
    pub case: String,
    pub format: &'static str,
    pub wall_s: f64,
    /// Wall time over the untraced frame's.
    pub ratio: f64,
    pub units: u64,
    pub signals: u64,
    pub changes: u64,
    /// Over the tracing's own time (traced minus untraced wall time); `None`
    /// when that is within the noise (under 5% of the untraced frame).
    pub changes_per_s: Option<f64>,
    pub bytes: u64,
}

/// The traced cases: instance filter (empty: every unit) and a name.
const CASES: [(&str, &str); 2] = [("", "full chip"), ("scheduler,tm0", "scheduler,tm0")];

fn frame(
    scene: &crate::scene::Scene,
    config: &Config,
    trace: Option<ChipTrace>,
) -> Result<(f64, Option<crate::render::VcdInfo>), BenchError> {
    let mut rc = RenderCfg::for_chip(config, SimOptions::default());
    if let Some(c) = rc.chip.as_mut() {
        c.trace = trace;
    }
    let t0 = Instant::now();
    let f = render::render(scene, Mode::Cycle, &rc, &mut |_| {})?;
    Ok((t0.elapsed().as_secs_f64(), f.chip.and_then(|c| c.vcd)))
}

/// Runs the untraced frame and every case in both formats over core cycles
/// `from..to`, calling `progress` before each run.
pub fn run(
    scene: &crate::scene::Scene,
    config: &Config,
    from: u64,
    to: u64,
    progress: &mut dyn FnMut(usize, usize, &str),
) -> Result<Vec<TraceRun>, BenchError> {
    let total = 1 + CASES.len() * 2;
    progress(0, total, "untraced");
    let (base, _) = frame(scene, config, None)?;
    let mut runs = vec![TraceRun {
        case: "untraced".into(),
        format: "-",
        wall_s: base,
        ratio: 1.0,
        units: 0,
        signals: 0,
        changes: 0,
        changes_per_s: None,
        bytes: 0,
    }];
    for (filter, name) in CASES {
        for format in ["vcd", "fst"] {
            progress(runs.len(), total, &format!("{name} {format}"));
            let path = std::env::temp_dir().join(format!(
                "dualstream-bench-trace-{}.{format}",
                std::process::id()
            ));
            let trace = ChipTrace {
                path: path.clone(),
                units: filter.into(),
                from,
                to: Some(to.saturating_sub(1)),
                max_bytes: 0,
                every_edge: false,
                show: Default::default(),
            };
            let r = frame(scene, config, Some(trace));
            let _ = std::fs::remove_file(&path);
            let _ = std::fs::remove_file(crate::rtl::trace::save_file_for(&path));
            let (wall_s, v) = r?;
            // A traced cycle frame always reports its waveform.
            let v = v.unwrap_or_default();
            runs.push(TraceRun {
                case: name.into(),
                format,
                wall_s,
                ratio: wall_s / base,
                units: v.units,
                signals: v.signals,
                changes: v.changes,
                changes_per_s: (wall_s > 1.05 * base).then(|| v.changes as f64 / (wall_s - base)),
                bytes: v.bytes,
            });
        }
    }
    Ok(runs)
}

/// The table: one row per run.
pub fn table(runs: &[TraceRun]) -> String {
    let mut s = format!(
        "{:<16} {:>6} {:>8} {:>6} {:>7} {:>9} {:>11} {:>12} {:>12}\n",
        "case", "format", "wall s", "ratio", "units", "signals", "changes", "changes/s", "bytes"
    );
    for r in runs {
        let rate = r
            .changes_per_s
            .map_or("-".to_string(), |x| format!("{x:.0}"));
        s += &format!(
            "{:<16} {:>6} {:>8.2} {:>6.2} {:>7} {:>9} {:>11} {:>12} {:>12}\n",
            r.case, r.format, r.wall_s, r.ratio, r.units, r.signals, r.changes, rate, r.bytes
        );
    }
    s
}
