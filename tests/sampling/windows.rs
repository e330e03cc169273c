//! Time sampling's windows: the chip taking a functional frame over, side by
//! side on threads, the shading windows, and the estimate of every figure.

use super::*;

/// With two threads the windows run side by side, each on a snapshot of the
/// image taken when the functional model reached it: the same record, in the
/// order the windows were taken, and the same frame as one thread.
#[test]
fn windows_side_by_side_record_what_one_thread_does() {
    let (s, c) = cornell_in_rows();
    let mut plan = windows_plan(2, 3);
    plan.warm = 1;
    plan.measure = 1;
    plan.shade_windows = 2;
    plan.shade_measure = 32;
    plan.tail_pending = 2;
    let (one, one_rec) = render_windows_on(&s, &c, plan.clone(), 1);
    let (two, two_rec) = render_windows_on(&s, &c, plan, 2);
    assert_eq!(one.radiance, two.radiance);
    // Everything but the wall times.
    let record = |rec: &dualstream::sampling::WindowRecord| {
        let mut v = serde_json::to_value(rec).unwrap();
        v.as_object_mut().unwrap().remove("chip_s");
        for smp in v["samples"].as_array_mut().unwrap() {
            smp.as_object_mut().unwrap().remove("wall_s");
            smp.as_object_mut().unwrap().remove("start_s");
        }
        v
    };
    // The schedule: one thread runs the windows one after another, two at
    // most two at a time; the time by kind adds up to the windows' time.
    for (rec, threads) in [(&one_rec, 1), (&two_rec, 2)] {
        let spans: Vec<(f64, f64)> = rec
            .samples
            .iter()
            .map(|x| (x.start_s, x.start_s + x.wall_s))
            .collect();
        for (i, &(a, b)) in spans.iter().enumerate() {
            assert!(a >= 0.0 && b >= a, "window {i}: {a} .. {b}");
            let running = spans.iter().filter(|&&(c, d)| c <= a && a < d).count();
            assert!(
                running <= threads,
                "{running} windows at {a} s on {threads} threads"
            );
        }
        if threads == 1 {
            for w in spans.windows(2) {
                // (start + wall rounds; the next start is microseconds later)
                assert!(w[1].0 >= w[0].1 - 1e-9, "one thread: {:?} overlaps", w);
            }
        }
        let by = rec.chip_s_by_kind();
        assert_eq!(
            by.iter().map(|k| k.windows).sum::<usize>(),
            rec.samples.len()
        );
        let sum: f64 = by.iter().map(|k| k.chip_s).sum();
        assert!((sum - rec.chip_s).abs() <= 1e-9 * rec.chip_s.max(1.0));
        assert!(
            by.windows(2).all(|w| w[0].kind < w[1].kind),
            "one entry a kind"
        );
        for k in &by {
            let n = rec.samples.iter().filter(|x| x.kind == k.kind).count();
            assert_eq!(n, k.windows, "{:?}", k.kind);
        }
    }
    let (a, b) = (record(&one_rec), record(&two_rec));
    let (sa, sb) = (
        a["samples"].as_array().unwrap(),
        b["samples"].as_array().unwrap(),
    );
    assert!(sa.len() >= 8, "enough windows to overlap ({})", sa.len());
    assert_eq!(sa.len(), sb.len());
    for (i, (x, y)) in sa.iter().zip(sb).enumerate() {
        assert!(
            x == y,
            "window {i} differs: {} {} against {} {}",
            x["kind"],
            x["first"],
            y["kind"],
            y["first"]
        );
    }
    assert!(a == b, "the functional passes differ");
}

