//! The GDDR5 channel controllers behind the memory unit; shading on the TPs and the L2.

use super::*;

#[test]
fn gddr5_every_ray_agrees_and_the_checker_is_clean() {
    for (name, w, h, seg_kb) in [("tiny", 16, 16, 8), ("cornell", 16, 12, 8)] {
        let s = scene(name, w, h, 3);
        let f = render(&s, Mode::Functional, &rcfg(seg_kb, None), &mut |_| {}).unwrap();
        // check_timing: every wavefront ran the timing checker (an error otherwise).
        let cfg = rcfg(seg_kb, Some((gddr5_cfg(1, 16), SimOptions::default())));
        let c = render(&s, Mode::Cycle, &cfg, &mut |_| {}).unwrap();
        same_frame(&f, &c, &format!("{name} on 1x16 gddr5"));
        let chip = c.chip.as_ref().unwrap();
        assert!(chip.total_cycles > 0);
        assert_eq!(chip.memory_model, "gddr5");
        for (k, w) in chip.waves.iter().enumerate() {
            // Every line the memory unit served went through a controller, with
            // its stream tag.
            assert_eq!(
                w.dram.tag_reads, w.lines_read,
                "{name} wave {k}: reads per tag"
            );
            assert_eq!(
                w.dram.tag_writes, w.lines_written,
                "{name} wave {k}: writes per tag"
            );
            assert_eq!(w.dram.reads, w.lines_read.iter().sum::<u64>());
            assert_eq!(w.dram.writes, w.lines_written.iter().sum::<u64>());
            assert!(w.dram.row_hits + w.dram.row_misses + w.dram.row_conflicts > 0);
            assert!(w.dram.energy_paper_j > w.dram.energy_physical_j);
            assert!(w.dram.energy_physical_j > 0.0);
        }
    }
}

/// The shading pass on the TPs (stage C) under sleeping off, shadow evaluation and
/// an evaluation-order shuffle: the same cycles and counts per run, the same image.
#[test]
fn tp_shading_is_invariant_under_sleeping_shadow_and_shuffles() {
    let s = scene("cornell", 8, 6, 2);
    let run = |opts: SimOptions| {
        let mut cfg = chip_cfg(1, 4);
        cfg.chip.shading = Shading::Tps;
        let c = render(&s, Mode::Cycle, &rcfg(8, Some((cfg, opts))), &mut |_| {}).unwrap();
        let chip = c.chip.unwrap();
        let waves: Vec<_> = chip
            .waves
            .iter()
            .map(|w| dualstream::machine::WaveCycles { evals: 0, ..*w })
            .collect();
        let bits: Vec<u32> = c
            .radiance
            .iter()
            .flat_map(|v| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()])
            .collect();
        (chip.total_cycles, waves, bits)
    };
    let base = run(SimOptions::default());
    assert!(base.1.iter().skip(1).all(|w| w.shade_items == 48));
    for (what, o) in variants() {
        let v = run(o);
        assert_eq!(v.0, base.0, "{what}: total cycles");
        assert_eq!(v.1, base.1, "{what}: per-run figures");
        assert!(v.2 == base.2, "{what}: image");
    }
}

/// The L2 (on by default) serves the hit record updater and the shading pass:
/// the same rays and image as without it and as functional mode, L2 accesses
/// and hits on every run, and no more DRAM hit-record or shading lines than the
/// direct wiring (`chip.l2.enabled = false`) on the same frame.
#[test]
fn the_l2_serves_hit_records_and_shading_and_saves_dram_lines() {
    use dualstream::mem::StreamTag;
    let s = scene("cornell", 16, 12, 3);
    let f = render(&s, Mode::Functional, &rcfg(8, None), &mut |_| {}).unwrap();
    let run = |l2: bool| {
        let mut cc = chip_cfg(2, 16);
        cc.chip.l2.enabled = l2;
        let mut cfg = rcfg(8, Some((cc, SimOptions::default())));
        cfg.verify = true;
        let c = render(&s, Mode::Cycle, &cfg, &mut |_| {}).unwrap();
        same_frame(&f, &c, &format!("L2 {l2}"));
        assert_eq!(c.verified_rays, c.total.rays);
        c.chip.unwrap()
    };
    let (on, off) = (run(true), run(false));
    let lines = |c: &dualstream::render::ChipFrame, t: StreamTag| -> u64 {
        c.waves
            .iter()
            .map(|w| w.lines_read[t as usize] + w.lines_written[t as usize])
            .sum()
    };
    for (k, w) in on.waves.iter().enumerate() {
        assert!(w.l2.accesses > 0 && w.l2.hits > 0, "run {k}: {:?}", w.l2);
        assert_eq!(w.l2.hits + w.l2.misses, w.l2.accesses, "run {k}");
        assert!(w.l2.flush_cycles > 0 && w.l2.flush_cycles < w.cycles);
        // Combined reads are accesses without an array read of their own.
        assert!(w.l2.combined <= w.l2.hits + w.l2.misses, "run {k}");
        assert_eq!(
            w.l2.array_accesses(),
            w.l2.accesses - w.l2.combined + w.l2.fills + w.l2.writebacks
        );
    }
    // Shading's clients read the same triangles and materials in the same cycle.
    assert!(on.waves.iter().map(|w| w.l2.combined).sum::<u64>() > 0);
    assert!(off.waves.iter().all(|w| w.l2.accesses == 0));
    for t in [StreamTag::Hit, StreamTag::Shading] {
        let (a, b) = (lines(&on, t), lines(&off, t));
        assert!(
            a > 0 && a < b,
            "{t:?}: {a} DRAM lines with the L2, {b} without"
        );
    }
    // The streams do not go through the L2.
    for t in [StreamTag::Ray, StreamTag::Scene] {
        assert_eq!(lines(&on, t), lines(&off, t), "{t:?} lines");
    }
}
