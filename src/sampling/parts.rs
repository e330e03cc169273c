//! The estimate by part of a time-sampled frame ([`super::estimate`] sums
//! it): per wavefront its root, head, rest and tail (measured, scaled or
//! borrowed), or the whole of one traced over a sample; per pass its shading;
//! the ray generation.

use super::counts::Count::{self, Cycles, SceneLines};
use super::counts::{Counts, seg_proxies, wave_counts, wave_window, window_counts};
use super::{SAMPLE_BORROW_FROM, SampleKind, SegWork, WindowPart, WindowRecord, root_between};
use crate::config::Config;
use crate::sampling::SamplingError;

/// Measured counts and their functional proxies.
type Pair = (Counts, Counts);

/// The trace parts one measured wavefront lends ([`Measured`]): root, head,
/// rest, tail, and the whole of one traced over a sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Part {
    Root,
    Head,
    Rest,
    Tail,
    Wave,
}

impl Part {
    const COUNT: usize = 5;

    /// The part's name in the breakdown ([`WindowPart::part`]).
    fn name(self) -> &'static str {
        match self {
            Part::Root => "root",
            Part::Head => "head",
            Part::Rest => "rest",
            Part::Tail => "tail",
            Part::Wave => "wave",
        }
    }
}

/// A measured wavefront and each of its parts (see [`Measured`]).
struct Lent {
    wave: usize,
    parts: [Pair; Part::COUNT],
}

impl Lent {
    fn part(&self, k: Part) -> &Pair {
        &self.parts[k as usize]
    }
}

/// Per measured wavefront, per trace part, the measured counts and their
/// proxies, for the wavefronts (or root passes) that borrow them, and pooled
/// for a wavefront too short to hold a window.
#[derive(Default)]
struct Measured(Vec<Lent>);

impl Measured {
    /// Adds counts `x` with proxies `px` to part `k` of wavefront `wave`.
    fn add(&mut self, k: Part, wave: usize, x: &Counts, px: &Counts) {
        let m = &mut self.0;
        if m.last().is_none_or(|m| m.wave != wave) {
            m.push(Lent {
                wave,
                parts: Default::default(),
            });
        }
        let m = &mut m.last_mut().expect("pushed").parts[k as usize];
        m.0.add(x, 1.0);
        m.1.add(px, 1.0);
    }

    /// The nearest measured wavefronts before and after `wave` that have part
    /// `k` and pass `ok`.
    fn neighbours(
        &self,
        k: Part,
        wave: usize,
        ok: &dyn Fn(usize) -> bool,
    ) -> (Option<&Lent>, Option<&Lent>) {
        let has = |m: &&Lent| m.part(k).1[Cycles] > 0.0 && ok(m.wave);
        (
            self.0.iter().rev().filter(|m| m.wave < wave).find(has),
            self.0.iter().filter(|m| m.wave > wave).find(has),
        )
    }

    /// Part `k` summed over the measured wavefronts that have it and pass
    /// `ok`: the nearest before and after `wave` (`all`: every one).
    fn nearest(&self, k: Part, wave: usize, all: bool, ok: &dyn Fn(usize) -> bool) -> Option<Pair> {
        let picked: Vec<&Lent> = if all {
            self.0
                .iter()
                .filter(|m| m.part(k).1[Cycles] > 0.0 && ok(m.wave))
                .collect()
        } else {
            let (before, after) = self.neighbours(k, wave, ok);
            before.into_iter().chain(after).collect()
        };
        let (mut x, mut px) = (Counts::default(), Counts::default());
        for m in picked {
            x.add(&m.part(k).0, 1.0);
            px.add(&m.part(k).1, 1.0);
        }
        (px[Cycles] > 0.0).then_some((x, px))
    }
}

/// A wavefront's rest (its passes between head and tail): the passes, their
/// summed proxies, the windows' summed counts and proxies, and each window's.
struct Rest {
    wave: usize,
    passes: std::ops::Range<usize>,
    proxy: Counts,
    x: Counts,
    px: Counts,
    ratios: Vec<Pair>,
}

