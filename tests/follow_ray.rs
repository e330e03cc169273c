//! Following one ray through the chip (`render --follow-ray`, `units/follow.rs`):
//! the events come in cycle order, name real unit instances, end in the
//! reference traversal's hit, change no result; the waveform's markers lie in
//! its window; bad rays get the typed error and leave no file.

use std::path::Path;
use std::process::Command;

#[path = "common/mod.rs"]
mod common;
use common::Scratch;

use dualstream::config::Config;
use dualstream::contract::SHADOW_BIT;
use dualstream::render::{self, Frame, Mode, RenderCfg, RenderError};
use dualstream::units::follow::{FollowEvent, FollowKind};

/// A chip of 2 TMs x 4 TPs with segments of one DRAM row (8 KB), so rays
/// are duplicated into several segments.
fn config() -> Config {
    let mut c = Config::default();
    c.tm.tps = 4;
    c.chip.tms = 2;
    c.accel.segment_bytes = 8192;
    c
}

/// The Cornell box at 16x16 with 3 hit points.
fn scene() -> dualstream::scene::Scene {
    let mut s = dualstream::scene::load("cornell").unwrap();
    (s.settings.width, s.settings.height, s.settings.bounces) = (16, 16, 3);
    s
}

fn frame(follow: Option<Vec<(u32, u32)>>) -> Result<Frame, RenderError> {
    let c = config();
    let mut rc = RenderCfg::for_chip(&c, Default::default());
    rc.chip.as_mut().unwrap().follow = follow;
    render::render(&scene(), Mode::Cycle, &rc, &mut |_| {})
}

/// Every ray of pixels 149, 40 and 126 (its shadow ray of wavefront 1 is
/// blocked), in every wavefront.
fn targets() -> Vec<(u32, u32)> {
    let mut t = Vec::new();
    for pix in [149, 40, 126] {
        t.push((0, pix));
        for w in 1..=3 {
            t.extend([(w, pix), (w, pix | SHADOW_BIT)]);
        }
    }
    t
}

