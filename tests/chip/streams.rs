//! Stream bandwidth (lines per cycle), the pass log, and the units' probes.

use super::*;

/// `chip.scheduler.ray_lines_per_cycle` / `scene_lines_per_cycle` memory ports
/// each: the streams issue that many lines in one cycle (a segment streams in a
/// burst), never more, with both memory models; one lane each issues one line
/// per cycle and the hits come out the same. (This run is latency-bound: the
/// cycles are not compared; see docs/chip.md for measured frames.)
#[test]
fn stream_lanes_carry_several_lines_per_cycle() {
    for gddr5 in [false, true] {
        let run = |ray: u32, scene: u32| {
            let mut cfg = if gddr5 {
                gddr5_cfg(1, 4)
            } else {
                chip_cfg(1, 4)
            };
            cfg.chip.scheduler.ray_lines_per_cycle = ray;
            cfg.chip.scheduler.scene_lines_per_cycle = scene;
            run_tiny_chip_with(cfg, SimOptions::default(), "chip.scheduler")
        };
        let one = run(1, 1);
        assert_eq!(sched_counter(&one, "ray_lines_peak"), 1);
        assert_eq!(sched_counter(&one, "scene_lines_peak"), 1);
        let wide = run(3, 4);
        assert_eq!(sched_counter(&wide, "scene_lines_peak"), 4, "gddr5 {gddr5}");
        let r = sched_counter(&wide, "ray_lines_peak");
        assert!((2..=3).contains(&r), "gddr5 {gddr5}: ray lines peak {r}");
        assert_eq!(wide.hits, one.hits, "gddr5 {gddr5}: the same hit records");
    }
}

