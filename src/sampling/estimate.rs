//! Time sampling's estimate of a frame's chip figures from its windows and
//! the functional model's counts.

use serde::Serialize;

use super::analytic::{combine, line_write_j};
use super::counts::{DRAM_J, WCOUNTS, add, seg_proxies, wave_counts, wave_window, window_counts};
use super::{
    KindTime, SAMPLE_BORROW_FROM, SampleKind, WindowPlan, WindowRecord, render_cfg, render_windows,
    root_between,
};
use crate::config::Config;
use crate::machine::config::MemoryModel;
use crate::render::{self, Frame, RenderCfg};
use crate::rtl::Threads;
use crate::scene::Scene;

/// One part of a time-sampled frame as [`windowed_parts`] estimated it: per
/// wavefront the `root` pass, the `head` (the admissions after it simulated
/// whole), the scaled `rest`, the `tail`; per pass `shade`; `emit` (ray
/// generation). `first..end`: admission ordinals of a trace part (the root is
/// 0..1), else 0..0.
#[derive(Clone, Debug, Serialize)]
pub struct WindowPart {
    pub wave: usize,
    pub part: &'static str,
    pub first: u64,
    pub end: u64,
    pub cycles: f64,
    pub lines: f64,
    pub dram_j: f64,
    /// Not simulated: the part's proxy times the measured wavefronts' ratio
    /// (`WindowPlan::wave_every`).
    pub borrowed: bool,
}

/// A wavefront's rest (its passes between head and tail): the passes, their
/// summed proxies, the windows' summed counts and proxies, and each window's.
struct Rest {
    wave: usize,
    passes: std::ops::Range<usize>,
    proxy: [f64; WCOUNTS],
    x: [f64; WCOUNTS],
    px: [f64; WCOUNTS],
    ratios: Vec<([f64; WCOUNTS], [f64; WCOUNTS])>,
}

/// A time-sampled frame's estimate (with its relative standard error of cycles,
/// lines and energy, if known) and the estimate by part of the frame.
struct Windowed {
    breakdown: Vec<WindowPart>,
    estimate: WindowEstimate,
}

