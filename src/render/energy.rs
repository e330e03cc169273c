//! The energy of a rendered frame: the TPs' and pipelines' activity implied by the
//! traversal counts (every enqueued ray is one ray-segment traversal by a TP), the
//! chip's counted scene-buffer, L2 and shading work in cycle mode, each charged with
//! the per-event energies of `crate::energy`, and the SRAMs' leakage over the
//! render time when `energy.leakage` is on.

use crate::config::Config;
use crate::energy::{Activity, Energy, Instructions, energy, shading_instructions};
use crate::units::tm::TpCosts;

use super::Frame;
use super::traverse::TraversalCounts;

/// The chip's SRAM leakage power in watts: per TM the L1's banks, the staging
/// buffer's banks and a scratchpad per TP; the L2's and the scene buffer's banks.
pub fn leakage_w(c: &Config) -> f64 {
    let e = &c.energy;
    let tm = c.tm.l1.banks as f64 * e.l1_leak_mw_per_bank
        + 2.0 * e.staging_leak_mw_per_bank
        + c.tm.tps as f64 * e.scratchpad_leak_mw;
    let l2 = if c.chip.l2.enabled {
        c.chip.l2.banks as f64 * e.l2_leak_mw_per_bank
    } else {
        0.0
    };
    (c.chip.tms as f64 * tm
        + l2
        + c.chip.scene_buffer.banks as f64 * e.scene_buffer_leak_mw_per_bank)
        * 1e-3
}

/// The activity of the thread processors and their pipelines implied by a
/// functional run: every ray-segment traversal runs the TP states the cycle model's
/// TP runs (the same traversal, `docs/tm.md`), so instruction counts, tests and L1
/// loads follow from the traversal counts and the TP cost table. The fetch state's
/// loads read the staging buffer; the other loads and stores use the local store.
/// Scene-buffer and L2 accesses depend on timing (L1 misses) and are left to the chip.
pub fn tm_activity(t: &TraversalCounts, traversals: u64, costs: &TpCosts) -> Activity {
    let uses = [
        (&costs.fetch, traversals),
        (&costs.init, traversals),
        (&costs.pop, t.pops),
        (&costs.exit, t.exits),
        (&costs.node_fetch, t.nodes),
        (&costs.box_issue, t.nodes),
        (&costs.node_push, t.nodes),
        (&costs.tri_fetch, t.tri_tests),
        (&costs.tri_issue, t.tri_tests),
        (&costs.tri_result, t.tri_tests),
        (&costs.finish, traversals),
    ];
    let mut i = Instructions::default();
    for (c, n) in uses {
        i.add_state(c, n);
    }
    let staging = costs.fetch.load as u64 * traversals;
    Activity {
        box_tests: t.box_tests,
        tri_tests: t.tri_tests,
        tri_hits: t.tri_hits,
        inverse_dirs: traversals,
        instructions: i,
        l1_accesses: t.l1_lines,
        l2_accesses: 0,
        scene_buffer_accesses: 0,
        staging_accesses: staging,
        local_store_accesses: i.load + i.store - staging,
    }
}

/// The TMs' energy of a rendered frame: traversal activity from its counts (every
/// enqueued ray is one ray-segment traversal by a TP), and in cycle mode the
/// scene-buffer reads and the shading pass's instructions the chip counted.
pub fn frame_energy(c: &Config, f: &Frame) -> Energy {
    let mut act = tm_activity(&f.total.traversal, f.total.enqueues, &c.tm.costs);
    if let Some(ch) = &f.chip {
        act.scene_buffer_accesses = ch.waves.iter().map(|w| w.scene_buffer_reads).sum();
        // Every L2 data-array access: client accesses, fills, writebacks.
        act.l2_accesses = ch.waves.iter().map(|w| w.l2.array_accesses()).sum();
        // The shading pass's instructions (on the TPs only; its global loads and
        // stores are charged where they are served).
        for w in &ch.waves {
            act.instructions += shading_instructions(&c.tm.costs, w.shade_uses);
        }
    }
    let mut e = energy(&c.energy, &act);
    if c.energy.leakage
        && let Some(ch) = &f.chip
    {
        let seconds = ch.total_cycles as f64 * ch.core_ps as f64 * 1e-12;
        e.leakage_j = Some(leakage_w(c) * seconds);
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::energy::EnergyCfg;

    #[test]
    fn leakage_counts_every_sram_bank_and_scales_with_the_chip() {
        let mut c = Config::default();
        let e = &c.energy;
        let per_tm = 8.0 * e.l1_leak_mw_per_bank
            + 2.0 * e.staging_leak_mw_per_bank
            + 16.0 * e.scratchpad_leak_mw;
        let global = 32.0 * e.l2_leak_mw_per_bank + 32.0 * e.scene_buffer_leak_mw_per_bank;
        let want = (128.0 * per_tm + global) * 1e-3;
        assert!((leakage_w(&c) - want).abs() < 1e-9, "{}", leakage_w(&c));
        c.chip.tms = 64;
        assert!((leakage_w(&c) - (64.0 * per_tm + global) * 1e-3).abs() < 1e-9);
        c.chip.l2.enabled = false;
        assert!(leakage_w(&c) < (64.0 * per_tm + global) * 1e-3 - 1e-3);
        assert!(
            !EnergyCfg::default().leakage,
            "off by default, as the paper's figures"
        );
    }
}
