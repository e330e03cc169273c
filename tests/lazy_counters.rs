//! Counters that sleeping units add up lazily (see docs/kernel.md, "Status and stall
//! counters") checked against independent measures of the same waits, on a chip
//! with contention: a TP's `blocked` against the kernel's status integral, and each
//! crossbar `*_conflicts` against the transfer logs of the TP request links (every
//! cycle a request is at the head of its link, visible and not taken, is one
//! conflict).

use dualstream::accel::AccelCfg;
use dualstream::config::Config;
use dualstream::contract::HitRec;
use dualstream::machine::Chip;
use dualstream::render::RenderCfg;
use dualstream::rtl::{LinkEvent, LinkId, SimOptions, Status};
use dualstream::units::tm_xbar::TmXbar;

fn counter(c: &[(&'static str, u64)], name: &str) -> u64 {
    c.iter()
        .find(|(n, _)| *n == name)
        .expect("counter exists")
        .1
}

/// Conflict cycles of one link from its log: for each transfer, the cycles from the
/// one its entry became the visible head to the one it was popped.
fn waits_from_log(log: &[LinkEvent], period: u64) -> u64 {
    let mut visible = std::collections::VecDeque::new();
    let mut last_pop: Option<u64> = None;
    let mut sum = 0;
    for e in log {
        match *e {
            LinkEvent::Push { visible: v, .. } => visible.push_back(v / period),
            LinkEvent::Pop { at } => {
                let v = visible.pop_front().expect("pop after a push");
                let head = last_pop.map_or(v, |p| v.max(p + 1));
                sum += at / period - head;
                last_pop = Some(at / period);
            }
        }
    }
    sum
}

#[test]
fn lazy_counters_match_independent_measures() {
    let mut cfg = Config::default();
    cfg.chip.tms = 1;
    cfg.tm.tps = 16;
    // One-entry TM links: a TP's second request before the first is taken blocks.
    cfg.links.tm.depth = 1;
    let mut s = dualstream::scene::load("cornell").unwrap();
    s.settings.width = 32;
    s.settings.height = 32;
    s.settings.bounces = 1;
    let rc = RenderCfg {
        accel: AccelCfg {
            segment_bytes: 8 << 10,
            ..AccelCfg::default()
        },
        ..RenderCfg::default()
    };
    let mut p = dualstream::render::prepare(&s, &rc).unwrap();
    let rays = dualstream::testbench::tm_tb::treelet_rays(&p, &s, 0).swap_remove(0);
    for r in &rays {
        HitRec::NONE.write(&mut p.mem, p.map.hit_addr(r.hit_index()));
    }
    cfg.accel = rc.accel.clone();
    let consts = dualstream::render::shade_consts(&s, &p);
    let mut chip = Chip::new(
        &cfg,
        &p.map,
        p.seg.segments.len(),
        &consts,
        SimOptions::default(),
    )
    .unwrap();
    let tm = &chip.tms[0];
    let xb: &TmXbar = chip.sim.unit_ref(tm.xbar);
    let classes: Vec<(&str, Vec<LinkId>)> = vec![
        ("div", xb.tp_div_req.iter().map(|i| i.id).collect()),
        ("box", xb.tp_box_req.iter().map(|i| i.id).collect()),
        ("tri", xb.tp_tri_req.iter().map(|i| i.id).collect()),
        ("ray_write", xb.tp_ray_write.iter().map(|i| i.id).collect()),
        ("hit", xb.tp_hit.iter().map(|i| i.id).collect()),
    ];
    let (xbar, tps) = (tm.xbar, tm.tps.clone());
    for (_, ids) in &classes {
        for &id in ids {
            chip.sim.log_link(id, true);
        }
    }
    chip.trace_wave(&mut p.mem, &rays).unwrap();

    let period = 1000;
    let xc = chip.sim.unit_stats(xbar).counters;
    let mut total = 0;
    for (name, ids) in &classes {
        let from_logs: u64 = ids
            .iter()
            .map(|&id| waits_from_log(chip.sim.link_log(id), period))
            .sum();
        let counted = counter(&xc, &format!("{name}_conflicts"));
        assert_eq!(counted, from_logs, "xbar {name}_conflicts vs the link logs");
        total += counted;
    }
    assert!(total > 0, "the test needs contention at the crossbar");

    let mut blocked = 0;
    for &tp in &tps {
        let st = chip.sim.unit_stats(tp);
        let b = counter(&st.counters, "blocked");
        assert_eq!(
            b,
            st.status_cycles[Status::OutputBlocked as usize],
            "TP blocked counter vs its output_blocked status cycles"
        );
        blocked += b;
    }
    assert!(blocked > 0, "the test needs TPs blocked on a full output");
}
