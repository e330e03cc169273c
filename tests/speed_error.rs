//! `bench speed-error`: every faster mode is compared against the full cycle model on
//! the same frame, and the figures are consistent with the modes' own runs.

use dualstream::config::Config;
use dualstream::sampling::estimate;
use dualstream::sampling::speed_error::{SpeedErrorOpts, plot, run, table, tile_sample};

mod common;
use common::Scratch;

fn tiny() -> (dualstream::scene::Scene, Config) {
    let mut s = dualstream::scene::load("tiny").unwrap();
    s.settings.width = 16;
    s.settings.height = 16;
    s.settings.bounces = 2;
    let mut c = Config::default();
    c.chip.tms = 4;
    c.tm.tps = 4;
    c.accel.segment_bytes = 8 << 10;
    (s, c)
}

#[test]
fn every_mode_against_the_cycle_model() {
    let (s, c) = tiny();
    let o = SpeedErrorOpts {
        small_tms: 2,
        sample_every: 4,
        tile: 4,
        ..SpeedErrorOpts::default()
    };
    let rows = run(&s, &c, &o).unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r.mode.as_str()).collect();
    assert_eq!(
        names,
        [
            "cycle",
            "cycle-fixed",
            "functional+estimate",
            "small-chip",
            "quarter-pixels",
            "sampled",
            "sampled-scaled",
            "windows"
        ]
    );
    let r = &rows[0];
    assert!(r.cycles > 0.0 && r.lines > 0.0 && r.energy_j > 0.0);
    assert_eq!((r.err_cycles, r.err_lines, r.err_energy), (0.0, 0.0, 0.0));
    for m in &rows[1..] {
        let want = (m.cycles - r.cycles) / r.cycles;
        assert!((m.err_cycles - want).abs() < 1e-12, "{}", m.mode);
        assert!(m.cycles > 0.0 && m.energy_j > 0.0, "{}", m.mode);
    }
    // Modes that render the same frame render the same image: every ray agrees
    // (time sampling's windows leave the functional model's image untouched).
    for m in rows[1..4].iter().chain(&rows[7..]) {
        assert_eq!(m.image_identical, Some(true), "{}", m.mode);
    }
    assert_eq!(rows[4].image_identical, None);
    // The samples' pixels are the whole frame's, and two samples give an error bar.
    for m in &rows[5..7] {
        assert_eq!(m.image_identical, Some(true), "{}", m.mode);
        let e = m.est_err.expect("two samples estimate their error");
        assert!(e.iter().all(|x| x.is_finite() && *x >= 0.0), "{e:?}");
    }
    assert!(rows[..5].iter().all(|m| m.est_err.is_none()));
    // The stream lines do not depend on timing: the chip with either memory moves
    // as many lines within the timing-dependent hit-record merging.
    assert!(rows[1].err_lines.abs() < 0.1, "{}", rows[1].err_lines);
    let t = table(&rows);
    assert_eq!(t.lines().count(), 9, "{t}");
    assert_eq!(plot(&rows).matches("<circle").count(), 8);
}

#[test]
fn the_estimate_is_at_least_every_resource_bound() {
    let (s, c) = tiny();
    let rc = dualstream::render::RenderCfg {
        accel: c.accel.clone(),
        ..Default::default()
    };
    let f = dualstream::render::render(&s, dualstream::render::Mode::Functional, &rc, &mut |_| {})
        .unwrap();
    let e = estimate(&c, &f);
    assert_eq!(e.binding.len(), f.waves.len());
    let (mut nodes, mut ray_lines) = (0u64, 0u64);
    for w in &f.waves {
        nodes += w.traversal.nodes;
        ray_lines += w.ray_lines();
    }
    // Box tests at one per TM per cycle, ray-stream lines at their lanes per cycle.
    assert!(e.cycles >= nodes as f64 / c.chip.tms as f64);
    let lanes = c.chip.scheduler.ray_lines_per_cycle as f64;
    assert!(e.cycles >= ray_lines as f64 / lanes);
    // Twice the TMs cannot make the compute bounds slower.
    let mut big = c.clone();
    big.chip.tms *= 2;
    assert!(estimate(&big, &f).cycles <= e.cycles);
}

