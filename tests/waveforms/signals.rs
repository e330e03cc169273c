//! What each signal means: fields agree with the packed vector they come
//! from, clocks toggle at their periods, and `fire` is `valid & ready`.

use std::collections::BTreeSet;

use crate::common::Scratch;
use crate::read::Wave;
use crate::{chip_trace, have, read};

/// A window of the 8-TM chip (a TP and a GDDR5 channel: both clock domains)
/// as VCD, and as FST when fst2vcd is there.
fn chip_waves(d: &Scratch) -> Vec<Wave> {
    let mut waves = Vec::new();
    for ext in ["vcd", "fst"] {
        if ext == "fst" && !have("fst2vcd") {
            continue;
        }
        let p = d.join(format!("c.{ext}"));
        chip_trace(
            &p,
            "chip.tm0.tp0,chip.tm0.l1,mem_ctrl0",
            "12000..12600",
            &[],
        );
        waves.push(if ext == "vcd" {
            read::vcd(&p)
        } else {
            read::fst(&p).0
        });
    }
    waves
}

/// LSB-first bits of a value as the reader gives it (binary text, MSB
/// first; a real is the f32 it was made from).
fn bits_of(v: &str, real: bool, width: usize) -> Vec<bool> {
    let mut b: Vec<bool> = if real {
        let x: f32 = v.parse().unwrap();
        (0..32).map(|k| (x.to_bits() >> k) & 1 == 1).collect()
    } else {
        v.bytes().rev().map(|c| c == b'1').collect()
    };
    b.resize(width, false);
    b
}

/// Every change time of the given signals.
fn times(w: &Wave, paths: &[&String]) -> BTreeSet<u64> {
    paths
        .iter()
        .flat_map(|p| w.changes.get(*p).into_iter().flatten().map(|c| c.0))
        .collect()
}

fn check_fields(w: &Wave) -> usize {
    let mut checked = 0;
    // A port's packed vector is `x_data` with fields `x.*`; a struct
    // register's is `r` with fields `r.*`.
    for data in &w.order {
        let port = data.strip_suffix("_data").unwrap_or(data);
        let fields: Vec<&String> = w
            .order
            .iter()
            .filter(|p| p.starts_with(&format!("{port}.")))
            .collect();
        if fields.is_empty() {
            continue;
        }
        let width = w.vars[data].width as usize;
        let fw = |f: &String| {
            if w.vars[f].kind == "real" {
                32
            } else {
                w.vars[f].width as usize
            }
        };
        let total: usize = fields.iter().map(|f| fw(f)).sum();
        assert_eq!(total, width, "{port}: fields tile the {width}-bit vector");
        let mut all = fields.clone();
        all.push(data);
        for t in times(w, &all) {
            let Some(d) = w.at(data, t) else { continue };
            let mut joined = Vec::new();
            for f in &fields {
                let v = w
                    .at(f, t)
                    .unwrap_or_else(|| panic!("{f} has a value at {t}"));
                joined.extend(bits_of(v, w.vars[*f].kind == "real", fw(f)));
            }
            assert_eq!(
                joined,
                bits_of(d, false, width),
                "{port} at {t}: fields = packed vector"
            );
            checked += 1;
        }
    }
    checked
}

fn check_clock(w: &Wave, name: &str, period: u64) {
    let path = w
        .order
        .iter()
        .find(|p| p.ends_with(&format!(".{name}")))
        .expect(name);
    let c = &w.changes[path];
    assert!(c.len() > 100, "{name} toggles ({} changes)", c.len());
    for pair in c.windows(2) {
        assert_eq!(
            pair[1].0 - pair[0].0,
            period / 2,
            "{name}: half a period apart"
        );
        assert_ne!(pair[1].1, pair[0].1, "{name}: alternates");
    }
    for (t, v) in c {
        assert_eq!(
            v == "1",
            t % period == 0,
            "{name} at {t}: high from each edge"
        );
    }
}

fn check_fire(w: &Wave) -> usize {
    let mut ports = 0;
    for fire in w.order.iter().filter(|p| p.ends_with("_fire")) {
        let port = fire.trim_end_matches("_fire");
        let (valid, ready) = (format!("{port}_valid"), format!("{port}_ready"));
        for t in times(w, &[fire, &valid, &ready]) {
            let (v, r, f) = (w.at(&valid, t), w.at(&ready, t), w.at(fire, t));
            assert_eq!(
                f == Some("1"),
                v == Some("1") && r == Some("1"),
                "{fire} at {t}"
            );
        }
        ports += 1;
    }
    ports
}

/// The chip window in both formats: fields, clocks, fire and the reset.
#[test]
fn fields_clocks_and_fire_mean_what_they_say() {
    let d = Scratch::new("wave-signals");
    for w in chip_waves(&d) {
        let fields = check_fields(&w);
        assert!(fields > 50, "field samples checked: {fields}");
        check_clock(&w, "clk_core", 1000);
        check_clock(&w, "clk_dram", 500);
        let rst = w
            .order
            .iter()
            .find(|p| p.ends_with(".rst"))
            .expect("a reset");
        assert!(w.changes[rst].iter().all(|c| c.1 == "0"));
        assert!(
            check_fire(&w) >= 13 + 2,
            "every port of the TP and the L1 has fire"
        );
        // Floats are numbers, as Verilator's --trace-structs shows them;
        // struct registers have fields too.
        assert_eq!(w.vars["chip.tm0.tp0.ray.ray.origin.x"].kind, "real");
        assert_eq!(w.vars["chip.tm0.tp0.best.t"].kind, "real");
        assert_eq!(w.vars["chip.tm0.tp0.cur.ray.ray_id"].width, 32);
        assert_eq!(w.vars["chip.tm0.tp0.ray.ray.ray_id"].width, 32);
    }
}

/// The checkers catch what they are for: a field off by one bit, a clock
/// at the wrong period, a fire that is not valid & ready.
#[test]
fn the_signal_checks_catch_faults() {
    let d = Scratch::new("wave-faults");
    let w = chip_waves(&d).remove(0);
    let caught = |f: &dyn Fn(&mut Wave)| {
        let mut bad = Wave {
            vars: w.vars.clone(),
            order: w.order.clone(),
            changes: w.changes.clone(),
            end: w.end,
            ..Wave::default()
        };
        f(&mut bad);
        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            check_fields(&bad);
            check_clock(&bad, "clk_core", 1000);
            check_fire(&bad);
        }))
        .is_err()
    };
    assert!(caught(&|b| {
        let p = "chip.tm0.tp0.ray.ray.ray_id".to_string();
        for c in b.changes.get_mut(&p).unwrap() {
            c.1 = format!("{}1", c.1); // shifted one bit
        }
    }));
    assert!(caught(&|b| {
        let p = b
            .order
            .iter()
            .find(|p| p.ends_with(".clk_core"))
            .unwrap()
            .clone();
        let c = b.changes.get_mut(&p).unwrap();
        c.remove(3);
    }));
    assert!(caught(&|b| {
        let p = "chip.tm0.tp0.ray_fire".to_string();
        for c in b.changes.get_mut(&p).unwrap() {
            c.1 = if c.1 == "1" { "0".into() } else { "1".into() };
        }
    }));
}