/// The estimate by part under way: every part adds its counts to `total`
/// in the order [`Parts::of`] takes them.
pub(super) struct Parts<'a> {
    rec: &'a WindowRecord,
    /// DRAM energy of writing one line back (`paper`, `physical`).
    wb_j: [f64; 2],
    /// Per segment pass of each wavefront, each count's functional proxy
    /// (`seg_proxies`).
    proxies: Vec<Vec<Counts>>,
    pub(super) total: Counts,
    pub(super) parts: Vec<WindowPart>,
    measured: Measured,
    per_wave: Vec<Rest>,
    /// Short wavefronts traced over a sample, and the whole and sampled
    /// figures of those simulated both ways.
    sampled: Vec<(usize, Counts)>,
    whole_sum: Counts,
    thin_sum: Counts,
    /// The wavefronts traced in no window, and those whose root pass borrows.
    borrowers: Vec<usize>,
    root_borrowers: Vec<usize>,
    /// The variance of the rests' cycles, lines and DRAM energy, if known.
    pub(super) var: [f64; 3],
    pub(super) se_known: bool,
}

/// A part's row in the breakdown.
fn part(wave: usize, part: &'static str, first: u64, end: u64, t: &Counts) -> WindowPart {
    WindowPart {
        wave,
        part,
        first,
        end,
        cycles: t[Cycles],
        lines: t.lines(),
        dram_j: t[Count::DramPaperJ],
        borrowed: false,
    }
}

/// A borrowed part's row.
fn borrowed(wave: usize, name: &'static str, first: u64, end: u64, t: &Counts) -> WindowPart {
    WindowPart {
        borrowed: true,
        ..part(wave, name, first, end, t)
    }
}

fn sum(r: &[Counts]) -> Counts {
    let mut t = Counts::default();
    for x in r {
        t.add(x, 1.0);
    }
    t
}

/// Each count of a rest (its proxies `rest`) scaled from windows `x` with
/// proxies `px`: each by its own proxy, the cycles' where the windows saw
/// none of it.
fn scale(rest: &Counts, x: &Counts, px: &Counts) -> Counts {
    Counts::from_fn(|i| {
        let j = if px[i] > 0.0 { i } else { Cycles };
        x[i] * rest[j] / px[j]
    })
}

/// Cycles, lines and DRAM energy of a scaled rest: the lines of the hit
/// records and the shading pass only, as the frame's ray and scene streams
/// are the functional model's counts (`estimate`).
fn figs(t: &Counts) -> [f64; 3] {
    [
        t[Cycles],
        t[Count::HitLines] + t[Count::ShadingLines],
        t[Count::DramPaperJ],
    ]
}

impl<'a> Parts<'a> {
    /// Every part of the frame that recorded `rec`, on `c`'s chip; `wb_j`:
    /// the DRAM energy of a line written back.
    pub(super) fn of(
        c: &Config,
        rec: &'a WindowRecord,
        wb_j: [f64; 2],
    ) -> Result<Self, SamplingError> {
        let proxies = rec
            .segs
            .iter()
            .map(|segs| segs.iter().map(|s| seg_proxies(c, s)).collect())
            .collect();
        let mut p = Parts {
            rec,
            wb_j,
            proxies,
            total: Counts::default(),
            parts: Vec::new(),
            measured: Measured::default(),
            per_wave: Vec::new(),
            sampled: Vec::new(),
            whole_sum: Counts::default(),
            thin_sum: Counts::default(),
            borrowers: Vec::new(),
            root_borrowers: Vec::new(),
            var: [0.0; 3],
            se_known: false,
        };
        for (wave, segs) in rec.segs.iter().enumerate() {
            if !rec.measured.get(wave).copied().unwrap_or(true) {
                p.borrowers.push(wave);
                continue;
            }
            p.measured_wave(wave, segs);
        }
        p.sampled_waves();
        p.rests()?;
        for wave in std::mem::take(&mut p.borrowers) {
            p.borrowed_wave(wave)?;
        }
        for wave in std::mem::take(&mut p.root_borrowers) {
            p.borrowed_root(wave)?;
        }
        p.shading();
        p.emission();
        // Wavefront by wavefront, its trace parts in admission order, then its
        // shading pass; the ray generation last.
        p.parts
            .sort_by_key(|p| (p.part == "emit", p.wave, p.part == "shade", p.first));
        Ok(p)
    }

    /// A root pass's cost goes with its rays (a root window is scaled by them):
    /// its proxy for the cycles and the DRAM energy, where the first-order bound
    /// follows the box tests and misjudges the root from one wavefront to the
    /// next (docs/speed-error.md, "Time sampling": borrowed wavefronts).
    fn root_proxy(&self, wave: usize) -> Counts {
        let mut p = self.proxies[wave][0];
        let rays = self.rec.segs[wave][0].rays as f64;
        for k in Count::TIMED {
            p[k] = rays;
        }
        p
    }