/// The time-sampled frame's parts (as `speed_error`'s) from the functional
/// frame `f` rendered with windows, which recorded `rec`. Per wavefront, the trace is its head (the root window
/// scaled by its rays, then the passes up to `head` simulated as is), its tail
/// (simulated as is) and between them the rest, scaled from the measured windows
/// by the proxy (`seg_proxy`) of the rest over that of the work the windows did
/// (rays finished by segment); each shading pass is its head as is and its
/// windows scaled by the items left over the measured items. Also the relative standard
/// error of the rest's cycles, lines and DRAM energy from the windows' spread
/// (`None` where a wavefront had fewer than two windows).
fn windowed_parts(c: &Config, f: &Frame, rec: &WindowRecord) -> Result<Windowed, String> {
    let wb_j = line_write_j(c)?;
    let mut total = [0.0; WCOUNTS];
    // Per measured wavefront, per trace part (root, head, rest, tail, and the
    // whole of one traced over a sample), the measured counts and their
    // proxies, for the wavefronts (or root passes) that borrow them, and pooled
    // for a wavefront too short to hold a window.
    type Pair = ([f64; WCOUNTS], [f64; WCOUNTS]);
    let mut measured: Vec<(usize, [Pair; 5])> = Vec::new();
    let mut pool_part = |k: usize, wave: usize, x: &[f64; WCOUNTS], px: &[f64; WCOUNTS]| {
        if measured.last().is_none_or(|m| m.0 != wave) {
            measured.push((wave, [([0.0; WCOUNTS], [0.0; WCOUNTS]); 5]));
        }
        let m = &mut measured.last_mut().expect("pushed").1[k];
        add(&mut m.0, x, 1.0);
        add(&mut m.1, px, 1.0);
    };
    let mut parts = Vec::new();
    let part = |wave, part, first, end, t: &[f64; WCOUNTS]| WindowPart {
        wave,
        part,
        first,
        end,
        cycles: t[0],
        lines: t[1] + t[2] + t[3] + t[4],
        dram_j: t[5],
        borrowed: false,
    };
    let sum = |r: &[[f64; WCOUNTS]]| {
        let mut t = [0.0; WCOUNTS];
        for x in r {
            add(&mut t, x, 1.0);
        }
        t
    };
    // Per segment pass of each wavefront, each count's functional proxy
    // (`seg_proxies`).
    let proxies: Vec<Vec<[f64; WCOUNTS]>> = rec
        .segs
        .iter()
        .map(|segs| segs.iter().map(|s| seg_proxies(c, s)).collect())
        .collect();
    // A root pass's cost goes with its rays (a root window is scaled by them):
    // its proxy for the cycles and the DRAM energy, where the first-order bound
    // follows the box tests and misjudges the root from one wavefront to the
    // next (Dragon Box 256x256: 1.35-1.43 cycles per ray in every bounce
    // wavefront, the bound's ratio off by up to 20%).
    let root_proxy = |wave: usize| {
        let mut p = proxies[wave][0];
        let rays = rec.segs[wave][0].rays as f64;
        p[0] = rays;
        for j in DRAM_J {
            p[j] = rays;
        }
        p
    };
    let mut per_wave = Vec::new();
    // Short wavefronts traced over a sample, and the whole and sampled
    // figures of those simulated both ways.
    let mut sampled: Vec<(usize, [f64; WCOUNTS])> = Vec::new();
    let (mut whole_sum, mut thin_sum) = ([0.0; WCOUNTS], [0.0; WCOUNTS]);
    let mut borrowers = Vec::new();
    // The wavefronts whose root pass borrows.
    let mut root_borrowers = Vec::new();
    for (wave, segs) in rec.segs.iter().enumerate() {
        if !rec.measured.get(wave).copied().unwrap_or(true) {
            borrowers.push(wave);
            continue;
        }
        let proxy = &proxies[wave];
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
            .map(|smp| wave_window(smp, segs, proxy, &index, wb_j));
        let calibrates = thin.is_some()
            && rec
                .samples
                .iter()
                .any(|s| s.wave == wave && s.kind == SampleKind::Root);
        if let Some(t) = thin
            && !calibrates
        {
            // Lent whole to those that borrow (`SAMPLE_BORROW_FROM`).
            pool_part(4, wave, &t, &sum(proxy));
            sampled.push((wave, t));
            continue;
        }
        // The head: the root pass (its window on one run of rays in k of the
        // queue, see `WindowPlan::root_rays`), then the window from the next
        // segment on, if any (measured whole).
        let mut head = [0.0; WCOUNTS];
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
            add(&mut root, &plain(&r.warm), 1.0);
            add(&mut root, &plain(&r.after), 1.0);
            // The rays it left out: as many cycles and joules each as in its
            // steady stretch (the DRAM's energy goes with time as well as
            // lines, and with the rows the lines fall in); the rest by the
            // rays (its rays are spread over the queue, the stretch's are
            // not), its segment's lines once.
            let left = smp.first as f64;
            let kept = segs.first().map_or(0, |s| s.rays) as f64 - left;
            let k = left / kept.max(1.0);
            let steady = plain(&r.counts);
            let timed =
                [0, DRAM_J[0], DRAM_J[1]].map(|i| root[i] + left * steady[i] / r.marks as f64);
            let scene = root[2];
            for x in root.iter_mut() {
                *x *= 1.0 + k;
            }
            root[2] -= k * scene;
            (root[0], root[DRAM_J[0]], root[DRAM_J[1]]) = (timed[0], timed[1], timed[2]);
            add(&mut head, &root, 1.0);
            if !segs.is_empty() {
                pool_part(0, wave, &root, &root_proxy(wave));
            }
            parts.push(part(wave, "root", 0, 1, &root));
        }
        if head_end == 0 && !segs.is_empty() {
            // No root window here: the root pass is borrowed, the rest is
            // measured after it all the same.
            root_borrowers.push(wave);
            head_end = 1;
        }
        // The tail, measured to the end, as is.
        let mut tail_start = segs.len();
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == SampleKind::Tail)
        {
            let t = window_counts(&smp.run, wb_j);
            add(&mut total, &t, 1.0);
            tail_start = (smp.first as usize).clamp(head_end.min(segs.len()), segs.len());
            pool_part(3, wave, &t, &sum(&proxy[tail_start..]));
            parts.push(part(wave, "tail", tail_start as u64, segs.len() as u64, &t));
        }
        let (mut x, mut px) = ([0.0; WCOUNTS], [0.0; WCOUNTS]);
        let mut ratios = Vec::new();
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == SampleKind::Trace)
        {
            let a = (smp.first as usize).min(segs.len());
            let b = (a + smp.run.marks as usize).min(segs.len());
            let wc = window_counts(&smp.run, wb_j);
            if a == 1 && head_end == 1 {
                // Right after the root pass, with no warm-up: the head's rest.
                add(&mut head, &wc, 1.0);
                head_end = b;
                pool_part(1, wave, &wc, &sum(&proxy[a..b]));
                parts.push(part(wave, "head", a as u64, b as u64, &wc));
                continue;
            }
            // The work the stretch did: each segment's proxy by the share of
            // its rays finished in it (passes straddle the stretch's ends, and
            // with 64 in flight the admissions alone are bursty); by the
            // admitted passes where the window did not say.
            let p = if smp.run.done.is_empty() {
                sum(&proxy[a..b])
            } else {
                let mut t = [0.0; WCOUNTS];
                for &(sg, d) in &smp.run.done {
                    if let Some(&i) = index.get(&sg)
                        && segs[i].rays > 0
                    {
                        add(&mut t, &proxy[i], d as f64 / segs[i].rays as f64);
                    }
                }
                t
            };
            add(&mut x, &wc, 1.0);
            add(&mut px, &p, 1.0);
            if p[0] > 0.0 {
                ratios.push((wc, p));
            }
        }
        add(&mut total, &head, 1.0);
        if let Some(t) = thin
            && calibrates
        {
            // Simulated whole after its root window: all of it is the head.
            add(&mut whole_sum, &head, 1.0);
            add(&mut thin_sum, &t, 1.0);
        }
        let rest = sum(&proxy[head_end.min(tail_start)..tail_start]);
        per_wave.push(Rest {
            wave,
            passes: head_end.min(tail_start)..tail_start,
            proxy: rest,
            x,
            px,
            ratios,
        });
        pool_part(2, wave, &x, &px);
    }
    // A sampled wavefront's counts by the ratio whole / sample of those
    // simulated both ways (none: as sampled).
    let correct = |t: &[f64; WCOUNTS]| -> [f64; WCOUNTS] {
        std::array::from_fn(|i| {
            if thin_sum[i] > 0.0 {
                t[i] * whole_sum[i] / thin_sum[i]
            } else {
                t[i]
            }
        })
    };
    for (wave, t) in &sampled {
        let c = correct(t);
        add(&mut total, &c, 1.0);
        parts.push(part(*wave, "wave", 0, rec.segs[*wave].len() as u64, &c));
    }
    // Part `k` summed over the measured wavefronts that have it and pass `ok`:
    // the nearest before and after `wave` (`all`: every one).
    // The nearest measured wavefronts before and after `wave` that have part `k`
    // and pass `ok`.
    let neighbours = |k: usize, wave: usize, ok: &dyn Fn(usize) -> bool| {
        let has = |m: &&(usize, [Pair; 5])| m.1[k].1[0] > 0.0 && ok(m.0);
        (
            measured.iter().rev().filter(|m| m.0 < wave).find(has),
            measured.iter().filter(|m| m.0 > wave).find(has),
        )
    };
    let nearest = |k: usize, wave: usize, all: bool, ok: &dyn Fn(usize) -> bool| {
        let picked: Vec<&(usize, [Pair; 5])> = if all {
            measured
                .iter()
                .filter(|m| m.1[k].1[0] > 0.0 && ok(m.0))
                .collect()
        } else {
            let (before, after) = neighbours(k, wave, ok);
            before.into_iter().chain(after).collect()
        };
        let (mut x, mut px) = ([0.0; WCOUNTS], [0.0; WCOUNTS]);
        for m in picked {
            add(&mut x, &m.1[k].0, 1.0);
            add(&mut px, &m.1[k].1, 1.0);
        }
        (px[0] > 0.0).then_some((x, px))
    };
    // Pooled over the frame, for a wavefront too short to hold a window.
    let (pool_x, pool_p) = nearest(2, 0, true, &|_| true).unwrap_or_default();
    // Each count of the rest scaled from windows `x` with proxies `px`: each by
    // its own proxy, the cycles' where the windows saw none of it.
    let scale = |rest: &[f64; WCOUNTS], x: &[f64; WCOUNTS], px: &[f64; WCOUNTS]| {
        std::array::from_fn::<f64, WCOUNTS, _>(|i| {
            let j = if px[i] > 0.0 { i } else { 0 };
            x[i] * rest[j] / px[j]
        })
    };
    // Cycles, lines and DRAM energy of a scaled rest: the lines of the hit
    // records and the shading pass only, as the frame's ray and scene streams
    // are the functional model's counts (below).
    let figs = |t: &[f64; WCOUNTS]| [t[0], t[3] + t[4], t[5]];
    let mut var = [0.0; 3];
    // The spread is the rest windows'; with none (every wavefront simulated
    // whole) there is nothing to spread.
    let mut se_known = per_wave.iter().any(|w| w.proxy[0] > 0.0);
    for w in &per_wave {
        let (rest, x, px) = (&w.proxy, &w.x, &w.px);
        if rest[0] == 0.0 {
            continue;
        }
        let (x, px) = if px[0] > 0.0 {
            (x, px)
        } else {
            (&pool_x, &pool_p)
        };
        if px[0] == 0.0 {
            return Err(
                "time sampling measured no window after the head; lower --window-every".into(),
            );
        }
        let r = scale(rest, x, px);
        add(&mut total, &r, 1.0);
        let (a, b) = (w.passes.start as u64, w.passes.end as u64);
        parts.push(part(w.wave, "rest", a, b, &r));
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
                var[k] += v / n as f64;
            }
        } else {
            se_known = false;
        }
    }
    // The wavefronts traced in no window: each part its proxy times the ratio
    // of the nearest measured wavefronts before and after it among those that
    // carry both bounce and shadow rays (neither the first nor the last, if
    // there are such; else any).
    for &wave in &borrowers {
        let middle = |v: usize| v > 0 && v < rec.final_wave;
        let (segs, proxy) = (&rec.segs[wave], &proxies[wave]);
        let n = segs.len();
        // A wavefront too short for a window is one part after its root, as in
        // its measured neighbours.
        let whole = rec.whole.get(wave).copied().unwrap_or(false);
        // One that borrows after a sampled one (`Run::root_pass` in `frame.rs`): its whole
        // proxy times the ratio of the nearest sampled wavefronts before and
        // after it from `SAMPLE_BORROW_FROM` on (not the last, if there are
        // others), one part, its root pass in it as in theirs.
        let from = SAMPLE_BORROW_FROM;
        if whole && neighbours(4, wave, &|v| v >= from).0.is_some() {
            let (x, px) = nearest(4, wave, false, &|v| v >= from && v < rec.final_wave)
                .or_else(|| nearest(4, wave, false, &|v| v >= from))
                .expect("a sampled wavefront before it");
            let t = correct(&scale(&sum(proxy), &x, &px));
            add(&mut total, &t, 1.0);
            parts.push(WindowPart {
                borrowed: true,
                ..part(wave, "wave", 0, n as u64, &t)
            });
            continue;
        }
        let head_end = if whole {
            n
        } else {
            (rec.head.max(1) as usize).min(n)
        };
        let tail_start =
            (rec.tail_from.get(wave).copied().unwrap_or(n as u64) as usize).clamp(head_end, n);
        if n > 0 {
            root_borrowers.push(wave);
        }
        let ranges = [
            (1, "head", n.min(1)..head_end),
            (2, "rest", head_end..tail_start),
            (3, "tail", tail_start..n),
        ];
        for (k, name, r) in ranges {
            let p = sum(&proxy[r.clone()]);
            if p[0] == 0.0 {
                continue;
            }
            // The measured wavefronts' part, else (never measured: a tail no
            // measured wavefront had, a head of one admission) their rest,
            // else their head (all of a wavefront simulated whole).
            let Some((x, px)) = [k, 2, 1]
                .into_iter()
                .flat_map(|j| [(j, true), (j, false)])
                .find_map(|(j, mid)| {
                    nearest(j, wave, false, if mid { &middle } else { &|_| true })
                })
            else {
                return Err(format!(
                    "time sampling: wavefront {wave} borrows the measured wavefronts' ratios, but none was measured; lower --window-waves"
                ));
            };
            let t = scale(&p, &x, &px);
            add(&mut total, &t, 1.0);
            parts.push(WindowPart {
                borrowed: true,
                ..part(wave, name, r.start as u64, r.end as u64, &t)
            });
        }
    }
    // Borrowed root passes: by the rays, as the nearest root windows before and
    // after (a root pass's cost per ray is about the same in every wavefront
    // after the first whose rays are alike: 1.30-1.39 cycles per ray at the
    // paper's size in the Dragon Box), the first's only if no other has one.
    // Between two root windows whose rays differ (an open scene's wavefronts
    // shrink), the cycles and DRAM energy lie on the line through them: a
    // smaller root pass costs more per ray (its start-up and drain weigh
    // more), see [`root_between`].
    for &wave in &root_borrowers {
        let (x, px) = nearest(0, wave, false, &|v| v > 0)
            .or_else(|| nearest(0, wave, false, &|_| true))
            .ok_or_else(|| {
                format!("time sampling: wavefront {wave} borrows its root pass, but no wavefront took a root window")
            })?;
        let mut t = scale(&root_proxy(wave), &x, &px);
        // Each neighbour's root window: its rays (the proxy's cycles) and counts.
        if let (Some(b), Some(a)) = neighbours(0, wave, &|v| v > 0) {
            let ((bx, bp), (ax, ap)) = (&b.1[0], &a.1[0]);
            let rays = rec.segs[wave][0].rays as f64;
            if let Some(f) = root_between(rays, bp[0], ap[0]) {
                for i in [0, DRAM_J[0], DRAM_J[1]] {
                    t[i] = bx[i] + f * (ax[i] - bx[i]);
                }
            }
        }
        add(&mut total, &t, 1.0);
        parts.push(WindowPart {
            borrowed: true,
            ..part(wave, "root", 0, 1, &t)
        });
    }
    // Shading passes: the head as is, the other items by the windows.
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
        let mut pass = [0.0; WCOUNTS];
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == SampleKind::ShadeHead)
        {
            add(&mut pass, &window_counts(&smp.run, wb_j), 1.0);
            left -= work(smp.first, smp.run.marks);
        }
        let (mut x, mut n) = ([0.0; WCOUNTS], 0.0);
        for smp in rec
            .samples
            .iter()
            .filter(|s| s.wave == wave && s.kind == SampleKind::Shade)
        {
            add(&mut x, &window_counts(&smp.run, wb_j), 1.0);
            n += work(smp.first, smp.run.marks);
        }
        if n > 0.0 && left > 0.0 {
            add(&mut pass, &x, left / n);
        }
        add(&mut total, &pass, 1.0);
        parts.push(part(wave, "shade", 0, 0, &pass));
    }
    // Ray generation: the host emits every primary ray (one per pixel). Its lines
    // go by `render`'s attribution, as in the cycle frame: the root queue's writes
    // nowhere, a hit record reset and a path state written per pixel.
    for smp in rec.samples.iter().filter(|s| s.kind == SampleKind::Emit) {
        if smp.run.marks > 0 {
            let k = rec.pixels as f64 / smp.run.marks as f64;
            let mut e = window_counts(&smp.run, wb_j).map(|x| x * k);
            e[1] = 0.0;
            e[3] += rec.pixels as f64;
            e[4] += rec.pixels as f64;
            add(&mut total, &e, 1.0);
            parts.push(part(0, "emit", 0, 0, &e));
        }
    }
    // Wavefront by wavefront, its trace parts in admission order, then its
    // shading pass; the ray generation last.
    parts.sort_by_key(|p| (p.part == "emit", p.wave, p.part == "shade", p.first));
    // The ray and scene streams: the chip moves exactly the functional model's
    // lines (the same buckets written and read, the same segments loaded, in
    // any timing: `tests/chip.rs` checks every wavefront's counts), so they are
    // taken from it rather than estimated. The hit records and the shading
    // pass go through the L2, whose filtering the windows measure.
    total[1] = f.total.ray_lines() as f64;
    total[2] = f.total.scene_lines as f64;
    // On-chip energy: the functional frame's traversal with the estimated global
    // units' activity, as a cycle frame would have it.
    let mut g = f.clone();
    let mut w = crate::machine::WaveCycles {
        scene_buffer_reads: total[6].round() as u64,
        shade_uses: std::array::from_fn(|k| total[8 + k].round() as u64),
        ..Default::default()
    };
    w.l2.accesses = total[7].round() as u64;
    g.chip = Some(render::ChipFrame {
        shading_on_tps: true,
        tms: c.chip.tms,
        tps_per_tm: c.tm.tps,
        waves: vec![w],
        total_cycles: total[0].round() as u64,
        sim_wall_s: 0.0,
        cycles_per_s: 0.0,
        memory_model: "gddr5".into(),
        core_ps: c.clocks.core_ps,
        line_bytes: crate::contract::LINE_BYTES,
        dram: None,
        vcd: None,
        evals_by_module: Vec::new(),
        sim_steps_by_lanes: Vec::new(),
    });
    let e = crate::energy::frame_energy(c, &g);
    let p = [
        total[0],
        total[1],
        total[2],
        total[3],
        total[4],
        e.compute_j + e.onchip_j,
        total[5],
    ];
    let f3 = combine(&p);
    let se = se_known.then(|| std::array::from_fn(|k| var[k].sqrt() / f3[k].max(1e-30)));
    Ok(Windowed {
        breakdown: parts,
        estimate: WindowEstimate {
            cycles: total[0],
            ray_lines: total[1],
            scene_lines: total[2],
            hit_lines: total[3],
            shading_lines: total[4],
            dram_paper_j: total[DRAM_J[0]],
            dram_physical_j: total[DRAM_J[1]],
            onchip_j: e.onchip_j,
            compute_j: e.compute_j,
            rel_se: se,
            windows: rec.samples.len(),
            chip_s: rec.chip_s,
            chip_s_by_kind: rec.chip_s_by_kind(),
            core_ps: c.clocks.core_ps,
            rays: f.total.rays,
        },
    })
}