#[test]
fn an_impossible_small_chip_is_named() {
    let (s, c) = tiny();
    let e = run(
        &s,
        &c,
        &SpeedErrorOpts {
            small_tms: 4,
            ..SpeedErrorOpts::default()
        },
    )
    .unwrap_err();
    assert!(e.contains("--small-tms 4") && e.contains("chip.tms"), "{e}");
}

#[test]
fn two_small_chips_fit_a_serial_and_a_parallel_part() {
    let (s, mut c) = tiny();
    c.chip.tms = 8;
    let rows = run(
        &s,
        &c,
        &SpeedErrorOpts {
            small_tms: 2,
            tile: 4,
            sample_every: 4,
            ..SpeedErrorOpts::default()
        },
    )
    .unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r.mode.as_str()).collect();
    assert_eq!(names[3..5], ["small-chip", "small-chips-fit"]);
    let fit = &rows[4];
    assert_eq!(fit.image_identical, Some(true));
    assert!(fit.note.contains("2 and 4 TMs"), "{}", fit.note);
    // Both small runs together take longer than the linear mode's one run.
    assert!(fit.wall_s >= rows[3].wall_s);
}

/// A pixel sample renders exactly its pixels, each as in the whole frame.
#[test]
fn a_pixel_sample_renders_its_pixels_as_the_whole_frame_does() {
    let (s, c) = tiny();
    let rc = |pixels: Option<Vec<u32>>| dualstream::render::RenderCfg {
        accel: c.accel.clone(),
        pixels,
        ..Default::default()
    };
    let mode = dualstream::render::Mode::Functional;
    let full = dualstream::render::render(&s, mode, &rc(None), &mut |_| {}).unwrap();
    let pix = tile_sample(16, 16, 4, 4, 1).unwrap();
    assert_eq!(pix.len(), 64, "a quarter of the 16 tiles");
    let part = dualstream::render::render(&s, mode, &rc(Some(pix.clone())), &mut |_| {}).unwrap();
    assert!(part.total.rays < full.total.rays);
    let lit = pix
        .iter()
        .filter(|&&p| full.radiance[p as usize] != glam::Vec3::ZERO)
        .count();
    assert!(lit > 0, "the test needs lit pixels in the sample");
    for p in 0..256u32 {
        let want = if pix.contains(&p) {
            full.radiance[p as usize]
        } else {
            glam::Vec3::ZERO
        };
        assert_eq!(
            part.radiance[p as usize].to_array().map(f32::to_bits),
            want.to_array().map(f32::to_bits),
            "pixel {p}"
        );
    }
    // The samples of the offsets partition the frame.
    let mut all: Vec<u32> = (0..4)
        .flat_map(|o| tile_sample(16, 16, 4, 4, o).unwrap())
        .collect();
    all.sort();
    assert_eq!(all, (0..256).collect::<Vec<u32>>());
    // A bad sample is named.
    for bad in [vec![], vec![3, 3], vec![5, 2], vec![256]] {
        let e =
            dualstream::render::render(&s, mode, &rc(Some(bad.clone())), &mut |_| {}).unwrap_err();
        assert!(e.contains("pixel sample"), "{bad:?}: {e}");
    }
}

/// Sampling every tile in one sample is the whole frame: both estimates equal the
/// reference.
#[test]
fn sampling_every_tile_is_the_whole_frame() {
    let (s, c) = tiny();
    let o = SpeedErrorOpts {
        sample_every: 1,
        subsets: 1,
        tile: 4,
        modes: Some(vec!["sampled".into()]),
        ..SpeedErrorOpts::default()
    };
    let rows = run(&s, &c, &o).unwrap();
    assert_eq!(rows.len(), 3);
    for m in &rows[1..] {
        for e in [m.err_cycles, m.err_lines, m.err_energy] {
            assert!(e.abs() < 1e-9, "{}: {e}", m.mode);
        }
        assert_eq!(m.est_err, None, "one sample has no error bar");
    }
}

