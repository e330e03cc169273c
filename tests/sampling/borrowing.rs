//! Time sampling's borrowing: wavefronts and root passes estimated from their
//! measured neighbours, and short wavefronts traced over a sample.

use super::*;

/// `wave_every`: a wavefront between the first and the last traced in no window
/// borrows the ratios of its measured neighbours. Its root, head, rest and tail
/// are estimated from its own functional work (marked borrowed in the log), its
/// shading pass keeps its windows, and the frame's estimate stays close to the
/// one that measured it. Root windows run in the first, second and last
/// wavefronts only; the others' roots go by their rays.
#[test]
fn a_borrowed_wavefront_is_estimated_from_its_measured_neighbours() {
    use dualstream::sampling::SampleKind;
    use dualstream::sampling::speed_error::Reference;
    let (mut s, c) = cornell_in_rows();
    s.settings.bounces = 4;
    let (dir, j, png) = reference_files(&s, &c, "borrowed");
    let estimate_with = |wave_every: u64, root_rays: u64| {
        // Root windows on a sample of each root pass (a pass no longer than a
        // quarter of a root window is simulated whole, never borrowed).
        let plan = borrowing_plan(wave_every, root_rays);
        let log = dir.join(format!("w{wave_every}-{root_rays}.json"));
        windows_against(&s, &c, plan, (&j, &png), &log)
    };
    let estimate = |wave_every: u64| estimate_with(wave_every, 256);
    // A pass log that is not one is refused with what to give instead.
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, "run,segment,rays,admit,retire\n0,1,2,three,4\n").unwrap();
    let mut r = Reference::load(&j, None, &s, &c).unwrap();
    let e = r.read_passes(&bad).unwrap_err().to_string();
    assert!(e.contains("line 2") && e.contains("--pass-log"), "{e}");
    let (all, va) = estimate(1);
    let (some, vs) = estimate(2);
    // Waves 0..=4: 0 (primary), 1 and 3 (every second from 1) and 4 (the last,
    // shadow rays only) measured; 2 borrows from 1 and 3.
    assert_eq!(
        vs["record"]["measured"],
        serde_json::json!([true, true, false, true, true])
    );
    let kinds = window_kinds;
    let k2 = kinds(&vs, 2);
    for k in [SampleKind::Root, SampleKind::Trace, SampleKind::Tail] {
        let name = format!("{k:?}");
        assert!(!k2.contains(&name), "wave 2 took a {name} window: {k2:?}");
        assert!(
            kinds(&va, 2).contains(&name),
            "measured, wave 2 has a {name}"
        );
    }
    assert!(k2.contains(&"Shade".to_string()), "{k2:?}");
    // Wave 3 is measured but for its root pass (root windows in waves 0, 1
    // and the last only); the others as before.
    let no_root =
        |v: Vec<String>| -> Vec<String> { v.into_iter().filter(|k| k != "Root").collect() };
    assert!(!kinds(&vs, 3).contains(&"Root".to_string()));
    assert_eq!(kinds(&vs, 3), no_root(kinds(&va, 3)));
    for w in [0, 1, 4] {
        assert_eq!(kinds(&vs, w), kinds(&va, w), "wave {w}");
    }
    // Root windows that hold a whole root pass: every measured wavefront
    // takes its own.
    let (_, whole) = estimate_with(2, u64::MAX);
    assert!(kinds(&whole, 3).contains(&"Root".to_string()));
    // Wave 2's parts are borrowed, the others' not; each borrowed part near
    // what wave 2's windows measured, and together the same passes.
    let parts = trace_parts;
    let (b, m) = (parts(&vs, 2), parts(&va, 2));
    assert!(
        b.iter().any(|p| p.0 == "root") && b.iter().all(|p| p.2),
        "{b:?}"
    );
    assert!(m.iter().all(|p| !p.2));
    for p in parts(&vs, 3) {
        assert_eq!(p.2, p.0 == "root", "wave 3: {p:?}");
    }
    let cyc = |p: &[(String, f64, bool)]| p.iter().map(|x| x.1).sum::<f64>();
    let (cb, cm) = (cyc(&b), cyc(&m));
    assert!(
        (cb / cm - 1.0).abs() < 0.15,
        "wave 2: borrowed {cb} {b:?}, measured {cm} {m:?}"
    );
    for (what, a, b) in figure_errors(&all, &some) {
        assert!(
            (a - b).abs() < 0.05,
            "{what}: measured {a:+.4}, borrowed {b:+.4}"
        );
    }
    assert_eq!(some.image_identical, Some(true));
    // Checked part by part against the reference's pass log, borrowed parts
    // marked; the sum of the parts is the frame's estimate but for emission.
    let by = &some.by_part;
    assert!(
        by.iter()
            .any(|p| p.borrowed && p.wave == 2 && p.part == "rest")
    );
    assert!(
        by.iter()
            .any(|p| !p.borrowed && p.wave == 3 && p.part == "rest")
    );
    for p in by {
        assert!(p.ref_cycles > 0.0 || p.part == "head", "{p:?}");
    }
    // A root window on a compacted queue (wave 1: more rays than a window's)
    // against the root pass it stands for (-1.3% when written).
    let compacted: Vec<u64> = vs["record"]["samples"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|x| x["kind"] == "Root" && x["first"].as_u64().unwrap() > 0)
        .map(|x| x["wave"].as_u64().unwrap())
        .collect();
    assert!(compacted.contains(&1), "{compacted:?}");
    for p in by
        .iter()
        .filter(|p| p.part == "root" && compacted.contains(&(p.wave as u64)))
    {
        assert!(p.err.abs() < 0.06, "{p:?}");
    }
    let sum: f64 = by.iter().map(|p| p.ref_cycles).sum();
    let frame = some.cycles / (1.0 + some.err_cycles);
    assert!(sum > 0.8 * frame && sum <= frame, "{sum} of {frame}");
}