/// Time sampling: the chip takes a wavefront over at a segment boundary of the
/// functional model and does exactly the work the functional model has left (the
/// same segment passes, box and triangle tests), and the window leaves no trace
/// in the functional model's frame.
#[test]
fn a_wavefront_taken_over_midway_does_the_rest_of_its_work() {
    use dualstream::sampling::SampleKind;
    let (s, c) = cornell_in_rows();
    let (plain, plain_rec) = render_windows(&s, &c, windows_plan(1, 1 << 20));
    let rec = &plain_rec;
    for head in [1u64, 3] {
        let (f, rec) = render_windows(&s, &c, windows_plan(head, 1 << 20));
        assert_eq!(f.radiance, plain.radiance, "windows do not touch the frame");
        let rec = &rec;
        let mut mids = 0;
        for smp in of_kind(rec, SampleKind::Trace) {
            let segs = &rec.segs[smp.wave];
            let first = smp.first as usize;
            if first == 1 && head > 1 {
                // The head's rest after the root window: admissions, not passes.
                assert_eq!(smp.run.marks, head - 1);
                continue;
            }
            mids += 1;
            assert!(smp.run.ended, "measured to the wavefront's end");
            assert_eq!(smp.run.marks as usize, segs.len() - first);
            let rest = &segs[first..];
            let nodes: u64 = rest.iter().map(|w| w.nodes).sum();
            let tris: u64 = rest.iter().map(|w| w.tri_tests).sum();
            let dup: u64 = rest.iter().map(|w| w.enqueues).sum();
            let scene: u64 = rest.iter().map(|w| w.scene_lines).sum();
            let k = &smp.run.counts;
            assert_eq!(k.box_tests, 2 * nodes, "wave {} from {first}", smp.wave);
            assert_eq!(k.tri_tests, tris, "wave {} from {first}", smp.wave);
            assert_eq!(k.duplicates, dup, "wave {} from {first}", smp.wave);
            let sl = k.lines_read[dualstream::mem::StreamTag::Scene as usize];
            assert_eq!(sl, scene, "wave {} from {first}", smp.wave);
            assert!(k.cycles > 0);
            // Rays finished by segment: every ray of every remaining pass, and
            // the passes it retired are those passes.
            let mut want: Vec<(u32, u64)> = rest.iter().map(|w| (w.seg, w.rays)).collect();
            want.sort_unstable();
            assert_eq!(smp.run.done, want, "wave {} from {first}", smp.wave);
            let mut retired: Vec<(u32, u64)> =
                smp.run.passes.iter().map(|p| (p.seg, p.rays)).collect();
            retired.sort_unstable();
            assert_eq!(retired, want, "wave {} from {first}", smp.wave);
        }
        // The root window, on its whole queue, is the root pass exactly: its
        // warm-up, measured stretch and the rest to the pass's end.
        for smp in of_kind(rec, SampleKind::Root) {
            let root = rec.segs[smp.wave][0];
            let (w, k, a) = (&smp.run.warm, &smp.run.counts, &smp.run.after);
            let sum = |f: fn(&dualstream::machine::WaveCycles) -> u64| f(w) + f(k) + f(a);
            assert_eq!(smp.first, 0, "no ray left out");
            assert!(smp.run.from + smp.run.marks <= root.rays);
            assert_eq!(sum(|x| x.box_tests), 2 * root.nodes, "wave {}", smp.wave);
            assert_eq!(sum(|x| x.tri_tests), root.tri_tests, "wave {}", smp.wave);
            assert_eq!(sum(|x| x.duplicates), root.enqueues, "wave {}", smp.wave);
        }
        assert!(
            mids >= 2,
            "a window after the head in each wavefront ({mids})"
        );
    }
    // A tail window from the first boundary after the head (every wavefront
    // has few queues left by this plan's count) measures the rest whole.
    let mut tail = windows_plan(1, 1 << 20);
    tail.tail_pending = u64::MAX;
    // The windows' warm-up (longer than any wavefront) is not the tail's.
    tail.warm = 1 << 20;
    let (f, r) = render_windows(&s, &c, tail);
    assert_eq!(f.radiance, plain.radiance);
    let r = &r;
    let tails = of_kind(r, SampleKind::Tail);
    assert!(!tails.is_empty());
    assert!(
        !r.samples.iter().any(|x| x.kind == SampleKind::Trace),
        "no window after the tail's start"
    );
    for smp in tails {
        let rest = &r.segs[smp.wave][1..];
        assert_eq!((smp.first, smp.run.ended), (1, true));
        assert_eq!(smp.run.marks as usize, rest.len());
        let nodes: u64 = rest.iter().map(|w| w.nodes).sum();
        assert_eq!(smp.run.counts.box_tests, 2 * nodes);
    }
    // A shading pass's head runs from its first item; its windows start after.
    let mut sh = windows_plan(1, 1 << 20);
    (
        sh.shade_head,
        sh.shade_windows,
        sh.shade_warm,
        sh.shade_measure,
    ) = (50, 2, 10, 20);
    let (f, r) = render_windows(&s, &c, sh);
    assert_eq!(f.radiance, plain.radiance);
    let r = &r;
    let heads = of_kind(r, SampleKind::ShadeHead);
    assert_eq!(heads.len(), r.segs.len(), "one per shading pass");
    for h in heads {
        // Checked every few cycles: a few items past the mark.
        assert!(
            h.first == 0 && (50..80).contains(&h.run.marks),
            "{}",
            h.run.marks
        );
    }
    for w in of_kind(r, SampleKind::Shade) {
        assert!(
            w.first >= 60 && (20..50).contains(&w.run.marks),
            "{} {}",
            w.first,
            w.run.marks
        );
    }
    // A root window on a compacted queue (one run of rays in k): the rays it
    // kept plus those it left out are the root pass's, it runs to the pass's
    // end and is measured from its first tenth of rays finished to its ninth,
    // and the frame goes on as it was.
    let mut thin = windows_plan(1, 1 << 20);
    // The first wavefront's root window keeps about 40 rays, the later ones'
    // about 24.
    (thin.root_rays, thin.bounce_root_rays) = (40, 24);
    let (f, r) = render_windows(&s, &c, thin);
    assert_eq!(
        f.radiance, plain.radiance,
        "a compacted root window leaves no trace"
    );
    let r = &r;
    let roots = of_kind(r, SampleKind::Root);
    assert_eq!(roots.len(), r.segs.len(), "one root window per wavefront");
    for smp in roots {
        let rays = r.segs[smp.wave][0].rays;
        let every = rays.div_ceil(if smp.wave == 0 { 40 } else { 24 });
        let run = dualstream::render::queues::COMPACT_RUN;
        let kept = (0..rays)
            .filter(|i| (i / run).is_multiple_of(every))
            .count() as u64;
        assert_eq!(smp.first, rays - kept, "wave {}", smp.wave);
        assert!(smp.run.ended, "wave {}: run to the pass's end", smp.wave);
        // The plan's tenths of the rays finished before the measurement and
        // in it (checked in steps: a few more).
        let (a, b) = dualstream::sampling::ROOT_STEADY_TENTHS;
        assert!(
            smp.run.from >= kept * a / 10 && smp.run.from + smp.run.marks <= kept,
            "wave {}: {} + {} of {kept}",
            smp.wave,
            smp.run.from,
            smp.run.marks
        );
        assert!(smp.run.marks >= kept * (b - a) / 10 || smp.run.after.cycles == 0);
        assert!(smp.run.warm.cycles > 0 && smp.run.counts.cycles > 0);
    }
    // Every wavefront's head ran from its start, the shading passes and the ray
    // generation were measured whole.
    let kinds: Vec<_> = rec.samples.iter().map(|x| (x.kind, x.first)).collect();
    assert!(kinds.contains(&(SampleKind::Emit, 0)), "{kinds:?}");
    assert!(kinds.contains(&(SampleKind::Shade, 0)), "{kinds:?}");
}