#[test]
fn bad_speed_error_options_are_named() {
    let (s, c) = tiny();
    let with = |f: &dyn Fn(&mut SpeedErrorOpts)| {
        let mut o = SpeedErrorOpts {
            modes: Some(vec!["sampled".into()]),
            tile: 4,
            sample_every: 4,
            ..SpeedErrorOpts::default()
        };
        f(&mut o);
        run(&s, &c, &o).unwrap_err()
    };
    assert!(with(&|o| o.sample_every = 0).contains("--sample-every 0"));
    assert!(with(&|o| o.tile = 0).contains("--tile 0"));
    assert!(with(&|o| o.tile = 17).contains("--tile 17"));
    assert!(with(&|o| o.subsets = 5).contains("--subsets 5"));
    assert!(with(&|o| o.modes = Some(vec!["warp".into()])).contains("unknown mode 'warp'"));
    assert!(
        with(&|o| {
            o.tile = 16;
            o.sample_every = 4;
            o.subsets = 4
        })
        .contains("too few")
    );
    // A wavefront sample's L2 share must leave whole sets.
    for share in [0, 3, 1 << 20] {
        let e = with(&|o| {
            o.modes = Some(vec!["windows".into()]);
            o.windows.wave_l2_share = share;
        });
        assert!(e.contains(&format!("--window-wave-l2 {share}")), "{e}");
    }
    // A share of a segment's lines: finite, not negative.
    for share in [-0.5, f64::NAN, f64::INFINITY] {
        let e = with(&|o| {
            o.modes = Some(vec!["windows".into()]);
            o.windows.wave_ray_share = share;
        });
        assert!(
            e.contains(&format!("--window-wave-ray-share {share}")),
            "{e}"
        );
    }
}

/// Renders `s` on the chip with GDDR5 as `render --mode cycle --stats --out` would and
/// writes its statistics and PNG; returns their directory (removed when it is
/// dropped) and their paths.
fn reference_files(
    s: &dualstream::scene::Scene,
    c: &Config,
    tag: &str,
) -> (Scratch, std::path::PathBuf, std::path::PathBuf) {
    use dualstream::render::{self, ChipRun, Mode, RenderCfg};
    let mut g = c.clone();
    g.chip.memory.model = dualstream::machine::config::MemoryModel::Gddr5;
    let rc = RenderCfg {
        accel: g.accel.clone(),
        memory: g.memory.clone(),
        chip: Some(Box::new(ChipRun {
            config: g.clone(),
            sim: Default::default(),
            trace: None,
        })),
        ..Default::default()
    };
    let rc = RenderCfg {
        pass_log: true,
        ..rc
    };
    let mut f = render::render(s, Mode::Cycle, &rc, &mut |_| {}).unwrap();
    f.energy = Some(dualstream::energy::frame_energy(&g, &f));
    let dir = Scratch::new(&format!("se-ref-{tag}"));
    let (j, p) = (dir.join("ref.json"), dir.join("ref.png"));
    render::output::write_json(&f, &j).unwrap();
    render::output::write_png(&f, &p).unwrap();
    // Beside them, as `render --pass-log passes.csv` writes it.
    render::output::write_pass_log(&f, &dir.join("passes.csv")).unwrap();
    (dir, j, p)
}

#[test]
fn a_reference_read_back_gives_the_same_errors() {
    use dualstream::sampling::speed_error::Reference;
    let (s, c) = tiny();
    let (_dir, j, p) = reference_files(&s, &c, "same");
    let modes = Some(vec![
        "functional+estimate".to_string(),
        "sampled".to_string(),
    ]);
    let o = SpeedErrorOpts {
        sample_every: 4,
        tile: 4,
        modes: modes.clone(),
        ..SpeedErrorOpts::default()
    };
    let own = run(&s, &c, &o).unwrap();
    let read = run(
        &s,
        &c,
        &SpeedErrorOpts {
            reference: Some(Reference::load(&j, Some(&p), &s, &c).unwrap()),
            ..o.clone()
        },
    )
    .unwrap();
    assert_eq!(own.len(), read.len());
    for (a, b) in own.iter().zip(&read) {
        assert_eq!(a.mode, b.mode);
        // Same figures and errors (the energy goes through the JSON's decimal text).
        for (x, y) in [
            (a.cycles, b.cycles),
            (a.lines, b.lines),
            (a.err_cycles, b.err_cycles),
            (a.err_lines, b.err_lines),
            (a.err_energy, b.err_energy),
        ] {
            assert!(
                (x - y).abs() <= 1e-9 * x.abs().max(1.0),
                "{}: {x} {y}",
                a.mode
            );
        }
        assert_eq!(b.image_identical, Some(true), "{}", b.mode);
    }
    // Without the PNG the images are not checked.
    let r = Reference::load(&j, None, &s, &c).unwrap();
    let rows = run(
        &s,
        &c,
        &SpeedErrorOpts {
            reference: Some(r),
            ..o
        },
    )
    .unwrap();
    assert!(rows[1..].iter().all(|m| m.image_identical.is_none()));
}

