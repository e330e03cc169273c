//! Sleeping, shadow mode, evaluation order and lanes change nothing: cycles,
//! statistics, waveforms and images are bit-identical.

use super::*;

use dualstream::rtl::UnitId;
use dualstream::rtl::unit::reset_mismatches;

/// Two evaluation threads (half of the TMs each) give the same cycles, statistics
/// of every unit and hit records as one, with the fixed-latency memory and with
/// GDDR5 on its own clock.
#[test]
fn two_threads_change_nothing() {
    for (what, cfg) in [("fixed", chip_cfg(4, 4)), ("gddr5", gddr5_cfg(4, 4))] {
        let one = SimOptions::default();
        let two = SimOptions {
            threads: 2,
            ..SimOptions::default()
        };
        let (base, p1) = run_tiny_chip_traced(cfg.clone(), one, None);
        // The same with a TM moving between the threads every 8 steps.
        let (m, _, _) = run_tiny_chip_balanced(cfg.clone(), two.clone(), None, true);
        assert!(
            m == base,
            "{what}: moving TMs between the threads changed the outcome"
        );
        let (r, p2) = run_tiny_chip_traced(cfg, two, None);
        assert!(base.cycles > 0);
        assert_eq!(p1, 0, "{what}: one thread handed steps to a worker");
        assert!(p2 > 0, "{what}: two threads never evaluated in parallel");
        assert!(
            r == base,
            "{what}: two threads changed cycles, statistics or hits"
        );
    }
}

/// Any lane count (3 and 4 oversubscribe this machine's cores: fine for
/// correctness) and the automatic choice, here switching among 1, 2, 4 and 5
/// lanes every 40 steps with load balancing on, give the same cycles, statistics
/// and hits as one thread.
#[test]
fn any_lane_count_and_auto_change_nothing() {
    let cfg = gddr5_cfg(5, 4);
    let (base, _) = run_tiny_chip_traced(cfg.clone(), SimOptions::default(), None);
    for n in [3, 4] {
        let (r, p) = run_tiny_chip_traced(
            cfg.clone(),
            SimOptions {
                threads: n,
                ..SimOptions::default()
            },
            None,
        );
        assert!(p > 0, "{n} lanes never evaluated in parallel");
        assert!(r == base, "{n} lanes changed cycles, statistics or hits");
    }
    let auto = SimOptions {
        threads: 5,
        auto_lanes: true,
        check_ready: true,
        ..SimOptions::default()
    };
    let (r, p, _) = run_tiny_chip_balanced(cfg, auto, None, true);
    assert!(p > 0, "auto never evaluated in parallel");
    assert!(r == base, "auto lanes changed cycles, statistics or hits");
}

/// A whole frame (5 bounces, shading on the TPs, L2, GDDR5) on two threads is
/// bit-identical to one thread.
#[test]
fn a_frame_on_two_threads_is_bit_identical() {
    let s = scene("cornell", 16, 16, 5);
    let run = |threads: usize| {
        let rc = rcfg(
            8,
            Some((
                gddr5_cfg(4, 4),
                SimOptions {
                    threads,
                    ..SimOptions::default()
                },
            )),
        );
        dualstream::render::render(&s, Mode::Cycle, &rc, &mut |_| {}).unwrap()
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.radiance, b.radiance);
    let (ca, cb) = (a.chip.as_ref().unwrap(), b.chip.as_ref().unwrap());
    assert!(ca.total_cycles > 0);
    assert_eq!(ca.total_cycles, cb.total_cycles);
    assert_eq!(format!("{:?}", a.waves), format!("{:?}", b.waves));
    assert_eq!(format!("{:?}", ca.waves), format!("{:?}", cb.waves));
    assert_eq!(format!("{:?}", ca.dram), format!("{:?}", cb.dram));
}

#[test]
fn sleeping_shadow_and_shuffles_change_nothing() {
    let base = run_tiny_chip(SimOptions::default());
    assert!(base.cycles > 0);
    for (what, o) in variants() {
        let r = run_tiny_chip(o);
        assert!(r == base, "{what}: cycles, statistics, VCD or hits differ");
    }
}