/// A plan whose windows cover everything (each wavefront's head runs to its end,
/// each shading pass and the ray generation whole) is the cycle model but for the
/// hand-overs between runs (the L2's end-of-run flush, the DRAM's open rows).
#[test]
fn windows_that_cover_the_frame_agree_with_the_cycle_model() {
    let (s, mut c) = tiny();
    // An L2 far smaller than a pass's hit records and path states, as at the
    // paper's size (a window's L2 starts cold, while the whole frame's carries the
    // tiny frame's path states from pass to pass).
    c.chip.l2.bytes = 2048;
    c.chip.l2.banks = 4;
    let rows = run(
        &s,
        &c,
        &SpeedErrorOpts {
            modes: Some(vec!["windows".into()]),
            windows: windows_plan(1 << 20, 1 << 20),
            ..SpeedErrorOpts::default()
        },
    )
    .unwrap();
    let w = &rows[1];
    assert_eq!(w.mode, "windows");
    for (what, e) in [
        ("cycles", w.err_cycles),
        ("lines", w.err_lines),
        ("energy", w.err_energy),
    ] {
        assert!(e.abs() < 0.03, "{what}: {e:+.4}");
    }
    assert_eq!(w.image_identical, Some(true));
    // The reference rendered here carries its pass log: every wavefront's root
    // and head (the whole trace, with this plan) and every shading pass are
    // checked against it, and together they are the reference's trace and
    // shading cycles within the window's error.
    assert!(rows[0].by_part.is_empty(), "the reference row has no parts");
    let by = &w.by_part;
    let n = by.iter().filter(|c| c.part == "root").count();
    assert!(n >= 2, "{by:?}");
    assert_eq!(by.iter().filter(|c| c.part == "shade").count(), n);
    for c in by {
        assert!(c.ref_cycles > 0.0, "{c:?}");
        assert!(!c.borrowed);
    }
    let est: f64 = by.iter().map(|c| c.cycles).sum();
    let refc: f64 = by.iter().map(|c| c.ref_cycles).sum();
    assert!((est / refc - 1.0).abs() < 0.05, "{est} against {refc}");
}

