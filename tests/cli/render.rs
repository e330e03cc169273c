//! `dualstream render`: functional, cycle and time-sampled frames, their images,
//! statistics, ray dumps and pass logs, and bad input.

use crate::common::Scratch;
use crate::{fails_with, run};

#[test]
fn render_writes_image_and_statistics() {
    let t = Scratch::new("cli-render");
    let (png, json) = (t.join("r.png"), t.join("r.json"));
    let o = run(&[
        "render",
        "--scene",
        "tiny",
        "--res",
        "16x16",
        "--out",
        png.to_str().unwrap(),
        "--stats",
        json.to_str().unwrap(),
        "--verify",
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        out.contains("ray duplication") && out.contains("verified"),
        "{out}"
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(stats["total"]["rays"].as_u64().unwrap() > 256);
    assert_eq!(stats["width"], 16);
    // The header: what made the file, before the statistics.
    let h = &stats["header"];
    assert_eq!(h["tool"], "dualstream");
    assert_eq!(h["run"]["scene"], "tiny");
    assert_eq!(h["run"]["resolution"], serde_json::json!([16, 16]));
    assert_eq!(h["run"]["mode"], "functional");
    assert_eq!(h["run"]["seed"], 1);
    assert!(h["config"]["chip"]["tms"].as_u64().unwrap() > 0);
    assert_eq!(h["config_hash"].as_str().unwrap().len(), 16);
    assert!(h["wall_s"].as_f64().unwrap() > 0.0);
    assert!(h["machine"]["cores"].as_u64().unwrap() >= 1);
    // Built inside this checkout: its revision (test binaries live in its
    // target/ too).
    if std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(".git")
        .exists()
    {
        let rev = h["git_revision"].as_str().expect("a revision");
        assert!(rev.len() >= 40, "{rev}");
    }
    let text = std::fs::read_to_string(&json).unwrap();
    assert!(
        text.trim_start().starts_with("{\n  \"header\""),
        "header first"
    );
}

/// `--stats -` writes the JSON to stdout, alone (the summary goes to
/// stderr), so it pipes into a JSON reader; the statistics equal a file's.
#[test]
fn render_stats_to_stdout() {
    let t = Scratch::new("cli-stats-stdout");
    let (png, json) = (t.join("r.png"), t.join("r.json"));
    let args = |stats: &str| {
        let p = png.to_str().unwrap().to_string();
        vec![
            "render".to_string(),
            "--scene".into(),
            "tiny".into(),
            "--res".into(),
            "8x8".into(),
            "--out".into(),
            p,
            "--stats".into(),
            stats.to_string(),
        ]
    };
    let o = run(&args("-").iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut piped: serde_json::Value =
        serde_json::from_slice(&o.stdout).expect("stdout is JSON alone");
    assert!(String::from_utf8_lossy(&o.stderr).contains("ray duplication"));
    assert!(!std::path::Path::new("-").exists(), "no file named -");
    let o = run(&args(json.to_str().unwrap())
        .iter()
        .map(String::as_str)
        .collect::<Vec<_>>());
    assert!(o.status.success());
    let mut file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    // Build times are wall clock; the rest is bit for bit.
    for v in [&mut piped, &mut file] {
        let o = v.as_object_mut().unwrap();
        o.remove("header");
        o.retain(|k, _| !k.ends_with("_s"));
        o["accel"]
            .as_object_mut()
            .unwrap()
            .retain(|k, _| !k.ends_with("_s"));
    }
    assert_eq!(piped, file, "the same statistics");
}

#[test]
fn render_and_scene_bad_input() {
    let t = Scratch::new("cli-bad");
    fails_with(
        &["render", "--scene", "tiny", "--res", "0x10"],
        &["width = 0"],
    );
    fails_with(
        &["render", "--scene", "tiny", "--res", "banana"],
        &["WIDTHxHEIGHT"],
    );
    fails_with(
        &["render", "--scene", "tiny", "--bounces", "17"],
        &["bounces"],
    );
    fails_with(
        &["render", "--scene", "tiny", "--mode", "warp"],
        &[
            "invalid value 'warp'",
            "functional, reference, cycle, windows",
        ],
    );
    // A typo gets the mode it was meant to be.
    fails_with(
        &["render", "--scene", "tiny", "--mode", "cycles"],
        &["a similar value exists: 'cycle'"],
    );
    fails_with(
        &["render", "--scene", "/nonexistent/scene.obj"],
        &["/nonexistent/scene.obj"],
    );
    fails_with(
        &[
            "render",
            "--scene",
            "tiny",
            "--out",
            "/nonexistent-dir/x.png",
        ],
        &["--out"],
    );
    fails_with(&["scene", "info", "nosuchscene"], &["nosuchscene"]);
    let cfg = t.join("seg.toml");
    std::fs::write(&cfg, "[accel]\nsegment_bytes = 1000\n").unwrap();
    fails_with(
        &["--config", cfg.to_str().unwrap(), "scene", "info", "tiny"],
        &["segment_bytes", "multiple of the DRAM row"],
    );
}

#[test]
fn dump_rays_writes_each_wavefront() {
    let t = Scratch::new("cli-dump");
    let dir = t.join("dump");
    let o = run(&[
        "render",
        "--scene",
        "tiny",
        "--res",
        "8x8",
        "--out",
        t.join("d.png").to_str().unwrap(),
        "--dump-rays",
        dir.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rays = std::fs::read(dir.join("wave0_rays.bin")).unwrap();
    let hits = std::fs::read(dir.join("wave0_hits.bin")).unwrap();
    assert_eq!(
        rays.len(),
        64 * 32,
        "wavefront 0: one primary ray per pixel"
    );
    assert_eq!(hits.len(), 64 * 16);
    // Ray 5's id is pixel 5, a bounce ray.
    assert_eq!(
        u32::from_le_bytes(rays[5 * 32 + 24..5 * 32 + 28].try_into().unwrap()),
        5
    );
    assert!(dir.join("wave1_rays.bin").exists());
}

/// `render --mode windows`: time sampling as a user runs it. The image is the
/// cycle model's (the frame is the functional model's, every ray the same), the
/// summary and the statistics carry the estimate of the cycle model's figures,
/// and options that need a clocked frame are refused.
#[test]
fn render_in_windows_estimates_the_cycle_frame() {
    let t = Scratch::new("cli-win");
    let cfg = t.join("win.toml");
    std::fs::write(
        &cfg,
        "[tm]\ntps = 4\n[chip]\ntms = 2\n[chip.memory]\nmodel = \"gddr5\"\n",
    )
    .unwrap();
    let (w_png, c_png, json) = (t.join("win.png"), t.join("cyc.png"), t.join("win.json"));
    let c = cfg.to_str().unwrap();
    let args = |mode: &'static str, png: &std::path::Path| -> Vec<String> {
        [
            "--config",
            c,
            "render",
            "--scene",
            "tiny",
            "--res",
            "16x16",
            "--bounces",
            "1",
            "--mode",
            mode,
            "--out",
        ]
        .iter()
        .map(|x| x.to_string())
        .chain([png.to_str().unwrap().to_string()])
        .collect()
    };
    let mut a = args("windows", &w_png);
    a.extend(["--stats".to_string(), json.to_str().unwrap().to_string()]);
    let o = run(&a.iter().map(|x| x.as_str()).collect::<Vec<_>>());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        out.contains("time sampling:") && out.contains("docs/speed-error.md"),
        "{out}"
    );
    let o = run(&args("cycle", &c_png)
        .iter()
        .map(|x| x.as_str())
        .collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read(&w_png).unwrap(),
        std::fs::read(&c_png).unwrap(),
        "the same image"
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let e = &v["estimate"];
    for k in [
        "cycles",
        "ray_lines",
        "dram_paper_j",
        "dram_physical_j",
        "onchip_j",
    ] {
        assert!(e[k].as_f64().unwrap() > 0.0, "{k}: {e}");
    }
    assert!(
        v["total"]["rays"].as_u64().unwrap() > 0,
        "the frame's statistics too"
    );
    let mut a = args("windows", &w_png);
    a.extend([
        "--vcd".to_string(),
        t.join("win.vcd").to_str().unwrap().to_string(),
    ]);
    fails_with(
        &a.iter().map(|x| x.as_str()).collect::<Vec<_>>(),
        &["--mode cycle"],
    );
}

#[test]
fn the_pass_log_is_written_in_cycle_mode_and_refused_elsewhere() {
    let t = Scratch::new("cli-passes");
    let (csv, png) = (t.join("passes.csv"), t.join("passes.png"));
    let args = [
        "render",
        "--scene",
        "cornell",
        "--res",
        "16x16",
        "--bounces",
        "1",
        "--out",
        png.to_str().unwrap(),
        "--pass-log",
        csv.to_str().unwrap(),
    ];
    fails_with(
        &[&args[..], &["--mode", "functional"]].concat(),
        &["--pass-log", "--mode cycle"],
    );
    let o = run(&[&args[..], &["--mode", "cycle"]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The summary ends with the frame in the paper's terms: its time is the
    // total cycles at the core clock.
    let out = String::from_utf8_lossy(&o.stdout);
    let cycles: u64 = out
        .lines()
        .find(|l| l.contains("total cycles"))
        .and_then(|l| l.split_whitespace().last())
        .unwrap()
        .parse()
        .unwrap();
    let head = out
        .lines()
        .find(|l| l.starts_with("frame: "))
        .expect("a frame line");
    assert!(
        head.contains(&format!("({cycles} cycles at 1.00 GHz)"))
            && head.contains(&format!("{:.3} ms", cycles as f64 * 1e-6))
            && head.contains("M rays/s"),
        "{head}"
    );
    assert!(out.contains("($: 64-byte cache lines"), "{out}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("run,segment,rays,admit,retire"));
    let rows: Vec<Vec<u64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    // The primary rays' root pass retires first, carrying every ray.
    assert_eq!(rows[0][..3], [0, 0, 256]);
    assert!(rows.iter().all(|r| r.len() == 5 && r[3] < r[4]));
    assert!(rows.iter().any(|r| r[0] == 1), "the bounce's passes too");
}

#[test]
fn coordinates_beyond_the_datapath_range_name_the_vertex_and_the_fix() {
    let t = Scratch::new("cli-range");
    // Near 1e38: cross products overflow (once refused as "all degenerate").
    let huge = t.join("huge.obj");
    std::fs::write(&huge, "v 1e38 0 0\nv 0 1e38 0\nv 0 0 1e38\nf 1 2 3\n").unwrap();
    // One small triangle far out (once: "camera up is parallel to the view").
    let far = t.join("far.obj");
    std::fs::write(&far, "v 0 0 0\nv 1e38 1 0\nv 1e38 0 1\nf 1 2 3\n").unwrap();
    for (f, vertex) in [
        (&huge, "huge.obj:1: vertex 1"),
        (&far, "far.obj:2: vertex 2"),
    ] {
        let f = f.to_str().unwrap();
        for args in [
            vec!["scene", "info", f],
            vec!["render", "--scene", f, "--res", "8x8"],
        ] {
            fails_with(&args, &[vertex, "1e6", "f32 datapath", "scale or recentre"]);
        }
    }
}

/// A TP whose traversal stack overflows stops; the chip then starves. The
/// error names the stack and the setting to raise, not the starvation.
#[test]
fn a_tp_stack_overflow_names_the_scratchpad() {
    let t = Scratch::new("cli-stack");
    let cfg = t.join("small.toml");
    std::fs::write(&cfg, "[tm]\nscratchpad_bytes = 36\n").unwrap();
    let png = t.join("s.png");
    fails_with(
        &[
            "--config",
            cfg.to_str().unwrap(),
            "render",
            "--scene",
            "cornell",
            "--mode",
            "cycle",
            "--res",
            "8x8",
            "--threads",
            "1",
            "--out",
            png.to_str().unwrap(),
        ],
        &[
            "traversal stack",
            "overflowed",
            "tm.scratchpad_bytes = 36 holds 3 entries",
            "can need up to",
        ],
    );
}

/// `--hdr x.pfm` writes the linear radiance: a PFM whose every pixel,
/// encoded as the PNG is, gives the PNG's bytes (same orientation, same
/// values, unclamped: some exceed 1 where the PNG saturates); another
/// extension is refused before the frame.
#[test]
fn render_writes_a_linear_hdr_image() {
    let t = Scratch::new("cli-hdr");
    let (png, pfm) = (t.join("r.png"), t.join("r.pfm"));
    let o = run(&[
        "render",
        "--res",
        "24x16",
        "--out",
        png.to_str().unwrap(),
        "--hdr",
        pfm.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bytes = std::fs::read(&pfm).unwrap();
    let head = b"PF\n24 16\n-1.0\n";
    assert_eq!(&bytes[..head.len()], head);
    let floats: Vec<f32> = bytes[head.len()..]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    assert_eq!(floats.len(), 24 * 16 * 3);
    let img = image::open(&png).unwrap().to_rgb8();
    let mut lit = 0;
    for y in 0..16u32 {
        for x in 0..24u32 {
            // PFM rows go bottom to top.
            let i = (((15 - y) * 24 + x) * 3) as usize;
            let c = glam::Vec3::new(floats[i], floats[i + 1], floats[i + 2]);
            assert_eq!(
                dualstream::render::output::rgb8(c),
                img.get_pixel(x, y).0,
                "pixel {x},{y}"
            );
            lit += (c.max_element() > 0.0) as u32;
        }
    }
    assert!(lit > 100, "a lit image ({lit} pixels)");
    fails_with(
        &[
            "render",
            "--res",
            "4x4",
            "--hdr",
            t.join("r.exr").to_str().unwrap(),
        ],
        &["give a path ending in .pfm"],
    );
    assert!(!t.join("r.exr").exists());
}

#[test]
fn render_spp_traces_more_paths_and_says_so() {
    let t = Scratch::new("cli-render-spp");
    let (png, json) = (t.join("s.png"), t.join("s.json"));
    let o = run(&[
        "render",
        "--scene",
        "tiny",
        "--res",
        "8x8",
        "--spp",
        "3",
        "--out",
        png.to_str().unwrap(),
        "--stats",
        json.to_str().unwrap(),
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("paths per pixel 3"), "{out}");
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(stats["spp"], 3);
    assert_eq!(stats["header"]["run"]["spp"], 3);
    assert_eq!(stats["waves"][0]["rays"], 3 * 64);
    fails_with(
        &["render", "--scene", "tiny", "--res", "8x8", "--spp", "0"],
        &["spp = 0", "1..="],
    );
    fails_with(
        &[
            "render", "--scene", "tiny", "--res", "8x8", "--spp", "2", "--mode", "windows",
        ],
        &["one path per pixel", "--spp 1"],
    );
}

/// Every array in `v` below `path`, other than lists of objects: positional
/// figures a reader would have to count to name.
fn positional(v: &serde_json::Value, path: &str, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Array(a) => {
            if a.iter().any(|x| !x.is_object()) {
                out.push(path.to_string());
            }
            for (i, x) in a.iter().enumerate() {
                positional(x, &format!("{path}[{i}]"), out);
            }
        }
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                positional(x, &format!("{path}.{k}"), out);
            }
        }
        _ => {}
    }
}

#[test]
fn render_stats_name_every_figure() {
    let t = Scratch::new("cli-render-named");
    let (png, json) = (t.join("n.png"), t.join("n.json"));
    let o = run(&[
        "render",
        "--scene",
        "tiny",
        "--res",
        "8x8",
        "--mode",
        "cycle",
        "--threads",
        "1",
        "--out",
        png.to_str().unwrap(),
        "--stats",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let mut arrays = Vec::new();
    positional(&v, "", &mut arrays);
    // The command line's words, and the resolution as [width, height].
    assert_eq!(arrays, [".header.command", ".header.run.resolution"]);
    let parts = v["energy"]["parts"].as_object().unwrap();
    assert!(parts["box_tests_j"].as_f64().unwrap() > 0.0, "{parts:?}");
    assert!(parts.keys().all(|k| k.ends_with("_j")), "{parts:?}");
    let sum: f64 = parts.values().map(|x| x.as_f64().unwrap()).sum();
    let total =
        v["energy"]["compute_j"].as_f64().unwrap() + v["energy"]["onchip_j"].as_f64().unwrap();
    assert!((sum - total).abs() <= 1e-9 * total, "{sum} vs {total}");
    // Counted when lanes run side by side: on one lane, none.
    assert!(v["chip"]["sim_steps_by_lanes"].is_object(), "{}", v["chip"]);
    assert!(v["chip"]["waves"][0]["lines_read"]["ray"].as_u64().unwrap() > 0);
}

#[test]
fn render_early_termination_flag_counts_and_refusals() {
    let t = Scratch::new("cli-render-et");
    let (png, json) = (t.join("r.png"), t.join("r.json"));
    let o = run(&[
        "render",
        "--scene",
        "cornell",
        "--res",
        "16x16",
        "--early-termination",
        "both",
        "--out",
        png.to_str().unwrap(),
        "--stats",
        json.to_str().unwrap(),
        "--verify",
    ]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{out}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        out.contains("early termination") && out.contains("rays dropped, pre-test"),
        "{out}"
    );
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(stats["early_termination"], "both");
    let e = &stats["total"]["early"];
    assert!(e["records_read"].as_u64().unwrap() > 0, "{e}");
    assert!(e.get("enqueues_avoided").is_some() && e.get("ray_lines_removed").is_some());
    assert_eq!(
        stats["header"]["config"]["chip"]["early_termination"], "both",
        "{}",
        stats["header"]
    );
    // A value that is not a choice, and the modes without it.
    fails_with(
        &["render", "--scene", "tiny", "--early-termination", "always"],
        &["always", "none, pre, post, both"],
    );
    for mode in ["cycle", "windows", "reference"] {
        fails_with(
            &[
                "render",
                "--scene",
                "tiny",
                "--mode",
                mode,
                "--early-termination",
                "pre",
            ],
            &[
                "early termination `pre` is in functional mode only so far",
                "--mode functional",
            ],
        );
    }
}