/// A wavefront with no more passes than where the plan's first measured
/// stretch would start holds no window: it is simulated whole after its root
/// pass (one head window to its end, no rest or tail), a borrowed one is one
/// part after its root like its neighbours, and the frame is estimated instead
/// of refused (Dabrovic Sponza: about 130 passes a wavefront against the
/// default plan's first window at admission 1040).
#[test]
fn a_wavefront_too_short_for_a_window_is_simulated_whole() {
    use dualstream::sampling::SampleKind;
    let (mut s, mut c) = cornell_in_rows();
    s.settings.bounces = 4;
    // An L2 smaller than a pass's hit records, as at the paper's size (see
    // `windows_that_cover_the_frame_agree_with_the_cycle_model`).
    c.chip.l2.bytes = 2048;
    c.chip.l2.banks = 4;
    let (dir, j, png) = reference_files(&s, &c, "whole");
    let estimate = |every: u64| {
        let mut plan = windows_plan(4, every);
        plan.warm = 3;
        plan.measure = 6;
        plan.tail_pending = 2;
        plan.wave_every = 2;
        let log = dir.join(format!("w{every}.json"));
        windows_against(&s, &c, plan, (&j, &png), &log)
    };
    // The first measured stretch starts at admission 10 with windows every 6
    // (these wavefronts have about 27 passes), at 1004 with every 1000.
    let (windowed, vf) = estimate(6);
    let (short, vs) = estimate(1000);
    // The bench's note says which wavefronts ran whole (the borrowed one did
    // not run).
    let measured = vs["record"]["measured"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|m| **m == true)
        .count();
    assert!(measured >= 2);
    assert!(
        short.note.contains(&format!(
            "{measured} short wavefronts simulated whole after their root window"
        )),
        "{}",
        short.note
    );
    assert!(
        !windowed.note.contains("simulated whole"),
        "{}",
        windowed.note
    );
    assert!(
        vf["record"]["whole"]
            .as_array()
            .unwrap()
            .iter()
            .all(|w| w == false)
    );
    assert!(
        vs["record"]["whole"]
            .as_array()
            .unwrap()
            .iter()
            .all(|w| w == true)
    );
    let rec: Vec<(u64, String, u64, bool, u64)> = vs["record"]["samples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| {
            (
                x["wave"].as_u64().unwrap(),
                x["kind"].as_str().unwrap().to_string(),
                x["first"].as_u64().unwrap(),
                x["run"]["ended"].as_bool().unwrap(),
                x["run"]["marks"].as_u64().unwrap(),
            )
        })
        .collect();
    let segs = vs["record"]["segs"].as_array().unwrap();
    for (wave, measured) in vs["record"]["measured"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let trace: Vec<_> = rec
            .iter()
            .filter(|r| r.0 == wave as u64 && (r.1 == "Trace" || r.1 == "Tail"))
            .collect();
        let passes = segs[wave].as_array().unwrap().len() as u64;
        if measured.as_bool().unwrap() && passes > 1 {
            // One window from the second admission to the wavefront's end.
            assert_eq!(trace.len(), 1, "wave {wave}: {trace:?}");
            let t = trace[0];
            assert_eq!(t.1, format!("{:?}", SampleKind::Trace));
            assert_eq!((t.2, t.3, t.4), (1, true, passes - 1), "wave {wave}");
        } else {
            assert!(trace.is_empty(), "wave {wave}: {trace:?}");
        }
    }
    // Parts: a root and a head to the end in every wavefront, borrowed in
    // wave 2 alike.
    for p in vs["parts"].as_array().unwrap() {
        let part = p["part"].as_str().unwrap();
        assert!(
            ["root", "head", "shade", "emit"].contains(&part),
            "{part} in a wavefront simulated whole"
        );
        if part == "head" {
            let wave = p["wave"].as_u64().unwrap() as usize;
            assert_eq!(
                p["end"].as_u64().unwrap() as usize,
                segs[wave].as_array().unwrap().len()
            );
            assert_eq!(p["borrowed"].as_bool().unwrap(), wave == 2);
        }
    }
    // Close to the reference: all but the borrowed wavefront is simulated.
    for (what, e) in [
        ("cycles", short.err_cycles),
        ("lines", short.err_lines),
        ("energy", short.err_energy),
    ] {
        assert!(e.abs() < 0.05, "{what}: whole {e:+.4}");
    }
    assert_eq!(short.image_identical, Some(true));
    assert!(short.est_err.is_none(), "no rest windows, no spread");
}

