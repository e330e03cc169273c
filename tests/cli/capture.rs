//! Vectors (`--capture`, docs/rtl.md "Vectors"): one file per unit instance,
//! a row per cycle of its own clock, the same results with and without.

use std::path::Path;

use crate::common::Scratch;
use crate::{fails_with, run};

/// A vector file's header (`// key rest` lines) and rows (hex tokens).
fn read_vec(p: &Path) -> (Vec<(String, String)>, Vec<Vec<u128>>) {
    let text = std::fs::read_to_string(p).unwrap();
    let (mut head, mut rows) = (Vec::new(), Vec::new());
    for l in text.lines() {
        if let Some(h) = l.strip_prefix("// ") {
            let (k, v) = h.split_once(' ').unwrap_or((h, ""));
            head.push((k.to_string(), v.to_string()));
        } else {
            // Wide data tokens are only checked for being hex; the others are read.
            rows.push(
                l.split(' ')
                    .map(|t| {
                        assert!(t.bytes().all(|b| b.is_ascii_hexdigit()), "{t}");
                        u128::from_str_radix(&t[t.len().saturating_sub(32)..], 16).unwrap()
                    })
                    .collect(),
            );
        }
    }
    (head, rows)
}

fn render_args(t: &Scratch, name: &str) -> Vec<String> {
    let cfg = t.join("chip.toml");
    std::fs::write(
        &cfg,
        "[tm]\ntps = 4\n[chip]\ntms = 2\n[chip.memory]\nmodel = \"gddr5\"\n",
    )
    .unwrap();
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let mut a: Vec<String> = vec!["--config".into(), s(&cfg)];
    a.extend(
        [
            "render",
            "--mode",
            "cycle",
            "--scene",
            "tiny",
            "--res",
            "8x8",
            "--bounces",
            "1",
        ]
        .map(String::from),
    );
    a.extend([
        "--out".into(),
        s(&t.join(format!("{name}.png"))),
        "--stats".into(),
        s(&t.join(format!("{name}.json"))),
    ]);
    a
}

/// The statistics but the header, the wall times and the simulator's steps by lanes
/// (how the kernel ran: a capture, like a waveform, runs one lane).
fn stats_without_times(p: &Path) -> String {
    // The header says how it was run (the command differs): not a result.
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
    v.as_object_mut().unwrap().remove("header");
    let lanes = v["chip"]
        .as_object_mut()
        .unwrap()
        .remove("sim_steps_by_lanes");
    assert!(
        lanes.is_some(),
        "the lanes figure moved: update this filter"
    );
    let s = serde_json::to_string_pretty(&v).unwrap();
    s.lines()
        .filter(|l| !l.contains("_s\":") && !l.contains("wall"))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn render_captures_vectors_per_instance_and_changes_no_result() {
    let t = Scratch::new("capture-render");
    let plain = render_args(&t, "plain");
    let o = run(&plain.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let dir = t.join("vec");
    let mut cap = render_args(&t, "cap");
    cap.extend(
        [
            "--capture",
            "tm0.staging_buffer,mem_ctrl0",
            "--capture-window",
            "0..",
            "--capture-dir",
        ]
        .map(String::from),
    );
    cap.push(dir.to_str().unwrap().into());
    let o = run(&cap.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("vectors: ") && out.contains("chip.tm0.staging_buffer.vec"),
        "{out}"
    );
    // Results are bit-identical.
    assert_eq!(
        std::fs::read(t.join("plain.png")).unwrap(),
        std::fs::read(t.join("cap.png")).unwrap()
    );
    assert!(
        stats_without_times(&t.join("plain.json")) == stats_without_times(&t.join("cap.json")),
        "capturing changed a statistic"
    );
    // One file per instance, nothing else left.
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["chip.mem_ctrl0.vec", "chip.tm0.staging_buffer.vec"]);

    let (head, rows) = read_vec(&dir.join("chip.tm0.staging_buffer.vec"));
    let get = |k: &str| head.iter().find(|h| h.0 == k).map(|h| h.1.clone());
    assert_eq!(get("dualstream").as_deref(), Some("vectors 1"));
    assert_eq!(get("module").as_deref(), Some("staging_buffer"));
    assert_eq!(get("clock").as_deref(), Some("core 1000"));
    assert_eq!(get("from_reset").as_deref(), Some("1"));
    let ports: Vec<&String> = head
        .iter()
        .filter(|h| h.0 == "port")
        .map(|h| &h.1)
        .collect();
    assert_eq!(ports.len(), 5, "fill and 4 TPs: {ports:?}");
    assert!(ports[0].starts_with("fill in ") && ports[0].ends_with(" sb_fill_t"));
    assert!(ports[1].starts_with("ray_0 out 384 sb_ray_t"), "{ports:?}");
    assert_eq!(get("rows"), Some(rows.len().to_string()));
    let (mut fills, mut outs) = (0, 0);
    for (i, r) in rows.iter().enumerate() {
        assert_eq!(r[0], i as u128, "a row per cycle, from 0");
        assert_eq!(r.len(), 1 + 3 * 5);
        fills += (r[1] & r[3]) as u64;
        outs += (1..5)
            .map(|k| (r[1 + 3 * k] & r[3 + 3 * k]) as u64)
            .sum::<u64>();
    }
    // Every ray staged leaves for a TP: the transfers agree.
    assert!(fills > 0);
    assert_eq!(fills, outs);
    // The DRAM controller's rows count its own (2 GHz) clock.
    let (head, rows) = read_vec(&dir.join("chip.mem_ctrl0.vec"));
    assert!(
        head.iter().any(|h| h.0 == "clock" && h.1 == "dram 500"),
        "{head:?}"
    );
    let core_rows = get("rows").unwrap().parse::<usize>().unwrap();
    assert!(
        rows.len() >= 2 * core_rows - 2,
        "{} vs {core_rows}",
        rows.len()
    );
}

#[test]
fn capture_windows_and_bad_names() {
    let t = Scratch::new("capture-tb");
    let dir = t.join("v");
    let d = dir.to_str().unwrap();
    let o = run(&[
        "tb",
        "hit_updater",
        "--cycles",
        "600",
        "--capture",
        "hit_updater",
        "--capture-from",
        "100",
        "--capture-to",
        "399",
        "--capture-dir",
        d,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (head, rows) = read_vec(&dir.join("tb.hit_record_updater.vec"));
    assert!(
        head.iter().any(|h| h.0 == "window" && h.1 == "100 399"),
        "{head:?}"
    );
    assert!(head.iter().any(|h| h.0 == "from_reset" && h.1 == "0"));
    assert_eq!(rows.len(), 300);
    assert_eq!(rows[0][0], 100);
    let r = render_args(&t, "x");
    let mut bad: Vec<&str> = r.iter().map(String::as_str).collect();
    bad.extend(["--capture", "tm0.stagingbuffer"]);
    fails_with(
        &bad,
        &[
            "--capture",
            "tm0.stagingbuffer",
            "staging_buffer",
            "tm0..tm1",
        ],
    );
    fails_with(
        &[
            "render",
            "--capture",
            "tm0",
            "--out",
            t.join("f.png").to_str().unwrap(),
        ],
        &["--mode cycle"],
    );
    fails_with(
        &["tb", "hit_updater", "--capture-window", "0..10"],
        &["--capture UNITS"],
    );
    fails_with(
        &["tb", "hit_updater", "--capture", "l1", "--capture-dir", d],
        &["no unit matches", "tb.hit_record_updater"],
    );
}
