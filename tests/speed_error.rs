//! `bench speed-error`: every faster mode is compared against the full cycle model on
//! the same frame, and the figures are consistent with the modes' own runs.

use dualstream::config::Config;
use dualstream::speed_error::{SpeedErrorOpts, estimate, plot, run, table};

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
    let rows = run(&s, &c, &SpeedErrorOpts { small_tms: 2 }).unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r.mode.as_str()).collect();
    assert_eq!(
        names,
        [
            "cycle",
            "cycle-fixed",
            "functional+estimate",
            "small-chip",
            "quarter-pixels"
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
    // Modes that render the same frame render the same image: every ray agrees.
    for m in &rows[1..4] {
        assert_eq!(m.image_identical, Some(true), "{}", m.mode);
    }
    assert_eq!(rows[4].image_identical, None);
    // The stream lines do not depend on timing: the chip with either memory moves
    // as many lines within the timing-dependent hit-record merging.
    assert!(rows[1].err_lines.abs() < 0.1, "{}", rows[1].err_lines);
    let t = table(&rows);
    assert_eq!(t.lines().count(), 6, "{t}");
    assert_eq!(plot(&rows).matches("<circle").count(), 5);
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
    let e = run(&s, &c, &SpeedErrorOpts { small_tms: 4 }).unwrap_err();
    assert!(e.contains("--small-tms 4") && e.contains("chip.tms"), "{e}");
}

#[test]
fn two_small_chips_fit_a_serial_and_a_parallel_part() {
    let (s, mut c) = tiny();
    c.chip.tms = 8;
    let rows = run(&s, &c, &SpeedErrorOpts { small_tms: 2 }).unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r.mode.as_str()).collect();
    assert_eq!(names[3..5], ["small-chip", "small-chips-fit"]);
    let fit = &rows[4];
    assert_eq!(fit.image_identical, Some(true));
    assert!(fit.note.contains("2 and 4 TMs"), "{}", fit.note);
    // Both small runs together take longer than the linear mode's one run.
    assert!(fit.wall_s >= rows[3].wall_s);
}