#[test]
fn a_reference_of_another_frame_is_refused() {
    use dualstream::sampling::speed_error::Reference;
    let (s, c) = tiny();
    let (_dir, j, p) = reference_files(&s, &c, "other");
    // Another resolution is named from the file alone.
    let mut wide = s.clone();
    wide.settings.width = 32;
    let e = Reference::load(&j, Some(&p), &wide, &c).unwrap_err();
    assert!(e.contains("16x16, not 32x16"), "{e}");
    // Another bounce count is the same size on paper: the traced rays tell.
    let mut deeper = s.clone();
    deeper.settings.bounces = 3;
    let r = Reference::load(&j, Some(&p), &deeper, &c).unwrap();
    let e = run(
        &deeper,
        &c,
        &SpeedErrorOpts {
            reference: Some(r),
            modes: Some(vec!["functional+estimate".to_string()]),
            ..SpeedErrorOpts::default()
        },
    )
    .unwrap_err();
    assert!(e.contains("rays") && e.contains("re-render"), "{e}");
    // A functional-mode file is not a reference.
    let text = std::fs::read_to_string(&j)
        .unwrap()
        .replace("\"cycle\"", "\"functional\"");
    std::fs::write(&j, text).unwrap();
    let e = Reference::load(&j, None, &s, &c).unwrap_err();
    assert!(e.contains("not cycle"), "{e}");
}

/// The windows row against a rendered reference (`reference_files` beside
/// `j`, with its pass log), and the window log it wrote to `log`.
fn windows_against(
    s: &dualstream::scene::Scene,
    c: &Config,
    plan: dualstream::sampling::WindowPlan,
    (j, png): (&std::path::Path, &std::path::Path),
    log: &std::path::Path,
) -> (
    dualstream::sampling::speed_error::ModeResult,
    serde_json::Value,
) {
    use dualstream::sampling::speed_error::Reference;
    let rows = run(
        s,
        c,
        &SpeedErrorOpts {
            modes: Some(vec!["windows".into()]),
            windows: plan,
            window_log: Some(log.to_path_buf()),
            reference: Some({
                let mut r = Reference::load(j, Some(png), s, c).unwrap();
                r.read_passes(&j.parent().unwrap().join("passes.csv"))
                    .unwrap();
                r
            }),
            ..SpeedErrorOpts::default()
        },
    )
    .unwrap();
    let v = serde_json::from_str(&std::fs::read_to_string(log).unwrap()).unwrap();
    (rows[1].clone(), v)
}

fn windows_plan(head: u64, every: u64) -> dualstream::sampling::WindowPlan {
    dualstream::sampling::WindowPlan {
        head,
        root_rays: u64::MAX,
        bounce_root_rays: u64::MAX,
        wave_rays: 0,
        wave_l2_share: 1,
        wave_ray_share: 0.0,
        wave_whole: 0,
        warm: 0,
        measure: every,
        every,
        shade_windows: 1,
        shade_warm: 0,
        shade_warm_cycles: 0,
        shade_measure: u64::MAX,
        shade_head: 0,
        tail_pending: 0,
        tail_warm: 0,
        wave_every: 1,
    }
}

/// The kinds of the windows wavefront `wave` took, in the order they ran, from
/// a window log.
fn window_kinds(v: &serde_json::Value, wave: u64) -> Vec<String> {
    v["record"]["samples"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|x| x["wave"] == wave)
        .map(|x| x["kind"].as_str().unwrap().to_string())
        .collect()
}

/// A window log's trace parts of wavefront `wave` (all but shading and
/// emission): name, cycles, borrowed.
fn trace_parts(v: &serde_json::Value, wave: u64) -> Vec<(String, f64, bool)> {
    v["parts"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["wave"] == wave && p["part"] != "shade" && p["part"] != "emit")
        .map(|p| {
            (
                p["part"].as_str().unwrap().to_string(),
                p["cycles"].as_f64().unwrap(),
                p["borrowed"].as_bool().unwrap(),
            )
        })
        .collect()
}

