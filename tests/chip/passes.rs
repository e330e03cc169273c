//! Passes end promptly after their last rays; buckets spread fairly over the TMs.

use super::*;

/// When the last rays (or shading items) of a pass are done, the pass ends within
/// a few hundred cycles (`WaveCycles::drain_cycles`: the last end marker to every
/// unit idle), on the default scene, on chips of several shapes, with both memory
/// models: never a drain that grows with the chip (TMs x slots).
#[test]
fn passes_end_promptly_after_their_last_rays() {
    const BOUND: u64 = 500;
    let s = scene(dualstream::scene::DEFAULT_SCENE, 16, 12, 2);
    for (tms, tps, gddr5) in [(1, 16, false), (8, 16, false), (4, 8, true), (2, 16, true)] {
        let cfg = if gddr5 {
            gddr5_cfg(tms, tps)
        } else {
            chip_cfg(tms, tps)
        };
        let c = render(
            &s,
            Mode::Cycle,
            &rcfg(8, Some((cfg, SimOptions::default()))),
            &mut |_| {},
        )
        .unwrap();
        let chip = c.chip.unwrap();
        for (k, w) in chip.waves.iter().enumerate() {
            let what = format!("{tms}x{tps} gddr5={gddr5} run {k}");
            assert!(
                w.drain_cycles >= 1 && w.drain_cycles <= BOUND,
                "{what}: drain {} cycles (of {})",
                w.drain_cycles,
                w.cycles
            );
            assert!(w.drain_cycles < w.cycles, "{what}: drain within the run");
        }
    }
}

// ---- distribution: balanced over the TMs ----

/// The scheduler hands each bucket to the free TM with the fewest outstanding
/// rays (round-robin on ties): on the default scene with an 8 x 16 chip every TM
/// gets rays in every traced run and no TM gets much more than its share.
/// (Lowest-numbered TMs first gave TM 0 up to three buckets while others had none.)
#[test]
fn every_tm_gets_a_fair_share_of_the_rays() {
    let s = scene("cornell", 24, 24, 1);
    let cfg = chip_cfg(8, 16);
    let c = render(
        &s,
        Mode::Cycle,
        &rcfg(64, Some((cfg, SimOptions::default()))),
        &mut |_| {},
    )
    .unwrap();
    let chip = c.chip.unwrap();
    let traced: Vec<_> = chip.waves.iter().filter(|w| w.rays_traced() > 0).collect();
    assert!(traced.len() >= 2, "primary and bounce runs traced");
    for (k, w) in traced.iter().enumerate() {
        assert_eq!(w.tms_with_rays, 8, "run {k}: every TM gets rays ({w:?})");
        assert!(w.tm_rays_min > 0, "run {k}: the least loaded TM gets rays");
        // A fast TM may take more buckets, but never two buckets more than another.
        assert!(
            w.tm_rays_max - w.tm_rays_min <= 2 * 64 && w.tm_imbalance(8) < 2.0,
            "run {k}: rays per TM from {} to {} (max/mean {:.2}, rays {})",
            w.tm_rays_min,
            w.tm_rays_max,
            w.tm_imbalance(8),
            w.rays_traced()
        );
    }
}

/// The distribution's state (outstanding rays per TM, the round-robin pointer)
/// changes only when buckets move: sleeping, shadow evaluation and shuffles give
/// the same cycles and per-TM figures on a chip with several TMs.
#[test]
fn distribution_is_invariant_under_sleeping_shadow_and_shuffles() {
    let s = scene("cornell", 12, 8, 1);
    let run = |opts: SimOptions| {
        let c = render(
            &s,
            Mode::Cycle,
            &rcfg(8, Some((chip_cfg(4, 2), opts))),
            &mut |_| {},
        )
        .unwrap();
        let chip = c.chip.unwrap();
        let waves: Vec<_> = chip
            .waves
            .iter()
            .map(|w| dualstream::machine::WaveCycles { evals: 0, ..*w })
            .collect();
        (chip.total_cycles, waves)
    };
    let base = run(SimOptions::default());
    assert!(base.1.iter().any(|w| w.tms_with_rays == 4));
    // "sleep off" is covered by "shadow" (sleep off, extra evaluations checked).
    for (what, o) in variants().into_iter().skip(1) {
        let v = run(o);
        assert_eq!(v.0, base.0, "{what}: total cycles");
        assert_eq!(v.1, base.1, "{what}: per-run figures");
    }
}