/// A frame's chip figures as time sampling estimates them (the `windows` mode):
/// what the chip with GDDR5 would report for the frame, from its windows and the
/// functional model's counts. Its error against the cycle model on the paper
/// scenes is measured in `docs/speed-error.md`; `rel_se` is its own estimate.
#[derive(Clone, Debug, Default, Serialize)]
pub struct WindowEstimate {
    pub cycles: f64,
    /// DRAM lines of each stream: rays, scene, hit records, shading.
    pub ray_lines: f64,
    pub scene_lines: f64,
    pub hit_lines: f64,
    pub shading_lines: f64,
    /// DRAM energy, `paper` and `physical` preset.
    pub dram_paper_j: f64,
    pub dram_physical_j: f64,
    /// On-chip memory and compute energy with the estimated global units' activity.
    pub onchip_j: f64,
    pub compute_j: f64,
    /// One relative standard error of the cycles, lines and energy from the
    /// windows' spread (`None` with fewer than two windows per wavefront).
    pub rel_se: Option<[f64; 3]>,
    /// Windows simulated, and their summed wall time, in all and by kind.
    pub windows: usize,
    pub chip_s: f64,
    pub chip_s_by_kind: Vec<KindTime>,
    /// Core clock period (ps), and the rays the frame traced.
    pub core_ps: u64,
    pub rays: u64,
}

