//! The GTKWave save file written beside every trace (`x.vcd.gtkw`,
//! `x.fst.gtkw`): GTKWave itself loads it (under Xvfb), shows every signal it
//! names, shows FSM states by name (a VCD through the generated filter, an
//! FST through its enum table) and floats as numbers, and opens on the traced
//! window; moved elsewhere with its trace and filters, it opens the same
//! from any working directory.

use std::path::Path;
use std::process::Command;

use crate::common::{Scratch, succeeds};
use crate::{chip_trace, have, read};

/// Runs GTKWave in `cwd` on `trace` (none: the one the save file names)
/// with `save` and a Tcl script that reports what it shows, then quits;
/// returns the report lines (`KEY value`).
fn gtkwave_report(dir: &Path, cwd: &Path, trace: Option<&Path>, save: &Path) -> Vec<String> {
    // GTKWave rewrites the save file it was given when a script saves:
    // give it a copy, beside the original (the files it names are relative
    // to it).
    let copy = save.with_file_name("view.gtkw");
    std::fs::copy(save, &copy).unwrap();
    let tcl = dir.join("report.tcl");
    std::fs::write(
        &tcl,
        r#"puts "DISPLAYED [llength [gtkwave::getDisplayedSignals]]"
gtkwave::setMarker 12300000
puts "STATE [gtkwave::getTraceValueAtMarkerFromName {chip.tm0.tp0.state[4:0]}]"
puts "REAL [gtkwave::getTraceValueAtMarkerFromName chip.tm0.tp0.ray.ray.origin.x]"
puts "WINDOW [gtkwave::getWindowStartTime] [gtkwave::getWindowEndTime]"
gtkwave::/File/Quit
"#,
    )
    .unwrap();
    let o = succeeds(
        Command::new("timeout")
            .current_dir(cwd)
            .args(["120", "xvfb-run", "-a", "gtkwave", "-S"])
            .arg(&tcl)
            .args(trace)
            .arg(&copy),
        "gtkwave",
    );
    std::fs::remove_file(&copy).unwrap();
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    out.lines().map(str::to_string).collect()
}

fn value<'a>(report: &'a [String], key: &str) -> &'a str {
    report
        .iter()
        .find_map(|l| l.strip_prefix(&format!("{key} ")))
        .unwrap_or_else(|| panic!("GTKWave reported no {key}: {report:?}"))
}

#[test]
fn gtkwave_opens_the_save_file_on_named_states_fields_and_the_window() {
    if !have("gtkwave") || !have("xvfb-run") {
        return;
    }
    let d = Scratch::new("wave-gtkw");
    for ext in ["vcd", "fst"] {
        let trace = d.join(format!("c.{ext}"));
        chip_trace(
            &trace,
            "chip.tm0.tp0,chip.tm0.l1,mem_ctrl0",
            "12000..12600",
            &[],
        );
        let save = d.join(format!("c.{ext}.gtkw"));
        let text = std::fs::read_to_string(&save).unwrap();
        // Signal lines: everything that is not a directive, flag, group or filter.
        let named: Vec<&str> = text
            .lines()
            .filter(|l| !l.is_empty() && !"[*@-^".contains(&l[..1]))
            .collect();
        // Each names a variable of the trace (vectors carry their range).
        let wave = if ext == "vcd" {
            read::vcd(&trace)
        } else {
            read::fst(&trace).0
        };
        for n in &named {
            let bare = n.split('[').next().unwrap();
            assert!(wave.vars.contains_key(bare), "{n} is not in the trace");
        }
        assert_eq!(
            named.len(),
            wave.vars.len(),
            "every traced signal is in the view"
        );
        assert!(named[0].ends_with("clk_core"), "clocks first: {named:?}");
        // A unit's group opens on its FSM state, above its ports and their
        // payloads' fields.
        let lines: Vec<&str> = text.lines().collect();
        let tp = lines.iter().position(|l| *l == "-chip.tm0.tp0").unwrap();
        let first = lines[tp + 1..].iter().find(|l| !"[*@-^".contains(&l[..1]));
        assert_eq!(
            first,
            Some(&"chip.tm0.tp0.state[4:0]"),
            "{ext}: state first"
        );
        let r = gtkwave_report(&d, &d, Some(&trace), &save);
        assert_eq!(
            value(&r, "DISPLAYED"),
            named.len().to_string(),
            "{ext}: GTKWave shows them all"
        );
        let state = value(&r, "STATE");
        assert!(
            state.chars().next().unwrap().is_ascii_uppercase(),
            "{ext}: state by name, got {state}"
        );
        let x: f64 = value(&r, "REAL")
            .parse()
            .expect("a float field shows as a number");
        assert!(x.is_finite());
        let w: Vec<u64> = value(&r, "WINDOW")
            .split(' ')
            .map(|t| t.parse().unwrap())
            .collect();
        assert_eq!(w[0], 12_000_000, "{ext}: opens at the window's start");
        assert!(
            (12_500_000..13_200_000).contains(&w[1]),
            "{ext}: shows the window: {w:?}"
        );
    }
    // Each format has its own save file, naming its own trace; a VCD names
    // states through a filter file beside it, by a relative path.
    for ext in ["vcd", "fst"] {
        let text = std::fs::read_to_string(d.join(format!("c.{ext}.gtkw"))).unwrap();
        assert!(
            text.contains(&format!("[dumpfile] \"c.{ext}\"\n")),
            "{text}"
        );
        assert_eq!(text.contains("^1 c.vcd.tp_state.filter\n"), ext == "vcd");
    }
    let filter = std::fs::read_to_string(d.join("c.vcd.tp_state.filter")).unwrap();
    assert!(
        filter.contains("\n0 Idle\n") && filter.contains("\n1 Fetch\n"),
        "{filter}"
    );
    // Moved together to another directory, opened from a third one (with
    // the trace named, and with the save file alone): states still by name.
    let moved = d.join("elsewhere/deeper");
    std::fs::create_dir_all(&moved).unwrap();
    for e in std::fs::read_dir(&*d).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        if name.starts_with("c.vcd") {
            std::fs::rename(d.join(&name), moved.join(&name)).unwrap();
        }
    }
    let cwd = d.join("cwd");
    std::fs::create_dir_all(&cwd).unwrap();
    let save = moved.join("c.vcd.gtkw");
    for trace in [Some(moved.join("c.vcd")), None] {
        let r = gtkwave_report(&d, &cwd, trace.as_deref(), &save);
        let state = value(&r, "STATE");
        assert!(
            state.chars().next().unwrap().is_ascii_uppercase(),
            "moved ({trace:?}): state by name, got {state}"
        );
    }
}
