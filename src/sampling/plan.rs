//! The window plan: where time sampling runs the chip in a functional frame.

use super::SegWork;
use crate::render::queues;
use crate::sampling::SamplingError;

/// Time sampling (`bench speed-error --modes windows`): while the functional model
/// traces a wavefront segment by segment, the chip takes it over at some segment
/// boundaries (`Chip::trace_window`) and is measured for a stretch of admissions;
/// after each wavefront it measures stretches of the shading pass that follows.
/// Counts are in segments that hold rays (admissions), in the order the functional
/// model and the scheduler both take them.
#[derive(Clone, Debug, PartialEq)]
pub struct WindowPlan {
    /// Admissions measured from each wavefront's start: the root pass (by its
    /// root window) and the next `head - 1` admissions simulated whole (the top
    /// of the tree, where the rays are).
    pub head: u64,
    /// Rays of the first wavefront's root window: a root pass of at most this
    /// many rays simulated whole, a longer one over about this many of its
    /// rays, one run in k of its queue packed into its first buckets
    /// (`RayQueues::boundary_compact`). The rays left out cost the cycles and
    /// DRAM energy per ray of its steady stretch ([`ROOT_STEADY_TENTHS`]), and
    /// k times its lines and other counts but for its segment's load.
    pub root_rays: u64,
    /// The same for the later wavefronts' root windows. Half of `root_rays`
    /// by default: a fresh chip runs the primary rays' root pass fast at
    /// first, so a shorter sample of it ends in that start and reads low,
    /// while the later root passes read the same with half the rays at half
    /// the cost (docs/results/2026-11-27-speed-error-root-windows-of-the-later-wavefronts-and-shorter-tails.md).
    pub bounce_root_rays: u64,
    /// Rays of a short wavefront's sample (one with too few passes for a
    /// window, see [`WindowPlan::first_window_start`]): such a wavefront of
    /// more rays is simulated from its root pass to its end over one run of
    /// rays in k of its root queue (`queues::Thinning::wave`: runs of
    /// [`WindowPlan::sample_run`] rays, hit records in place), on
    /// `wave_l2_share` of the L2, and measured
    /// over its visits (rays finished in a segment) from the first tenth to the
    /// ninth ([`ROOT_STEADY_TENTHS`]); the visits it left out cost that
    /// stretch's cycles and DRAM energy each, its other counts go by the
    /// functional work. With `wave_every` above 1, one between the fourth
    /// wavefront and the last borrows from the sampled ones from the third on
    /// (`SAMPLE_BORROW_FROM`) if its rays are alike the last measured one's
    /// and the wavefront before it was sampled too. 0: such a wavefront
    /// is simulated whole after its root window.
    pub wave_rays: u64,
    /// A wavefront sample's L2 is this share of the chip's. The sample
    /// passes its rays' hit records through the passes k times faster than
    /// the wavefront does, so a whole L2 still holds them when a ray comes
    /// back in a later pass and the sample's hit-record lines read low; one
    /// k-th of it loses the reuse between neighbouring rays in a pass. The
    /// share between is measured, not derived (on Dabrovic Sponza:
    /// docs/results/2026-11-26-speed-error-short-wavefronts-over-a-sample.md
    /// for a quarter, docs/results/2026-11-27-speed-error-root-windows-of-the-later-wavefronts-and-shorter-tails.md
    /// for an eighth).
    pub wave_l2_share: u32,
    /// A short wavefront is traced over a sample only if the sample's ray
    /// stream per pass (its rays times the visits a ray makes, guessed from
    /// the last wavefront, else one, over the passes) comes to at least this
    /// share of a segment's lines; else it is simulated whole. Below that the
    /// sample's passes are bound by loading their segments, not by their rays,
    /// and its cycles per visit say nothing of the whole wavefront's. The
    /// default sits between the shares of samples measured bad and good
    /// (docs/results/2026-11-27-speed-error-middle-root-passes-and-shading-windows.md,
    /// "A guard on wavefront samples").
    pub wave_ray_share: f64,
    /// Of the sampled short wavefronts, those from the second to this one
    /// are also simulated whole (root window, then the rest whole): the ratio
    /// of their whole figures to their samples' corrects every other sampled
    /// wavefront, count by count (double sampling: what is left of a sample's
    /// bias, see `wave_l2_share`, is alike over the wavefronts). A whole
    /// wavefront costs as much as the cycle model's, so this is for checking
    /// a sample on a new scene. 0: no correction.
    pub wave_whole: u64,
    /// Admissions simulated before a window's measurement (to fill the working
    /// set, the TMs and the caches) and measured.
    pub warm: u64,
    pub measure: u64,
    /// One window's measurement starts every `every` admissions after the head.
    pub every: u64,
    /// Shading windows per pass (evenly spread over the pixels), their warm-up
    /// and measured items.
    pub shade_windows: u32,
    pub shade_warm: u64,
    pub shade_measure: u64,
    /// And at least this many cycles of warm-up: a shading pass's rate
    /// settles over time, not items, and not by the L2 (docs/speed-error.md,
    /// "Why the Dragon's later shading passes read high").
    pub shade_warm_cycles: u64,
    /// Items of each shading pass simulated from its start, as is.
    pub shade_head: u64,
    /// The tail window starts (its warm-up) at the first boundary after the
    /// head where at most this many queues hold rays.
    pub tail_pending: u64,
    /// Admissions the tail window runs before its measurement (the tail is
    /// shorter than a window's warm-up, so it has its own).
    pub tail_warm: u64,
    /// Wavefronts traced in windows: the first (primary rays), the last (the
    /// last hit points' shadow rays) and every `wave_every`-th from the second
    /// on (1: all). The others take no trace window: their root, head, rest and
    /// tail are their functional proxies times the ratios of the nearest
    /// measured wavefronts between the first and the last (their shading
    /// passes keep their windows). With `wave_every` above 1, root windows run
    /// in the first, second and last wavefronts only, and the other roots go
    /// by the rays of the nearest of those after the first: a root pass costs
    /// the same per ray in every wavefront after the first (once the root pass
    /// is longer than a root window). A wavefront whose rays differ from the
    /// last measured one's by more than [`BORROW_ALIKE`] is traced in windows
    /// all the same, but its root pass is still borrowed: on the line through
    /// the nearest root windows before and after it, in rays
    /// ([`super::root_between`]).
    pub wave_every: u64,
}

