//! What time sampling scales: a window's counts and each count's functional
//! proxy for a segment pass.

use super::analytic::peak_bytes_per_cycle;
use super::{BORROW_ALIKE, SegWork, WindowSample};
use crate::config::Config;

/// First-order cycles of one segment pass from its functional work: the largest
/// of the bounds `estimate` takes per wavefront. The proxy time sampling scales by.
pub(super) fn seg_proxy(c: &Config, w: &SegWork) -> f64 {
    let line = crate::contract::LINE_BYTES as f64;
    let tms = c.chip.tms as f64;
    let tps = tms * c.tm.tps as f64;
    let k = &c.tm.costs;
    let tp = (k.fetch.cycles + k.init.cycles + k.finish.cycles) as f64 * w.rays as f64
        + k.pop.cycles as f64 * w.pops as f64
        + k.exit.cycles as f64 * w.exits as f64
        + (k.node_fetch.cycles + k.box_issue.cycles + k.node_push.cycles + c.box_pipe.latency)
            as f64
            * w.nodes as f64
        + (k.tri_fetch.cycles + k.tri_issue.cycles + k.tri_result.cycles + c.tri_pipe.latency)
            as f64
            * w.tri_tests as f64;
    [
        (w.scene_lines + w.ray_lines + w.hit_lines) as f64 * line / peak_bytes_per_cycle(c),
        w.ray_lines as f64 / c.chip.scheduler.ray_lines_per_cycle as f64,
        w.scene_lines as f64 / c.chip.scheduler.scene_lines_per_cycle as f64,
        w.nodes as f64 * c.box_pipe.interval as f64 / tms,
        w.tri_tests as f64 * c.tri_pipe.interval as f64 / (tms * c.tm.tri_pipes as f64),
        tp / tps,
    ]
    .into_iter()
    .fold(0.0, f64::max)
}

/// Each of [`window_counts`]' functional proxy for one segment pass: the
/// first-order cycles for the cycles, DRAM energy and the shading actions; the
/// functional model's own lines for each stream; box and triangle tests for the
/// scene-buffer reads (L1 misses); hit-record lines for the L2.
pub(super) fn seg_proxies(c: &Config, w: &SegWork) -> Counts {
    let cyc = seg_proxy(c, w);
    Counts::from_fn(|k| match k {
        Cycles | DramPaperJ | DramPhysicalJ => cyc,
        RayLines => w.ray_lines as f64,
        SceneLines => w.scene_lines as f64,
        HitLines | L2Accesses => w.hit_lines as f64,
        SceneBufferReads => (w.nodes + w.tri_tests) as f64,
        ShadingLines | ShadeLoad | Shade | ShadeEmit | ShadeStore => 0.0,
    })
}

/// What time sampling scales, per window: cycles; lines of the ray, scene, hit and
/// shading streams; DRAM energy (`paper` and `physical` preset); scene-buffer
/// reads, L2 array accesses and the four shading actions (for the on-chip energy).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Count {
    Cycles,
    RayLines,
    SceneLines,
    HitLines,
    ShadingLines,
    DramPaperJ,
    SceneBufferReads,
    L2Accesses,
    ShadeLoad,
    Shade,
    ShadeEmit,
    ShadeStore,
    DramPhysicalJ,
}

use Count::*;

impl Count {
    pub(super) const COUNT: usize = 13;
    /// Every kind, in the order sums over all of them take.
    pub(super) const ALL: [Count; Count::COUNT] = [
        Cycles,
        RayLines,
        SceneLines,
        HitLines,
        ShadingLines,
        DramPaperJ,
        SceneBufferReads,
        L2Accesses,
        ShadeLoad,
        Shade,
        ShadeEmit,
        ShadeStore,
        DramPhysicalJ,
    ];
    /// The counts that go with time: the cycles and the DRAM energy (`paper`,
    /// `physical`), which goes with time as well as lines, so it shares the
    /// cycles' proxies.
    pub(super) const TIMED: [Count; 3] = [Cycles, DramPaperJ, DramPhysicalJ];

    fn timed(self) -> bool {
        Count::TIMED.contains(&self)
    }
}

/// One value of each [`Count`] kind, indexed by the kind.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct Counts([f64; Count::COUNT]);

impl std::ops::Index<Count> for Counts {
    type Output = f64;
    fn index(&self, k: Count) -> &f64 {
        &self.0[k as usize]
    }
}

impl std::ops::IndexMut<Count> for Counts {
    fn index_mut(&mut self, k: Count) -> &mut f64 {
        &mut self.0[k as usize]
    }
}

impl Counts {
    /// Each kind's value `f(kind)`.
    pub(super) fn from_fn(mut f: impl FnMut(Count) -> f64) -> Counts {
        Counts(Count::ALL.map(&mut f))
    }

    /// Each value `f(value)`.
    pub(super) fn map(self, f: impl FnMut(f64) -> f64) -> Counts {
        Counts(self.0.map(f))
    }

    /// `self += k x`, kind by kind.
    pub(super) fn add(&mut self, x: &Counts, k: f64) {
        for i in Count::ALL {
            self[i] += x[i] * k;
        }
    }

    /// The lines of every stream.
    pub(super) fn lines(&self) -> f64 {
        self[RayLines] + self[SceneLines] + self[HitLines] + self[ShadingLines]
    }
}

/// A window's counts; the writebacks it owes (`WindowRun::dirtied`) are added to
/// their stream's lines and charged `wb_j` each.
pub(super) fn window_counts(r: &crate::machine::WindowRun, wb_j: [f64; 2]) -> Counts {
    wave_counts(&r.counts, &r.dirtied, wb_j)
}