/// A short wavefront (too few passes for a window) of more rays than
/// `wave_rays` is traced over a packed sample of its root queue from its root
/// pass to its end, measured over its visits from the first tenth to the
/// ninth; the first `wave_whole` from the second on are simulated whole too
/// (root window, then the head to the end), and the frame is as it was.
#[test]
fn a_short_wavefront_is_traced_over_a_sample_to_its_end() {
    use dualstream::sampling::SampleKind;
    let (s, c) = cornell_in_rows();
    // No window fits before admission 1004 (these wavefronts have about 27
    // passes).
    let mut short = windows_plan(4, 1000);
    (short.warm, short.measure) = (3, 6);
    let (plain, _) = render_windows(&s, &c, short.clone());
    let mut plan = short;
    plan.wave_rays = 40;
    plan.wave_whole = 1;
    (plan.root_rays, plan.bounce_root_rays) = (40, 40);
    let (f, r) = render_windows(&s, &c, plan.clone());
    assert_eq!(
        f.radiance, plain.radiance,
        "a sampled wavefront leaves no trace"
    );
    let r = &r;
    assert!(r.whole.iter().all(|&w| w), "{:?}", r.whole);
    let waves = of_kind(r, SampleKind::Wave);
    let sampled: Vec<usize> = (0..r.segs.len())
        .filter(|&w| r.segs[w].first().is_some_and(|s| s.rays > 40))
        .collect();
    assert!(sampled.len() >= 2, "{sampled:?}");
    assert_eq!(
        waves.iter().map(|x| x.wave).collect::<Vec<_>>(),
        sampled,
        "one sample per wavefront of more rays than wave_rays"
    );
    for smp in &waves {
        let segs = &r.segs[smp.wave];
        let rays = segs[0].rays;
        let every = rays.div_ceil(40);
        let run = plan.sample_run();
        let kept = (0..rays)
            .filter(|i| {
                dualstream::render::queues::sampled_run(i / run, rays.div_ceil(run), every, true)
            })
            .count() as u64;
        assert_eq!(smp.first, rays - kept, "wave {}", smp.wave);
        // Run to the wavefront's end: its visits are about one in k of the
        // wavefront's (every kept ray goes down the tree as in the frame).
        let visits: u64 = smp.run.done.iter().map(|d| d.1).sum();
        let all: u64 = segs.iter().map(|s| s.rays).sum();
        let k = rays as f64 / kept as f64;
        let ratio = visits as f64 * k / all as f64;
        assert!(
            (0.6..1.6).contains(&ratio),
            "wave {}: {visits} visits x {k:.2} against {all}",
            smp.wave
        );
        assert!(smp.run.done.len() > 1, "it went past the root segment");
        assert!(smp.run.ended);
        // Measured from the first tenth of its visits to the ninth (looked at
        // in steps: a little past each).
        let (a, b) = dualstream::sampling::ROOT_STEADY_TENTHS;
        assert!(
            smp.run.from >= visits * a / 10
                && smp.run.from + smp.run.marks >= visits * b / 10
                && smp.run.from + smp.run.marks <= visits,
            "wave {}: {} + {} of {visits}",
            smp.wave,
            smp.run.from,
            smp.run.marks
        );
        assert!(smp.run.warm.cycles > 0 && smp.run.counts.cycles > 0 && smp.run.after.cycles > 0);
        // The whole wavefront as well only in the second one.
        let whole = r
            .samples
            .iter()
            .filter(|x| {
                x.wave == smp.wave && matches!(x.kind, SampleKind::Root | SampleKind::Trace)
            })
            .count();
        assert_eq!(whole > 0, smp.wave == 1, "wave {}", smp.wave);
    }
    // A sample whose passes would stream more scene than rays is not taken:
    // those wavefronts are simulated whole after their root pass.
    plan.wave_ray_share = 1e6;
    let (g, r) = render_windows(&s, &c, plan);
    assert_eq!(g.radiance, plain.radiance);
    let r = &r;
    assert!(of_kind(r, SampleKind::Wave).is_empty());
    for &w in &sampled {
        assert!(
            r.samples
                .iter()
                .any(|x| x.wave == w && x.kind == SampleKind::Root),
            "wave {w} simulated whole from its root window"
        );
    }
}