/// A root window's measured stretch, in tenths of its rays finished: from the
/// first tenth to the ninth, past the pass's start-up (the TMs filling) and
/// before its drain (its last rays traced), which the whole pass has once.
pub const ROOT_STEADY_TENTHS: (u64, u64) = (1, 9);

/// The first wavefront whose sample (`WindowPlan::wave_rays`) a later one may
/// borrow: the primary rays' and the first bounce's cost more per visit (see
/// the root pass in `frame.rs`).
pub const SAMPLE_BORROW_FROM: usize = 2;
/// Time sampling borrows for a wavefront (its trace or its root pass) only if
/// its rays are within this fraction of the last measured one's: the ratios it
/// borrows were measured at that load, and a wavefront with fewer rays is more
/// latency-bound (docs/speed-error.md, "Time sampling": borrowed wavefronts).
pub const BORROW_ALIKE: f64 = 0.1;

impl WindowPlan {
    /// Whether wavefront `wave` of a frame whose last is `last` is traced in
    /// windows (see `wave_every`).
    pub fn measures_wave(&self, wave: usize, last: usize) -> bool {
        wave == 0 || wave >= last || (wave as u64 - 1).is_multiple_of(self.wave_every.max(1))
    }

    /// The admission where a wavefront's first measured stretch starts: a
    /// wavefront with no more passes holds no window, so it is simulated whole
    /// after its root pass (its passes are guessed from the last wavefront's,
    /// or from the segments for the first).
    pub fn first_window_start(&self) -> u64 {
        // A window starts at admission k >= 1 (>= 2 after a head window) with
        // k + warm - head a multiple of `every` (see `trace_window` in `frame.rs`).
        let k_min = if self.head > 1 { 2 } else { 1 };
        let lo = (k_min + self.warm).saturating_sub(self.head);
        self.head
            .saturating_add(lo.div_ceil(self.every.max(1)).saturating_mul(self.every))
    }

    /// Whether a short wavefront of `rays` (the last wavefront's passes
    /// `last`, if any; `passes` expected) is worth a sample: its ray-stream
    /// lines per pass at least `wave_ray_share` of a segment's (of
    /// `segment_bytes`, the scene's mean; see there).
    pub fn sample_streams_rays(
        &self,
        rays: u64,
        last: Option<&[SegWork]>,
        passes: u64,
        segment_bytes: f64,
    ) -> bool {
        let kept = rays / rays.div_ceil(self.wave_rays.max(1));
        let visits = last
            .filter(|s| s.first().is_some_and(|f| f.rays > 0))
            .map_or(1.0, |s| {
                s.iter().map(|x| x.rays).sum::<u64>() as f64 / s[0].rays as f64
            });
        let line = crate::contract::LINE_BYTES as f64;
        let ray_lines = kept as f64 * visits * crate::contract::RAY_BYTES as f64 / line;
        let seg_lines = segment_bytes / line;
        ray_lines / passes.max(1) as f64 >= self.wave_ray_share * seg_lines
    }

    /// Rays in a run of a wavefront sample: [`queues::SAMPLE_RUN`], fewer
    /// for a sample of fewer than 16 such runs (at least
    /// [`queues::COMPACT_RUN`]).
    pub fn sample_run(&self) -> u64 {
        (self.wave_rays / 16).clamp(queues::COMPACT_RUN, queues::SAMPLE_RUN)
    }

    /// Whether wavefront `wave` takes a root window (see `wave_every`).
    pub fn measures_root(&self, wave: usize, last: usize) -> bool {
        self.wave_every <= 1 || wave <= 1 || wave >= last
    }

    /// A root pass of at most this many rays between the second wavefront and
    /// the last is simulated whole, not borrowed: a quarter of such a
    /// wavefront's root window (`bounce_root_rays`). Such a pass is so
    /// latency-bound that borrowing misses it, and it is cheap; one up to a
    /// whole root window costs as much as a root window
    /// (docs/results/2026-11-27-speed-error-middle-root-passes-and-shading-windows.md).
    pub fn root_whole(&self) -> u64 {
        self.bounce_root_rays / 4
    }