#[test]
fn a_followed_ray_ends_in_the_reference_hit_and_changes_nothing() {
    let plain = frame(None).unwrap();
    let followed = frame(Some(targets())).unwrap();
    // Following changes no result: image, statistics, cycles.
    assert_eq!(plain.radiance, followed.radiance, "image");
    // Every figure but the wall times (`*_s`).
    fn untimed(v: &mut serde_json::Value) {
        if let Some(o) = v.as_object_mut() {
            o.retain(|k, _| !k.ends_with("_s"));
            o.values_mut().for_each(untimed);
        } else if let Some(a) = v.as_array_mut() {
            a.iter_mut().for_each(untimed);
        }
    }
    let json = |f: &Frame| {
        let mut v = serde_json::to_value(f).unwrap();
        untimed(&mut v);
        v
    };
    let (a, b) = (json(&plain), json(&followed));
    assert!(a["chip"]["total_cycles"].as_u64().unwrap() > 0);
    assert!(a == b, "statistics differ with following");
    assert!(plain.chip.as_ref().unwrap().follow.is_none());

    let ev: &[FollowEvent] = followed.chip.as_ref().unwrap().follow.as_deref().unwrap();
    assert!(ev.len() > 100, "{} events", ev.len());
    assert!(
        ev.windows(2).all(|w| w[0].cycle <= w[1].cycle),
        "events in cycle order"
    );
    let t = targets();
    assert!(ev.iter().all(|e| t.contains(&(e.wave, e.ray_id))));

    // Each followed ray that was traced: its segments' best hits, the closest
    // of them and the hit record's last write, against the reference.
    let sc = scene();
    let p = render::prepare(&sc, &RenderCfg::for_chip(&config(), Default::default())).unwrap();
    let (mut traced, mut duplicated, mut hits, mut blocked) = (0, 0, 0, 0);
    for &(w, id) in &t {
        let mine: Vec<&FollowEvent> = ev
            .iter()
            .filter(|e| (e.wave, e.ray_id) == (w, id))
            .collect();
        let Some(&(origin, dir)) = mine
            .iter()
            .find_map(|e| match &e.kind {
                FollowKind::Taken { origin, dir, .. } => Some((*origin, *dir)),
                _ => None,
            })
            .as_ref()
        else {
            continue;
        };
        traced += 1;
        let takes = mine
            .iter()
            .filter(|e| matches!(e.kind, FollowKind::Taken { .. }));
        let finishes: Vec<Option<(f32, u32)>> = mine
            .iter()
            .filter_map(|e| match e.kind {
                FollowKind::Finish { best, .. } => Some(best),
                _ => None,
            })
            .collect();
        let segs = takes.count();
        assert_eq!(
            segs,
            finishes.len(),
            "ray {w}:{id:#x}: every segment taken is finished"
        );
        let queued = mine
            .iter()
            .filter(|e| matches!(e.kind, FollowKind::Queued { .. }))
            .count();
        assert_eq!(
            queued, segs,
            "ray {w}:{id:#x}: each duplicate queued once, then taken"
        );
        duplicated += (segs > 1) as u32;
        let shadow = id & SHADOW_BIT != 0;
        let want = render::traverse::reference_trace(&p.bvh, &sc.triangles, origin, dir, shadow);
        let best = finishes
            .iter()
            .flatten()
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
            .copied();
        let last_write = mine.iter().rev().find_map(|e| match e.kind {
            FollowKind::HitCompared {
                t,
                tri_id,
                written: true,
                ..
            } => Some((t, tri_id)),
            _ => None,
        });
        if shadow {
            assert_eq!(best.is_some(), want.is_hit(), "shadow ray {w}:{id:#x}");
            assert_eq!(
                last_write.is_some(),
                want.is_hit(),
                "shadow ray {w}:{id:#x}"
            );
            blocked += want.is_hit() as u32;
        } else {
            let want = want.is_hit().then_some((want.t, want.tri_id));
            let bits = |h: Option<(f32, u32)>| h.map(|(t, i)| (t.to_bits(), i));
            assert_eq!(
                bits(best),
                bits(want),
                "ray {w}:{id:#x}: closest segment hit"
            );
            assert_eq!(bits(last_write), bits(want), "ray {w}:{id:#x}: hit record");
        }
        hits += want.is_hit() as u32;
    }
    assert!(traced >= 8, "{traced} rays traced");
    assert!(duplicated >= 2, "{duplicated} rays with duplicates");
    assert!(hits >= 4, "{hits} hits");
    assert!(blocked >= 1, "{blocked} shadow rays blocked");
    // The pixels' shading passes, on the TPs.
    let shaded = ev
        .iter()
        .filter(|e| matches!(e.kind, FollowKind::Shaded { .. }))
        .count();
    assert!(shaded >= 4, "{shaded} shading items");
}