/// Shading windows are scaled by the functional pass's shading lines per
/// pixel, not by items: in an open scene's later passes most paths are done
/// (one line, the path state the chip reads) and windows over the sky and over
/// the model cost far apart.
#[test]
fn shading_windows_are_scaled_by_the_pixels_lines() {
    let (_, mut c) = tiny();
    c.chip.memory.model = dualstream::units::memory::MemoryModel::Gddr5;
    // An L2 far smaller than the path states, as at the paper's size (with the
    // default one the tiny frame's path states stay in it from pass to pass,
    // which a window's cold L2 does not see).
    c.chip.l2.bytes = 2048;
    c.chip.l2.banks = 4;
    // A tetrahedron under the sky: rays that leave it are done.
    let dir = Scratch::new("se-tetra");
    let obj = dir.join("tetra.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let mut s = dualstream::scene::load(obj.to_str().unwrap()).unwrap();
    s.settings.width = 48;
    s.settings.height = 48;
    s.settings.bounces = 3;
    let (dir, j, png) = reference_files(&s, &c, "shade-lines");
    let mut plan = windows_plan(1 << 20, 1 << 20);
    (
        plan.shade_head,
        plan.shade_windows,
        plan.shade_warm,
        plan.shade_measure,
    ) = (0, 2, 512, 512);
    let log = dir.join("w.json");
    let (row, v) = windows_against(&s, &c, plan.clone(), (&j, &png), &log);
    // The record: per shading pass, per pixel, its lines; a done path one.
    let (_, rec) = render_windows(&s, &c, plan);
    assert_eq!(rec.shade_lines.len(), 2, "two shading passes");
    for l in &rec.shade_lines {
        assert_eq!(l.len(), 48 * 48);
        assert!(l.iter().all(|&x| x >= 1));
    }
    let done = rec.shade_lines[1].iter().filter(|&&x| x == 1).count();
    assert!(
        done > 48 * 48 / 2,
        "most paths done after the first bounce ({done})"
    );
    assert!(
        rec.shade_lines[0].iter().all(|&x| x > 1),
        "none done at first"
    );
    // The second pass, estimated from windows over mostly done paths: by
    // their lines within 3% of the reference, by their items far off (here
    // -1.1% against -13.1%; the windows' places are hashed, see
    // `sampling::windows::shade_window_starts`).
    let (mut cyc, mut items) = (0.0, 0.0);
    for x in v["record"]["samples"].as_array().unwrap() {
        if x["wave"] == 1 && x["kind"] == "Shade" {
            cyc += x["run"]["counts"]["cycles"].as_f64().unwrap();
            items += x["run"]["marks"].as_f64().unwrap();
        }
    }
    let by_items = cyc * (48.0 * 48.0) / items;
    let p = row
        .by_part
        .iter()
        .find(|p| p.part == "shade" && p.wave == 1)
        .unwrap();
    let (e_lines, e_items) = (p.err.abs(), (by_items / p.ref_cycles - 1.0).abs());
    assert!(
        e_lines < 0.03 && e_items > e_lines + 0.05,
        "by lines {:+.3}, by items {:+.3}",
        p.err,
        by_items / p.ref_cycles - 1.0
    );
}

/// A shading window warms up for its items and at least its cycles (a pass's
/// rate settles over time); its first measured item is where the warm-up
/// really ended, which the lines proxy of its range reads.
#[test]
fn a_shading_window_warms_up_for_its_cycles_too() {
    use dualstream::sampling::SampleKind;
    let (s, c) = cornell_in_rows();
    let mut sh = windows_plan(1, 1 << 20);
    (sh.shade_windows, sh.shade_warm, sh.shade_measure) = (2, 8, 16);
    let (items, items_rec) = render_windows(&s, &c, sh.clone());
    sh.shade_warm_cycles = 2000;
    let (cycles, cycles_rec) = render_windows(&s, &c, sh);
    assert_eq!(items.radiance, cycles.radiance);
    let (a, b) = (
        of_kind(&items_rec, SampleKind::Shade),
        of_kind(&cycles_rec, SampleKind::Shade),
    );
    // Where each window's pixels start: the first measured item less the
    // items warmed up. The same places either way (a window may start near
    // its pass's end, so the cycles' warm-up can leave it nothing to measure).
    let start = |w: &dualstream::sampling::WindowSample| (w.wave, w.first - w.run.from);
    assert!(!b.is_empty());
    assert!(b.len() <= a.len());
    for y in &b {
        let x = a.iter().find(|x| start(x) == start(y)).unwrap();
        assert!(x.run.warm.cycles < 2000, "{}", x.run.warm.cycles);
        assert!(y.run.warm.cycles >= 2000, "{}", y.run.warm.cycles);
        assert!(y.run.from > x.run.from, "{} {}", y.run.from, x.run.from);
        assert!(y.first > x.first);
    }
}

/// `time_sampled` (what `report paper --mode windows` shows) estimates every
/// figure of the cycle frame: with windows that cover the frame (see
/// `windows_that_cover_the_frame_agree_with_the_cycle_model`) its cycles, the
/// hit-record and shading lines, the DRAM energy in both presets and the
/// on-chip and compute energy are the cycle model's within the hand-overs'
/// error, its ray and scene streams are the cycle model's exactly, and the
/// report's rows carry the estimate, marked as one.
#[test]
fn a_time_sampled_frame_estimates_every_figure_of_the_cycle_frame() {
    use dualstream::report::paper::{TABLE2, compare_sampled};
    let (s, mut c) = tiny();
    c.chip.l2.bytes = 2048;
    c.chip.l2.banks = 4;
    c.chip.memory.model = dualstream::units::memory::MemoryModel::Gddr5;
    let ts =
        dualstream::sampling::time_sampled(&s, &c, 1, &windows_plan(1 << 20, 1 << 20)).unwrap();
    let rc = dualstream::render::RenderCfg {
        accel: c.accel.clone(),
        chip: Some(Box::new(dualstream::render::ChipRun {
            config: c.clone(),
            ..Default::default()
        })),
        ..Default::default()
    };
    let f =
        dualstream::render::render(&s, dualstream::render::Mode::Cycle, &rc, &mut |_| {}).unwrap();
    assert_eq!(ts.frame.radiance, f.radiance, "the same image");
    let e = &ts.estimate;
    let chip = f.chip.as_ref().unwrap();
    let dram = chip.dram.unwrap();
    let en = dualstream::render::energy::frame_energy(&c, &f);
    let t = &f.total;
    for (what, est, cyc, tol) in [
        ("cycles", e.cycles, chip.total_cycles as f64, 0.03),
        ("hit lines", e.hit_lines, t.hit_lines() as f64, 0.05),
        (
            "shading lines",
            e.shading_lines,
            t.shading_lines as f64,
            0.03,
        ),
        ("DRAM J paper", e.dram_paper_j, dram.energy_paper_j, 0.05),
        (
            "DRAM J physical",
            e.dram_physical_j,
            dram.energy_physical_j,
            0.05,
        ),
        ("on-chip J", e.onchip_j, en.onchip_j, 0.03),
        ("compute J", e.compute_j, en.compute_j, 0.01),
    ] {
        let err = est / cyc - 1.0;
        eprintln!("{what}: {est} against {cyc} ({err:+.4})");
        assert!(
            cyc > 0.0 && err.abs() < tol,
            "{what}: {est} against {cyc} ({err:+.4})"
        );
    }
    assert_eq!(e.rays, t.rays);
    // The ray and scene streams are the functional model's counts, which the
    // chip moves exactly.
    assert_eq!(e.ray_lines, t.ray_lines() as f64);
    assert_eq!(e.scene_lines, t.scene_lines as f64);
    let rows = compare_sampled(&TABLE2[1], &ts.frame, e);
    assert_eq!(rows.len(), 14);
    let get = |m: &str| rows.iter().find(|r| r.metric == m).unwrap();
    let ms = get("render time (ms)").ours.unwrap();
    assert!((ms - e.cycles * 1e-6).abs() < 1e-12, "1 GHz core: {ms}");
    assert_eq!(
        get("DRAM energy, physical preset (J)").ours,
        Some(e.dram_physical_j)
    );
    assert_eq!(get("$ lines transferred (M)").ours, Some(e.lines() / 1e6));
    for r in &rows {
        assert!(r.ours.is_some(), "{}: every figure estimated", r.metric);
    }
    assert!(
        get("average bandwidth (GB/s)")
            .note
            .contains("time sampling")
    );
}