    /// Rays of wavefront `wave`'s root window (`root_rays` for the first,
    /// `bounce_root_rays` after).
    pub fn root_window_rays(&self, wave: usize) -> u64 {
        if wave == 0 {
            self.root_rays
        } else {
            self.bounce_root_rays
        }
    }
}

impl WindowPlan {
    pub fn validate(&self) -> Result<(), SamplingError> {
        if self.head == 0 || self.measure == 0 || self.every == 0 {
            return Err(SamplingError::Invalid(format!(
                "time sampling needs a head, a measured stretch and a period of at least one segment admission (head {}, --window-measure {}, --window-every {}); raise the zero one",
                self.head, self.measure, self.every
            )));
        }
        if self.wave_every == 0 {
            return Err(SamplingError::Invalid(
                "--window-waves 0 has no period: use 1 to trace every wavefront in windows, N to trace the first, the last and every N-th from the second".into(),
            ));
        }
        for (flag, rays) in [
            ("--window-root-rays", self.root_rays),
            ("--window-bounce-root-rays", self.bounce_root_rays),
        ] {
            if rays < 4 {
                return Err(SamplingError::Invalid(format!(
                    "{flag} {rays}: the root window needs at least 4 rays (a warm-up and a measured stretch); raise it"
                )));
            }
        }
        if self.measure > self.every {
            return Err(SamplingError::Invalid(format!(
                "windows overlap: --window-measure {} admissions every --window-every {}; measure at most every",
                self.measure, self.every
            )));
        }
        if !(self.wave_ray_share.is_finite() && self.wave_ray_share >= 0.0) {
            return Err(SamplingError::Invalid(format!(
                "--window-wave-ray-share {}: give a share of a segment's lines, 0 or more (0: sample every short wavefront of many rays)",
                self.wave_ray_share
            )));
        }
        if self.shade_windows == 0 || self.shade_measure == 0 {
            return Err(SamplingError::Invalid(format!(
                "--shade-windows {} of {} measured items: the shading passes would go unmeasured; use at least one window of one item",
                self.shade_windows, self.shade_measure
            )));
        }
        Ok(())
    }
}

/// The default time-sampling plan (chosen at the paper's size, docs/speed-error.md):
/// wavefronts 0, 1, 3 and the last traced in windows, the others borrowing
/// their neighbours' ratios; in each, the root pass over about 64 K rays (32 K
/// after the first wavefront); the first 16 segment passes; then 64
/// admissions measured after 96 of warm-up (one and a half turnovers of the
/// scene buffer's 64 slots) every 1024; the tail from 8 pending queues; four
/// shading windows of 2048 items after 4096 and at least 16384 cycles, after
/// the first 16384, each at a hashed place in its quarter of the pass. A
/// wavefront too short for windows is traced over a sample of about 64 K of
/// its rays on an eighth of the L2; from the fourth on, one alike the last
/// measured (and after another sampled one) borrows the samples of the third
/// wavefront on instead.
pub fn default_windows() -> WindowPlan {
    WindowPlan {
        head: 16,
        root_rays: 65536,
        bounce_root_rays: 32768,
        wave_rays: 65536,
        wave_l2_share: 8,
        wave_ray_share: 0.15,
        wave_whole: 0,
        warm: 96,
        measure: 64,
        every: 1024,
        shade_windows: 4,
        shade_warm: 4096,
        shade_measure: 2048,
        shade_warm_cycles: 16384,
        shade_head: 16384,
        tail_pending: 8,
        tail_warm: 0,
        wave_every: 2,
    }
}

#[cfg(test)]
mod tests {
    use super::{SegWork, WindowPlan, default_windows};

    /// The sample's ray stream against the scene stream, with the paper
    /// scenes' figures: Sponza's first wavefront (1 M rays, 135 segments of
    /// 55 KB on average, no visits known yet) is sampled, the Dragon's (1984 segments of
    /// 49 KB) is not, nor its later ones (3.9 visits a ray), and a low enough
    /// share takes both.
    #[test]
    fn a_sample_must_stream_rays_more_than_scene() {
        let plan = default_windows();
        let (sponza, dragon) = (55_195.0, 49_251.0);
        assert!(plan.sample_streams_rays(1 << 20, None, 135, sponza));
        assert!(!plan.sample_streams_rays(1 << 20, None, 1984, dragon));
        // The last wavefront: 1 M rays at the root, 3.9 visits a ray.
        let last: Vec<SegWork> = std::iter::once(1 << 20)
            .chain(std::iter::repeat_n(1_552, 1962))
            .map(|rays| SegWork {
                rays,
                ..Default::default()
            })
            .collect();
        assert!(!plan.sample_streams_rays(767_169, Some(&last), 1963, dragon));
        let low = WindowPlan {
            wave_ray_share: 0.01,
            ..plan
        };
        assert!(low.sample_streams_rays(767_169, Some(&last), 1963, dragon));
    }
}