#[test]
fn a_ray_the_frame_does_not_have_is_a_typed_error() {
    let e = frame(Some(vec![(4, 3)])).unwrap_err();
    assert!(
        matches!(
            e,
            RenderError::NoSuchRay {
                wave: 4,
                ray_id: 3,
                ..
            }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("0..=3"), "{e}");
    let e = frame(Some(vec![(1, 256)])).unwrap_err();
    assert!(e.to_string().contains("0..256"), "{e}");
    let e = frame(Some(vec![(0, 7 | SHADOW_BIT)])).unwrap_err();
    assert!(matches!(e, RenderError::NoSuchRay { wave: 0, .. }), "{e:?}");
    // Not in cycle mode.
    let c = config();
    let mut rc = RenderCfg::for_chip(&c, Default::default());
    rc.chip.as_mut().unwrap().follow = Some(vec![(0, 1)]);
    let e = render::render(&scene(), Mode::Functional, &rc, &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("cycle mode"), "{e}");
}

fn dualstream(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_dualstream"))
        .args(args)
        .output()
        .unwrap()
}

fn cli_config(t: &Path) -> String {
    let p = t.join("c.toml");
    std::fs::write(
        &p,
        "[tm]\ntps = 4\n[chip]\ntms = 2\n[accel]\nsegment_bytes = 8192\n",
    )
    .unwrap();
    p.to_str().unwrap().to_string()
}

/// The VCD's unit scopes (dotted paths of the module scopes) and its last time.
fn vcd_scopes(path: &Path) -> (std::collections::BTreeSet<String>, u64) {
    let text = std::fs::read_to_string(path).unwrap();
    let (mut scopes, mut stack, mut last) = (std::collections::BTreeSet::new(), Vec::new(), 0);
    let mut words = text.split_whitespace();
    while let Some(w) = words.next() {
        match w {
            "$scope" => {
                let kind = words.next().unwrap();
                stack.push((kind == "module", words.next().unwrap().to_string()));
                if stack.iter().all(|s| s.0) {
                    scopes.insert(
                        stack
                            .iter()
                            .map(|s| s.1.as_str())
                            .collect::<Vec<_>>()
                            .join("."),
                    );
                }
            }
            "$upscope" => {
                stack.pop();
            }
            _ if w.starts_with('#') => last = w[1..].parse().unwrap_or(last),
            _ => {}
        }
    }
    (scopes, last)
}

/// The save file's window start and named markers (time, name).
fn gtkw_markers(path: &Path) -> (u64, Vec<(u64, String)>) {
    let s = std::fs::read_to_string(path).unwrap();
    let start = s
        .lines()
        .find_map(|l| l.strip_prefix("[timestart] "))
        .unwrap()
        .parse()
        .unwrap();
    let star = s.lines().find(|l| l.starts_with('*')).unwrap();
    let times: Vec<u64> = star
        .split(' ')
        .skip(2)
        .filter_map(|t| t.parse().ok())
        .collect();
    let names: Vec<String> = s
        .lines()
        .filter_map(|l| l.strip_prefix("[markername] "))
        .map(|n| n[1..].to_string())
        .collect();
    assert_eq!(times.len(), names.len(), "a name per marker: {star}");
    (start, times.into_iter().zip(names).collect())
}

/// (cycle, unit, name) of each logged event.
fn log_events(path: &Path) -> Vec<(u64, String, String)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            (f[0].parse().unwrap(), f[1].to_string(), f[4].to_string())
        })
        .collect()
}

#[test]
fn render_follow_ray_writes_the_log_and_marks_the_waveform() {
    let t = Scratch::new("follow-cli");
    let cfg = cli_config(&t);
    let s = |n: &str| t.join(n).to_str().unwrap().to_string();
    let base = [
        "--config",
        &cfg,
        "render",
        "--mode",
        "cycle",
        "--scene",
        "cornell",
        "--res",
        "16x16",
        "--bounces",
        "3",
    ];
    let (png, vcd) = (s("f.png"), s("f.vcd"));
    let mut args = base.to_vec();
    args.extend(["--out", &png, "--follow-ray", "1:149", "--vcd", &vcd]);
    let o = common::succeeds(
        Command::new(env!("CARGO_BIN_EXE_dualstream")).args(&args),
        "dualstream render --follow-ray",
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("followed:"), "{out}");
    let log = log_events(&t.join("f.follow.txt"));
    assert!(log.len() > 50, "{} events", log.len());
    assert!(log.windows(2).all(|w| w[0].0 <= w[1].0), "cycle order");
    // Every unit named is a unit instance of the trace.
    let (scopes, end) = vcd_scopes(&t.join("f.vcd"));
    for (_, unit, _) in &log {
        assert!(scopes.contains(unit), "{unit} is no scope of the trace");
    }
    for kind in [
        "queued",
        "staged",
        "taken",
        "box_test",
        "tri_test",
        "exit",
        "finish",
        "hit_compared",
    ] {
        assert!(log.iter().any(|e| e.2 == kind), "no {kind} event");
    }
    // The window is the ray's span (default, 1 ns cycles): markers at its
    // key events, every one in the window and at a logged event.
    let (start, markers) = gtkw_markers(&t.join("f.vcd.gtkw"));
    assert!(start <= log[0].0 * 1000 && log.last().unwrap().0 * 1000 <= end);
    assert!(markers.len() >= 5, "{markers:?}");
    for (time, name) in &markers {
        assert!(
            (start..=end).contains(time),
            "marker {name} at {time} outside {start}..={end}"
        );
        assert!(
            log.iter()
                .any(|e| e.0 * 1000 == *time && name.contains(&e.1)),
            "marker {name} at {time} is no logged event"
        );
    }

    // An explicit window that cuts the ray's span: only the markers in it.
    let (lo, hi) = (log[0].0, log.last().unwrap().0);
    let mid = (lo + hi) / 2;
    let win = format!("{lo}..{mid}");
    let vcd2 = s("g.vcd");
    let mut args = base.to_vec();
    args.extend(["--out", &png, "--follow-ray", "1:149", "--vcd", &vcd2]);
    args.extend(["--trace-window", &win, "--trace-units", "scheduler"]);
    args.extend(["--follow-ray-out", "-"]);
    let o = common::succeeds(
        Command::new(env!("CARGO_BIN_EXE_dualstream")).args(&args),
        "dualstream render --follow-ray",
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains(" taken seg="), "the log on stdout: {out}");
    let (start, markers) = gtkw_markers(&t.join("g.vcd.gtkw"));
    let (_, end) = vcd_scopes(&t.join("g.vcd"));
    assert!(!markers.is_empty());
    assert!(
        markers.iter().all(|(m, _)| (start..=end).contains(m)),
        "{markers:?} in {start}..={end}"
    );
    assert!(
        end < hi * 1000,
        "the window ends before the ray's last event"
    );
}