    /// A sampled wavefront's counts by the ratio whole / sample of those
    /// simulated both ways (none: as sampled).
    fn correct(&self, t: &Counts) -> Counts {
        Counts::from_fn(|i| {
            if self.thin_sum[i] > 0.0 {
                t[i] * self.whole_sum[i] / self.thin_sum[i]
            } else {
                t[i]
            }
        })
    }

    /// A wavefront traced in windows (or over a sample): its measured parts,
    /// and the rest to scale.
    fn measured_wave(&mut self, wave: usize, segs: &[SegWork]) {
        let rec = self.rec;
        let index: std::collections::HashMap<u32, usize> =
            segs.iter().enumerate().map(|(i, s)| (s.seg, i)).collect();
        // A short wavefront traced over a sample from its root pass to its end
        // (`WindowPlan::wave_rays`): the whole wavefront is one part, once the
        // wavefronts also simulated whole (`WindowPlan::wave_whole`) say how
        // far off such samples are.
        let thin = rec
            .samples
            .iter()
            .find(|s| s.wave == wave && s.kind == SampleKind::Wave)
            .map(|smp| wave_window(smp, segs, &self.proxies[wave], &index, self.wb_j));
        let calibrates = thin.is_some()
            && rec
                .samples
                .iter()
                .any(|s| s.wave == wave && s.kind == SampleKind::Root);
        if let Some(t) = thin
            && !calibrates
        {
            // Lent whole to those that borrow (`SAMPLE_BORROW_FROM`).
            let whole = sum(&self.proxies[wave]);
            self.measured.add(Part::Wave, wave, &t, &whole);
            self.sampled.push((wave, t));
            return;
        }
        // The head: the root pass (its window on one run of rays in k of the
        // queue, see `WindowPlan::root_rays`), then the window from the next
        // segment on, if any (measured whole).
        let mut head = Counts::default();
        let mut head_end = self.root_windows(wave, segs, &mut head);
        if head_end == 0 && !segs.is_empty() {
            // No root window here: the root pass is borrowed, the rest is
            // measured after it all the same.
            self.root_borrowers.push(wave);
            head_end = 1;
        }
        let tail_start = self.tail_windows(wave, segs, head_end);
        let (x, px, ratios) = self.trace_windows(wave, segs, &index, &mut head, &mut head_end);
        self.total.add(&head, 1.0);
        if let Some(t) = thin
            && calibrates
        {
            // Simulated whole after its root window: all of it is the head.
            self.whole_sum.add(&head, 1.0);
            self.thin_sum.add(&t, 1.0);
        }
        let proxy = &self.proxies[wave];
        let rest = sum(&proxy[head_end.min(tail_start)..tail_start]);
        self.per_wave.push(Rest {
            wave,
            passes: head_end.min(tail_start)..tail_start,
            proxy: rest,
            x,
            px,
            ratios,
        });
        self.measured.add(Part::Rest, wave, &x, &px);
    }