/// The same with the GDDR5 controllers on their own clock (cross-domain links).
#[test]
fn gddr5_sleeping_shadow_and_shuffles_change_nothing() {
    let cfg = gddr5_cfg(1, 4);
    // Tracing every controller at the DRAM clock would dominate the run: the core
    // units and two controllers are traced (all units' statistics are compared).
    let trace = "chip.memory,chip.scheduler,chip.scene_buffer,chip.hit_updater,chip.tm0,chip.mem_ctrl0,chip.mem_ctrl5";
    let base = run_tiny_chip_with(cfg.clone(), SimOptions::default(), trace);
    assert!(base.cycles > 0);
    // "sleep off" is covered by "shadow" (sleep off, and every extra evaluation
    // checked to change nothing); skipped to keep the test short.
    for (what, o) in variants().into_iter().skip(1) {
        let r = run_tiny_chip_with(cfg.clone(), o, trace);
        assert!(
            r == base,
            "gddr5 {what}: cycles, statistics, VCD or hits differ"
        );
    }
}

/// A TP that no tracer watches runs through its internal states (the pop after a
/// node's push, a triangle's result) in one evaluation and sleeps until the next
/// state that offers on a link. That must give the same cycles, statistics of
/// every unit and hits as the traced chip, whose TPs go state by state: with
/// sleeping, with sleeping off, under the shadow check and shuffled; also with
/// one-entry, two-cycle TM links, where offers are refused. And it must save
/// evaluations, or the test would not test it.
#[test]
fn untraced_tps_run_through_internal_states_exactly() {
    let mut tight = chip_cfg(1, 4);
    tight.links.tm = dualstream::rtl::LinkCfg { depth: 1, delay: 2 };
    tight.tm.l1.hit_latency = 2;
    for (what, cfg) in [
        ("fixed", chip_cfg(1, 4)),
        ("gddr5", gddr5_cfg(1, 4)),
        ("one-entry links", tight),
    ] {
        let trace = Some("chip.tm0");
        let (mut base, _, traced_evals) =
            run_tiny_chip_balanced(cfg.clone(), SimOptions::default(), trace, false);
        assert!(base.cycles > 0);
        base.vcd_hash = 0;
        let mut runs = vec![("sleeping", SimOptions::default())];
        runs.extend(variants());
        for (how, o) in runs {
            let sleeping = how == "sleeping";
            let (mut r, _, evals) = run_tiny_chip_balanced(cfg.clone(), o, None, false);
            r.vcd_hash = 0;
            assert!(
                r == base,
                "{what}, {how}: untraced TPs changed cycles, statistics or hits"
            );
            if sleeping {
                assert!(
                    evals * 10 < traced_evals * 9,
                    "{what}: untraced TPs took {evals} evaluations, traced {traced_evals}: \
                     they did not run through their internal states"
                );
            }
        }
    }
}

/// Every unit holds the reset its declaration gives (the Verilog's reset) once
/// elaborated, and again when the simulator's reset follows a wave, which left
/// registers elsewhere: with the fixed memory (with and without the L2) and
/// with GDDR5.
#[test]
fn reset_returns_every_unit_to_its_declared_reset() {
    let mut no_l2 = chip_cfg(2, 4);
    no_l2.chip.l2.enabled = false;
    for cfg in [chip_cfg(2, 4), no_l2, gddr5_cfg(2, 4)] {
        let (mut chip, mut p, rays) = tiny_chip(cfg, SimOptions::default());
        let mismatches = |chip: &Chip| -> Vec<String> {
            let sim = &chip.sim;
            (0..sim.unit_count() as u32)
                .map(UnitId)
                .flat_map(|u| reset_mismatches(sim.unit(u), sim.cycle(sim.unit_clock(u))))
                .collect()
        };
        assert_eq!(mismatches(&chip), Vec::<String>::new(), "elaborated");
        chip.trace_wave(&mut p.mem, &rays).unwrap();
        let after_wave = mismatches(&chip);
        assert!(
            after_wave.iter().any(|m| m.starts_with("tp.")),
            "the wave left no TP register off its reset: the check saw nothing"
        );
        chip.sim.reset();
        assert_eq!(mismatches(&chip), Vec::<String>::new(), "after a reset");
    }
}
