//! What `render --mode windows` gives the user besides the functional frame's
//! output: the estimate's summary and JSON.

use crate::sampling::SamplingError;
use std::path::Path;

use super::{WindowEstimate, kind_times_text};
use crate::render::Frame;
use crate::render::header::RunHeader;
use crate::render::output::write_stats;

/// [`crate::render::output::write_json`] of a time-sampled frame: the functional frame's statistics and,
/// as `estimate`, the windows' estimate of the cycle model's figures.
pub fn write_json_estimated(
    frame: &Frame,
    estimate: &WindowEstimate,
    header: Option<&RunHeader>,
    path: Option<&Path>,
) -> Result<(), SamplingError> {
    #[derive(serde::Serialize)]
    struct Estimated<'a> {
        #[serde(flatten)]
        frame: &'a Frame,
        estimate: &'a WindowEstimate,
    }
    Ok(write_stats(&Estimated { frame, estimate }, header, path)?)
}

/// The chip's figures as time sampling estimates them (`render --mode windows`).
pub fn window_summary(e: &WindowEstimate) -> String {
    let mut s = format!(
        "  time sampling: {} windows of the chip with GDDR5 ({:.1} s in the chips: {}); the cycle model's figures, estimated:\n",
        e.windows,
        e.chip_s,
        kind_times_text(&e.chip_s_by_kind)
    );
    s += &format!(
        "  cycles {:.0} ({:.3} ms, {:.1} M rays/s)\n",
        e.cycles,
        e.time_ms(),
        e.mrays_per_s()
    );
    s += &format!(
        "  DRAM lines {:.3} M: rays {:.3} M, scene {:.3} M, hit records {:.3} M, shading {:.3} M ({:.1} GB/s)\n",
        e.lines() / 1e6,
        e.ray_lines / 1e6,
        e.scene_lines / 1e6,
        e.hit_lines / 1e6,
        e.shading_lines / 1e6,
        e.bandwidth_gbs()
    );
    s += &format!(
        "  energy: DRAM {:.4} J (paper preset; physical {:.4} J), on-chip {:.4} J, compute {:.4} J\n",
        e.dram_paper_j, e.dram_physical_j, e.onchip_j, e.compute_j
    );
    if let Some(se) = e.se_text() {
        s += &format!("  {se}\n");
    }
    s += "  measured error against the cycle model on the paper scenes: docs/speed-error.md\n";
    s
}