/// [`window_counts`] of counts `w` owing the writebacks `dirtied`.
pub(super) fn wave_counts(
    w: &crate::machine::WaveCycles,
    dirtied: &[i64; crate::mem::StreamTag::COUNT],
    wb_j: [f64; 2],
) -> Counts {
    use crate::mem::StreamTag as T;
    let l = |t: T| {
        (w.lines_read[t as usize] + w.lines_written[t as usize]) as f64 + dirtied[t as usize] as f64
    };
    let owed: i64 = dirtied.iter().sum();
    let u = &w.shade_uses;
    Counts::from_fn(|k| match k {
        Cycles => w.cycles as f64,
        RayLines => l(T::Ray),
        SceneLines => l(T::Scene),
        HitLines => l(T::Hit),
        ShadingLines => l(T::Shading),
        DramPaperJ => w.dram.energy_paper_j + owed as f64 * wb_j[0],
        SceneBufferReads => w.scene_buffer_reads as f64,
        L2Accesses => w.l2.array_accesses() as f64,
        ShadeLoad => u.shade_load as f64,
        Shade => u.shade as f64,
        ShadeEmit => u.shade_emit as f64,
        ShadeStore => u.shade_store as f64,
        DramPhysicalJ => w.dram.energy_physical_j + owed as f64 * wb_j[1],
    })
}

/// Where a borrowed root pass of `rays` lies between the root windows of the
/// nearest measured wavefronts before and after it (`before` and `after` rays):
/// the fraction of the way from the one to the other, if it lies between them
/// (no extrapolation) and its rays are alike neither's (within
/// [`BORROW_ALIKE`]: a pass alike a window costs what it does per ray,
/// so it takes their ratio, as in the Dragon Box's bounce wavefronts). Its
/// cycles and DRAM energy are then interpolated on the line through the two:
/// a smaller root pass costs more per ray, as its start-up and drain weigh
/// more, and the line follows that where one neighbour's ratio does not
/// (docs/results/2026-11-26-speed-error-root-passes-on-a-line.md).
pub fn root_between(rays: f64, before: f64, after: f64) -> Option<f64> {
    let (lo, hi) = (before.min(after), before.max(after));
    let alike = |m: f64| (rays - m).abs() <= BORROW_ALIKE * m;
    ((lo..=hi).contains(&rays) && !alike(before) && !alike(after))
        .then(|| (rays - before) / (after - before))
}

/// A short wavefront's estimate from its [`SampleKind::Wave`] window,
/// which traced one run of rays in k of its root queue to the wavefront's end.
/// The visits (rays finished in a segment) it left out cost the cycles and the
/// DRAM energy (which goes with time and rows as well as lines) per visit of
/// its steady stretch: its start-up and drain are the wavefront's once. Its
/// other counts are scaled by the functional work: the wavefront's over that of
/// the visits the window made (each pass's proxy by its share of rays done),
/// but the scene lines by the passes (a pass loads its segment however few
/// rays it has), and the writebacks it owes once (the L2 holds as many at the
/// wavefront's end).
pub(super) fn wave_window(
    smp: &WindowSample,
    segs: &[SegWork],
    proxy: &[Counts],
    index: &std::collections::HashMap<u32, usize>,
    wb_j: [f64; 2],
) -> Counts {
    let r = &smp.run;
    let none = [0; crate::mem::StreamTag::COUNT];
    let plain = |w| wave_counts(w, &none, wb_j);
    let mut t = plain(&r.counts);
    t.add(&plain(&r.warm), 1.0);
    t.add(&plain(&r.after), 1.0);
    let owed = wave_counts(&Default::default(), &r.dirtied, wb_j);
    let steady = plain(&r.counts);
    let visits: u64 = r.done.iter().map(|d| d.1).sum();
    let all: u64 = segs.iter().map(|s| s.rays).sum();
    let left = all.saturating_sub(visits) as f64;
    let (mut full, mut did) = (Counts::default(), Counts::default());
    for p in proxy {
        full.add(p, 1.0);
    }
    for &(sg, d) in &r.done {
        if let Some(&i) = index.get(&sg)
            && segs[i].rays > 0
        {
            let share = d as f64 / segs[i].rays as f64;
            did.add(&proxy[i], share);
            did[SceneLines] += proxy[i][SceneLines] * (1.0 - share);
        }
    }
    Counts::from_fn(|i| {
        if i.timed() {
            let rate = if r.marks > 0 {
                steady[i] / r.marks as f64
            } else {
                0.0
            };
            t[i] + left * rate + owed[i]
        } else {
            let j = if did[i] > 0.0 { i } else { Cycles };
            let k = if did[j] > 0.0 { full[j] / did[j] } else { 1.0 };
            t[i] * k + owed[i]
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Counts::from_fn` walks `Count::ALL`; each kind must land at its own
    /// index, or a sum over all kinds would mix them up.
    #[test]
    fn every_count_kind_is_at_its_own_index() {
        for (i, k) in Count::ALL.into_iter().enumerate() {
            assert_eq!(k as usize, i, "{k:?}");
        }
        let c = Counts::from_fn(|k| 1.0 + k as usize as f64);
        let mut t = Counts::default();
        t.add(&c, 2.0);
        for k in Count::ALL {
            assert_eq!(t[k], 2.0 * (1.0 + k as usize as f64), "{k:?}");
        }
        assert_eq!(c.lines(), 2.0 + 3.0 + 4.0 + 5.0);
    }
}
