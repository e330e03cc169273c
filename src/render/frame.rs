//! What a render gives: the frame, its counts per wavefront and the facts of
//! its acceleration structure.

use glam::Vec3;
use serde::Serialize;

use super::traverse::TraversalCounts;
use super::{ChipFrame, Mode};
use crate::contract::LINE_BYTES;

/// Where a render is, for progress reporting.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    pub wave: usize,
    /// Upper bound on wavefronts (hit points per path + 1).
    pub waves_max: usize,
    /// Rays of this wavefront (unique).
    pub rays: u64,
    /// Ray-segment traversals done and known so far in this wavefront.
    pub done: u64,
    pub known: u64,
    /// Cycle mode: the chip's core cycles so far in the frame.
    pub cycles: u64,
}

/// Counts of one wavefront (or of a frame, summed).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct WaveStats {
    pub rays: u64,
    pub bounce_rays: u64,
    pub shadow_rays: u64,
    /// Rays enqueued into any segment, the initial one included.
    pub enqueues: u64,
    pub segments_loaded: u64,
    pub traversal: TraversalCounts,
    pub ray_lines_read: u64,
    pub ray_lines_written: u64,
    pub scene_lines: u64,
    pub hit_lines_read: u64,
    pub hit_lines_written: u64,
    pub shading_lines: u64,
    pub hits: u64,
    pub occluded: u64,
    /// Early ray termination's reads and savings (zero with `none`).
    pub early: super::early_term::EarlyTermCounts,
}

impl WaveStats {
    pub(super) fn add(&mut self, o: &WaveStats) {
        self.rays += o.rays;
        self.bounce_rays += o.bounce_rays;
        self.shadow_rays += o.shadow_rays;
        self.enqueues += o.enqueues;
        self.segments_loaded += o.segments_loaded;
        self.traversal += o.traversal;
        self.ray_lines_read += o.ray_lines_read;
        self.ray_lines_written += o.ray_lines_written;
        self.scene_lines += o.scene_lines;
        self.hit_lines_read += o.hit_lines_read;
        self.hit_lines_written += o.hit_lines_written;
        self.shading_lines += o.shading_lines;
        self.hits += o.hits;
        self.occluded += o.occluded;
        self.early += o.early;
    }
    /// Enqueues per unique ray (the paper's ray duplication).
    pub fn duplication(&self) -> f64 {
        if self.rays == 0 {
            0.0
        } else {
            self.enqueues as f64 / self.rays as f64
        }
    }
    pub fn ray_lines(&self) -> u64 {
        self.ray_lines_read + self.ray_lines_written
    }
    pub fn hit_lines(&self) -> u64 {
        self.hit_lines_read + self.hit_lines_written
    }
    pub fn total_lines(&self) -> u64 {
        self.ray_lines() + self.scene_lines + self.hit_lines() + self.shading_lines
    }
    /// DRAM bytes per ray (the paper's Table 3).
    pub fn bytes_per_ray(&self) -> f64 {
        if self.rays == 0 {
            0.0
        } else {
            (self.total_lines() * LINE_BYTES) as f64 / self.rays as f64
        }
    }
}

/// Facts about the acceleration structure.
#[derive(Clone, Debug, Serialize)]
pub struct AccelInfo {
    pub triangles: u64,
    pub bvh_nodes: u64,
    pub bvh_depth: u32,
    pub segments: u64,
    pub scene_bytes: u64,
    pub children_min: u64,
    pub children_mean: f64,
    pub children_max: u64,
    pub segment_bytes_mean: f64,
    pub bvh_build_s: f64,
    pub segment_build_s: f64,
    /// Why the BVH was built by the binned-SAH fallback rather than PLOC (absent,
    /// and not in the statistics, for a PLOC tree).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bvh_fallback: Option<String>,
}

/// A rendered frame.
#[derive(Clone, Debug, Serialize)]
pub struct Frame {
    pub scene: String,
    pub mode: Mode,
    /// Early ray termination across segments (its counts: `total.early`).
    pub early_termination: crate::config::EarlyTermination,
    pub width: u32,
    pub height: u32,
    /// Paths per pixel: the rays and every count are of all of them.
    pub spp: u32,
    #[serde(skip)]
    pub radiance: Vec<Vec3>,
    pub accel: AccelInfo,
    pub waves: Vec<WaveStats>,
    pub total: WaveStats,
    pub duplication: f64,
    pub bytes_per_ray: f64,
    pub wall_s: f64,
    pub trace_s: f64,
    pub verified_rays: u64,
    pub dram_resident_mb: f64,
    /// Compute and on-chip energy of the TMs implied by the traversal (set by the
    /// caller from the energy table and the TP cost table; functional mode only).
    pub energy: Option<crate::energy::Energy>,
    /// Cycle mode only.
    pub chip: Option<ChipFrame>,
    /// Cycle mode with [`RenderCfg::pass_log`]: per chip run, the segment passes
    /// in retirement order.
    #[serde(skip)]
    pub passes: Vec<Vec<crate::units::stream_scheduler::PassEvent>>,
}