/// Two rows' errors in cycles, lines and energy, side by side.
fn figure_errors(
    a: &dualstream::sampling::speed_error::ModeResult,
    b: &dualstream::sampling::speed_error::ModeResult,
) -> [(&'static str, f64, f64); 3] {
    [
        ("cycles", a.err_cycles, b.err_cycles),
        ("lines", a.err_lines, b.err_lines),
        ("energy", a.err_energy, b.err_energy),
    ]
}

/// A small plan for the borrowing tests: windows of 6 admissions after 2 of
/// warm-up every 4, the tail from 2 pending queues, wavefronts traced every
/// `wave_every`, root windows of `root_rays`.
fn borrowing_plan(wave_every: u64, root_rays: u64) -> dualstream::sampling::WindowPlan {
    let mut plan = windows_plan(4, 6);
    plan.warm = 2;
    plan.measure = 6;
    plan.tail_pending = 2;
    plan.wave_every = wave_every;
    plan.root_rays = root_rays;
    plan.bounce_root_rays = root_rays;
    plan
}

/// The spheres without their room (its 12 triangles come first) at 16x16, 4
/// bounces: most bounce rays escape, so each wavefront has far fewer rays
/// than the last.
fn open_spheres() -> dualstream::scene::Scene {
    let mut s = dualstream::scene::load("spheres").unwrap();
    s.triangles.drain(..12);
    s.tri_material.drain(..12);
    s.settings.width = 16;
    s.settings.height = 16;
    s.settings.bounces = 4;
    s
}

/// Part `part` of wavefront `wave` in a window log.
fn part_of<'a>(v: &'a serde_json::Value, wave: u64, part: &str) -> &'a serde_json::Value {
    v["parts"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["wave"] == wave && p["part"] == part)
        .unwrap()
}

/// The windows of one kind, in the order they ran.
fn of_kind(
    r: &dualstream::sampling::WindowRecord,
    kind: dualstream::sampling::SampleKind,
) -> Vec<&dualstream::sampling::WindowSample> {
    r.samples.iter().filter(|x| x.kind == kind).collect()
}

fn render_windows(
    s: &dualstream::scene::Scene,
    c: &Config,
    plan: dualstream::sampling::WindowPlan,
) -> (
    dualstream::render::Frame,
    dualstream::sampling::WindowRecord,
) {
    render_windows_on(s, c, plan, 1)
}

/// With `threads` simulator threads (above one: the windows run side by side).
fn render_windows_on(
    s: &dualstream::scene::Scene,
    c: &Config,
    plan: dualstream::sampling::WindowPlan,
    threads: usize,
) -> (
    dualstream::render::Frame,
    dualstream::sampling::WindowRecord,
) {
    let rc = dualstream::render::RenderCfg {
        accel: c.accel.clone(),
        chip: Some(Box::new(dualstream::render::ChipRun {
            config: c.clone(),
            sim: dualstream::rtl::SimOptions {
                threads,
                ..Default::default()
            },
            ..Default::default()
        })),
        ..Default::default()
    };
    dualstream::sampling::render_windows(s, &rc, &plan).unwrap()
}

/// The Cornell box, 16x16, 2 bounces, on the tiny chip with GDDR5, in segments
/// of one DRAM row: a wavefront has passes to take over.
fn cornell_in_rows() -> (dualstream::scene::Scene, Config) {
    let (_, mut c) = tiny();
    let mut s = dualstream::scene::load("cornell").unwrap();
    s.settings.width = 16;
    s.settings.height = 16;
    s.settings.bounces = 2;
    c.chip.memory.model = dualstream::machine::config::MemoryModel::Gddr5;
    c.accel.segment_bytes = c.memory.row_bytes as u32;
    (s, c)
}

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
    let e = r.read_passes(&bad).unwrap_err();
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

/// Shading windows are scaled by the functional pass's shading lines per
/// pixel, not by items: in an open scene's later passes most paths are done
/// (one line, the path state the chip reads) and windows over the sky and over
/// the model cost far apart.
#[test]
fn shading_windows_are_scaled_by_the_pixels_lines() {
    let (_, mut c) = tiny();
    c.chip.memory.model = dualstream::machine::config::MemoryModel::Gddr5;
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
    c.chip.memory.model = dualstream::machine::config::MemoryModel::Gddr5;
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
    let en = dualstream::energy::frame_energy(&c, &f);
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
