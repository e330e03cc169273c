//! The configuration: `--config` files (impossible ones refused), `dualstream
//! config`, the example configs, `--threads` (on the commands that simulate) and the global `--memory`.

use crate::common::Scratch;
use crate::{fails_with, run};

#[test]
fn impossible_config() {
    let t = Scratch::new("cli-config");
    let cfg = t.join("bad.toml");
    std::fs::write(&cfg, "[box_pipe]\nlatency = 0\ninterval = 1\n").unwrap();
    fails_with(
        &["--config", cfg.to_str().unwrap(), "tb", "box_pipe"],
        &["box_pipe.latency = 0", "set latency"],
    );
    std::fs::write(&cfg, "[tri_pipe]\nlatency = 31\ninterval = 0\n").unwrap();
    fails_with(
        &["--config", cfg.to_str().unwrap(), "tb", "tri_pipe"],
        &["interval = 0"],
    );
    std::fs::write(&cfg, "[box_pipe\n").unwrap();
    fails_with(
        &["--config", cfg.to_str().unwrap(), "tb", "box_pipe"],
        &["config"],
    );
    fails_with(
        &["--config", "/nonexistent/x.toml", "tb", "box_pipe"],
        &["cannot read config", "/nonexistent/x.toml"],
    );
}

#[test]
fn prints_the_default_config() {
    let o = run(&["config", "--print-default"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success());
    assert!(
        out.contains("[box_pipe]") && out.contains("latency = 8"),
        "{out}"
    );
    // Every key with its comment, the three memory sections told apart.
    assert!(
        out.contains("# Thread multiprocessors: 128 [DS17 §5.1]"),
        "{out}"
    );
    assert!(out.contains("[memory] is the DRAM image's layout"), "{out}");
    // Given back as --config, it is the default: the same as no file.
    let t = Scratch::new("cli-config-default");
    let p = t.join("default.toml");
    std::fs::write(&p, out.as_bytes()).unwrap();
    let loaded = run(&["--config", p.to_str().unwrap(), "config"]);
    assert!(
        loaded.status.success(),
        "{}",
        String::from_utf8_lossy(&loaded.stderr)
    );
    assert_eq!(loaded.stdout, run(&["config"]).stdout);
}

#[test]
fn threads_and_memory_choices_are_checked() {
    fails_with(
        &["render", "--threads", "0", "--res", "4x4"],
        &["--threads 0", "auto"],
    );
    fails_with(
        &["render", "--threads", "9999", "--res", "4x4"],
        &["core(s)", "auto"],
    );
    fails_with(
        &["scene", "info", "cornell", "--threads", "two"],
        &["not a number"],
    );
    // Only the commands that simulate take it: `config` and `hdl` neither
    // list nor accept it.
    fails_with(&["config", "--threads", "1"], &["--threads"]);
    let o = run(&["hdl", "--help"]);
    assert!(!String::from_utf8_lossy(&o.stdout).contains("--threads"));
    fails_with(
        &["--memory", "sram", "config", "--print-default"],
        &["gddr5", "fixed"],
    );
    // `config` without --print-default prints the configuration in force.
    let o = run(&["--memory", "fixed", "config"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("model = \"fixed\""));
    let o = run(&["config"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("model = \"gddr5\""));
}

/// The example configurations the README points to load and say what they set.
#[test]
fn example_configs_load() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/examples");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "toml") {
            let o = run(&["--config", p.to_str().unwrap(), "config"]);
            assert!(
                o.status.success(),
                "{}: {}",
                p.display(),
                String::from_utf8_lossy(&o.stderr)
            );
            n += 1;
        }
    }
    assert!(n > 0, "no example configs in {}", dir.display());
    let o = run(&[
        "--config",
        dir.join("chip-8tms.toml").to_str().unwrap(),
        "config",
    ]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("tms = 8"));
}