#[test]
fn bad_stream_lanes_are_named() {
    for (key, v) in [("ray_lines_per_cycle", 0), ("scene_lines_per_cycle", 17)] {
        let e = Config::from_toml(&format!("[chip.scheduler]\n{key} = {v}\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("chip.scheduler.{key} = {v}")), "{e}");
    }
}

#[test]
fn the_pass_log_lists_every_segment_pass_once() {
    let s = scene("cornell", 16, 12, 3);
    let f = render(&s, Mode::Functional, &rcfg(8, None), &mut |_| {}).unwrap();
    let mut cfg = rcfg(8, Some((chip_cfg(2, 16), SimOptions::default())));
    cfg.pass_log = true;
    let c = render(&s, Mode::Cycle, &cfg, &mut |_| {}).unwrap();
    let chip = c.chip.as_ref().unwrap();
    assert_eq!(c.passes.len(), chip.waves.len(), "a log per chip run");
    let mut last = 0;
    for (k, (log, w)) in c.passes.iter().zip(&chip.waves).enumerate() {
        assert_eq!(
            log.len() as u64,
            w.segments_loaded,
            "run {k}: every admission"
        );
        let mut segs: Vec<u32> = log.iter().map(|p| p.seg).collect();
        segs.sort_unstable();
        segs.dedup();
        assert_eq!(
            segs.len(),
            log.len(),
            "run {k}: a segment once per wavefront"
        );
        for p in log {
            assert!(
                p.admit < p.retire && p.retire >= last,
                "run {k}: {p:?} in order"
            );
            last = p.retire;
        }
        // Run k traces wavefront k: every ray written into a queue (the root
        // queue's by the emission or the shading pass) is traced by one pass.
        let rays: u64 = log.iter().map(|p| p.rays).sum();
        let want = f.waves.get(k).map_or(0, |w| w.enqueues);
        assert_eq!(rays, want, "run {k}: rays of its passes");
    }
    assert!(c.passes[0].len() > 1, "several segments");
}

/// What the chip top reads of each unit goes through the unit's probe: the
/// probes agree with the counters each unit reports by name, and the
/// wavefront's figures (a fresh chip: its totals) are those counters.
#[test]
fn every_probe_reads_what_its_unit_counts() {
    use dualstream::rtl::UnitId;
    use dualstream::units::{
        hit_record_updater::HitRecordUpdater, l2::L2, memory::Memory, scene_buffer::SceneBuffer,
        stream_scheduler::StreamScheduler, tp::Tp,
    };
    let s = scene("cornell", 8, 8, 1);
    let rc = rcfg(8, None);
    let mut p = dualstream::render::prepare(&s, &rc).unwrap();
    let rays = dualstream::testbench::tm_tb::treelet_rays(&p, &s, 0).swap_remove(0);
    for r in &rays {
        HitRec::NONE.write(&mut p.mem, p.map.hit_addr(r.hit_index()));
    }
    let mut cfg = chip_cfg(2, 4);
    assert!(cfg.chip.l2.enabled, "the default chip has an L2");
    cfg.accel = rc.accel.clone();
    let consts = dualstream::render::shade_consts(&s, &p);
    let nseg = p.seg.segments.len();
    let mut chip = Chip::new(&cfg, &p.map, nseg, &consts, SimOptions::default()).unwrap();
    let w = chip.trace_wave(&mut p.mem, &rays).unwrap();
    let sim = &chip.sim;
    let named = |u: UnitId| -> std::collections::BTreeMap<&'static str, u64> {
        sim.unit(u).counters().into_iter().collect()
    };

    let sch = sim.unit_ref::<StreamScheduler>(chip.scheduler);
    let (st, c) = (sch.probe().stats, named(chip.scheduler));
    assert!(st.segments_loaded > 1 && st.rays_forwarded > 0, "{st:?}");
    for (name, v) in [
        ("segments_loaded", st.segments_loaded),
        ("enqueues", st.enqueues),
        ("markers", st.markers),
        ("rays_forwarded", st.rays_forwarded),
        ("shade_done", st.shade_done),
    ] {
        assert_eq!(c[name], v, "scheduler {name}");
    }
    assert_eq!(w.segments_loaded, st.segments_loaded);
    assert_eq!(w.duplicates + rays.len() as u64, st.enqueues);
    let done: u64 = sch.done_by_segment().iter().sum();
    assert_eq!(done, sch.enqueued_by_segment().iter().sum::<u64>());
    assert_eq!(done, st.markers, "every ray finished once, in its segments");
    assert_eq!(sch.done_by_segment().len(), nseg);
    assert_eq!(sch.dest_entries(), cfg.chip.scheduler.dest_entries);

    let m = sim.unit_ref::<Memory>(chip.memory).probe();
    let c = named(chip.memory);
    assert!(m.responses > 0);
    assert_eq!((c["requests"], c["responses"]), (m.requests, m.responses));
    assert_eq!(m.in_flight, 0, "drained");
    let tags = ["ray", "scene", "hit", "shading", "other"];
    for (k, t) in tags.iter().enumerate() {
        assert_eq!(
            c[format!("{t}_lines_read").as_str()],
            m.lines_read[k],
            "{t}"
        );
        assert_eq!(c[format!("{t}_lines_written").as_str()], m.lines_written[k]);
    }
    assert_eq!(w.lines_read, m.lines_read);
    assert_eq!(w.lines_written, m.lines_written);

    let sb = sim.unit_ref::<SceneBuffer>(chip.scene_buffer).probe();
    let c = named(chip.scene_buffer);
    assert!(sb.reads > 0 && sb.fills > 0, "{sb:?}");
    for (name, v) in [
        ("reads", sb.reads),
        ("fills", sb.fills),
        ("stale_fills", sb.stale_fills),
        ("stalls", sb.stalls),
        ("stall_cycles", sb.stall_cycles),
        ("bank_conflicts", sb.bank_conflicts),
    ] {
        assert_eq!(c[name], v, "scene buffer {name}");
    }
    assert_eq!(
        (w.scene_buffer_reads, w.scene_buffer_stalls),
        (sb.reads, sb.stalls)
    );
    assert_eq!(w.scene_buffer_stall_cycles, sb.stall_cycles);

    let h = sim.unit_ref::<HitRecordUpdater>(chip.hit_updater).probe();
    let c = named(chip.hit_updater);
    assert!(h.updates > 0 && h.reads > 0, "{h:?}");
    for (name, v) in [
        ("updates", h.updates),
        ("merged", h.merged),
        ("reads", h.reads),
        ("writes", h.writes),
        ("hazard_waits", h.hazard_waits),
    ] {
        assert_eq!(c[name], v, "hit record updater {name}");
    }
    assert_eq!((h.queued, h.in_flight), (0, 0), "drained");
    assert_eq!(w.hit_merged, h.merged);

    let l2u = chip.l2.expect("an L2");
    let l2 = sim.unit_ref::<L2>(l2u).probe();
    let c = named(l2u);
    assert!(l2.stats.accesses > 0, "{l2:?}");
    for (name, v) in [
        ("accesses", l2.stats.accesses),
        ("hits", l2.stats.hits),
        ("misses", l2.stats.misses),
        ("merges", l2.stats.merges),
        ("bank_conflicts", l2.stats.bank_conflicts),
        ("fills", l2.stats.fills),
        ("writebacks", l2.stats.writebacks),
        ("combined", l2.stats.combined),
    ] {
        assert_eq!(c[name], v, "L2 {name}");
    }
    assert_eq!((l2.live_mshrs, l2.mem_queued, l2.at_memory), (0, 0, 0));
    assert_eq!(
        (w.l2.accesses, w.l2.fills),
        (l2.stats.accesses, l2.stats.fills)
    );

    let tps: Vec<UnitId> = chip.tms.iter().flat_map(|t| t.tps.clone()).collect();
    let sum = |name: &str| -> u64 { tps.iter().map(|&u| named(u)[name]).sum() };
    let probed = |f: fn(&dualstream::units::tp::TpStats) -> u64| -> u64 {
        tps.iter().map(|&u| f(sim.unit_ref::<Tp>(u).probe())).sum()
    };
    assert!(sum("box_tests") > 0);
    assert_eq!(probed(|s| s.box_tests), sum("box_tests"));
    assert_eq!(probed(|s| s.tri_tests), sum("tri_tests"));
    assert_eq!(probed(|s| s.l1_loads), sum("l1_loads"));
    assert_eq!(w.box_tests, sum("box_tests"));
    assert_eq!(w.tri_tests, sum("tri_tests"));
    assert_eq!(w.l1_lines, sum("l1_loads"));
    assert_eq!(w.hits_sent, sum("hits"));
    let deepest = tps.iter().map(|&u| named(u)["max_stack"]).max().unwrap();
    assert_eq!(w.max_stack, deepest);
    assert!(tps.iter().all(|&u| !sim.unit_ref::<Tp>(u).holds_work()));
}