impl WindowEstimate {
    /// DRAM lines of every stream.
    pub fn lines(&self) -> f64 {
        self.ray_lines + self.scene_lines + self.hit_lines + self.shading_lines
    }
    /// Render time (ms) at the core clock.
    pub fn time_ms(&self) -> f64 {
        self.cycles * self.core_ps as f64 * 1e-9
    }
    /// Rays traced per second (millions) at that time.
    pub fn mrays_per_s(&self) -> f64 {
        self.rays as f64 / (self.time_ms() * 1e-3).max(1e-30) / 1e6
    }
    /// The windows' own standard error as text, where they have one.
    pub fn se_text(&self) -> Option<String> {
        self.rel_se.map(|[c, l, j]| {
            format!(
                "own standard error (windows' spread): cycles {:.1}%, lines {:.1}%, energy {:.1}%",
                100.0 * c,
                100.0 * l,
                100.0 * j
            )
        })
    }
    /// Average DRAM bandwidth (GB/s) over that time.
    pub fn bandwidth_gbs(&self) -> f64 {
        self.lines() * crate::contract::LINE_BYTES as f64 / (self.time_ms() * 1e-3).max(1e-30) / 1e9
    }
}

/// A frame rendered by the functional model with time sampling's windows on the
/// chip with GDDR5: the frame (its image is the cycle model's), the estimate of
/// the cycle model's figures, and the estimate by part.
pub struct TimeSampled {
    pub frame: Frame,
    pub estimate: WindowEstimate,
    pub parts: Vec<WindowPart>,
    /// What the windows recorded.
    pub record: WindowRecord,
}