    /// The root windows of wavefront `wave`, added to its `head`; the
    /// admission the head goes on from (0: no root window).
    fn root_windows(&mut self, wave: usize, segs: &[SegWork], head: &mut Counts) -> usize {
        let (rec, wb_j) = (self.rec, self.wb_j);
        let mut head_end = 0usize;
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == SampleKind::Root)
        {
            // The window ends with the root pass (or before the children, if
            // it sent no ray on); the rest is measured after it.
            head_end = 1;
            let r = &smp.run;
            if r.marks == 0 {
                continue;
            }
            let plain = |w| wave_counts(w, &[0; crate::mem::StreamTag::COUNT], wb_j);
            let mut root = window_counts(r, wb_j);
            root.add(&plain(&r.warm), 1.0);
            root.add(&plain(&r.after), 1.0);
            // The rays it left out: as many cycles and joules each as in its
            // steady stretch (the DRAM's energy goes with time as well as
            // lines, and with the rows the lines fall in); the rest by the
            // rays (its rays are spread over the queue, the stretch's are
            // not), its segment's lines once.
            let left = smp.first as f64;
            let kept = segs.first().map_or(0, |s| s.rays) as f64 - left;
            let k = left / kept.max(1.0);
            let steady = plain(&r.counts);
            let timed = Count::TIMED.map(|i| root[i] + left * steady[i] / r.marks as f64);
            let scene = root[SceneLines];
            root = root.map(|x| x * (1.0 + k));
            root[SceneLines] -= k * scene;
            for (i, t) in Count::TIMED.into_iter().zip(timed) {
                root[i] = t;
            }
            head.add(&root, 1.0);
            if !segs.is_empty() {
                let p = self.root_proxy(wave);
                self.measured.add(Part::Root, wave, &root, &p);
            }
            self.parts.push(part(wave, Part::Root.name(), 0, 1, &root));
        }
        head_end
    }

    /// The tail of wavefront `wave`, measured to the end, as is; where it
    /// starts (its pass count if it has none).
    fn tail_windows(&mut self, wave: usize, segs: &[SegWork], head_end: usize) -> usize {
        let rec = self.rec;
        let mut tail_start = segs.len();
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == SampleKind::Tail)
        {
            let t = window_counts(&smp.run, self.wb_j);
            self.total.add(&t, 1.0);
            tail_start = (smp.first as usize).clamp(head_end.min(segs.len()), segs.len());
            let p = sum(&self.proxies[wave][tail_start..]);
            self.measured.add(Part::Tail, wave, &t, &p);
            let n = segs.len() as u64;
            self.parts
                .push(part(wave, Part::Tail.name(), tail_start as u64, n, &t));
        }
        tail_start
    }

    /// The trace windows of wavefront `wave`: one right after the root pass
    /// goes to the `head` (and moves `head_end`); the others' summed counts
    /// and proxies, and each one's, to scale the rest by.
    fn trace_windows(
        &mut self,
        wave: usize,
        segs: &[SegWork],
        index: &std::collections::HashMap<u32, usize>,
        head: &mut Counts,
        head_end: &mut usize,
    ) -> (Counts, Counts, Vec<Pair>) {
        let rec = self.rec;
        let (mut x, mut px) = (Counts::default(), Counts::default());
        let mut ratios = Vec::new();
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == SampleKind::Trace)
        {
            let proxy = &self.proxies[wave];
            let a = (smp.first as usize).min(segs.len());
            let b = (a + smp.run.marks as usize).min(segs.len());
            let wc = window_counts(&smp.run, self.wb_j);
            if a == 1 && *head_end == 1 {
                // Right after the root pass, with no warm-up: the head's rest.
                head.add(&wc, 1.0);
                *head_end = b;
                let p = sum(&proxy[a..b]);
                self.measured.add(Part::Head, wave, &wc, &p);
                let name = Part::Head.name();
                self.parts.push(part(wave, name, a as u64, b as u64, &wc));
                continue;
            }
            // The work the stretch did: each segment's proxy by the share of
            // its rays finished in it (passes straddle the stretch's ends, and
            // with 64 in flight the admissions alone are bursty); by the
            // admitted passes where the window did not say.
            let p = if smp.run.done.is_empty() {
                sum(&proxy[a..b])
            } else {
                let mut t = Counts::default();
                for &(sg, d) in &smp.run.done {
                    if let Some(&i) = index.get(&sg)
                        && segs[i].rays > 0
                    {
                        t.add(&proxy[i], d as f64 / segs[i].rays as f64);
                    }
                }
                t
            };
            x.add(&wc, 1.0);
            px.add(&p, 1.0);
            if p[Cycles] > 0.0 {
                ratios.push((wc, p));
            }
        }
        (x, px, ratios)
    }

    /// The short wavefronts traced over a sample, corrected.
    fn sampled_waves(&mut self) {
        for (wave, t) in std::mem::take(&mut self.sampled) {
            let c = self.correct(&t);
            self.total.add(&c, 1.0);
            let n = self.rec.segs[wave].len() as u64;
            self.parts.push(part(wave, Part::Wave.name(), 0, n, &c));
        }
    }

    /// Each measured wavefront's rest, scaled from its windows (pooled over
    /// the frame for a wavefront too short to hold one), and the variance of
    /// the rests from the windows' spread.
    fn rests(&mut self) -> Result<(), SamplingError> {
        let (pool_x, pool_p) = self
            .measured
            .nearest(Part::Rest, 0, true, &|_| true)
            .unwrap_or_default();
        // The spread is the rest windows'; with none (every wavefront simulated
        // whole) there is nothing to spread.
        self.se_known = self.per_wave.iter().any(|w| w.proxy[Cycles] > 0.0);
        for w in &self.per_wave {
            let (rest, x, px) = (&w.proxy, &w.x, &w.px);
            if rest[Cycles] == 0.0 {
                continue;
            }
            let (x, px) = if px[Cycles] > 0.0 {
                (x, px)
            } else {
                (&pool_x, &pool_p)
            };
            if px[Cycles] == 0.0 {
                return Err(SamplingError::Uncovered(
                    "time sampling measured no window after the head; lower --window-every".into(),
                ));
            }
            let r = scale(rest, x, px);
            self.total.add(&r, 1.0);
            let (a, b) = (w.passes.start as u64, w.passes.end as u64);
            self.parts.push(part(w.wave, Part::Rest.name(), a, b, &r));
            // Variance of the rest from the spread of what each window alone would
            // say of it.
            let n = w.ratios.len();
            if n >= 2 {
                let each: Vec<[f64; 3]> = w
                    .ratios
                    .iter()
                    .map(|(w, p)| figs(&scale(rest, w, p)))
                    .collect();
                for k in 0..3 {
                    let m = each.iter().map(|e| e[k]).sum::<f64>() / n as f64;
                    let v = each.iter().map(|e| (e[k] - m).powi(2)).sum::<f64>() / (n - 1) as f64;
                    self.var[k] += v / n as f64;
                }
            } else {
                self.se_known = false;
            }
        }
        Ok(())
    }

    /// A wavefront traced in no window: each part its proxy times the ratio
    /// of the nearest measured wavefronts before and after it among those that
    /// carry both bounce and shadow rays (neither the first nor the last, if
    /// there are such; else any).
    fn borrowed_wave(&mut self, wave: usize) -> Result<(), SamplingError> {
        let rec = self.rec;
        let middle = |v: usize| v > 0 && v < rec.final_wave;
        let segs = &rec.segs[wave];
        let n = segs.len();
        // A wavefront too short for a window is one part after its root, as in
        // its measured neighbours.
        let whole = rec.whole.get(wave).copied().unwrap_or(false);
        // One that borrows after a sampled one (`Run::root_pass` in `frame.rs`): its whole
        // proxy times the ratio of the nearest sampled wavefronts before and
        // after it from `SAMPLE_BORROW_FROM` on (not the last, if there are
        // others), one part, its root pass in it as in theirs.
        let from = SAMPLE_BORROW_FROM;
        let m = &self.measured;
        if whole && m.neighbours(Part::Wave, wave, &|v| v >= from).0.is_some() {
            let (x, px) = m
                .nearest(Part::Wave, wave, false, &|v| {
                    v >= from && v < rec.final_wave
                })
                .or_else(|| m.nearest(Part::Wave, wave, false, &|v| v >= from))
                .expect("a sampled wavefront before it");
            let t = self.correct(&scale(&sum(&self.proxies[wave]), &x, &px));
            self.total.add(&t, 1.0);
            let name = Part::Wave.name();
            self.parts.push(borrowed(wave, name, 0, n as u64, &t));
            return Ok(());
        }
        let head_end = if whole {
            n
        } else {
            (rec.head.max(1) as usize).min(n)
        };
        let tail_start =
            (rec.tail_from.get(wave).copied().unwrap_or(n as u64) as usize).clamp(head_end, n);
        if n > 0 {
            self.root_borrowers.push(wave);
        }
        let ranges = [
            (Part::Head, n.min(1)..head_end),
            (Part::Rest, head_end..tail_start),
            (Part::Tail, tail_start..n),
        ];
        for (k, r) in ranges {
            let p = sum(&self.proxies[wave][r.clone()]);
            if p[Cycles] == 0.0 {
                continue;
            }
            // The measured wavefronts' part, else (never measured: a tail no
            // measured wavefront had, a head of one admission) their rest,
            // else their head (all of a wavefront simulated whole).
            let Some((x, px)) = [k, Part::Rest, Part::Head]
                .into_iter()
                .flat_map(|j| [(j, true), (j, false)])
                .find_map(|(j, mid)| {
                    self.measured
                        .nearest(j, wave, false, if mid { &middle } else { &|_| true })
                })
            else {
                return Err(SamplingError::Uncovered(format!(
                    "time sampling: wavefront {wave} borrows the measured wavefronts' ratios, but none was measured; lower --window-waves"
                )));
            };
            let t = scale(&p, &x, &px);
            self.total.add(&t, 1.0);
            let (a, b) = (r.start as u64, r.end as u64);
            self.parts.push(borrowed(wave, k.name(), a, b, &t));
        }
        Ok(())
    }

    /// A borrowed root pass: by the rays, as the nearest root windows before and
    /// after (a root pass's cost per ray is about the same in every wavefront
    /// after the first whose rays are alike: docs/speed-error.md, "Time
    /// sampling": borrowed wavefronts), the first's only if no other has one.
    /// Between two root windows whose rays differ (an open scene's wavefronts
    /// shrink), the cycles and DRAM energy lie on the line through them: a
    /// smaller root pass costs more per ray (its start-up and drain weigh
    /// more), see [`root_between`].
    fn borrowed_root(&mut self, wave: usize) -> Result<(), SamplingError> {
        let m = &self.measured;
        let (x, px) = m
            .nearest(Part::Root, wave, false, &|v| v > 0)
            .or_else(|| m.nearest(Part::Root, wave, false, &|_| true))
            .ok_or_else(|| {
                SamplingError::Uncovered(format!("time sampling: wavefront {wave} borrows its root pass, but no wavefront took a root window"))
            })?;
        let mut t = scale(&self.root_proxy(wave), &x, &px);
        // Each neighbour's root window: its rays (the proxy's cycles) and counts.
        if let (Some(b), Some(a)) = m.neighbours(Part::Root, wave, &|v| v > 0) {
            let ((bx, bp), (ax, ap)) = (b.part(Part::Root), a.part(Part::Root));
            let rays = self.rec.segs[wave][0].rays as f64;
            if let Some(f) = root_between(rays, bp[Cycles], ap[Cycles]) {
                for i in Count::TIMED {
                    t[i] = bx[i] + f * (ax[i] - bx[i]);
                }
            }
        }
        self.total.add(&t, 1.0);
        self.parts.push(borrowed(wave, Part::Root.name(), 0, 1, &t));
        Ok(())
    }

    /// Shading passes: the head as is, the other items by the windows.
    fn shading(&mut self) {
        let (rec, wb_j) = (self.rec, self.wb_j);
        let passes = rec
            .samples
            .iter()
            .filter(|s| matches!(s.kind, SampleKind::Shade | SampleKind::ShadeHead))
            .map(|s| s.wave)
            .max();
        for wave in 0..passes.map_or(0, |m| m + 1) {
            // The work of the items from `a` on, `n` of them: their shading lines
            // in the functional pass (a path that was done costs the chip its
            // read, an active one its hit records, triangle and material too: in
            // a later bounce of an open scene most pixels are done, and windows
            // over the sky and over the model differ by far more than their
            // items), else the items.
            let lines = rec.shade_lines.get(wave).filter(|l| !l.is_empty());
            let work = |a: u64, n: u64| -> f64 {
                match lines {
                    Some(l) => {
                        let a = (a as usize).min(l.len());
                        let b = a.saturating_add(n as usize).min(l.len());
                        l[a..b].iter().map(|&x| x as f64).sum()
                    }
                    None => n as f64,
                }
            };
            let mut left = work(0, rec.pixels as u64);
            let mut pass = Counts::default();
            for smp in rec
                .samples
                .iter()
                .filter(|s| s.wave == wave && s.kind == SampleKind::ShadeHead)
            {
                pass.add(&window_counts(&smp.run, wb_j), 1.0);
                left -= work(smp.first, smp.run.marks);
            }
            let (mut x, mut n) = (Counts::default(), 0.0);
            for smp in rec
                .samples
                .iter()
                .filter(|s| s.wave == wave && s.kind == SampleKind::Shade)
            {
                x.add(&window_counts(&smp.run, wb_j), 1.0);
                n += work(smp.first, smp.run.marks);
            }
            if n > 0.0 && left > 0.0 {
                pass.add(&x, left / n);
            }
            self.total.add(&pass, 1.0);
            self.parts.push(part(wave, "shade", 0, 0, &pass));
        }
    }

    /// Ray generation: the host emits every primary ray (one per pixel). Its lines
    /// go by `render`'s attribution, as in the cycle frame: the root queue's writes
    /// nowhere, a hit record reset and a path state written per pixel.
    fn emission(&mut self) {
        let rec = self.rec;
        for smp in rec.samples.iter().filter(|s| s.kind == SampleKind::Emit) {
            if smp.run.marks > 0 {
                let k = rec.pixels as f64 / smp.run.marks as f64;
                let mut e = window_counts(&smp.run, self.wb_j).map(|x| x * k);
                e[Count::RayLines] = 0.0;
                e[Count::HitLines] += rec.pixels as f64;
                e[Count::ShadingLines] += rec.pixels as f64;
                self.total.add(&e, 1.0);
                self.parts.push(part(0, "emit", 0, 0, &e));
            }
        }
    }
}