/// With `wave_every` above 1, a sampled short wavefront after the third whose
/// rays are alike the last measured one's, right after another sampled one,
/// borrows: it takes no trace window of any kind (its shading pass keeps its
/// windows), and its estimate is one part, its whole functional proxy times the
/// ratio of the nearest sampled wavefronts from the third on; the frame stays
/// close to the one that measured every sample.
#[test]
fn a_sampled_wavefront_alike_its_sampled_neighbours_borrows_them() {
    use dualstream::sampling::{BORROW_ALIKE, SAMPLE_BORROW_FROM, SampleKind};
    let (mut s, c) = cornell_in_rows();
    s.settings.bounces = 6;
    let (dir, j, png) = reference_files(&s, &c, "sample-borrow");
    let estimate = |wave_every: u64| {
        let mut plan = windows_plan(4, 1000);
        (plan.warm, plan.measure) = (3, 6);
        plan.wave_rays = 40;
        (plan.root_rays, plan.bounce_root_rays) = (40, 40);
        plan.wave_every = wave_every;
        let log = dir.join(format!("sample-borrow-{wave_every}.json"));
        windows_against(&s, &c, plan, (&j, &png), &log)
    };
    let (all, va) = estimate(1);
    let (some, vs) = estimate(2);
    assert_eq!(some.image_identical, Some(true));
    let rec = &vs["record"];
    let last = rec["final_wave"].as_u64().unwrap() as usize;
    let roots: Vec<u64> = rec["segs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w[0]["rays"].as_u64().unwrap())
        .collect();
    let sampled = |v: &serde_json::Value, w: usize| {
        v["record"]["samples"]
            .as_array()
            .unwrap()
            .iter()
            .any(|x| x["wave"] == w as u64 && x["kind"] == "Wave")
    };
    // Every wavefront but the last (its shadow rays) holds more rays than a
    // sample: measured one by one, each is sampled.
    assert_eq!(va["record"]["measured"].as_array().unwrap().len(), last + 1);
    for w in 0..last {
        assert!(sampled(&va, w), "wave {w}: {roots:?}");
    }
    // The rule: the first three and the last measured, the others borrow
    // while alike the last measured one.
    let mut expect = Vec::new();
    let mut traced = None::<u64>;
    for (w, &rays) in roots.iter().enumerate() {
        let alike = traced.is_some_and(|m| rays.abs_diff(m) as f64 <= BORROW_ALIKE * m as f64);
        let measured = w <= SAMPLE_BORROW_FROM || w >= last || !alike;
        if measured {
            traced = Some(rays);
        }
        expect.push(measured);
    }
    assert_eq!(rec["measured"], serde_json::json!(expect), "{roots:?}");
    let borrowed: Vec<usize> = (0..=last).filter(|&w| !expect[w]).collect();
    assert!(!borrowed.is_empty(), "no wavefront alike: {roots:?}");
    let parts = |v: &serde_json::Value, wave: usize| trace_parts(v, wave as u64);
    for &w in &borrowed {
        let kinds = window_kinds(&vs, w as u64);
        assert!(
            kinds
                .iter()
                .all(|k| k == &format!("{:?}", SampleKind::Shade)
                    || k == &format!("{:?}", SampleKind::ShadeHead)),
            "wave {w} took {kinds:?}"
        );
        assert!(
            !kinds.is_empty(),
            "wave {w}'s shading pass keeps its windows"
        );
        let b = parts(&vs, w);
        assert_eq!(b.len(), 1, "one part: {b:?}");
        assert!(b[0].0 == "wave" && b[0].2, "{b:?}");
        // Its donors: the nearest measured ones before and after it from the
        // third on but the last. Their rays are alike its own, so their
        // proxies are too: its estimate is near theirs (the first
        // wavefronts' are not: the primary rays' 0.6x, the first bounce's
        // 1.2x here).
        let before = (SAMPLE_BORROW_FROM..w).rev().find(|&v| expect[v]);
        let after = (w + 1..last).find(|&v| expect[v]);
        let donors: Vec<usize> = before.into_iter().chain(after).collect();
        assert!(!donors.is_empty());
        let d: f64 = donors.iter().map(|&v| parts(&vs, v)[0].1).sum::<f64>() / donors.len() as f64;
        assert!(
            (b[0].1 / d - 1.0).abs() < 0.1,
            "wave {w}: borrowed {b:?}, donors {donors:?} {d}"
        );
    }
    // The donors are sampled and measured; the rest as when all are measured.
    for (w, _) in expect.iter().enumerate().filter(|e| *e.1) {
        assert_eq!(
            window_kinds(&vs, w as u64),
            window_kinds(&va, w as u64),
            "wave {w}"
        );
    }
    for (what, a, b) in figure_errors(&all, &some) {
        // (A sample of 40 rays is far from its regime: both are far off the
        // cycle model here, so they are compared with each other.)
        assert!(
            ((1.0 + b) / (1.0 + a) - 1.0).abs() < 0.05,
            "{what}: measured {a:+.4}, borrowed {b:+.4}"
        );
    }
}

/// A borrowed root pass between two root windows whose rays differ lies on the
/// line through them; alike neighbours set no slope, and nothing outside them
/// is extrapolated.
#[test]
fn a_root_pass_between_unlike_root_windows_lies_on_their_line() {
    use dualstream::sampling::root_between;
    // The Dragon's reference (1024x1024, default chip, GDDR5): root passes of
    // wavefronts 1-5 in rays and cycles.
    let roots = [
        (767_169.0, 1_068_062.0),
        (157_264.0, 234_967.0),
        (68_700.0, 115_259.0),
        (32_747.0, 58_564.0),
        (6_115.0, 15_088.0),
    ];
    let (b, a) = (roots[0], roots[4]);
    for &(rays, cycles) in &roots[1..4] {
        let f = root_between(rays, b.0, a.0).expect("between unlike windows");
        assert!((0.0..=1.0).contains(&f), "{f}");
        let line = b.1 + f * (a.1 - b.1);
        let ratio = rays * b.1 / b.0;
        // The line is nearer than wavefront 1's ratio, and within 12%.
        assert!(
            (line / cycles - 1.0).abs() < (ratio / cycles - 1.0).abs(),
            "{rays}: line {line}, ratio {ratio}, reference {cycles}"
        );
        assert!((line / cycles - 1.0).abs() < 0.12, "{rays}: {line}");
    }
    // From either side, the same point.
    let f = root_between(157_264.0, b.0, a.0).unwrap();
    let g = root_between(157_264.0, a.0, b.0).unwrap();
    assert!((f + g - 1.0).abs() < 1e-12, "{f} {g}");
    // A pass alike either window (within BORROW_ALIKE) takes their ratio, and
    // one outside them is not extrapolated.
    assert_eq!(root_between(b.0 * 0.95, b.0, a.0), None);
    assert_eq!(root_between(a.0 * 1.05, b.0, a.0), None);
    assert_eq!(root_between(1_000.0, 1_000.0, 1_050.0), None);
    assert_eq!(root_between(800_000.0, b.0, a.0), None);
    assert_eq!(root_between(5_000.0, b.0, a.0), None);
}

/// An open scene's wavefronts shrink from bounce to bounce: a middle wavefront
/// whose rays differ from its measured neighbour's is traced in windows, but
/// its root pass (longer than a root window) is borrowed, on the line through
/// the root windows before and after it.
#[test]
fn a_shrinking_wavefront_borrows_its_root_on_the_line() {
    let (_, c) = cornell_in_rows();
    let s = open_spheres();
    let (dir, j, png) = reference_files(&s, &c, "line");
    let plan = borrowing_plan(2, 32);
    let (_, v) = windows_against(&s, &c, plan, (&j, &png), &dir.join("w.json"));
    let rays: Vec<f64> = v["record"]["segs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w[0]["rays"].as_f64().unwrap())
        .collect();
    assert_eq!(rays.len(), 5);
    let kinds = |wave: u64| window_kinds(&v, wave);
    let root = |wave: u64| -> (f64, f64, bool) {
        let p = part_of(&v, wave, "root");
        (
            p["cycles"].as_f64().unwrap(),
            p["dram_j"].as_f64().unwrap(),
            p["borrowed"].as_bool().unwrap(),
        )
    };
    let (b, a) = ((rays[1], root(1)), (rays[4], root(4)));
    assert!(!b.1.2 && !a.1.2, "waves 1 and 4 take root windows");
    for wave in [2u64, 3] {
        let r = rays[wave as usize];
        // Unlike wave 1 (measured in windows for that) and longer than a root
        // window (one of at most a quarter of it is simulated whole).
        assert!(r < 0.9 * rays[1] && r > 32.0, "wave {wave}: {rays:?}");
        let k = kinds(wave);
        assert!(k.contains(&"Trace".to_string()), "wave {wave}: {k:?}");
        assert!(!k.contains(&"Root".to_string()), "wave {wave}: {k:?}");
        let (cyc, j, borrowed) = root(wave);
        assert!(borrowed, "wave {wave}");
        let f = (r - b.0) / (a.0 - b.0);
        let (lc, lj) = (b.1.0 + f * (a.1.0 - b.1.0), b.1.1 + f * (a.1.1 - b.1.1));
        assert!(
            (cyc / lc - 1.0).abs() < 1e-9,
            "wave {wave}: {cyc} off the line {lc}"
        );
        assert!(
            (j / lj - 1.0).abs() < 1e-9,
            "wave {wave}: {j} J off the line {lj}"
        );
    }
}

/// A middle wavefront's root pass is simulated whole only if it is at most a
/// quarter of a root window (`WindowPlan::root_whole`): such a pass is
/// latency-bound and cheap. Up to a whole root window it is borrowed on the
/// line like a longer one (the Dragon's fifth wavefront, 32,747 rays, cost as
/// many evaluations as a root window for 0.4% of the frame).
#[test]
fn a_middle_root_pass_is_whole_only_below_a_quarter_root_window() {
    let (_, c) = cornell_in_rows();
    let s = open_spheres();
    let (dir, j, png) = reference_files(&s, &c, "quarter");
    let run = |root_rays: u64| {
        let log = dir.join(format!("q{root_rays}.json"));
        windows_against(&s, &c, borrowing_plan(2, root_rays), (&j, &png), &log).1
    };
    let v = run(32);
    let rays = v["record"]["segs"][2][0]["rays"].as_u64().unwrap();
    assert!(rays > 8, "wave 2 holds {rays} rays");
    let root_of = |v: &serde_json::Value| {
        (
            window_kinds(v, 2).contains(&"Root".to_string()),
            part_of(v, 2, "root")["borrowed"].as_bool().unwrap(),
        )
    };
    // At most a whole root window but above a quarter: borrowed.
    assert_eq!(root_of(&run(rays)), (false, true));
    // At most a quarter of a root window: simulated whole.
    assert_eq!(root_of(&run(rays * 4)), (true, false));
}