/// Renders `scene` with time sampling (`plan`) on `threads` simulator threads
/// (above one: that many windows side by side), with `config`'s chip on GDDR5.
pub fn time_sampled(
    scene: &Scene,
    config: &Config,
    threads: impl Into<Threads>,
    plan: &WindowPlan,
) -> Result<TimeSampled, String> {
    time_sampled_with(
        scene,
        config,
        render_cfg(config, None, threads.into()),
        plan,
    )
}

/// [`time_sampled`] with the rest of the render's settings from `rc` (its
/// checks, its ray dumps, its chip's simulator options); its chip is
/// `config`'s on GDDR5 and its windows `plan`'s.
pub fn time_sampled_with(
    scene: &Scene,
    config: &Config,
    mut rc: RenderCfg,
    plan: &WindowPlan,
) -> Result<TimeSampled, String> {
    plan.validate()?;
    let mut gddr5 = config.clone();
    gddr5.chip.memory.model = MemoryModel::Gddr5;
    match rc.chip.as_mut() {
        Some(ch) => ch.config = gddr5.clone(),
        None => rc.chip = render_cfg(&gddr5, None, Threads::fixed(1)).chip,
    }
    let (frame, record) = render_windows(scene, &rc, plan)?;
    let w = windowed_parts(&gddr5, &frame, &record)?;
    Ok(TimeSampled {
        frame,
        estimate: w.estimate,
        parts: w.breakdown,
        record,
    })
}