#[test]
fn bad_rays_and_pixels_fail_with_the_fix_and_leave_no_file() {
    let t = Scratch::new("follow-bad");
    let cfg = cli_config(&t);
    let s = |n: &str| t.join(n).to_str().unwrap().to_string();
    let (png, vcd, log) = (s("b.png"), s("b.vcd"), s("b.log"));
    let base = [
        "--config",
        &cfg,
        "render",
        "--scene",
        "tiny",
        "--res",
        "8x8",
        "--bounces",
        "2",
        "--out",
        &png,
        "--vcd",
        &vcd,
        "--follow-ray-out",
        &log,
    ];
    for (extra, needles) in [
        (
            &["--mode", "cycle", "--follow-ray", "3:1"][..],
            &["no ray 0x1 in wavefront 3", "0..=2"][..],
        ),
        (&["--mode", "cycle", "--follow-ray", "1:64"], &["0..64"]),
        (
            &["--mode", "cycle", "--follow-ray", "0:5s"],
            &["primary rays only"],
        ),
        // Wavefront 2 of 2 hit points holds shadow rays only: never traced.
        (
            &["--mode", "cycle", "--follow-ray", "2:5"],
            &["never traced", "shadow ray"],
        ),
        (
            &["--mode", "cycle", "--follow-pixel", "8,0"],
            &["outside the 8x8 frame"],
        ),
        (&["--mode", "cycle", "--follow-pixel", "3"], &["not X,Y"]),
        (
            &["--mode", "cycle", "--follow-ray", "1:x"],
            &["not [WAVE:]ID"],
        ),
        (
            &["--mode", "functional", "--follow-ray", "1:5"],
            &["--mode cycle"],
        ),
    ] {
        let mut args = base.to_vec();
        args.extend(extra);
        let o = dualstream(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success() && !err.contains("panicked"),
            "{extra:?}: {err}"
        );
        for n in needles {
            assert!(
                err.contains(n),
                "{extra:?}: error should mention '{n}': {err}"
            );
        }
        for f in ["b.png", "b.vcd", "b.vcd.gtkw", "b.log"] {
            assert!(!t.join(f).exists(), "{extra:?} left {f}");
        }
    }
    // An explicit trace window: the frame and its waveform run, then the
    // check finds the ray never traced; the waveform goes too.
    let mut args = base.to_vec();
    args.extend([
        "--mode",
        "cycle",
        "--follow-ray",
        "2:5",
        "--trace-window",
        "0..500",
    ]);
    let o = dualstream(&args);
    assert!(!o.status.success());
    for f in ["b.png", "b.vcd", "b.vcd.gtkw", "b.log"] {
        assert!(!t.join(f).exists(), "left {f}");
    }
}
