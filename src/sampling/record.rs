//! What time sampling records of a frame: the functional work of every
//! segment pass and every window's measurement.

use serde::Serialize;

use crate::render::WaveStats;
use crate::render::queues::RayQueues;

/// Functional work of one segment pass (for the ratio estimator of time sampling).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SegWork {
    /// The segment.
    pub seg: u32,
    /// Rays the segment's queue held.
    pub rays: u64,
    pub nodes: u64,
    pub tri_tests: u64,
    pub pops: u64,
    pub exits: u64,
    /// Rays written into child queues.
    pub enqueues: u64,
    pub scene_lines: u64,
    pub ray_lines: u64,
    pub hit_lines: u64,
}

/// One measured window of time sampling.
#[derive(Clone, Debug, Serialize)]
pub struct WindowSample {
    /// The functional wavefront it belongs to (a shading window: the pass that
    /// shades this wavefront's hits).
    pub wave: usize,
    pub kind: SampleKind,
    /// First measured admission (its ordinal in the wavefront), shading item or
    /// emitted ray.
    pub first: u64,
    pub run: crate::machine::WindowRun,
    /// Simulator wall time of the window (building the chip included).
    pub wall_s: f64,
    /// When its chip started, in seconds after the frame's time sampling
    /// began: with more than one thread the windows run side by side, and
    /// these with `wall_s` are their schedule (which window held the frame up).
    pub start_s: f64,
}

/// What a window measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
pub enum SampleKind {
    /// The host emitting the primary rays (before the first wavefront).
    Emit,
    /// A wavefront's root pass over a sample of its queue (`first`: the rays
    /// left out), to the next admission.
    Root,
    /// A short wavefront over a sample of its root queue, from its root pass to
    /// its end (`WindowPlan::wave_rays`; `first`: the rays left out).
    Wave,
    /// Segment passes of a wavefront.
    Trace,
    /// A wavefront's last segment passes (from the first boundary after the
    /// head with at most `WindowPlan::tail_pending` queues holding rays),
    /// measured to its end.
    Tail,
    /// The shading pass after a wavefront.
    Shade,
    /// A shading pass's first `WindowPlan::shade_head` items, from its start.
    ShadeHead,
}

/// The windows of one kind and their summed wall time (see
/// [`WindowRecord::chip_s_by_kind`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct KindTime {
    pub kind: SampleKind,
    pub windows: usize,
    pub chip_s: f64,
}

/// What time sampling recorded (see [`super::WindowPlan`]).
#[derive(Clone, Debug, Default, Serialize)]
pub struct WindowRecord {
    /// Per functional wavefront, per segment pass in order.
    pub segs: Vec<Vec<SegWork>>,
    pub samples: Vec<WindowSample>,
    /// Shading items per pass (the frame's pixels) = primary rays.
    pub pixels: u32,
    /// Wall time in the chip windows (building the chip included).
    pub chip_s: f64,
    /// The plan's head (admissions from each wavefront's start measured whole).
    pub head: u64,
    /// Per wavefront: whether it was traced in windows (`WindowPlan::wave_every`),
    /// and the first admission of its tail (its pass count if it has none).
    pub measured: Vec<bool>,
    pub tail_from: Vec<u64>,
    /// Per wavefront: whether it was too short to hold a window after its head
    /// (`WindowPlan::first_window_start`), so simulated whole after its root pass
    /// (borrowed: its part after the root is one, like its neighbours').
    pub whole: Vec<bool>,
    /// Per shading pass, per pixel: the shading lines the functional model
    /// moved for it (a path that was done: 1, the path state the chip reads),
    /// the work proxy the pass's windows are scaled by. Not in the window log.
    #[serde(skip)]
    pub shade_lines: Vec<Vec<u8>>,
    /// The frame's last possible wavefront (the shadow rays of the paths' last
    /// hit points: the bounce count).
    pub final_wave: usize,
}

impl SampleKind {
    /// Its name in summaries.
    pub fn label(self) -> &'static str {
        match self {
            SampleKind::Emit => "emission",
            SampleKind::Root => "root",
            SampleKind::Wave => "wavefront samples",
            SampleKind::Trace => "trace",
            SampleKind::Tail => "tail",
            SampleKind::Shade => "shading",
            SampleKind::ShadeHead => "shading heads",
        }
    }
}

/// The windows' wall time by kind as text: "12 trace 53.7 s, 3 root 11.2 s, ...".
pub fn kind_times_text(by: &[KindTime]) -> String {
    by.iter()
        .map(|k| format!("{} {} {:.1} s", k.windows, k.kind.label(), k.chip_s))
        .collect::<Vec<_>>()
        .join(", ")
}

impl WindowRecord {
    /// The windows' wall time by kind, in [`SampleKind`] order (kinds with no
    /// window left out): where time sampling's cost goes, so that a plan is
    /// tuned where it pays.
    pub fn chip_s_by_kind(&self) -> Vec<KindTime> {
        let mut by: Vec<KindTime> = Vec::new();
        let mut samples: Vec<&WindowSample> = self.samples.iter().collect();
        samples.sort_by_key(|s| s.kind);
        for s in samples {
            match by.last_mut() {
                Some(k) if k.kind == s.kind => {
                    k.windows += 1;
                    k.chip_s += s.wall_s;
                }
                _ => by.push(KindTime {
                    kind: s.kind,
                    windows: 1,
                    chip_s: s.wall_s,
                }),
            }
        }
        by
    }
}

/// Running totals of the functional model's work, for [`SegWork`] by difference.
#[derive(Clone, Copy, Default)]
pub(super) struct WorkSoFar {
    nodes: u64,
    tri_tests: u64,
    pops: u64,
    exits: u64,
    enqueues: u64,
    scene_lines: u64,
    ray_lines: u64,
    hit_lines: u64,
}

impl WorkSoFar {
    pub(super) fn of(st: &WaveStats, q: &RayQueues) -> Self {
        WorkSoFar {
            nodes: st.traversal.nodes,
            tri_tests: st.traversal.tri_tests,
            pops: st.traversal.pops,
            exits: st.traversal.exits,
            enqueues: st.enqueues,
            scene_lines: st.scene_lines,
            ray_lines: q.traffic.lines_read + q.traffic.lines_written,
            hit_lines: st.hit_lines_read + st.hit_lines_written,
        }
    }
    pub(super) fn since(&self, b: &WorkSoFar, seg: u32, rays: u64) -> SegWork {
        SegWork {
            seg,
            rays,
            nodes: self.nodes - b.nodes,
            tri_tests: self.tri_tests - b.tri_tests,
            pops: self.pops - b.pops,
            exits: self.exits - b.exits,
            enqueues: self.enqueues - b.enqueues,
            scene_lines: self.scene_lines - b.scene_lines,
            ray_lines: self.ray_lines - b.ray_lines,
            hit_lines: self.hit_lines - b.hit_lines,
        }
    }
}
